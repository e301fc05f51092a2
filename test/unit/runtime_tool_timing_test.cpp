// Tool timing end to end in one process: the actuator's stage on a test CAN
// bus with a simulated tool controller (ToolSimulator) behind it, which
// executes the TARGETs with a known delay and answers TOOL_FIRED; the drive
// sends ODOMETRY every 10 ms. The plant map and the counters must show the
// lag, the compensation must put the strikes on the stems, and a learned
// latency must converge. (The same with stemd-toolsim on a real vcan runs in
// the VM checks: test/vm/guest.sh, check toolsim.)
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "stemd/actuation/tool_simulator.hpp"
#include "stemd/protocol/messages.hpp"
#include "stemd/runtime/actuation_stage.hpp"
#include "stemd/runtime/logging.hpp"
#include "fake_can_bus.hpp"
#include "runtime_test_util.hpp"

namespace stemd::runtime {
namespace {

using protocol::CanFrame;
using protocol::MessageKind;

constexpr double kGsd = 0.33;
const cv::Size kSize{1296, 966};
constexpr std::int64_t kPeriodNs = 33'333'333;  // 30 fps
constexpr std::int64_t kT0 = 5'000'000'000;
constexpr double kOdom0 = 10000.0;              // the drive's odometer at kT0
constexpr double kKmh = 1e6 / 3600.0;

geometry::CameraModel nadir_camera()
{
    geometry::NadirParams p;
    p.gsd_mm_per_px = kGsd;
    p.principal_px = geometry::image_centre(kSize);
    return *geometry::CameraModel::nadir(p);
}

struct Outcome {
    std::unique_ptr<ActuationStage> stage;
    test::FakeCanBus* bus = nullptr;
    std::vector<std::string> map;   // the plant map's lines
    std::size_t lines_before_finish = 0;
};

struct Drive {
    double kmh = 5.0;
    double delay_ms = 40.0;         // the simulated tool's
    double latency_ms = 0.0;        // configured
    bool learn = false;
    int plants = 20;
    bool tool_answers = true;
    int answers = -1;               // TARGETs the tool executes (-1: all)
    // Frames to slip into the bus while driving (at the first poll at or
    // after odometer kOdom0 + at_mm).
    double inject_at_mm = -1;
    std::vector<CanFrame> inject{};
};

// Weeds every 60 mm on the centre line from 250 mm ahead of the start.
Outcome drive(const Drive& d)
{
    const double v = d.kmh * kKmh;
    ActuationConfig config;
    config.tools = {{.id = 3, .offset_mm = 600, .y_min_mm = -220, .y_max_mm = 220, .lanes = 1,
                     .latency_ms = d.latency_ms, .learn_latency = d.learn, .latency_min_ms = 0,
                     .latency_max_ms = 200}};
    config.policy = PolicyChoice::all;
    config.odometry = OdometrySource::can;
    const auto dir = test::scratch_dir("tool-timing");
    const auto map_path = dir / "map.jsonl";

    Outcome run;
    ActuationStage::Parts parts;
    auto bus = std::make_unique<test::FakeCanBus>();
    run.bus = bus.get();
    parts.bus = std::move(bus);
    parts.map = std::make_unique<PlantMap>(make_logger("map"));
    EXPECT_TRUE(parts.map->open(map_path));
    std::string error;
    run.stage = ActuationStage::make(config, nadir_camera(), kSize, std::move(parts), make_logger("tool-timing"), error);
    EXPECT_TRUE(run.stage) << error;
    if (!run.stage)
        return run;

    std::vector<double> plants;
    for (int i = 0; i < d.plants; ++i)
        plants.push_back(kOdom0 + 250.0 + 60.0 * i);
    const auto odom_at = [&](std::int64_t t) { return kOdom0 + v * static_cast<double>(t - kT0) / 1e9; };
    const protocol::CanIds ids;
    protocol::E2eCounter odometry_counter, fired_counter;
    actuation::ToolSimulator tool(d.delay_ms);
    std::size_t seen_sent = 0;
    bool injected = false;
    const double end_mm = plants.back() + 600.0 + 1500.0;
    std::int64_t k = 0;
    for (std::int64_t t = kT0 - 50'000'000; odom_at(t) < end_mm; t += 1'000'000) {
        const double odom = odom_at(t);
        if (t % 10'000'000 == 0) {
            CanFrame f;
            EXPECT_TRUE(protocol::encode(protocol::Odometry{static_cast<std::uint32_t>(std::llround(odom)),
                                                            static_cast<std::int16_t>(std::lround(v))},
                                         odometry_counter.next(), ids, f));
            run.bus->inbox.push_back(f);
            run.bus->inbox_t_rx_ns.push_back(t);
        }
        if (!injected && d.inject_at_mm >= 0 && odom >= kOdom0 + d.inject_at_mm) {
            for (const CanFrame& f : d.inject) {
                run.bus->inbox.push_back(f);
                run.bus->inbox_t_rx_ns.push_back(t);
            }
            injected = true;
        }
        run.stage->poll(t);
        if (t >= kT0 + k * kPeriodNs) {
            // Frame k, captured at its period: the plants in view.
            FrameResult r;
            r.seq = static_cast<std::uint64_t>(k);
            r.t_sample_ns = kT0 + k * kPeriodNs;
            r.odom_mm = std::nan("");
            const double at_capture = odom_at(r.t_sample_ns);
            const cv::Point2d c = geometry::image_centre(kSize);
            for (double s : plants) {
                const double vpx = c.y - (s - at_capture) / kGsd;
                if (vpx < 20 || vpx > kSize.height - 21)
                    continue;
                vision::Plant p;
                p.stem = {static_cast<float>(c.x), static_cast<float>(vpx)};
                p.bbox = cv::Rect(static_cast<int>(c.x) - 15, static_cast<int>(vpx) - 15, 31, 31);
                p.has_stem = true;
                p.confidence = 0.8f;
                r.plant_class[r.detections.plants.size()] = protocol::PlantClass::Weed;
                r.detections.plants.push_back(p);
            }
            run.stage->on_frame(r, t + 1'000'000);
            ++k;
        }
        // The tool controller: new TARGETs, then its strikes.
        for (; seen_sent < run.bus->sent.size(); ++seen_sent) {
            const CanFrame& f = run.bus->sent[seen_sent];
            protocol::TargetCommand cmd;
            if (ids.kind_of(f) == MessageKind::Target && protocol::decode(f, ids, cmd) && d.tool_answers &&
                (d.answers < 0 || tool.counters().commands < static_cast<std::uint64_t>(d.answers)))
                tool.command(cmd, odom);
        }
        for (const protocol::ToolFired& fired : tool.advance(t, odom)) {
            CanFrame f;
            EXPECT_TRUE(protocol::encode(fired, fired_counter.next(), ids, f));
            run.bus->inbox.push_back(f);
            run.bus->inbox_t_rx_ns.push_back(t);
        }
    }
    {
        std::ifstream before(map_path);
        for (std::string line; std::getline(before, line);)
            ++run.lines_before_finish;
    }
    EXPECT_TRUE(run.stage->finish());
    std::ifstream in(map_path);
    for (std::string line; std::getline(in, line);)
        run.map.push_back(line);
    std::filesystem::remove_all(dir);
    return run;
}

// A number in a map line ("key":value); NaN when absent or null.
double field(const std::string& line, const std::string& key)
{
    const std::string tag = "\"" + key + "\":";
    const std::size_t at = line.find(tag);
    if (at == std::string::npos || line.compare(at + tag.size(), 4, "null") == 0)
        return std::nan("");
    return std::strtod(line.c_str() + at + tag.size(), nullptr);
}

// The map lines with the tool-timing columns. Plants that left the view
// before the tool's first TOOL_FIRED have none: the first strike is 656 mm
// past the first plant, the view reaches 160 mm back, the track ends a few
// frames later: about 8 plants 60 mm apart.
std::vector<std::string> with_lag(const std::vector<std::string>& map)
{
    std::vector<std::string> out;
    for (const std::string& line : map)
        if (std::isfinite(field(line, "fire_lag_mm")))
            out.push_back(line);
    return out;
}

constexpr std::size_t kBeforeFirstReport = 12;   // a bound on the plants above

TEST(ToolTiming, UncompensatedLagIsSpeedTimesDelayInTheMapAndTheCounters)
{
    const Outcome run = drive({.kmh = 5.04, .delay_ms = 40.0, .plants = 30});   // 1400 mm/s: 56 mm
    ASSERT_TRUE(run.stage);
    ASSERT_EQ(run.map.size(), 30u);
    const auto lines = with_lag(run.map);
    EXPECT_GE(lines.size(), 30u - kBeforeFirstReport);
    for (const std::string& line : lines) {
        EXPECT_EQ(field(line, "fire_lead_mm"), 0.0) << line;
        EXPECT_NEAR(field(line, "fire_lag_mm"), 56.0, 1.0) << line;
        EXPECT_NEAR(field(line, "fire_lag_ms"), 40.0, 1.0) << line;
        EXPECT_NEAR(field(line, "strike_mm"), 56.0, 1.0) << line;
        EXPECT_NEAR(field(line, "fired_odom_mm"), field(line, "fire_odom_mm") + 56.0, 1.0) << line;
    }
    const ActuationCounters& c = run.stage->counters();
    // Every strike counts, whether its map line has the columns or not.
    EXPECT_EQ(c.rx_tool_fired.load(), 30u);
    EXPECT_EQ(c.fired_unmatched.load(), 0u);
    EXPECT_EQ(c.rx_rejected.load(), 0u);
    const ToolTimingCounters& t = c.tool_timing[0];
    EXPECT_EQ(t.tool_id.load(), 3);
    EXPECT_EQ(t.fired.load(), 30u);
    EXPECT_NEAR(t.lag_mean_mm.load(), 56.0, 1.0);
    EXPECT_NEAR(t.lag_mean_ms.load(), 40.0, 1.0);
    EXPECT_NEAR(t.strike_p95_mm.load(), 56.0, 1.5);
    EXPECT_FALSE(c.tool_timing[1].configured.load());
}

TEST(ToolTiming, CompensatedStrikesLandOnTheStemsFrom1To8Kmh)
{
    for (double kmh : {1.0, 3.0, 5.0, 8.0}) {
        const Outcome run = drive({.kmh = kmh, .delay_ms = 40.0, .latency_ms = 40.0, .plants = 30});
        ASSERT_TRUE(run.stage);
        ASSERT_EQ(run.map.size(), 30u) << kmh << " km/h";
        const auto lines = with_lag(run.map);
        EXPECT_GE(lines.size(), 30u - kBeforeFirstReport) << kmh << " km/h";
        // The odometer's mm: commanded and fired points are whole mm, so a
        // lag is known to 1 mm, i.e. 1 mm / speed in time (3.6 ms at 1 km/h);
        // the speed it is divided by is the odometry's estimate from
        // whole-mm samples, a few % off at walking pace (5 % of 40 ms: 2 ms).
        const double ms_resolution = 1000.0 / (kmh * kKmh) + 2.0;
        for (const std::string& line : lines) {
            EXPECT_LE(std::abs(field(line, "strike_mm")), 5.0) << line;
            // The lead comes from the odometry's speed, estimated from
            // whole-mm ODOMETRY samples 10 ms apart: within 0.5 mm.
            EXPECT_NEAR(field(line, "fire_lead_mm"), kmh * kKmh * 0.040, 0.5) << line;
            EXPECT_NEAR(field(line, "fire_lag_ms"), 40.0, ms_resolution) << line;
        }
        EXPECT_LE(run.stage->counters().tool_timing[0].strike_p95_mm.load(), 5.0) << kmh << " km/h";
        EXPECT_EQ(run.stage->counters().compensation_misses.load(), 0u);
    }
}

TEST(ToolTiming, LearnedLatencyConvergesAndTheLaterStrikesLandOnTheStems)
{
    const Outcome run = drive({.kmh = 6.0, .delay_ms = 40.0, .latency_ms = 0.0, .learn = true, .plants = 40});
    ASSERT_TRUE(run.stage);
    ASSERT_EQ(run.map.size(), 40u);
    EXPECT_NEAR(run.stage->counters().tool_timing[0].latency_ms.load(), 40.0, 1.0);
    EXPECT_TRUE(run.stage->counters().tool_timing[0].learning.load());
    // The first strikes are late by the whole 40 ms (66.7 mm at 6 km/h);
    // once learned (from the 5th report on, for commands made after it), on
    // the stem.
    const auto lines = with_lag(run.map);
    ASSERT_GE(lines.size(), 40u - kBeforeFirstReport);
    EXPECT_NEAR(field(lines.front(), "strike_mm"), 6.0 * kKmh * 0.040, 1.5) << lines.front();
    EXPECT_EQ(field(lines.front(), "fire_lead_mm"), 0.0) << lines.front();
    for (std::size_t i = lines.size() - 10; i < lines.size(); ++i) {
        EXPECT_LE(std::abs(field(lines[i], "strike_mm")), 5.0) << lines[i];
        EXPECT_NEAR(field(lines[i], "fire_lead_mm"), 6.0 * kKmh * 0.040, 1.5) << lines[i];
    }
}

TEST(ToolTiming, BadCrcAndUnknownToolsAreRejectedDuplicatesUnmatched)
{
    const protocol::CanIds ids;
    std::vector<CanFrame> bad;
    CanFrame f;
    // Alive counters 12, 13, 14: the simulated tool's first frame (0) then
    // follows on, so its stream is not broken by these.
    ASSERT_TRUE(protocol::encode(protocol::ToolFired{0, 7, 0, 12345}, 12, ids, f));   // tool 7: not in the table
    bad.push_back(f);
    ASSERT_TRUE(protocol::encode(protocol::ToolFired{0, 3, 0, 12345}, 13, ids, f));
    f.data[4] ^= 0x08;   // a flipped bit: bad CRC
    bad.push_back(f);
    ASSERT_TRUE(protocol::encode(protocol::ToolFired{4000, 3, 0, 12345}, 14, ids, f));  // never sent
    bad.push_back(f);
    const Outcome run = drive({.kmh = 5.0, .inject_at_mm = 0.0, .inject = bad});
    ASSERT_TRUE(run.stage);
    const ActuationCounters& c = run.stage->counters();
    EXPECT_EQ(c.rx_rejected.load(), 2u);
    EXPECT_EQ(c.fired_unmatched.load(), 1u);
    EXPECT_EQ(c.tool_timing[0].fired.load(), 20u);
    ASSERT_EQ(run.map.size(), 20u);
}

// Once the tool reports, a sent plant's line waits for its strike; when the
// strike never comes the line is written anyway, 1 m of travel later.
TEST(ToolTiming, ALineWaitsForItsStrikeOnlyWhileItCanCome)
{
    // The tool stops answering after its 10th strike.
    const Outcome run = drive({.kmh = 5.0, .plants = 30, .answers = 10});
    ASSERT_TRUE(run.stage);
    ASSERT_EQ(run.map.size(), 30u);
    EXPECT_EQ(run.stage->counters().tool_timing[0].fired.load(), 10u);
    // Targets 0..9 were struck; those of them that left the view after the
    // tool's first report have the columns, no later one has.
    const auto lines = with_lag(run.map);
    EXPECT_FALSE(lines.empty());
    for (const std::string& line : lines)
        EXPECT_LT(field(line, "id"), 10.0) << line;
    // The drive ended 1.5 m past the last point: none was left for finish().
    EXPECT_EQ(run.lines_before_finish, 30u);
}

TEST(ToolTiming, WithoutAnAnswerEveryPlantIsStillWrittenOnce)
{
    const Outcome run = drive({.kmh = 5.0, .tool_answers = false});
    ASSERT_TRUE(run.stage);
    ASSERT_EQ(run.map.size(), 20u);
    for (const std::string& line : run.map) {
        EXPECT_NE(line.find("\"reason\":\"sent\""), std::string::npos) << line;
        EXPECT_NE(line.find("\"fire_lead_mm\":"), std::string::npos) << line;
        EXPECT_EQ(line.find("fire_lag_mm"), std::string::npos) << line;
    }
    EXPECT_EQ(run.stage->counters().tool_timing[0].fired.load(), 0u);
}

}  // namespace
}  // namespace stemd::runtime
