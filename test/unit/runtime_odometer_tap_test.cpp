// The recorder's odometer (runtime::OdometerTap) on ODOMETRY frames with
// known receive times and on encoder counts read at known times: interpolated at a capture between two samples,
// waited for while the bus speaks, extrapolated only as far as the daemon
// would, never across a silence or a reversal; bad frames refused. The
// receiving thread on a real bus: vm.record_odometry (stemd-record on vcan0).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <thread>

#include "stemd/protocol/messages.hpp"
#include "stemd/runtime/odometer_tap.hpp"
#include "fake_can_bus.hpp"
#include "fake_gpio_lines.hpp"

namespace stemd::runtime {
namespace {

using Reading = OdometerTap::Reading;

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kT0 = 7'000 * kMs;

class OdometerTapTest : public ::testing::Test {
protected:
    OdometerTapTest()
    {
        auto bus = std::make_unique<test::FakeCanBus>();
        bus_ = bus.get();
        tap_ = std::make_unique<OdometerTap>(std::move(bus), ids_,
                                             OdometerTapParams{.timeout_ns = 500 * kMs,
                                                               .max_extrapolation_ns = 100 * kMs,
                                                               .capacity = 64});
    }

    // An ODOMETRY frame as the drive sends it, received at t_rx_ns.
    void drive_says(std::uint32_t odom_mm, std::int64_t t_rx_ns)
    {
        protocol::CanFrame f;
        ASSERT_TRUE(protocol::encode(protocol::Odometry{.odom_mm = odom_mm, .speed_mm_per_s = 1400},
                                     counter_.next(), ids_, f));
        bus_->inbox.push_back(f);
        bus_->inbox_t_rx_ns.push_back(t_rx_ns);
        tap_->receive(0);
    }

    Reading read(std::int64_t t_ns, std::int64_t now_ns)
    {
        odom_mm_ = std::nan("");
        return tap_->odometer_at(t_ns, now_ns, odom_mm_);
    }

