// Overlays like the paper's figures 3 and 4: outer contour, convex hull,
// cut points, leaf roots and centres, leaf directions, stem, centre of mass;
// stemless plants (grass) get a grey cross instead of a stem.
// Drawing is kept out of the vision library; this only reads its results.
#pragma once

#include <opencv2/core/mat.hpp>

#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/types.hpp"

namespace stemd::viz {

// Draws onto `canvas` (CV_8UC3, the frame's size). `closed` is the closed
// mask the detections came from (Workspace::closed()); contours and hulls
// are traced again from it.
void draw_overlay(cv::Mat& canvas, const vision::Detections& detections, const vision::BitMask& closed);

}  // namespace stemd::viz
