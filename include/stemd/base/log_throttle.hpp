// One log line per interval for an event that can come with every frame (a
// corrupt frame, a CAN error frame). The event is counted where it happens;
// the throttle only spares the real-time thread a locked, flushed write to
// the log for each one. The first event is logged at once, later ones at
// most once per interval, each with how many were left out since the last.
#pragma once

#include <cstdint>

namespace stemd::base {

class LogThrottle {
public:
    explicit LogThrottle(std::int64_t interval_ns = 1'000'000'000) : interval_ns_(interval_ns) {}

    // True when the event at now_ns (CLOCK_MONOTONIC) is to be logged;
    // `left_out` is then how many were not logged since the last one that was.
    bool allow(std::int64_t now_ns, std::uint64_t& left_out) noexcept
    {
        if (logged_once_ && now_ns - last_ns_ < interval_ns_) {
            ++left_out_;
            return false;
        }
        left_out = left_out_;
        left_out_ = 0;
        last_ns_ = now_ns;
        logged_once_ = true;
        return true;
    }

private:
    std::int64_t interval_ns_;
    std::int64_t last_ns_ = 0;
    bool logged_once_ = false;
    std::uint64_t left_out_ = 0;
};

}  // namespace stemd::base
