// Deadline scheduling of targets: which tool and lane treats a plant, at
// which odometer reading, and whether its command can still be on time.
//
// Everything is scheduled by distance travelled. A tool mounted offset_mm
// behind the camera's principal point is over a plant at s_mm when the
// odometer reads fire_odom_mm = s_mm + offset_mm (README, "Machine frame and
// field coordinates"). The command must reach the tool controller at least
// lead_ms before the plant arrives, and putting it on the bus takes up to
// send_budget_ms. A tool that takes latency_ms to act is commanded earlier
// by compensation_mm(v, latency_ms) = v × latency_ms (fire_lag.hpp; 0 when
// standing): fire_odom_mm = aim_odom_mm - v × latency_ms, with aim_odom_mm =
// s_mm + offset_mm, so that the strike lands on the stem at any speed. The
// deadline is the command's, at the compensated point. With
// d = fire_odom_mm - odom_mm (mm still to travel) and v = speed_mm_per_s:
//   - d < 0: the fire position has passed: deadline miss.
//   - v <= standing_speed_mm_per_s (standing, creeping, or reversing): no
//     deadline pressure, the command is on time; its bus deadline is
//     now + standing_deadline_ms.
//   - otherwise time_to_arrival_ms = d / v * 1000; if it is less than
//     lead_ms + send_budget_ms the target is a deadline miss: counted, never
//     sent late. Else it is sent, and must be on the bus by
//     deadline_ns = now_ns + (time_to_arrival_ms - lead_ms) ms
//     (the value for CanBus::send). The comparison is done on distances
//     (d * 1000 < (lead_ms + send_budget_ms) * v), so that the boundary is
//     exact: "just enough" is sent.
//
// schedule() checks, in this order, and counts the first reason a target
// is not sent:
//   1. policy: weeds_only sends only targets classed Weed (a crop or an
//      unclassified plant is never treated); all sends every class.
//   2. no tool: no tool's lateral span [y_min_mm, y_max_mm] covers y_mm
//      (or y_mm is not finite, or the command would not encode: |lateral|
//      beyond 2047 mm).
//   3. disabled: the enable input is inactive.
//   4. not ready: no tool covering y_mm is ready (its bit in the tool
//      controller's TOOL_STATUS tools_ready_mask is clear).
//   5. deadline: as above. When several ready tools cover y_mm they are
//      tried in table order and the first that can be on time is chosen; a
//      miss means none could. A miss that the first tool could have made without
//      its compensation is also counted as compensation_misses: the
//      compensation moved its point into the past or too close. Such a
//      command is dropped, never sent late.
// Lane within a tool: lane_width = (y_max - y_min) / lanes,
// lane = floor((y - y_min) / lane_width), y == y_max being in the last lane.
//
// Nothing allocates after construction; nothing throws. Single-threaded.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "stemd/protocol/messages.hpp"
#include "stemd/actuation/tracker.hpp"

