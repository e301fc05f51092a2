// A frame's stems in field coordinates: each stem -> (s_mm, y_mm) through
// the camera model at the odometer at capture; the plant's class from the
// frame's class map, if any. A plant cut by the leading or trailing image
// border (the along-track borders, per camera.forward) is skipped (counted:
// clipped): its stem is estimated from part of it, and the same plant is
// seen whole in other frames. Plants cut by the lateral borders are kept
// (some are never seen whole). No allocation after make().
#pragma once

#include <array>
#include <optional>
#include <span>

#include <opencv2/core/types.hpp>

#include "stemd/actuation/tracker.hpp"
#include "stemd/geometry/camera_model.hpp"
#include "stemd/runtime/actuation_counters.hpp"
#include "stemd/runtime/detection_sink.hpp"

namespace stemd::runtime {

class PlantProjector {
public:
    // nullopt when the camera model puts no part of the image on the ground.
    static std::optional<PlantProjector> make(const geometry::CameraModel& camera, cv::Size frame_size);

    // The frame's plants with a stem, as detections for the tracker; valid
    // until the next call.
    std::span<const actuation::TrackDetection> project(const FrameResult& result, double odom_at_capture,
                                                       ActuationCounters& counters) noexcept;

    // The view's along-track extent relative to the odometer at capture.
    double view_forward_min_mm() const { return view_min_mm_; }
    double view_forward_max_mm() const { return view_max_mm_; }

private:
    PlantProjector(const geometry::CameraModel& camera, cv::Size frame_size, double view_min_mm, double view_max_mm);

    bool clipped_along_track(const cv::Rect& bbox) const noexcept;
    double extent_mm(const vision::Plant& plant, double odom_mm) const noexcept;

    geometry::CameraModel camera_;
    cv::Size frame_size_;
    double view_min_mm_ = 0, view_max_mm_ = 0;
    std::array<actuation::TrackDetection, vision::kMaxPlants> detections_{};
};

}  // namespace stemd::runtime
