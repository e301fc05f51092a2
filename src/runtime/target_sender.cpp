#include "stemd/runtime/target_sender.hpp"

#include "stemd/runtime/status.hpp"

namespace stemd::runtime {

namespace {

MapReason reason_of(actuation::ScheduleOutcome o)
{
    using actuation::ScheduleOutcome;
    switch (o) {
    case ScheduleOutcome::send: return MapReason::sent;
    case ScheduleOutcome::policy: return MapReason::policy;
    case ScheduleOutcome::no_tool: return MapReason::no_tool;
    case ScheduleOutcome::disabled: return MapReason::disabled;
    case ScheduleOutcome::deadline_miss: return MapReason::deadline_miss;
    }
    return MapReason::pending;
}

}  // namespace

TargetSender::TargetSender(actuation::Scheduler scheduler, std::optional<actuation::Scheduler> scheduler_all,
                           drivers::CanBus& bus, protocol::CanIds ids, const OdometryInput& odometry,
                           ActuationCounters& counters)
    : scheduler_(scheduler),
      scheduler_all_(scheduler_all),
      bus_(bus),
      ids_(ids),
      odometry_(odometry),
      counters_(counters)
{
}

bool TargetSender::schedule(const actuation::Target& target, std::int64_t now_ns, bool class_map,
                            bool enabled) noexcept
{
    MapEntry& entry = outcomes_[target.target_id];
    entry = MapEntry{};
    // The odometer and speed now (not at capture): the time the pipeline
    // took is already gone from the command's budget.
    double odom_now = 0;
    if (!odometry_.odometer_at(now_ns, odom_now)) {
        entry.reason = MapReason::no_odometry;
        bump(counters_.no_odometry);
        return false;
    }
    actuation::ScheduleNow now;
    now.now_ns = now_ns;
    now.odom_mm = odom_now;
    now.speed_mm_per_s = odometry_.speed_mm_per_s();
    now.enabled = enabled;
    actuation::Scheduler& scheduler = (scheduler_all_ && !class_map) ? *scheduler_all_ : scheduler_;
    const actuation::ScheduleDecision d = scheduler.schedule(target, now);
    entry.reason = reason_of(d.outcome);
    if (d.outcome != actuation::ScheduleOutcome::policy && d.outcome != actuation::ScheduleOutcome::no_tool) {
        entry.has_tool = true;
        entry.tool = d.command.tool_id;
        entry.lane = d.command.lane;
        entry.fire_odom_mm = d.fire_odom_mm;
    }
    switch (d.outcome) {
    case actuation::ScheduleOutcome::policy: bump(counters_.policy); return false;
    case actuation::ScheduleOutcome::no_tool: bump(counters_.no_tool); return false;
    case actuation::ScheduleOutcome::disabled: bump(counters_.disabled); return false;
    case actuation::ScheduleOutcome::deadline_miss: bump(counters_.deadline_misses); return false;
    case actuation::ScheduleOutcome::send: break;
    }
    protocol::CanFrame frame;
    if (!protocol::encode(d.command, target_counter_.next(), ids_, frame)) {
        // The scheduler keeps every field in range; count it if not.
        entry.reason = MapReason::bus_error;
        bump(counters_.bus_errors);
        return false;
    }
    switch (bus_.send(frame, d.deadline_ns)) {
    case drivers::SendResult::sent: bump(counters_.sent); return true;
    case drivers::SendResult::deadline_passed:
        entry.reason = MapReason::bus_deadline;
        bump(counters_.bus_deadline);
        break;
    case drivers::SendResult::error:
        entry.reason = MapReason::bus_error;
        bump(counters_.bus_errors);
        break;
    }
    return false;
}

}  // namespace stemd::runtime
