// The camera model the camera.* keys describe, for the daemon's actuation:
// a nadir camera at camera.gsd_mm_per_px with its principal point at the
// image centre, or a calibrated one (camera.calibration_file and the pose).
#pragma once

#include <optional>
#include <string>

#include <opencv2/core/types.hpp>

#include "stemd/geometry/camera_model.hpp"
#include "stemd/runtime/config_problem.hpp"

namespace stemd::runtime {

// camera.* (camera.gsd_mm_per_px is the pipeline's: vision::Params).
struct CameraSettings {
    geometry::ModelKind model = geometry::ModelKind::nadir;
    std::string calibration_file;   // empty: not set (none)
    geometry::Pose pose;            // calibrated: height and tilts
    geometry::Mount mount;          // forward direction, principal point's ground position
};

// nullopt with `error` set when the calibration file cannot be read, its
// image size differs from the frames', or the pose does not see the ground.
std::optional<geometry::CameraModel> camera_model(const CameraSettings& camera, double gsd_mm_per_px,
                                                  cv::Size frame_size, ConfigProblem& error);

}  // namespace stemd::runtime
