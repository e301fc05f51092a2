// Builds the GNSS backend that the settings name, so that the runtime need
// not include a backend's header (drivers/gpsd).
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include <spdlog/logger.h>

#include "stemd/drivers/gnss_source.hpp"

namespace stemd::drivers {

struct GnssSpec {
    std::string host = "localhost";   // gpsd's host
    std::uint16_t port = 2947;        // gpsd's port
};

// A gpsd client (not yet started); nullptr with `error` set when this build
// has no libgps.
std::unique_ptr<GnssSource> make_gpsd_source(const GnssSpec& spec, std::shared_ptr<spdlog::logger> log,
                                             std::string& error);

}  // namespace stemd::drivers
