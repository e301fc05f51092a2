// Outer contour of one component, traced on the bit mask.
#pragma once

#include <vector>

#include <opencv2/core/types.hpp>

#include "stemd/vision/bitmask.hpp"

namespace stemd::vision {

// Suzuki-Abe outer border following (8-connectivity) from `start`, the
// component's top-most-then-left-most pixel: the same points, in the same
// order, as cv::findContours(RETR_EXTERNAL, CHAIN_APPROX_NONE). `contour`
// is cleared and filled up to its capacity(); returns false (contour
// truncated) if the border is longer than that.
bool trace_outer_contour(const BitMask& mask, cv::Point start, std::vector<cv::Point>& contour);

}  // namespace stemd::vision
