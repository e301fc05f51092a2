#include "stemd/runtime/can_link.hpp"

#include "stemd/runtime/status.hpp"

namespace stemd::runtime {

protocol::DaemonState heartbeat_state(const HeartbeatInputs& in) noexcept
{
    if (in.camera_lost)
        return protocol::DaemonState::CameraLost;
    if (!in.frames_seen)
        return protocol::DaemonState::Starting;
    if (!in.enabled || !in.odometry)
        return protocol::DaemonState::Idle;
    if (in.new_misses)
        return protocol::DaemonState::Degraded;
    return protocol::DaemonState::Active;
}

CanLink::CanLink(drivers::CanBus& bus, protocol::CanIds ids, std::int64_t heartbeat_interval_ns,
                 OdometryInput& odometry, TargetSender& sender, ActuationCounters& counters)
    : bus_(bus),
      ids_(ids),
      heartbeat_interval_ns_(heartbeat_interval_ns),
      odometry_(odometry),
      sender_(sender),
      counters_(counters),
      odometry_checker_(ids.id(protocol::MessageKind::Odometry), 3),
      tool_status_checker_(ids.id(protocol::MessageKind::ToolStatus), 3),
      tool_fired_checker_(ids.id(protocol::MessageKind::ToolFired), 3)
{
}

void CanLink::receive() noexcept
{
    protocol::CanFrame frame;
    std::int64_t t_rx_ns = 0;
    for (int i = 0; i < 64 && bus_.receive(frame, 0, t_rx_ns); ++i) {
        const auto kind = ids_.kind_of(frame);
        if (!kind)
            continue;   // not one of ours (the socket filter normally keeps these out)
        if (*kind == protocol::MessageKind::Odometry) {
            protocol::Odometry m;
            if (!accepted(frame, odometry_checker_, m))
                continue;
            bump(counters_.rx_odometry);
            odometry_.add_can(t_rx_ns, m.odom_mm);
        } else if (*kind == protocol::MessageKind::ToolStatus) {
            protocol::ToolStatus m;
            if (!accepted(frame, tool_status_checker_, m))
                continue;
            counters_.tools_ready_mask.store(m.tools_ready_mask, std::memory_order_relaxed);
            counters_.tool_error_code.store(m.error_code, std::memory_order_relaxed);
            counters_.tool_status_rx_ns.store(t_rx_ns, std::memory_order_relaxed);
            // Last: a reader that sees the count sees the values above.
            counters_.rx_tool_status.fetch_add(1, std::memory_order_release);
            sender_.on_tool_status(m, t_rx_ns);
        } else if (*kind == protocol::MessageKind::ToolFired) {
            protocol::ToolFired m;
            if (!accepted(frame, tool_fired_checker_, m))
                continue;
            switch (sender_.on_fired(m, odometry_.speed_mm_per_s())) {
            case TargetSender::Fired::matched: bump(counters_.rx_tool_fired); break;
            case TargetSender::Fired::unmatched:
                bump(counters_.rx_tool_fired);
                bump(counters_.fired_unmatched);
                break;
            case TargetSender::Fired::unknown_tool: bump(counters_.rx_rejected); break;
            }
        }
    }
}

template <typename Message>
bool CanLink::accepted(const protocol::CanFrame& frame, protocol::E2eChecker& checker, Message& out) noexcept
{
    if (!protocol::decode_checked(frame, checker, ids_, out)) {
        bump(counters_.rx_rejected);
        return false;
    }
    return true;
}

void CanLink::heartbeat_if_due(std::int64_t now_ns, bool frames_seen, bool camera_lost, bool enabled) noexcept
{
    if (now_ns >= next_heartbeat_ns_)
        heartbeat(now_ns, frames_seen, camera_lost, enabled);
}

void CanLink::heartbeat(std::int64_t now_ns, bool frames_seen, bool camera_lost, bool enabled) noexcept
{
    // On a fixed grid (10 Hz stays 10 Hz however late a poll comes); a
    // heartbeat more than a period late is not caught up, and each period
    // that passed without one is a miss.
    const std::int64_t late_ns = next_heartbeat_ns_ == 0 ? 0 : now_ns - next_heartbeat_ns_;
    if (late_ns >= heartbeat_interval_ns_)
        counters_.heartbeat_misses.fetch_add(static_cast<std::uint64_t>(late_ns / heartbeat_interval_ns_),
                                             std::memory_order_relaxed);
    next_heartbeat_ns_ = next_heartbeat_ns_ == 0 || late_ns >= heartbeat_interval_ns_
        ? now_ns + heartbeat_interval_ns_
        : next_heartbeat_ns_ + heartbeat_interval_ns_;
    const std::uint64_t misses = counters_.deadline_misses.load(std::memory_order_relaxed) +
                                 counters_.bus_deadline.load(std::memory_order_relaxed);
    protocol::Heartbeat hb;
    double odom = 0;
    hb.state = heartbeat_state({.frames_seen = frames_seen,
                                .camera_lost = camera_lost,
                                .enabled = enabled,
                                .odometry = odometry_.odometer_at(now_ns, odom),
                                .new_misses = misses != misses_at_last_heartbeat_});
    misses_at_last_heartbeat_ = misses;
    hb.targets_sent = counters_.sent.load(std::memory_order_relaxed);
    hb.deadline_misses = misses;
    hb.targets_dropped = counters_.no_tool.load(std::memory_order_relaxed) +
                         counters_.disabled.load(std::memory_order_relaxed) +
                         counters_.not_ready.load(std::memory_order_relaxed) +
                         counters_.bus_errors.load(std::memory_order_relaxed);
    hb.rx_rejected = counters_.rx_rejected.load(std::memory_order_relaxed);
    protocol::CanFrame frame;
    // Heartbeat failures have their own counter: bus_errors goes out inside
    // targets_dropped and must count TARGETs only.
    if (!protocol::encode(hb, heartbeat_counter_.next(), ids_, frame)) {
        bump(counters_.heartbeat_errors);
        return;
    }
    if (bus_.send(frame, now_ns + heartbeat_interval_ns_) == drivers::SendResult::sent)
        bump(counters_.heartbeats);
    else
        bump(counters_.heartbeat_errors);
}

}  // namespace stemd::runtime
