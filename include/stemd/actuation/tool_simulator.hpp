// A tool controller in software, for tests and stemd-toolsim: it executes
// TARGET commands against an odometer it is given, each strike taking effect
// delay_ms after the odometer reached the command's fire_odom_mm (a valve's
// or a stamp's latency), and reports where that was as a TOOL_FIRED.
//
// The odometer comes as samples (time, unwrapped mm) through advance(); a
// crossing of fire_odom_mm and the odometer at the strike are interpolated
// linearly between samples, so the reports do not depend on how often
// advance() is called. A command whose point the odometer has already
// passed when it arrives is not executed (counted: late), as a real
// controller would answer it with TARGET_LATE. No allocation after
// construction; nothing throws. Single-threaded.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "stemd/protocol/messages.hpp"

namespace stemd::actuation {

struct ToolSimCounters {
    std::uint64_t commands = 0;  // TARGETs taken
    std::uint64_t late = 0;      // their point had passed: not executed
    std::uint64_t full = 0;      // no room for another pending command
    std::uint64_t fired = 0;     // strikes reported
};

class ToolSimulator {
public:
    static constexpr std::size_t kMaxPending = 256;

    explicit ToolSimulator(double delay_ms) noexcept;

    // A TARGET received while the odometer read odom_mm (unwrapped); its
    // fire_odom_mm (modulo 2^18) is placed within ±131 m of it. False when
    // late or full (counted).
    bool command(const protocol::TargetCommand& target, double odom_mm) noexcept;
    // The odometer at t_ns (samples in time order). Returns the strikes that
    // took effect since the last call, valid until the next call.
    std::span<const protocol::ToolFired> advance(std::int64_t t_ns, double odom_mm) noexcept;

    const ToolSimCounters& counters() const noexcept { return counters_; }
    double delay_ms() const noexcept { return delay_ms_; }

private:
    struct Pending {
        bool used = false;
        bool triggered = false;
        protocol::TargetCommand command;
        double fire_mm = 0;         // unwrapped
        double trigger_t_ns = 0;    // when the odometer reached fire_mm
    };

    const double delay_ms_;
    std::array<Pending, kMaxPending> pending_{};
    std::array<protocol::ToolFired, kMaxPending> fired_{};
    bool have_sample_ = false;
    std::int64_t last_t_ns_ = 0;
    double last_odom_mm_ = 0;
    ToolSimCounters counters_;
};

}  // namespace stemd::actuation
