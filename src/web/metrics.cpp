#include "stemd/web/metrics.hpp"

#include <cstdio>
#include <initializer_list>
#include <string_view>
#include <utility>

#include "stemd/runtime/daemon.hpp"

namespace stemd::web {

namespace {

class Text {
public:
    void family(std::string_view name, std::string_view type, std::string_view help)
    {
        out_.append("# HELP stemd_").append(name).append(" ").append(help).append("\n");
        out_.append("# TYPE stemd_").append(name).append(" ").append(type).append("\n");
    }
    // A counter family of one unlabelled sample.
    void counter(std::string_view name, std::string_view help, std::uint64_t value)
    {
        family(name, "counter", help);
        sample(name, "", value);
    }
    // A counter family of one sample per value of `label`.
    void counters(std::string_view name, std::string_view help, std::string_view label,
                  std::initializer_list<std::pair<std::string_view, std::uint64_t>> values)
    {
        family(name, "counter", help);
        for (const auto& [key, value] : values)
            sample(name, std::string(label) + "=\"" + std::string(key) + "\"", value);
    }
    void sample(std::string_view name, std::string_view labels, std::uint64_t value)
    {
        head(name, labels);
        out_.append(std::to_string(value)).append("\n");
    }
    void sample(std::string_view name, std::string_view labels, double value)
    {
        head(name, labels);
        char buffer[64];
        std::snprintf(buffer, sizeof buffer, "%.9g", value);
        out_.append(buffer).append("\n");
    }
    // One histogram's series; `labels` ("thread=\"capture\"") go before le.
    void histogram(std::string_view name, std::string_view labels, const Histogram& h)
    {
        const std::string bucket = std::string(name) + "_bucket";
        const std::string sep = labels.empty() ? "" : ",";
        for (std::size_t i = 0; i < kBucketUpperNs.size(); ++i) {
            char le[32];
            std::snprintf(le, sizeof le, "%.6g", static_cast<double>(kBucketUpperNs[i]) / 1e9);
            sample(bucket, std::string(labels) + sep + "le=\"" + le + "\"", h.below[i]);
        }
        sample(bucket, std::string(labels) + sep + "le=\"+Inf\"", h.count);
        sample(std::string(name) + "_sum", labels, h.sum_s);
        sample(std::string(name) + "_count", labels, h.count);
    }
    std::string take() { return std::move(out_); }

private:
    void head(std::string_view name, std::string_view labels)
    {
        out_.append("stemd_").append(name);
        if (!labels.empty())
            out_.append("{").append(labels).append("}");
        out_.append(" ");
    }
    std::string out_;
};

}  // namespace

Histogram histogram_of(const runtime::DurationHistogram& h)
{
    Histogram out;
    const auto c = h.cumulative(kBucketUpperNs, out.below);
    out.count = c.count;
    out.sum_s = static_cast<double>(c.sum_ns) / 1e9;
    return out;
}

Metrics collect_metrics(runtime::Daemon& daemon)
{
    const runtime::StatusSnapshot s = daemon.snapshot(true);
    const runtime::Counters& c = daemon.counters();
    Metrics m;
    m.frames_in = s.frames_in;
    m.frames_out = s.frames_out;
    m.stems = s.stems_out;
    m.late = s.late;
    m.ring_full = s.ring_full;
    m.overwritten = s.overwritten;
    m.results_full = s.results_full;
    m.corrupt = s.corrupt;
    m.bad_size = s.bad_size;
    m.failed = s.failed;
    m.bad_class = s.bad_class;
    m.class_model = s.class_model;
    m.weed_parts = s.weed_parts;
    m.stemless_weeds = s.stemless_weeds;
    m.weed_cover = s.weed_cover;
    m.cells_over_budget = s.cells_over_budget;
    m.frames_over_budget = s.frames_over_budget;
    m.class_socket = s.class_socket;
    m.class_maps = s.class_maps;
    m.class_timeouts = s.class_timeouts;
    m.class_bad_messages = s.class_bad_messages;
    m.class_peers = s.class_peers;
    m.can_interface = s.can_interface;
    m.can_tx_late = s.can_tx_late;
    m.can_tx_unconfirmed = s.can_tx_unconfirmed;
    m.can_tx_waits = s.can_tx_waits;
    m.can_bus_off = s.can_bus_off;
    m.can_error_passive = s.can_error_passive;
    m.trigger = s.trigger;
    m.trigger_pulses = s.trigger_pulses;
    m.trigger_late = s.trigger_late;
    m.trigger_failed = s.trigger_failed;
    m.files = s.files;
    m.file_lines_written = s.file_lines_written;
    m.file_lines_lost = s.file_lines_lost;
    m.capture_to_result = histogram_of(c.actuator.latency);
    m.pipeline = histogram_of(c.processing.pipeline);
    m.cycle_capture = histogram_of(c.capture.cycle);
    m.cycle_processing = histogram_of(c.processing.cycle);
    m.cycle_actuator = histogram_of(c.actuator.cycle);
    if (const runtime::ActuationCounters* a = daemon.actuation_counters()) {
        const auto get = [](const std::atomic<std::uint64_t>& v) { return v.load(std::memory_order_relaxed); };
        m.actuation = true;
        m.targets = get(a->targets);
        m.sent = get(a->sent);
        m.policy = get(a->policy);
        m.no_tool = get(a->no_tool);
        m.disabled = get(a->disabled);
        m.not_ready = get(a->not_ready);
        m.deadline_miss = get(a->deadline_misses);
        m.bus_deadline = get(a->bus_deadline);
        m.bus_error = get(a->bus_errors);
        m.heartbeat_errors = get(a->heartbeat_errors);
        m.heartbeat_misses = get(a->heartbeat_misses);
        m.no_odometry = get(a->no_odometry);
        m.rx_odometry = get(a->rx_odometry);
        m.odometry_going_back = get(a->odometry_going_back);
        m.capture_to_send = histogram_of(a->send_latency);
    }
    return m;
}

std::string format_metrics(const Metrics& m)
{
    Text t;
    t.counter("frames_in_total", "Frames the source delivered.", m.frames_in);
    t.counter("frames_out_total", "Frames whose detections reached the actuator.", m.frames_out);
    t.counter("stems_total", "Plants with a stem in the frames out.", m.stems);
    t.counter("frames_late_total", "Paced replay: frames the source came to more than 2 ms late.", m.late);
    t.counters("frames_dropped_total", "Frames dropped, by cause.", "cause",
               {{"ring_full", m.ring_full}, {"overwritten", m.overwritten}, {"results_full", m.results_full},
                {"corrupt", m.corrupt}, {"bad_size", m.bad_size}, {"failed", m.failed}});
    if (m.trigger)
        t.counters("trigger_pulses_total",
                   "Camera trigger periods by outcome: pulsed, skipped for lateness, or not pulsed (GPIO lines down or "
                   "being reopened).",
                   "outcome", {{"sent", m.trigger_pulses}, {"late", m.trigger_late}, {"failed", m.trigger_failed}});
    if (m.files)
        t.counters("file_lines_total",
                   "Lines of the detections CSV and the plant map by outcome: written, or lost (a failed write, or "
                   "the writer's queue full while the disk stalled).",
                   "outcome", {{"written", m.file_lines_written}, {"lost", m.file_lines_lost}});
    if (m.actuation) {
        t.counter("deadline_misses_total", "Targets never sent because they could not be on time (scheduler or bus).",
                  m.deadline_miss + m.bus_deadline);
        t.counter("targets_confirmed_total", "Plants confirmed by the tracker (one target each).", m.targets);
        t.counters("targets_total", "Targets by outcome.", "outcome",
                   {{"sent", m.sent}, {"policy", m.policy}, {"no_tool", m.no_tool}, {"disabled", m.disabled},
                    {"not_ready", m.not_ready}, {"deadline_miss", m.deadline_miss}, {"bus_deadline", m.bus_deadline}, {"bus_error", m.bus_error}});
        t.counters("bus_errors_total", "CAN frames the bus failed, by frame.", "frame",
                   {{"target", m.bus_error}, {"heartbeat", m.heartbeat_errors}});
        t.counter("heartbeat_misses_total",
                  "HEARTBEAT periods that passed without their HEARTBEAT (the actuator thread came over a period late).",
                  m.heartbeat_misses);
        t.counter("no_odometry_frames_total", "Frames not actuated: no usable odometer reading.", m.no_odometry);
        t.counter("odometry_frames_total", "ODOMETRY frames taken from the CAN bus (odometry.source can).",
                  m.rx_odometry);
        t.counter("odometer_samples_going_back_total",
                  "Odometer samples refused for going back (the machine reversing): frames are not actuated until "
                  "it passes its highest reading again.",
                  m.odometry_going_back);
    }
    if (m.can_interface) {
        t.counters("can_frames_total",
                   "TARGET and HEARTBEAT frames by what the interface reported: on the wire after their deadline, or "
                   "never reported on it.",
                   "outcome", {{"late", m.can_tx_late}, {"unconfirmed", m.can_tx_unconfirmed}});
        t.counter("can_send_waits_total",
                  "Sends that waited for the frame before them to leave the interface (a busy or stalled bus).",
                  m.can_tx_waits);
        t.counters("can_controller_events_total", "The CAN controller's error states entered.", "state",
                   {{"bus_off", m.can_bus_off}, {"error_passive", m.can_error_passive}});
    }
    t.counter("bad_class_plants_total", "Plants whose class-map window held values above 2 (taken as unknown).",
              m.bad_class);
    if (m.class_model) {
        t.counters("weed_targets_total", "Weed targets the in-box model added beside the plants' own stems, by kind.",
                   "kind", {{"part", m.weed_parts}, {"stemless", m.stemless_weeds}, {"cover", m.weed_cover}});
        t.counter("classifier_cells_over_budget_total",
                  "Vegetated cells classify.max_cells left unclassified (their plants unknown).", m.cells_over_budget);
        t.counter("classifier_frames_over_budget_total", "Frames with cells over classify.max_cells.",
                  m.frames_over_budget);
    }
    if (m.class_socket) {
        t.counter("class_maps_total", "Class maps received from the external provider.", m.class_maps);
        t.counter("class_timeouts_total", "Frames whose class map came too late or never (plants unknown).",
                  m.class_timeouts);
        t.counter("class_bad_messages_total", "Malformed messages from the external provider, dropped.",
                  m.class_bad_messages);
        t.counter("class_peers_total", "Connections the class socket accepted.", m.class_peers);
    }
    t.family("capture_to_result_seconds", "histogram", "Capture (exposure) to the result at the actuator.");
    t.histogram("capture_to_result_seconds", "", m.capture_to_result);
    if (m.actuation) {
        t.family("capture_to_send_seconds", "histogram", "Capture to the TARGET handed to the bus.");
        t.histogram("capture_to_send_seconds", "", m.capture_to_send);
    }
    t.family("pipeline_seconds", "histogram", "Wall time of the detection pipeline per frame.");
    t.histogram("pipeline_seconds", "", m.pipeline);
    t.family("thread_cycle_seconds", "histogram", "Per-frame work of each real-time thread.");
    t.histogram("thread_cycle_seconds", "thread=\"capture\"", m.cycle_capture);
    t.histogram("thread_cycle_seconds", "thread=\"processing\"", m.cycle_processing);
    t.histogram("thread_cycle_seconds", "thread=\"actuator\"", m.cycle_actuator);
    t.counter("live_frames_published_total", "Frames the processing thread copied for the live view.",
              m.live_frames_published);
    t.counter("live_frames_encoded_total", "JPEGs the web thread encoded.", m.live_frames_encoded);
    t.counter("live_plants_dropped_total", "Plants the live view missed (its ring was full).", m.live_plants_dropped);
    t.counter("web_requests_total", "HTTP requests the live view answered.", m.web_requests);
    t.counter("web_unauthorized_total", "Control requests refused for a missing or wrong token.", m.web_unauthorized);
    return t.take();
}

}  // namespace stemd::web
