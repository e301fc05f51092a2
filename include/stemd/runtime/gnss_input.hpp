// The actuator's GNSS side: drains the receiver's fixes (drivers::GnssSource)
// between frames, finds each fix's odometer reading at its time
// (gnss.time: when received, or its own UTC time through the system clock),
// and keeps the antenna's track in a local tangent plane around the first
// fix (geometry::GnssTrack). place() then gives a plant's WGS84 position
// from its field coordinates (s_mm, y_mm) and the machine's geometry: the
// principal point's x (camera.x_mm) and the antenna's offset.
//
// A fix newer than the odometer's newest sample waits (a small fixed
// queue) until the odometer has caught up or gnss.max_age_ms has passed.
// No allocation after construction; nothing locks or throws. Single thread
// (the actuator's); counters() from any thread.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <optional>
#include <string_view>

#include "stemd/drivers/gnss_source.hpp"
#include "stemd/geometry/georef.hpp"
#include "stemd/runtime/actuation_config.hpp"
#include "stemd/runtime/odometry_input.hpp"

namespace stemd::runtime {

// A plant's georef column in the plant map.
enum class GeorefStatus : std::uint8_t {
    off,            // gnss.source none: no column
    fix,            // between the fixes bracketing its odometer reading
    extrapolated,   // past the newest fix, along the heading, within gnss.max_extrapolation_mm
    no_fix,         // no fix around it (none yet, lost, or it is older than the track kept)
    stale,          // past the newest fix, which is older than gnss.max_age_ms
    no_heading,     // too little travel yet for a heading (gnss.heading_baseline_mm)
    // Placed (between fixes or extrapolated), but from fixes whose error
    // estimate (eph) is above gnss.max_eph_mm: the position is there to be
    // looked at, not to be trusted as one within the tolerance.
    degraded,
};
std::string_view to_string(GeorefStatus s);

// fix, extrapolated, degraded: lat_deg/lon_deg hold a position.
bool has_position(GeorefStatus s);

struct GeorefResult {
    GeorefStatus status = GeorefStatus::off;
    double lat_deg = 0;
    double lon_deg = 0;
    // The fixes around the plant (the worse of the two bracketing it, or
    // the newest when past it); mode 0 when there was none.
    geometry::FixQuality quality;
};

struct GnssCountersView {
    std::uint64_t fixes = 0;      // taken from the receiver
    std::uint64_t on_track = 0;   // with an odometer reading, on the track
    std::uint64_t unplaced = 0;   // no odometer reading at their time (counted, dropped)
    std::uint64_t degraded = 0;   // plants placed as georef degraded
    geometry::FixQuality last;    // the newest fix taken from the receiver (mode 0: none yet)
};

class GnssInput {
public:
    // principal_x_mm: camera.x_mm (where a plant is, along machine x, when
    // the odometer reads its s_mm).
    GnssInput(const GnssConfig& config, double principal_x_mm);

    // Moves the fixes received so far onto the track. realtime_minus_monotonic_ns:
    // CLOCK_REALTIME - CLOCK_MONOTONIC now (gnss.time gnss).
    void poll(drivers::GnssSource& source, const OdometryInput& odometry, std::int64_t now_ns,
              std::int64_t realtime_minus_monotonic_ns) noexcept;
    // A fix, as poll() takes it (tests drive this directly).
    void add(const drivers::GnssFix& fix, const OdometryInput& odometry, std::int64_t now_ns,
             std::int64_t realtime_minus_monotonic_ns) noexcept;

    // A plant's position; counts the degraded ones (counters()).
    GeorefResult place(double s_mm, double y_mm, std::int64_t now_ns) noexcept;

    GnssCountersView counters() const;
    double max_eph_mm() const { return config_.max_eph_mm; }
    const geometry::GnssTrack& track() const { return track_; }

private:
    // The fix's time on CLOCK_MONOTONIC, per gnss.time.
    std::int64_t fix_time_ns(const drivers::GnssFix& fix, std::int64_t realtime_minus_monotonic_ns) const noexcept;
    // True when the fix was used or dropped; false: the odometer is not there yet.
    bool try_place(const drivers::GnssFix& fix, const OdometryInput& odometry, std::int64_t now_ns,
                   std::int64_t realtime_minus_monotonic_ns) noexcept;

    const GnssConfig config_;
    const double principal_x_mm_;
    geometry::GnssTrack track_;
    std::optional<geometry::LocalTangentPlane> plane_;
    std::array<drivers::GnssFix, 64> waiting_{};
    std::size_t waiting_head_ = 0;
    std::size_t waiting_size_ = 0;
    std::atomic<std::uint64_t> fixes_{0}, on_track_{0}, unplaced_{0}, degraded_{0};
    // The newest fix's quality, for the status line.
    std::atomic<std::uint8_t> last_mode_{0}, last_status_{0};
    std::atomic<double> last_eph_mm_{-1};
};

}  // namespace stemd::runtime
