// The camera trigger's cadence: one pulse per period, late periods skipped
// and counted, never a burst of catch-up pulses.
#include <gtest/gtest.h>

#include "stemd/runtime/trigger_clock.hpp"

namespace stemd::runtime {
namespace {

constexpr std::int64_t kPeriod = 33'333'333;

TEST(TriggerClock, FirstPulseAtOnceThenOnePerPeriod)
{
    TriggerClock clock(kPeriod);
    EXPECT_TRUE(clock.due(1000));
    clock.fired(1000);
    EXPECT_FALSE(clock.due(1000 + kPeriod - 1));
    EXPECT_EQ(clock.wait_ns(1000 + kPeriod - 10), 10);
    EXPECT_TRUE(clock.due(1000 + kPeriod));
    // Fired a little late: the cadence stays on the original grid.
    clock.fired(1000 + kPeriod + 500);
    EXPECT_EQ(clock.next_ns(), 1000 + 2 * kPeriod);
    EXPECT_EQ(clock.late(), 0u);
}

TEST(TriggerClock, LatePeriodsAreSkippedAndCounted)
{
    TriggerClock clock(kPeriod);
    clock.fired(0);
    // Back only after 3.5 periods: pulse times kPeriod, 2 kPeriod and
    // 3 kPeriod are due; one pulse goes out now, two periods are lost.
    const std::int64_t now = 3 * kPeriod + kPeriod / 2;
    ASSERT_TRUE(clock.due(now));
    clock.fired(now);
    EXPECT_EQ(clock.late(), 2u);
    EXPECT_EQ(clock.next_ns(), 4 * kPeriod);
    EXPECT_FALSE(clock.due(now + 1));
}

TEST(TriggerClock, NonPositivePeriodDoesNotDivideByZero)
{
    TriggerClock clock(0);
    clock.fired(10);
    clock.fired(20);
    EXPECT_TRUE(clock.due(30));
}

}  // namespace
}  // namespace stemd::runtime
