// spdlog loggers, one per subsystem ("main", "capture", "processing",
// "actuator", "status", "replay"...), all writing to one stderr sink.
// journald comes with the systemd unit.
#pragma once

#include <memory>
#include <string>

#include <spdlog/logger.h>

namespace stemd::runtime {

// Sets the level of every logger made by make_logger, now and later.
// `level`: trace | debug | info | warn | error (config key log.level).
void set_log_level(const std::string& level);

// The logger for `subsystem`, created on first use (not on the per-frame
// path: threads take theirs before they start).
std::shared_ptr<spdlog::logger> make_logger(const std::string& subsystem);

}  // namespace stemd::runtime
