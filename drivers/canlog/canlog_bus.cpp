#include "canlog/canlog_bus.hpp"

#include <time.h>

#include <array>
#include <cerrno>
#include <cstring>

#include "stemd/protocol/candump_format.hpp"
#include "stemd/base/clock.hpp"

namespace stemd::drivers {

namespace {

std::uint64_t clock_us(clockid_t clock)
{
    timespec ts{};
    clock_gettime(clock, &ts);
    return static_cast<std::uint64_t>(ts.tv_sec) * 1'000'000 + static_cast<std::uint64_t>(ts.tv_nsec) / 1000;
}

}  // namespace

CanLogBus::CanLogBus(CanLogOptions options, std::shared_ptr<spdlog::logger> log)
    : options_(std::move(options)), log_(std::move(log)), name_("canlog:" + options_.path.string())
{
}

CanLogBus::~CanLogBus() = default;

bool CanLogBus::open()
{
    if (file_.is_open())
        return true;
    if (!protocol::valid_interface_name(options_.interface)) {
        log_->error("{}: interface name '{}' cannot be written in a candump line (1..15 characters, no "
                    "whitespace, '(', ')' or '#')",
                    name_, options_.interface);
        return false;
    }
    const bool standard_output = options_.path == CanLogOptions::kStandardOutput;
    if (const int e = standard_output ? file_.open_duplicate(STDOUT_FILENO)
                                      : file_.open(options_.path.c_str(), options_.append);
        e != 0) {
        log_->error("{}: cannot open {}: {} (errno {})", name_, options_.path.string(), std::strerror(e), e);
        return false;
    }
    log_->info("{}: logging frames as {} ({} timestamps)", name_, options_.interface,
               options_.clock == CanLogOptions::Clock::realtime ? "CLOCK_REALTIME" : "CLOCK_MONOTONIC");
    return true;
}

SendResult CanLogBus::send(const protocol::CanFrame& frame, std::int64_t deadline_ns, SendGate gate)
{
    if (base::monotonic_ns() >= deadline_ns) {
        CanBusCounterCells::bump(counters_.deadline_misses);
        return SendResult::deadline_passed;
    }
    if (!gate.open()) {
        CanBusCounterCells::bump(counters_.withdrawn);
        return SendResult::withdrawn;
    }
    if (!file_.is_open()) {
        CanBusCounterCells::bump(counters_.errors);
        return SendResult::error;
    }
    std::array<char, protocol::kCandumpLineMax + 1> line{};
    const std::uint64_t t_us =
        clock_us(options_.clock == CanLogOptions::Clock::realtime ? CLOCK_REALTIME : CLOCK_MONOTONIC);
    const std::size_t n = protocol::format_candump_line(std::span<char>(line.data(), protocol::kCandumpLineMax),
                                                         t_us, options_.interface, frame);
    if (n == 0) {
        CanBusCounterCells::bump(counters_.errors);
        log_->error("{}: frame id 0x{:X} dlc {} cannot be written as a candump line", name_, frame.id, frame.dlc);
        return SendResult::error;
    }
    line[n] = '\n';
    if (const int e = file_.write({line.data(), n + 1}); e != 0) {
        CanBusCounterCells::bump(counters_.errors);
        // Logged once: a full disk fails every line after the first.
        if (!write_error_logged_)
            log_->error("{}: write failed: {} (errno {}); frames that cannot be written are counted as bus errors",
                        name_, std::strerror(e), e);
        write_error_logged_ = true;
        return SendResult::error;
    }
    CanBusCounterCells::bump(counters_.sent);
    return SendResult::sent;
}

bool CanLogBus::receive(protocol::CanFrame& /*out*/, std::int64_t timeout_ns, std::int64_t& /*t_rx_ns*/)
{
    if (timeout_ns > 0) {
        base::sleep_until_ns(base::monotonic_ns() + timeout_ns);
    }
    return false;
}

CanBusCounters CanLogBus::counters() const
{
    return counters_.load();
}

}  // namespace stemd::drivers
