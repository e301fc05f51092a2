// The actuator's odometer, from the configured source (odometry.source): a
// frame's own odom_mm (a recording's column), a constant speed from the
// first frame on, ODOMETRY frames from the bus (at their receive time), or
// a wheel encoder. `auto` takes the frames' column once one frame has
// carried it; from then on a frame without it has no odometer, as under
// `recording` (a constant-speed odometer for it would place its plants,
// and the commands for them, on another scale: the daemon resolves `auto`
// per recording before it starts, resolve_auto_odometry()). Samples that
// would not advance the ring are refused; those below the newest reading
// (the machine reversing) are counted, odometry_going_back: from the first
// of them until the odometer passes its highest reading again, frames have
// no odometer (not even one extrapolated at the speed before the turn). No
// allocation after construction; nothing throws.
#pragma once

#include <cstdint>

#include "stemd/geometry/odometry.hpp"
#include "stemd/runtime/actuation_config.hpp"
#include "stemd/runtime/actuation_counters.hpp"

namespace stemd::runtime {

class OdometryInput {
public:
    OdometryInput(const ActuationConfig& config, ActuationCounters& counters);

    // A frame's odometer (NaN: the frame has none) at its capture. Also
    // where a constant speed starts and what says it is in use.
    void add_frame(std::int64_t t_sample_ns, double odom_mm) noexcept;
    // The encoder's tick count, read at now_ns (odometry.source encoder).
    void add_encoder(std::int64_t now_ns, std::int64_t ticks) noexcept;
    // An ODOMETRY frame's 32-bit odometer (wraps), received at t_rx_ns
    // (odometry.source can).
    void add_can(std::int64_t t_rx_ns, std::uint32_t odom_raw_mm) noexcept;

    // False without a usable reading (none yet, stale).
    bool odometer_at(std::int64_t t_ns, double& odom_mm) const noexcept;
    // The odometer at a frame's capture, given the frame's own odom_mm:
    // when that column is the source (recording, or auto once frames carry
    // it), a frame without it has none. A recording leaves the cell empty
    // where the odometer was not known (stemd-record), so the replay does
    // not guess one either.
    bool frame_odometer(std::int64_t t_sample_ns, double frame_odom_mm, double& odom_mm) const noexcept;
    double speed_mm_per_s() const noexcept;
    // True when t_ns is not past the newest sample (a constant speed covers
    // every instant): odometer_at(t_ns) then interpolates, it does not guess.
    bool covers(std::int64_t t_ns) const noexcept;

private:
    void push(const geometry::OdomSample& sample) noexcept;

    const OdometrySource source_;
    const double speed_mm_per_s_;          // odometry.speed_mm_per_s (constant)
    const double encoder_mm_per_tick_;
    ActuationCounters& counters_;
    geometry::OdometryRing ring_;
    std::int64_t constant_t0_ns_ = -1;
    bool constant_now_ = false;       // the last frame's odometer came from the constant speed
    bool frames_carry_odom_ = false;  // auto: a frame has carried odom_mm
    // The first refused sample below the newest reading (-1: none since the
    // last accepted one): from then on the odometer is not extrapolated at
    // the speed it had before the machine turned back.
    std::int64_t going_back_since_ns_ = -1;
    geometry::OdometerUnwrap can_odom_;
};

}  // namespace stemd::runtime
