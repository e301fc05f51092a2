#include "stemd/runtime/status.hpp"

#include <time.h>

#include <algorithm>

#include <spdlog/fmt/fmt.h>

#include "stemd/geometry/georef.hpp"
#include "stemd/protocol/messages.hpp"

namespace stemd::runtime {

namespace {

std::string drops(const StatusSnapshot& now, const StatusSnapshot& before)
{
    return fmt::format("drops: ring_full {}, overwritten {}, results_full {}, corrupt {}, bad_size {}, failed {}",
                       now.ring_full - before.ring_full, now.overwritten - before.overwritten,
                       now.results_full - before.results_full, now.corrupt - before.corrupt,
                       now.bad_size - before.bad_size, now.failed - before.failed);
}

std::string source(const StatusSnapshot& now, const StatusSnapshot& before)
{
    return fmt::format(" | source: timeouts {}, errors {}, reopens {}", now.source_timeouts - before.source_timeouts,
                       now.source_errors - before.source_errors, now.source_reopens - before.source_reopens);
}

std::string trigger(const StatusSnapshot& now, const StatusSnapshot& before)
{
    if (!now.trigger)
        return "";
    return fmt::format(" | trigger: pulses {}, late {}, failed {}", now.trigger_pulses - before.trigger_pulses,
                       now.trigger_late - before.trigger_late, now.trigger_failed - before.trigger_failed);
}

std::string files(const StatusSnapshot& now, const StatusSnapshot& before)
{
    if (!now.files)
        return "";
    return fmt::format(" | files: lines written {}, lost {}", now.file_lines_written - before.file_lines_written,
                       now.file_lines_lost - before.file_lines_lost);
}

// What was seen but not reported, and how far a paced replay fell behind
// (the worst lateness is the whole run's).
std::string behind(const StatusSnapshot& now, const StatusSnapshot& before)
{
    return fmt::format("over_capacity {}, late {} (worst {:.1f} ms)", now.over_capacity - before.over_capacity,
                       now.late - before.late, now.worst_lateness_ms);
}

std::string actuation(const StatusSnapshot& now, const StatusSnapshot& before)
{
    if (!now.actuation)
        return "";
    return fmt::format(" | targets {}, sent {}, deadline_misses {}, not_treated {} (tools not ready {}), no_odometry {}, "
                       "bus_errors {}, heartbeat_errors {}, heartbeat_misses {}, bad_class {}",
                       now.targets - before.targets, now.sent - before.sent,
                       now.deadline_misses - before.deadline_misses, now.not_treated - before.not_treated,
                       now.not_ready - before.not_ready,
                       now.no_odometry - before.no_odometry, now.bus_errors - before.bus_errors,
                       now.heartbeat_errors - before.heartbeat_errors, now.heartbeat_misses - before.heartbeat_misses,
                       now.bad_class - before.bad_class);
}

std::string odometry(const StatusSnapshot& now, const StatusSnapshot& before)
{
    const std::uint64_t going_back = now.odometry_going_back - before.odometry_going_back;
    if (now.odometry_can)
        return fmt::format(" | odometry: rx {}, going back {}", now.rx_odometry - before.rx_odometry, going_back);
    if (now.odometry_encoder)
        return fmt::format(" | odometry: going back {}", going_back);
    return "";
}

// What the tool controller said last: a state, the same in the interval's
// line and the summary.
std::string tool_controller(const StatusSnapshot& s)
{
    if (!s.tool_status)
        return "";
    const std::string_view name = protocol::tool_error_name(s.tool_error_code);
    return fmt::format(" | tool controller: ready 0x{:04X}, error {} ({}), TOOL_STATUS {:.0f} ms ago",
                       s.tools_ready_mask, s.tool_error_code, name.empty() ? "unnamed" : name,
                       s.tool_status_age_ms);
}

std::string can(const StatusSnapshot& now, const StatusSnapshot& before)
{
    if (!now.can_interface)
        return "";
    return fmt::format(" | can: late on the wire {}, unconfirmed {}, waited {}, bus_off {}, error_passive {}",
                       now.can_tx_late - before.can_tx_late, now.can_tx_unconfirmed - before.can_tx_unconfirmed,
                       now.can_tx_waits - before.can_tx_waits, now.can_bus_off - before.can_bus_off,
                       now.can_error_passive - before.can_error_passive);
}

// Tool timing, whole run: per tool that fired or leads its commands, e.g.
// " | tool 0: fired 12, lag 55.6 mm 40.0 ms (p95 56.0 mm 40.25 ms), strike p95 1.0 mm, latency 40.0 ms learned".
std::string tool_timing(const StatusSnapshot& s)
{
    if (!s.actuation)
        return "";
    std::string out;
    for (std::size_t i = 0; i < s.n_tools && i < s.tool_timing.size(); ++i) {
        const StatusSnapshot::ToolTiming& t = s.tool_timing[i];
        if (t.fired == 0 && t.latency_ms == 0 && !t.learning)
            continue;
        out += fmt::format(" | tool {}: fired {}, lag {:.1f} mm {:.1f} ms (p95 {:.1f} mm {:.2f} ms), strike p95 "
                           "{:.2f} mm, latency {:.1f} ms{}",
                           static_cast<unsigned>(t.tool_id), t.fired, t.lag_mean_mm, t.lag_mean_ms, t.lag_p95_mm,
                           t.lag_p95_ms, t.strike_p95_mm, t.latency_ms, t.learning ? " learned" : "");
    }
    if (s.rx_tool_fired > 0 || s.compensation_misses > 0)
        out += fmt::format(" | fired_unmatched {}, compensation_misses {}", s.fired_unmatched, s.compensation_misses);
    return out;
}

std::string gnss(const StatusSnapshot& s)
{
    if (!s.gnss)
        return "";
    const std::string_view mode = geometry::mode_name(s.gnss_mode);
    const std::string_view status = geometry::status_name(s.gnss_status);
    const std::string eph = s.gnss_eph_mm < 0 ? std::string("eph unknown")
                                              : fmt::format("eph {:.1f} mm{}", s.gnss_eph_mm,
                                                            s.gnss_eph_mm > s.gnss_max_eph_mm ? " over gnss.max_eph_mm" : "");
    return fmt::format(" | gnss: {} {}, {}, fixes {}, degraded {}", mode, status, eph, s.gnss_fixes, s.gnss_degraded);
}

std::string class_socket(const StatusSnapshot& now, const StatusSnapshot& before)
{
    if (!now.class_socket)
        return "";
    return fmt::format(" | classes: maps {}, class_timeouts {}, bad_messages {}, peers {}",
                       now.class_maps - before.class_maps, now.class_timeouts - before.class_timeouts,
                       now.class_bad_messages - before.class_bad_messages, now.class_peers - before.class_peers);
}

// The in-box model's weed targets beyond each plant's own stem, and the
// vegetated cells its budget (classify.max_cells) left unclassified.
std::string class_model(const StatusSnapshot& now, const StatusSnapshot& before)
{
    if (!now.class_model)
        return "";
    return fmt::format(" | weed targets: parts {}, stemless {}, cover {} | cells over budget {} in {} frames",
                       now.weed_parts - before.weed_parts, now.stemless_weeds - before.stemless_weeds,
                       now.weed_cover - before.weed_cover, now.cells_over_budget - before.cells_over_budget,
                       now.frames_over_budget - before.frames_over_budget);
}

std::string durations(const StatusSnapshot& s)
{
    std::string out = fmt::format("latency p50 {:.2f} p99 {:.2f} ms | pipeline p50 {:.2f} p99 {:.2f} ms",
                                  s.latency.p50_ms, s.latency.p99_ms, s.pipeline.p50_ms, s.pipeline.p99_ms);
    if (s.actuation)
        out += fmt::format(" | capture to send p50 {:.2f} p99 {:.2f} max {:.2f} ms", s.send.p50_ms, s.send.p99_ms,
                           s.send.max_ms);
    return out;
}

}  // namespace

std::string format_status(const StatusSnapshot& now, const StatusSnapshot& before)
{
    const double dt_s = std::max(1e-9, static_cast<double>(now.t_ns - before.t_ns) / 1e9);
    return fmt::format("in {:.1f} fps, out {:.1f} fps, bare soil {}, ",
                       static_cast<double>(now.frames_in - before.frames_in) / dt_s,
                       static_cast<double>(now.frames_out - before.frames_out) / dt_s,
                       now.no_vegetation - before.no_vegetation)
           + behind(now, before) + " | " + drops(now, before) + source(now, before) + trigger(now, before) + files(now, before) + actuation(now, before) + odometry(now, before) + tool_controller(now) + can(now, before) + class_socket(now, before) + class_model(now, before) + " | "
           + durations(now) + tool_timing(now) + gnss(now);
}

std::string format_latency_changes(const StatusSnapshot& now, const StatusSnapshot& before)
{
    std::string out;
    for (std::size_t i = 0; i < now.n_tools && i < now.tool_timing.size(); ++i) {
        const StatusSnapshot::ToolTiming& t = now.tool_timing[i];
        const double was = i < before.n_tools ? before.tool_timing[i].latency_ms : t.latency_ms;
        if (t.latency_ms == was)
            continue;
        out += fmt::format("{}tool {}: latency {:.1f} ms ({}, was {:.1f} ms)", out.empty() ? "" : "; ",
                           static_cast<unsigned>(t.tool_id), t.latency_ms, t.learning ? "learned" : "set", was);
    }
    return out;
}

std::string format_summary(const StatusSnapshot& end, double run_s)
{
    return fmt::format("{} frames in, {} out, {} stems in {:.2f} s ({:.1f} fps out), {} bare soil, ", end.frames_in,
                       end.frames_out, end.stems_out, run_s,
                       run_s > 0 ? static_cast<double>(end.frames_out) / run_s : 0.0, end.no_vegetation)
           + behind(end, StatusSnapshot{}) + " | " + drops(end, StatusSnapshot{}) + source(end, StatusSnapshot{})
           + trigger(end, StatusSnapshot{}) + files(end, StatusSnapshot{}) + actuation(end, StatusSnapshot{}) + odometry(end, StatusSnapshot{}) + tool_controller(end) + can(end, StatusSnapshot{}) + class_socket(end, StatusSnapshot{}) + class_model(end, StatusSnapshot{}) + " | " + durations(end) + tool_timing(end) + gnss(end);
}

}  // namespace stemd::runtime
