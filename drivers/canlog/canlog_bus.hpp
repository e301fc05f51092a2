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
// The file is opened (truncated, or appended to; standard output is shared
// as it is) by open(), and each frame is
// one line written with one write(2) (base::RecordFile): a frame send()
// reports as sent is in the file, a kill tears no line, and a write that
// fails (a full disk: ENOSPC) is the send's error, counted like a bus error.
// receive() has nothing to deliver: it waits out its timeout and returns
// false. One thread drives it; counters() from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include <spdlog/logger.h>

#include "stemd/base/record_file.hpp"
#include "stemd/drivers/can_bus.hpp"

namespace stemd::drivers {

struct CanLogOptions {
    // kStandardOutput writes to the process's standard output as it is
    // (a terminal, a pipe, or a file the shell opened), after what is there.
    static constexpr const char* kStandardOutput = "-";
    std::filesystem::path path;
    std::string interface = "can0";  // the interface name written in each line
    enum class Clock : std::uint8_t { realtime, monotonic } clock = Clock::realtime;
    bool append = false;             // false: truncate at open()
};

class CanLogBus final : public CanBus {
public:
    CanLogBus(CanLogOptions options, std::shared_ptr<spdlog::logger> log);
    ~CanLogBus() override;

    // Opens the file; false (logged with path and errno) if it cannot, or if
    // the interface name is not one candump could print.
    bool open();

    std::string_view name() const override { return name_; }
    // error if not open, if the frame cannot be formatted, or if the write fails.
    using CanBus::send;
    SendResult send(const protocol::CanFrame& frame, std::int64_t deadline_ns, SendGate gate) override;
    using CanBus::receive;
    bool receive(protocol::CanFrame& out, std::int64_t timeout_ns, std::int64_t& t_rx_ns) override;
    CanBusCounters counters() const override;
    // Frames that could not be written: the log is incomplete.
    bool output_lost() const override { return counters_.errors.load(std::memory_order_relaxed) > 0; }

private:
    const CanLogOptions options_;
    const std::shared_ptr<spdlog::logger> log_;
    const std::string name_;
    base::RecordFile file_;
    bool write_error_logged_ = false;

    CanBusCounterCells counters_;
};

}  // namespace stemd::drivers
