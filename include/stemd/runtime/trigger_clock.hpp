// When to pulse the camera trigger output (gpio.trigger_line): once per
// frame period (1 / source.fps), on the capture thread, before it waits for
// the frame the pulse asks for. Pure logic on CLOCK_MONOTONIC ns, so the
// schedule is tested without a clock.
//
// Pulses keep a fixed cadence (t0, t0 + T, t0 + 2T, ...). When the thread
// comes back too late for one or more pulse times, those periods are
// skipped (counted in late()) and the cadence resumes from the next one:
// never a burst of catch-up pulses.
#pragma once

#include <algorithm>
#include <cstdint>

namespace stemd::runtime {

class TriggerClock {
public:
    explicit TriggerClock(std::int64_t period_ns) : period_ns_(std::max<std::int64_t>(period_ns, 1)) {}

    // True when a pulse is due at now_ns (the first call is always due).
    bool due(std::int64_t now_ns) const { return next_ns_ < 0 || now_ns >= next_ns_; }

    // A pulse went out at now_ns: schedules the next one.
    void fired(std::int64_t now_ns)
    {
        if (next_ns_ < 0) {
            next_ns_ = now_ns + period_ns_;
            return;
        }
        const std::int64_t periods_behind = (now_ns - next_ns_) / period_ns_;
        late_ += static_cast<std::uint64_t>(periods_behind);
        next_ns_ += (periods_behind + 1) * period_ns_;
    }

    // Time until the next pulse (0 if due): how long the capture thread may wait.
    std::int64_t wait_ns(std::int64_t now_ns) const { return next_ns_ < 0 ? 0 : std::max<std::int64_t>(next_ns_ - now_ns, 0); }
    std::int64_t next_ns() const { return next_ns_; }
    std::uint64_t late() const { return late_; }

private:
    std::int64_t period_ns_;
    std::int64_t next_ns_ = -1;
    std::uint64_t late_ = 0;
};

}  // namespace stemd::runtime
