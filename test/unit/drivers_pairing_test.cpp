// RGB/NIR pairing by capture timestamp (include/stemd/drivers/timestamp_pairing.hpp)
// on fake timestamps: jitter, lost frames on either side, clock offsets within
// and over the tolerance, burst orderings, ties, out-of-order frames, a full
// side (force), advance(), and a randomized comparison with an offline
// reference of the documented rule. Then PairedNirSource's errors without
// devices (test/vm/paired_nir_check.cpp runs it on two vivid instances).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <random>
#include <set>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include "stemd/drivers/timestamp_pairing.hpp"
#include "captured_log.hpp"
#include "v4l2/paired_nir_source.hpp"

using stemd::drivers::PairDecision;
using stemd::drivers::PairSide;
using stemd::drivers::PushResult;
using stemd::drivers::TimestampPairer;

namespace {

constexpr std::int64_t ms = 1'000'000;
constexpr std::int64_t kPeriod = 33 * ms;
using Kind = PairDecision::Kind;

// Nothing on the heap: the pairer is a plain value.
static_assert(std::is_trivially_destructible_v<TimestampPairer<4>>);
static_assert(std::is_trivially_copyable_v<TimestampPairer<4>>);

// Usable at compile time (so it is pure logic).
constexpr bool compile_time_pairs()
{
    TimestampPairer<4> p(5 * ms);
    p.push(PairSide::rgb, 100 * ms, 1);
    p.push(PairSide::nir, 101 * ms, 2);
    const auto d = p.decide();
    return d && d->kind == Kind::paired && d->rgb_id == 1 && d->nir_id == 2 && !p.decide();
}
static_assert(compile_time_pairs());

struct Event {
    PairSide side;
    std::int64_t t;
};

struct Outcome {
    std::vector<std::pair<std::int64_t, std::int64_t>> pairs;  // (rgb t, nir t)
    std::vector<std::int64_t> unpaired_rgb;
    std::vector<std::int64_t> unpaired_nir;
    std::uint64_t forced = 0;
};

// Feeds events as the source does (force while full, push, decide all) and
// drains at the end with force(). Ids are the timestamps' indices.
template <std::size_t N>
Outcome run(TimestampPairer<N>& p, const std::vector<Event>& events, bool drain = true)
{
    Outcome o;
    auto handle = [&](const PairDecision& d) {
        o.forced += d.forced ? 1 : 0;
        switch (d.kind) {
        case Kind::paired: o.pairs.emplace_back(d.rgb_t_ns, d.nir_t_ns); break;
        case Kind::unpaired_rgb: o.unpaired_rgb.push_back(d.rgb_t_ns); break;
        case Kind::unpaired_nir: o.unpaired_nir.push_back(d.nir_t_ns); break;
        }
    };
    std::uint32_t id = 0;
    for (const Event& e : events) {
        while (p.full(e.side))
            handle(*p.force(e.side));
        if (p.push(e.side, e.t, id++) == PushResult::out_of_order)
            (e.side == PairSide::rgb ? o.unpaired_rgb : o.unpaired_nir).push_back(e.t);
        while (auto d = p.decide())
            handle(*d);
    }
    if (drain) {
        while (p.pending(PairSide::rgb) + p.pending(PairSide::nir) > 0)
            handle(*p.force(PairSide::nir));
    }
    return o;
}

// Two cameras at kPeriod: rgb at i*kPeriod + rgb_off(i), nir at i*kPeriod + nir_off(i),
// interleaved by timestamp (ties: rgb first), skipping lost frames.
template <typename RgbOff, typename NirOff>
std::vector<Event> streams(int n, RgbOff rgb_off, NirOff nir_off, const std::set<int>& lost_rgb = {},
                           const std::set<int>& lost_nir = {})
{
    std::vector<Event> ev;
    for (int i = 0; i < n; ++i) {
        if (!lost_rgb.count(i))
            ev.push_back({PairSide::rgb, 1000 * ms + i * kPeriod + rgb_off(i)});
        if (!lost_nir.count(i))
            ev.push_back({PairSide::nir, 1000 * ms + i * kPeriod + nir_off(i)});
    }
    std::stable_sort(ev.begin(), ev.end(), [](const Event& a, const Event& b) { return a.t < b.t; });
    return ev;
}

// The documented rule, offline: RGB frames in time order, each takes the
// unused NIR frame nearest to it (the earlier on a tie) if within tolerance.
Outcome reference(std::vector<std::int64_t> rgb, std::vector<std::int64_t> nir, std::int64_t tol)
{
    std::sort(rgb.begin(), rgb.end());
    std::sort(nir.begin(), nir.end());
    std::vector<bool> used(nir.size(), false);
    Outcome o;
    for (const std::int64_t r : rgb) {
        std::size_t best = nir.size();
        for (std::size_t i = 0; i < nir.size(); ++i) {
            if (used[i])
                continue;
            if (best == nir.size() || std::llabs(nir[i] - r) < std::llabs(nir[best] - r))
                best = i;
        }
        if (best < nir.size() && std::llabs(nir[best] - r) <= tol) {
            used[best] = true;
            o.pairs.emplace_back(r, nir[best]);
        } else {
            o.unpaired_rgb.push_back(r);
        }
    }
    for (std::size_t i = 0; i < nir.size(); ++i)
        if (!used[i])
            o.unpaired_nir.push_back(nir[i]);
    return o;
}

void expect_same(Outcome a, Outcome b)
{
    std::sort(a.pairs.begin(), a.pairs.end());
    std::sort(b.pairs.begin(), b.pairs.end());
    std::sort(a.unpaired_rgb.begin(), a.unpaired_rgb.end());
    std::sort(b.unpaired_rgb.begin(), b.unpaired_rgb.end());
    std::sort(a.unpaired_nir.begin(), a.unpaired_nir.end());
    std::sort(b.unpaired_nir.begin(), b.unpaired_nir.end());
    EXPECT_EQ(a.pairs, b.pairs);
    EXPECT_EQ(a.unpaired_rgb, b.unpaired_rgb);
    EXPECT_EQ(a.unpaired_nir, b.unpaired_nir);
}

}  // namespace