    const protocol::CanIds ids_ = *protocol::CanIds::make(0x300);
    protocol::E2eCounter counter_;
    test::FakeCanBus* bus_ = nullptr;
    std::unique_ptr<OdometerTap> tap_;
    double odom_mm_ = 0;
};

TEST_F(OdometerTapTest, ACaptureBetweenTwoSamplesIsInterpolated)
{
    drive_says(1000, kT0);
    drive_says(1014, kT0 + 10 * kMs);
    drive_says(1028, kT0 + 20 * kMs);
    // 15 ms: halfway from 1014 to 1028.
    ASSERT_EQ(read(kT0 + 15 * kMs, kT0 + 21 * kMs), Reading::known);
    EXPECT_DOUBLE_EQ(odom_mm_, 1021.0);
    ASSERT_EQ(read(kT0 + 10 * kMs, kT0 + 21 * kMs), Reading::known);
    EXPECT_DOUBLE_EQ(odom_mm_, 1014.0);
    EXPECT_EQ(tap_->counters().samples, 3u);
}

TEST_F(OdometerTapTest, ACaptureAfterTheNewestSampleWaitsForTheNextWhileTheBusSpeaks)
{
    drive_says(1000, kT0);
    drive_says(1014, kT0 + 10 * kMs);
    EXPECT_EQ(read(kT0 + 15 * kMs, kT0 + 16 * kMs), Reading::wait);
    // Still speaking 90 ms later (its last sample 10 ms ago): still worth waiting.
    drive_says(1140, kT0 + 100 * kMs);
    EXPECT_EQ(read(kT0 + 105 * kMs, kT0 + 110 * kMs), Reading::wait);
    drive_says(1154, kT0 + 110 * kMs);
    ASSERT_EQ(read(kT0 + 105 * kMs, kT0 + 111 * kMs), Reading::known);
    EXPECT_DOUBLE_EQ(odom_mm_, 1147.0);
}

TEST_F(OdometerTapTest, AQuietBusIsExtrapolatedOnlyAsFarAsTheDaemonWould)
{
    drive_says(1000, kT0);
    drive_says(1014, kT0 + 10 * kMs);   // 1.4 mm/ms
    // Nothing for 190 ms (over max_extrapolation): not worth waiting. A
    // capture 40 ms past the newest sample takes its speed, as the
    // actuator's odometer would.
    ASSERT_EQ(read(kT0 + 50 * kMs, kT0 + 200 * kMs), Reading::known);
    EXPECT_NEAR(odom_mm_, 1014.0 + 1.4 * 40, 1e-9);
    // 140 ms past it: the daemon would call it stale.
    EXPECT_EQ(read(kT0 + 150 * kMs, kT0 + 200 * kMs), Reading::unknown);
}

TEST_F(OdometerTapTest, AWaitEndsWhenTheBusFallsQuiet)
{
    drive_says(1000, kT0);
    drive_says(1014, kT0 + 10 * kMs);
    EXPECT_EQ(read(kT0 + 20 * kMs, kT0 + 60 * kMs), Reading::wait);
    // 101 ms after its last sample the bus counts as quiet: the capture,
    // 10 ms past that sample, is extrapolated instead of waited for.
    ASSERT_EQ(read(kT0 + 20 * kMs, kT0 + 111 * kMs), Reading::known);
    EXPECT_NEAR(odom_mm_, 1028.0, 1e-9);
}

TEST_F(OdometerTapTest, ASilenceLongerThanTheTimeoutIsNotBridged)
{
    drive_says(1000, kT0);
    drive_says(1700, kT0 + 1000 * kMs);   // a second of silence (timeout 500 ms)
    EXPECT_EQ(read(kT0 + 500 * kMs, kT0 + 1001 * kMs), Reading::unknown);
    drive_says(1714, kT0 + 1010 * kMs);
    ASSERT_EQ(read(kT0 + 1005 * kMs, kT0 + 1011 * kMs), Reading::known);
    EXPECT_DOUBLE_EQ(odom_mm_, 1707.0);
}

TEST_F(OdometerTapTest, NoReadingWhileTheMachineReversesUntilItPassesItsHighestReadingAgain)
{
    drive_says(1000, kT0);
    drive_says(1014, kT0 + 10 * kMs);
    drive_says(1010, kT0 + 20 * kMs);   // backing up
    drive_says(1000, kT0 + 30 * kMs);
    drive_says(1012, kT0 + 40 * kMs);   // forward again, not yet past 1014
    drive_says(1026, kT0 + 50 * kMs);
    drive_says(1040, kT0 + 60 * kMs);
    for (const std::int64_t t : {15 * kMs, 25 * kMs, 35 * kMs})
        EXPECT_EQ(read(kT0 + t, kT0 + 61 * kMs), Reading::unknown) << t / kMs << " ms";
    ASSERT_EQ(read(kT0 + 55 * kMs, kT0 + 61 * kMs), Reading::known);
    EXPECT_DOUBLE_EQ(odom_mm_, 1033.0);
    EXPECT_EQ(tap_->counters().backwards, 3u);   // 1010, 1000, 1012: all below 1014
}

TEST_F(OdometerTapTest, FramesWithABadCrcOrACounterJumpAreRefusedAndCounted)
{
    drive_says(1000, kT0);
    protocol::CanFrame f;
    ASSERT_TRUE(protocol::encode(protocol::Odometry{.odom_mm = 5000, .speed_mm_per_s = 1400}, counter_.next(), ids_, f));
    f.data[0] ^= 0x01;   // the CRC
    bus_->inbox.push_back(f);
    bus_->inbox_t_rx_ns.push_back(kT0 + 10 * kMs);
    for (int i = 0; i < 5; ++i)
        counter_.next();   // a jump of 6
    ASSERT_TRUE(protocol::encode(protocol::Odometry{.odom_mm = 6000, .speed_mm_per_s = 1400}, counter_.next(), ids_, f));
    bus_->inbox.push_back(f);
    bus_->inbox_t_rx_ns.push_back(kT0 + 20 * kMs);
    tap_->receive(0);
    EXPECT_EQ(tap_->counters().rejected, 2u);
    EXPECT_EQ(tap_->counters().samples, 1u);
    // Neither moved the odometer: nothing after 1000 mm at kT0.
    EXPECT_NE(read(kT0 + 15 * kMs, kT0 + 16 * kMs), Reading::known);
}

TEST_F(OdometerTapTest, TheOdometerRunsOnThroughItsWrap)
{
    drive_says(0xFFFFFFF0u, kT0);
    drive_says(0x00000004u, kT0 + 10 * kMs);   // 20 mm further, past 2^32
    ASSERT_EQ(read(kT0 + 5 * kMs, kT0 + 11 * kMs), Reading::known);
    EXPECT_DOUBLE_EQ(odom_mm_, 4294967280.0 + 10.0);
}

TEST_F(OdometerTapTest, ABusThatNeverSpokeIsNotWaitedFor)
{
    EXPECT_EQ(read(kT0, kT0 + 1 * kMs), Reading::unknown);
}

TEST_F(OdometerTapTest, OtherFramesOnTheBusAreNotOdometry)
{
    drive_says(1000, kT0);
    protocol::CanFrame f;
    ASSERT_TRUE(protocol::encode(protocol::Heartbeat{}, 0, ids_, f));
    bus_->inbox.push_back(f);
    bus_->inbox_t_rx_ns.push_back(kT0 + 10 * kMs);
    tap_->receive(0);
    EXPECT_EQ(tap_->counters().samples, 1u);
    EXPECT_EQ(tap_->counters().rejected, 0u);
}

TEST_F(OdometerTapTest, ItsThreadHandsTheSamplesToTheReader)
{
    // Queued before the thread starts: from then on only it reads the bus.
    for (int i = 0; i < 3; ++i) {
        protocol::CanFrame f;
        ASSERT_TRUE(protocol::encode(protocol::Odometry{.odom_mm = static_cast<std::uint32_t>(1000 + 14 * i),
                                                        .speed_mm_per_s = 1400},
                                     counter_.next(), ids_, f));
        bus_->inbox.push_back(f);
        bus_->inbox_t_rx_ns.push_back(kT0 + i * 10 * kMs);
    }
    tap_->start();
    // The reader asks as the writer thread does, until the thread has
    // delivered (the bus counts as speaking: `now` is the newest sample's).
    Reading r = Reading::wait;
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while ((r = read(kT0 + 15 * kMs, kT0 + 20 * kMs)) != Reading::known && std::chrono::steady_clock::now() < give_up)
        std::this_thread::yield();
    tap_->stop();
    ASSERT_EQ(r, Reading::known);
    EXPECT_DOUBLE_EQ(odom_mm_, 1021.0);
    EXPECT_EQ(tap_->counters().samples, 3u);
}

// The wheel encoder: its count read at known times, 0.1 mm a tick.
class OdometerTapEncoderTest : public ::testing::Test {
protected:
    OdometerTapEncoderTest()
    {
        auto lines = std::make_unique<test::FakeGpioLines>();
        lines_ = lines.get();
        tap_ = std::make_unique<OdometerTap>(std::move(lines), 0.1,
                                             OdometerTapParams{.timeout_ns = 500 * kMs,
                                                               .max_extrapolation_ns = 100 * kMs,
                                                               .capacity = 64});
    }
    void count_at(std::int64_t ticks, std::int64_t t_ns)
    {
        lines_->ticks.store(ticks);
        tap_->read_encoder(t_ns);
    }

