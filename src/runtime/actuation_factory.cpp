#include "stemd/runtime/actuation_factory.hpp"

#include <utility>

#include "canlog/canlog_bus.hpp"
#include "socketcan/socketcan_bus.hpp"
#if STEMD_HAVE_LIBGPIOD
#include "gpiod/gpiod_lines.hpp"
#endif
#include "stemd/runtime/logging.hpp"

namespace stemd::runtime {

std::unique_ptr<ActuationStage> make_actuation(const ActuationConfig& config, const geometry::CameraModel& camera,
                                               cv::Size frame_size, std::string& error)
{
    if (const auto problem = check_actuation_config(config)) {
        error = problem->key + ": " + problem->message;
        return nullptr;
    }
    const auto log = make_logger("actuator");
    const auto ids = protocol::CanIds::make(config.can_base_id);
    if (!ids) {
        error = "can.base_id " + std::to_string(config.can_base_id) + " is too large";
        return nullptr;
    }
    ActuationStage::Parts parts;
    if (config.can_interface.empty()) {
        drivers::CanLogOptions options;
        options.path = config.can_log_file == "-" ? "/dev/stdout" : config.can_log_file;
        options.clock = config.can_log_monotonic ? drivers::CanLogOptions::Clock::monotonic
                                                 : drivers::CanLogOptions::Clock::realtime;
        auto bus = std::make_unique<drivers::CanLogBus>(options, make_logger("canlog"));
        if (!bus->open()) {
            error = "cannot open the CAN log " + options.path.string();
            return nullptr;
        }
        log->info("no CAN interface: commands go to {} (candump -L format)", options.path.string());
        parts.bus = std::move(bus);
    } else {
        drivers::SocketCanOptions options;
        options.interface = config.can_interface;
        options.rx_ids = {ids->id(protocol::MessageKind::Odometry), ids->id(protocol::MessageKind::ToolStatus)};
        auto bus = std::make_unique<drivers::SocketCanBus>(options, make_logger("socketcan"));
        if (!bus->open())
            log->warn("{}: not up yet; retrying in the background", bus->name());
        parts.bus = std::move(bus);
    }
    if (!config.gpio_chip.empty()) {
#if STEMD_HAVE_LIBGPIOD
        drivers::GpiodOptions options;
        options.chip = config.gpio_chip;
        options.enable_line = static_cast<unsigned>(config.enable_line);
        options.enable_active_low = config.enable_active_low;
        options.enable_debounce_ns = config.enable_debounce_ns;
        options.trigger_line = config.trigger_line;
        options.trigger_active_low = config.trigger_active_low;
        options.encoder = config.encoder_mode == "quadrature" ? drivers::EncoderMode::quadrature
                          : config.encoder_mode == "single"   ? drivers::EncoderMode::single
                                                              : drivers::EncoderMode::none;
        options.encoder_a_line = config.encoder_a_line;
        options.encoder_b_line = config.encoder_b_line;
        auto gpio = std::make_unique<drivers::GpiodLines>(options, make_logger("gpiod"));
        if (!gpio->open())
            log->warn("{}: not available yet ({}); commands stay disabled until it is", gpio->name(),
                      gpio->last_error());
        gpio->start();
        parts.gpio = std::move(gpio);
#else
        error = "gpio.chip is set but this build has no libgpiod (apt install libgpiod-dev, rebuild)";
        return nullptr;
#endif
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
    return ActuationStage::make(config, camera, frame_size, std::move(parts), log, error);
}

}  // namespace stemd::runtime
