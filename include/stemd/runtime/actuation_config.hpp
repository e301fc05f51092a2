// The actuation side of the configuration, typed: the tools list and the
// tracker.*, scheduler.*, odometry.*, can.*, gpio.*, map.* and gnss.* keys, filled
// by config::Config.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "stemd/actuation/scheduler.hpp"
#include "stemd/actuation/tracker.hpp"
#include "stemd/base/enum_names.hpp"
#include "stemd/runtime/config_problem.hpp"

namespace stemd::runtime {

enum class OdometrySource : std::uint8_t {
    automatic,  // odometry.source: auto — the recording's odom_mm column when the frames carry it, else constant
    recording,  // the frames' odom_mm (replay of a recording with that column); frames without it are not actuated
    constant,   // odometry.speed_mm_per_s from the first frame on
    can,        // ODOMETRY frames received on the CAN bus
    encoder,    // a wheel encoder on GPIO lines (gpio.encoder_*)
};
inline constexpr base::EnumName<OdometrySource> kOdometrySourceNames[]{
    {OdometrySource::automatic, "auto"}, {OdometrySource::recording, "recording"},
    {OdometrySource::constant, "constant"}, {OdometrySource::can, "can"}, {OdometrySource::encoder, "encoder"}};

// scheduler.policy: auto = weeds_only when the frames carry a class map or
// classify.model is set (the daemon then gives every result one), all without.
enum class PolicyChoice : std::uint8_t { automatic, weeds_only, all };
inline constexpr base::EnumName<PolicyChoice> kPolicyChoiceNames[]{
    {PolicyChoice::automatic, "auto"}, {PolicyChoice::weeds_only, "weeds_only"}, {PolicyChoice::all, "all"}};

// gnss.*: a GNSS receiver through gpsd, for the plant map's WGS84 positions.
enum class GnssSourceKind : std::uint8_t { none, gpsd };
inline constexpr base::EnumName<GnssSourceKind> kGnssSourceNames[]{{GnssSourceKind::none, "none"},
                                                                   {GnssSourceKind::gpsd, "gpsd"}};
// gnss.time: which time of a fix finds its odometer reading.
enum class GnssTime : std::uint8_t {
    receive,   // CLOCK_MONOTONIC when stemd received it (includes the receiver's and gpsd's latency)
    gnss,      // the fix's own UTC time, through the system clock (needs it synchronised: chrony + gpsd)
};
inline constexpr base::EnumName<GnssTime> kGnssTimeNames[]{{GnssTime::receive, "receive"}, {GnssTime::gnss, "gnss"}};

struct GnssConfig {
    GnssSourceKind source = GnssSourceKind::none;
    std::string host = "localhost";
    int port = 2947;
    double antenna_x_mm = 0;              // the antenna's phase centre, machine frame
    double antenna_y_mm = 0;
    std::int64_t max_age_ns = 1'000'000'000;
    GnssTime time = GnssTime::receive;
    double heading_baseline_mm = 2000;
    double max_extrapolation_mm = 500;
    // A plant placed from fixes whose horizontal error estimate is above
    // this is georef "degraded" (placed, not to be trusted as a fix).
    double max_eph_mm = 100;
};

struct ActuationConfig {
    // tools: the list (1..16 entries, ids unique: checked by the loader).
    std::vector<actuation::ToolSpec> tools{{.id = 0, .offset_mm = 600, .y_min_mm = -220, .y_max_mm = 220, .lanes = 1}};
    actuation::TrackerParams tracker;
    actuation::SchedulerParams scheduler;   // .policy is not configured: ActuationStage::make resolves `policy`
    PolicyChoice policy = PolicyChoice::automatic;

    // odometry.*
    OdometrySource odometry = OdometrySource::automatic;
    double speed_mm_per_s = 1388.9;           // constant: 5 km/h
    double encoder_mm_per_tick = 0.1;
    std::int64_t max_extrapolation_ns = 100'000'000;
    std::int64_t odometry_timeout_ns = 500'000'000;   // can/encoder: no fresh sample for this long = no odometry

    // can.*
    std::string can_interface;                // empty: none configured (log sink)
    std::uint32_t can_base_id = 0x300;
    std::string can_log_file = "-";           // log sink: "-" = stdout
    bool can_log_monotonic = false;           // can.log_clock: monotonic (true) or realtime
    std::int64_t heartbeat_interval_ns = 100'000'000;
    // A tool controller's TOOL_STATUS holds this long (0: until the next).
    std::int64_t tool_status_timeout_ns = 1'000'000'000;

    // gpio.* (chip empty: no GPIO; the enable input is then taken as active)
    std::string gpio_chip;
    int enable_line = -1;
    bool enable_active_low = false;           // gpio.enable_active: low (true) or high
    std::int64_t enable_debounce_ns = 20'000'000;
    int trigger_line = -1;
    bool trigger_active_low = false;          // gpio.trigger_active: low (true) or high
    std::uint32_t trigger_pulse_us = 100;
    std::string encoder_mode = "none";        // none | quadrature | single
    int encoder_a_line = -1;
    int encoder_b_line = -1;

    // map.file (empty: none); --map FILE sets it
    std::string map_file;

    GnssConfig gnss;
};

// What the schema cannot check key by key: GPIO lines without a chip, a
// chip without the enable input, encoder or CAN odometry without an encoder
// or a bus. The daemon refuses these at start, and --check-config with it.
std::optional<ConfigProblem> check_actuation_config(const ActuationConfig& config);

}  // namespace stemd::runtime
