// The daemon's counters and histograms in the Prometheus text exposition
// format 0.0.4 (what /metrics serves). Pure formatting: the numbers are
// gathered by the caller (collect_metrics reads a running daemon).
//
// Names (all prefixed stemd_): frames_in_total, frames_out_total,
// stems_total, frames_late_total, frames_dropped_total{cause},
// deadline_misses_total, targets_confirmed_total, targets_total{outcome},
// bus_errors_total{frame}, no_odometry_frames_total,
// odometry_frames_total, odometer_samples_going_back_total, can_frames_total{outcome},
// can_send_waits_total, can_controller_events_total{state}, and the histograms
// capture_to_result_seconds, capture_to_send_seconds, pipeline_seconds and
// thread_cycle_seconds{thread}; live_* for the view itself.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "stemd/runtime/duration_histogram.hpp"

namespace stemd::runtime {
class Daemon;
}

namespace stemd::web {

// Upper bounds of the histograms' buckets (on the daemon's 50 us grid).
inline constexpr std::array<std::int64_t, 14> kBucketUpperNs = {
    500'000, 1'000'000, 2'000'000, 3'000'000, 4'000'000, 5'000'000, 7'500'000,
    10'000'000, 15'000'000, 20'000'000, 33'000'000, 50'000'000, 100'000'000, 200'000'000};

struct Histogram {
    std::array<std::uint64_t, kBucketUpperNs.size()> below{};   // cumulative, per bound
    std::uint64_t count = 0;                                   // the +Inf bucket
    double sum_s = 0;
};
Histogram histogram_of(const runtime::DurationHistogram& h);

struct Metrics {
    std::uint64_t frames_in = 0, frames_out = 0, stems = 0, late = 0;
    // frames_dropped_total{cause=...}
    std::uint64_t ring_full = 0, overwritten = 0, results_full = 0, corrupt = 0, bad_size = 0, failed = 0;
    bool actuation = false;   // the actuation's series are written only with it
    std::uint64_t targets = 0, sent = 0, policy = 0, no_tool = 0, disabled = 0, not_ready = 0, deadline_miss = 0,
                  bus_deadline = 0, bus_error = 0, heartbeat_errors = 0, heartbeat_misses = 0,
                  no_odometry = 0, rx_odometry = 0, odometry_going_back = 0;
    // The SocketCAN interface's series, written only with one.
    bool can_interface = false;
    std::uint64_t can_tx_late = 0, can_tx_unconfirmed = 0, can_tx_waits = 0, can_bus_off = 0, can_error_passive = 0;
    // Plants' classes: class-map windows with values above 2 (any provider);
    // the in-box model's weed targets beside the plants' stems and the cells
    // its budget left out; the socket provider's maps, late maps, bad
    // messages and peers. Each group is written only with its provider.
    std::uint64_t bad_class = 0;
    bool class_model = false;
    std::uint64_t weed_parts = 0, stemless_weeds = 0, weed_cover = 0, cells_over_budget = 0, frames_over_budget = 0;
    bool class_socket = false;
    std::uint64_t class_maps = 0, class_timeouts = 0, class_bad_messages = 0, class_peers = 0;
    // The camera trigger's pulses by outcome, with a trigger line.
    bool trigger = false;
    std::uint64_t trigger_pulses = 0, trigger_late = 0, trigger_failed = 0;
    // The optional files' lines by outcome, with --detections-csv or --map.
    bool files = false;
    std::uint64_t file_lines_written = 0, file_lines_lost = 0;
    Histogram capture_to_result, capture_to_send, pipeline;
    Histogram cycle_capture, cycle_processing, cycle_actuator;
    // The live view.
    std::uint64_t live_frames_published = 0, live_frames_encoded = 0, live_plants_dropped = 0, web_requests = 0;
    std::uint64_t web_unauthorized = 0;   // control requests without the right token
};

// Everything but the live_* numbers, from a running daemon; any thread
// (whole-run totals: the status line's intervals are left alone).
Metrics collect_metrics(runtime::Daemon& daemon);

std::string format_metrics(const Metrics& m);

}  // namespace stemd::web