TEST(TimestampPairer, SimultaneousFramesPairAtOnce)
{
    TimestampPairer<4> p(5 * ms);
    EXPECT_EQ(p.push(PairSide::rgb, 100 * ms, 7), PushResult::accepted);
    EXPECT_FALSE(p.decide());  // no NIR yet
    EXPECT_EQ(p.push(PairSide::nir, 100 * ms, 9), PushResult::accepted);
    const auto d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::paired);
    EXPECT_EQ(d->rgb_id, 7u);
    EXPECT_EQ(d->nir_id, 9u);
    EXPECT_EQ(d->rgb_t_ns, 100 * ms);
    EXPECT_EQ(d->nir_t_ns, 100 * ms);
    EXPECT_FALSE(d->forced);
    EXPECT_FALSE(p.decide());
    EXPECT_EQ(p.counters().paired, 1u);
    EXPECT_EQ(p.pending(PairSide::rgb) + p.pending(PairSide::nir), 0u);
}

TEST(TimestampPairer, JitterWithinTolerancePairsEverything)
{
    std::mt19937 rng(1);
    std::uniform_int_distribution<std::int64_t> jitter(-2 * ms, 2 * ms);
    std::vector<std::int64_t> rj(200), nj(200);
    for (int i = 0; i < 200; ++i) {
        rj[i] = jitter(rng);
        nj[i] = jitter(rng);
    }
    TimestampPairer<4> p(5 * ms);
    const auto o = run(p, streams(200, [&](int i) { return rj[i]; }, [&](int i) { return nj[i]; }));
    ASSERT_EQ(o.pairs.size(), 200u);
    for (int i = 0; i < 200; ++i) {
        EXPECT_EQ(o.pairs[i].first, 1000 * ms + i * kPeriod + rj[i]);
        EXPECT_EQ(o.pairs[i].second, 1000 * ms + i * kPeriod + nj[i]);
    }
    EXPECT_TRUE(o.unpaired_rgb.empty());
    EXPECT_TRUE(o.unpaired_nir.empty());
    EXPECT_LE(o.forced, 1u);  // the last frame, by the final drain
    EXPECT_EQ(p.counters().paired, 200u);
}

