#include "stemd/vision/stem.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace stemd::vision {

namespace {

// Confidence of a fallback, fixed and low: the point does not come from
// converging leaves.
constexpr float kCutMeanConfidence = 0.3f;
// The robust fit needs lines that cross at a real angle: for two equal
// leaves, conditioning = tan^2(angle / 2), so 0.05 is about 25 degrees.
constexpr double kMinConditioning = 0.05;

bool inside(const cv::Rect& bbox, cv::Point2f p)
{
    // Pixel centres sit at integers, so the box's edges are half a pixel out.
    return p.x >= bbox.x - 0.5f && p.x <= bbox.x + bbox.width - 0.5f && p.y >= bbox.y - 0.5f &&
           p.y <= bbox.y + bbox.height - 0.5f;
}

}  // namespace

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

std::optional<LineFit> fit_leaf_lines(std::span<const Leaf> leaves, double scale_px)
{
    struct Line {
        double ax, ay, ux, uy, weight;
    };
    Line lines[kMaxLeaves];
    int n = 0;
    for (const Leaf& leaf : leaves) {
        const double dx = leaf.centre.x - leaf.root.x, dy = leaf.centre.y - leaf.root.y;
        const double length = std::hypot(dx, dy);
        if (length < 1e-6 || n == static_cast<int>(kMaxLeaves))
            continue;
        // An elongated leaf is symmetric about its midrib, which points at
        // the stem: its principal axis through its centroid depends on the
        // leaf alone, while the root moves wherever a neighbour overlaps it.
        if (leaf.elongation >= kMinElongationForAxis)
            lines[n++] = {leaf.centre.x, leaf.centre.y, leaf.axis.x, leaf.axis.y, length};
        else
            lines[n++] = {leaf.root.x, leaf.root.y, dx / length, dy / length, length};
    }
    if (n < 2)
        return std::nullopt;
    scale_px = std::max(scale_px, 0.5);

    double robust[kMaxLeaves];
    std::fill(robust, robust + n, 1.0);
    LineFit fit;
    // Iteratively re-weighted least squares: a few rounds settle it.
    for (int round = 0; round < 4; ++round) {
        // Normal equations of sum w |(I - u u^T)(p - a)|^2.
        double a00 = 0, a01 = 0, a11 = 0, b0 = 0, b1 = 0;
        for (int i = 0; i < n; ++i) {
            const Line& l = lines[i];
            const double w = l.weight * robust[i];
            const double m00 = 1 - l.ux * l.ux, m01 = -l.ux * l.uy, m11 = 1 - l.uy * l.uy;
            a00 += w * m00;
            a01 += w * m01;
            a11 += w * m11;
            b0 += w * (m00 * l.ax + m01 * l.ay);
            b1 += w * (m01 * l.ax + m11 * l.ay);
        }
        const double det = a00 * a11 - a01 * a01;
        const double half_trace = 0.5 * (a00 + a11);
        const double spread = std::sqrt(std::max(0.0, half_trace * half_trace - det));
        const double largest = half_trace + spread;
        fit.conditioning = largest > 0 ? std::max(0.0, half_trace - spread) / largest : 0;
        if (det <= 1e-12 * largest * largest)
            return LineFit{{}, 0, 0, 0};  // parallel lines: no point
        const double px = (a11 * b0 - a01 * b1) / det, py = (a00 * b1 - a01 * b0) / det;
        fit.point = {static_cast<float>(px), static_cast<float>(py)};
        double sum_w = 0, sum_wr2 = 0;
        fit.leaves_used = 0;
        for (int i = 0; i < n; ++i) {
            const Line& l = lines[i];
            const double r = std::abs((px - l.ax) * l.uy - (py - l.ay) * l.ux);  // distance to the line
            sum_w += l.weight * robust[i];
            sum_wr2 += l.weight * robust[i] * r * r;
            robust[i] = 1.0 / (1.0 + (r / scale_px) * (r / scale_px));  // Cauchy
            fit.leaves_used += robust[i] >= 0.5;
        }
        fit.rms_px = sum_w > 0 ? std::sqrt(sum_wr2 / sum_w) : 0;
    }
    return fit;
}

StemEstimate estimate_stem(std::span<const Leaf> leaves, cv::Point2f centre_of_mass, const cv::Rect& bbox,
                           double plant_radius_px, const Params& params)
{
    StemEstimate estimate{centre_of_mass, StemMethod::com, StemEstimator::com, kCentreOfMassConfidence,
                          ComReason::none};
    if (params.stem_estimator == StemEstimator::com) {
        estimate.com_reason = ComReason::method_com;
        return estimate;
    }

    if (params.stem_estimator == StemEstimator::paper) {
        if (static_cast<int>(leaves.size()) < params.min_leaves) {
            estimate.com_reason = ComReason::too_few_leaves;
            return estimate;
        }
        const auto intersection = mean_leaf_intersection(leaves, params.min_intersection_angle_deg);
        if (!intersection) {
            estimate.com_reason = ComReason::no_intersections;
            return estimate;
        }
        if (!inside(bbox, *intersection)) {
            estimate.com_reason = ComReason::outside_box;
            return estimate;
        }
        estimate = {*intersection, StemMethod::leaves, StemEstimator::paper, 0.5f, ComReason::none};
        return estimate;
    }

    // Robust: two leaves already cross (min_leaves is the paper's rule).
    if (leaves.size() < 2) {
        estimate.com_reason = ComReason::too_few_leaves;
        return estimate;
    }
    const double radius_px = std::max(plant_radius_px, 1.0);
    // The cut points ring the stem: their mean is the fallback, their
    // spread how far from it the leaf lines may meet.
    cv::Point2f cut_mean(0, 0);
    for (const Leaf& leaf : leaves)
        cut_mean += leaf.cut_a;
    cut_mean *= 1.0f / static_cast<float>(leaves.size());
    double cut_spread = 0;
    for (const Leaf& leaf : leaves)
        cut_spread = std::max(cut_spread, static_cast<double>(cv::norm(leaf.cut_a - cut_mean)));

    const auto fit = fit_leaf_lines(leaves, 0.05 * radius_px);
    const bool well_posed = fit && fit->leaves_used >= 2 && fit->conditioning >= kMinConditioning;
    if (well_posed && inside(bbox, fit->point) &&
        cv::norm(fit->point - cut_mean) <= std::max(cut_spread, 0.1 * radius_px)) {
        const double n = fit->leaves_used;
        const double relative_residual = fit->rms_px / (0.05 * radius_px);
        const double confidence = (1.0 - 1.0 / n) / (1.0 + relative_residual * relative_residual) *
                                  std::min(1.0, fit->conditioning / 0.25);
        estimate = {fit->point, StemMethod::leaves, StemEstimator::robust,
                    static_cast<float>(std::clamp(confidence, 0.0, 1.0)), ComReason::none};
        return estimate;
    }
    // Where the leaves meet is still best told by the cuts between them.
    if (inside(bbox, cut_mean)) {
        const float confidence = kCutMeanConfidence * (1.0f - 1.0f / static_cast<float>(leaves.size()));
        estimate = {cut_mean, StemMethod::leaves, StemEstimator::robust, confidence, ComReason::none};
        return estimate;
    }
    estimate.com_reason = ComReason::ill_conditioned;
    return estimate;
}

}  // namespace stemd::vision
