// Polygons in image px and their fixed-point filling: every shape of the
// synthetic field (leaves, crowns, clods, cuts) is one.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace stemd::synth {

using Polygon = std::vector<cv::Point2d>;

cv::Point2d perpendicular(cv::Point2d v);
cv::Point2d unit(cv::Point2d v);

// An ellipse of `vertices` corners, its x radius along angle_rad.
Polygon circle_polygon(cv::Point2d centre, double radius_x, double radius_y, double angle_rad, int vertices);
Polygon translated(Polygon poly, cv::Point2d offset);
// The pixels `poly` may touch (anti-aliasing included), inside `clip`.
cv::Rect bounding_box(const Polygon& poly, const cv::Rect& clip);

constexpr int kShift = 4;   // sub-pixel bits for OpenCV drawing

// Fills `poly` (shifted by -origin) into `image`, at kShift sub-pixel bits.
std::vector<cv::Point> to_fixed(const Polygon& poly, cv::Point2d origin);
void fill(cv::Mat& image, const Polygon& poly, cv::Point2d origin, const cv::Scalar& value, int line_type);

}  // namespace stemd::synth
