// Tracker: one target per plant on synthetic field strips with known motion.
// Frames every 30 mm of travel, a 300 mm view centred on the principal
// point (field extent [odom - 150, odom + 150]), detection noise within ±1 mm.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "stemd/actuation/tracker.hpp"

using namespace stemd::actuation;
using namespace stemd::protocol;

namespace {

struct Plant {
    double s_mm;
    double y_mm;
    PlantClass cls = PlantClass::Weed;
};

constexpr double kStepMm = 30;
constexpr double kHalfViewMm = 150;
constexpr double kNoiseMm = 1.0;

TrackerParams params(int confirm_frames = 3)
{
    TrackerParams p;
    p.association_radius_mm = 10;
    p.confirm_frames = confirm_frames;
    p.exit_margin_mm = 40;  // > kStepMm
    p.max_missed_frames = 3;
    return p;
}

TrackFrame frame_at(double odom, std::span<const TrackDetection> dets)
{
    TrackFrame f;
    f.t_sample_ns = static_cast<std::int64_t>(odom * 1e6);  // 1 m/s
    f.odom_at_capture_mm = odom;
    f.view_s_min_mm = odom - kHalfViewMm;
    f.view_s_max_mm = odom + kHalfViewMm;
    f.detections = dets;
    return f;
}

// Drives over the plants from odom_begin to odom_end; `seen(plant, frame)`
// decides whether a plant in view is detected. Returns every target.
template <typename Seen>
std::vector<Target> drive(Tracker& tracker, const std::vector<Plant>& plants, double odom_begin, double odom_end,
                          Seen seen, std::uint32_t seed = 1)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> noise(-kNoiseMm, kNoiseMm);
    std::vector<Target> targets;
    std::vector<TrackDetection> dets;
    int frame = 0;
    for (double odom = odom_begin; odom <= odom_end; odom += kStepMm, ++frame) {
        dets.clear();
        for (std::size_t i = 0; i < plants.size(); ++i) {
            const Plant& p = plants[i];
            if (p.s_mm < odom - kHalfViewMm || p.s_mm > odom + kHalfViewMm || !seen(i, frame))
                continue;
            dets.push_back({p.s_mm + noise(rng), p.y_mm + noise(rng), 0.8f, p.cls, 3});
        }
        for (const Target& t : tracker.update(frame_at(odom, dets)))
            targets.push_back(t);
    }
    return targets;
}

const auto kAlways = [](std::size_t, int) { return true; };

// Index of the plant within `tol` of the target, or -1.
int nearest_plant(const std::vector<Plant>& plants, const Target& t, double tol)
{
    int found = -1;
    for (std::size_t i = 0; i < plants.size(); ++i)
        if (std::hypot(plants[i].s_mm - t.s_mm, plants[i].y_mm - t.y_mm) <= tol)
            found = static_cast<int>(i);
    return found;
}

}  // namespace

TEST(ActuationTracker, EachPlantBecomesExactlyOneTargetNearTheTruth)
{
    std::vector<Plant> plants;
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> gap(40, 160), lateral(-250, 250);
    double s = 500;
    for (int i = 0; i < 60; ++i) {
        s += gap(rng);
        plants.push_back({s, lateral(rng), i % 3 == 0 ? PlantClass::Crop : PlantClass::Weed});
    }
    Tracker tracker(params());
    const auto targets = drive(tracker, plants, 0, s + 400, kAlways);

    ASSERT_EQ(targets.size(), plants.size());
    std::vector<int> hits(plants.size(), 0);
    for (std::size_t k = 0; k < targets.size(); ++k) {
        const Target& t = targets[k];
        const int i = nearest_plant(plants, t, 2.0);
        ASSERT_GE(i, 0) << "target " << k << " at s=" << t.s_mm << " y=" << t.y_mm;
        ++hits[static_cast<std::size_t>(i)];
        EXPECT_EQ(t.plant_class, plants[static_cast<std::size_t>(i)].cls);
        EXPECT_EQ(t.sightings, 3u);
        EXPECT_FALSE(t.by_exit);
        EXPECT_EQ(t.target_id, k);
        EXPECT_EQ(t.leaves, 3);
        EXPECT_NEAR(t.confidence, 0.8f, 1e-6);
    }
    for (int h : hits)
        EXPECT_EQ(h, 1);
    const auto& c = tracker.counters();
    EXPECT_EQ(c.tracks_created, plants.size());
    EXPECT_EQ(c.confirmed, plants.size());
    EXPECT_EQ(c.confirmed_by_exit, 0u);
    EXPECT_EQ(c.retired, plants.size());
    EXPECT_EQ(c.retired_unconfirmed, 0u);
    EXPECT_EQ(c.capacity_drops, 0u);
    EXPECT_EQ(tracker.active_tracks(), 0u);
}

