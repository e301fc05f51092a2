// The one clock of stemd: CLOCK_MONOTONIC, in nanoseconds. Capture times,
// deadlines, timeouts and latencies all come from it, so they compare.
#pragma once

#include <cstdint>

#include <time.h>

namespace stemd::base {

inline std::int64_t monotonic_ns()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace stemd::base
