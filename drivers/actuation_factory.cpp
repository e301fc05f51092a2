#include "stemd/drivers/actuation_factory.hpp"

#include <utility>

#include "canlog/canlog_bus.hpp"
#include "socketcan/socketcan_bus.hpp"
#if STEMD_HAVE_LIBGPIOD
#include "gpiod/gpiod_lines.hpp"
#endif

namespace stemd::drivers {

std::unique_ptr<CanBus> make_can_bus(const CanBusSpec& spec, const MakeLogger& make_logger, spdlog::logger& log,
                                     std::string& error)
{
    if (spec.interface.empty()) {
        CanLogOptions options;
        options.path = spec.log_file;
        options.clock = spec.log_monotonic ? CanLogOptions::Clock::monotonic : CanLogOptions::Clock::realtime;
        auto bus = std::make_unique<CanLogBus>(options, make_logger("canlog"));
        if (!bus->open()) {
            error = "cannot open the CAN log " + options.path.string();
            return nullptr;
        }
        log.info("no CAN interface: commands go to {} (candump -L format)",
                 spec.log_file == CanLogOptions::kStandardOutput ? "standard output" : options.path.string());
        return bus;
    }
    SocketCanOptions options;
    options.interface = spec.interface;
    options.rx_ids = spec.rx_ids;
    options.confirmed_tx_ids = spec.confirmed_tx_ids;
    auto bus = std::make_unique<SocketCanBus>(options, make_logger("socketcan"));
    if (!bus->open())
        log.warn("{}: not up yet; retrying in the background", bus->name());
    return bus;
}

std::unique_ptr<GpioLines> make_gpio_lines(const GpioSpec& spec, const MakeLogger& make_logger, spdlog::logger& log,
                                           std::string& error)
{
#if STEMD_HAVE_LIBGPIOD
    (void)error;
    GpiodOptions options;
    options.chip = spec.chip;
    options.enable_line = spec.enable_line;
    options.enable_active_low = spec.enable_active_low;
    options.enable_debounce_ns = spec.enable_debounce_ns;
    options.trigger_line = spec.trigger_line;
    options.trigger_active_low = spec.trigger_active_low;
    options.encoder = spec.encoder_mode == "quadrature" ? EncoderMode::quadrature
                      : spec.encoder_mode == "single"   ? EncoderMode::single
                                                        : EncoderMode::none;
    options.encoder_a_line = spec.encoder_a_line;
    options.encoder_b_line = spec.encoder_b_line;
    auto gpio = std::make_unique<GpiodLines>(options, make_logger("gpiod"));
    if (!gpio->open())
        log.warn("{}: not available yet ({}); commands stay disabled until it is", gpio->name(), gpio->last_error());
    gpio->start();
    return gpio;
#else
    (void)spec, (void)make_logger, (void)log;
    error = "gpio.chip is set but this build has no libgpiod (apt install libgpiod-dev, rebuild)";
    return nullptr;
#endif
}

}  // namespace stemd::drivers
