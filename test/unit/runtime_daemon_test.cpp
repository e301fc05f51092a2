// The daemon's threads with a scripted source: overflow policies and their
// counters, back-pressure, end of stream, and a prompt stop.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <thread>

#include <opencv2/core/utility.hpp>

#include "runtime_test_util.hpp"
#include "stemd/runtime/daemon.hpp"
#include "stemd/runtime/actuation_stage.hpp"
#include "stemd/protocol/messages.hpp"
#include "fake_can_bus.hpp"
#include "fake_gpio_lines.hpp"
#include "stemd/runtime/logging.hpp"
#include "stemd/base/clock.hpp"

using namespace stemd;
using namespace std::chrono_literals;

namespace {

// Delivers `frames` frames as fast as asked (or endlessly with frames < 0),
// without touching the pixels; each frame's name is its number.
class ScriptedSource final : public drivers::FrameSource {
public:
    ScriptedSource(long frames, bool realtime) : frames_(frames), realtime_(realtime) {}
    std::string_view name() const override { return "scripted"; }
    bool open() override { return true; }
    bool start() override { return true; }
    drivers::NextStatus next(drivers::Frame& into, std::chrono::nanoseconds) override
    {
        if (frames_ >= 0 && next_ >= frames_)
            return drivers::NextStatus::end_of_stream;
        into.t_sample_ns = stemd::base::monotonic_ns();
        into.t_recorded_ns = next_;
        into.source_seq = static_cast<std::uint64_t>(next_);
        ++next_;
        delivered_.fetch_add(1);
        return drivers::NextStatus::frame;
    }
    void stop() override {}
    drivers::SourceCounters counters() const override { return {.delivered = delivered_.load()}; }
    bool realtime() const override { return realtime_; }

private:
    const long frames_;
    const bool realtime_;
    long next_ = 0;
    std::atomic<std::uint64_t> delivered_{0};
};

runtime::DaemonConfig config_for(runtime::OverflowPolicy policy)
{
    runtime::DaemonConfig config;
    // Full-size frames: detect() takes a millisecond or more, the scripted
    // source microseconds, so a realtime source overflows the ring.
    config.frame_size = {1296, 966};
    config.ring_capacity = 2;
    config.results_capacity = 2;
    config.overflow = policy;
    return config;
}

struct DaemonRun {
    std::unique_ptr<runtime::Daemon> daemon;
    runtime::StatusSnapshot end;
};

DaemonRun run_to_end(const runtime::DaemonConfig& config, long frames, bool realtime)
{
    DaemonRun run;
    run.daemon = std::make_unique<runtime::Daemon>(config, std::make_unique<ScriptedSource>(frames, realtime),
                                                   std::make_unique<runtime::DetectionSink>(
                                                       runtime::make_logger("actuator")));
    EXPECT_TRUE(run.daemon->start());
    EXPECT_TRUE(test::wait_for([&] { return run.daemon->finished(); }, 120s));
    EXPECT_TRUE(run.daemon->join());
    run.end = run.daemon->snapshot(true);
    return run;
}

}  // namespace

TEST(Daemon, EachOverflowPolicyCountsEveryFrameItDoesNotProcess)
{
    constexpr long kFrames = 300;
    for (const auto policy : {runtime::OverflowPolicy::drop_newest, runtime::OverflowPolicy::overwrite_oldest}) {
        const bool drop_newest = policy == runtime::OverflowPolicy::drop_newest;
        SCOPED_TRACE(drop_newest ? "drop_newest" : "overwrite_oldest");
        const DaemonRun run = run_to_end(config_for(policy), kFrames, true);
        // The policy's own drop counter, and the other policy's.
        const std::uint64_t dropped = drop_newest ? run.end.ring_full : run.end.overwritten;
        const std::uint64_t other = drop_newest ? run.end.overwritten : run.end.ring_full;
        EXPECT_EQ(run.end.frames_in, static_cast<std::uint64_t>(kFrames));
        EXPECT_GT(dropped, 0u) << "the ring never overflowed: the test proves nothing";
        EXPECT_EQ(other, 0u);
        EXPECT_EQ(run.end.frames_out + dropped + run.end.results_full + run.end.failed,
                  static_cast<std::uint64_t>(kFrames));
        EXPECT_EQ(run.daemon->counters().capture.no_free_slot.load(), 0u);
    }
}

