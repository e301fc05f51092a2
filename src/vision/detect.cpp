#include "stemd/vision/detect.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include "stemd/vision/contour.hpp"
#include "stemd/vision/stem.hpp"

namespace stemd::vision {

namespace {

std::int64_t now_ns()
{
    // steady_clock is CLOCK_MONOTONIC on Linux.
    return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

DetectStatus check_frame(const FrameView& frame, const Params& params, cv::Size expected)
{
    const cv::Mat& primary = params.segmentation == Segmentation::mask ? frame.mask : frame.bgr;
    if (params.segmentation == Segmentation::mask && frame.mask.empty())
        return DetectStatus::missing_mask;
    if (primary.empty())
        return DetectStatus::empty_frame;
    if (primary.type() != (params.segmentation == Segmentation::mask ? CV_8UC1 : CV_8UC3))
        return DetectStatus::bad_format;
    if (primary.size() != expected)
        return DetectStatus::size_mismatch;
    if (params.segmentation == Segmentation::ndvi) {
        if (frame.nir.empty() || frame.nir.size() != expected)
            return DetectStatus::missing_nir;
        if (frame.nir.type() != CV_8UC1)
            return DetectStatus::bad_format;
    }
    return DetectStatus::ok;
}

// Length of a closed 8-connected contour: 1 per straight step, sqrt(2) per diagonal.
double contour_length_px(const std::vector<cv::Point>& contour)
{
    if (contour.size() < 2)
        return static_cast<double>(contour.size());
    int straight = 0, diagonal = 0;
    for (std::size_t i = 0; i < contour.size(); ++i) {
        const cv::Point d = contour[(i + 1) % contour.size()] - contour[i];
        (d.x != 0 && d.y != 0 ? diagonal : straight) += 1;
    }
    return straight + std::numbers::sqrt2 * diagonal;
}

}  // namespace

Workspace::Workspace(cv::Size frame_size, const Params& params)
    : frame_size_(frame_size)
{
    const int width = std::max(frame_size.width, 0);
    const int height = std::max(frame_size.height, 0);
    raw_index_.create(height, width, CV_8UC1);
    index_.create(height, width, CV_8UC1);
    smooth_row_.resize(static_cast<std::size_t>(width));
    vegetation_.reset(width, height);
    thresholded_.reset(width, height);
    closed_.reset(width, height);
    reserved_radius_px_ = std::clamp(params.closing_radius_px, 0, kMaxClosingRadiusPx);
    closing_.reserve(width, height, kMaxClosingRadiusPx);
    labels_.reserve(width, height);
    // 8-connected components are at least one pixel apart in both directions.
    components_.reserve(static_cast<std::size_t>((width + 1) / 2) * static_cast<std::size_t>((height + 1) / 2));
    // Room for ordinary plants; longer (comb-like) contours are truncated,
    // counted, and the plant falls back to its centre of mass.
    contour_.reserve(static_cast<std::size_t>(2 * (width + height)) * 8);
    hull_.reserve(contour_.capacity() + 2);  // the monotone chain holds one extra point while building
    hull_order_.reserve(contour_.capacity());
    defects_.reserve(kMaxLeaves * 4);
    // Set the kernels up once so the first frame allocates nothing either.
    if (width > 0 && height > 0) {
        close_mask(vegetation_, reserved_radius_px_, closed_, closing_);
        open_mask(thresholded_, std::clamp(params.opening_radius_px, 0, kMaxClosingRadiusPx), vegetation_,
                  opening_);
    }
}

void detect(const FrameView& frame, const Params& params, Workspace& ws, Detections& out, StageTimes* times)
{
    out.plants.clear();
    out.stats = DetectStats{};
    out.status = check_frame(frame, params, ws.frame_size_);
    if (out.status != DetectStatus::ok)
        return;
    StageTimes t;
    const std::int64_t t0 = now_ns();

    // 1. Vegetation index and threshold (or the external mask).
    std::int64_t t_index = t0;
    if (params.segmentation == Segmentation::mask) {
        pack_mask(frame.mask, params.mask_vegetation, ws.vegetation_);
        t_index = now_ns();
    } else {
        cv::Mat& index = params.smooth_index ? ws.raw_index_ : ws.index_;
        if (params.segmentation == Segmentation::ndvi)
            ndvi(frame.bgr, frame.nir, ws.ndvi_table_, index);
        else if (params.segmentation == Segmentation::chromatic_exg)
            chromatic_excess_green(frame.bgr, index);
        else
            excess_green(frame.bgr, index);
        if (params.smooth_index)
            smooth_binomial3(ws.raw_index_, ws.smooth_row_.data(), ws.index_);
        t_index = now_ns();
        compute_histogram(ws.index_, ws.histogram_);
        out.stats.threshold = auto_threshold(ws.histogram_, params.threshold, params.soil_sigmas);
        const double separation = class_separation(ws.histogram_, out.stats.threshold);
        out.stats.class_separation = static_cast<float>(separation);
        out.stats.no_vegetation = separation < params.min_class_separation;
        // No second class: an empty mask (index > 255 never holds), so the
        // rest of the pipeline runs as usual and finds nothing.
        threshold_to_bits(ws.index_, out.stats.no_vegetation ? 255 : out.stats.threshold, ws.thresholded_);
        open_mask(ws.thresholded_, std::clamp(params.opening_radius_px, 0, kMaxClosingRadiusPx), ws.vegetation_,
                  ws.opening_);
    }
    const std::int64_t t_threshold = now_ns();
    out.stats.vegetation_px = static_cast<int>(ws.vegetation_.count());

    // 2. Closing.
    close_mask(ws.vegetation_, std::clamp(params.closing_radius_px, 0, kMaxClosingRadiusPx), ws.closed_,
               ws.closing_);
    const std::int64_t t_closing = now_ns();

    // 3. Plants.
    label_components(ws.closed_, ws.labels_, ws.components_);
    const std::int64_t t_plants = now_ns();
    out.stats.components = static_cast<int>(ws.components_.size());

    // 4. Leaves and stems, plant by plant.
    const double pixel_area_mm2 = params.gsd_mm_per_px * params.gsd_mm_per_px;
    const auto min_depth_px = static_cast<float>(params.defect_depth_mm / params.gsd_mm_per_px);
    for (const Component& c : ws.components_) {
        if (static_cast<double>(c.area_px) * pixel_area_mm2 < params.min_plant_area_mm2) {
            ++out.stats.small_components;
            continue;
        }
        if (out.plants.full()) {
            ++out.stats.plants_over_capacity;
            continue;
        }
        Plant plant;
        plant.area_px = static_cast<int>(c.area_px);
        plant.bbox = cv::Rect(c.x_min, c.y_min, c.x_max - c.x_min + 1, c.y_max - c.y_min + 1);
        plant.centre_of_mass = {static_cast<float>(c.sum_x / static_cast<double>(c.area_px)),
                                static_cast<float>(c.sum_y / static_cast<double>(c.area_px))};
        plant.first_pixel = c.first_pixel;

        const double radius_px = std::sqrt(static_cast<double>(c.area_px) / std::numbers::pi);
        if (params.stem_estimator != StemEstimator::com) {
            if (!trace_outer_contour(ws.closed_, c.first_pixel, ws.contour_)) {
                ++out.stats.contour_overflows;
                plant.stem = plant.centre_of_mass;
                plant.com_reason = ComReason::contour_overflow;
                plant.confidence = 0;
                plant.has_stem = false;
                ++out.stats.stemless;
                out.plants.push_back(plant);
                continue;
            }
            convex_hull_indices(ws.contour_, ws.hull_, ws.hull_order_);
            // The cut depth scales with the plant when asked: a fixed depth
            // over-cuts large plants' wavy edges and under-cuts small ones.
            const float depth_px =
                std::max(min_depth_px, static_cast<float>(params.defect_depth_rel * radius_px));
            convexity_defects(ws.contour_, ws.hull_, depth_px, ws.defects_);
            plant.defects = static_cast<int>(ws.defects_.size());
            out.stats.leaves_over_capacity += leaves_from_defects(ws.contour_, ws.defects_, plant.leaves);
            plant.hull_fill = static_cast<float>(static_cast<double>(c.area_px) /
                                                 std::max(convex_hull_area_px(ws.contour_, ws.hull_), 1.0));
            plant.mean_width_mm =
                static_cast<float>(2.0 * static_cast<double>(c.area_px) / std::max(contour_length_px(ws.contour_), 1.0) *
                                   params.gsd_mm_per_px);
        }
        const StemEstimate stem = estimate_stem({plant.leaves.begin(), plant.leaves.size()}, plant.centre_of_mass,
                                                plant.bbox, radius_px, params);
        plant.stem = stem.stem;
        plant.method = stem.method;
        plant.estimator = stem.estimator;
        plant.confidence = stem.confidence;
        plant.com_reason = stem.com_reason;
        if (stem.com_reason == ComReason::outside_box)
            ++out.stats.outside_box_fallbacks;
        // Linear-leaved blobs (grass) have no stem to strike: thin on
        // average and mostly empty hull (blades fanned out from the base).
        const bool grass = params.stem_estimator == StemEstimator::robust &&
                           static_cast<double>(c.area_px) * pixel_area_mm2 >= params.grass_min_area_mm2 &&
                           plant.mean_width_mm < params.grass_max_width_mm &&
                           plant.hull_fill < params.grass_max_hull_fill;
        if (grass)
            plant.confidence = 0;
        if (grass || plant.confidence < params.min_confidence) {
            plant.has_stem = false;
            ++out.stats.stemless;
        }
        out.plants.push_back(plant);
    }
    const std::int64_t t_leaves = now_ns();
    if (times) {
        t.index_ns = t_index - t0;
        t.threshold_ns = t_threshold - t_index;
        t.closing_ns = t_closing - t_threshold;
        t.plants_ns = t_plants - t_closing;
        t.leaves_ns = t_leaves - t_plants;
        t.total_ns = t_leaves - t0;
        *times = t;
    }
}

std::size_t Workspace::reserved_bytes() const
{
    return (raw_index_.total() + index_.total()) * index_.elemSize() + smooth_row_.capacity() * sizeof(std::uint16_t) +
           vegetation_.reserved_bytes() + thresholded_.reserved_bytes() + closed_.reserved_bytes() +
           opening_.reserved_bytes() + closing_.reserved_bytes() + labels_.reserved_bytes() + components_.capacity() * sizeof(Component) +
           contour_.capacity() * sizeof(cv::Point) + (hull_.capacity() + hull_order_.capacity()) * sizeof(int) +
           defects_.capacity() * sizeof(Defect) + sizeof(NdviTable);
}

Detections detect(const FrameView& frame, const Params& params)
{
    const cv::Mat& primary = params.segmentation == Segmentation::mask ? frame.mask : frame.bgr;
    Workspace ws(primary.size(), params);
    Detections out;
    detect(frame, params, ws, out);
    return out;
}

}  // namespace stemd::vision
