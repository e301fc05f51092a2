// Synthetic plants for the VM checks' frames: a rosette of elliptic leaves
// radiating from a known stem, which stemd's detector finds within a few px.
#pragma once

#include <cmath>

#include <opencv2/imgproc.hpp>

namespace stemd::vmprobe {

struct Rosette {
  cv::Point2f stem;     // px
  int leaves;
  float leaf_length;    // px, stem to leaf tip
  float rotation_deg;   // of the first leaf
};

// Draws `r` into `bgr` in `colour`: each leaf an ellipse from the stem
// outwards, and a small disc on the stem.
inline void draw_rosette(cv::Mat& bgr, const Rosette& r, const cv::Scalar& colour) {
  for (int i = 0; i < r.leaves; ++i) {
    const float a = r.rotation_deg + 360.0f * static_cast<float>(i) / static_cast<float>(r.leaves);
    const float rad = a * static_cast<float>(CV_PI) / 180.0f;
    const cv::Point2f centre = r.stem + 0.5f * r.leaf_length * cv::Point2f(std::cos(rad), std::sin(rad));
    cv::ellipse(bgr, cv::RotatedRect(centre, cv::Size2f(r.leaf_length, r.leaf_length * 0.38f), a), colour,
                cv::FILLED, cv::LINE_AA);
  }
  cv::circle(bgr, r.stem, 4, colour, cv::FILLED, cv::LINE_AA);
}

}  // namespace stemd::vmprobe