TEST(Daemon, OpenCvRunsOnTheDaemonsOwnThreadsOnly)
{
    cv::setNumThreads(-1);   // OpenCV's default: a worker per CPU
    if (cv::getNumThreads() <= 1)
        GTEST_SKIP() << "one CPU: OpenCV's default is one thread already";
    const DaemonRun run = run_to_end(config_for(runtime::OverflowPolicy::drop_newest), 5, false);
    EXPECT_EQ(run.end.frames_out, 5u);
    EXPECT_EQ(cv::getNumThreads(), 1) << "OpenCV's worker pool is still in use";
}

TEST(Daemon, SourceThatCanWaitGetsBackPressureAndLosesNothing)
{
    constexpr long kFrames = 60;
    const DaemonRun run = run_to_end(config_for(runtime::OverflowPolicy::drop_newest), kFrames, false);
    EXPECT_EQ(run.end.frames_in, static_cast<std::uint64_t>(kFrames));
    EXPECT_EQ(run.end.frames_out, static_cast<std::uint64_t>(kFrames));
    EXPECT_EQ(run.end.ring_full + run.end.overwritten + run.end.results_full + run.end.failed, 0u);
    EXPECT_GT(run.daemon->counters().capture.backpressure_waits.load(), 0u);
    EXPECT_EQ(run.end.latency.count, static_cast<std::uint64_t>(kFrames));
    EXPECT_GT(run.end.pipeline.p50_ms, 0.0);
}

TEST(Daemon, StopsPromptlyWhileFramesKeepComing)
{
    runtime::Daemon daemon(config_for(runtime::OverflowPolicy::drop_newest),
                           std::make_unique<ScriptedSource>(-1, true),
                           std::make_unique<runtime::DetectionSink>(runtime::make_logger("actuator")));
    ASSERT_TRUE(daemon.start());
    ASSERT_TRUE(test::wait_for([&] { return daemon.counters().actuator.frames.load() >= 5; }, 60s));
    const auto t0 = std::chrono::steady_clock::now();
    daemon.request_stop();
    EXPECT_TRUE(daemon.join());
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 1s);
    EXPECT_FALSE(daemon.finished() && daemon.source_failed());
}

namespace {

// A source that hangs in next() (ignoring its timeout) until released: a
// stuck driver.
class HangingSource final : public drivers::FrameSource {
public:
    std::string_view name() const override { return "hanging"; }
    bool open() override { return true; }
    bool start() override { return true; }
    drivers::NextStatus next(drivers::Frame& into, std::chrono::nanoseconds) override
    {
        if (hang_.load()) {
            entered_.store(true);
            while (hang_.load())
                std::this_thread::yield();
        }
        into.t_sample_ns = stemd::base::monotonic_ns();
        return drivers::NextStatus::end_of_stream;
    }
    void stop() override {}
    drivers::SourceCounters counters() const override { return {}; }
    bool realtime() const override { return true; }
    void release() { hang_.store(false); }
    bool entered() const { return entered_.load(); }

private:
    std::atomic<bool> hang_{true};
    std::atomic<bool> entered_{false};
};

}  // namespace

