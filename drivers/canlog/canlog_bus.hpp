// canlog: a CanBus that writes every sent frame as a `candump -L` line
// (protocol::format_candump_line) to a file, for canplayer, log2asc and
// cantools. The default sink when no CAN interface is configured.
//
//   (1700000000.123456) can0 301#1A2B3C4D5E6F7081
//
// Timestamps: CLOCK_REALTIME by default, as candump itself writes (wall-clock
// seconds since the epoch, which log2asc and canplayer expect); optionally
// CLOCK_MONOTONIC, to line the log up with the daemon's own monotonic times.
// Deadlines are CLOCK_MONOTONIC like every CanBus (see can_bus.hpp).
//
// The file is opened (truncated, or appended to) by open(), written through a
// stdio buffer, flushed every `flush_every` lines and when the bus is
// destroyed. receive() has nothing to deliver: it waits out its timeout and
// returns false. One thread drives it; counters() from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <spdlog/logger.h>

#include "stemd/drivers/can_bus.hpp"

namespace stemd::drivers {

struct CanLogOptions {
    std::filesystem::path path;
    std::string interface = "can0";  // the interface name written in each line
    enum class Clock : std::uint8_t { realtime, monotonic } clock = Clock::realtime;
    bool append = false;             // false: truncate at open()
    std::uint32_t flush_every = 64;  // lines; 0 or 1 = flush after every line
};

class CanLogBus final : public CanBus {
public:
    CanLogBus(CanLogOptions options, std::shared_ptr<spdlog::logger> log);
    ~CanLogBus() override;  // flushes and closes
    CanLogBus(const CanLogBus&) = delete;
    CanLogBus& operator=(const CanLogBus&) = delete;

    // Opens the file; false (logged with path and errno) if it cannot, or if
    // the interface name is not one candump could print.
    bool open();

    std::string_view name() const override { return name_; }
    // error if not open, if the frame cannot be formatted, or if the write fails.
    SendResult send(const protocol::CanFrame& frame, std::int64_t deadline_ns) override;
    using CanBus::receive;
    bool receive(protocol::CanFrame& out, std::int64_t timeout_ns, std::int64_t& t_rx_ns) override;
    CanBusCounters counters() const override;

    bool flush();

private:
    struct FileCloser {
        void operator()(std::FILE* f) const { std::fclose(f); }
    };

    const CanLogOptions options_;
    const std::shared_ptr<spdlog::logger> log_;
    const std::string name_;
    std::unique_ptr<std::FILE, FileCloser> file_;
    std::uint32_t unflushed_ = 0;

    std::atomic<std::uint64_t> sent_{0};
    std::atomic<std::uint64_t> deadline_misses_{0};
    std::atomic<std::uint64_t> errors_{0};
};

}  // namespace stemd::drivers
