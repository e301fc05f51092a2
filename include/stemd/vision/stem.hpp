// Stem position from the leaf directions (or the centre of mass).
#pragma once

#include <optional>
#include <span>

#include <opencv2/core/types.hpp>

#include "stemd/vision/types.hpp"

namespace stemd::vision {

// Mean of the pairwise intersections of the leaf direction lines
// (root -> centre). Pairs whose lines meet at less than min_angle_deg
// (and exactly parallel ones) and leaves without a direction are skipped;
// nullopt when no pair is left.
std::optional<cv::Point2f> mean_leaf_intersection(std::span<const Leaf> leaves, double min_angle_deg);

struct StemEstimate {
    cv::Point2f stem;
    StemMethod method = StemMethod::com;
    ComReason com_reason = ComReason::none;
};

// The paper's rule: with at least min_leaves leaves the intersection mean,
// else the centre of mass; a leaf estimate outside `bbox` (inclusive pixel
// box) falls back to the centre of mass too.
StemEstimate estimate_stem(std::span<const Leaf> leaves, cv::Point2f centre_of_mass, const cv::Rect& bbox,
                           const Params& params);

}  // namespace stemd::vision
