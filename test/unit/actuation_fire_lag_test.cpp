// Tool timing, pure: the compensation, the lag statistics, the latency
// learner, the latency in the scheduler, the simulated tool controller, and
// the targets: a 40 ms tool at 5 km/h strikes v × 40 ms late uncompensated,
// and within 5 mm (p95) of the stem compensated, from 1 to 8 km/h.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "stemd/actuation/fire_lag.hpp"
#include "stemd/actuation/scheduler.hpp"
#include "stemd/actuation/tool_simulator.hpp"

namespace stemd::actuation {
namespace {

constexpr double kKmh = 1e6 / 3600.0;  // mm/s per km/h

TEST(FireLag, CompensationIsSpeedTimesLatencyAndNothingWhenStanding)
{
    EXPECT_DOUBLE_EQ(compensation_mm(1400.0, 40.0, 1.0), 56.0);
    EXPECT_DOUBLE_EQ(compensation_mm(2000.0, 12.5, 1.0), 25.0);
    EXPECT_EQ(compensation_mm(1.0, 40.0, 1.0), 0.0);     // at the standing speed
    EXPECT_EQ(compensation_mm(-500.0, 40.0, 1.0), 0.0);  // reversing
    EXPECT_EQ(compensation_mm(1400.0, 0.0, 1.0), 0.0);
    EXPECT_EQ(compensation_mm(std::nan(""), 40.0, 1.0), 0.0);
}

TEST(FireLag, LagInMsNeedsMotion)
{
    EXPECT_DOUBLE_EQ(lag_ms_of(56.0, 1400.0), 40.0);
    EXPECT_DOUBLE_EQ(lag_ms_of(-14.0, 1400.0), -10.0);
    EXPECT_TRUE(std::isnan(lag_ms_of(5.0, kMinLagSpeedMmPerS - 1)));
    EXPECT_TRUE(std::isnan(lag_ms_of(5.0, 0.0)));
}

// The nearest-rank 95th percentile of `v`, for comparison with the histogram's.
double nearest_rank_p95(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    return v[static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(v.size()))) - 1];
}

TEST(LagStats, MeansAndP95WithinOneBucket)
{
    LagStats stats;
    std::vector<double> mm, ms, strike;
    std::mt19937 rng(7);
    std::normal_distribution<double> lag(56.0, 3.0);
    for (int i = 0; i < 1000; ++i) {
        const double l = lag(rng);
        const double speed = 1000.0 + (i % 7) * 100.0;
        mm.push_back(l);
        ms.push_back(l / speed * 1000.0);
        strike.push_back(l - 56.0);
        stats.record(l, l / speed * 1000.0, l - 56.0);
    }
    const LagSummary s = stats.summary();
    ASSERT_EQ(s.count, 1000u);
    ASSERT_EQ(s.count_ms, 1000u);
    double sum_mm = 0, sum_ms = 0;
    for (std::size_t i = 0; i < mm.size(); ++i) {
        sum_mm += mm[i];
        sum_ms += ms[i];
    }
    EXPECT_NEAR(s.mean_mm, sum_mm / 1000.0, 1e-9);
    EXPECT_NEAR(s.mean_ms, sum_ms / 1000.0, 1e-9);
    // The bucket's upper edge: at or above the exact value, by less than a bucket.
    const double p95_mm = nearest_rank_p95(mm);
    EXPECT_GE(s.p95_mm, p95_mm);
    EXPECT_LE(s.p95_mm, p95_mm + LagStats::kMmBucket);
    const double p95_ms = nearest_rank_p95(ms);
    EXPECT_GE(s.p95_ms, p95_ms);
    EXPECT_LE(s.p95_ms, p95_ms + LagStats::kMsBucket);
    for (double& v : strike)
        v = std::abs(v);
    const double p95_strike = nearest_rank_p95(strike);
    EXPECT_GE(s.strike_p95_mm, p95_strike);
    EXPECT_LE(s.strike_p95_mm, p95_strike + LagStats::kStrikeBucket);
}

