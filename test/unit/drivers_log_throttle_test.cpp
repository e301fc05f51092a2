// The log throttle the frame sources and the CAN bus use for per-frame
// warnings.
#include <gtest/gtest.h>

#include "stemd/base/log_throttle.hpp"

using stemd::base::LogThrottle;

TEST(LogThrottle, TheFirstEventIsLoggedThenOnePerIntervalWithTheCountLeftOut)
{
    constexpr std::int64_t kMs = 1'000'000;
    LogThrottle throttle(1000 * kMs);
    std::uint64_t left_out = 99;
    ASSERT_TRUE(throttle.allow(5 * kMs, left_out));
    EXPECT_EQ(left_out, 0u);
    // 30 events a second for two seconds: one line a second.
    int logged = 0;
    for (int k = 1; k <= 60; ++k) {
        const std::int64_t t = 5 * kMs + k * 1000 * kMs / 30;
        if (throttle.allow(t, left_out)) {
            ++logged;
            EXPECT_EQ(left_out, 29u) << "at event " << k;
        }
    }
    EXPECT_EQ(logged, 2);
    // A quiet spell, then one event: logged at once, none left out since
    // the last line.
    ASSERT_TRUE(throttle.allow(60'000 * kMs, left_out));
    EXPECT_EQ(left_out, 0u);
}

TEST(LogThrottle, AnEventAtTimeZeroIsLogged)
{
    LogThrottle throttle;
    std::uint64_t left_out = 0;
    EXPECT_TRUE(throttle.allow(0, left_out));
    EXPECT_FALSE(throttle.allow(1, left_out));
    EXPECT_TRUE(throttle.allow(1'000'000'000, left_out));
    EXPECT_EQ(left_out, 1u);
}
