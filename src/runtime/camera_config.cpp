#include "stemd/runtime/camera_config.hpp"

namespace stemd::runtime {

std::optional<geometry::CameraModel> camera_model(const CameraSettings& camera, double gsd_mm_per_px,
                                                  cv::Size frame_size, ConfigProblem& error)
{
    using namespace geometry;
    std::string why;
    if (camera.model == ModelKind::nadir) {
        NadirParams p;
        p.gsd_mm_per_px = gsd_mm_per_px;
        p.principal_px = image_centre(frame_size);
        p.mount = camera.mount;
        auto model = CameraModel::nadir(p, &why);
        if (!model)
            error = {"camera.gsd_mm_per_px", why};
        return model;
    }
    const std::string& file = camera.calibration_file;
    if (file.empty()) {
        error = {"camera.calibration_file", "camera.model is calibrated but camera.calibration_file is none"};
        return std::nullopt;
    }
    const auto intrinsics = read_calibration(file, &why);
    if (!intrinsics) {
        error = {"camera.calibration_file", why};
        return std::nullopt;
    }
    if (intrinsics->image_size != frame_size) {
        error = {"camera.calibration_file",
                 file + " is calibrated for " + std::to_string(intrinsics->image_size.width) + "x" +
                     std::to_string(intrinsics->image_size.height) +
                     " frames, source.width_px x source.height_px is " + std::to_string(frame_size.width) + "x" +
                     std::to_string(frame_size.height)};
        return std::nullopt;
    }
    auto model = CameraModel::calibrated(*intrinsics, camera.pose, camera.mount, &why);
    if (!model)
        error = {"camera.height_mm", "camera pose (camera.height_mm, roll/pitch/yaw_deg): " + why};
    return model;
}

}  // namespace stemd::runtime
