#include "stemd/runtime/actuation_config.hpp"

namespace stemd::runtime {

std::optional<ConfigProblem> check_actuation_config(const ActuationConfig& c)
{
#ifndef STEMD_HAVE_LIBGPS
    if (c.gnss.source == GnssSourceKind::gpsd)
        return ConfigProblem{"gnss.source", "gpsd, but this stemd was built without libgps (apt install libgps-dev, rebuild)"};
#endif
    for (std::size_t i = 0; i < c.tools.size(); ++i)
        if (c.tools[i].learn_latency && c.tools[i].latency_min_ms > c.tools[i].latency_max_ms)
            return ConfigProblem{"tools[" + std::to_string(i) + "].latency_max_ms",
                                 "below latency_min_ms: the learned latency has no room"};
    const bool encoder = c.encoder_mode != "none";
    if (c.gpio_chip.empty()) {
        if (c.enable_line >= 0)
            return ConfigProblem{"gpio.enable_line", "a line is set but gpio.chip is none"};
        if (c.trigger_line >= 0)
            return ConfigProblem{"gpio.trigger_line", "a line is set but gpio.chip is none"};
        if (encoder)
            return ConfigProblem{"gpio.encoder", c.encoder_mode + " is set but gpio.chip is none"};
    } else if (c.enable_line < 0) {
        return ConfigProblem{"gpio.enable_line",
                             "-1 with gpio.chip " + c.gpio_chip +
                                 ": the enable (e-stop) input is required when stemd drives GPIO"};
    }
    if (encoder && c.encoder_a_line < 0)
        return ConfigProblem{"gpio.encoder_a_line", "-1 with gpio.encoder " + c.encoder_mode};
    if (c.encoder_mode == "quadrature" && c.encoder_b_line < 0)
        return ConfigProblem{"gpio.encoder_b_line", "-1 with gpio.encoder quadrature (it needs channels A and B)"};
    if (c.odometry == OdometrySource::encoder && !encoder)
        return ConfigProblem{"odometry.source", "encoder, but gpio.encoder is none (no wheel encoder configured)"};
    if (c.odometry == OdometrySource::can && c.can_interface.empty())
        return ConfigProblem{"odometry.source",
                             "can, but can.interface is none (commands go to a log; no ODOMETRY frames can arrive)"};
    return std::nullopt;
}

}  // namespace stemd::runtime
