// The CAN bus and GPIO lines an actuation configuration names, built from
// plain settings: SocketCAN on an interface, or, with none, the candump log
// sink; libgpiod lines on a chip. The runtime maps its configuration onto
// these specs, so the backends' own headers stay private to drivers/.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <spdlog/logger.h>

#include "stemd/drivers/can_bus.hpp"
#include "stemd/drivers/gpio_lines.hpp"
#include "stemd/drivers/source_factory.hpp"

namespace stemd::drivers {

struct CanBusSpec {
    std::string interface;            // SocketCAN interface; empty: the log sink
    std::string log_file = "-";       // log sink: "-" = stdout
    bool log_monotonic = false;       // log sink timestamps: CLOCK_MONOTONIC, else CLOCK_REALTIME
    std::vector<std::uint32_t> rx_ids;  // SocketCAN: the ids to receive
    // SocketCAN: the ids sent one at a time, each once the previous one is
    // on the wire (SocketCanOptions::confirmed_tx_ids).
    std::vector<std::uint32_t> confirmed_tx_ids;
};

// nullptr with `error` set when the log sink cannot be opened. A SocketCAN
// interface that is down is not an error: the bus reopens it with backoff.
// What was built is logged to `log`; the bus logs to its own logger.
std::unique_ptr<CanBus> make_can_bus(const CanBusSpec& spec, const MakeLogger& make_logger, spdlog::logger& log,
                                     std::string& error);

struct GpioSpec {
    std::string chip;
    unsigned enable_line = 0;
    bool enable_active_low = false;
    std::int64_t enable_debounce_ns = 20'000'000;
    int trigger_line = -1;            // -1: no trigger output
    bool trigger_active_low = false;
    std::string encoder_mode = "none";  // none | quadrature | single
    int encoder_a_line = -1;
    int encoder_b_line = -1;
};

// The lines, opened and started; a chip not there yet is not an error (the
// lines reopen it and commands stay disabled until then). nullptr with
// `error` set in a build without libgpiod.
std::unique_ptr<GpioLines> make_gpio_lines(const GpioSpec& spec, const MakeLogger& make_logger, spdlog::logger& log,
                                           std::string& error);

}  // namespace stemd::drivers
