#include "polygon.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <opencv2/imgproc.hpp>

namespace stemd::synth {
namespace {

constexpr double kFixedOne = 1 << kShift;

}  // namespace

cv::Point2d perpendicular(cv::Point2d v) { return {-v.y, v.x}; }
cv::Point2d unit(cv::Point2d v) { return v * (1.0 / std::hypot(v.x, v.y)); }

Polygon circle_polygon(cv::Point2d centre, double radius_x, double radius_y, double angle_rad, int vertices)
{
    Polygon poly;
    const cv::Point2d u{std::cos(angle_rad), std::sin(angle_rad)};
    for (int i = 0; i < vertices; ++i) {
        const double a = 2 * std::numbers::pi * i / vertices;
        poly.push_back(centre + u * (radius_x * std::cos(a)) + perpendicular(u) * (radius_y * std::sin(a)));
    }
    return poly;
}

Polygon translated(Polygon poly, cv::Point2d offset)
{
    for (cv::Point2d& p : poly)
        p += offset;
    return poly;
}

cv::Rect bounding_box(const Polygon& poly, const cv::Rect& clip)
{
    double x0 = poly[0].x, x1 = x0, y0 = poly[0].y, y1 = y0;
    for (const cv::Point2d& p : poly) {
        x0 = std::min(x0, p.x), x1 = std::max(x1, p.x);
        y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
    }
    const cv::Point tl(static_cast<int>(std::floor(x0)) - 2, static_cast<int>(std::floor(y0)) - 2);
    const cv::Point br(static_cast<int>(std::ceil(x1)) + 3, static_cast<int>(std::ceil(y1)) + 3);
    return cv::Rect(tl, br) & clip;
}

std::vector<cv::Point> to_fixed(const Polygon& poly, cv::Point2d origin)
{
    std::vector<cv::Point> fixed;
    fixed.reserve(poly.size());
    for (const cv::Point2d& p : poly)
        fixed.emplace_back(static_cast<int>(std::lround((p.x - origin.x) * kFixedOne)),
                           static_cast<int>(std::lround((p.y - origin.y) * kFixedOne)));
    return fixed;
}

void fill(cv::Mat& image, const Polygon& poly, cv::Point2d origin, const cv::Scalar& value, int line_type)
{
    const std::vector<std::vector<cv::Point>> polys{to_fixed(poly, origin)};
    cv::fillPoly(image, polys, value, line_type, kShift);
}

}  // namespace stemd::synth
