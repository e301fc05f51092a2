// The canlog CAN bus: lines written for sent frames read back exactly with the
// actuation candump parser; timestamps; one write per line, write failures; deadlines; receive timeout.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <time.h>
#include <unistd.h>

#include <cstdio>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>

#include "canlog/canlog_bus.hpp"
#include "stemd/protocol/candump_format.hpp"
#include "stemd/protocol/messages.hpp"
#include "stemd/base/clock.hpp"
#include "temp_dir_test.hpp"

namespace fs = std::filesystem;
using namespace stemd;
using namespace stemd::drivers;

namespace {

std::shared_ptr<spdlog::logger> quiet_logger()
{
    return std::make_shared<spdlog::logger>("canlog-test", std::make_shared<spdlog::sinks::null_sink_mt>());
}

constexpr std::int64_t kSecond = 1'000'000'000;

std::uint64_t now_us(clockid_t clock)
{
    timespec ts{};
    clock_gettime(clock, &ts);
    return static_cast<std::uint64_t>(ts.tv_sec) * 1'000'000 + static_cast<std::uint64_t>(ts.tv_nsec) / 1000;
}

std::vector<std::string> read_lines(const fs::path& path)
{
    std::ifstream in(path);
    std::vector<std::string> lines;
    for (std::string line; std::getline(in, line);)
        lines.push_back(line);
    return lines;
}

// A mix of stemd messages (E2E-protected) and foreign frames: 29-bit, short, empty.
std::vector<protocol::CanFrame> sample_frames()
{
    const protocol::CanIds ids;
    std::vector<protocol::CanFrame> frames;
    protocol::CanFrame f;
    protocol::TargetCommand target{.target_id = 4095, .tool_id = 3, .lane = 7, .fire_odom_mm = 123456,
                                    .lateral_mm = -2047, .plant_class = protocol::PlantClass::Weed};
    EXPECT_TRUE(protocol::encode(target, 5, ids, f));
    frames.push_back(f);
    EXPECT_TRUE(protocol::encode(protocol::Odometry{.odom_mm = 0xFFFFFFFF, .speed_mm_per_s = -32767}, 14, ids, f));
    frames.push_back(f);
    frames.push_back({.id = 0x1ABCDEF0, .extended = true, .dlc = 3, .data = {0xDE, 0xAD, 0x01}});
    frames.push_back({.id = 0x7FF, .extended = false, .dlc = 0, .data = {}});
    frames.push_back({.id = 0x000, .extended = false, .dlc = 8, .data = {0, 1, 2, 3, 4, 5, 6, 0xFF}});
    return frames;
}

CanLogOptions to(const fs::path& path, const char* interface = "can0",
                 CanLogOptions::Clock clock = CanLogOptions::Clock::realtime)
{
    CanLogOptions o;
    o.path = path;
    o.interface = interface;
    o.clock = clock;
    return o;
}

using CanLogTest = stemd::test::TempDirTest;

}  // namespace

TEST_F(CanLogTest, SentFramesReadBackExactlyWithTheCandumpParser)
{
    const auto path = dir_ / "can.log";
    const auto frames = sample_frames();
    const std::uint64_t t0 = now_us(CLOCK_REALTIME);
    {
        CanLogBus bus(to(path, "vcan7"), quiet_logger());
        ASSERT_TRUE(bus.open());
        EXPECT_EQ(bus.name(), "canlog:" + path.string());
        for (const auto& f : frames)
            EXPECT_EQ(bus.send(f, stemd::base::monotonic_ns() + kSecond), SendResult::sent);
        EXPECT_EQ(bus.counters().sent, frames.size());
        EXPECT_EQ(bus.counters().errors, 0U);
    }
    const std::uint64_t t1 = now_us(CLOCK_REALTIME);
    const auto lines = read_lines(path);
    ASSERT_EQ(lines.size(), frames.size());
    std::uint64_t last_t = 0;
    for (std::size_t i = 0; i < lines.size(); ++i) {
        SCOPED_TRACE(lines[i]);
        protocol::CandumpRecord rec;
        std::string error;
        ASSERT_TRUE(protocol::parse_candump_line(lines[i], rec, error)) << error;
        EXPECT_EQ(rec.frame, frames[i]);
        EXPECT_EQ(rec.interface, "vcan7");
        // CLOCK_REALTIME by default, as candump writes.
        EXPECT_GE(rec.time_us, t0);
        EXPECT_LE(rec.time_us, t1);
        EXPECT_GE(rec.time_us, last_t);
        last_t = rec.time_us;
        // And byte for byte what the formatter writes for that time.
        EXPECT_EQ(lines[i], protocol::format_candump_line(rec.time_us, "vcan7", frames[i]));
    }
}