TEST(TimestampPairer, LostNirFrameDropsItsRgbFrameAsSoonAsTheNextNirComes)
{
    TimestampPairer<4> p(5 * ms);
    p.push(PairSide::rgb, 0, 0);
    p.push(PairSide::nir, 1 * ms, 0);
    ASSERT_EQ(p.decide()->kind, Kind::paired);
    p.push(PairSide::rgb, kPeriod, 1);  // its NIR frame is lost
    EXPECT_FALSE(p.decide());            // it may still come
    p.push(PairSide::rgb, 2 * kPeriod, 2);
    EXPECT_FALSE(p.decide());
    p.push(PairSide::nir, 2 * kPeriod + 1 * ms, 2);  // newer than kPeriod + tolerance
    auto d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::unpaired_rgb);
    EXPECT_EQ(d->rgb_id, 1u);
    d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::paired);
    EXPECT_EQ(d->rgb_id, 2u);
    EXPECT_EQ(d->nir_id, 2u);
    EXPECT_EQ(p.counters().unpaired_rgb, 1u);
    EXPECT_EQ(p.counters().unpaired_nir, 0u);
    EXPECT_EQ(p.counters().paired, 2u);
}

TEST(TimestampPairer, LostRgbFrameDropsItsNirFrame)
{
    TimestampPairer<4> p(5 * ms);
    const auto o = run(p, streams(50, [](int) { return 0; }, [](int i) { return (i % 3 - 1) * ms; }, {10, 11, 30}));
    EXPECT_EQ(o.pairs.size(), 47u);
    EXPECT_TRUE(o.unpaired_rgb.empty());
    ASSERT_EQ(o.unpaired_nir.size(), 3u);
    EXPECT_EQ(o.unpaired_nir[0], 1000 * ms + 10 * kPeriod + (10 % 3 - 1) * ms);
    EXPECT_EQ(o.forced, 0u);
    EXPECT_EQ(p.counters().unpaired_nir, 3u);
}

TEST(TimestampPairer, LostNirFramesInStream)
{
    TimestampPairer<4> p(5 * ms);
    const auto o = run(p, streams(50, [](int) { return 0; }, [](int) { return 2 * ms; }, {}, {0, 5, 6, 7, 49}));
    EXPECT_EQ(o.pairs.size(), 45u);
    EXPECT_EQ(o.unpaired_rgb.size(), 5u);
    EXPECT_TRUE(o.unpaired_nir.empty());
    // The last RGB frame (49) is decided only by the final drain: nothing newer came.
    EXPECT_EQ(o.forced, 1u);
}

TEST(TimestampPairer, ClockOffsetWithinToleranceInEitherDirection)
{
    for (const std::int64_t off : {-4 * ms, 4 * ms, 5 * ms, -5 * ms}) {
        TimestampPairer<4> p(5 * ms);
        const auto o = run(p, streams(60, [](int) { return 0; }, [&](int) { return off; }));
        EXPECT_EQ(o.pairs.size(), 60u) << off;
        for (const auto& [r, n] : o.pairs)
            EXPECT_EQ(n - r, off);
    }
}

TEST(TimestampPairer, ClockOffsetOverToleranceDropsEverything)
{
    for (const std::int64_t off : {-6 * ms, 6 * ms, 16 * ms}) {
        TimestampPairer<4> p(5 * ms);
        const auto o = run(p, streams(60, [](int) { return 0; }, [&](int) { return off; }));
        EXPECT_TRUE(o.pairs.empty()) << off;
        EXPECT_EQ(o.unpaired_rgb.size(), 60u);
        EXPECT_EQ(o.unpaired_nir.size(), 60u);
        EXPECT_LE(o.forced, 2u);  // only the drain at the end
        EXPECT_EQ(p.counters().unpaired_rgb, 60u);
        EXPECT_EQ(p.counters().unpaired_nir, 60u);
    }
}

