// The GPIO lines' pure logic (include/stemd/drivers/gpio_lines.hpp), no chip
// needed: the quadrature decoding table (all 16 transitions, invalid double
// steps counted) and the enable input's asymmetric debouncing. The real
// lines run on gpio-sim in the VM (test/vm/gpiod_check.cpp, ctest vm.gpiod).
#include <gtest/gtest.h>

#include <cstdint>

#include "stemd/drivers/gpio_lines.hpp"

using namespace stemd::drivers;

namespace {

constexpr std::uint8_t ab(int a, int b) { return static_cast<std::uint8_t>((a << 1) | b); }
constexpr std::int64_t kMs = 1'000'000;

}  // namespace

TEST(GpiodQuadrature, FullTransitionTable)
{
    // Forward (A leads B): 00 -> 10 -> 11 -> 01 -> 00.
    const std::uint8_t fwd[4] = {ab(0, 0), ab(1, 0), ab(1, 1), ab(0, 1)};
    int checked = 0;
    for (int i = 0; i < 4; ++i) {
        const std::uint8_t s = fwd[i];
        const std::uint8_t next = fwd[(i + 1) % 4];
        const std::uint8_t prev = fwd[(i + 3) % 4];
        const std::uint8_t opposite = fwd[(i + 2) % 4];
        EXPECT_EQ(quad_step(s, s), QuadStep::none) << int(s);
        EXPECT_EQ(quad_step(s, next), QuadStep::forward) << int(s) << "->" << int(next);
        EXPECT_EQ(quad_step(s, prev), QuadStep::backward) << int(s) << "->" << int(prev);
        EXPECT_EQ(quad_step(s, opposite), QuadStep::invalid) << int(s) << "->" << int(opposite);
        checked += 4;
    }
    EXPECT_EQ(checked, 16);
    // Spot checks in A/B terms: A rising while B low is forward; B rising while A low is backward.
    static_assert(quad_step(ab(0, 0), ab(1, 0)) == QuadStep::forward);
    static_assert(quad_step(ab(0, 0), ab(0, 1)) == QuadStep::backward);
    static_assert(quad_step(ab(0, 0), ab(1, 1)) == QuadStep::invalid);
    static_assert(quad_step(ab(1, 0), ab(0, 1)) == QuadStep::invalid);
}

TEST(GpiodQuadrature, DecoderCountsForwardThenBack)
{
    const std::uint8_t fwd[4] = {ab(0, 0), ab(1, 0), ab(1, 1), ab(0, 1)};
    QuadratureDecoder d;
    d.reset(ab(0, 0));
    int pos = 0;
    for (int i = 0; i < 10; ++i) {  // 10 edges forward
        pos = (pos + 1) % 4;
        EXPECT_EQ(d.sample(fwd[pos]), QuadStep::forward);
    }
    EXPECT_EQ(d.ticks(), 10);
    EXPECT_EQ(d.last_direction(), QuadStep::forward);
    for (int i = 0; i < 4; ++i) {  // 4 back
        pos = (pos + 3) % 4;
        EXPECT_EQ(d.sample(fwd[pos]), QuadStep::backward);
    }
    EXPECT_EQ(d.ticks(), 6);
    EXPECT_EQ(d.last_direction(), QuadStep::backward);
    EXPECT_EQ(d.invalid(), 0U);
    // Repeated samples (an edge seen twice) count nothing.
    EXPECT_EQ(d.sample(fwd[pos]), QuadStep::none);
    EXPECT_EQ(d.ticks(), 6);
}

TEST(GpiodQuadrature, DoubleStepsAreCountedNotApplied)
{
    QuadratureDecoder d;
    d.reset(ab(0, 0));
    EXPECT_EQ(d.sample(ab(1, 1)), QuadStep::invalid);  // both lines changed: an edge was missed
    EXPECT_EQ(d.ticks(), 0);
    EXPECT_EQ(d.invalid(), 1U);
    EXPECT_EQ(d.state(), ab(1, 1));  // resynchronised on the new state
    EXPECT_EQ(d.sample(ab(0, 1)), QuadStep::forward);
    EXPECT_EQ(d.ticks(), 1);
    EXPECT_EQ(d.sample(ab(1, 0)), QuadStep::invalid);
    EXPECT_EQ(d.invalid(), 2U);
    EXPECT_EQ(d.ticks(), 1);
}

TEST(GpiodDebounce, EnablesOnlyAfterStableActive)
{
    EnableDebouncer d(20 * kMs);
    d.reset(false, 0);
    EXPECT_FALSE(d.enabled());
    EXPECT_EQ(d.next_deadline_ns(), -1);
    d.sample(true, 100 * kMs);
    EXPECT_FALSE(d.enabled());
    EXPECT_EQ(d.next_deadline_ns(), 120 * kMs);
    d.on_time(119 * kMs);
    EXPECT_FALSE(d.enabled());
    d.on_time(120 * kMs);
    EXPECT_TRUE(d.enabled());
    EXPECT_EQ(d.next_deadline_ns(), -1);
    EXPECT_EQ(d.bounces(), 0U);
}

TEST(GpiodDebounce, DisablesAtOnce)
{
    EnableDebouncer d(20 * kMs);
    d.reset(true, 0);
    d.on_time(20 * kMs);
    ASSERT_TRUE(d.enabled());
    d.sample(false, 21 * kMs);  // e-stop: no debounce on the safe side
    EXPECT_FALSE(d.enabled());
    EXPECT_EQ(d.bounces(), 0U);
}

TEST(GpiodDebounce, BouncesRestartTheWait)
{
    EnableDebouncer d(20 * kMs);
    d.reset(false, 0);
    d.sample(true, 10 * kMs);
    d.sample(false, 15 * kMs);  // bounce
    d.sample(true, 18 * kMs);
    d.on_time(30 * kMs);        // 20 ms after the first rise, but only 12 after the last
    EXPECT_FALSE(d.enabled());
    EXPECT_EQ(d.bounces(), 1U);
    d.sample(true, 33 * kMs);   // repeated active level does not restart the wait
    d.on_time(38 * kMs);
    EXPECT_TRUE(d.enabled());
}

TEST(GpiodDebounce, ZeroDebounceFollowsAtOnceAndForceDisables)
{
    EnableDebouncer d(0);
    d.reset(true, 5);
    EXPECT_TRUE(d.enabled());
    d.force_disabled();
    EXPECT_FALSE(d.enabled());
    d.sample(true, 6);
    EXPECT_TRUE(d.enabled());
}
