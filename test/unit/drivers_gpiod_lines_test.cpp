// GpiodLines where the host has no such GPIO chip (build and CI machines): a
// clear error naming the chip and errno, the lines `down`, enable off
// (fail-safe), the trigger refused and counted; the thread retries without
// crashing and stops cleanly. The real lines: test/vm/gpiod_check.cpp.
#include <gtest/gtest.h>

#ifdef STEMD_HAVE_LIBGPIOD

#include <atomic>
#include <chrono>
#include <sstream>
#include <thread>

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include "gpiod/gpiod_lines.hpp"
#include "captured_log.hpp"

using namespace stemd::drivers;

namespace {

using stemd::test::CapturedLog;

GpiodOptions missing_chip()
{
    GpiodOptions o;
    o.chip = "stemd-no-such-gpiochip";
    o.enable_line = 3;
    o.trigger_line = 0;
    o.reopen_min_ns = 1'000'000;
    o.reopen_max_ns = 4'000'000;
    return o;
}

}  // namespace

TEST(GpiodLines, MissingChipIsAClearError)
{
    CapturedLog log;
    GpiodLines lines(missing_chip(), log.logger);
    EXPECT_EQ(lines.name(), "gpiod:stemd-no-such-gpiochip");
    EXPECT_FALSE(lines.open());
    EXPECT_EQ(lines.state(), GpiodState::down);
    const std::string err = lines.last_error();
    EXPECT_NE(err.find("stemd-no-such-gpiochip"), std::string::npos) << err;
    EXPECT_NE(err.find("gpiod_chip_open_lookup"), std::string::npos) << err;
    EXPECT_NE(err.find("errno"), std::string::npos) << err;
    EXPECT_NE(log.text().find("stemd-no-such-gpiochip"), std::string::npos) << log.text();
    EXPECT_FALSE(lines.enabled());
    EXPECT_FALSE(lines.set_trigger(true));
    EXPECT_FALSE(lines.pulse(10));
    EXPECT_GE(lines.counters().errors, 2U);
    EXPECT_EQ(lines.counters().trigger_pulses, 0U);
}

TEST(GpiodLines, RetriesInTheBackgroundAndStops)
{
    CapturedLog log;
    GpiodLines lines(missing_chip(), log.logger);
    lines.start();
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    EXPECT_FALSE(lines.wait_change(false, 5'000'000));  // stays disabled
    EXPECT_EQ(lines.state(), GpiodState::down);
    EXPECT_GE(lines.counters().errors, 3U);  // several reopen attempts...
    lines.stop();                            // (the log is read once the thread is gone)
    std::size_t logged = 0;
    for (std::size_t pos = 0; (pos = log.text().find("gpiod_chip_open_lookup", pos)) != std::string::npos; ++pos)
        ++logged;
    EXPECT_EQ(logged, 1U);  // ...logged once
}

TEST(GpiodLines, EncoderOptionsAreChecked)
{
    CapturedLog log;
    GpiodOptions o = missing_chip();
    o.encoder = EncoderMode::quadrature;
    o.encoder_a_line = 1;  // no B
    GpiodLines lines(o, log.logger);
    EXPECT_FALSE(lines.open());
    EXPECT_NE(lines.last_error().find("encoder_b_line"), std::string::npos) << lines.last_error();
}

TEST(GpiodLines, ATriggerPulseDueWhileTheLinesAreBeingReopenedIsSkippedNotWaitedFor)
{
    CapturedLog log;
    GpiodLines lines(missing_chip(), log.logger);
    std::uint64_t errors_before = 0;
    {
        auto held = lines.hold_lines_for_test();
        // The capture thread's two pulses must return while the lines are
        // held; one that waited would return only after the release below
        // (and then fail for the missing chip, not as busy).
        std::atomic<bool> returned{false};
        std::thread capture([&] {
            EXPECT_FALSE(lines.pulse(10));
            EXPECT_FALSE(lines.pulse(10));
            returned.store(true);
        });
        const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(5);
        while (!returned.load() && std::chrono::steady_clock::now() < give_up)
            std::this_thread::yield();
        EXPECT_TRUE(returned.load()) << "pulse() waited for the lines";
        held.unlock();
        capture.join();
        errors_before = lines.counters().errors;
    }
    const GpioCounters c = lines.counters();
    EXPECT_EQ(c.trigger_busy, 2U);
    EXPECT_EQ(c.trigger_pulses, 0U);
    // Once the lines are free again a pulse is tried (and fails here: no chip).
    EXPECT_FALSE(lines.pulse(10));
    EXPECT_EQ(lines.counters().trigger_busy, 2U);
    EXPECT_EQ(lines.counters().errors, errors_before + 1);
}

#else

TEST(GpiodLines, NotBuilt) { GTEST_SKIP() << "libgpiod 1.x was missing when CMake configured"; }

#endif