    test::FakeGpioLines* lines_ = nullptr;
    std::unique_ptr<OdometerTap> tap_;
    double odom_mm_ = 0;
};

TEST_F(OdometerTapEncoderTest, ACaptureBetweenTwoReadingsIsInterpolatedInMillimetres)
{
    count_at(10000, kT0);            // 1000 mm
    count_at(10140, kT0 + 10 * kMs);  // 1014 mm
    ASSERT_EQ(tap_->odometer_at(kT0 + 5 * kMs, kT0 + 11 * kMs, odom_mm_), OdometerTap::Reading::known);
    EXPECT_NEAR(odom_mm_, 1007.0, 1e-9);
    EXPECT_EQ(tap_->counters().samples, 2u);
}

TEST_F(OdometerTapEncoderTest, AnEncoderCountingBackIsNotUsedUntilItPassesItsHighestCountAgain)
{
    count_at(10000, kT0);
    count_at(9900, kT0 + 10 * kMs);   // reversing
    count_at(10100, kT0 + 20 * kMs);
    count_at(10200, kT0 + 30 * kMs);
    EXPECT_EQ(tap_->odometer_at(kT0 + 5 * kMs, kT0 + 31 * kMs, odom_mm_), OdometerTap::Reading::unknown);
    EXPECT_EQ(tap_->odometer_at(kT0 + 15 * kMs, kT0 + 31 * kMs, odom_mm_), OdometerTap::Reading::unknown);
    ASSERT_EQ(tap_->odometer_at(kT0 + 25 * kMs, kT0 + 31 * kMs, odom_mm_), OdometerTap::Reading::known);
    EXPECT_NEAR(odom_mm_, 1015.0, 1e-9);
    EXPECT_EQ(tap_->counters().backwards, 1u);
}

}  // namespace
}  // namespace stemd::runtime
