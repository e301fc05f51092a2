// The actuator thread's work: stems -> field coordinates -> one target per
// plant -> deadline-checked TARGET commands on the CAN bus. The stage wires
// its parts, one job each:
//
// Per frame (on_frame):
//  1. The odometer at the frame's capture time (OdometryInput, per
//     odometry.source). Without a usable reading (none yet, stale) the
//     frame's detections are not actuated (counted: no_odometry).
//  2. Each stem -> field position (PlantProjector), skipping plants cut by
//     the along-track borders.
//  3. Tracker::update: each plant becomes one target, once.
//  4. For each new target, TargetSender: scheduled with the odometer and
//     speed NOW, sent before its deadline or counted.
//  5. Tracks that ended go to the plant map, with what became of them (and,
//     with a GNSS receiver, where they are: GnssInput); a sent one for a
//     tool that reports its strikes waits (a fixed number of lines) for its
//     TOOL_FIRED, until the odometer is kFiredWaitMm past its point.
// Between frames (poll): received ODOMETRY / TOOL_STATUS / TOOL_FIRED and
// the HEARTBEAT (CanLink), encoder samples (OdometryInput), GNSS fixes
// (GnssInput), the map lines whose strike came back.
//
// Everything is allocated in make(); on_frame() and poll() do not allocate,
// lock or throw. File I/O (the plant map, the candump log) is one write(2)
// per line.
// Single-threaded (the actuator thread); counters() from any thread.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include <opencv2/core/types.hpp>
#include <spdlog/logger.h>

#include "stemd/actuation/tracker.hpp"
#include "stemd/drivers/can_bus.hpp"
#include "stemd/drivers/gnss_source.hpp"
#include "stemd/drivers/gpio_lines.hpp"
#include "stemd/geometry/camera_model.hpp"
#include "stemd/runtime/actuation_config.hpp"
#include "stemd/runtime/actuation_counters.hpp"
#include "stemd/runtime/can_link.hpp"
#include "stemd/runtime/detection_sink.hpp"
#include "stemd/runtime/gnss_input.hpp"
#include "stemd/runtime/live_feed.hpp"
#include "stemd/runtime/odometry_input.hpp"
#include "stemd/runtime/plant_map.hpp"
#include "stemd/runtime/plant_projector.hpp"
#include "stemd/runtime/target_sender.hpp"

namespace stemd::runtime {

class ActuationStage {
public:
    // Everything the stage drives. bus: required. gpio: optional (no
    // enable input: always enabled; encoder odometry needs it).
    struct Parts {
        std::unique_ptr<drivers::CanBus> bus;
        std::unique_ptr<drivers::GpioLines> gpio;
        std::unique_ptr<PlantMap> map;   // optional
        std::unique_ptr<drivers::GnssSource> gnss;   // optional, started: positions for the map
    };

    // nullopt-like: nullptr with `error` set when the tools or parameters
    // are invalid, or the odometry source needs a part that is missing.
    static std::unique_ptr<ActuationStage> make(const ActuationConfig& config, const geometry::CameraModel& camera,
                                                cv::Size frame_size, Parts parts,
                                                std::shared_ptr<spdlog::logger> log, std::string& error);
    ~ActuationStage();
    ActuationStage(const ActuationStage&) = delete;
    ActuationStage& operator=(const ActuationStage&) = delete;

    void on_frame(const FrameResult& result, std::int64_t now_ns) noexcept;
    // A frame's own odometer (a recording's odom_mm) as soon as it is
    // captured, ahead of its detections: the odometer then stays as fresh as
    // the capture, not as late as the pipeline. on_frame() adds the same
    // sample if this was not called.
    void on_capture(std::int64_t t_sample_ns, double odom_mm) noexcept;
    // camera_lost: the capture side has no camera (see HeartbeatInputs);
    // the HEARTBEAT says so.
    void poll(std::int64_t now_ns, bool camera_lost = false) noexcept;
    // The source ended (a recording played once) after the last on_frame():
    // the machine is taken to drive on by one more frame step (the travel
    // between the last two frames) in which nothing is seen, so the plants
    // that step carries past the view's trailing edge become targets by the
    // tracker's exit rule, as they would in the field, instead of ending
    // unconfirmed. They are scheduled against the odometer at the last
    // frame's capture, the newest one known. Nothing without two frames
    // with an odometer.
    void end_of_stream() noexcept;
    // End of the run: the tracks still open go to the plant map; the map is
    // closed. False (logged) if the map lost lines or the bus is a log that
    // lost frames.
    bool finish() noexcept;

