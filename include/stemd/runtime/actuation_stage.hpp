// The actuator thread's work: stems -> field coordinates -> one target per
// plant -> deadline-checked TARGET commands on the CAN bus.
//
// Per frame (on_frame):
//  1. The odometer at the frame's capture time, from the configured
//     odometry (odometry.source): the frame's own odom_mm (a recording's
//     column), a constant speed, ODOMETRY frames from the bus, or a wheel
//     encoder. Without a usable reading (none yet, stale) the frame's
//     detections are not actuated (counted: no_odometry).
//  2. Each stem -> field position (s_mm, y_mm) through the camera model;
//     the plant's class from the frame's class map, if any. A plant cut by
//     the leading or trailing image border (the along-track borders, per
//     camera.forward) is skipped (counted: clipped): its stem is estimated
//     from part of it, and the same plant is seen whole in other frames.
//     Plants cut by the lateral borders are kept (some are never seen whole).
//  3. Tracker::update: each plant becomes one target, once.
//  4. For each new target, Scheduler::schedule with the odometer and speed
//     NOW (not at capture) and the enable input; a target that cannot be on
//     time is a deadline miss, counted and never sent. Sent ones are encoded
//     (E2E counter + CRC) and given to CanBus::send with their deadline; the
//     bus never sends after it (counted as bus_deadline).
//  5. Tracks that ended go to the plant map, with what became of them.
// Between frames (poll): received ODOMETRY / TOOL_STATUS (E2E-checked: bad
// CRC or counter jumps are rejected and counted), encoder samples, and a
// HEARTBEAT every can.heartbeat_ms.
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

#include "stemd/actuation/e2e.hpp"
#include "stemd/actuation/messages.hpp"
#include "stemd/actuation/scheduler.hpp"
#include "stemd/actuation/tracker.hpp"
#include "stemd/drivers/can_bus.hpp"
#include "stemd/drivers/gpio_lines.hpp"
#include "stemd/geometry/camera_model.hpp"
#include "stemd/geometry/odometry.hpp"
#include "stemd/runtime/actuation_config.hpp"
#include "stemd/runtime/detection_sink.hpp"
#include "stemd/runtime/plant_map.hpp"

namespace stemd::runtime {

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
    std::atomic<std::uint64_t> deadline_misses{0};  // could not be on time: never sent
    std::atomic<std::uint64_t> bus_deadline{0};     // the bus could not take it before its deadline: never sent
    std::atomic<std::uint64_t> bus_errors{0};       // TARGETs that could not be encoded or sent
    std::atomic<std::uint64_t> heartbeats{0};
    std::atomic<std::uint64_t> heartbeat_errors{0}; // HEARTBEATs that could not be encoded or sent
    std::atomic<std::uint64_t> rx_odometry{0};      // ODOMETRY frames accepted
    std::atomic<std::uint64_t> rx_tool_status{0};   // TOOL_STATUS frames accepted
    std::atomic<std::uint64_t> rx_rejected{0};      // received frames rejected: E2E (CRC, counter) or decode
    std::atomic<std::uint64_t> odometry_rejected{0};  // samples the odometry ring refused (not monotonic)
    std::atomic<std::uint64_t> map_errors{0};
    std::atomic<std::uint64_t> tools_ready_mask{0}; // the last TOOL_STATUS's
};

class ActuationStage {
public:
    // Everything the stage drives. bus: required. gpio: optional (no
    // enable input: always enabled; encoder odometry needs it).
    struct Parts {
        std::unique_ptr<drivers::CanBus> bus;
        std::unique_ptr<drivers::GpioLines> gpio;
        std::unique_ptr<PlantMap> map;   // optional
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
    void on_capture(std::int64_t t_capture_ns, double odom_mm) noexcept;
    void poll(std::int64_t now_ns) noexcept;
    // End of the run: the tracks still open go to the plant map; the map is
    // closed. False (logged) if the map lost lines or the bus is a log that
    // lost frames.
    bool finish() noexcept;

    const ActuationCounters& counters() const { return counters_; }
    const drivers::CanBus& bus() const { return *parts_.bus; }
    const actuation::Tracker& tracker() const { return tracker_; }
    // The GPIO lines when they have a camera trigger output (else nullptr):
    // the capture thread pulses it once per frame period (gpio.trigger_pulse_us).
    drivers::GpioLines* trigger_lines() const
    {
        return parts_.gpio && parts_.gpio->has_trigger() ? parts_.gpio.get() : nullptr;
    }
    std::uint32_t trigger_pulse_us() const { return config_.trigger_pulse_us; }
    // The view's along-track extent relative to the odometer at capture.
    double view_forward_min_mm() const { return view_min_mm_; }
    double view_forward_max_mm() const { return view_max_mm_; }

private:
    bool clipped_along_track(const cv::Rect& bbox) const noexcept;
    double extent_mm(const vision::Plant& plant, double odom_mm) const noexcept;

    ActuationStage(const ActuationConfig& config, const geometry::CameraModel& camera, cv::Size frame_size, Parts parts,
                   actuation::Scheduler scheduler, actuation::CanIds ids, std::shared_ptr<spdlog::logger> log);

    bool odometer_at(std::int64_t t_ns, double& odom_mm) const noexcept;
    void add_frame_odometry(std::int64_t t_capture_ns, double odom_mm) noexcept;
    void schedule(const actuation::Target& target, std::int64_t now_ns, bool class_map) noexcept;
    void write_retired(std::span<const actuation::RetiredTrack> retired) noexcept;
    void receive(std::int64_t now_ns) noexcept;
    void heartbeat(std::int64_t now_ns) noexcept;

    const ActuationConfig config_;
    const geometry::CameraModel camera_;
    const cv::Size frame_size_;
    Parts parts_;
    const std::shared_ptr<spdlog::logger> log_;
    actuation::Tracker tracker_;
    actuation::Scheduler scheduler_;
    std::optional<actuation::Scheduler> scheduler_all_;        // policy auto: frames without a class map
    const actuation::CanIds ids_;
    geometry::OdometryRing odometry_;
    double view_min_mm_ = 0, view_max_mm_ = 0;

    std::array<actuation::TrackDetection, vision::kMaxPlants> detections_{};
    std::array<MapEntry, actuation::kMaxTargetId + 1> outcomes_{};   // by target_id, for the map

    actuation::E2eCounter target_counter_, heartbeat_counter_;
    actuation::E2eChecker odometry_checker_, tool_status_checker_;
    bool have_odometry_frame_ = false;
    std::uint32_t last_can_odom_raw_ = 0;
    double can_odom_mm_ = 0;          // unwrapped
    std::int64_t constant_t0_ns_ = -1;
    bool constant_now_ = false;       // the last frame's odometer came from the constant speed
    std::int64_t next_heartbeat_ns_ = 0;
    std::int64_t last_frame_ns_ = -1;
    std::uint64_t misses_at_last_heartbeat_ = 0;
    bool bus_loss_reported_ = false;
    ActuationCounters counters_;
};

}  // namespace stemd::runtime