namespace stemd::actuation {

inline constexpr double kMaxLatencyMs = 1000.0;  // a tool's latency_ms and its learning bounds

struct ToolSpec {
    std::uint8_t id = 0;       // TARGET tool_id, 0..15
    double offset_mm = 0;      // behind the principal point (>= 0 for a tool behind the camera)
    double y_min_mm = 0;       // lateral span, machine y (left > 0)
    double y_max_mm = 0;       // > y_min_mm
    std::uint8_t lanes = 1;    // nozzles across the span, 1..16 (1 for a stamp)
    // Time from the odometer reaching fire_odom_mm to the strike taking
    // effect: commands go out earlier by speed × latency_ms.
    double latency_ms = 0;     // 0..1000
    // Learn latency_ms from the measured lag (TOOL_FIRED), within
    // [latency_min_ms, latency_max_ms] (the runtime does; see fire_lag.hpp).
    bool learn_latency = false;
    double latency_min_ms = 0;
    double latency_max_ms = 200;
};

enum class TreatPolicy : std::uint8_t { weeds_only, all };
std::string_view to_string(TreatPolicy p);
std::optional<TreatPolicy> parse_treat_policy(std::string_view s);  // "weeds_only", "all"

struct SchedulerParams {
    double lead_ms = 20.0;                 // the command is at the tool at least this long before arrival
    double send_budget_ms = 2.0;           // worst-case time to get it onto the bus
    double standing_speed_mm_per_s = 1.0;  // at or below: standing, no deadline pressure
    double standing_deadline_ms = 100.0;   // bus deadline when standing
    TreatPolicy policy = TreatPolicy::weeds_only;
};

enum class ScheduleOutcome : std::uint8_t { send, policy, no_tool, disabled, not_ready, deadline_miss };
std::string_view to_string(ScheduleOutcome o);

// What the actuator thread knows when it schedules.
struct ScheduleNow {
    std::int64_t now_ns = 0;        // CLOCK_MONOTONIC
    double odom_mm = 0;             // the odometer now (geometry scale, monotonic)
    double speed_mm_per_s = 0;
    bool enabled = false;           // the enable input
    // Bit n set: tool n may be commanded (the tool controller's
    // TOOL_STATUS); every bit while its readiness is not known.
    std::uint16_t tools_ready_mask = 0xFFFF;
};

struct ScheduleDecision {
    ScheduleOutcome outcome = ScheduleOutcome::policy;
    // send: ready for protocol::encode. Other outcomes: tool, lane and
    // fire position as far as they were determined (for logs).
    protocol::TargetCommand command;
    double aim_odom_mm = 0;          // s_mm + offset_mm: the stem under the tool
    double lead_mm = 0;              // the latency's compensation (0 when standing)
    double fire_odom_mm = 0;         // aim_odom_mm - lead_mm, unrounded: the commanded point
    double time_to_arrival_ms = 0;   // +inf when standing
    std::int64_t deadline_ns = 0;    // send: on the bus by then (CanBus::send)
    bool compensation_miss = false;  // deadline_miss: on time without the latency lead
    bool ok() const { return outcome == ScheduleOutcome::send; }
};

struct SchedulerCounters {
    std::uint64_t scheduled = 0;  // schedule() calls
    std::uint64_t sent = 0;       // decisions to send
    std::uint64_t policy = 0;
    std::uint64_t no_tool = 0;
    std::uint64_t disabled = 0;
    std::uint64_t not_ready = 0;
    std::uint64_t deadline_misses = 0;
    std::uint64_t compensation_misses = 0;  // of deadline_misses: on time without the compensation
};

class Scheduler {
public:
    static constexpr std::size_t kMaxTools = protocol::kMaxToolId + 1;

    // nullopt with `error` set when the table or the parameters are invalid:
    // no tools, more than 16, an id > 15 or repeated, an empty or non-finite
    // span, lanes outside 1..16, a non-finite offset, negative lead or budget,
    // a latency outside 0..1000 ms or (learning) outside its bounds.
    static std::optional<Scheduler> make(std::span<const ToolSpec> tools, const SchedulerParams& params,
                                         std::string_view* error = nullptr);

    ScheduleDecision schedule(const Target& target, const ScheduleNow& now) noexcept;
    // A tool's latency from now on (a learned one), clamped to 0..1000 ms;
    // false if no tool has that id or the value is not finite.
    bool set_latency_ms(std::uint8_t tool_id, double latency_ms) noexcept;

    std::span<const ToolSpec> tools() const { return {tools_.data(), n_tools_}; }
    const SchedulerParams& params() const { return params_; }
    const SchedulerCounters& counters() const { return counters_; }

private:
    Scheduler() = default;

    std::array<ToolSpec, kMaxTools> tools_{};
    std::size_t n_tools_ = 0;
    SchedulerParams params_;
    SchedulerCounters counters_;
};

}  // namespace stemd::actuation