TEST(TimestampPairer, BurstOrderingsGiveTheSamePairs)
{
    // Three frames each side, jittered; delivered all-RGB-first, all-NIR-first,
    // and interleaved: the same pairs.
    const std::int64_t rgb[] = {0, kPeriod + 1 * ms, 2 * kPeriod - 1 * ms};
    const std::int64_t nir[] = {2 * ms, kPeriod - 2 * ms, 2 * kPeriod + 3 * ms};
    std::vector<std::vector<Event>> orders(3);
    for (int i = 0; i < 3; ++i) {
        orders[0].push_back({PairSide::rgb, rgb[i]});
        orders[1].push_back({PairSide::nir, nir[i]});
    }
    for (int i = 0; i < 3; ++i) {
        orders[0].push_back({PairSide::nir, nir[i]});
        orders[1].push_back({PairSide::rgb, rgb[i]});
        orders[2].push_back({PairSide::nir, nir[i]});
        orders[2].push_back({PairSide::rgb, rgb[i]});
    }
    for (const auto& order : orders) {
        TimestampPairer<4> p(5 * ms);
        const auto o = run(p, order);
        ASSERT_EQ(o.pairs.size(), 3u);
        for (int i = 0; i < 3; ++i) {
            EXPECT_EQ(o.pairs[i].first, rgb[i]);
            EXPECT_EQ(o.pairs[i].second, nir[i]);
        }
    }
}

TEST(TimestampPairer, BurstOfFourDecidesWithoutForcing)
{
    // A burst of 4 RGB frames (capacity), then their 4 NIR frames.
    TimestampPairer<4> p(5 * ms);
    for (std::uint32_t i = 0; i < 4; ++i)
        EXPECT_EQ(p.push(PairSide::rgb, i * kPeriod, i), PushResult::accepted);
    EXPECT_TRUE(p.full(PairSide::rgb));
    EXPECT_EQ(p.push(PairSide::rgb, 4 * kPeriod, 4), PushResult::full);
    for (std::uint32_t i = 0; i < 4; ++i) {
        p.push(PairSide::nir, i * kPeriod + 1 * ms, 10 + i);
        const auto d = p.decide();
        ASSERT_TRUE(d);
        EXPECT_EQ(d->kind, Kind::paired);
        EXPECT_EQ(d->rgb_id, i);
        EXPECT_EQ(d->nir_id, 10 + i);
    }
    EXPECT_EQ(p.counters().forced, 0u);
}

TEST(TimestampPairer, NirBeforeRgbWaitsUntilNothingNearerCanCome)
{
    TimestampPairer<4> p(5 * ms);
    p.push(PairSide::rgb, 100 * ms, 1);
    p.push(PairSide::nir, 98 * ms, 1);
    EXPECT_FALSE(p.decide());  // a NIR at 98..102 ms could still come
    p.push(PairSide::nir, 101 * ms, 2);  // nearer: wins
    auto d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::paired);
    EXPECT_EQ(d->nir_id, 2u);
    d = p.decide();  // the older NIR: no later RGB can prefer it
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::unpaired_nir);
    EXPECT_EQ(d->nir_id, 1u);
    EXPECT_FALSE(p.decide());
}

TEST(TimestampPairer, AdvanceDecidesWithoutANewerFrame)
{
    TimestampPairer<4> p(5 * ms);
    p.push(PairSide::rgb, 100 * ms, 1);
    p.push(PairSide::nir, 98 * ms, 1);
    EXPECT_FALSE(p.decide());
    p.advance(PairSide::nir, 101 * ms);  // a NIR at 101 ms could still be nearer than 98 ms
    EXPECT_FALSE(p.decide());
    p.advance(PairSide::nir, 102 * ms);  // the NIR device is reopening: nothing older will come
    auto d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::paired);
    EXPECT_EQ(p.watermark(PairSide::nir), 102 * ms);
    p.advance(PairSide::nir, 50 * ms);  // never lowers it
    EXPECT_EQ(p.watermark(PairSide::nir), 102 * ms);

    p.push(PairSide::rgb, 200 * ms, 2);  // NIR device gone
    EXPECT_FALSE(p.decide());
    p.advance(PairSide::nir, 205 * ms);  // exactly at tolerance: a NIR at 205 ms could still pair
    EXPECT_FALSE(p.decide());
    p.advance(PairSide::nir, 205 * ms + 1);
    d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::unpaired_rgb);
    EXPECT_FALSE(d->forced);
}

TEST(TimestampPairer, ExactlyAtToleranceStillPairs)
{
    TimestampPairer<4> p(5 * ms);
    p.push(PairSide::rgb, 100 * ms, 1);
    p.push(PairSide::nir, 105 * ms, 1);
    const auto d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::paired);
}

