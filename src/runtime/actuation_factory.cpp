#include "stemd/runtime/actuation_factory.hpp"

#include <optional>
#include <utility>

#include "stemd/drivers/actuation_factory.hpp"
#include "stemd/drivers/gnss_factory.hpp"
#include "stemd/runtime/logging.hpp"

namespace stemd::runtime {

namespace {

drivers::GpioSpec gpio_spec(const ActuationConfig& config)
{
    drivers::GpioSpec gpio;
    gpio.chip = config.gpio_chip;
    gpio.enable_line = static_cast<unsigned>(config.enable_line);
    gpio.enable_active_low = config.enable_active_low;
    gpio.enable_debounce_ns = config.enable_debounce_ns;
    gpio.trigger_line = config.trigger_line;
    gpio.trigger_active_low = config.trigger_active_low;
    gpio.encoder_mode = config.encoder_mode;
    gpio.encoder_a_line = config.encoder_a_line;
    gpio.encoder_b_line = config.encoder_b_line;
    return gpio;
}

// The message identifiers, once the configuration holds together; else
// nullopt with `error` naming the key.
std::optional<protocol::CanIds> checked_ids(const ActuationConfig& config, std::string& error)
{
    if (const auto problem = check_actuation_config(config)) {
        error = problem->key + ": " + problem->message;
        return std::nullopt;
    }
    auto ids = protocol::CanIds::make(config.can_base_id);
    if (!ids)
        error = "can.base_id " + std::to_string(config.can_base_id) + " is too large";
    return ids;
}

}  // namespace

std::unique_ptr<ActuationStage> make_actuation(const ActuationConfig& config, const geometry::CameraModel& camera,
                                               cv::Size frame_size, std::string& error)
{
    const auto ids = checked_ids(config, error);
    if (!ids)
        return nullptr;
    const auto log = make_logger("actuator");
    ActuationStage::Parts parts;
    drivers::CanBusSpec can;
    can.interface = config.can_interface;
    can.log_file = config.can_log_file;
    can.log_monotonic = config.can_log_monotonic;
    can.rx_ids = {ids->id(protocol::MessageKind::Odometry), ids->id(protocol::MessageKind::ToolStatus),
                  ids->id(protocol::MessageKind::ToolFired)};
    // A TARGET in the kernel's queue cannot be withdrawn when the enable
    // input drops or its deadline passes: it is written only once the bus
    // has taken the frame before it.
    can.confirmed_tx_ids = {ids->id(protocol::MessageKind::Target), ids->id(protocol::MessageKind::Heartbeat)};
    parts.bus = drivers::make_can_bus(can, make_logger, *log, error);
    if (!parts.bus)
        return nullptr;
    if (!config.gpio_chip.empty()) {
        parts.gpio = drivers::make_gpio_lines(gpio_spec(config), make_logger, *log, error);
        if (!parts.gpio)
            return nullptr;
    } else {
        log->warn("no GPIO enable input (gpio.chip none): commands are always enabled");
    }
    if (!config.map_file.empty()) {
        auto map = std::make_unique<PlantMap>(make_logger("map"));
        if (!map->open(config.map_file)) {
            error = "cannot create the plant map " + config.map_file;
            return nullptr;
        }
        parts.map = std::move(map);
    }
    if (config.gnss.source == GnssSourceKind::gpsd) {
        drivers::GnssSpec spec;
        spec.host = config.gnss.host;
        spec.port = static_cast<std::uint16_t>(config.gnss.port);
        parts.gnss = drivers::make_gpsd_source(spec, make_logger("gnss"), error);
        if (!parts.gnss)
            return nullptr;
        // Its own thread: it connects, and reconnects, without holding anyone up.
        parts.gnss->start();
    }
    return ActuationStage::make(config, camera, frame_size, std::move(parts), log, error);
}

std::unique_ptr<OdometerTap> make_odometer_tap(const ActuationConfig& config, std::string& error)
{
    const auto ids = checked_ids(config, error);
    if (!ids)
        return nullptr;
    if (config.odometry != OdometrySource::encoder && config.odometry != OdometrySource::can) {
        error = "odometry.source: neither can nor encoder (no odometer to record)";
        return nullptr;
    }
    const OdometerTapParams params{.timeout_ns = config.odometry_timeout_ns,
                                   .max_extrapolation_ns = config.max_extrapolation_ns};
    const auto log = make_logger("odometer");
    if (config.odometry == OdometrySource::encoder) {
        auto lines = drivers::make_gpio_lines(gpio_spec(config), make_logger, *log, error);
        if (!lines)
            return nullptr;
        return std::make_unique<OdometerTap>(std::move(lines), config.encoder_mm_per_tick, params);
    }
    drivers::CanBusSpec can;
    can.interface = config.can_interface;
    can.rx_ids = {ids->id(protocol::MessageKind::Odometry)};
    auto bus = drivers::make_can_bus(can, make_logger, *log, error);
    if (!bus)
        return nullptr;
    return std::make_unique<OdometerTap>(std::move(bus), *ids, params);
}

}  // namespace stemd::runtime
