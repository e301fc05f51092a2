// The configured actuation built from an ActuationConfig: the CAN bus
// (SocketCAN on can.interface, or the candump log sink on can.log_file when
// no interface is configured or --can-log is given), the GPIO lines
// (gpio.chip, if any), the plant map (map.file / --map) and the stage that
// drives them (actuation_stage.hpp).
#pragma once

#include <memory>
#include <string>

#include <opencv2/core/types.hpp>

#include "stemd/geometry/camera_model.hpp"
#include "stemd/runtime/actuation_config.hpp"
#include "stemd/runtime/actuation_stage.hpp"
#include "stemd/runtime/odometer_tap.hpp"

namespace stemd::runtime {

// nullptr with `error` set when a part cannot be opened (the log file, the
// plant map, the GPIO chip) or the configuration cannot work. A SocketCAN
// interface that is down is not an error: the bus reopens it with backoff.
std::unique_ptr<ActuationStage> make_actuation(const ActuationConfig& config, const geometry::CameraModel& camera,
                                               cv::Size frame_size, std::string& error);

// The machine's odometer as odometry.source names it (can: ODOMETRY frames
// on can.interface; encoder: the wheel encoder on the gpio.* lines), for a
// program that records without actuating (not started). nullptr with
// `error` set ("KEY: why", as make_actuation words it) when the
// configuration does not hold together (check_actuation_config), names no
// such source, or the source cannot be opened. A SocketCAN interface that
// is down, or a GPIO chip not there yet, is not an error: they are reopened
// with backoff.
std::unique_ptr<OdometerTap> make_odometer_tap(const ActuationConfig& config, std::string& error);

}  // namespace stemd::runtime
