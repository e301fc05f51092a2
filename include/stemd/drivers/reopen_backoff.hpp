// The reopen schedule every backend with a "close and reopen" state machine
// uses (drivers/v4l2, drivers/libcamera, drivers/socketcan, drivers/gpiod):
// pure timing logic on CLOCK_MONOTONIC ns that the caller passes in, so tests
// drive it with fake time. It opens nothing, logs nothing and keeps no state
// names: each driver keeps its own states and log lines.
//
//   on_failure(now): an attempt (or the running device) failed at `now`; the
//       next attempt is due at now + current_delay_ns(), and the delay then
//       doubles, capped at max_ns. The first failure after construction or
//       after on_success() waits min_ns.
//   due(now):        true from next_attempt_ns() on (exactly at the boundary
//       too); true before any failure.
//   on_success():    the delay starts over at min_ns (a recovery if it
//       followed failures).
//   reset():         the delay starts over at min_ns, nothing counted.
//   retry_now():     the next attempt is due at once (an explicit open());
//       the delay is kept.
//
// max_ns below min_ns is taken as min_ns; negative values as 0. Doubling and
// now + delay saturate at INT64_MAX instead of overflowing. Not thread-safe:
// one thread (the one that reopens) owns it.
#pragma once

#include <chrono>
#include <cstdint>
#include <limits>

namespace stemd::drivers {

class ReopenBackoff {
public:
    constexpr ReopenBackoff(std::int64_t min_ns, std::int64_t max_ns)
        : min_ns_(min_ns > 0 ? min_ns : 0), max_ns_(max_ns > min_ns_ ? max_ns : min_ns_), delay_ns_(min_ns_)
    {
    }
    constexpr ReopenBackoff(std::chrono::nanoseconds min, std::chrono::nanoseconds max)
        : ReopenBackoff(min.count(), max.count())
    {
    }

    constexpr void on_failure(std::int64_t now_ns)
    {
        next_attempt_ns_ = saturating_add(now_ns, delay_ns_);
        delay_ns_ = delay_ns_ >= max_ns_ - delay_ns_ ? max_ns_ : delay_ns_ * 2;
        ++failures_;
        ++consecutive_failures_;
    }
    constexpr void on_success()
    {
        if (consecutive_failures_ > 0)
            ++recoveries_;
        delay_ns_ = min_ns_;
        consecutive_failures_ = 0;
    }
    // The delay starts over at min_ns without a success (counters kept):
    // for an explicit open() that begins a new schedule.
    constexpr void reset()
    {
        delay_ns_ = min_ns_;
        consecutive_failures_ = 0;
    }
    constexpr void retry_now() { next_attempt_ns_ = std::numeric_limits<std::int64_t>::min(); }

    constexpr bool due(std::int64_t now_ns) const { return now_ns >= next_attempt_ns_; }
    // When the next attempt is due (meaningful after a failure).
    constexpr std::int64_t next_attempt_ns() const { return next_attempt_ns_; }
    // How long until the next attempt is due: 0 when due.
    constexpr std::int64_t wait_ns(std::int64_t now_ns) const
    {
        return due(now_ns) ? 0 : next_attempt_ns_ - now_ns;
    }
    // The delay the next on_failure() applies.
    constexpr std::int64_t current_delay_ns() const { return delay_ns_; }
    constexpr std::int64_t min_ns() const { return min_ns_; }
    constexpr std::int64_t max_ns() const { return max_ns_; }

    // Counters: every failure; failures since the last success; successes
    // that followed at least one failure.
    constexpr std::uint64_t failures() const { return failures_; }
    constexpr std::uint32_t consecutive_failures() const { return consecutive_failures_; }
    constexpr std::uint64_t recoveries() const { return recoveries_; }

private:
    static constexpr std::int64_t saturating_add(std::int64_t a, std::int64_t b)  // b >= 0
    {
        return a > std::numeric_limits<std::int64_t>::max() - b ? std::numeric_limits<std::int64_t>::max() : a + b;
    }

    std::int64_t min_ns_;
    std::int64_t max_ns_;
    std::int64_t delay_ns_;
    std::int64_t next_attempt_ns_ = std::numeric_limits<std::int64_t>::min();
    std::uint64_t failures_ = 0;
    std::uint32_t consecutive_failures_ = 0;
    std::uint64_t recoveries_ = 0;
};

}  // namespace stemd::drivers
