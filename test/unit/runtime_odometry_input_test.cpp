// The actuator's odometer (runtime::OdometryInput) from the frames' own
// odom_mm: under `recording`, and under `auto` once a frame has carried
// it, a frame without it has no odometer (it is not actuated), never one
// from the constant speed, which starts at zero on another scale.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

#include "stemd/runtime/actuation_counters.hpp"
#include "stemd/runtime/odometry_input.hpp"

namespace stemd::runtime {
namespace {

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kT0 = 9'000 * kMs;
const double kNoOdometer = std::nan("");

ActuationConfig odometry(OdometrySource source)
{
    ActuationConfig c;
    c.odometry = source;
    c.speed_mm_per_s = 1388.9;
    c.max_extrapolation_ns = 100 * kMs;
    return c;
}

TEST(OdometryInput, AutoNeverTakesTheConstantSpeedOnceAFrameCarriedItsOdometer)
{
    const ActuationConfig config = odometry(OdometrySource::automatic);
    ActuationCounters counters;
    OdometryInput in(config, counters);
    double odom_mm = 0;
    in.add_frame(kT0, 5000);
    in.add_frame(kT0 + 33 * kMs, 5046);
    in.add_frame(kT0 + 67 * kMs, kNoOdometer);
    // The frame without its cell: no odometer, though one 34 ms past the
    // newest sample could be extrapolated.
    EXPECT_FALSE(in.frame_odometer(kT0 + 67 * kMs, kNoOdometer, odom_mm));
    // The odometer now (the scheduler's) stays on the recording's scale.
    ASSERT_TRUE(in.odometer_at(kT0 + 67 * kMs, odom_mm));
    EXPECT_NEAR(odom_mm, 5046 + 46.0 / 33 * 34, 1.0);
    in.add_frame(kT0 + 100 * kMs, 5138);
    ASSERT_TRUE(in.frame_odometer(kT0 + 100 * kMs, 5138, odom_mm));
    EXPECT_DOUBLE_EQ(odom_mm, 5138);
}

TEST(OdometryInput, AutoWithoutAnyOdometerInTheFramesDrivesAtTheConstantSpeed)
{
    const ActuationConfig config = odometry(OdometrySource::automatic);
    ActuationCounters counters;
    OdometryInput in(config, counters);
    double odom_mm = -1;
    in.add_frame(kT0, kNoOdometer);
    in.add_frame(kT0 + 100 * kMs, kNoOdometer);
    ASSERT_TRUE(in.frame_odometer(kT0 + 100 * kMs, kNoOdometer, odom_mm));
    EXPECT_NEAR(odom_mm, 138.89, 1e-9);
}

TEST(OdometryInput, UnderRecordingAFrameWithoutItsOdometerHasNone)
{
    const ActuationConfig config = odometry(OdometrySource::recording);
    ActuationCounters counters;
    OdometryInput in(config, counters);
    double odom_mm = 0;
    EXPECT_FALSE(in.frame_odometer(kT0, kNoOdometer, odom_mm));   // none yet
    in.add_frame(kT0 + 33 * kMs, 46);
    in.add_frame(kT0 + 67 * kMs, kNoOdometer);
    EXPECT_FALSE(in.frame_odometer(kT0 + 67 * kMs, kNoOdometer, odom_mm));
    ASSERT_TRUE(in.frame_odometer(kT0 + 33 * kMs, 46, odom_mm));
    EXPECT_DOUBLE_EQ(odom_mm, 46);
}

}  // namespace
}  // namespace stemd::runtime
