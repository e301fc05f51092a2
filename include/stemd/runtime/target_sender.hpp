// New targets to TARGET commands: Scheduler::schedule with the odometer
// and speed NOW (not at capture) and the enable input; a target that cannot
// be on time is a deadline miss, counted and never sent. Sent ones are
// encoded (E2E counter + CRC) and given to CanBus::send with their
// deadline; the bus never sends after it (counted as bus_deadline). What
// became of each target is kept by target_id for the plant map.
//
// Tool timing: on_fired() matches a TOOL_FIRED to its TARGET (target_id and
// tool_id), records the lag per tool (fire_lag.hpp) and publishes it to the
// counters; for a tool with learn_latency it learns the latency and gives it
// to the schedulers, so that the next commands lead by it.
//
// Tool readiness: a tool whose bit in the tool controller's last TOOL_STATUS
// tools_ready_mask is clear gets no TARGET (another ready tool covering the
// plant may; else it is counted not_ready). Until the first TOOL_STATUS
// every tool is taken as ready (a controller that never sends one); once
// the last is older than tool_status_timeout_ns (0: never), none is: a
// controller that fell silent cannot be counted on to strike. No allocation,
// locks or exceptions after construction.
#pragma once

#include <array>
#include <cstdint>
#include <optional>

#include "stemd/actuation/fire_lag.hpp"
#include "stemd/actuation/scheduler.hpp"
#include "stemd/actuation/tracker.hpp"
#include "stemd/drivers/can_bus.hpp"
#include "stemd/protocol/e2e.hpp"
#include "stemd/protocol/messages.hpp"
#include "stemd/runtime/actuation_counters.hpp"
#include "stemd/runtime/odometry_input.hpp"
#include "stemd/runtime/plant_map.hpp"

namespace stemd::runtime {

class TargetSender {
public:
    // scheduler_all (policy auto): the scheduler for frames without a class map.
    TargetSender(actuation::Scheduler scheduler, std::optional<actuation::Scheduler> scheduler_all,
                 drivers::CanBus& bus, protocol::CanIds ids, const OdometryInput& odometry,
                 ActuationCounters& counters, std::int64_t tool_status_timeout_ns);

    // True when the bus took the TARGET frame. `enable` is open while the
    // enable input is on: the scheduler reads it, and the bus checks it again
    // before it writes the frame, however long a full transmit queue kept
    // the frame waiting (a withdrawn frame is counted as disabled).
    bool schedule(const actuation::Target& target, std::int64_t now_ns, bool class_map,
                  drivers::SendGate enable) noexcept;
    // What became of target_id's last target.
    const MapEntry& outcome(std::uint16_t target_id) const { return outcomes_[target_id]; }

    enum class Fired : std::uint8_t { matched, unknown_tool, unmatched };
    // A TOOL_FIRED, with the odometry's speed now (the strike was moments ago).
    Fired on_fired(const protocol::ToolFired& fired, double speed_mm_per_s) noexcept;
    // A TOOL_STATUS, received at t_rx_ns (CLOCK_MONOTONIC).
    void on_tool_status(const protocol::ToolStatus& status, std::int64_t t_rx_ns) noexcept;
    // Bit n set: tool n may be commanded at now_ns (above).
    std::uint16_t tools_ready_mask(std::int64_t now_ns) const noexcept;
    // Whether the tool has reported a strike (TOOL_FIRED) in this run.
    bool reports_fired(std::uint8_t tool_id) const { return tool_id <= protocol::kMaxToolId && reports_fired_[tool_id]; }

private:
    actuation::Scheduler scheduler_;
    std::optional<actuation::Scheduler> scheduler_all_;
    drivers::CanBus& bus_;
    const protocol::CanIds ids_;
    const OdometryInput& odometry_;
    ActuationCounters& counters_;
    protocol::E2eCounter target_counter_;
    std::array<MapEntry, protocol::kMaxTargetId + 1> outcomes_{};
    // Per tool, in table order.
    std::array<actuation::LagStats, actuation::Scheduler::kMaxTools> lag_{};
    std::array<actuation::LatencyLearner, actuation::Scheduler::kMaxTools> learners_{};
    std::array<bool, protocol::kMaxToolId + 1> reports_fired_{};   // by tool id
    const std::int64_t tool_status_timeout_ns_;
    bool tool_status_seen_ = false;
    std::uint16_t tools_ready_mask_ = 0xFFFF;
    std::int64_t tool_status_rx_ns_ = 0;
};

}  // namespace stemd::runtime
