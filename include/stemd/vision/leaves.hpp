// Leaves from convexity defects of a plant's outer contour.
#pragma once

#include <span>
#include <vector>

#include <opencv2/core/types.hpp>

#include "stemd/vision/types.hpp"

namespace stemd::vision {

// Indices of the contour points on the convex hull, ascending (contour
// order), each hull vertex once. Monotone chain; never throws, even for
// contours that revisit points (1-pixel bridges) where OpenCV's
// convexityDefects rejects the hull as "not monotonous".
// `order` is scratch of at least 2 * (contour's x extent + 1) capacity.
void convex_hull_indices(std::span<const cv::Point> contour, std::vector<int>& hull, std::vector<int>& order);

// Area of the convex hull around the contour's pixel squares (not just
// their centres): the hull polygon's area plus half its perimeter plus 1,
// so a convex blob's pixel area is about equal to it. 0 for no hull.
double convex_hull_area_px(std::span<const cv::Point> contour, std::span<const int> hull);

struct Defect {
    int start = 0;      // hull vertex before the pocket (contour index)
    int end = 0;        // hull vertex after it
    int deepest = 0;    // contour point farthest from the hull edge: the cut point
    float depth_px = 0;
};

// One defect per hull edge whose pocket is deeper than min_depth_px, in
// contour order. `out` is cleared and filled up to its capacity().
void convexity_defects(std::span<const cv::Point> contour, std::span<const int> hull, float min_depth_px,
                       std::vector<Defect>& out);

// The leaf bounded by the contour from index `from` to `to` (to may exceed
// the contour's size: it wraps), closed by the straight cut between them:
// cut_a, cut_b at the ends, root their mean, centre the polygon's area
// centroid (its vertex mean if it has no area), axis and elongation from
// its second moments. from = 0, to = size - 1 makes the whole contour a leaf.
Leaf leaf_from_polygon(std::span<const cv::Point> contour, int from, int to);

// Each pair of neighbouring cut points (cyclic) bounds one leaf: the
// contour between them closed by the cut. root = mean of the cut points,
// centre = area centroid of that polygon (its vertex mean if it has no
// area). Fewer than two defects give no leaves. Returns how many leaves
// did not fit in `out`.
int leaves_from_defects(std::span<const cv::Point> contour, std::span<const Defect> defects,
                        FixedVector<Leaf, kMaxLeaves>& out);

}  // namespace stemd::vision