TEST_F(CanLogTest, DefaultInterfaceIsCan0AndMonotonicClockIsAvailable)
{
    const auto path = dir_ / "mono.log";
    const std::uint64_t t0 = now_us(CLOCK_MONOTONIC);
    {
        CanLogBus bus(to(path, "can0", CanLogOptions::Clock::monotonic), quiet_logger());
        ASSERT_TRUE(bus.open());
        ASSERT_EQ(bus.send(sample_frames()[0], stemd::base::monotonic_ns() + kSecond), SendResult::sent);
    }
    const std::uint64_t t1 = now_us(CLOCK_MONOTONIC);
    const auto lines = read_lines(path);
    ASSERT_EQ(lines.size(), 1U);
    protocol::CandumpRecord rec;
    std::string error;
    ASSERT_TRUE(protocol::parse_candump_line(lines[0], rec, error)) << error;
    EXPECT_EQ(rec.interface, "can0");
    EXPECT_GE(rec.time_us, t0);
    EXPECT_LE(rec.time_us, t1);
}

TEST_F(CanLogTest, DeadlineAlreadyPassedIsNotWrittenAndCounted)
{
    const auto path = dir_ / "late.log";
    {
        CanLogBus bus(to(path), quiet_logger());
        ASSERT_TRUE(bus.open());
        EXPECT_EQ(bus.send(sample_frames()[0], stemd::base::monotonic_ns() - 1), SendResult::deadline_passed);
        EXPECT_EQ(bus.send(sample_frames()[0], stemd::base::monotonic_ns()), SendResult::deadline_passed);
        const auto c = bus.counters();
        EXPECT_EQ(c.deadline_misses, 2U);
        EXPECT_EQ(c.sent, 0U);
        EXPECT_EQ(c.errors, 0U);
    }
    EXPECT_TRUE(read_lines(path).empty());
}

TEST_F(CanLogTest, AClosedGateIsNotWrittenAndCounted)
{
    const auto path = dir_ / "gate.log";
    {
        CanLogBus bus(to(path), quiet_logger());
        ASSERT_TRUE(bus.open());
        bool open = false;
        const stemd::drivers::SendGate gate{.is_open = [](const void* c) { return *static_cast<const bool*>(c); },
                                            .context = &open};
        EXPECT_EQ(bus.send(sample_frames()[0], stemd::base::monotonic_ns() + kSecond, gate), SendResult::withdrawn);
        open = true;
        EXPECT_EQ(bus.send(sample_frames()[1], stemd::base::monotonic_ns() + kSecond, gate), SendResult::sent);
        const auto c = bus.counters();
        EXPECT_EQ(c.withdrawn, 1U);
        EXPECT_EQ(c.sent, 1U);
        EXPECT_EQ(c.errors, 0U);
    }
    EXPECT_EQ(read_lines(path).size(), 1U);
}

TEST_F(CanLogTest, EverySentFrameIsInTheFileWhenSendReturns)
{
    const auto path = dir_ / "lines.log";
    CanLogBus bus(to(path), quiet_logger());
    ASSERT_TRUE(bus.open());
    const auto f = sample_frames()[0];
    for (std::size_t i = 1; i <= 3; ++i) {
        ASSERT_EQ(bus.send(f, stemd::base::monotonic_ns() + kSecond), SendResult::sent);
        EXPECT_EQ(read_lines(path).size(), i) << "nothing waits in a buffer";
    }
    EXPECT_FALSE(bus.output_lost());
}

