// The camera model the camera.* keys describe, for the daemon's actuation:
// a nadir camera at camera.gsd_mm_per_px with its principal point at the
// image centre, or a calibrated one (camera.calibration_file and the pose).
#pragma once

#include <optional>
#include <string>

#include <opencv2/core/types.hpp>

#include "stemd/geometry/camera_model.hpp"
#include "stemd/runtime/config.hpp"

namespace stemd::runtime {

// nullopt with `error` set (naming the key, its origin and the reason) when
// the calibration file cannot be read, its image size differs from the
// frames', or the pose does not see the ground.
std::optional<geometry::CameraModel> camera_model(const config::Config& config, cv::Size frame_size,
                                                  std::string& error);

}  // namespace stemd::runtime