TEST(TimestampPairer, TieGoesToTheEarlierNir)
{
    TimestampPairer<4> p(5 * ms);
    p.push(PairSide::nir, 97 * ms, 1);
    p.push(PairSide::rgb, 100 * ms, 1);
    p.push(PairSide::nir, 103 * ms, 2);
    auto d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::paired);
    EXPECT_EQ(d->nir_id, 1u);
    // The later one waits for an RGB frame near it.
    EXPECT_FALSE(p.decide());
    p.push(PairSide::rgb, 120 * ms, 2);
    d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::unpaired_nir);
    EXPECT_EQ(d->nir_id, 2u);
}

TEST(TimestampPairer, OutOfOrderFrameIsRejectedAndCounted)
{
    TimestampPairer<4> p(5 * ms);
    EXPECT_EQ(p.push(PairSide::nir, 100 * ms, 1), PushResult::accepted);
    EXPECT_EQ(p.push(PairSide::nir, 99 * ms, 2), PushResult::out_of_order);
    EXPECT_EQ(p.push(PairSide::nir, 100 * ms, 3), PushResult::accepted);  // equal is fine
    EXPECT_EQ(p.pending(PairSide::nir), 2u);
    EXPECT_EQ(p.counters().out_of_order, 1u);
    EXPECT_EQ(p.counters().unpaired_nir, 1u);
}

TEST(TimestampPairer, AStalledDeviceForcesTheOldestOfTheOtherOut)
{
    for (const PairSide side : {PairSide::rgb, PairSide::nir}) {
        SCOPED_TRACE(side == PairSide::rgb ? "NIR stalled" : "RGB stalled");
        TimestampPairer<4> p(5 * ms);
        std::vector<Event> ev;
        for (int i = 0; i < 10; ++i)
            ev.push_back({side, i * kPeriod});
        const auto o = run(p, ev, false);
        const auto& unpaired = side == PairSide::rgb ? o.unpaired_rgb : o.unpaired_nir;
        EXPECT_EQ(unpaired.size(), 6u);  // 4 still held
        EXPECT_EQ(o.forced, 6u);
        EXPECT_EQ(unpaired.front(), 0);
        EXPECT_EQ(p.pending(side), 4u);
        EXPECT_EQ(p.counters().forced, 6u);
    }
}

TEST(TimestampPairer, ForceOnAFullNirSidePairsThePendingRgbFirst)
{
    // Both NIR frames precede the RGB frame, so a nearer NIR could still
    // come and nothing is final; force() pairs the oldest RGB frame with the
    // best candidate there is.
    TimestampPairer<2> p(5 * ms);
    p.push(PairSide::rgb, 100 * ms, 1);
    p.push(PairSide::nir, 99 * ms, 1);
    p.push(PairSide::nir, 99 * ms + 500'000, 2);
    // NIR watermark 99.5 ms < 100 + 0.5: not final.
    EXPECT_FALSE(p.decide());
    ASSERT_TRUE(p.full(PairSide::nir));
    auto d = p.force(PairSide::nir);
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::paired);
    EXPECT_TRUE(d->forced);
    EXPECT_EQ(d->nir_id, 2u);
    EXPECT_FALSE(p.full(PairSide::nir));
    d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::unpaired_nir);
    EXPECT_EQ(d->nir_id, 1u);
    EXPECT_FALSE(p.force(PairSide::rgb));  // nothing left
}

TEST(TimestampPairer, ClearForgetsPendingAndWatermarks)
{
    TimestampPairer<4> p(5 * ms);
    p.push(PairSide::rgb, 100 * ms, 1);
    p.push(PairSide::nir, 300 * ms, 1);
    p.clear();
    EXPECT_EQ(p.pending(PairSide::rgb), 0u);
    EXPECT_EQ(p.watermark(PairSide::nir), std::numeric_limits<std::int64_t>::min());
    EXPECT_EQ(p.push(PairSide::nir, 50 * ms, 2), PushResult::accepted);
}

TEST(TimestampPairer, NegativeToleranceMeansExact)
{
    TimestampPairer<4> p(-3);
    EXPECT_EQ(p.tolerance_ns(), 0);
    p.push(PairSide::rgb, 10, 1);
    p.push(PairSide::nir, 10, 1);
    ASSERT_TRUE(p.decide());
}

