// A GNSS receiver as the actuator sees it: fixes, each stamped with
// CLOCK_MONOTONIC when it was received and with the receiver's own (GNSS,
// UTC) time, taken from a lock-free ring that the backend's own thread
// fills. try_pop() never blocks, locks or allocates.
#pragma once

#include <cstdint>
#include <memory>
#include <string_view>

#include "stemd/base/non_copyable.hpp"

namespace stemd::drivers {

struct GnssFix {
    std::int64_t timestamp_sample_ns = 0;   // CLOCK_MONOTONIC when the fix was received
    std::int64_t gnss_time_ns = 0;          // the fix's UTC time, ns since the Unix epoch; 0: unknown
    std::uint8_t mode = 0;                  // 2: 2D, 3: 3D (gpsd's fix mode; lesser fixes are not published)
    std::uint8_t quality = 0;               // gpsd's fix status: 1 GPS, 2 DGPS, 3 RTK fixed, 4 RTK float, ...
    double lat_deg = 0;
    double lon_deg = 0;
    double height_m = 0;                    // above the ellipsoid; 0 when the fix has none (2D)
    double eph_m = -1;                      // horizontal error estimate (95 %), m; -1: unknown
    double epx_m = -1;                      // longitude error estimate, m; -1: unknown
    double epy_m = -1;                      // latitude error estimate, m; -1: unknown
};

struct GnssCounters {
    std::uint64_t fixes = 0;        // published
    std::uint64_t no_fix = 0;       // reports without a position (mode < 2)
    std::uint64_t dropped = 0;      // the ring was full
    std::uint64_t connects = 0;     // successful connections (1 + reconnections)
    std::uint64_t failures = 0;     // failed connections and lost streams
};

class GnssSource : base::NonCopyable {
public:
    virtual ~GnssSource() = default;
    virtual std::string_view name() const = 0;   // e.g. "gpsd localhost:2947"
    // Starts the backend's thread; it connects (and reconnects) by itself.
    virtual bool start() = 0;
    virtual void stop() = 0;
    // The oldest fix not yet taken. Consumer side: one thread.
    virtual bool try_pop(GnssFix& out) noexcept = 0;
    virtual GnssCounters counters() const = 0;
};

}  // namespace stemd::drivers
