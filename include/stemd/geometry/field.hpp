// Field coordinates of a stem.
//
// s_mm (along-track): the odometer reading at which the stem is under the
// camera's principal point, i.e. odom_mm at capture + the stem's forward
// offset from the principal point's ground position. A tool mounted
// d_mm ahead of that point (machine x) is over the stem when the odometer
// reads s_mm - d_mm (behind it: d_mm < 0, so s_mm + |d_mm|).
// y_mm (lateral): the stem's machine-frame y (left of the machine's centre
// line > 0), camera.y_mm included.
#pragma once

#include <optional>

#include <opencv2/core/types.hpp>

#include "stemd/geometry/camera_model.hpp"

namespace stemd::geometry {

struct FieldPoint {
    double s_mm = 0;
    double y_mm = 0;
};

// nullopt when the camera model cannot map the pixel to the ground.
std::optional<FieldPoint> field_position(const CameraModel& camera, cv::Point2f stem_px,
                                         double odom_at_capture_mm) noexcept;

}  // namespace stemd::geometry
