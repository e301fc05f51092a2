// What the actuator's parts count, for the status line and the heartbeat.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

#include "stemd/runtime/duration_histogram.hpp"

namespace stemd::runtime {

// One tool's timing (tool timing, fire_lag.hpp), whole run: written by the
// actuator thread after each TOOL_FIRED, read by the status line.
struct ToolTimingCounters {
    std::atomic<bool> configured{false};
    std::atomic<std::uint8_t> tool_id{0};
    std::atomic<bool> learning{false};
    std::atomic<double> latency_ms{0};       // applied now (configured or learned)
    std::atomic<std::uint64_t> fired{0};     // TOOL_FIRED matched to a TARGET
    std::atomic<double> lag_mean_mm{0}, lag_p95_mm{0};
    std::atomic<double> lag_mean_ms{0}, lag_p95_ms{0};
    std::atomic<double> strike_p95_mm{0};    // |fired - aim|: how far from the stem
};

// Written by the actuator thread only (relaxed atomics), read by the status line.
struct ActuationCounters {
    std::atomic<std::uint64_t> frames{0};           // frames whose stems were tracked
    std::atomic<std::uint64_t> no_odometry{0};      // frames not actuated: no usable odometer reading
    std::atomic<std::uint64_t> off_ground{0};       // stems the camera model could not put on the ground
    std::atomic<std::uint64_t> clipped{0};          // plants cut by the leading/trailing border, not tracked
    std::atomic<std::uint64_t> targets{0};          // plants confirmed (one target each)
    std::atomic<std::uint64_t> sent{0};             // TARGET frames the bus took
    std::atomic<std::uint64_t> policy{0};           // targets not treated by policy (crops, unclassified)
    std::atomic<std::uint64_t> no_tool{0};          // no tool covers the plant's y
    std::atomic<std::uint64_t> disabled{0};         // the enable input was inactive
    std::atomic<std::uint64_t> not_ready{0};        // no tool covering the plant was ready (TOOL_STATUS)
    std::atomic<std::uint64_t> deadline_misses{0};  // could not be on time: never sent
    std::atomic<std::uint64_t> bus_deadline{0};     // the bus could not take it before its deadline: never sent
    std::atomic<std::uint64_t> bus_errors{0};       // TARGETs that could not be encoded or sent
    std::atomic<std::uint64_t> heartbeats{0};
    std::atomic<std::uint64_t> heartbeat_errors{0}; // HEARTBEATs that could not be encoded or sent
    std::atomic<std::uint64_t> heartbeat_misses{0}; // HEARTBEAT periods that passed without their HEARTBEAT
    std::atomic<std::uint64_t> rx_odometry{0};      // ODOMETRY frames accepted
    std::atomic<std::uint64_t> rx_tool_status{0};   // TOOL_STATUS frames accepted
    std::atomic<std::uint64_t> rx_tool_fired{0};    // TOOL_FIRED frames accepted (known tool)
    std::atomic<std::uint64_t> fired_unmatched{0};  // TOOL_FIRED for no TARGET sent (or reported twice)
    std::atomic<std::uint64_t> compensation_misses{0};  // deadline misses only because of a tool's latency lead
    std::atomic<std::uint64_t> rx_rejected{0};      // received frames rejected: E2E (CRC, counter) or decode
    std::atomic<std::uint64_t> odometry_going_back{0};  // samples below the newest (reversing): refused
    std::atomic<std::uint64_t> map_errors{0};
    // The last TOOL_STATUS: its tools_ready_mask and error_code, and when it
    // came (CLOCK_MONOTONIC; rx_tool_status says whether one did).
    std::atomic<std::uint64_t> tools_ready_mask{0};
    std::atomic<std::uint64_t> tool_error_code{0};
    std::atomic<std::int64_t> tool_status_rx_ns{0};
    // Capture (t_sample_ns of the frame that confirmed the plant) to the
    // moment its TARGET was decided and handed to the bus (the now_ns the
    // deadline was checked against): the whole chain's latency.
    DurationHistogram send_latency;
    // Per tool, in the tools table's order.
    std::array<ToolTimingCounters, 16> tool_timing;
};

}  // namespace stemd::runtime
