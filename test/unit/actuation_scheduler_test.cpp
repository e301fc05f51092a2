// Scheduler: tool and lane choice, fire position, deadlines by distance,
// enable input and policy. Also the real-time check for the tracker and the
// scheduler: this file holds the actuation binary's counting operator new.
#include <gtest/gtest.h>

#include "counting_new.hpp"

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "stemd/protocol/messages.hpp"
#include "stemd/actuation/scheduler.hpp"
#include "stemd/actuation/tracker.hpp"

using namespace stemd::actuation;
using namespace stemd::protocol;

namespace {

// A 12-nozzle boom (50 mm lanes) 500 mm behind the camera, and a stamp
// 700 mm behind it covering the strip just left of the boom.
const std::array<ToolSpec, 2> kTools = {{
    {3, 500.0, -300.0, 300.0, 12},
    {5, 700.0, 300.0, 500.0, 1},
}};

SchedulerParams params(TreatPolicy policy = TreatPolicy::weeds_only)
{
    SchedulerParams p;
    p.lead_ms = 20;
    p.send_budget_ms = 2;
    p.policy = policy;
    return p;
}

Scheduler make(const SchedulerParams& p = params())
{
    std::string_view err;
    auto s = Scheduler::make(kTools, p, &err);
    EXPECT_TRUE(s.has_value()) << err;
    return *s;
}

Target weed(double s, double y, std::uint16_t id = 1)
{
    Target t;
    t.target_id = id;
    t.s_mm = s;
    t.y_mm = y;
    t.plant_class = PlantClass::Weed;
    t.sightings = 3;
    return t;
}

ScheduleNow at(double odom, double speed, bool enabled = true, std::int64_t now_ns = 5'000'000'000)
{
    return {now_ns, odom, speed, enabled};
}

}  // namespace

TEST(ActuationScheduler, FirePositionIsSPlusTheToolOffset)
{
    Scheduler s = make();
    const auto d = s.schedule(weed(10'000.4, 0, 77), at(9'000, 1000));
    ASSERT_TRUE(d.ok()) << to_string(d.outcome);
    EXPECT_EQ(d.command.tool_id, 3);
    EXPECT_EQ(d.command.target_id, 77);
    EXPECT_DOUBLE_EQ(d.fire_odom_mm, 10'500.4);
    EXPECT_EQ(d.command.fire_odom_mm, 10'500u);
    EXPECT_EQ(d.command.lateral_mm, 0);
    EXPECT_EQ(d.command.plant_class, PlantClass::Weed);
    // 1500.4 mm at 1 m/s: arrival in 1500.4 ms, on the bus by arrival - 20 ms.
    EXPECT_NEAR(d.time_to_arrival_ms, 1500.4, 1e-9);
    EXPECT_NEAR(static_cast<double>(d.deadline_ns), 5e9 + 1480.4e6, 1.0);
    // The command encodes.
    CanFrame f;
    EXPECT_TRUE(encode(d.command, 0, CanIds{}, f));
}

TEST(ActuationScheduler, LeadTimeBoundaryIsExact)
{
    Scheduler s = make();
    // fire at 1500; lead 20 ms + budget 2 ms at 1000 mm/s = 22 mm.
    const auto enough = s.schedule(weed(1000, 0), at(1478, 1000));
    ASSERT_EQ(enough.outcome, ScheduleOutcome::send);
    EXPECT_EQ(enough.deadline_ns, 5'000'000'000 + 2'000'000);  // arrival - lead = now + budget
    const auto short_ = s.schedule(weed(1000, 0), at(1478.001, 1000));
    EXPECT_EQ(short_.outcome, ScheduleOutcome::deadline_miss);
    EXPECT_LT(short_.time_to_arrival_ms, 22.0);
    // At 1250 mm/s the boundary is 27.5 mm (exact in binary).
    EXPECT_TRUE(s.schedule(weed(1000, 0), at(1500 - 27.5, 1250)).ok());
    EXPECT_FALSE(s.schedule(weed(1000, 0), at(1500 - 27.5 + 1e-9, 1250)).ok());
    // Already passed.
    EXPECT_EQ(s.schedule(weed(1000, 0), at(1501, 1000)).outcome, ScheduleOutcome::deadline_miss);
    EXPECT_EQ(s.counters().sent, 2u);
    EXPECT_EQ(s.counters().deadline_misses, 3u);
}

TEST(ActuationScheduler, ASlowPipelineMissesAndSendsNothing)
{
    Scheduler s = make();
    // Targets reach the scheduler when the plant is already 480..499 mm
    // past the camera: at 1389 mm/s the 500 mm boom is < 22 ms away.
    int sent = 0;
    for (int i = 0; i < 20; ++i) {
        const double plant_s = 2000.0 + 100.0 * i;
        const double odom = plant_s + 480 + i;  // fire position 500 - (480 + i) = 20 - i mm ahead
        sent += s.schedule(weed(plant_s, 10.0 * i - 100), at(odom, 1389)).ok() ? 1 : 0;
    }
    EXPECT_EQ(sent, 0);
    EXPECT_EQ(s.counters().deadline_misses, 20u);
    EXPECT_EQ(s.counters().sent, 0u);
}

TEST(ActuationScheduler, StandingHasNoDeadlinePressure)
{
    Scheduler s = make();
    const auto d = s.schedule(weed(1000, 0), at(1499, 0));
    ASSERT_TRUE(d.ok());
    EXPECT_TRUE(std::isinf(d.time_to_arrival_ms));
    EXPECT_EQ(d.deadline_ns, 5'000'000'000 + 100'000'000);  // standing_deadline_ms
    // Reversing counts as standing; a fire position already passed is still a miss.
    EXPECT_TRUE(s.schedule(weed(1000, 0), at(1499, -300)).ok());
    EXPECT_EQ(s.schedule(weed(1000, 0), at(1501, 0)).outcome, ScheduleOutcome::deadline_miss);
}

TEST(ActuationScheduler, EnableOffSendsNothing)
{
    Scheduler s = make();
    for (int i = 0; i < 5; ++i) {
        const auto d = s.schedule(weed(1000 + 100 * i, 0), at(0, 1000, false));
        EXPECT_EQ(d.outcome, ScheduleOutcome::disabled);
    }
    EXPECT_EQ(s.counters().disabled, 5u);
    EXPECT_EQ(s.counters().sent, 0u);
}

TEST(ActuationScheduler, LaneSelectionAtSpanEdges)
{
    Scheduler s = make();
    struct Case {
        double y;
        ScheduleOutcome outcome;
        std::uint8_t tool;
        std::uint8_t lane;
    };
    const Case cases[] = {
        {-300.0, ScheduleOutcome::send, 3, 0},   // the boom's right edge
        {-250.001, ScheduleOutcome::send, 3, 0},
        {-250.0, ScheduleOutcome::send, 3, 1},   // a lane boundary belongs to the next lane
        {-0.001, ScheduleOutcome::send, 3, 5},
        {0.0, ScheduleOutcome::send, 3, 6},
        {299.999, ScheduleOutcome::send, 3, 11},
        {300.0, ScheduleOutcome::send, 3, 11},   // the left edge: last lane; the boom comes first in the table
        {300.001, ScheduleOutcome::send, 5, 0},  // the stamp
        {500.0, ScheduleOutcome::send, 5, 0},
        {500.001, ScheduleOutcome::no_tool, 0, 0},
        {-300.001, ScheduleOutcome::no_tool, 0, 0},
        {std::nan(""), ScheduleOutcome::no_tool, 0, 0},
    };
    for (const Case& c : cases) {
        const auto d = s.schedule(weed(1000, c.y), at(0, 1000));
        EXPECT_EQ(d.outcome, c.outcome) << "y=" << c.y;
        if (c.outcome == ScheduleOutcome::send) {
            EXPECT_EQ(d.command.tool_id, c.tool) << "y=" << c.y;
            EXPECT_EQ(d.command.lane, c.lane) << "y=" << c.y;
            EXPECT_EQ(d.command.lateral_mm, static_cast<std::int16_t>(std::lround(c.y)));
        }
    }
    EXPECT_EQ(s.counters().no_tool, 3u);
}

TEST(ActuationScheduler, OverlappingToolsFallBackToOneThatIsOnTime)
{
    const std::array<ToolSpec, 2> tools = {{{1, 100.0, -200.0, 200.0, 4}, {2, 900.0, -200.0, 200.0, 1}}};
    auto s = Scheduler::make(tools, params());
    ASSERT_TRUE(s);
    // Plant at 1000: tool 1 fires at 1100 (5 mm ahead: too late), tool 2 at 1900.
    const auto d = s->schedule(weed(1000, 50), at(1095, 1000));
    ASSERT_TRUE(d.ok());
    EXPECT_EQ(d.command.tool_id, 2);
    EXPECT_EQ(d.command.lane, 0);
    EXPECT_EQ(d.command.fire_odom_mm, 1900u);
    // Both too late: a miss, reported against the first tool.
    const auto m = s->schedule(weed(1000, 50), at(1890, 1000));
    EXPECT_EQ(m.outcome, ScheduleOutcome::deadline_miss);
    EXPECT_EQ(m.command.tool_id, 1);
}

// A tool whose TOOL_STATUS ready bit is clear is passed over for the next
// covering tool; with none ready the target is not_ready, never sent, and
// that comes after the enable input and before the deadline.
TEST(ActuationScheduler, ToolsThatAreNotReadyGetNoTarget)
{
    const std::array<ToolSpec, 2> tools = {{{1, 100.0, -200.0, 200.0, 4}, {2, 900.0, -200.0, 200.0, 1}}};
    auto s = Scheduler::make(tools, params());
    ASSERT_TRUE(s);
    ScheduleNow now = at(0, 1000);
    now.tools_ready_mask = 1U << 2;   // tool 1 not ready
    const auto d = s->schedule(weed(1000, 50), now);
    ASSERT_TRUE(d.ok()) << to_string(d.outcome);
    EXPECT_EQ(d.command.tool_id, 2);
    EXPECT_EQ(d.command.fire_odom_mm, 1900u);

    now.tools_ready_mask = 0xFFFF & ~(1U << 1) & ~(1U << 2);   // the other 14 tools ready, not these
    const auto none = s->schedule(weed(1000, 50), now);
    EXPECT_EQ(none.outcome, ScheduleOutcome::not_ready);
    EXPECT_EQ(s->counters().not_ready, 1u);

    // Not ready and too late: not_ready, since no ready tool could be tried.
    const auto late = s->schedule(weed(1000, 50), {now.now_ns, 1890, 1000, true, now.tools_ready_mask});
    EXPECT_EQ(late.outcome, ScheduleOutcome::not_ready);
    // Disabled first.
    const auto off = s->schedule(weed(1000, 50), {now.now_ns, 0, 1000, false, now.tools_ready_mask});
    EXPECT_EQ(off.outcome, ScheduleOutcome::disabled);
    // A ready tool that is too late is a deadline miss reported against it.
    now.tools_ready_mask = 1U << 1;
    const auto miss = s->schedule(weed(1000, 50), {now.now_ns, 1095, 1000, true, now.tools_ready_mask});
    EXPECT_EQ(miss.outcome, ScheduleOutcome::deadline_miss);
    EXPECT_EQ(miss.command.tool_id, 1);
    EXPECT_EQ(s->counters().not_ready, 2u);
    EXPECT_EQ(s->counters().sent, 1u);
}

TEST(ActuationScheduler, WeedsOnlyPolicy)
{
    Scheduler weeds = make(params(TreatPolicy::weeds_only));
    Scheduler all = make(params(TreatPolicy::all));
    for (PlantClass c : {PlantClass::Crop, PlantClass::Unknown, PlantClass::Weed}) {
        Target t = weed(1000, 0);
        t.plant_class = c;
        EXPECT_EQ(weeds.schedule(t, at(0, 1000)).ok(), c == PlantClass::Weed);
        const auto d = all.schedule(t, at(0, 1000));
        EXPECT_TRUE(d.ok());
        EXPECT_EQ(d.command.plant_class, c);
    }
    EXPECT_EQ(weeds.counters().policy, 2u);
    EXPECT_EQ(weeds.counters().sent, 1u);
    // The policy is checked before the enable input.
    Target crop = weed(1000, 0);
    crop.plant_class = PlantClass::Crop;
    EXPECT_EQ(weeds.schedule(crop, at(0, 1000, false)).outcome, ScheduleOutcome::policy);
    EXPECT_EQ(parse_treat_policy("weeds_only"), TreatPolicy::weeds_only);
    EXPECT_EQ(parse_treat_policy("all"), TreatPolicy::all);
    EXPECT_FALSE(parse_treat_policy("weeds"));
}

TEST(ActuationScheduler, TargetIdWrapAndOdometerWrap)
{
    Scheduler s = make();
    auto d = s.schedule(weed(1000, 0, 4095), at(0, 1000));
    ASSERT_TRUE(d.ok());
    EXPECT_EQ(d.command.target_id, 4095);
    CanFrame f;
    ASSERT_TRUE(encode(d.command, 0, CanIds{}, f));
    // An id beyond 12 bits is taken modulo 4096.
    EXPECT_EQ(s.schedule(weed(1000, 0, 4096 + 7), at(0, 1000)).command.target_id, 7);

    // The odometer past 2^32 mm: the command carries it modulo 2^32, and the
    // frame modulo 2^18; fire_distance_mm agrees with the scheduler's distance.
    const double odom = 4294967296.0 + 100.0;
    d = s.schedule(weed(odom - 400 + 50, 0), at(odom, 1000));  // fire 150 mm ahead
    ASSERT_TRUE(d.ok());
    EXPECT_EQ(d.command.fire_odom_mm, 250u);
    ASSERT_TRUE(encode(d.command, 1, CanIds{}, f));
    TargetCommand back;
    ASSERT_TRUE(decode(f, CanIds{}, back));
    EXPECT_EQ(fire_distance_mm(back.fire_odom_mm, static_cast<std::uint32_t>(100)), 150);
}

TEST(ActuationScheduler, InvalidToolTablesAreRejected)
{
    std::string_view err;
    EXPECT_FALSE(Scheduler::make({}, params(), &err));
    EXPECT_EQ(err, "no tools");
    const ToolSpec bad_id[] = {{16, 0, -1, 1, 1}};
    EXPECT_FALSE(Scheduler::make(bad_id, params(), &err));
    const ToolSpec repeated[] = {{1, 0, -1, 1, 1}, {1, 0, 2, 3, 1}};
    EXPECT_FALSE(Scheduler::make(repeated, params(), &err));
    EXPECT_EQ(err, "repeated tool id");
    const ToolSpec empty_span[] = {{1, 0, 1, 1, 1}};
    EXPECT_FALSE(Scheduler::make(empty_span, params(), &err));
    const ToolSpec lanes[] = {{1, 0, -1, 1, 17}};
    EXPECT_FALSE(Scheduler::make(lanes, params(), &err));
    const ToolSpec no_lanes[] = {{1, 0, -1, 1, 0}};
    EXPECT_FALSE(Scheduler::make(no_lanes, params(), &err));
    SchedulerParams p = params();
    p.lead_ms = -1;
    EXPECT_FALSE(Scheduler::make(kTools, p, &err));
}

// Real-time discipline: after construction, tracking and scheduling a whole
// field strip allocate nothing.
TEST(ActuationRealTime, TrackerAndSchedulerAllocateNothing)
{
    TrackerParams tp;
    tp.association_radius_mm = 10;
    tp.exit_margin_mm = 40;
    Tracker tracker(tp);
    Scheduler sched = make();

    // Plants every 37 mm, lanes across the boom; preallocated detections.
    constexpr int kPlants = 200;
    std::vector<TrackDetection> dets(kPlants);
    std::vector<TargetCommand> commands(kPlants * 2);
    std::size_t n_commands = 0;
    std::size_t n_targets = 0;

    const long before = stemd::test::allocations();
    for (double odom = 0; odom < 37.0 * kPlants + 1000; odom += 30) {
        std::size_t n = 0;
        for (int i = 0; i < kPlants; ++i) {
            const double s = 200 + 37.0 * i;
            if (s < odom - 150 || s > odom + 150)
                continue;
            dets[n++] = {s + 0.5 * std::sin(odom + i), -280 + 5.0 * (i % 100), 0.9f,
                         i % 4 == 0 ? PlantClass::Crop : PlantClass::Weed, 2};
        }
        TrackFrame f;
        f.t_sample_ns = static_cast<std::int64_t>(odom * 1e6);
        f.odom_at_capture_mm = odom;
        f.view_s_min_mm = odom - 150;
        f.view_s_max_mm = odom + 150;
        f.detections = std::span(dets.data(), n);
        for (const Target& t : tracker.update(f)) {
            ++n_targets;
            const auto d = sched.schedule(t, {f.t_sample_ns, odom, 1000, true});
            if (d.ok() && n_commands < commands.size())
                commands[n_commands++] = d.command;
        }
    }
    const long after = stemd::test::allocations();
    EXPECT_EQ(after - before, 0);
    EXPECT_EQ(n_targets, static_cast<std::size_t>(kPlants));
    EXPECT_EQ(n_commands, static_cast<std::size_t>(kPlants - kPlants / 4));  // weeds only
    EXPECT_EQ(sched.counters().policy, static_cast<std::uint64_t>(kPlants / 4));
    EXPECT_EQ(sched.counters().deadline_misses + sched.counters().no_tool, 0u);
}