TEST(ActuationTracker, PlantsAtTheMinimumSpacingAreNotMerged)
{
    Tracker tracker(params());
    const double d = tracker.min_separation_mm(kNoiseMm);  // radius + 2e = 12 mm
    EXPECT_DOUBLE_EQ(d, 12.0);
    // Pairs along-track, across and diagonally, each at exactly d.
    const std::vector<Plant> plants = {
        {1000, 0},      {1000 + d, 0},                               // along s
        {1500, -100},   {1500, -100 + d},                            // across
        {2000, 50},     {2000 + d / std::sqrt(2.0), 50 + d / std::sqrt(2.0)},  // diagonal
    };
    // The hard case: the first plant of each pair is missed every other
    // frame, so the second one's detection meets only its neighbour's track.
    for (std::uint32_t seed = 1; seed <= 50; ++seed) {
        Tracker tr(params());
        const auto targets = drive(tr, plants, 700, 2500, [](std::size_t i, int frame) {
            return i % 2 == 1 || frame % 2 == 0;
        }, seed);
        ASSERT_EQ(targets.size(), plants.size()) << "seed " << seed;
        std::vector<int> hits(plants.size(), 0);
        for (const Target& t : targets) {
            const int i = nearest_plant(plants, t, 2.0);
            ASSERT_GE(i, 0) << "seed " << seed << " s=" << t.s_mm << " y=" << t.y_mm;
            ++hits[static_cast<std::size_t>(i)];
        }
        for (int h : hits)
            EXPECT_EQ(h, 1) << "seed " << seed;
        EXPECT_EQ(tr.counters().tracks_created, plants.size()) << "seed " << seed;
    }
}

TEST(ActuationTracker, APlantSeenOnceThenLeavingIsEmittedByTheExitRule)
{
    Tracker tracker(params());
    // Seen only in frame 7, at odom 1110: s = 1020 is then 60 mm inside the
    // trailing edge (960), outside the 40 mm margin. The next frame (1140)
    // puts it 30 mm from the edge: emitted there, by exit, with 1 sighting.
    const std::vector<Plant> plants = {{1020, 20}};
    const auto targets = drive(tracker, plants, 900, 1400, [](std::size_t, int frame) { return frame == 7; });
    ASSERT_EQ(targets.size(), 1u);
    EXPECT_TRUE(targets[0].by_exit);
    EXPECT_EQ(targets[0].sightings, 1u);
    EXPECT_EQ(targets[0].t_emit_ns, static_cast<std::int64_t>(1140 * 1e6));
    EXPECT_NEAR(targets[0].s_mm, 1020, 1.0);
    EXPECT_EQ(tracker.counters().confirmed_by_exit, 1u);
    EXPECT_EQ(tracker.counters().retired_unconfirmed, 0u);
}