TEST(TimestampPairer, ExtremeTimestampsDoNotOverflow)
{
    constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
    constexpr std::int64_t kMin = std::numeric_limits<std::int64_t>::min();
    TimestampPairer<4> p(5 * ms);
    p.push(PairSide::rgb, kMin + 1, 1);
    p.push(PairSide::nir, kMax - 1, 1);
    auto d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::unpaired_rgb);
    p.push(PairSide::rgb, kMax, 2);
    EXPECT_FALSE(p.decide());  // a NIR at kMax would be nearer
    p.push(PairSide::nir, kMax, 2);
    d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::paired);
    EXPECT_EQ(d->nir_id, 2u);
    d = p.decide();
    ASSERT_TRUE(d);
    EXPECT_EQ(d->kind, Kind::unpaired_nir);
}

TEST(TimestampPairer, MatchesTheOfflineRuleOnRandomStreams)
{
    // Random offsets, jitter, losses and delivery delays (which reorder the two
    // sides, each side staying in order). With room for every frame the
    // online decisions equal the offline rule and nothing is forced except
    // the final drain, which the rule also covers.
    std::mt19937 rng(42);
    for (int round = 0; round < 300; ++round) {
        const std::int64_t tol = std::uniform_int_distribution<std::int64_t>(1 * ms, 20 * ms)(rng);
        const std::int64_t offset = std::uniform_int_distribution<std::int64_t>(-25 * ms, 25 * ms)(rng);
        const std::int64_t jit = std::uniform_int_distribution<std::int64_t>(0, 6 * ms)(rng);
        const int loss_pct = std::uniform_int_distribution<int>(0, 30)(rng);
        std::uniform_int_distribution<std::int64_t> jitter(-jit, jit);
        std::uniform_int_distribution<int> pct(0, 99);
        std::uniform_int_distribution<std::int64_t> delay(0, 80 * ms);
        std::vector<std::int64_t> rgb, nir;
        std::vector<std::tuple<std::int64_t, PairSide, std::int64_t>> arrivals;  // (arrival, side, t)
        std::int64_t last_r = std::numeric_limits<std::int64_t>::min(), last_n = last_r;
        std::int64_t last_ra = last_r, last_na = last_r;
        for (int i = 0; i < 80; ++i) {
            const std::int64_t base = 1000 * ms + i * kPeriod;
            if (pct(rng) >= loss_pct) {
                const std::int64_t t = std::max(last_r, base + jitter(rng));
                last_r = t;
                last_ra = std::max(last_ra, t + delay(rng));
                rgb.push_back(t);
                arrivals.emplace_back(last_ra, PairSide::rgb, t);
            }
            if (pct(rng) >= loss_pct) {
                const std::int64_t t = std::max(last_n, base + offset + jitter(rng));
                last_n = t;
                last_na = std::max(last_na, t + delay(rng));
                nir.push_back(t);
                arrivals.emplace_back(last_na, PairSide::nir, t);
            }
        }
        std::stable_sort(arrivals.begin(), arrivals.end(),
                         [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });
        std::vector<Event> ev;
        for (const auto& [a, side, t] : arrivals)
            ev.push_back({side, t});
        TimestampPairer<128> p(tol);
        const auto online = run(p, ev);
        SCOPED_TRACE("round " + std::to_string(round) + " tol " + std::to_string(tol) + " offset " +
                     std::to_string(offset) + " jitter " + std::to_string(jit));
        expect_same(online, reference(rgb, nir, tol));
        EXPECT_EQ(p.counters().paired + p.counters().unpaired_rgb, rgb.size());
        EXPECT_EQ(p.counters().paired + p.counters().unpaired_nir, nir.size());
        if (HasFailure())
            break;
    }
}

