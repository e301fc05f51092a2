// stemd-eval --targets with tools that have a latency: commands go out
// speed x latency earlier than the stem, so the score must compare where
// they strike (the log's TOOL_FIRED, or fire_odom_mm + the lead), not the
// commanded odometer.
#include "stemd/eval/targets.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <string>
#include <unistd.h>

#include <gtest/gtest.h>

#include "stemd/protocol/candump_format.hpp"

using namespace stemd;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct LogWriter {
    protocol::CanIds ids = *protocol::CanIds::make(0x300);
    std::ofstream out;
    std::uint64_t t_us = 1'000'000;
    std::uint8_t counter = 0;
    explicit LogWriter(const std::filesystem::path& p) : out(p) {}
    template <typename Msg>
    void write(const Msg& m)
    {
        protocol::CanFrame f;
        ASSERT_TRUE(protocol::encode(m, counter, ids, f));
        counter = static_cast<std::uint8_t>((counter + 1) % 15);
        out << protocol::format_candump_line(t_us, "vcan0", f) << "\n";
        t_us += 1000;
    }
};

std::filesystem::path temp_log(const char* name)
{
    return std::filesystem::temp_directory_path() / (std::string("stemd-eval-") + name + "-" + std::to_string(::getpid()) + ".log");
}

// The log as stemd-eval reads it; a log it cannot read fails the test, with the reason.
std::optional<eval::TargetLog> read_log(const std::filesystem::path& path)
{
    std::string error;
    auto log = eval::read_target_log(path, *protocol::CanIds::make(0x300), error);
    EXPECT_TRUE(log) << error;
    return log;
}

}  // namespace

TEST(EvalTargets, ALatencyLeadIsScoredAtTheStrikePointNotTheCommand)
{
    // Tool 0 at offset 600 mm with a 40 ms latency, 1400 mm/s: stemd
    // commands 56 mm before the stem's fire point.
    const std::array<eval::TruthPlant, 2> plants{{{1, 1000, 10, PlantClass::Weed, 20},
                                                  {2, 2000, -20, PlantClass::Weed, 20}}};
    std::array<double, 16> offsets;
    offsets.fill(kNaN);
    offsets[0] = 600;
    std::array<double, 16> latency{};
    latency[0] = 40;
    const auto path = temp_log("lead");
    {
        LogWriter w(path);
        w.write(protocol::Odometry{.odom_mm = 100, .speed_mm_per_s = 1400});
        w.write(protocol::TargetCommand{.target_id = 1, .tool_id = 0, .lane = 0, .fire_odom_mm = 1600 - 56,
                                        .lateral_mm = 10, .plant_class = PlantClass::Weed});
        w.write(protocol::TargetCommand{.target_id = 2, .tool_id = 0, .lane = 0, .fire_odom_mm = 2600 - 56,
                                        .lateral_mm = -20, .plant_class = PlantClass::Weed});
    }
    const auto log = read_log(path);
    ASSERT_TRUE(log);
    ASSERT_EQ(log->targets.size(), 2u);
    EXPECT_DOUBLE_EQ(log->speed_mm_per_s[0], 1400);
    EXPECT_TRUE(std::isnan(log->fired_odom_mm[0]));
    // The command itself is 56 mm early: outside a 20 mm tolerance.
    const eval::TargetScore as_commanded = eval::score_targets(plants, log->targets, offsets, 20);
    EXPECT_EQ(as_commanded.matched, 0u);
    // Where it strikes: on the stem.
    const auto leads = eval::target_leads_mm(*log, latency, 1000);
    ASSERT_EQ(leads.size(), 2u);
    EXPECT_DOUBLE_EQ(leads[0], 56);
    const eval::TargetScore struck = eval::score_targets(plants, log->targets, offsets, 20, leads);
    EXPECT_EQ(struck.matched, 2u);
    EXPECT_TRUE(struck.exact());
    EXPECT_DOUBLE_EQ(struck.error_max_mm, 0);
    std::filesystem::remove(path);
}

TEST(EvalTargets, WithoutOdometryFramesTheConfiguredSpeedGivesTheLead)
{
    const auto path = temp_log("speed");
    {
        LogWriter w(path);
        w.write(protocol::TargetCommand{.target_id = 1, .tool_id = 3, .lane = 0, .fire_odom_mm = 5000,
                                        .lateral_mm = 0, .plant_class = PlantClass::Weed});
    }
    const auto log = read_log(path);
    ASSERT_TRUE(log);
    std::array<double, 16> latency{};
    latency[3] = 25;
    // 2000 mm/s x 25 ms.
    EXPECT_DOUBLE_EQ(eval::target_leads_mm(*log, latency, 2000)[0], 50);
    // A tool without a latency: no lead.
    latency[3] = 0;
    EXPECT_DOUBLE_EQ(eval::target_leads_mm(*log, latency, 2000)[0], 0);
    std::filesystem::remove(path);
}

TEST(EvalTargets, TheToolsOwnFiredReportIsTheStrikePoint)
{
    const auto path = temp_log("fired");
    {
        LogWriter w(path);
        w.write(protocol::Odometry{.odom_mm = 100, .speed_mm_per_s = 1400});
        // Near the odometer's wrap: commanded at 2^18 - 30, fired 10 mm past 0.
        w.write(protocol::TargetCommand{.target_id = 7, .tool_id = 1, .lane = 2, .fire_odom_mm = 262144 - 30,
                                        .lateral_mm = 0, .plant_class = PlantClass::Weed});
        w.write(protocol::TargetCommand{.target_id = 8, .tool_id = 1, .lane = 2, .fire_odom_mm = 1000,
                                        .lateral_mm = 0, .plant_class = PlantClass::Weed});
        // Another tool's report for the same target id does not count.
        w.write(protocol::ToolFired{.target_id = 7, .tool_id = 0, .lane = 2, .fired_odom_mm = 500});
        w.write(protocol::ToolFired{.target_id = 7, .tool_id = 1, .lane = 2, .fired_odom_mm = 10});
    }
    const auto log = read_log(path);
    ASSERT_TRUE(log);
    ASSERT_EQ(log->targets.size(), 2u);
    EXPECT_DOUBLE_EQ(log->fired_odom_mm[0], 10);
    EXPECT_TRUE(std::isnan(log->fired_odom_mm[1]));
    std::array<double, 16> latency{};
    latency[1] = 40;
    const auto leads = eval::target_leads_mm(*log, latency, 1000);
    EXPECT_DOUBLE_EQ(leads[0], 40);   // fired - commanded, across the wrap
    EXPECT_DOUBLE_EQ(leads[1], 56);   // no report: speed x latency
    std::filesystem::remove(path);
}
