#include "plant_render.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <opencv2/imgproc.hpp>

namespace stemd::synth {
namespace {

constexpr double kPi = std::numbers::pi;

struct Stroke {
    Polygon points;
    int thickness_px = 1;
    cv::Vec3d gain{1, 1, 1};   // multiplies the layer colour per channel
    bool closed = false;
};

// One leaf, grass blade or crown: alpha-composited over the image, its hard
// fill (minus cuts) added to the plant's mask.
struct Layer {
    Polygon outline;
    std::vector<Polygon> cuts;
    std::vector<Stroke> strokes;
    cv::Vec3d bgr;
    double nir = 0;
    // Brightness ramps along the leaf: `ramp_gain` from base to tip.
    cv::Point2d ramp_origin, ramp_direction;
    double ramp_length_px = 1, ramp_gain = 0;
};

void composite(Canvas& canvas, const cv::Rect& box, const cv::Mat& alpha, const cv::Mat& colour, const Layer& layer)
{
    for (int y = 0; y < box.height; ++y) {
        const std::uint8_t* a = alpha.ptr<std::uint8_t>(y);
        const auto* c = colour.ptr<cv::Vec3b>(y);
        auto* dst = canvas.bgr.ptr<cv::Vec3b>(box.y + y) + box.x;
        std::uint8_t* near_infrared = canvas.nir.ptr<std::uint8_t>(box.y + y) + box.x;
        for (int x = 0; x < box.width; ++x) {
            if (a[x] == 0)
                continue;
            const cv::Point2d p = cv::Point2d(box.x + x, box.y + y) - layer.ramp_origin;
            const double u = std::clamp(p.dot(layer.ramp_direction) / layer.ramp_length_px, 0.0, 1.0);
            const float texture = canvas.leaf_texture[static_cast<std::size_t>(box.y + y) * canvas.bgr.cols + box.x + x];
            const double gain = (1 + layer.ramp_gain * (u - 0.5)) * (1 + 0.08 * texture);
            const int w = a[x];
            for (int ch = 0; ch < 3; ++ch) {
                const int v = cv::saturate_cast<std::uint8_t>(c[x][ch] * gain);
                dst[x][ch] = static_cast<std::uint8_t>((dst[x][ch] * (255 - w) + v * w + 127) / 255);
            }
            const int n = cv::saturate_cast<std::uint8_t>(layer.nir * (0.95 + 0.1 * u));
            near_infrared[x] = static_cast<std::uint8_t>((near_infrared[x] * (255 - w) + n * w + 127) / 255);
        }
    }
}

// Draws `layer` inside `plant_box` and ORs its hard fill into plant_mask
// (which covers plant_box).
void draw_layer(Canvas& canvas, const cv::Rect& plant_box, cv::Mat& plant_mask, const Layer& layer)
{
    const cv::Rect box = bounding_box(layer.outline, plant_box);
    if (box.empty())
        return;
    const cv::Point2d origin(box.x, box.y);
    cv::Mat alpha = cv::Mat::zeros(box.size(), CV_8UC1), hard = cv::Mat::zeros(box.size(), CV_8UC1);
    fill(alpha, layer.outline, origin, cv::Scalar(255), cv::LINE_AA);
    fill(hard, layer.outline, origin, cv::Scalar(255), cv::LINE_8);
    for (const Polygon& cut : layer.cuts) {
        fill(alpha, cut, origin, cv::Scalar(0), cv::LINE_AA);
        fill(hard, cut, origin, cv::Scalar(0), cv::LINE_8);
    }
    cv::Mat colour(box.size(), CV_8UC3, cv::Scalar(layer.bgr[0], layer.bgr[1], layer.bgr[2]));
    for (const Stroke& stroke : layer.strokes) {
        const cv::Vec3d c = layer.bgr.mul(stroke.gain);
        const std::vector<std::vector<cv::Point>> lines{to_fixed(stroke.points, origin)};
        cv::polylines(colour, lines, stroke.closed, cv::Scalar(c[0], c[1], c[2]), stroke.thickness_px, cv::LINE_AA,
                      kShift);
    }
    composite(canvas, box, alpha, colour, layer);
    cv::Mat target = plant_mask(box - plant_box.tl());
    cv::bitwise_or(target, hard, target);
}

// Fragmentation of one leaf: gaps across the petiole, a tear into the
// blade, holes in the blade; none near the stem, so the stem stays on the
// mask. `fragmentation` scales how likely and how many.
std::vector<Polygon> leaf_cuts(const LeafParams& leaf, cv::Point2d stem, double fragmentation, double px_per_mm,
                               Rng& rng)
{
    std::vector<Polygon> cuts;
    if (fragmentation <= 0)
        return cuts;
    const double margin_px = 1.5;
    if (leaf.petiole_length_px > 2 * px_per_mm && rng.chance(fragmentation)) {
        const double s = leaf.petiole_length_px * rng.uniform(0.35, 0.85);
        const double across = leaf.petiole_half_px + margin_px;
        cuts.push_back(cross_band(leaf, stem, s, rng.uniform(0.4, 1.0) * px_per_mm, -across, across));
    }
    const double blade_px = leaf.length_px - leaf.petiole_length_px;
    if (blade_px < 3 * px_per_mm)
        return cuts;
    if (rng.chance(fragmentation)) {   // a tear from one edge into the blade
        const double s = leaf.petiole_length_px + blade_px * rng.uniform(0.2, 0.8);
        const double h = half_width(leaf, s), side = rng.chance(0.5) ? 1.0 : -1.0;
        const double depth = rng.uniform(0.4, 0.8) * 2 * h;
        cuts.push_back(cross_band(leaf, stem, s, rng.uniform(0.3, 0.7) * px_per_mm, side * (h + margin_px),
                                  side * (h - depth)));
    }
    const double blade_area_mm2 = blade_px * leaf.blade_half_px * 1.3 / (px_per_mm * px_per_mm);
    const int holes = static_cast<int>(fragmentation * blade_area_mm2 / 60 + rng.uniform());
    for (int i = 0; i < holes; ++i) {
        const double s = leaf.petiole_length_px + blade_px * rng.uniform(0.1, 0.9);
        const cv::Point2d centre =
            stem + centre_point(leaf, s) + centre_normal(leaf, s) * (half_width(leaf, s) * rng.uniform(-0.8, 0.8));
        const double r_px = rng.uniform(0.4, 1.2) * px_per_mm;
        cuts.push_back(circle_polygon(centre, r_px, r_px * rng.uniform(0.6, 1.0), rng.uniform(0, kPi), 10));
    }
    return cuts;
}

std::vector<Polygon> grass_cuts(const LeafParams& blade, cv::Point2d stem, double fragmentation, double px_per_mm,
                                Rng& rng)
{
    std::vector<Polygon> cuts;
    for (int i = 0; i < 2 && rng.chance(fragmentation * (i == 0 ? 1.0 : 0.5)); ++i) {
        const double s = blade.length_px * rng.uniform(0.2, 0.8);
        const double across = blade.petiole_half_px + 1.5;
        cuts.push_back(cross_band(blade, stem, s, rng.uniform(0.4, 1.0) * px_per_mm, -across, across));
    }
    return cuts;
}


// Pale petiole, light midrib and a dark rim on rosette leaves large enough
// to show them.
std::vector<Stroke> leaf_strokes(const LeafParams& leaf, cv::Point2d stem, const Polygon& outline, double px_per_mm)
{
    std::vector<Stroke> strokes;
    if (leaf.shape == BladeShape::linear)
        return strokes;
    auto axis = [&](double s0, double s1) {
        Polygon pts;
        for (int i = 0; i <= 8; ++i)
            pts.push_back(stem + centre_point(leaf, s0 + (s1 - s0) * i / 8));
        return pts;
    };
    const int petiole_width_px = std::max(1, static_cast<int>(std::lround(2 * leaf.petiole_half_px)));
    strokes.push_back({axis(0, leaf.petiole_length_px), petiole_width_px, {1.0, 1.12, 1.25}, false});
    if (leaf.length_px - leaf.petiole_length_px > 6 * px_per_mm) {
        strokes.push_back({axis(leaf.petiole_length_px, leaf.petiole_length_px + 0.85 * (leaf.length_px - leaf.petiole_length_px)), 1,
                           {1.05, 1.15, 1.2}, false});
        strokes.push_back({outline, 1, {0.75, 0.75, 0.75}, true});
    }
    return strokes;
}

Layer leaf_layer(const Plant& plant, const LeafParams& leaf, double fragmentation, double px_per_mm, Rng& rng)
{
    Layer layer;
    layer.outline = translated(leaf_outline(leaf), plant.stem_px);
    layer.cuts = leaf.shape == BladeShape::linear ? grass_cuts(leaf, plant.stem_px, fragmentation, px_per_mm, rng)
                                                  : leaf_cuts(leaf, plant.stem_px, fragmentation, px_per_mm, rng);
    layer.strokes = leaf_strokes(leaf, plant.stem_px, layer.outline, px_per_mm);
    layer.bgr = plant.bgr * leaf.shade;
    layer.nir = plant.nir + leaf.nir_shift;
    layer.ramp_origin = plant.stem_px;
    layer.ramp_direction = direction(leaf);
    layer.ramp_length_px = leaf.length_px;
    layer.ramp_gain = 0.2;
    return layer;
}

Layer crown_layer(const Plant& plant)
{
    Layer layer;
    layer.outline = circle_polygon(plant.stem_px, plant.crown_radius_px, plant.crown_radius_px, 0, 16);
    layer.bgr = plant.bgr * 0.9;
    layer.nir = plant.nir;
    layer.ramp_origin = plant.stem_px;
    layer.ramp_direction = {1, 0};
    return layer;
}

}  // namespace

GroundTruthStem render_plant(Canvas& canvas, const Plant& plant, double fragmentation, double px_per_mm, Rng& rng,
                             cv::Mat* mask_out, cv::Rect* box_out)
{
    const double extent_px = plant_extent_px(plant);
    const cv::Point2d reach(extent_px + 3, extent_px + 3);   // + anti-aliasing
    const cv::Rect image(0, 0, canvas.bgr.cols, canvas.bgr.rows);
    const cv::Rect plant_box = bounding_box({plant.stem_px - reach, plant.stem_px + reach}, image);
    cv::Mat plant_mask = cv::Mat::zeros(plant_box.size(), CV_8UC1);
    std::vector<LeafParams> leaves = plant.leaves;
    std::stable_sort(leaves.begin(), leaves.end(),
                     [](const LeafParams& a, const LeafParams& b) { return a.length_px > b.length_px; });
    for (const LeafParams& leaf : leaves)
        draw_layer(canvas, plant_box, plant_mask, leaf_layer(plant, leaf, fragmentation, px_per_mm, rng));
    draw_layer(canvas, plant_box, plant_mask, crown_layer(plant));
    cv::Mat target = canvas.mask(plant_box);
    cv::bitwise_or(target, plant_mask, target);
    if (!canvas.plant_class.empty()) {
        canvas.plant_class(plant_box).setTo(cv::Scalar(to_value(plant.plant_class)), plant_mask);
    }
    if (mask_out != nullptr && box_out != nullptr) {
        *mask_out = plant_mask;
        *box_out = plant_box;
    }

    GroundTruthStem gt;
    gt.x_px = plant.stem_px.x;
    gt.y_px = plant.stem_px.y;
    gt.kind = plant.plant_class;
    gt.leaves = static_cast<int>(plant.leaves.size());
    gt.radius_mm = extent_px / px_per_mm;
    const cv::Moments m = cv::moments(plant_mask, true);
    gt.area_px = static_cast<int>(m.m00);
    if (m.m00 > 0) {
        gt.mass_x_px = plant_box.x + m.m10 / m.m00;
        gt.mass_y_px = plant_box.y + m.m01 / m.m00;
    }
    return gt;
}

}  // namespace stemd::synth