TEST(ActuationTracker, APlantAtTheTrailingEdgeSeenInTheLastFrameOnly)
{
    Tracker tracker(params());
    // One frame: the plant sits on the trailing edge of the view.
    const TrackDetection det{850.4, -30, 0.5f, PlantClass::Weed, 2};
    const auto out = tracker.update(frame_at(1000, std::span(&det, 1)));
    ASSERT_EQ(out.size(), 1u);
    EXPECT_TRUE(out[0].by_exit);
    EXPECT_EQ(out[0].sightings, 1u);
    EXPECT_DOUBLE_EQ(out[0].s_mm, 850.4);
    EXPECT_EQ(out[0].plant_class, PlantClass::Weed);
    // Next frame: it is behind the view, retired, and never emitted again.
    EXPECT_TRUE(tracker.update(frame_at(1030, {})).empty());
    EXPECT_EQ(tracker.active_tracks(), 0u);
    EXPECT_EQ(tracker.counters().confirmed, 1u);
    EXPECT_EQ(tracker.counters().retired_unconfirmed, 0u);
}

TEST(ActuationTracker, ASingleSightingInMidViewIsRetiredUnconfirmed)
{
    Tracker tracker(params());
    // A false positive seen once in mid-view, 150 mm ahead of the trailing edge.
    const TrackDetection det{1000, 0, 0.9f, PlantClass::Weed, 1};
    EXPECT_TRUE(tracker.update(frame_at(1000, std::span(&det, 1))).empty());
    for (double odom = 1030; odom <= 1090; odom += kStepMm)
        EXPECT_TRUE(tracker.update(frame_at(odom, {})).empty());
    EXPECT_EQ(tracker.active_tracks(), 0u);
    EXPECT_EQ(tracker.counters().confirmed, 0u);
    EXPECT_EQ(tracker.counters().retired_unconfirmed, 1u);
}

TEST(ActuationTracker, AnEmittedPlantIsNeverEmittedAgain)
{
    Tracker tracker(params(1));
    const std::vector<Plant> plants = {{1000, 0}, {1100, 100}};
    const auto targets = drive(tracker, plants, 700, 1400, kAlways);
    EXPECT_EQ(targets.size(), 2u);
    EXPECT_EQ(tracker.counters().tracks_created, 2u);
}

TEST(ActuationTracker, FusionIsConfidenceWeightedAndClassVotesByConfidence)
{
    Tracker tracker(params(3));
    const TrackDetection a{1000, 10, 0.75f, PlantClass::Crop, 1};
    const TrackDetection b{1004, 14, 0.25f, PlantClass::Weed, 4};
    const TrackDetection c{1002, 12, 0.25f, PlantClass::Weed, 2};
    EXPECT_TRUE(tracker.update(frame_at(1000, std::span(&a, 1))).empty());
    EXPECT_TRUE(tracker.update(frame_at(1010, std::span(&b, 1))).empty());
    const auto out = tracker.update(frame_at(1020, std::span(&c, 1)));
    ASSERT_EQ(out.size(), 1u);
    // (0.75*1000 + 0.25*1004 + 0.25*1002) / 1.25
    EXPECT_NEAR(out[0].s_mm, (750 + 251 + 250.5) / 1.25, 1e-9);
    EXPECT_NEAR(out[0].y_mm, (7.5 + 3.5 + 3) / 1.25, 1e-9);
    EXPECT_EQ(out[0].plant_class, PlantClass::Crop);  // 0.75 > 0.25 + 0.25
    EXPECT_EQ(out[0].leaves, 4);
}

TEST(ActuationTracker, GreedyClosestFirstIsOneToOne)
{
    Tracker tracker(params(10));
    const TrackDetection first[] = {{1000, 0, 1, PlantClass::Weed, 0}, {1008, 0, 1, PlantClass::Weed, 0}};
    tracker.update(frame_at(1000, first));
    EXPECT_EQ(tracker.active_tracks(), 2u);
    // Both detections are within the radius of both tracks: the closest pair
    // (1007 -> track at 1008) goes first, the other takes the remaining track.
    const TrackDetection second[] = {{1003, 0, 1, PlantClass::Weed, 0}, {1007, 0, 1, PlantClass::Weed, 0}};
    tracker.update(frame_at(1010, second));
    EXPECT_EQ(tracker.active_tracks(), 2u);
    EXPECT_EQ(tracker.counters().tracks_created, 2u);
}

