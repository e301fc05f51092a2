// The reopen schedule the drivers share (include/stemd/drivers/reopen_backoff.hpp),
// on fake time: the first retry after min, doubling up to the cap, due exactly
// at the boundary, starting over after a success, counters, no overflow.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <limits>

#include "stemd/drivers/reopen_backoff.hpp"

using stemd::drivers::ReopenBackoff;
using namespace std::chrono_literals;

namespace {
constexpr std::int64_t ms = 1'000'000;
constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
}  // namespace

TEST(ReopenBackoff, DueBeforeAnyFailure)
{
    const ReopenBackoff b(10 * ms, 1000 * ms);
    EXPECT_TRUE(b.due(0));
    EXPECT_TRUE(b.due(-1));
    EXPECT_EQ(b.wait_ns(123), 0);
    EXPECT_EQ(b.current_delay_ns(), 10 * ms);
    EXPECT_EQ(b.failures(), 0u);
    EXPECT_EQ(b.consecutive_failures(), 0u);
    EXPECT_EQ(b.recoveries(), 0u);
}

TEST(ReopenBackoff, DoublesFromMinUpToTheCap)
{
    ReopenBackoff b(100 * ms, 1000 * ms);
    std::int64_t t = 5 * ms;
    const std::int64_t expected_ms[] = {100, 200, 400, 800, 1000, 1000, 1000};
    for (const std::int64_t d : expected_ms) {
        EXPECT_EQ(b.current_delay_ns(), d * ms);
        b.on_failure(t);
        EXPECT_EQ(b.next_attempt_ns(), t + d * ms);
        t = b.next_attempt_ns();
    }
    EXPECT_EQ(b.failures(), 7u);
    EXPECT_EQ(b.consecutive_failures(), 7u);
}

TEST(ReopenBackoff, DueExactlyAtTheBoundary)
{
    ReopenBackoff b(10 * ms, 40 * ms);
    b.on_failure(1000);
    EXPECT_FALSE(b.due(1000));
    EXPECT_FALSE(b.due(1000 + 10 * ms - 1));
    EXPECT_EQ(b.wait_ns(1000 + 10 * ms - 1), 1);
    EXPECT_TRUE(b.due(1000 + 10 * ms));
    EXPECT_EQ(b.wait_ns(1000 + 10 * ms), 0);
    EXPECT_TRUE(b.due(1000 + 10 * ms + 1));
}

TEST(ReopenBackoff, SuccessStartsOverAndCountsARecovery)
{
    ReopenBackoff b(10 * ms, 1000 * ms);
    b.on_failure(0);
    b.on_failure(10 * ms);
    b.on_failure(30 * ms);
    EXPECT_EQ(b.current_delay_ns(), 80 * ms);
    b.on_success();
    EXPECT_EQ(b.current_delay_ns(), 10 * ms);
    EXPECT_EQ(b.consecutive_failures(), 0u);
    EXPECT_EQ(b.failures(), 3u);
    EXPECT_EQ(b.recoveries(), 1u);
    b.on_success();  // a success without failures is no recovery
    EXPECT_EQ(b.recoveries(), 1u);
    b.on_failure(100 * ms);
    EXPECT_EQ(b.next_attempt_ns(), 110 * ms);
    EXPECT_EQ(b.consecutive_failures(), 1u);
}

TEST(ReopenBackoff, RetryNowMakesItDueAndKeepsTheDelay)
{
    ReopenBackoff b(10 * ms, 1000 * ms);
    b.on_failure(0);
    EXPECT_FALSE(b.due(5 * ms));
    b.retry_now();
    EXPECT_TRUE(b.due(5 * ms));
    EXPECT_EQ(b.current_delay_ns(), 20 * ms);
}

TEST(ReopenBackoff, ChronoConstructorAndOddLimits)
{
    const ReopenBackoff c(100ms, 5s);
    EXPECT_EQ(c.min_ns(), 100 * ms);
    EXPECT_EQ(c.max_ns(), 5000 * ms);
    const ReopenBackoff inverted(50 * ms, 10 * ms);  // max below min: min
    EXPECT_EQ(inverted.max_ns(), 50 * ms);
    ReopenBackoff zero(0, 0);  // retries at once, always
    zero.on_failure(7);
    EXPECT_TRUE(zero.due(7));
    EXPECT_EQ(zero.current_delay_ns(), 0);
    const ReopenBackoff negative(-5, -1);
    EXPECT_EQ(negative.min_ns(), 0);
    EXPECT_EQ(negative.max_ns(), 0);
}

TEST(ReopenBackoff, NoOverflowWithAHugeMax)
{
    ReopenBackoff b(1, kMax);
    std::int64_t previous = 0;
    for (int i = 0; i < 200; ++i) {
        b.on_failure(1'000);
        EXPECT_GE(b.current_delay_ns(), previous);
        EXPECT_GT(b.current_delay_ns(), 0);
        EXPECT_GE(b.next_attempt_ns(), 1'000);
        previous = b.current_delay_ns();
    }
    EXPECT_EQ(b.current_delay_ns(), kMax);
    b.on_failure(1'000);  // now + INT64_MAX saturates
    EXPECT_EQ(b.next_attempt_ns(), kMax);
    EXPECT_FALSE(b.due(kMax - 1));
    EXPECT_TRUE(b.due(kMax));

    ReopenBackoff late(kMax / 2 + 1, kMax);  // doubling would overflow: capped instead
    late.on_failure(0);
    EXPECT_EQ(late.current_delay_ns(), kMax);
}

static_assert([] {
    ReopenBackoff b(2, 5);
    b.on_failure(0);
    b.on_failure(2);
    b.on_failure(6);
    return b.next_attempt_ns() == 11 && b.current_delay_ns() == 5;  // 2, 4, then capped at 5
}());

TEST(ReopenBackoff, ResetStartsOverWithoutARecovery)
{
    ReopenBackoff b(10 * ms, 1000 * ms);
    b.on_failure(0);
    b.on_failure(10 * ms);
    b.reset();
    EXPECT_EQ(b.current_delay_ns(), 10 * ms);
    EXPECT_EQ(b.consecutive_failures(), 0u);
    EXPECT_EQ(b.failures(), 2u);
    EXPECT_EQ(b.recoveries(), 0u);
}
