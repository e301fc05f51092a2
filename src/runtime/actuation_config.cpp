#include "stemd/runtime/actuation_config.hpp"

#include <cmath>

namespace stemd::runtime {

namespace {

std::int64_t ms_to_ns(double ms)
{
    return static_cast<std::int64_t>(std::llround(ms * 1e6));
}

// "none" (the schema's "not set") -> "".
std::string unless_none(const std::string& text)
{
    return text == "none" ? std::string() : text;
}

}  // namespace

ActuationConfig actuation_config(const config::Config& config)
{
    ActuationConfig a;

    const std::size_t n_tools = config.list_size("tools");
    a.tools.reserve(n_tools);
    for (std::size_t i = 0; i < n_tools; ++i) {
        actuation::ToolSpec tool;
        tool.id = static_cast<std::uint8_t>(config.get_item_int("tools", i, "id"));
        tool.offset_mm = config.get_item_real("tools", i, "offset_mm");
        tool.y_min_mm = config.get_item_real("tools", i, "y_min_mm");
        tool.y_max_mm = config.get_item_real("tools", i, "y_max_mm");
        tool.lanes = static_cast<std::uint8_t>(config.get_item_int("tools", i, "lanes"));
        a.tools.push_back(tool);
    }

    a.tracker.association_radius_mm = config.get_real("tracker.association_radius_mm");
    a.tracker.confirm_frames = static_cast<std::uint32_t>(config.get_int("tracker.confirm_frames"));
    a.tracker.exit_margin_mm = config.get_real("tracker.exit_margin_mm");
    a.tracker.max_missed_frames = static_cast<std::uint32_t>(config.get_int("tracker.max_missed_frames"));
    a.tracker.capacity = static_cast<std::size_t>(config.get_int("tracker.capacity"));
    // tracker.max_detections: no key, the library's default.

    a.scheduler.lead_ms = config.get_real("scheduler.lead_ms");
    a.scheduler.send_budget_ms = config.get_real("scheduler.send_budget_ms");
    a.scheduler.standing_speed_mm_per_s = config.get_real("scheduler.standing_speed_mm_per_s");
    const std::string& policy = config.get_text("scheduler.policy");
    a.policy = policy == "weeds_only" ? PolicyChoice::weeds_only
             : policy == "all"        ? PolicyChoice::all
                                      : PolicyChoice::automatic;
    // The resolved policy is chosen at start; until then the fixed choices map directly.
    a.scheduler.policy = a.policy == PolicyChoice::all ? actuation::TreatPolicy::all : actuation::TreatPolicy::weeds_only;

    const std::string& source = config.get_text("odometry.source");
    a.odometry = source == "recording" ? OdometrySource::recording
               : source == "constant"  ? OdometrySource::constant
               : source == "can"       ? OdometrySource::can
               : source == "encoder"   ? OdometrySource::encoder
                                       : OdometrySource::automatic;
    a.speed_mm_per_s = config.get_real("odometry.speed_mm_per_s");
    a.encoder_mm_per_tick = config.get_real("odometry.encoder_mm_per_tick");
    a.max_extrapolation_ns = ms_to_ns(config.get_real("odometry.max_extrapolation_ms"));
    a.odometry_timeout_ns = ms_to_ns(config.get_real("odometry.timeout_ms"));

    a.can_interface = unless_none(config.get_text("can.interface"));
    a.can_base_id = static_cast<std::uint32_t>(config.get_int("can.base_id"));
    a.can_log_file = config.get_text("can.log_file");
    a.can_log_monotonic = config.get_text("can.log_clock") == "monotonic";
    a.heartbeat_interval_ns = ms_to_ns(config.get_real("can.heartbeat_ms"));

    a.gpio_chip = unless_none(config.get_text("gpio.chip"));
    a.enable_line = static_cast<int>(config.get_int("gpio.enable_line"));
    a.enable_active_low = config.get_text("gpio.enable_active") == "low";
    a.enable_debounce_ns = ms_to_ns(config.get_real("gpio.enable_debounce_ms"));
    a.trigger_line = static_cast<int>(config.get_int("gpio.trigger_line"));
    a.trigger_active_low = config.get_text("gpio.trigger_active") == "low";
    a.trigger_pulse_us = static_cast<std::uint32_t>(config.get_int("gpio.trigger_pulse_us"));
    a.encoder_mode = config.get_text("gpio.encoder");
    a.encoder_a_line = static_cast<int>(config.get_int("gpio.encoder_a_line"));
    a.encoder_b_line = static_cast<int>(config.get_int("gpio.encoder_b_line"));

    a.map_file = unless_none(config.get_text("map.file"));
    return a;
}

}  // namespace stemd::runtime