    const ActuationCounters& counters() const { return counters_; }
    // The status thread takes the histograms' intervals through this one.
    ActuationCounters& counters() { return counters_; }
    const drivers::CanBus& bus() const { return *parts_.bus; }
    const actuation::Tracker& tracker() const { return tracker_; }
    // The GPIO lines when they have a camera trigger output (else nullptr):
    // the capture thread pulses it once per frame period (gpio.trigger_pulse_us).
    drivers::GpioLines* trigger_lines() const
    {
        return parts_.gpio && parts_.gpio->has_trigger() ? parts_.gpio.get() : nullptr;
    }
    std::uint32_t trigger_pulse_us() const { return config_.trigger_pulse_us; }
    OdometrySource odometry_source() const { return config_.odometry; }
    // Commands go to a SocketCAN interface, not to a log.
    bool on_can_interface() const { return !config_.can_interface.empty(); }
    // The view's along-track extent relative to the odometer at capture.
    double view_forward_min_mm() const { return projector_.view_forward_min_mm(); }
    double view_forward_max_mm() const { return projector_.view_forward_max_mm(); }
    const OdometryInput& odometry() const { return odometry_; }
    const GnssInput* gnss() const { return gnss_ ? &*gnss_ : nullptr; }
    // Before the first frame: every plant the map gets (with or without a
    // map file) is pushed to the live view's feed too (nullptr: none).
    void set_live_feed(LiveFeed* feed) { live_feed_ = feed; }
    // Before the first frame: the plant map's lines go through `writer`'s
    // thread (which must outlive this stage). False without a map file.
    bool attach_map_writer(RecordWriter& writer)
    {
        if (!parts_.map || !parts_.map->is_open())
            return false;
        parts_.map->attach(writer);
        return true;
    }
    bool has_map() const { return parts_.map && parts_.map->is_open(); }
    // The operator's software disable (any thread): while set, targets are
    // not sent and the heartbeat says disabled. It can only add to the
    // enable input: clearing it never enables past an inactive input.
    void set_operator_disabled(bool disabled) noexcept { operator_disabled_.store(disabled, std::memory_order_relaxed); }
    // The enable input as the actuator thread last polled it (any thread).
    bool enable_input_seen() const noexcept { return enable_input_seen_.load(std::memory_order_relaxed); }

private:
    ActuationStage(const ActuationConfig& config, Parts parts, PlantProjector projector,
                   actuation::Scheduler scheduler, std::optional<actuation::Scheduler> scheduler_all,
                   protocol::CanIds ids, std::shared_ptr<spdlog::logger> log, double principal_x_mm);

    static constexpr std::size_t kWaitingLines = 256;
    static constexpr double kFiredWaitMm = 1000.0;

    bool enable_input() const noexcept { return parts_.gpio ? parts_.gpio->enabled() : true; }
    bool enabled() const noexcept
    {
        return enable_input() && !operator_disabled_.load(std::memory_order_relaxed);
    }
    // enabled() as the bus checks it before writing a TARGET.
    drivers::SendGate enable_gate() const noexcept
    {
        return {.is_open = [](const void* stage) { return static_cast<const ActuationStage*>(stage)->enabled(); },
                .context = this};
    }
    void write_retired(std::span<const actuation::RetiredTrack> retired, std::int64_t now_ns) noexcept;
    void poll_gnss(std::int64_t now_ns) noexcept;
    // One map line; with GNSS, placed on the track as it is at now_ns.
    void write_line(const actuation::RetiredTrack& track, const MapEntry& entry, std::int64_t now_ns) noexcept;
    // Writes the waiting lines whose TOOL_FIRED came or will not come (all: every one).
    void write_waiting(std::int64_t now_ns, bool all) noexcept;

    const ActuationConfig config_;
    Parts parts_;
    const std::shared_ptr<spdlog::logger> log_;
    bool bus_loss_reported_ = false;
    std::atomic<bool> operator_disabled_{false};
    std::atomic<bool> enable_input_seen_{true};
    ActuationCounters counters_;
    OdometryInput odometry_;
    PlantProjector projector_;
    actuation::Tracker tracker_;
    TargetSender sender_;
    CanLink link_;
    std::optional<GnssInput> gnss_;
    bool gnss_reported_ = false;
    bool odometry_announced_ = false;
    std::int64_t last_frame_ns_ = -1;
    // The last two frames the tracker took (end_of_stream's frame step).
    std::uint64_t frames_tracked_ = 0;
    std::uint64_t last_seq_ = 0;
    std::int64_t last_capture_ns_ = 0;
    double last_odom_mm_ = 0;
    double prev_odom_mm_ = 0;
    bool last_class_map_ = false;
    // Map lines of sent plants waiting for their TOOL_FIRED.
    struct Waiting {
        bool used = false;
        actuation::RetiredTrack track;
        MapEntry entry;   // as it was when the track ended
    };
    std::array<Waiting, kWaitingLines> waiting_{};
    std::size_t n_waiting_ = 0;
    LiveFeed* live_feed_ = nullptr;
};

}  // namespace stemd::runtime