TEST(LagStats, StandingHasNoMsAndNonFiniteIsIgnored)
{
    LagStats stats;
    stats.record(10.0, std::nan(""), 1.0);
    stats.record(std::nan(""), 5.0, 1.0);
    stats.record(10.0, 5.0, std::numeric_limits<double>::infinity());
    const LagSummary s = stats.summary();
    EXPECT_EQ(s.count, 1u);
    EXPECT_EQ(s.count_ms, 0u);
    EXPECT_EQ(s.mean_mm, 10.0);
    EXPECT_EQ(s.mean_ms, 0.0);
    EXPECT_EQ(LagStats{}.summary().count, 0u);
}

TEST(LagStats, ValuesBeyondTheRangeCountInTheEndBuckets)
{
    LagStats stats;
    stats.record(5000.0, 900.0, -400.0);
    const LagSummary s = stats.summary();
    EXPECT_EQ(s.count, 1u);
    EXPECT_EQ(s.mean_mm, 5000.0);  // the mean is exact
    EXPECT_EQ(s.p95_mm, 512.0);    // the histogram's end
    EXPECT_EQ(s.p95_ms, 256.0);
    EXPECT_EQ(s.strike_p95_mm, 256.0);
}

TEST(LatencyLearner, MedianOfTheLastSamplesWithinBounds)
{
    LatencyLearner l(10.0, 0.0, 100.0);
    EXPECT_EQ(l.latency_ms(), 10.0);
    for (int i = 0; i < 4; ++i)
        EXPECT_FALSE(l.add(40.0)) << "fewer than " << LatencyLearner::kMinSamples << " samples";
    EXPECT_EQ(l.latency_ms(), 10.0);
    EXPECT_TRUE(l.add(40.0));
    EXPECT_EQ(l.latency_ms(), 40.0);
    // One wild report does not move it; nor a non-finite one.
    EXPECT_FALSE(l.add(900.0));
    EXPECT_FALSE(l.add(std::nan("")));
    EXPECT_EQ(l.latency_ms(), 40.0);
    // Below the minimum change it stays.
    for (int i = 0; i < 10; ++i)
        l.add(40.1);
    EXPECT_EQ(l.latency_ms(), 40.0);
    // The window forgets: a tool that got slower is followed.
    for (std::size_t i = 0; i < LatencyLearner::kWindow; ++i)
        l.add(60.0);
    EXPECT_EQ(l.latency_ms(), 60.0);
    // Clamped to the bounds.
    for (std::size_t i = 0; i < LatencyLearner::kWindow; ++i)
        l.add(250.0);
    EXPECT_EQ(l.latency_ms(), 100.0);
    LatencyLearner low(5.0, 2.0, 50.0);
    for (int i = 0; i < 10; ++i)
        low.add(-30.0);
    EXPECT_EQ(low.latency_ms(), 2.0);
}

ToolSpec tool(double latency_ms)
{
    return {.id = 2, .offset_mm = 600, .y_min_mm = -200, .y_max_mm = 200, .lanes = 1, .latency_ms = latency_ms};
}

Target weed(double s_mm)
{
    Target t;
    t.target_id = 9;
    t.s_mm = s_mm;
    t.y_mm = 0;
    t.plant_class = PlantClass::Weed;
    return t;
}