TEST(ActuationTracker, AWeedPartAndThePlantItGrewIntoAreTrackedApart)
{
    Tracker tracker(params(2));
    TrackDetection crop{1000, 0, 0.2f, PlantClass::Crop, 3};
    TrackDetection part{1005, 0, 0.2f, PlantClass::Weed, 0};
    part.weed_part = true;
    const TrackDetection first[] = {crop, part};
    EXPECT_TRUE(tracker.update(frame_at(1000, first)).empty());
    EXPECT_EQ(tracker.active_tracks(), 2u);
    // The crop is missed, and the part is seen nearer the crop's track
    // (1 mm) than its own (4 mm): it still joins its own.
    part.s_mm = 1001;
    const auto out = tracker.update(frame_at(1010, std::span(&part, 1)));
    ASSERT_EQ(out.size(), 1u) << "the part's track confirmed by its second sighting, the crop's not";
    EXPECT_EQ(out[0].plant_class, PlantClass::Weed);
    EXPECT_NEAR(out[0].s_mm, 1003, 1e-9);
    EXPECT_EQ(tracker.counters().tracks_created, 2u);
    // And a plant's sighting never joins a part's track, even on it: the
    // crop's own track takes it (its second sighting) and stays crop.
    const TrackDetection on_part{1003, 0, 0.2f, PlantClass::Crop, 3};
    const auto crop_out = tracker.update(frame_at(1020, std::span(&on_part, 1)));
    ASSERT_EQ(crop_out.size(), 1u);
    EXPECT_EQ(crop_out[0].plant_class, PlantClass::Crop);
    EXPECT_NEAR(crop_out[0].s_mm, 1001.5, 1e-9);
    EXPECT_EQ(tracker.counters().tracks_created, 2u);
}

TEST(ActuationTracker, CapacityDropsAreCounted)
{
    TrackerParams p = params();
    p.capacity = 4;
    Tracker tracker(p);
    std::vector<TrackDetection> dets;
    for (int i = 0; i < 6; ++i)
        dets.push_back({1000.0 + 20 * i, 0, 1, PlantClass::Weed, 0});
    dets.push_back({std::nan(""), 0, 1, PlantClass::Weed, 0});
    tracker.update(frame_at(1050, dets));
    EXPECT_EQ(tracker.active_tracks(), 4u);
    EXPECT_EQ(tracker.counters().tracks_created, 4u);
    EXPECT_EQ(tracker.counters().capacity_drops, 2u);
    EXPECT_EQ(tracker.counters().rejected_detections, 1u);
}

TEST(ActuationTracker, TargetIdsWrapAt4096)
{
    Tracker tracker(params(1));
    std::vector<std::uint16_t> ids;
    for (int i = 0; i < 4098; ++i) {
        const double odom = 1000.0 + 400.0 * i;  // each plant alone in its own frame
        const TrackDetection det{odom, 0, 1, PlantClass::Weed, 0};
        for (const Target& t : tracker.update(frame_at(odom, std::span(&det, 1))))
            ids.push_back(t.target_id);
    }
    ASSERT_EQ(ids.size(), 4098u);
    EXPECT_EQ(ids[0], 0);
    EXPECT_EQ(ids[4095], 4095);
    EXPECT_EQ(ids[4096], 0);
    EXPECT_EQ(ids[4097], 1);
}