TEST(TimestampPairer, CapacityFourKeepsUpWithTwoInterleavedCameras)
{
    // Realistic delivery (each frame arrives 0..20 ms after capture, sides
    // reordered): four pending frames per side never need force() and give
    // the offline rule's answer.
    std::mt19937 rng(7);
    for (int round = 0; round < 100; ++round) {
        std::uniform_int_distribution<std::int64_t> jitter(-1 * ms, 1 * ms);
        std::uniform_int_distribution<std::int64_t> delay(0, 20 * ms);
        std::vector<std::int64_t> rgb, nir;
        std::vector<std::tuple<std::int64_t, PairSide, std::int64_t>> arrivals;
        for (int i = 0; i < 100; ++i) {
            const std::int64_t r = 1000 * ms + i * kPeriod + jitter(rng);
            const std::int64_t n = 1000 * ms + i * kPeriod + 3 * ms + jitter(rng);
            rgb.push_back(r);
            nir.push_back(n);
            arrivals.emplace_back(r + delay(rng), PairSide::rgb, r);
            arrivals.emplace_back(n + delay(rng), PairSide::nir, n);
        }
        std::stable_sort(arrivals.begin(), arrivals.end(),
                         [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });
        // Keep each side in capture order (a device delivers in order).
        std::vector<Event> ev;
        std::size_t ri = 0, ni = 0;
        for (const auto& a : arrivals)
            ev.push_back(std::get<1>(a) == PairSide::rgb ? Event{PairSide::rgb, rgb[ri++]}
                                                         : Event{PairSide::nir, nir[ni++]});
        TimestampPairer<4> p(5 * ms);
        const auto o = run(p, ev);
        EXPECT_EQ(o.pairs.size(), 100u);
        EXPECT_LE(o.forced, 1u);  // the final drain at most
        expect_same(o, reference(rgb, nir, 5 * ms));
        if (HasFailure())
            break;
    }
}

// --- PairedNirSource without devices (the VM check, test/vm/paired_nir_check.cpp,
// runs it on two vivid instances) ---

using stemd::test::CapturedLog;

namespace {
stemd::drivers::PairedNirOptions paired_devices(const char* rgb, const char* nir)
{
    stemd::drivers::PairedNirOptions options;
    options.rgb.device = rgb;
    options.nir.device = nir;
    return options;
}
}  // namespace

TEST(PairedNirSource, MissingNirDeviceIsAClearErrorAndNextFails)
{
    CapturedLog log;
    const auto options = paired_devices("/dev/stemd-no-such-rgb", "/dev/stemd-no-such-nir");
    stemd::drivers::PairedNirSource source(options, log.logger);
    EXPECT_EQ(source.name(), "paired:/dev/stemd-no-such-rgb+/dev/stemd-no-such-nir");
    EXPECT_TRUE(source.realtime());
    EXPECT_FALSE(source.open());
    EXPECT_FALSE(source.start());
    stemd::drivers::Frame frame;
    frame.bgr = cv::Mat(480, 640, CV_8UC3);
    frame.nir = cv::Mat(480, 640, CV_8UC1);
    EXPECT_EQ(source.next(frame, std::chrono::milliseconds(1)), stemd::drivers::NextStatus::failed);
    source.stop();
    EXPECT_EQ(source.counters().delivered, 0u);
    EXPECT_EQ(source.paired_counters().unpaired_rgb, 0u);
    EXPECT_NE(log.text().find("/dev/stemd-no-such-rgb: cannot open"), std::string::npos) << log.text();
}

TEST(PairedNirSource, RgbDeviceThatIsNoV4l2DeviceIsAClearError)
{
    CapturedLog log;
    auto options = paired_devices("/dev/null", "/dev/stemd-no-such-nir");
    options.rgb.size = {320, 240};
    options.nir.pixel_format = stemd::drivers::V4l2PixelFormat::yuyv;
    stemd::drivers::PairedNirSource source(options, log.logger);
    EXPECT_EQ(source.nir_source().name(), "v4l2:/dev/stemd-no-such-nir");
    EXPECT_FALSE(source.open());  // /dev/null is no V4L2 device
    EXPECT_NE(log.text().find("/dev/null: VIDIOC_QUERYCAP"), std::string::npos) << log.text();
}

TEST(PairedNirSource, TheSameDeviceTwiceIsRejected)
{
    CapturedLog log;
    const auto options = paired_devices("/dev/video0", "/dev/video0");
    stemd::drivers::PairedNirSource source(options, log.logger);
    EXPECT_FALSE(source.open());
    EXPECT_NE(log.text().find("the same device /dev/video0"), std::string::npos) << log.text();
}
