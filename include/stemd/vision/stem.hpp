// Stem position from the leaf directions (or the centre of mass).
#pragma once

#include <optional>
#include <span>

#include <opencv2/core/types.hpp>

#include "stemd/vision/types.hpp"

namespace stemd::vision {

// The paper's estimator: mean of the pairwise intersections of the leaf
// direction lines (root -> centre). Pairs whose lines meet at less than
// min_angle_deg (and exactly parallel ones) and leaves without a direction
// are skipped; nullopt when no pair is left.
std::optional<cv::Point2f> mean_leaf_intersection(std::span<const Leaf> leaves, double min_angle_deg);

// A leaf whose principal second moments differ by less than this has no
// clear long axis (a round blade): its midrib's direction is unknown.
inline constexpr double kMinElongationForAxis = 1.5;

struct LineFit {
    cv::Point2f point;
    double rms_px = 0;        // weighted RMS distance of the point to the leaf lines
    double conditioning = 0;  // smallest / largest eigenvalue of the normal matrix, in [0, 1]
    int leaves_used = 0;      // leaves that kept at least half their weight
};

// The point nearest all leaf lines in the weighted least-squares sense.
// A leaf's line runs along its principal axis through its centroid when the
// leaf is elongated (its midrib points at the stem, whatever its neighbours
// overlap), else from its root through its centre. Each leaf is weighted by
// its length (longer leaves give better-defined directions) and re-weighted
// with a Cauchy loss of scale `scale_px`, so a leaf whose line misses the
// others (a cut in the wrong place) loses its say.
// nullopt with fewer than two leaves with a direction.
std::optional<LineFit> fit_leaf_lines(std::span<const Leaf> leaves, double scale_px);

// The confidence of a stem at the centre of mass: fixed and low, the point
// does not come from converging leaves.
inline constexpr float kCentreOfMassConfidence = 0.2f;

struct StemEstimate {
    cv::Point2f stem;
    StemMethod method = StemMethod::com;
    StemEstimator estimator = StemEstimator::com;
    float confidence = 0;
    ComReason com_reason = ComReason::none;
};

// The estimate `params.stem_estimator` asks for, with its fallbacks:
//  paper:  with at least min_leaves leaves the intersection mean, else the
//          centre of mass; an estimate outside `bbox` falls back too.
//  robust: fit_leaf_lines with at least two leaves; the fit must be well
//          conditioned, inside `bbox` and where the leaves meet (within the
//          cut points' spread of their mean), else the mean of the cut
//          points (two or more leaves), else the centre of mass.
// `plant_radius_px` is the plant's equivalent radius sqrt(area / pi).
// Confidence: leaves-based fits grow with the number of leaves and fall
// with the residual (relative to the plant's size) and poor conditioning;
// fallbacks get a fixed low value.
StemEstimate estimate_stem(std::span<const Leaf> leaves, cv::Point2f centre_of_mass, const cv::Rect& bbox,
                           double plant_radius_px, const Params& params);

}  // namespace stemd::vision
