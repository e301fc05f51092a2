#include "stemd/runtime/camera_config.hpp"

namespace stemd::runtime {

std::optional<geometry::CameraModel> camera_model(const config::Config& config, cv::Size frame_size,
                                                  std::string& error)
{
    using namespace geometry;
    Mount mount;
    // The schema has checked the choice already.
    mount.forward = parse_forward(config.get_text("camera.forward")).value_or(Forward::up);
    mount.x_mm = config.get_real("camera.x_mm");
    mount.y_mm = config.get_real("camera.y_mm");
    std::string why;
    if (config.get_text("camera.model") == "nadir") {
        NadirParams p;
        p.gsd_mm_per_px = config.get_real("camera.gsd_mm_per_px");
        p.principal_px = image_centre(frame_size);
        p.mount = mount;
        auto model = CameraModel::nadir(p, &why);
        if (!model)
            error = "camera.gsd_mm_per_px (" + config.origin_of("camera.gsd_mm_per_px") + "): " + why;
        return model;
    }
    const std::string& file = config.get_text("camera.calibration_file");
    const std::string origin = config.origin_of("camera.calibration_file");
    if (file == "none") {
        error = "camera.model is calibrated but camera.calibration_file is none (" + origin + ")";
        return std::nullopt;
    }
    const auto intrinsics = read_calibration(file, &why);
    if (!intrinsics) {
        error = "camera.calibration_file (" + origin + "): " + why;
        return std::nullopt;
    }
    if (intrinsics->image_size != frame_size) {
        error = "camera.calibration_file (" + origin + "): " + file + " is calibrated for " +
                std::to_string(intrinsics->image_size.width) + "x" + std::to_string(intrinsics->image_size.height) +
                " frames, source.width_px x source.height_px is " + std::to_string(frame_size.width) + "x" +
                std::to_string(frame_size.height);
        return std::nullopt;
    }
    Pose pose;
    pose.height_mm = config.get_real("camera.height_mm");
    pose.roll_deg = config.get_real("camera.roll_deg");
    pose.pitch_deg = config.get_real("camera.pitch_deg");
    pose.yaw_deg = config.get_real("camera.yaw_deg");
    auto model = CameraModel::calibrated(*intrinsics, pose, mount, &why);
    if (!model)
        error = "camera pose (camera.height_mm, roll/pitch/yaw_deg): " + why;
    return model;
}

}  // namespace stemd::runtime
