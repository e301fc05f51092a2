#include "plant.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace stemd::synth {
namespace {

constexpr double kPi = std::numbers::pi;

// Starts slightly behind the stem so that the petioles cover it.
double leaf_start(const LeafParams& leaf) { return -leaf.petiole_half_px; }

}  // namespace

cv::Point2d direction(const LeafParams& leaf) { return {std::cos(leaf.angle_rad), std::sin(leaf.angle_rad)}; }

cv::Point2d centre_point(const LeafParams& leaf, double s)
{
    const double t = std::max(s, 0.0) / leaf.length_px;
    const cv::Point2d d = direction(leaf);
    return d * s + perpendicular(d) * (leaf.bend * leaf.length_px * t * t);
}

cv::Point2d centre_normal(const LeafParams& leaf, double s)
{
    const double t = std::max(s, 0.0) / leaf.length_px;
    const cv::Point2d d = direction(leaf);
    return perpendicular(unit(d + perpendicular(d) * (2 * leaf.bend * t)));
}

double half_width(const LeafParams& leaf, double s)
{
    if (leaf.shape == BladeShape::linear)
        return leaf.petiole_half_px * std::clamp(1 - s / leaf.length_px, 0.0, 1.0);
    if (s < leaf.petiole_length_px)
        return leaf.petiole_half_px;
    const double t = (s - leaf.petiole_length_px) / (leaf.length_px - leaf.petiole_length_px);
    // sin(pi t^a) peaks at t = peak_t when peak_t^a = 1/2.
    const double a = std::log(0.5) / std::log(leaf.peak_t);
    const double blade = leaf.blade_half_px * std::sin(kPi * std::pow(t, a));
    return t < 0.5 ? std::max(blade, leaf.petiole_half_px) : blade;
}

Polygon leaf_outline(const LeafParams& leaf)
{
    constexpr int kSamples = 36;
    const double s0 = leaf_start(leaf);
    Polygon left, right;
    for (int i = 0; i <= kSamples; ++i) {
        const double s = s0 + (leaf.length_px - s0) * i / kSamples;
        const cv::Point2d c = centre_point(leaf, s);
        const cv::Point2d n = centre_normal(leaf, s) * half_width(leaf, s);
        left.push_back(c + n);
        right.push_back(c - n);
    }
    left.insert(left.end(), right.rbegin(), right.rend());
    return left;
}

Polygon cross_band(const LeafParams& leaf, cv::Point2d stem, double s, double along, double from, double to)
{
    const cv::Point2d a = stem + centre_point(leaf, s - along / 2);
    const cv::Point2d b = stem + centre_point(leaf, s + along / 2);
    const cv::Point2d na = centre_normal(leaf, s - along / 2), nb = centre_normal(leaf, s + along / 2);
    return {a + na * from, b + nb * from, b + nb * to, a + na * to};
}

double plant_extent_px(const Plant& plant)
{
    double extent = plant.crown_radius_px;
    for (const LeafParams& leaf : plant.leaves)
        for (const cv::Point2d& p : leaf_outline(leaf))
            extent = std::max(extent, std::hypot(p.x, p.y));
    return extent;
}

void scale_plant(Plant& plant, double factor)
{
    plant.crown_radius_px *= factor;
    for (LeafParams& leaf : plant.leaves) {
        leaf.length_px *= factor;
        leaf.petiole_length_px *= factor;
        leaf.petiole_half_px *= factor;
        leaf.blade_half_px *= factor;
    }
}

}  // namespace stemd::synth