TEST(Daemon, AStuckThreadIsReportedForTheWatchdog)
{
    auto source = std::make_unique<HangingSource>();
    HangingSource* hanging = source.get();
    runtime::Daemon daemon(config_for(runtime::OverflowPolicy::drop_newest), std::move(source),
                           std::make_unique<runtime::DetectionSink>(runtime::make_logger("actuator")));
    ASSERT_TRUE(daemon.start());
    ASSERT_TRUE(test::wait_for([&] { return hanging->entered(); }, 10s));
    constexpr std::int64_t kMaxAgeNs = 200'000'000;
    // The other two threads keep stamping while they idle; capture does not.
    const char* stalled = nullptr;
    EXPECT_TRUE(test::wait_for(
        [&] { return (stalled = daemon.stalled_thread(stemd::base::monotonic_ns(), kMaxAgeNs)) != nullptr; }, 10s));
    ASSERT_NE(stalled, nullptr);
    EXPECT_STREQ(stalled, "capture");
    hanging->release();
    ASSERT_TRUE(test::wait_for([&] { return daemon.finished(); }, 10s));
    // Finished threads are not stuck.
    EXPECT_EQ(daemon.stalled_thread(stemd::base::monotonic_ns() + 10 * kMaxAgeNs, kMaxAgeNs), nullptr);
    EXPECT_TRUE(daemon.join());
}