ScheduleNow moving(double odom_mm, double speed_mm_per_s, bool enabled = true)
{
    return {.now_ns = 1'000'000'000, .odom_mm = odom_mm, .speed_mm_per_s = speed_mm_per_s, .enabled = enabled};
}

TEST(SchedulerLatency, CommandsEarlierBySpeedTimesLatency)
{
    const std::array tools{tool(40.0)};
    auto s = Scheduler::make(tools, SchedulerParams{});
    ASSERT_TRUE(s);
    const ScheduleDecision d = s->schedule(weed(1000.0), moving(0.0, 1400.0));
    ASSERT_TRUE(d.ok());
    EXPECT_DOUBLE_EQ(d.aim_odom_mm, 1600.0);
    EXPECT_DOUBLE_EQ(d.lead_mm, 56.0);
    EXPECT_DOUBLE_EQ(d.fire_odom_mm, 1544.0);
    EXPECT_EQ(d.command.fire_odom_mm, 1544u);
    // The deadline is the compensated point's: (1544 mm / 1.4 m/s) - lead_ms.
    EXPECT_NEAR(static_cast<double>(d.deadline_ns - 1'000'000'000) / 1e6, 1544.0 / 1.4 - 20.0, 1e-3);
    // Standing: nothing to lead.
    const ScheduleDecision st = s->schedule(weed(1000.0), moving(0.0, 0.0));
    ASSERT_TRUE(st.ok());
    EXPECT_EQ(st.lead_mm, 0.0);
    EXPECT_EQ(st.command.fire_odom_mm, 1600u);
    // A learned latency applies to the next command.
    ASSERT_TRUE(s->set_latency_ms(2, 20.0));
    EXPECT_FALSE(s->set_latency_ms(3, 20.0));
    EXPECT_EQ(s->schedule(weed(1000.0), moving(0.0, 1400.0)).command.fire_odom_mm, 1572u);
}

TEST(SchedulerLatency, CompensationIntoThePastIsADroppedCountedMiss)
{
    const std::array tools{tool(100.0)};
    auto s = Scheduler::make(tools, SchedulerParams{.lead_ms = 20.0, .send_budget_ms = 2.0});
    ASSERT_TRUE(s);
    // 2 m/s: the stem is 250 mm (125 ms) ahead; 100 ms of latency leaves
    // 50 mm (25 ms) to the fire point: enough for the 22 ms budget.
    EXPECT_TRUE(s->schedule(weed(0.0), moving(350.0, 2000.0)).ok());
    // 150 mm ahead: the fire point is 50 mm behind the machine.
    const ScheduleDecision late = s->schedule(weed(0.0), moving(450.0, 2000.0));
    EXPECT_EQ(late.outcome, ScheduleOutcome::deadline_miss);
    EXPECT_TRUE(late.compensation_miss);
    // 140 mm ahead: the fire point 60 mm too close for lead + budget (44 mm).
    const ScheduleDecision close = s->schedule(weed(0.0), moving(560.0, 2000.0));
    EXPECT_EQ(close.outcome, ScheduleOutcome::deadline_miss);
    EXPECT_FALSE(close.compensation_miss) << "40 mm ahead is too close even without the latency";
    EXPECT_EQ(s->counters().deadline_misses, 2u);
    EXPECT_EQ(s->counters().compensation_misses, 1u);
    EXPECT_EQ(s->counters().sent, 1u);
    // The enable input still comes first.
    EXPECT_EQ(s->schedule(weed(0.0), moving(0.0, 2000.0, false)).outcome, ScheduleOutcome::disabled);
}

TEST(SchedulerLatency, InvalidLatenciesAreRefused)
{
    std::string_view why;
    for (double bad : {-1.0, 1000.5, std::nan("")}) {
        const std::array tools{tool(bad)};
        EXPECT_FALSE(Scheduler::make(tools, SchedulerParams{}, &why)) << bad;
        EXPECT_NE(why.find("latency"), std::string_view::npos);
    }
    ToolSpec learn = tool(10.0);
    learn.learn_latency = true;
    learn.latency_min_ms = 50.0;
    learn.latency_max_ms = 20.0;
    const std::array tools{learn};
    EXPECT_FALSE(Scheduler::make(tools, SchedulerParams{}, &why));
}

TEST(ToolSimulator, StrikesDelayAfterThePointWhateverTheStep)
{
    for (const std::int64_t step_ns : {1'000'000LL, 7'000'000LL, 33'000'000LL}) {
        ToolSimulator sim(40.0);
        const double v = 1400.0;
        sim.advance(0, 0.0);
        protocol::TargetCommand c;
        c.target_id = 5;
        c.tool_id = 1;
        c.lane = 3;
        c.fire_odom_mm = 700;
        ASSERT_TRUE(sim.command(c, 0.0));
        std::vector<protocol::ToolFired> fired;
        for (std::int64_t t = step_ns; t < 2'000'000'000; t += step_ns)
            for (const protocol::ToolFired& f : sim.advance(t, v * static_cast<double>(t) / 1e9))
                fired.push_back(f);
        ASSERT_EQ(fired.size(), 1u) << step_ns;
        EXPECT_EQ(fired[0].target_id, 5);
        EXPECT_EQ(fired[0].tool_id, 1);
        EXPECT_EQ(fired[0].lane, 3);
        EXPECT_EQ(fired[0].fired_odom_mm, 756u) << "700 mm + 1.4 m/s x 40 ms; step " << step_ns;
    }
}

TEST(ToolSimulator, PassedPointsAreLateAndTheOdometerWraps)
{
    ToolSimulator sim(10.0);
    protocol::TargetCommand c;
    c.fire_odom_mm = 100;
    EXPECT_FALSE(sim.command(c, 500.0));
    EXPECT_EQ(sim.counters().late, 1u);
    // Across 2^18 (the TARGET's field): 262100 -> fire at 262144 + 50.
    c.fire_odom_mm = 50;
    ASSERT_TRUE(sim.command(c, 262100.0));
    sim.advance(0, 262100.0);
    std::vector<protocol::ToolFired> fired;
    for (std::int64_t t = 1'000'000; t < 1'000'000'000; t += 1'000'000)
        for (const protocol::ToolFired& f : sim.advance(t, 262100.0 + 1000.0 * static_cast<double>(t) / 1e9))
            fired.push_back(f);
    ASSERT_EQ(fired.size(), 1u);
    EXPECT_EQ(fired[0].fired_odom_mm, 262144u + 60u);
}

// One pass down a strip at `kmh` with a tool that strikes `delay_ms` after
// its point, configured with latency_ms (or learning it): plants every
// 97 mm; each TARGET is scheduled when its stem is 700 mm before the tool,
// with the speed then; the speed wanders ±3 % (a tractor on soil), so the
// speed at the strike is not quite the one the command was made with.
struct Pass {
    LagStats stats;                  // lag = fired - commanded, strike = fired - stem
    std::vector<double> strike_mm;   // in strike order
    double latency_ms = 0;           // the scheduler's at the end
};

Pass drive(double kmh, double delay_ms, double latency_ms, bool learn = false, int plants = 200)
{
    const double v0 = kmh * kKmh;
    ToolSpec spec = tool(latency_ms);
    spec.learn_latency = learn;
    const std::array tools{spec};
    auto s = Scheduler::make(tools, SchedulerParams{});
    EXPECT_TRUE(s);
    LatencyLearner learner(latency_ms, spec.latency_min_ms, spec.latency_max_ms);
    ToolSimulator sim(delay_ms);
    Pass out;
    std::vector<double> aim(plants), commanded(plants);
    const auto speed = [&](double t_s) { return v0 * (1.0 + 0.03 * std::sin(2.0 * M_PI * t_s / 2.3)); };
    double odom = 0;
    int next = 0;
    constexpr std::int64_t kStepNs = 1'000'000;
    sim.advance(0, 0.0);
    for (std::int64_t t = kStepNs; sim.counters().fired < static_cast<std::uint64_t>(plants); t += kStepNs) {
        const double t_s = static_cast<double>(t) / 1e9;
        odom += speed(t_s) * static_cast<double>(kStepNs) / 1e9;
        const auto s_mm = [](int i) { return 1000.0 + 97.0 * i; };
        while (next < plants && odom >= s_mm(next) + 600.0 - 700.0) {
            Target tg = weed(s_mm(next));
            tg.target_id = static_cast<std::uint16_t>(next);
            const ScheduleDecision d =
                s->schedule(tg, {.now_ns = t, .odom_mm = odom, .speed_mm_per_s = speed(t_s), .enabled = true});
            EXPECT_TRUE(d.ok());
            aim[static_cast<std::size_t>(next)] = d.aim_odom_mm;
            commanded[static_cast<std::size_t>(next)] = d.command.fire_odom_mm;
            EXPECT_TRUE(sim.command(d.command, odom));
            ++next;
        }
        for (const protocol::ToolFired& f : sim.advance(t, odom)) {
            const std::size_t i = f.target_id;
            const double lag_mm = protocol::fire_distance_mm(f.fired_odom_mm, static_cast<std::uint32_t>(commanded[i]));
            const double strike_mm = static_cast<double>(f.fired_odom_mm) - aim[i];
            const double lag_ms = lag_ms_of(lag_mm, speed(t_s));
            out.stats.record(lag_mm, lag_ms, strike_mm);
            out.strike_mm.push_back(strike_mm);
            if (learn && learner.add(lag_ms))
                s->set_latency_ms(spec.id, learner.latency_ms());
        }
        if (t > 1'000'000'000'000) {
            ADD_FAILURE() << "the tool never fired them all";
            break;
        }
    }
    out.latency_ms = s->tools()[0].latency_ms;
    return out;
}

// 40 ms at 1.4 m/s (5 km/h) is 56 mm: uncompensated, that is how late
// every strike lands, and the lag measures the 40 ms whatever the speed.
TEST(ToolTimingTargets, UncompensatedStrikesLandSpeedTimesDelayLate)
{
    const Pass p = drive(5.04, 40.0, 0.0);   // 1400 mm/s
    const LagSummary s = p.stats.summary();
    ASSERT_EQ(s.count, 200u);
    EXPECT_NEAR(s.strike_mean_mm, 56.0, 1.0);
    EXPECT_NEAR(s.mean_mm, 56.0, 1.0);
    EXPECT_NEAR(s.mean_ms, 40.0, 0.5);
    for (double kmh : {1.0, 8.0}) {
        const LagSummary o = drive(kmh, 40.0, 0.0).stats.summary();
        EXPECT_NEAR(o.mean_mm, kmh * kKmh * 0.040, 1.0) << kmh << " km/h";
        EXPECT_NEAR(o.mean_ms, 40.0, 0.5) << kmh << " km/h";
    }
}

TEST(ToolTimingTargets, CompensatedStrikesLandWithin5MmP95From1To8Kmh)
{
    for (double kmh = 1.0; kmh <= 8.0; kmh += 1.0) {
        const Pass p = drive(kmh, 40.0, 40.0);
        const LagSummary s = p.stats.summary();
        ASSERT_EQ(s.count, 200u);
        EXPECT_LE(s.strike_p95_mm, 5.0) << kmh << " km/h";
        // The lag against the command is still the tool's whole 40 ms.
        EXPECT_NEAR(s.mean_ms, 40.0, 0.5) << kmh << " km/h";
    }
}

TEST(ToolTimingTargets, LearnedLatencyReachesTheTargetFromZero)
{
    for (double kmh : {1.0, 5.0, 8.0}) {
        const Pass p = drive(kmh, 40.0, 0.0, true, 300);
        EXPECT_NEAR(p.latency_ms, 40.0, 1.0) << kmh << " km/h";
        // After the window filled (and the commands already out at the time
        // drained), strikes are on the stem.
        LagStats late;
        for (std::size_t i = 100; i < p.strike_mm.size(); ++i)
            late.record(p.strike_mm[i], std::nan(""), p.strike_mm[i]);
        EXPECT_LE(late.summary().strike_p95_mm, 5.0) << kmh << " km/h";
    }
}

}  // namespace
}  // namespace stemd::actuation