TEST(ActuationTracker, RetiredTracksReportTheirLifeForThePlantMap)
{
    Tracker tracker(params());
    // Plant A seen in frames 0..k while in view; a false positive B seen once.
    const TrackDetection a{1000, 5, 0.8f, PlantClass::Crop, 4};
    const TrackDetection b{1050, -40, 0.5f, PlantClass::Weed, 1};
    std::vector<RetiredTrack> retired;
    std::uint64_t seq = 10;
    std::uint16_t a_id = 0;
    for (double odom = 900; odom <= 1300; odom += kStepMm, ++seq) {
        std::vector<TrackDetection> dets;
        if (a.s_mm >= odom - kHalfViewMm && a.s_mm <= odom + kHalfViewMm)
            dets.push_back(a);
        if (seq == 11)
            dets.push_back(b);
        TrackFrame f = frame_at(odom, dets);
        f.seq = seq;
        for (const Target& t : tracker.update(f)) {
            a_id = t.target_id;
            EXPECT_EQ(t.first_seq, 10u);
        }
        for (const RetiredTrack& r : tracker.retired())
            retired.push_back(r);
    }
    ASSERT_EQ(retired.size(), 2u);
    const RetiredTrack& fp = retired[0].emitted ? retired[1] : retired[0];
    const RetiredTrack& plant = retired[0].emitted ? retired[0] : retired[1];
    EXPECT_FALSE(fp.emitted);
    EXPECT_EQ(fp.first_seq, 11u);
    EXPECT_EQ(fp.last_seq, 11u);
    EXPECT_TRUE(plant.emitted);
    EXPECT_EQ(plant.target_id, a_id);
    EXPECT_EQ(plant.first_seq, 10u);
    // In view from odom 900 (s_min 750) until s_min passes 1000: odom <= 1150,
    // i.e. frames 10..18 (odom 900, 930, ..., 1140).
    EXPECT_EQ(plant.last_seq, 18u);
    EXPECT_EQ(plant.sightings, 9u);
    EXPECT_EQ(plant.plant_class, PlantClass::Crop);
    EXPECT_EQ(plant.leaves, 4);
    EXPECT_DOUBLE_EQ(plant.s_mm, 1000);
}

TEST(ActuationTracker, DrainRetiresEveryActiveTrack)
{
    Tracker tracker(params());
    const TrackDetection dets[] = {{1000, 0, 0.8f, PlantClass::Weed, 2}, {1060, 30, 0.8f, PlantClass::Weed, 2}};
    for (int i = 0; i < 3; ++i) {
        TrackFrame f = frame_at(1000, dets);
        f.seq = static_cast<std::uint64_t>(i);
        EXPECT_EQ(tracker.update(f).size(), i == 2 ? 2u : 0u);
    }
    const auto drained = tracker.drain();
    ASSERT_EQ(drained.size(), 2u);
    for (const RetiredTrack& r : drained) {
        EXPECT_TRUE(r.emitted);
        EXPECT_EQ(r.first_seq, 0u);
        EXPECT_EQ(r.last_seq, 2u);
    }
    EXPECT_EQ(tracker.active_tracks(), 0u);
    EXPECT_TRUE(tracker.drain().empty());
}

TEST(ActuationTracker, ExitRuleAllowsForThePlantsExtent)
{
    // A plant 50 mm along-track half-size, seen twice (fewer than
    // confirm_frames) with its stem 80 mm ahead of the trailing edge: beyond
    // exit_margin_mm (40), but its leaves already reach the edge (80 < 40 +
    // 50): it is emitted now, before the border cuts it.
    Tracker tracker(params());
    const TrackDetection big{1000, 0, 0.8f, PlantClass::Weed, 4, 50.0};
    const TrackDetection small{1000, 0, 0.8f, PlantClass::Weed, 4, 0.0};
    for (const TrackDetection* d : {&big, &small}) {
        Tracker t(params());
        EXPECT_TRUE(t.update(frame_at(1000 + kHalfViewMm - 100, std::span(d, 1))).empty());
        const auto out = t.update(frame_at(1000 + kHalfViewMm - 80, std::span(d, 1)));
        EXPECT_EQ(out.size(), d == &big ? 1u : 0u);
    }
}
