// Odometry ring: interpolation, extrapolation bound, rejection, wrap.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "stemd/geometry/odometry.hpp"

using namespace stemd::geometry;

namespace {
constexpr std::int64_t kMs = 1'000'000;
}

TEST(Odometry, EmptyRingSaysSo)
{
    const OdometryRing ring;
    EXPECT_TRUE(ring.empty());
    EXPECT_EQ(ring.odom_at(0).status, OdomStatus::empty);
    EXPECT_EQ(ring.speed_mm_per_s(100 * kMs), 0);
    EXPECT_EQ(ring.last_speed_mm_per_s(), 0);
}

TEST(Odometry, InterpolatesExactlyOnAKnownTrajectory)
{
    OdometryRing ring({16, 50 * kMs});
    // Accelerate, cruise, stop: 0 -> 5 mm in 10 ms, -> 15 in 10 ms, stand for 20 ms, -> 16 in 8 ms.
    const OdomSample samples[] = {{1000 * kMs, 100}, {1010 * kMs, 105}, {1020 * kMs, 115}, {1040 * kMs, 115},
                                  {1048 * kMs, 116}};
    for (const OdomSample& s : samples)
        ASSERT_TRUE(ring.push(s));
    for (const OdomSample& s : samples) {
        const OdomQuery q = ring.odom_at(s.t_ns);
        EXPECT_EQ(q.status, OdomStatus::ok);
        EXPECT_EQ(q.odom_mm, s.odom_mm);
    }
    EXPECT_EQ(ring.odom_at(1005 * kMs).odom_mm, 102.5);
    EXPECT_EQ(ring.odom_at(1012 * kMs + 500'000).odom_mm, 107.5);
    EXPECT_EQ(ring.odom_at(1030 * kMs).odom_mm, 115);
    EXPECT_EQ(ring.odom_at(1044 * kMs).odom_mm, 115.5);
    EXPECT_EQ(ring.odom_at(1044 * kMs).status, OdomStatus::ok);
    const OdomQuery early = ring.odom_at(999 * kMs);
    EXPECT_EQ(early.status, OdomStatus::before_history);
    EXPECT_EQ(early.odom_mm, 100);
    EXPECT_DOUBLE_EQ(ring.last_speed_mm_per_s(), 125.0);  // 1 mm in 8 ms
}

TEST(Odometry, ExtrapolatesAtTheLastSpeedForABoundedTime)
{
    OdometryRing ring({8, 50 * kMs});
    ASSERT_TRUE(ring.push({0, 0}));
    // One sample: no speed yet, so it holds still.
    EXPECT_EQ(ring.odom_at(10 * kMs).status, OdomStatus::extrapolated);
    EXPECT_EQ(ring.odom_at(10 * kMs).odom_mm, 0);
    ASSERT_TRUE(ring.push({100 * kMs, 50}));   // 500 mm/s
    ASSERT_TRUE(ring.push({200 * kMs, 150}));  // then 1000 mm/s
    EXPECT_DOUBLE_EQ(ring.last_speed_mm_per_s(), 1000);
    const OdomQuery q = ring.odom_at(220 * kMs);
    EXPECT_EQ(q.status, OdomStatus::extrapolated);
    EXPECT_DOUBLE_EQ(q.odom_mm, 170);
    const OdomQuery bound = ring.odom_at(250 * kMs);
    EXPECT_EQ(bound.status, OdomStatus::extrapolated);
    EXPECT_DOUBLE_EQ(bound.odom_mm, 200);
    const OdomQuery stale = ring.odom_at(250 * kMs + 1);
    EXPECT_EQ(stale.status, OdomStatus::stale);
    EXPECT_EQ(stale.odom_mm, 150);  // the newest sample: a lower bound, not to act on

    OdometryRing strict({8, 0});
    ASSERT_TRUE(strict.push({0, 0}));
    ASSERT_TRUE(strict.push({10, 1}));
    EXPECT_EQ(strict.odom_at(10).status, OdomStatus::ok);
    EXPECT_EQ(strict.odom_at(11).status, OdomStatus::stale);
}

TEST(Odometry, RejectsAndCountsNonMonotonicSamples)
{
    OdometryRing ring({8, 50 * kMs});
    ASSERT_TRUE(ring.push({100, 10}));
    EXPECT_FALSE(ring.push({100, 11}));  // same time
    EXPECT_FALSE(ring.push({99, 11}));   // earlier
    EXPECT_FALSE(ring.push({200, 9}));   // odometer going back
    EXPECT_FALSE(ring.push({300, std::numeric_limits<double>::quiet_NaN()}));
    EXPECT_FALSE(ring.push({300, std::numeric_limits<double>::infinity()}));
    EXPECT_EQ(ring.rejected(), 5u);
    EXPECT_EQ(ring.size(), 1u);
    EXPECT_TRUE(ring.push({200, 10}));  // standing still is fine
    EXPECT_EQ(ring.size(), 2u);
    EXPECT_EQ(ring.rejected(), 5u);
}

TEST(Odometry, WrapsAtCapacityKeepingTheNewest)
{
    OdometryRing ring({4, 50 * kMs});
    EXPECT_EQ(ring.capacity(), 4u);
    const ConstantSpeedOdometer source(250, 0, 1000);  // 250 mm/s from 1000 mm
    for (int i = 0; i < 10; ++i)
        ASSERT_TRUE(ring.push(source.sample(i * 4 * kMs)));  // every 4 ms: 1 mm apart
    EXPECT_EQ(ring.size(), 4u);
    EXPECT_EQ(ring.overwritten(), 6u);
    EXPECT_EQ(ring.oldest().t_ns, 24 * kMs);
    EXPECT_EQ(ring.newest().t_ns, 36 * kMs);
    for (std::size_t i = 0; i + 1 < ring.size(); ++i)
        EXPECT_LT(ring.at(i).t_ns, ring.at(i + 1).t_ns);
    EXPECT_EQ(ring.odom_at(23 * kMs).status, OdomStatus::before_history);
    for (std::int64_t t = 24 * kMs; t <= 36 * kMs; t += kMs / 4) {
        const OdomQuery q = ring.odom_at(t);
        EXPECT_EQ(q.status, OdomStatus::ok);
        EXPECT_NEAR(q.odom_mm, source.sample(t).odom_mm, 1e-9) << t;
    }
    // Keep going: still exact after many wraps.
    for (int i = 10; i < 103; ++i)
        ASSERT_TRUE(ring.push(source.sample(i * 4 * kMs)));
    EXPECT_NEAR(ring.odom_at(409 * kMs).odom_mm, source.sample(409 * kMs).odom_mm, 1e-9);
    EXPECT_NEAR(ring.odom_at(420 * kMs).odom_mm, source.sample(420 * kMs).odom_mm, 1e-9);
    EXPECT_EQ(ring.odom_at(420 * kMs).status, OdomStatus::extrapolated);
}

TEST(Odometry, SpeedEstimate)
{
    OdometryRing ring({64, 50 * kMs});
    const ConstantSpeedOdometer source(1234.5, 5 * kMs, 20);
    EXPECT_DOUBLE_EQ(source.speed_mm_per_s(), 1234.5);
    for (int i = 0; i < 40; ++i)
        ASSERT_TRUE(ring.push(source.sample(5 * kMs + i * 3 * kMs)));
    EXPECT_NEAR(ring.speed_mm_per_s(30 * kMs), 1234.5, 1e-6);
    EXPECT_NEAR(ring.speed_mm_per_s(1000 * kMs), 1234.5, 1e-6);  // more than kept: all of it
    EXPECT_NEAR(ring.last_speed_mm_per_s(), 1234.5, 1e-6);
    // Speed change: a short window sees the new speed, a long one the mean.
    OdometryRing change({64, 50 * kMs});
    ASSERT_TRUE(change.push({0, 0}));
    ASSERT_TRUE(change.push({100 * kMs, 100}));  // 1000 mm/s
    ASSERT_TRUE(change.push({200 * kMs, 100}));  // stopped
    EXPECT_DOUBLE_EQ(change.speed_mm_per_s(50 * kMs), 0);
    EXPECT_DOUBLE_EQ(change.speed_mm_per_s(200 * kMs), 500);
}

TEST(Odometry, StatusNames)
{
    EXPECT_EQ(to_string(OdomStatus::ok), "ok");
    EXPECT_EQ(to_string(OdomStatus::stale), "stale");
    EXPECT_EQ(to_string(OdomStatus::before_history), "before_history");
}

// A sample stamped late (a frame delivered late) and the next one on time
// are a few ms apart: the extrapolation must not take their quotient as the
// speed. 700 mm/s at 15 fps; sample 10 stamped 60 ms late.
TEST(Odometry, ExtrapolationIsNotThrownByOneLateStamp)
{
    OdometryRing ring({64, 100 * kMs});
    const double speed_mm_per_s = 700;
    const std::int64_t period_ns = 1'000'000'000 / 15;
    for (int i = 0; i <= 11; ++i) {
        const std::int64_t t_ns = i * period_ns + (i == 10 ? 60 * kMs : 0);
        ASSERT_TRUE(ring.push({t_ns, speed_mm_per_s * static_cast<double>(i * period_ns) * 1e-9}));
    }
    const std::int64_t t_query_ns = 11 * period_ns + 50 * kMs;
    const OdomQuery q = ring.odom_at(t_query_ns);
    ASSERT_EQ(q.status, OdomStatus::extrapolated);
    const double truth_mm = speed_mm_per_s * static_cast<double>(t_query_ns) * 1e-9;
    EXPECT_NEAR(q.odom_mm, truth_mm, 10.0);
}
