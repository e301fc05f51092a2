// GpioLines on libgpiod 1.6 (the v1 GPIO character-device uAPI; Debian 12).
//
// One chip (by name "gpiochip0", path "/dev/gpiochip0", label or number, as
// gpiod_chip_open_lookup takes it), consumer "stemd":
//   - enable input: both-edge events, GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW when
//     enable_active_low (libgpiod then reports logical levels and edges);
//   - trigger output (optional): requested as output, inactive, with
//     ACTIVE_LOW when trigger_active_low;
//   - encoder A (and B for quadrature), optional: both-edge events. On each
//     batch of events the thread reads both levels and decodes the step from
//     the last sampled state (v1 reports an edge's level when its IRQ thread
//     runs, so the event type alone is not trusted; a missed edge shows up as
//     an invalid double step).
//
// State machine (the GPIO thread drives it; state() from any thread):
//
//   closed --open ok--> up --(poll error, read error, health read fails)--> down
//     |                 ^                                            |
//     +--open fails--> down --reopen (backoff reopen_min..max, doubling)--+
//   (the schedule is a ReopenBackoff, include/stemd/drivers/reopen_backoff.hpp)
//
// While not `up`, enabled() is false (fail-safe) and set_trigger() fails.
// Errors are logged once per distinct message, naming chip, line and errno.
// Nothing throws after construction.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <spdlog/logger.h>

#include "stemd/drivers/gpio_lines.hpp"
#include "stemd/drivers/reopen_backoff.hpp"
#include "stemd/base/log_throttle.hpp"
#include "stemd/base/unique_fd.hpp"

struct gpiod_chip;
struct gpiod_line;

namespace stemd::drivers {

struct GpiodOptions {
    std::string chip = "gpiochip0";
    unsigned enable_line = 0;
    bool enable_active_low = false;
    std::int64_t enable_debounce_ns = 20'000'000;  // 20 ms stable before enabling
    int trigger_line = -1;                         // -1: no trigger output
    bool trigger_active_low = false;
    EncoderMode encoder = EncoderMode::none;
    int encoder_a_line = -1;
    int encoder_b_line = -1;                       // quadrature only
    // While up, the enable line's level is also read this often: v1 (Linux 6.1)
    // does not wake poll() when the chip goes away, and a missed edge is healed.
    std::int64_t health_check_ns = 100'000'000;    // 100 ms
    std::int64_t reopen_min_ns = 10'000'000;       // first retry after a failure: 10 ms
    std::int64_t reopen_max_ns = 1'000'000'000;    // backoff doubles up to 1 s
};

enum class GpiodState : std::uint8_t { closed, up, down };
std::string_view to_string(GpiodState s);

class GpiodLines final : public GpioLines {
public:
    GpiodLines(GpiodOptions options, std::shared_ptr<spdlog::logger> log);
    ~GpiodLines() override;  // stops the thread, releases the lines, closes the chip

    // Opens the chip and requests the lines now, on the caller's thread;
    // false (logged, last_error()) leaves the lines `down`. Call before start().
    bool open();
    // Starts the GPIO thread (which reopens on the backoff schedule when down).
    void start();
    void stop();

    std::string_view name() const override { return name_; }
    bool enabled() const override { return enabled_.load(std::memory_order_acquire); }
    bool wait_change(bool seen, std::int64_t timeout_ns) override;
    bool has_trigger() const override { return options_.trigger_line >= 0; }
    bool set_trigger(bool active) override;
    // The camera trigger, from the capture thread (SCHED_FIFO): never waits
    // for the GPIO thread, which holds the lines' mutex while it opens or
    // drops the chip (milliseconds, with log writes). A pulse due then is
    // skipped (false, counted trigger_busy): the lines are changing and it
    // could not go out anyway. A failed write is counted, and logged at
    // most once a second.
    bool pulse(std::uint32_t width_us) override;
    EncoderMode encoder_mode() const override { return options_.encoder; }
    EncoderReading encoder() const override;
    GpioCounters counters() const override;

    GpiodState state() const { return state_.load(std::memory_order_relaxed); }
    // Tests: holds the lines as the GPIO thread does while it reopens them.
    std::unique_lock<std::mutex> hold_lines_for_test() { return std::unique_lock(io_mutex_); }
    // The last failure, "<what> on <chip> line <n>: <strerror> (errno N)"; "" if none.
    std::string last_error() const;

private:
    struct Chip;  // RAII chip + requested lines (gpiod_lines.cpp)

    bool try_open();       // io_mutex_ held
    void go_down(const char* what, int line, int err);  // io_mutex_ held
    void fail(const char* what, int line, int err);
    void run();
    bool handle_events(int which, std::int64_t now_ns);  // false: the lines were lost
    void sample_encoder();
    void publish_enable();
    void set_state(GpiodState s) { state_.store(s, std::memory_order_relaxed); }

    const GpiodOptions options_;
    const std::shared_ptr<spdlog::logger> log_;
    const std::string name_;

    // chip_ lifetime and the trigger line (not the enable path). The
    // capture thread's pulse() only tries it: see pulse().
    std::mutex io_mutex_;
    std::unique_ptr<Chip> chip_;
    std::atomic<GpiodState> state_{GpiodState::closed};
    ReopenBackoff backoff_;  // when the next open is due (reopen_min..reopen_max); io_mutex_ held
    std::int64_t next_health_ns_ = 0;
    bool was_up_ = false;

    EnableDebouncer debouncer_;   // GPIO thread (or open() before start)
    QuadratureDecoder decoder_;   // GPIO thread
    std::atomic<bool> enabled_{false};
    std::atomic<std::int64_t> ticks_{0};
    std::atomic<int> direction_{0};
    std::atomic<std::uint64_t> invalid_{0};

    std::mutex change_mutex_;
    std::condition_variable change_cv_;

    mutable std::mutex error_mutex_;
    std::string last_error_;

    base::UniqueFd stop_fd_;  // eventfd that wakes the thread for stop()
    std::thread thread_;

    std::atomic<std::uint64_t> edges_{0};
    std::atomic<std::uint64_t> bounces_{0};
    std::atomic<std::uint64_t> errors_{0};
    std::atomic<std::uint64_t> reopens_{0};
    std::atomic<std::uint64_t> pulses_{0};
    std::atomic<std::uint64_t> trigger_busy_{0};
    base::LogThrottle trigger_log_;   // pulse()'s failures: the capture thread's
};

}  // namespace stemd::drivers