TEST_F(CanLogTest, AFullDiskIsABusErrorAndTheLogIsLost)
{
    CanLogBus bus(to("/dev/full"), quiet_logger());
    ASSERT_TRUE(bus.open());
    const auto f = sample_frames()[0];
    for (int i = 0; i < 3; ++i)
        EXPECT_EQ(bus.send(f, stemd::base::monotonic_ns() + kSecond), SendResult::error);
    EXPECT_EQ(bus.counters().errors, 3U);
    EXPECT_EQ(bus.counters().sent, 0U);
    EXPECT_TRUE(bus.output_lost());
}

TEST_F(CanLogTest, ReceiveWaitsOutItsTimeoutAndReturnsFalse)
{
    CanLogBus bus(to(dir_ / "rx.log"), quiet_logger());
    ASSERT_TRUE(bus.open());
    protocol::CanFrame f{.id = 0x123, .extended = false, .dlc = 1, .data = {0x42}};
    const auto before = f;
    const std::int64_t t0 = stemd::base::monotonic_ns();
    EXPECT_FALSE(bus.receive(f, 20'000'000));
    EXPECT_GE(stemd::base::monotonic_ns() - t0, 20'000'000);
    EXPECT_EQ(f, before);
    EXPECT_EQ(bus.counters().rx, 0U);
}

TEST_F(CanLogTest, OpenFailuresAndInvalidFramesAreErrorsNotCrashes)
{
    CanLogBus no_dir(to(dir_ / "missing" / "can.log"), quiet_logger());
    EXPECT_FALSE(no_dir.open());
    EXPECT_EQ(no_dir.send(sample_frames()[0], stemd::base::monotonic_ns() + kSecond), SendResult::error);
    EXPECT_EQ(no_dir.counters().errors, 1U);

    CanLogBus bad_name(to(dir_ / "x.log", "can 0"), quiet_logger());
    EXPECT_FALSE(bad_name.open());

    CanLogBus bus(to(dir_ / "y.log"), quiet_logger());
    ASSERT_TRUE(bus.open());
    EXPECT_EQ(bus.send({.id = 0x800, .extended = false, .dlc = 8, .data = {}}, stemd::base::monotonic_ns() + kSecond),
              SendResult::error);
    EXPECT_EQ(bus.send({.id = 0x100, .extended = false, .dlc = 9, .data = {}}, stemd::base::monotonic_ns() + kSecond),
              SendResult::error);
    EXPECT_EQ(bus.counters().errors, 2U);
    EXPECT_EQ(bus.counters().sent, 0U);
}

// "-" is the process's standard output as the shell opened it: what is
// already there stays, and the frames follow it (reopening /dev/stdout
// would truncate a redirected file and write from its start).
TEST_F(CanLogTest, StandardOutputKeepsWhatTheRedirectedFileHeld)
{
    const auto path = dir_ / "stdout.txt";
    const int file = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    ASSERT_GE(file, 0);
    std::fflush(stdout);
    const int saved_stdout = ::dup(STDOUT_FILENO);
    ASSERT_GE(saved_stdout, 0);
    ASSERT_EQ(::dup2(file, STDOUT_FILENO), STDOUT_FILENO);
    ::close(file);
    const std::string before = "written before the log opened\n";
    const bool wrote_before = ::write(STDOUT_FILENO, before.data(), before.size()) ==
                              static_cast<ssize_t>(before.size());
    const auto frames = sample_frames();
    bool opened = false;
    {
        CanLogOptions options = to(CanLogOptions::kStandardOutput);
        CanLogBus bus(options, quiet_logger());
        opened = bus.open();
        for (const auto& f : frames) {
            if (opened) {
                EXPECT_EQ(bus.send(f, stemd::base::monotonic_ns() + kSecond), SendResult::sent);
            }
        }
    }
    ASSERT_EQ(::dup2(saved_stdout, STDOUT_FILENO), STDOUT_FILENO);
    ::close(saved_stdout);
    ASSERT_TRUE(wrote_before);
    ASSERT_TRUE(opened);

    const auto lines = read_lines(path);
    ASSERT_EQ(lines.size(), 1 + frames.size());
    EXPECT_EQ(lines[0] + "\n", before);
    for (std::size_t i = 0; i < frames.size(); ++i) {
        protocol::CandumpRecord rec;
        std::string error;
        ASSERT_TRUE(protocol::parse_candump_line(lines[1 + i], rec, error)) << error;
        EXPECT_EQ(rec.frame, frames[i]);
    }
}
