// The one clock of stemd: CLOCK_MONOTONIC, in nanoseconds. Capture times,
// deadlines, timeouts and latencies all come from it, so they compare; the
// sleeps below run on it too.
#pragma once

#include <cerrno>
#include <cstdint>

#include <time.h>

namespace stemd::base {

inline std::int64_t monotonic_ns()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// Sleeps `ns` on CLOCK_MONOTONIC, resuming after signals with what is left.
inline void sleep_for_ns(std::int64_t ns)
{
    if (ns <= 0)
        return;
    timespec ts{static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, &ts) == EINTR) {
    }
}

// Sleeps until monotonic_ns() reaches `t_ns` (at once if it has).
inline void sleep_until_ns(std::int64_t t_ns)
{
    if (t_ns <= 0)
        return;
    const timespec ts{static_cast<time_t>(t_ns / 1'000'000'000), static_cast<long>(t_ns % 1'000'000'000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
}

}  // namespace stemd::base
