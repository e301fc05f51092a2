#include "stemd/geometry/field.hpp"

namespace stemd::geometry {

std::optional<FieldPoint> field_position(const CameraModel& camera, cv::Point2f stem_px,
                                         double odom_at_capture_mm) noexcept
{
    const std::optional<GroundPoint> g = camera.pixel_to_ground(cv::Point2d(stem_px.x, stem_px.y));
    if (!g)
        return std::nullopt;
    return FieldPoint{odom_at_capture_mm + g->forward_mm, g->y_mm};
}

}  // namespace stemd::geometry
