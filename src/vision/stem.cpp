#include "stemd/vision/stem.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace stemd::vision {

std::optional<cv::Point2f> mean_leaf_intersection(std::span<const Leaf> leaves, double min_angle_deg)
{
    // |sin| of the angle between two lines below this: skip the pair. Never
    // zero, so exactly parallel lines are always skipped.
    const double min_sin = std::max(1e-9, std::sin(std::clamp(min_angle_deg, 0.0, 90.0) * std::numbers::pi / 180.0));
    double sum_x = 0, sum_y = 0;
    int count = 0;
    for (std::size_t i = 0; i < leaves.size(); ++i) {
        const double pix = leaves[i].root.x, piy = leaves[i].root.y;
        const double dix = leaves[i].centre.x - pix, diy = leaves[i].centre.y - piy;
        const double li = std::hypot(dix, diy);
        if (li < 1e-6)
            continue;  // a leaf without a direction
        for (std::size_t j = i + 1; j < leaves.size(); ++j) {
            const double pjx = leaves[j].root.x, pjy = leaves[j].root.y;
            const double djx = leaves[j].centre.x - pjx, djy = leaves[j].centre.y - pjy;
            const double lj = std::hypot(djx, djy);
            if (lj < 1e-6)
                continue;
            const double denominator = dix * djy - diy * djx;
            if (std::abs(denominator) < min_sin * li * lj)
                continue;
            const double t = ((pjx - pix) * djy - (pjy - piy) * djx) / denominator;
            sum_x += pix + t * dix;
            sum_y += piy + t * diy;
            ++count;
        }
    }
    if (count == 0)
        return std::nullopt;
    return cv::Point2f(static_cast<float>(sum_x / count), static_cast<float>(sum_y / count));
}

StemEstimate estimate_stem(std::span<const Leaf> leaves, cv::Point2f centre_of_mass, const cv::Rect& bbox,
                           const Params& params)
{
    StemEstimate estimate{centre_of_mass, StemMethod::com, ComReason::none};
    if (params.stem_method == StemMethod::com) {
        estimate.com_reason = ComReason::method_com;
        return estimate;
    }
    if (static_cast<int>(leaves.size()) < params.min_leaves) {
        estimate.com_reason = ComReason::too_few_leaves;
        return estimate;
    }
    const auto intersection = mean_leaf_intersection(leaves, params.min_intersection_angle_deg);
    if (!intersection) {
        estimate.com_reason = ComReason::no_intersections;
        return estimate;
    }
    // Pixel centres sit at integers, so the box's edges are half a pixel out.
    const bool inside = intersection->x >= bbox.x - 0.5f && intersection->x <= bbox.x + bbox.width - 0.5f &&
                        intersection->y >= bbox.y - 0.5f && intersection->y <= bbox.y + bbox.height - 0.5f;
    if (!inside) {
        estimate.com_reason = ComReason::outside_box;
        return estimate;
    }
    estimate.stem = *intersection;
    estimate.method = StemMethod::leaves;
    return estimate;
}

}  // namespace stemd::vision
