// The actuator's CAN traffic other than commands: received ODOMETRY (to the
// odometry input, at each frame's receive time), TOOL_STATUS and TOOL_FIRED
// (to the target sender's tool timing), E2E-checked (bad CRC or counter
// jumps are rejected and counted; so is a TOOL_FIRED of a tool not in the
// table), and the HEARTBEAT on
// a fixed grid of can.heartbeat_ms. No allocation, locks or exceptions.
#pragma once

#include <cstdint>

#include "stemd/drivers/can_bus.hpp"
#include "stemd/protocol/e2e.hpp"
#include "stemd/protocol/messages.hpp"
#include "stemd/runtime/actuation_counters.hpp"
#include "stemd/runtime/odometry_input.hpp"
#include "stemd/runtime/target_sender.hpp"

namespace stemd::runtime {

// What the actuator knows when a HEARTBEAT is due.
struct HeartbeatInputs {
    bool frames_seen = false;  // a frame's detections have reached the actuator
    // The source is reopening its camera, or no frame has come for
    // source.lost_after_ms.
    bool camera_lost = false;
    bool enabled = false;      // the enable input (always on without one)
    bool odometry = false;     // a usable odometer reading now
    bool new_misses = false;   // deadline misses since the previous HEARTBEAT
};

// The HEARTBEAT's state, first match: CameraLost (also before the first
// frame: a camera lost at start is still lost), Starting before the first
// frame, Idle when disabled or without odometry, Degraded after new deadline
// misses, else Active. Fault is never sent from these inputs.
protocol::DaemonState heartbeat_state(const HeartbeatInputs& in) noexcept;

class CanLink {
public:
    CanLink(drivers::CanBus& bus, protocol::CanIds ids, std::int64_t heartbeat_interval_ns, OdometryInput& odometry,
            TargetSender& sender, ActuationCounters& counters);

    // Whatever is queued, without waiting; bounded so a flooded bus cannot
    // starve the frames.
    void receive() noexcept;
    // Sends the HEARTBEAT when due, its state from heartbeat_state().
    void heartbeat_if_due(std::int64_t now_ns, bool frames_seen, bool camera_lost, bool enabled) noexcept;

private:
    // E2E-checked and decoded into `out`; else counted as rx_rejected.
    template <typename Message>
    bool accepted(const protocol::CanFrame& frame, protocol::E2eChecker& checker, Message& out) noexcept;
    void heartbeat(std::int64_t now_ns, bool frames_seen, bool camera_lost, bool enabled) noexcept;

    drivers::CanBus& bus_;
    const protocol::CanIds ids_;
    const std::int64_t heartbeat_interval_ns_;
    OdometryInput& odometry_;
    TargetSender& sender_;
    ActuationCounters& counters_;
    protocol::E2eCounter heartbeat_counter_;
    protocol::E2eChecker odometry_checker_, tool_status_checker_, tool_fired_checker_;
    std::int64_t next_heartbeat_ns_ = 0;
    std::uint64_t misses_at_last_heartbeat_ = 0;
};

}  // namespace stemd::runtime
