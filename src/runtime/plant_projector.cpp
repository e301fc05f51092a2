#include "stemd/runtime/plant_projector.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "stemd/geometry/field.hpp"
#include "stemd/runtime/status.hpp"

namespace stemd::runtime {

namespace {

// The along-track extent of the view relative to the odometer at capture:
// the image border's field positions (corners and edge midpoints, enough
// for the nadir model and for mild tilt/distortion).
bool view_extent(const geometry::CameraModel& camera, cv::Size size, double& lo, double& hi)
{
    const double w = size.width - 1, h = size.height - 1;
    const cv::Point2f border[] = {{0, 0}, {static_cast<float>(w / 2), 0}, {static_cast<float>(w), 0},
                                  {0, static_cast<float>(h / 2)}, {static_cast<float>(w), static_cast<float>(h / 2)},
                                  {0, static_cast<float>(h)}, {static_cast<float>(w / 2), static_cast<float>(h)},
                                  {static_cast<float>(w), static_cast<float>(h)}};
    lo = std::numeric_limits<double>::infinity();
    hi = -lo;
    for (const cv::Point2f& px : border)
        if (const auto p = geometry::field_position(camera, px, 0.0)) {
            lo = std::min(lo, p->s_mm);
            hi = std::max(hi, p->s_mm);
        }
    return lo <= hi;
}

}  // namespace

std::optional<PlantProjector> PlantProjector::make(const geometry::CameraModel& camera, cv::Size frame_size)
{
    double lo = 0, hi = 0;
    if (!view_extent(camera, frame_size, lo, hi))
        return std::nullopt;
    return PlantProjector(camera, frame_size, lo, hi);
}

PlantProjector::PlantProjector(const geometry::CameraModel& camera, cv::Size frame_size, double view_min_mm,
                               double view_max_mm)
    : camera_(camera), frame_size_(frame_size), view_min_mm_(view_min_mm), view_max_mm_(view_max_mm)
{
}

std::span<const actuation::TrackDetection> PlantProjector::project(const FrameResult& r, double odom_at_capture,
                                                                   ActuationCounters& counters) noexcept
{
    std::size_t n = 0;
    const auto& plants = r.detections.plants;
    for (std::size_t i = 0; i < plants.size(); ++i) {
        const vision::Plant& p = plants[i];
        if (!p.has_stem)
            continue;
        if (clipped_along_track(p.bbox)) {
            bump(counters.clipped);
            continue;
        }
        const auto field = geometry::field_position(camera_, p.stem, odom_at_capture);
        if (!field) {
            bump(counters.off_ground);
            continue;
        }
        actuation::TrackDetection& d = detections_[n++];
        d.s_mm = field->s_mm;
        d.y_mm = field->y_mm;
        d.confidence = p.confidence;
        d.plant_class = r.has_class_map ? r.plant_class[i] : PlantClass::Unknown;
        d.leaves = static_cast<std::uint8_t>(std::min<std::size_t>(p.leaves.size(), 255));
        d.extent_mm = extent_mm(p, odom_at_capture);
        // A stemless weed's target stands for the whole plant, not for a
        // part of another: it joins plant tracks (ComReason::stemless_weed).
        // A further target on a wide weed lies beside that weed's own, so it
        // is tracked apart as a part is.
        d.weed_part = p.com_reason == vision::ComReason::weed_part || p.com_reason == vision::ComReason::weed_cover;
    }
    return {detections_.data(), n};
}

bool PlantProjector::clipped_along_track(const cv::Rect& bbox) const noexcept
{
    using geometry::Forward;
    const Forward f = camera_.mount().forward;
    if (f == Forward::up || f == Forward::down)
        return bbox.y <= 0 || bbox.y + bbox.height >= frame_size_.height;
    return bbox.x <= 0 || bbox.x + bbox.width >= frame_size_.width;
}

double PlantProjector::extent_mm(const vision::Plant& p, double odom_mm) const noexcept
{
    // Half the distance along track between the plant's two along-track
    // bounding-box edges, through the stem.
    using geometry::Forward;
    const Forward f = camera_.mount().forward;
    const bool vertical = f == Forward::up || f == Forward::down;
    const cv::Point2f a = vertical ? cv::Point2f(p.stem.x, static_cast<float>(p.bbox.y))
                                   : cv::Point2f(static_cast<float>(p.bbox.x), p.stem.y);
    const cv::Point2f b = vertical ? cv::Point2f(p.stem.x, static_cast<float>(p.bbox.y + p.bbox.height - 1))
                                   : cv::Point2f(static_cast<float>(p.bbox.x + p.bbox.width - 1), p.stem.y);
    const auto fa = geometry::field_position(camera_, a, odom_mm);
    const auto fb = geometry::field_position(camera_, b, odom_mm);
    return fa && fb ? std::abs(fa->s_mm - fb->s_mm) / 2 : 0.0;
}

}  // namespace stemd::runtime
