// Status counters of the daemon: members written by the one thread that
// owns them (relaxed atomics, so the status line can read them from
// anywhere), and the status line itself.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>

#include "stemd/runtime/duration_histogram.hpp"

namespace stemd::runtime {

// Adds to a counter that has one writer thread: a relaxed load-add-store is
// enough (readers only need a recent value) and cheaper than a locked
// read-modify-write.
inline void bump(std::atomic<std::uint64_t>& counter, std::uint64_t by = 1)
{
    counter.store(counter.load(std::memory_order_relaxed) + by, std::memory_order_relaxed);
}

// Every counter of the daemon, grouped by the thread that writes it.
struct Counters {
    struct Capture {
        std::atomic<std::uint64_t> frames{0};          // frames the source delivered
        std::atomic<std::uint64_t> timeouts{0};        // next() returned nothing in its whole timeout (not one cut short for a trigger pulse)
        std::atomic<std::uint64_t> backpressure_waits{0};  // fast replay: ring full, waited (not a drop)
        std::atomic<std::uint64_t> no_free_slot{0};    // never expected: the pool is sized so it cannot happen
        std::atomic<std::uint64_t> trigger_pulses{0};  // camera trigger pulses sent (gpio.trigger_line)
        std::atomic<std::uint64_t> trigger_late{0};    // trigger periods skipped: the thread came back too late
        std::atomic<std::uint64_t> trigger_failed{0};  // pulses due that did not go out (lines down or being reopened)
        DurationHistogram cycle;                       // a delivered frame: from next() returning to the ring push
    } capture;
    struct Processing {
        std::atomic<std::uint64_t> frames{0};          // frames detect() ran on
        std::atomic<std::uint64_t> failed{0};          // detect() status != ok (size, format, missing plane)
        std::atomic<std::uint64_t> no_vegetation{0};   // frames with no vegetation at all (bare soil)
        std::atomic<std::uint64_t> results_full{0};    // result ring full: result dropped
        std::atomic<std::uint64_t> plants_over_capacity{0};   // plants beyond vision::kMaxPlants in a frame
        DurationHistogram pipeline;                    // detect() wall time
        DurationHistogram cycle;                       // a frame's whole turn: detect, classes, live view copy
    } processing;
    struct Actuator {
        std::atomic<std::uint64_t> frames{0};          // results handed to the sink
        std::atomic<std::uint64_t> stems{0};           // plants with a stem (stemd-detect's rows)
        std::atomic<std::uint64_t> sink_errors{0};     // e.g. the CSV could not be written
        DurationHistogram latency;                     // t_sample_ns -> result received by the actuator
        DurationHistogram cycle;                       // a result's turn: sink, actuation
    } actuator;
};

// The numbers one status line shows, read at one moment.
struct StatusSnapshot {
    std::int64_t t_ns = 0;   // CLOCK_MONOTONIC when taken
    std::uint64_t frames_in = 0, frames_out = 0, stems_out = 0;
    // Drops by cause.
    std::uint64_t ring_full = 0;       // drop_newest: the new frame was dropped
    std::uint64_t overwritten = 0;     // overwrite_oldest: an old waiting frame was replaced
    std::uint64_t results_full = 0;    // result ring full
    std::uint64_t corrupt = 0;         // unreadable or undecodable frames (source)
    std::uint64_t bad_size = 0;        // frames not the slots' size (source)
    std::uint64_t failed = 0;          // detect() refused the frame
    std::uint64_t no_vegetation = 0;   // bare-soil frames (not a drop: nothing to see)
    std::uint64_t over_capacity = 0;   // plants beyond the 256 a frame holds (detected, not reported)
    std::uint64_t late = 0;            // paced replay: frames the source came to late
    double worst_lateness_ms = 0;      // paced replay: the most a frame was late (whole run)
    std::uint64_t bad_class = 0;       // plants with class-map values other than 0, 1, 2
    // classify.provider socket: class maps received, frames whose map came
    // too late or never (plants unknown), malformed messages dropped,
    // connections accepted.
    bool class_socket = false;
    std::uint64_t class_maps = 0, class_timeouts = 0, class_bad_messages = 0, class_peers = 0;
    // classify.provider model: weed targets added beside the plants' stems
    // (vision::add_weed_parts), by kind.
    bool class_model = false;
    std::uint64_t weed_parts = 0, stemless_weeds = 0, weed_cover = 0;
    // Vegetated cells classify.max_cells left unclassified, and the frames.
    std::uint64_t cells_over_budget = 0, frames_over_budget = 0;
    // The source's own: waits without a frame, failures (a camera unplugged),
    // successful reopens after one.
    std::uint64_t source_timeouts = 0, source_errors = 0, source_reopens = 0;
    // The camera trigger (gpio.trigger_line): pulses sent, periods skipped
    // for lateness, pulses that did not go out.
    bool trigger = false;
    std::uint64_t trigger_pulses = 0, trigger_late = 0, trigger_failed = 0;
    // The optional files (--detections-csv, --map) through the writer
    // thread: lines written, and lost (a failed write, or the writer's ring
    // full while the disk stalled).
    bool files = false;
    std::uint64_t file_lines_written = 0, file_lines_lost = 0;
    // Actuation (when a CAN side is configured).
    bool actuation = false;
    // not_ready (of not_treated): no tool covering the plant was ready (TOOL_STATUS).
    std::uint64_t not_ready = 0;
    std::uint64_t targets = 0, sent = 0, deadline_misses = 0, no_odometry = 0, not_treated = 0, bus_errors = 0,
                  heartbeat_errors = 0, heartbeat_misses = 0;
    // A live odometer (odometry.source can or encoder): ODOMETRY frames
    // taken (CAN), and samples refused for going back (the machine
    // reversing: no frame is actuated until the odometer passes its highest
    // reading again).
    bool odometry_can = false, odometry_encoder = false;
    std::uint64_t rx_odometry = 0, odometry_going_back = 0;
    // The tool controller's last TOOL_STATUS, once one came: its
    // tools_ready_mask, error_code, and how long ago it came.
    bool tool_status = false;
    std::uint16_t tools_ready_mask = 0;
    std::uint8_t tool_error_code = 0;
    double tool_status_age_ms = 0;
    // A SocketCAN interface (can.interface): TARGETs and HEARTBEATs that
    // reached the wire after their deadline, written ones the interface
    // never reported on the wire, sends that waited for the frame before to
    // leave, and the controller's bus-off and error-passive events.
    bool can_interface = false;
    std::uint64_t can_tx_late = 0, can_tx_unconfirmed = 0, can_tx_waits = 0, can_bus_off = 0, can_error_passive = 0;
    DurationHistogram::Summary latency;    // interval, or whole run for the final line
    DurationHistogram::Summary pipeline;
    DurationHistogram::Summary send;       // actuation: capture -> TARGET on the bus
    // Tool timing (whole run), per configured tool in table order.
    struct ToolTiming {
        std::uint8_t tool_id = 0;
        bool learning = false;
        double latency_ms = 0;
        std::uint64_t fired = 0;
        double lag_mean_mm = 0, lag_p95_mm = 0, lag_mean_ms = 0, lag_p95_ms = 0, strike_p95_mm = 0;
    };
    std::array<ToolTiming, 16> tool_timing{};
    std::size_t n_tools = 0;
    std::uint64_t rx_tool_fired = 0, fired_unmatched = 0, compensation_misses = 0;
    // GNSS (gnss.source set), whole run: the newest fix's mode, gpsd status
    // and horizontal error estimate (mm, < 0: unknown), and the plants
    // placed as georef degraded (eph above gnss.max_eph_mm).
    bool gnss = false;
    std::uint8_t gnss_mode = 0, gnss_status = 0;
    double gnss_eph_mm = -1, gnss_max_eph_mm = 0;
    std::uint64_t gnss_fixes = 0, gnss_degraded = 0;
};

// "in 30.0 fps, out 30.0 fps, bare soil 0, over_capacity 0, late 0 (worst 0.3 ms) |
//  drops: ring_full 0, overwritten 0, results_full 0, corrupt 1, bad_size 0, failed 0 |
//  source: timeouts 0, errors 0, reopens 0 |
//  latency p50 1.62 p99 2.31 ms | pipeline p50 1.35 p99 1.90 ms"
// With a camera trigger, " | trigger: pulses 300, late 0, failed 0" after the source's;
// with --detections-csv or --map, " | files: lines written 812, lost 0" after that.
// With GNSS, e.g. " | gnss: 3d rtk_fixed, eph 14.0 mm, fixes 812, degraded 0"
// ("eph 2400.0 mm over gnss.max_eph_mm" when the newest fix is above it).
std::string format_status(const StatusSnapshot& now, const StatusSnapshot& before);
// The run's totals for the last line: frames, drops, whole-run percentiles.
std::string format_summary(const StatusSnapshot& end, double run_s);
// "tool 0: latency 40.2 ms (learned, was 0.0 ms)" for each tool whose
// applied latency changed since `before`, "; "-separated; "" if none did.
std::string format_latency_changes(const StatusSnapshot& now, const StatusSnapshot& before);

}  // namespace stemd::runtime
