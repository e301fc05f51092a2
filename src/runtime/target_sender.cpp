#include "stemd/runtime/target_sender.hpp"

#include <cmath>

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
    case ScheduleOutcome::not_ready: return MapReason::not_ready;
    case ScheduleOutcome::deadline_miss: return MapReason::deadline_miss;
    }
    return MapReason::pending;
}

}  // namespace

TargetSender::TargetSender(actuation::Scheduler scheduler, std::optional<actuation::Scheduler> scheduler_all,
                           drivers::CanBus& bus, protocol::CanIds ids, const OdometryInput& odometry,
                           ActuationCounters& counters, std::int64_t tool_status_timeout_ns)
    : scheduler_(scheduler),
      scheduler_all_(scheduler_all),
      bus_(bus),
      ids_(ids),
      odometry_(odometry),
      counters_(counters),
      tool_status_timeout_ns_(tool_status_timeout_ns)
{
    const auto tools = scheduler_.tools();
    for (std::size_t i = 0; i < tools.size(); ++i) {
        const actuation::ToolSpec& t = tools[i];
        learners_[i] = actuation::LatencyLearner(t.latency_ms, t.latency_min_ms, t.latency_max_ms);
        ToolTimingCounters& c = counters_.tool_timing[i];
        c.tool_id.store(t.id, std::memory_order_relaxed);
        c.learning.store(t.learn_latency, std::memory_order_relaxed);
        c.latency_ms.store(t.latency_ms, std::memory_order_relaxed);
        c.configured.store(true, std::memory_order_release);
    }
}

TargetSender::Fired TargetSender::on_fired(const protocol::ToolFired& fired, double speed_mm_per_s) noexcept
{
    const auto tools = scheduler_.tools();
    std::size_t slot = tools.size();
    for (std::size_t i = 0; i < tools.size(); ++i)
        if (tools[i].id == fired.tool_id)
            slot = i;
    if (slot == tools.size())
        return Fired::unknown_tool;
    MapEntry& e = outcomes_[fired.target_id];
    if (e.reason != MapReason::sent || !e.has_tool || e.tool != fired.tool_id || e.fired)
        return Fired::unmatched;
    const double lag_mm = protocol::fire_distance_mm(fired.fired_odom_mm, e.command_fire_raw);
    reports_fired_[fired.tool_id] = true;
    e.fired = true;
    e.fired_odom_mm = std::round(e.fire_odom_mm) + lag_mm;
    e.fire_lag_mm = lag_mm;
    e.fire_lag_ms = actuation::lag_ms_of(lag_mm, speed_mm_per_s);
    e.strike_mm = e.fired_odom_mm - e.aim_odom_mm;
    actuation::LagStats& stats = lag_[slot];
    stats.record(e.fire_lag_mm, e.fire_lag_ms, e.strike_mm);

    ToolTimingCounters& c = counters_.tool_timing[slot];
    if (tools[slot].learn_latency && learners_[slot].add(e.fire_lag_ms)) {
        const double learned = learners_[slot].latency_ms();
        scheduler_.set_latency_ms(fired.tool_id, learned);
        if (scheduler_all_)
            scheduler_all_->set_latency_ms(fired.tool_id, learned);
        c.latency_ms.store(learned, std::memory_order_relaxed);
    }
    const actuation::LagSummary sum = stats.summary();
    c.lag_mean_mm.store(sum.mean_mm, std::memory_order_relaxed);
    c.lag_p95_mm.store(sum.p95_mm, std::memory_order_relaxed);
    c.lag_mean_ms.store(sum.mean_ms, std::memory_order_relaxed);
    c.lag_p95_ms.store(sum.p95_ms, std::memory_order_relaxed);
    c.strike_p95_mm.store(sum.strike_p95_mm, std::memory_order_relaxed);
    bump(c.fired);
    return Fired::matched;
}

void TargetSender::on_tool_status(const protocol::ToolStatus& status, std::int64_t t_rx_ns) noexcept
{
    tool_status_seen_ = true;
    tools_ready_mask_ = status.tools_ready_mask;
    tool_status_rx_ns_ = t_rx_ns;
}

std::uint16_t TargetSender::tools_ready_mask(std::int64_t now_ns) const noexcept
{
    if (!tool_status_seen_)
        return 0xFFFF;
    if (tool_status_timeout_ns_ > 0 && now_ns - tool_status_rx_ns_ > tool_status_timeout_ns_)
        return 0;
    return tools_ready_mask_;
}

bool TargetSender::schedule(const actuation::Target& target, std::int64_t now_ns, bool class_map,
                            drivers::SendGate enable) noexcept
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
    now.enabled = enable.open();
    now.tools_ready_mask = tools_ready_mask(now_ns);
    actuation::Scheduler& scheduler = (scheduler_all_ && !class_map) ? *scheduler_all_ : scheduler_;
    const actuation::ScheduleDecision d = scheduler.schedule(target, now);
    entry.reason = reason_of(d.outcome);
    if (d.outcome != actuation::ScheduleOutcome::policy && d.outcome != actuation::ScheduleOutcome::no_tool) {
        entry.has_tool = true;
        entry.tool = d.command.tool_id;
        entry.lane = d.command.lane;
        entry.fire_odom_mm = d.fire_odom_mm;
        entry.command_fire_raw = d.command.fire_odom_mm;
        entry.aim_odom_mm = d.aim_odom_mm;
        entry.lead_mm = d.lead_mm;
    }
    switch (d.outcome) {
    case actuation::ScheduleOutcome::policy: bump(counters_.policy); return false;
    case actuation::ScheduleOutcome::no_tool: bump(counters_.no_tool); return false;
    case actuation::ScheduleOutcome::disabled: bump(counters_.disabled); return false;
    case actuation::ScheduleOutcome::not_ready: bump(counters_.not_ready); return false;
    case actuation::ScheduleOutcome::deadline_miss:
        bump(counters_.deadline_misses);
        if (d.compensation_miss)
            bump(counters_.compensation_misses);
        return false;
    case actuation::ScheduleOutcome::send: break;
    }
    protocol::CanFrame frame;
    if (!protocol::encode(d.command, target_counter_.next(), ids_, frame)) {
        // The scheduler keeps every field in range; count it if not.
        entry.reason = MapReason::bus_error;
        bump(counters_.bus_errors);
        return false;
    }
    switch (bus_.send(frame, d.deadline_ns, enable)) {
    case drivers::SendResult::sent: bump(counters_.sent); return true;
    case drivers::SendResult::withdrawn:
        entry.reason = MapReason::disabled;
        bump(counters_.disabled);
        break;
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