TEST(Daemon, NoThreadIsStalledWhileFramesFlow)
{
    runtime::Daemon daemon(config_for(runtime::OverflowPolicy::drop_newest),
                           std::make_unique<ScriptedSource>(-1, true),
                           std::make_unique<runtime::DetectionSink>(runtime::make_logger("actuator")));
    ASSERT_TRUE(daemon.start());
    ASSERT_TRUE(test::wait_for([&] { return daemon.snapshot(false).frames_out >= 5; }, 60s));
    EXPECT_EQ(daemon.stalled_thread(stemd::base::monotonic_ns(), 1'000'000'000), nullptr);
    daemon.request_stop();
    EXPECT_TRUE(daemon.join());
}

TEST(Daemon, ActuatorThreadDrivesTheActuationStage)
{
    // Scripted frames: the stage gets every frame, its odometry (constant
    // speed) and its heartbeat, while the status reads its counters from
    // another thread (TSan checks the sharing).
    runtime::ActuationConfig actuation;
    actuation.tools = {{.id = 0, .offset_mm = 600, .y_min_mm = -220, .y_max_mm = 220, .lanes = 1}};
    actuation.odometry = runtime::OdometrySource::constant;
    actuation.heartbeat_interval_ns = 1'000'000;   // every ms: several during the run
    geometry::NadirParams nadir;
    nadir.principal_px = geometry::image_centre({1296, 966});
    auto bus = std::make_unique<test::FakeCanBus>();
    const test::FakeCanBus& sent = *bus;
    runtime::ActuationStage::Parts parts;
    parts.bus = std::move(bus);
    std::string error;
    auto stage = runtime::ActuationStage::make(actuation, *geometry::CameraModel::nadir(nadir), {1296, 966},
                                               std::move(parts), runtime::make_logger("actuator"), error);
    ASSERT_TRUE(stage) << error;
    runtime::Daemon daemon(config_for(runtime::OverflowPolicy::drop_newest),
                           std::make_unique<ScriptedSource>(40, false),
                           std::make_unique<runtime::DetectionSink>(runtime::make_logger("actuator")),
                           std::move(stage));
    ASSERT_TRUE(daemon.start());
    std::uint64_t reads = 0;
    EXPECT_TRUE(test::wait_for([&] {
        reads += daemon.snapshot(false).actuation ? 1 : 0;   // read concurrently with the actuator
        return daemon.finished();
    }, 120s));
    EXPECT_TRUE(daemon.join());
    EXPECT_GT(reads, 0u);
    const runtime::StatusSnapshot end = daemon.snapshot(true);
    EXPECT_TRUE(end.actuation);
    EXPECT_EQ(end.frames_out, 40u);
    EXPECT_EQ(end.no_odometry, 0u);
    std::uint64_t targets = 0, heartbeats = 0;
    for (const auto& frame : sent.sent) {
        targets += protocol::CanIds{}.kind_of(frame) == protocol::MessageKind::Target;
        heartbeats += protocol::CanIds{}.kind_of(frame) == protocol::MessageKind::Heartbeat;
    }
    EXPECT_EQ(targets, end.sent);
    EXPECT_GE(heartbeats, 1u);
}

namespace {

// An actuation stage with the fake GPIO lines `lines` (a trigger output,
// 150 us pulses) and a fake bus.
std::unique_ptr<runtime::ActuationStage> stage_with_trigger(std::unique_ptr<test::FakeGpioLines> lines)
{
    runtime::ActuationConfig actuation;
    actuation.tools = {{.id = 0, .offset_mm = 600, .y_min_mm = -220, .y_max_mm = 220, .lanes = 1}};
    actuation.trigger_pulse_us = 150;
    geometry::NadirParams nadir;
    nadir.principal_px = geometry::image_centre({1296, 966});
    runtime::ActuationStage::Parts parts;
    parts.bus = std::make_unique<test::FakeCanBus>();
    parts.gpio = std::move(lines);
    std::string error;
    auto stage = runtime::ActuationStage::make(actuation, *geometry::CameraModel::nadir(nadir), {1296, 966},
                                               std::move(parts), runtime::make_logger("actuator"), error);
    EXPECT_TRUE(stage) << error;
    return stage;
}

// A camera that sends nothing: each next() waits out its timeout (as a
// V4L2 poll does) and counts it.
class SilentSource final : public drivers::FrameSource {
public:
    std::string_view name() const override { return "silent"; }
    bool open() override { return true; }
    bool start() override { return true; }
    drivers::NextStatus next(drivers::Frame&, std::chrono::nanoseconds timeout) override
    {
        std::this_thread::sleep_for(timeout);
        timeouts_.fetch_add(1);
        return drivers::NextStatus::timeout;
    }
    void stop() override {}
    drivers::SourceCounters counters() const override { return {.timeouts = timeouts_.load()}; }
    bool realtime() const override { return true; }
    std::uint64_t timeouts() const { return timeouts_.load(); }

private:
    std::atomic<std::uint64_t> timeouts_{0};
};

}  // namespace

TEST(Daemon, CaptureThreadPulsesTheCameraTrigger)
{
    // A source that waits for frames (realtime, endless) and GPIO lines with
    // a trigger output: the capture thread pulses it, with the configured
    // width, and counts the pulses. (The cadence itself: TriggerClock tests.)
    auto gpio = std::make_unique<test::FakeGpioLines>(/*with_trigger=*/true);
    test::FakeGpioLines& lines = *gpio;
    auto stage = stage_with_trigger(std::move(gpio));
    ASSERT_TRUE(stage);
    runtime::DaemonConfig config = config_for(runtime::OverflowPolicy::drop_newest);
    config.fps = 200;
    runtime::Daemon daemon(config, std::make_unique<ScriptedSource>(-1, true),
                           std::make_unique<runtime::DetectionSink>(runtime::make_logger("actuator")),
                           std::move(stage));
    ASSERT_TRUE(daemon.start());
    EXPECT_TRUE(test::wait_for([&] { return lines.pulses.load() >= 3; }, 60s));
    // Pulses that do not go out (the lines down) are counted as failed.
    lines.trigger_works.store(false);
    const std::uint64_t calls_before = lines.pulses.load();
    EXPECT_TRUE(test::wait_for([&] { return lines.pulses.load() >= calls_before + 3; }, 60s));
    daemon.request_stop();
    EXPECT_TRUE(daemon.join());
    EXPECT_EQ(lines.last_width_us.load(), 150u);
    const std::uint64_t sent = daemon.counters().capture.trigger_pulses.load();
    const std::uint64_t failed = daemon.counters().capture.trigger_failed.load();
    EXPECT_EQ(sent + failed, lines.pulses.load());
    EXPECT_GE(failed, 3u);
    EXPECT_GE(sent, 3u);
    const runtime::StatusSnapshot s = daemon.snapshot(true);
    EXPECT_TRUE(s.trigger);
    EXPECT_EQ(s.trigger_failed, failed);
}

// With a trigger, the capture thread cuts its wait for a frame short at
// each pulse; the source counts each such wait as a timeout. The status
// line's source timeouts are the daemon's: waits of the whole
// kSourceTimeout (100 ms) without a frame, so a triggered camera that
// delivers is not shown as timing out, and a silent one still is.
TEST(Daemon, WaitsCutShortForTheTriggerAreNotSourceTimeouts)
{
    for (const bool with_trigger : {true, false}) {
        SCOPED_TRACE(with_trigger ? "trigger" : "no trigger");
        auto gpio = std::make_unique<test::FakeGpioLines>(with_trigger);
        test::FakeGpioLines& lines = *gpio;
        auto stage = stage_with_trigger(std::move(gpio));
        ASSERT_TRUE(stage);
        runtime::DaemonConfig config = config_for(runtime::OverflowPolicy::drop_newest);
        config.fps = 100;   // a pulse every 10 ms
        auto source = std::make_unique<SilentSource>();
        const SilentSource& silent = *source;
        runtime::Daemon daemon(config, std::move(source),
                               std::make_unique<runtime::DetectionSink>(runtime::make_logger("actuator")),
                               std::move(stage));
        ASSERT_TRUE(daemon.start());
        EXPECT_TRUE(test::wait_for([&] { return silent.timeouts() >= 3; }, 60s));
        daemon.request_stop();
        EXPECT_TRUE(daemon.join());
        const runtime::StatusSnapshot s = daemon.snapshot(true);
        if (with_trigger) {
            EXPECT_GE(lines.pulses.load(), 3u);
            EXPECT_EQ(s.source_timeouts, 0u) << "the source counted " << silent.timeouts();
        } else {
            EXPECT_EQ(lines.pulses.load(), 0u);
            // Each of the source's waits but the one the stop cut short.
            EXPECT_GE(s.source_timeouts + 1, silent.timeouts());
            EXPECT_GE(s.source_timeouts, 2u);
        }
    }
}

namespace {

// Delivers frames, then throws std::bad_alloc from next(), as a decoder
// does under a memory limit.
class ThrowingSource final : public drivers::FrameSource {
public:
    explicit ThrowingSource(long frames_before) : frames_before_(frames_before) {}
    std::string_view name() const override { return "throwing"; }
    bool open() override { return true; }
    bool start() override { return true; }
    drivers::NextStatus next(drivers::Frame& into, std::chrono::nanoseconds) override
    {
        if (next_ >= frames_before_)
            throw std::bad_alloc();
        into.t_sample_ns = stemd::base::monotonic_ns();
        into.source_seq = static_cast<std::uint64_t>(next_++);
        return drivers::NextStatus::frame;
    }
    void stop() override {}
    drivers::SourceCounters counters() const override { return {}; }
    bool realtime() const override { return false; }

private:
    const long frames_before_;
    long next_ = 0;
};

}  // namespace

TEST(Daemon, AnExceptionInAThreadStopsTheRunWithOneLineInsteadOfTerminating)
{
    runtime::Daemon daemon(config_for(runtime::OverflowPolicy::drop_newest), std::make_unique<ThrowingSource>(3),
                           std::make_unique<runtime::DetectionSink>(runtime::make_logger("actuator")));
    testing::internal::CaptureStderr();
    ASSERT_TRUE(daemon.start());
    const bool failed = test::wait_for([&] { return daemon.thread_failed(); }, 60s);
    daemon.join();
    const std::string err = testing::internal::GetCapturedStderr();
    ASSERT_TRUE(failed);
    EXPECT_NE(err.find("stemd: capture thread: out of memory"), std::string::npos) << err;
    // The frames before the failure went through.
    EXPECT_EQ(daemon.snapshot(true).frames_in, 3u);
    EXPECT_FALSE(daemon.source_failed());
    EXPECT_EQ(daemon.stalled_thread(stemd::base::monotonic_ns() + 60'000'000'000, 1'000'000'000), nullptr);
}
