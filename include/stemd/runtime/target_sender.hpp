// New targets to TARGET commands: Scheduler::schedule with the odometer
// and speed NOW (not at capture) and the enable input; a target that cannot
// be on time is a deadline miss, counted and never sent. Sent ones are
// encoded (E2E counter + CRC) and given to CanBus::send with their
// deadline; the bus never sends after it (counted as bus_deadline). What
// became of each target is kept by target_id for the plant map. No
// allocation, locks or exceptions after construction.
#pragma once

#include <array>
#include <cstdint>
#include <optional>

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
                 ActuationCounters& counters);

    // True when the bus took the TARGET frame.
    bool schedule(const actuation::Target& target, std::int64_t now_ns, bool class_map, bool enabled) noexcept;
    // What became of target_id's last target.
    const MapEntry& outcome(std::uint16_t target_id) const { return outcomes_[target_id]; }

private:
    actuation::Scheduler scheduler_;
    std::optional<actuation::Scheduler> scheduler_all_;
    drivers::CanBus& bus_;
    const protocol::CanIds ids_;
    const OdometryInput& odometry_;
    ActuationCounters& counters_;
    protocol::E2eCounter target_counter_;
    std::array<MapEntry, protocol::kMaxTargetId + 1> outcomes_{};
};

}  // namespace stemd::runtime
