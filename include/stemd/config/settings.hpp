// Everything the configuration sets, typed: each schema row (schema.hpp) is
// bound to one member here, so loading a file fills these structs and the
// defaults below must equal the schema's (a test compares them).
#pragma once

#include "stemd/runtime/actuation_config.hpp"
#include "stemd/runtime/camera_config.hpp"
#include "stemd/runtime/daemon_config.hpp"

namespace stemd::config {

struct Settings {
    runtime::DaemonConfig daemon;        // source.*, ring.*, threads.*, status.*, log.*; .vision: the pipeline's keys
    runtime::CameraSettings camera;      // camera.* except camera.gsd_mm_per_px (daemon.vision)
    runtime::ActuationConfig actuation;  // tools, tracker.*, scheduler.*, odometry.*, can.*, gpio.*, map.*
};

}  // namespace stemd::config
