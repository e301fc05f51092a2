// The actuator's stage end to end on synthetic detections: a strip of
// plants at known field positions seen by overlapping frames of a nadir
// camera; each plant must become exactly one TARGET at its fire position,
// and the enable input, a slow pipeline, CAN odometry (with corrupt frames),
// the class policy and the heartbeat behave as documented.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>
#include <memory>
#include <vector>

#include "stemd/protocol/messages.hpp"
#include "stemd/runtime/actuation_stage.hpp"
#include "stemd/runtime/logging.hpp"
#include "fake_can_bus.hpp"
#include "fake_gpio_lines.hpp"

namespace stemd::runtime {
namespace {

using protocol::CanFrame;
using protocol::MessageKind;
using protocol::PlantClass;

using FakeBus = test::FakeCanBus;

using FakeGpio = test::FakeGpioLines;

constexpr double kGsd = 0.33;
const cv::Size kSize{1296, 966};
constexpr double kSpeed = 1388.9;           // mm/s, 5 km/h
constexpr std::int64_t kPeriodNs = 33'333'333;  // 30 fps
constexpr std::int64_t kT0 = 5'000'000'000;

struct Plant {
    double s_mm, y_mm;
    PlantClass cls;
};

// Plants 60 mm apart along the strip, alternating sides and classes.
std::vector<Plant> strip(int n)
{
    std::vector<Plant> plants;
    for (int i = 0; i < n; ++i)
        plants.push_back({250.0 + 60.0 * i, (i % 2 ? -1.0 : 1.0) * (20.0 + 7.0 * (i % 5)),
                          i % 3 == 0 ? PlantClass::Crop : PlantClass::Weed});
    return plants;
}

geometry::CameraModel nadir_camera()
{
    geometry::NadirParams p;
    p.gsd_mm_per_px = kGsd;
    p.principal_px = geometry::image_centre(kSize);
    return *geometry::CameraModel::nadir(p);
}

ActuationConfig base_config()
{
    ActuationConfig c;
    c.tools = {{.id = 3, .offset_mm = 600, .y_min_mm = -220, .y_max_mm = 220, .lanes = 4}};
    c.policy = PolicyChoice::all;
    c.odometry = OdometrySource::recording;
    c.heartbeat_interval_ns = 100'000'000;
    return c;
}

// Frame k as the processing thread would hand it over: the plants whose
// stems are inside the image, at their pixels (forward = up: a plant ahead
// of the principal point is above the centre row; left of the machine is
// image left).
// frame_at: the same for a frame taken at `odom` mm, whatever the speed.
std::unique_ptr<FrameResult> frame_at(const std::vector<Plant>& plants, int k, double odom, bool class_map = false,
                                      bool with_odom = true)
{
    auto r = std::make_unique<FrameResult>();
    r->seq = static_cast<std::uint64_t>(k);
    r->t_sample_ns = kT0 + k * kPeriodNs;
    r->odom_mm = with_odom ? odom : std::nan("");
    r->has_class_map = class_map;
    const cv::Point2d c = geometry::image_centre(kSize);
    for (const Plant& p : plants) {
        const double u = c.x - p.y_mm / kGsd, v = c.y - (p.s_mm - odom) / kGsd;
        if (u < 0 || v < 0 || u > kSize.width - 1 || v > kSize.height - 1)
            continue;
        vision::Plant vp;
        vp.stem = {static_cast<float>(u), static_cast<float>(v)};
        // A plant 10 mm across (30 px): cut by the border near the edges.
        vp.bbox = cv::Rect(static_cast<int>(u) - 15, static_cast<int>(v) - 15, 31, 31) & cv::Rect({0, 0}, kSize);
        vp.has_stem = true;
        vp.confidence = 0.8f;
        r->plant_class[r->detections.plants.size()] = p.cls;
        r->detections.plants.push_back(vp);
    }
    return r;
}

std::unique_ptr<FrameResult> frame(const std::vector<Plant>& plants, int k, bool class_map = false,
                                   bool with_odom = true)
{
    return frame_at(plants, k, k * kSpeed / 30.0, class_map, with_odom);
}

struct Stage {
    std::unique_ptr<ActuationStage> stage;
    FakeBus* bus = nullptr;
    FakeGpio* gpio = nullptr;
};

// with_gpio: GPIO lines whose encoder is `encoder`.
Stage make_stage(const ActuationConfig& config, bool with_gpio = false,
                 drivers::EncoderMode encoder = drivers::EncoderMode::none)
{
    Stage run;
    ActuationStage::Parts parts;
    auto bus = std::make_unique<FakeBus>();
    run.bus = bus.get();
    parts.bus = std::move(bus);
    if (with_gpio) {
        auto gpio = std::make_unique<FakeGpio>();
        gpio->encoder_mode_value = encoder;
        run.gpio = gpio.get();
        parts.gpio = std::move(gpio);
    }
    std::string error;
    run.stage = ActuationStage::make(config, nadir_camera(), kSize, std::move(parts), runtime::make_logger("actuator-test"), error);
    EXPECT_TRUE(run.stage) << error;
    return run;
}

std::vector<protocol::TargetCommand> targets(const FakeBus& bus, const protocol::CanIds& ids = {})
{
    std::vector<protocol::TargetCommand> out;
    for (const CanFrame& f : bus.sent)
        if (ids.kind_of(f) == MessageKind::Target) {
            protocol::TargetCommand t;
            EXPECT_TRUE(protocol::decode(f, ids, t));
            out.push_back(t);
        }
    return out;
}

// Frames until the last plant has left the view at the trailing edge.
int frames_for(const std::vector<Plant>& plants)
{
    return static_cast<int>((plants.back().s_mm + kSize.height * kGsd) / (kSpeed / 30.0)) + 2;
}

// Every frame of the strip through the stage, each handed over `pipeline_ns`
// after its capture.
void drive(Stage& run, const std::vector<Plant>& plants, std::int64_t pipeline_ns, bool class_map = false,
           bool with_odom = true)
{
    for (int k = 0; k < frames_for(plants); ++k) {
        const auto r = frame(plants, k, class_map, with_odom);
        run.stage->on_frame(*r, r->t_sample_ns + pipeline_ns);
    }
}

// Each TARGET fires within `tol_mm` of some plant's fire position (its
// along-track position plus `offset_mm`).
void expect_at_fire_positions(const std::vector<protocol::TargetCommand>& sent, const std::vector<Plant>& plants,
                              double offset_mm, double tol_mm)
{
    for (const auto& t : sent) {
        bool found = false;
        for (const Plant& p : plants)
            found = found || std::abs(t.fire_odom_mm - (p.s_mm + offset_mm)) <= tol_mm;
        EXPECT_TRUE(found) << t.fire_odom_mm;
    }
}

TEST(ActuationStage, EveryPlantBecomesExactlyOneTargetAtItsFirePosition)
{
    const auto plants = strip(30);
    Stage run = make_stage(base_config());
    drive(run, plants, 3'000'000);   // 3 ms pipeline
    const auto sent = targets(*run.bus);
    ASSERT_EQ(sent.size(), plants.size());
    std::map<std::size_t, int> hits;
    for (const auto& t : sent) {
        // The plant this command is for: the one whose fire position is nearest.
        std::size_t best = 0;
        for (std::size_t i = 1; i < plants.size(); ++i)
            if (std::abs(plants[i].s_mm + 600 - t.fire_odom_mm) < std::abs(plants[best].s_mm + 600 - t.fire_odom_mm))
                best = i;
        ++hits[best];
        EXPECT_NEAR(t.fire_odom_mm, plants[best].s_mm + 600, 1.0);
        EXPECT_NEAR(t.lateral_mm, plants[best].y_mm, 1.0);
        EXPECT_EQ(t.tool_id, 3);
        // Lanes of 110 mm from y = -220.
        EXPECT_EQ(t.lane, static_cast<int>(std::floor((plants[best].y_mm + 220) / 110)));
    }
    EXPECT_EQ(hits.size(), plants.size()) << "a plant got two commands and another none";
    EXPECT_EQ(run.stage->counters().deadline_misses.load(), 0u);
    EXPECT_EQ(run.stage->counters().sent.load(), plants.size());
    EXPECT_EQ(run.stage->counters().targets.load(), plants.size());
    // Each TARGET left 3 ms after its frame's capture (the 50 us bucket's middle).
    const auto latency = run.stage->counters().send_latency.total();
    EXPECT_EQ(latency.count, plants.size());
    EXPECT_NEAR(latency.p50_ms, 3.0, 0.05);
    EXPECT_NEAR(latency.max_ms, 3.0, 1e-9);
}

TEST(ActuationStage, EnableInactiveSendsNothingAndCountsEveryTarget)
{
    const auto plants = strip(10);
    Stage run = make_stage(base_config(), true);
    run.gpio->enable = false;
    drive(run, plants, 3'000'000);
    EXPECT_TRUE(targets(*run.bus).empty());
    EXPECT_EQ(run.stage->counters().disabled.load(), plants.size());
    EXPECT_EQ(run.stage->counters().sent.load(), 0u);
}

TEST(ActuationStage, EnableTakesEffectFromTheNextFrame)
{
    const auto plants = strip(10);
    Stage run = make_stage(base_config(), true);
    std::size_t sent_before_disable = 0;
    const int n = frames_for(plants);
    for (int k = 0; k < n; ++k) {
        if (k == n / 2) {
            run.gpio->enable = false;
            sent_before_disable = targets(*run.bus).size();
        }
        const auto r = frame(plants, k);
        run.stage->on_frame(*r, r->t_sample_ns + 3'000'000);
    }
    EXPECT_GT(sent_before_disable, 0u);
    EXPECT_EQ(targets(*run.bus).size(), sent_before_disable);
    EXPECT_EQ(run.stage->counters().disabled.load() + sent_before_disable, plants.size());
}

TEST(ActuationStage, EnableDroppingWhileTheBusHoldsATargetWithdrawsIt)
{
    // The enable input drops between the scheduler's decision and the
    // bus's write of the third TARGET, as it can while a full transmit
    // queue keeps the frame waiting: that TARGET must not go out either.
    const auto plants = strip(10);
    Stage run = make_stage(base_config(), true);
    int attempts = 0;
    run.bus->before_write = [&](const CanFrame& f) {
        if (protocol::CanIds{}.kind_of(f) == MessageKind::Target && ++attempts == 3)
            run.gpio->enable = false;
    };
    drive(run, plants, 3'000'000);
    EXPECT_EQ(attempts, 3) << "the scheduler stops asking once enable is off";
    EXPECT_EQ(targets(*run.bus).size(), 2u);
    EXPECT_EQ(run.stage->counters().sent.load(), 2u);
    EXPECT_EQ(run.stage->counters().disabled.load(), plants.size() - 2);
}

TEST(ActuationStage, OperatorDisableStopsTargetsAndClearingItResumesThem)
{
    const auto plants = strip(10);
    Stage run = make_stage(base_config(), true);
    std::size_t sent_before_disable = 0, sent_while_disabled = 0;
    const int n = frames_for(plants);
    for (int k = 0; k < n; ++k) {
        if (k == n / 3) {
            run.stage->set_operator_disabled(true);
            sent_before_disable = targets(*run.bus).size();
        }
        if (k == 2 * n / 3) {
            sent_while_disabled = targets(*run.bus).size();
            run.stage->set_operator_disabled(false);
        }
        const auto r = frame(plants, k);
        run.stage->on_frame(*r, r->t_sample_ns + 3'000'000);
    }
    EXPECT_GT(sent_before_disable, 0u);
    EXPECT_EQ(sent_while_disabled, sent_before_disable);
    EXPECT_GT(targets(*run.bus).size(), sent_while_disabled);
    EXPECT_GT(run.stage->counters().disabled.load(), 0u);
    EXPECT_EQ(run.stage->counters().disabled.load() + targets(*run.bus).size(), plants.size());
}

TEST(ActuationStage, ClearingTheOperatorDisableNeverOverridesAnInactiveEnableInput)
{
    const auto plants = strip(10);
    Stage run = make_stage(base_config(), true);
    run.gpio->enable = false;
    run.stage->set_operator_disabled(true);
    run.stage->set_operator_disabled(false);
    for (int k = 0; k < frames_for(plants); ++k) {
        const auto r = frame(plants, k);
        run.stage->on_frame(*r, r->t_sample_ns + 3'000'000);
    }
    EXPECT_TRUE(targets(*run.bus).empty());
    EXPECT_EQ(run.stage->counters().disabled.load(), plants.size());
}

TEST(ActuationStage, SlowPipelineMakesDeadlineMissesThatAreNeverSent)
{
    const auto plants = strip(10);
    ActuationConfig config = base_config();
    config.tools[0].offset_mm = 150;   // a tool close behind the camera
    config.max_extrapolation_ns = 2'000'000'000;
    Stage run = make_stage(config);
    // 400 ms late: the machine has moved 556 mm since the capture, past
    // every fire position (a plant is confirmed at most ~160 mm ahead).
    drive(run, plants, 400'000'000);
    EXPECT_TRUE(targets(*run.bus).empty());
    EXPECT_EQ(run.stage->counters().deadline_misses.load(), plants.size());
    EXPECT_EQ(run.stage->counters().send_latency.total().count, 0u) << "nothing was sent";
}

TEST(ActuationStage, DeadlineGivenToTheBusLeavesTheLeadTime)
{
    const auto plants = strip(5);
    ActuationConfig config = base_config();
    config.scheduler.lead_ms = 20;
    Stage run = make_stage(config);
    std::vector<std::int64_t> now_of_send;
    for (int k = 0; k < frames_for(plants); ++k) {
        const auto r = frame(plants, k);
        const std::size_t before = run.bus->sent.size();
        const std::int64_t now = r->t_sample_ns + 3'000'000;
        run.stage->on_frame(*r, now);
        for (std::size_t i = before; i < run.bus->sent.size(); ++i) {
            protocol::TargetCommand t;
            ASSERT_TRUE(protocol::decode(run.bus->sent[i], {}, t));
            // Odometer now (interpolated at constant speed) and arrival.
            const double odom_now = k * kSpeed / 30.0 + kSpeed * 0.003;
            const double arrival_ms = (t.fire_odom_mm - odom_now) / kSpeed * 1000.0;
            const double deadline_ms = static_cast<double>(run.bus->deadlines[i] - now) / 1e6;
            EXPECT_NEAR(deadline_ms, arrival_ms - 20.0, 1.0);   // fire_odom_mm is rounded to 1 mm
        }
    }
    EXPECT_EQ(targets(*run.bus).size(), plants.size());
}

TEST(ActuationStage, FramesWithoutOdometryAreNotActuated)
{
    const auto plants = strip(5);
    Stage run = make_stage(base_config());   // odometry.source: recording
    drive(run, plants, 3'000'000, false, /*with_odom=*/false);
    EXPECT_TRUE(targets(*run.bus).empty());
    EXPECT_EQ(run.stage->counters().no_odometry.load(), static_cast<std::uint64_t>(frames_for(plants)));
}

TEST(ActuationStage, AutoPolicyTreatsOnlyWeedsWithAClassMapAndEverythingWithout)
{
    const auto plants = strip(12);
    std::size_t weeds = 0;
    for (const Plant& p : plants)
        weeds += p.cls == PlantClass::Weed;
    ActuationConfig config = base_config();
    config.policy = PolicyChoice::automatic;
    for (const bool class_map : {true, false}) {
        Stage run = make_stage(config);
        drive(run, plants, 3'000'000, class_map);
        const auto sent = targets(*run.bus);
        if (class_map) {
            EXPECT_EQ(sent.size(), weeds);
            for (const auto& t : sent)
                EXPECT_EQ(t.plant_class, PlantClass::Weed);
            EXPECT_EQ(run.stage->counters().policy.load(), plants.size() - weeds);
        } else {
            EXPECT_EQ(sent.size(), plants.size());
            for (const auto& t : sent)
                EXPECT_EQ(t.plant_class, PlantClass::Unknown);
        }
    }
}

TEST(ActuationStage, AWeedStemlessInSomeFramesIsStillOneTarget)
{
    // Weeds only. Every other frame sees each weed without a stem of its
    // own, struck at its weed cells' centre 2 mm from the stem
    // (ComReason::stemless_weed): that target stands for the same plant,
    // so it joins the plant's track and adds no TARGET.
    std::vector<Plant> weeds = strip(9);
    for (Plant& p : weeds)
        p.cls = PlantClass::Weed;
    ActuationConfig config = base_config();
    config.policy = PolicyChoice::weeds_only;
    for (const auto reason : {vision::ComReason::stemless_weed, vision::ComReason::weed_part}) {
        Stage run = make_stage(config);
        for (int k = 0; k < frames_for(weeds); ++k) {
            const auto r = frame(weeds, k, true);
            if (k % 2)
                for (vision::Plant& p : r->detections.plants) {
                    p.com_reason = reason;
                    p.stem.x += static_cast<float>(2.0 / kGsd);
                }
            run.stage->on_frame(*r, r->t_sample_ns + 3'000'000);
        }
        const auto sent = targets(*run.bus);
        if (reason == vision::ComReason::stemless_weed) {
            EXPECT_EQ(sent.size(), weeds.size()) << "one TARGET per weed";
            expect_at_fire_positions(sent, weeds, 600, 10);
        } else {
            // A weed part stands for a weed grown into another plant, so
            // parts and plants are tracked apart: two TARGETs per weed here.
            EXPECT_EQ(sent.size(), 2 * weeds.size());
        }
    }
}

TEST(ActuationStage, EachFurtherTargetOnAWideWeedIsOneTargetOfItsOwn)
{
    // Weeds only. Each weed carries further targets (ComReason::weed_cover)
    // besides its stem: one 16 mm to its right and 4 mm ahead in every
    // frame, and one 6 mm to its left, within the tracker's association
    // radius of the stem, in the frames that miss the stem. Both move by up
    // to 1 mm from frame to frame, as a farthest cell does. Each is one
    // TARGET at its own place: the left one is not taken for the stem.
    std::vector<Plant> weeds = strip(9);
    for (Plant& p : weeds)
        p.cls = PlantClass::Weed;
    struct Offset {
        double ds_mm, dy_mm;
    };
    const Offset left{0, 6}, right{4, -16};
    ActuationConfig config = base_config();
    config.policy = PolicyChoice::weeds_only;
    Stage run = make_stage(config);
    for (int k = 0; k < frames_for(weeds); ++k) {
        const auto seen = frame(weeds, k, true);
        auto r = frame({}, k, true);
        const double jitter_px = (k % 3 - 1) / kGsd;
        for (std::size_t i = 0; i < seen->detections.plants.size(); ++i) {
            if (k % 2 == 0) {
                r->plant_class[r->detections.plants.size()] = PlantClass::Weed;
                r->detections.plants.push_back(seen->detections.plants[i]);
            }
            for (const bool is_left : {true, false}) {
                if (is_left && k % 2 == 0)
                    continue;
                const Offset& o = is_left ? left : right;
                vision::Plant cover = seen->detections.plants[i];
                // Image up is ahead, image left is the machine's left.
                cover.stem.x -= static_cast<float>(o.dy_mm / kGsd + jitter_px);
                cover.stem.y -= static_cast<float>(o.ds_mm / kGsd - jitter_px);
                cover.com_reason = vision::ComReason::weed_cover;
                r->plant_class[r->detections.plants.size()] = PlantClass::Weed;
                r->detections.plants.push_back(cover);
            }
        }
        run.stage->on_frame(*r, r->t_sample_ns + 3'000'000);
    }
    const auto sent = targets(*run.bus);
    EXPECT_EQ(sent.size(), 3 * weeds.size()) << "the stem and two further targets per weed";
    std::map<std::pair<std::size_t, int>, int> hits;   // (weed, 0 stem / 1 left / 2 right)
    for (const auto& t : sent) {
        bool found = false;
        for (std::size_t i = 0; i < weeds.size() && !found; ++i) {
            const Offset places[]{{0, 0}, left, right};
            for (int which = 0; which < 3 && !found; ++which) {
                const double ds = t.fire_odom_mm - (weeds[i].s_mm + places[which].ds_mm + 600);
                const double dy = t.lateral_mm - (weeds[i].y_mm + places[which].dy_mm);
                if (std::hypot(ds, dy) <= 2.0) {
                    found = true;
                    ++hits[{i, which}];
                }
            }
        }
        EXPECT_TRUE(found) << "fire " << t.fire_odom_mm << " lateral " << t.lateral_mm;
    }
    EXPECT_EQ(hits.size(), 3 * weeds.size()) << "one TARGET at each place";
}

TEST(ActuationStage, CanOdometryDrivesTheFramesAndCorruptFramesAreRejected)
{
    const auto plants = strip(8);
    ActuationConfig config = base_config();
    config.odometry = OdometrySource::can;
    Stage run = make_stage(config);
    const protocol::CanIds ids;
    protocol::E2eCounter counter;
    std::size_t corrupted = 0;
    // The drive sends ODOMETRY every 10 ms; the frames carry no odometer.
    const int n = frames_for(plants);
    for (std::int64_t t = kT0 - 50'000'000, k = 0; k < n; t += 10'000'000) {
        CanFrame f;
        const double odom = static_cast<double>(t - kT0) * 1e-9 * kSpeed;
        ASSERT_TRUE(protocol::encode(
            protocol::Odometry{static_cast<std::uint32_t>(std::llround(odom + 100000.0)), 1389}, counter.next(), ids,
            f));
        if ((t / 10'000'000) % 37 == 0) {
            f.data[5] ^= 0x10;   // a flipped bit: the CRC no longer matches
            ++corrupted;
        }
        run.bus->inbox.push_back(f);
        run.bus->inbox_t_rx_ns.push_back(t);
        run.stage->poll(t);
        if (t >= kT0 + k * kPeriodNs) {
            auto r = frame(plants, static_cast<int>(k), false, false);
            run.stage->on_frame(*r, t + 1'000'000);
            ++k;
        }
    }
    EXPECT_EQ(run.stage->counters().rx_rejected.load(), corrupted);
    EXPECT_GT(corrupted, 0u);
    const auto sent = targets(*run.bus);
    ASSERT_EQ(sent.size(), plants.size());
    for (std::size_t i = 0; i < sent.size(); ++i) {
        // Odometer offset 100000 mm; frames are stamped at multiples of the
        // period but odometry samples every 10 ms: interpolated within 1 mm.
        bool found = false;
        for (const Plant& p : plants)
            found = found || std::abs(sent[i].fire_odom_mm - (p.s_mm + 100000.0 + 600.0)) <= 2.0;
        EXPECT_TRUE(found) << "fire_odom_mm " << sent[i].fire_odom_mm;
    }
}

// The strip through a stage whose tool controller sends, before frame k,
// the TOOL_STATUS mask status(k) returns (none when it returns -1), with
// the TARGETs sent before each frame.
struct ToolStatusRun {
    Stage run;
    std::vector<std::uint64_t> sent_before;
    std::uint64_t heartbeat_dropped = 0;   // the last HEARTBEAT's targets_dropped
};

template <typename StatusOf>
ToolStatusRun drive_with_tool_status(const std::vector<Plant>& plants, std::int64_t timeout_ns, StatusOf status)
{
    ActuationConfig config = base_config();
    config.tool_status_timeout_ns = timeout_ns;
    ToolStatusRun out{make_stage(config), {}, 0};
    const protocol::CanIds ids;
    protocol::E2eCounter counter;
    for (int k = 0; k < frames_for(plants); ++k) {
        const std::int64_t t = kT0 + k * kPeriodNs + 3'000'000;
        if (const int mask = status(k); mask >= 0) {
            CanFrame f;
            EXPECT_TRUE(protocol::encode(protocol::ToolStatus{static_cast<std::uint16_t>(mask), 0, false, 0, 0},
                                         counter.next(), ids, f));
            out.run.bus->inbox.push_back(f);
            out.run.bus->inbox_t_rx_ns.push_back(t);
        }
        out.run.stage->poll(t);
        out.sent_before.push_back(out.run.stage->counters().sent.load());
        const auto r = frame(plants, k);
        out.run.stage->on_frame(*r, t);
    }
    out.run.stage->poll(kT0 + frames_for(plants) * kPeriodNs + 200'000'000);
    protocol::Heartbeat last{};
    for (const CanFrame& f : out.run.bus->sent) {
        if (ids.kind_of(f) == MessageKind::Heartbeat) {
            EXPECT_TRUE(protocol::decode(f, ids, last));
        }
    }
    out.heartbeat_dropped = last.targets_dropped;
    return out;
}

// The tool controller's TOOL_STATUS: until the first every tool counts as
// ready; a clear ready bit stops its TARGETs (counted not_ready, and in the
// HEARTBEAT's targets_dropped); a TOOL_STATUS older than
// can.tool_status_timeout_ms counts as none ready, unless that is 0.
TEST(ActuationStage, ToolsReportedNotReadyGetNoTargets)
{
    const auto plants = strip(40);   // 65 frames, 2.2 s
    const std::uint16_t tool3_down = 0xFFFF & ~(1U << 3);   // the table's one tool is 3

    const auto never = drive_with_tool_status(plants, 500'000'000, [](int) { return -1; });
    EXPECT_EQ(never.run.stage->counters().sent.load(), plants.size()) << "no TOOL_STATUS: every tool is ready";

    const auto down = drive_with_tool_status(plants, 500'000'000, [&](int k) { return k % 3 == 0 ? tool3_down : -1; });
    EXPECT_EQ(down.run.stage->counters().sent.load(), 0u);
    EXPECT_TRUE(targets(*down.run.bus).empty());
    EXPECT_EQ(down.run.stage->counters().not_ready.load(), plants.size());
    EXPECT_EQ(down.heartbeat_dropped, plants.size());

    // Ready every 100 ms until frame 24 (0.8 s), then silent: nothing is
    // sent from 500 ms after the last TOOL_STATUS on.
    const int last_status = 24;
    const auto silent =
        drive_with_tool_status(plants, 500'000'000, [&](int k) { return k % 3 == 0 && k <= last_status ? 0xFFFF : -1; });
    const auto& c = silent.run.stage->counters();
    const int stale_from = last_status + 16;   // 16 frames: 533 ms after it
    ASSERT_LT(stale_from, static_cast<int>(silent.sent_before.size()));
    const std::uint64_t sent_in_time = silent.sent_before[stale_from];
    EXPECT_GT(sent_in_time, 0u);
    EXPECT_LT(sent_in_time, plants.size()) << "the strip must outlast the status for this test to say anything";
    EXPECT_EQ(c.sent.load(), sent_in_time) << "a TARGET went out after the tool controller fell silent";
    EXPECT_EQ(c.not_ready.load(), plants.size() - sent_in_time);

    const auto held = drive_with_tool_status(plants, 0, [&](int k) { return k == 0 ? 0xFFFF : -1; });
    EXPECT_EQ(held.run.stage->counters().sent.load(), plants.size()) << "timeout 0: the last TOOL_STATUS holds";
}

// ODOMETRY frames carry the time the bus received them, not the time a
// later poll read them: a drive sample 100 ms old is the odometer 100 ms ago.
TEST(ActuationStage, CanOdometryIsStampedWhenReceivedNotWhenPolled)
{
    ActuationConfig config = base_config();
    config.odometry = OdometrySource::can;
    config.max_extrapolation_ns = 500'000'000;
    Stage run = make_stage(config);
    const protocol::CanIds ids;
    protocol::E2eCounter counter;
    constexpr std::int64_t kPollNs = kT0;
    for (const auto& [odom_mm, t_rx_ns] : {std::pair{1000u, kPollNs - 100'000'000}, {1100u, kPollNs - 50'000'000}}) {
        CanFrame f;
        ASSERT_TRUE(protocol::encode(protocol::Odometry{odom_mm, 2000}, counter.next(), ids, f));
        run.bus->inbox.push_back(f);
        run.bus->inbox_t_rx_ns.push_back(t_rx_ns);
    }
    run.stage->poll(kPollNs);
    EXPECT_EQ(run.stage->counters().rx_odometry.load(), 2u);
    EXPECT_EQ(run.stage->counters().odometry_going_back.load(), 0u);
    double odom_mm = 0;
    ASSERT_TRUE(run.stage->odometry().odometer_at(kPollNs - 100'000'000, odom_mm));
    EXPECT_DOUBLE_EQ(odom_mm, 1000.0);
    ASSERT_TRUE(run.stage->odometry().odometer_at(kPollNs - 75'000'000, odom_mm));
    EXPECT_NEAR(odom_mm, 1050.0, 1e-6);
    // At the poll, 50 ms after the newest sample: extrapolated at 2 m/s.
    ASSERT_TRUE(run.stage->odometry().odometer_at(kPollNs, odom_mm));
    EXPECT_NEAR(odom_mm, 1200.0, 1e-6);
}

// The drive reversing: its odometer counts down. Those samples are refused
// and counted; the odometer holds its highest reading, and goes stale,
// until the drive passes that reading again.
TEST(ActuationStage, CanOdometryGoingBackIsCountedAndNotFollowed)
{
    ActuationConfig config = base_config();
    config.odometry = OdometrySource::can;
    config.max_extrapolation_ns = 100'000'000;
    Stage run = make_stage(config);
    const protocol::CanIds ids;
    protocol::E2eCounter counter;
    const auto drive_says = [&](std::uint32_t odom_mm, std::int64_t t_rx_ns) {
        CanFrame f;
        ASSERT_TRUE(protocol::encode(protocol::Odometry{odom_mm, 0}, counter.next(), ids, f));
        run.bus->inbox.push_back(f);
        run.bus->inbox_t_rx_ns.push_back(t_rx_ns);
        run.stage->poll(t_rx_ns);
    };
    constexpr std::int64_t kMs = 1'000'000;
    drive_says(1000, kT0);
    drive_says(1010, kT0 + 10 * kMs);
    for (int i = 1; i <= 30; ++i)   // 300 ms backing up 3 mm every 10 ms
        drive_says(1010 - 3 * i, kT0 + (10 + 10 * i) * kMs);
    EXPECT_EQ(run.stage->counters().rx_odometry.load(), 32u);
    EXPECT_EQ(run.stage->counters().odometry_going_back.load(), 30u);
    double odom_mm = 0;
    EXPECT_FALSE(run.stage->odometry().odometer_at(kT0 + 310 * kMs, odom_mm)) << odom_mm;   // stale
    drive_says(1020, kT0 + 320 * kMs);   // past 1010 again
    ASSERT_TRUE(run.stage->odometry().odometer_at(kT0 + 320 * kMs, odom_mm));
    EXPECT_DOUBLE_EQ(odom_mm, 1020.0);
}

// The machine drives over the strip, backs up 300 mm over plants it has
// commanded, and drives on (CAN ODOMETRY, a frame at every sample): each
// plant still gets exactly one TARGET. Frames taken while it reverses, and
// until it passes its turning point, are not actuated; nor are they placed
// at the speed it had before it turned.
TEST(ActuationStage, BackingUpOverCommandedPlantsCommandsNoneTwice)
{
    ActuationConfig config = base_config();
    config.odometry = OdometrySource::can;
    Stage run = make_stage(config);
    const protocol::CanIds ids;
    protocol::E2eCounter counter;
    const auto plants = strip(10);
    const double step_mm = kSpeed / 30.0;
    std::vector<double> path;   // the odometer at each frame
    for (double odom = 0; odom < 650; odom += step_mm)
        path.push_back(odom);
    const double turn_mm = path.back();
    for (int i = 1; i <= 10; ++i)
        path.push_back(turn_mm - 30.0 * i);
    for (double odom = path.back() + step_mm; odom < plants.back().s_mm + kSize.height * kGsd + 2 * step_mm;
         odom += step_mm)
        path.push_back(odom);
    for (std::size_t k = 0; k < path.size(); ++k) {
        const std::int64_t t_ns = kT0 + static_cast<std::int64_t>(k) * kPeriodNs;
        CanFrame f;
        ASSERT_TRUE(protocol::encode(protocol::Odometry{static_cast<std::uint32_t>(std::lround(path[k])), 0},
                                     counter.next(), ids, f));
        run.bus->inbox.push_back(f);
        run.bus->inbox_t_rx_ns.push_back(t_ns);
        run.stage->poll(t_ns);
        const auto r = frame_at(plants, static_cast<int>(k), path[k], false, false);
        run.stage->on_frame(*r, t_ns + 1'000'000);
        run.stage->poll(t_ns + 2'000'000);
    }
    run.stage->finish();
    const auto sent = targets(*run.bus);
    EXPECT_EQ(sent.size(), plants.size());
    std::set<std::size_t> hit;
    for (const auto& t : sent)
        for (std::size_t i = 0; i < plants.size(); ++i) {
            if (std::abs(t.fire_odom_mm - (plants[i].s_mm + 600.0)) <= 2.0) {
                EXPECT_TRUE(hit.insert(i).second) << "a second TARGET for plant " << i;
            }
        }
    EXPECT_EQ(hit.size(), plants.size());
    EXPECT_GT(run.stage->counters().no_odometry.load(), 10u);   // the reversal and its way back
}

TEST(ActuationStage, HeartbeatEveryIntervalWithState)
{
    Stage run = make_stage(base_config());
    for (std::int64_t t = kT0; t < kT0 + 1'000'000'000; t += 1'000'000)
        run.stage->poll(t);
    std::vector<protocol::Heartbeat> beats;
    for (const CanFrame& f : run.bus->sent) {
        protocol::Heartbeat hb;
        ASSERT_TRUE(protocol::decode(f, {}, hb));
        beats.push_back(hb);
    }
    ASSERT_EQ(beats.size(), 10u);   // t = 0, 100, ..., 900 ms
    EXPECT_EQ(beats[0].state, protocol::DaemonState::Starting);
    EXPECT_EQ(run.stage->counters().heartbeats.load(), 10u);
}


TEST(ActuationStage, ConstantSpeedOdometryNeverGoesStale)
{
    // No odometer in the frames: odometry.source constant. A pipeline
    // 400 ms late (beyond the 100 ms extrapolation limit of sampled
    // odometry) still knows the odometer now, and the 600 mm tool is still
    // ahead of every plant: all are sent.
    const auto plants = strip(6);
    ActuationConfig config = base_config();
    config.odometry = OdometrySource::constant;
    config.speed_mm_per_s = kSpeed;
    Stage run = make_stage(config);
    drive(run, plants, 400'000'000, false, /*with_odom=*/false);
    EXPECT_EQ(run.stage->counters().no_odometry.load(), 0u);
    EXPECT_EQ(targets(*run.bus).size(), plants.size());
    // The constant odometer starts at 0 with the first frame, like the
    // recording's: the fire positions are the same.
    expect_at_fire_positions(targets(*run.bus), plants, 600, 1.0);
}


TEST(ActuationStage, WheelEncoderOdometry)
{
    // odometry.source encoder: 0.1 mm per tick, sampled between frames;
    // the frames carry no odometer. Fire positions follow the encoder.
    const auto plants = strip(6);
    ActuationConfig config = base_config();
    config.odometry = OdometrySource::encoder;
    config.encoder_mm_per_tick = 0.1;
    Stage run = make_stage(config, true, drivers::EncoderMode::quadrature);
    ASSERT_TRUE(run.stage);
    const int n = frames_for(plants);
    for (std::int64_t t = kT0 - 20'000'000, k = 0; k < n; t += 5'000'000) {
        // 5 km/h: ticks of 0.1 mm.
        run.gpio->ticks.store(std::llround(static_cast<double>(t - kT0) * 1e-9 * kSpeed / 0.1) + 50'000);
        run.stage->poll(t);
        if (t >= kT0 + k * kPeriodNs) {
            const auto r = frame(plants, static_cast<int>(k), false, false);
            run.stage->on_frame(*r, t + 1'000'000);
            ++k;
        }
    }
    const auto sent = targets(*run.bus);
    ASSERT_EQ(sent.size(), plants.size());
    expect_at_fire_positions(sent, plants, 5000 + 600, 2.0);   // encoder offset 50000 ticks = 5000 mm
}

TEST(ActuationStage, EncoderOdometryWithoutAnEncoderIsRefused)
{
    ActuationConfig config = base_config();
    config.odometry = OdometrySource::encoder;
    ActuationStage::Parts parts;
    parts.bus = std::make_unique<FakeBus>();
    std::string error;
    EXPECT_FALSE(ActuationStage::make(config, nadir_camera(), kSize, std::move(parts),
                                      runtime::make_logger("actuator-test"), error));
    EXPECT_NE(error.find("encoder"), std::string::npos) << error;
}


TEST(ActuationStage, PlantsCutByTheAlongTrackBordersAreNotTrackedButLateralOnesAre)
{
    Stage run = make_stage(base_config());
    auto r = std::make_unique<FrameResult>();
    r->t_sample_ns = kT0;
    r->odom_mm = 0;
    const auto add = [&](cv::Point2f stem, cv::Rect bbox) {
        vision::Plant p;
        p.stem = stem;
        p.confidence = 0.8f;
        p.bbox = bbox;
        r->detections.plants.push_back(p);
    };
    add({600, 10}, {580, 0, 40, 40});       // cut by the top (leading) border
    add({600, 950}, {580, 930, 40, 36});    // cut by the bottom (trailing) border
    add({5, 480}, {0, 460, 30, 40});        // cut by the left border: kept
    add({600, 480}, {580, 460, 40, 40});    // whole
    for (int k = 0; k < 3; ++k) {
        r->seq = static_cast<std::uint64_t>(k);
        r->t_sample_ns = kT0 + k;   // the same view again: three sightings
        run.stage->on_frame(*r, r->t_sample_ns + 1'000'000);
    }
    EXPECT_EQ(run.stage->counters().clipped.load(), 6u);
    EXPECT_EQ(run.stage->counters().targets.load(), 2u);
}


TEST(ActuationStage, HeartbeatPeriodsPassedWithoutAPollAreCountedAsMisses)
{
    // 100 ms period. Polls every millisecond to +150 ms (heartbeats at 0
    // and +100 ms), then none until +500 ms (a stalled actuator thread):
    // the slots at +200, +300 and +400 ms passed with no heartbeat. The
    // poll at +500 ms sends one and the grid goes on from it (+600, +700).
    Stage run = make_stage(base_config());
    for (std::int64_t t = kT0; t <= kT0 + 150'000'000; t += 1'000'000)
        run.stage->poll(t);
    EXPECT_EQ(run.stage->counters().heartbeats.load(), 2u);
    EXPECT_EQ(run.stage->counters().heartbeat_misses.load(), 0u);
    for (std::int64_t t = kT0 + 500'000'000; t <= kT0 + 700'000'000; t += 1'000'000)
        run.stage->poll(t);
    EXPECT_EQ(run.stage->counters().heartbeat_misses.load(), 3u);
    EXPECT_EQ(run.stage->counters().heartbeats.load(), 5u);
}

TEST(ActuationStage, FailedHeartbeatsAreNotCountedAsDroppedTargets)
{
    // The first heartbeats fail on the bus; the ones after must still say
    // no TARGET was dropped (targets_dropped counts TARGETs only), and the
    // failures have their own counter.
    Stage run = make_stage(base_config());
    run.bus->fail_id = protocol::CanIds{}.id(protocol::MessageKind::Heartbeat);
    for (std::int64_t t = kT0; t < kT0 + 300'000'000; t += 1'000'000)
        run.stage->poll(t);
    EXPECT_EQ(run.stage->counters().heartbeat_errors.load(), 3u);
    EXPECT_EQ(run.stage->counters().bus_errors.load(), 0u);
    EXPECT_TRUE(run.bus->sent.empty());
    run.bus->fail_id.reset();
    for (std::int64_t t = kT0 + 300'000'000; t < kT0 + 500'000'000; t += 1'000'000)
        run.stage->poll(t);
    ASSERT_EQ(run.bus->sent.size(), 2u);
    for (const CanFrame& f : run.bus->sent) {
        protocol::Heartbeat hb;
        ASSERT_TRUE(protocol::decode(f, {}, hb));
        EXPECT_EQ(hb.targets_dropped, 0u);
    }
    EXPECT_EQ(run.stage->counters().heartbeats.load(), 2u);
}

TEST(ActuationStage, HeartbeatKeepsItsCadenceWhenPollsComeLate)
{
    // Polls every 3 ms against a 100 ms heartbeat: each heartbeat goes out
    // up to 3 ms late, but the next is still due on the 100 ms grid, so 10
    // heartbeats fit in 1 s (not 9.7, as with "100 ms after the last one").
    Stage run = make_stage(base_config());
    std::vector<std::int64_t> sent_at;
    for (std::int64_t t = kT0; t < kT0 + 1'000'000'000; t += 3'000'000) {
        const std::size_t before = run.bus->sent.size();
        run.stage->poll(t);
        if (run.bus->sent.size() > before)
            sent_at.push_back(t);
    }
    ASSERT_EQ(sent_at.size(), 10u);
    for (std::size_t i = 1; i < sent_at.size(); ++i) {
        const std::int64_t grid = kT0 + static_cast<std::int64_t>(i) * 100'000'000;
        EXPECT_GE(sent_at[i], grid);
        EXPECT_LT(sent_at[i], grid + 3'000'000);
    }
}


// The recording's odometer handed over at capture (the daemon's capture
// thread does) keeps the actuator's odometer as fresh as the camera, so a
// pipeline 200 ms late (beyond the 100 ms extrapolation limit) still
// actuates every plant; with the odometer only inside the late results the
// same run has nothing fresh to fire by.
TEST(ActuationStage, RecordingOdometerGivenAtCaptureOutlivesASlowPipeline)
{
    const auto plants = strip(6);
    constexpr std::int64_t kLateNs = 200'000'000;
    constexpr int kFramesInFlight = 6;   // 200 ms / 33 ms: captured, not yet out
    ActuationConfig config = base_config();
    config.max_extrapolation_ns = 100'000'000;

    Stage at_capture = make_stage(config);
    Stage with_result = make_stage(config);
    const int n = frames_for(plants);
    for (int k = 0; k < n; ++k) {
        const auto r = frame(plants, k);
        const std::int64_t now_ns = r->t_sample_ns + kLateNs;
        for (int j = k; j <= std::min(k + kFramesInFlight, n - 1); ++j) {
            const auto captured = frame(plants, j);
            at_capture.stage->on_capture(captured->t_sample_ns, captured->odom_mm);
        }
        at_capture.stage->on_frame(*r, now_ns);
        with_result.stage->on_frame(*r, now_ns);
    }
    EXPECT_EQ(at_capture.stage->counters().no_odometry.load(), 0u);
    EXPECT_EQ(targets(*at_capture.bus).size(), plants.size());
    expect_at_fire_positions(targets(*at_capture.bus), plants, 600, 1.0);
    EXPECT_TRUE(targets(*with_result.bus).empty());
    EXPECT_EQ(with_result.stage->counters().no_odometry.load(), plants.size());
}

}  // namespace
}  // namespace stemd::runtime

namespace stemd::runtime {
namespace {

TEST(HeartbeatState, EachInputMapsToItsState)
{
    using protocol::DaemonState;
    const HeartbeatInputs healthy{
        .frames_seen = true, .camera_lost = false, .enabled = true, .odometry = true, .new_misses = false};
    EXPECT_EQ(heartbeat_state(healthy), DaemonState::Active);
    HeartbeatInputs in = healthy;
    in.new_misses = true;
    EXPECT_EQ(heartbeat_state(in), DaemonState::Degraded);
    in = healthy;
    in.enabled = false;
    EXPECT_EQ(heartbeat_state(in), DaemonState::Idle);
    in = healthy;
    in.odometry = false;
    EXPECT_EQ(heartbeat_state(in), DaemonState::Idle);
    in = healthy;
    in.frames_seen = false;
    EXPECT_EQ(heartbeat_state(in), DaemonState::Starting);
    // A lost camera outranks everything else: the tool must know why no
    // target comes, whatever else is also wrong.
    for (const bool frames_seen : {false, true})
        for (const bool enabled : {false, true})
            for (const bool odometry : {false, true})
                for (const bool misses : {false, true})
                    EXPECT_EQ(heartbeat_state({.frames_seen = frames_seen,
                                               .camera_lost = true,
                                               .enabled = enabled,
                                               .odometry = odometry,
                                               .new_misses = misses}),
                              DaemonState::CameraLost);
}

TEST(ActuationStage, HeartbeatSaysCameraLostWhileTheCaptureSideSaysSo)
{
    Stage run = make_stage(base_config());
    // 300 ms healthy (no frame yet), 300 ms lost, 300 ms back.
    for (std::int64_t t = kT0; t < kT0 + 900'000'000; t += 1'000'000) {
        const bool lost = t >= kT0 + 300'000'000 && t < kT0 + 600'000'000;
        run.stage->poll(t, lost);
    }
    std::vector<protocol::DaemonState> states;
    for (const CanFrame& f : run.bus->sent) {
        protocol::Heartbeat hb;
        ASSERT_TRUE(protocol::decode(f, {}, hb));
        states.push_back(hb.state);
    }
    using protocol::DaemonState;
    const std::vector<DaemonState> expected{DaemonState::Starting,   DaemonState::Starting,   DaemonState::Starting,
                                            DaemonState::CameraLost, DaemonState::CameraLost, DaemonState::CameraLost,
                                            DaemonState::Starting,   DaemonState::Starting,   DaemonState::Starting};
    EXPECT_EQ(states, expected);
}

// Frames a second apart (BoniRob's recording: 0.26 m/s, the view 319 mm
// long here): a plant seen only in the last frame, mid-view, is sent when
// the stream ends, as the next frame step would carry it out of the view;
// without the end it stays unconfirmed.
TEST(ActuationStage, TheEndOfAStreamSendsWhatTheNextFrameStepWouldCarryOut)
{
    constexpr double kStepMm = 265.0;
    const std::vector<Plant> plants{{100.0, 20.0, PlantClass::Weed}, {530.0, -30.0, PlantClass::Weed}};
    for (const bool end : {false, true}) {
        SCOPED_TRACE(end ? "end of stream" : "stopped");
        Stage run = make_stage(base_config());
        for (int k = 0; k < 3; ++k) {
            auto r = frame({}, k);
            r->t_sample_ns = kT0 + k * 1'000'000'000LL;
            r->odom_mm = k * kStepMm;
            // Frame k sees the plants within its 319 mm view.
            const cv::Point2d c = geometry::image_centre(kSize);
            for (const Plant& p : plants) {
                const double v = c.y - (p.s_mm - r->odom_mm) / kGsd;
                if (v < 20 || v > kSize.height - 21)
                    continue;
                vision::Plant vp;
                vp.stem = {static_cast<float>(c.x - p.y_mm / kGsd), static_cast<float>(v)};
                vp.bbox = cv::Rect(static_cast<int>(vp.stem.x) - 15, static_cast<int>(v) - 15, 31, 31);
                vp.has_stem = true;
                vp.confidence = 0.8f;
                r->plant_class[r->detections.plants.size()] = p.cls;
                r->detections.plants.push_back(vp);
            }
            run.stage->on_frame(*r, r->t_sample_ns + 3'000'000);
        }
        EXPECT_EQ(targets(*run.bus).size(), 1u) << "the first plant left the view at frame 1";
        if (end)
            run.stage->end_of_stream();
        const auto sent = targets(*run.bus);
        ASSERT_EQ(sent.size(), end ? 2u : 1u);
        if (end) {
            EXPECT_NEAR(sent.back().fire_odom_mm, 530.0 + 600.0, 1.0);
        }
        EXPECT_EQ(run.stage->counters().no_odometry.load(), 0u);
    }
}

// At 30 fps the next step is 46 mm: a plant in mid-view when the stream
// ends is not sent (it would have been seen again), and none is sent twice.
TEST(ActuationStage, TheEndOfAStreamLeavesMidViewPlantsAlone)
{
    const auto plants = strip(30);
    Stage run = make_stage(base_config());
    const int last = frames_for(plants) / 2;
    for (int k = 0; k <= last; ++k) {
        const auto r = frame(plants, k);
        run.stage->on_frame(*r, r->t_sample_ns + 3'000'000);
    }
    const std::size_t before = targets(*run.bus).size();
    run.stage->end_of_stream();
    const auto sent = targets(*run.bus);
    ASSERT_GE(sent.size(), before);
    const double odom_last = last * kSpeed / 30.0;
    const double view_min_next = odom_last + kSpeed / 30.0 + run.stage->view_forward_min_mm();
    for (std::size_t i = before; i < sent.size(); ++i) {
        // Within the exit margin (60 mm) and the plant's half-size (5 mm)
        // of the next view's trailing edge.
        EXPECT_LT(sent[i].fire_odom_mm - 600.0, view_min_next + 60.0 + 5.0 + 1.0);
    }
    std::set<int> fire;
    for (const auto& t : sent)
        EXPECT_TRUE(fire.insert(static_cast<int>(t.fire_odom_mm)).second) << "a plant sent twice";
    // Plants ahead of that reach, in view, stay unsent.
    int ahead_in_view = 0;
    for (const Plant& p : plants)
        if (p.s_mm > view_min_next + 70.0 && p.s_mm < odom_last + run.stage->view_forward_max_mm())
            ++ahead_in_view;
    EXPECT_GT(ahead_in_view, 0);
    EXPECT_LE(sent.size(), plants.size() - static_cast<std::size_t>(ahead_in_view));
}

// A frame processed 200 ms after its capture, beyond the 100 ms the
// odometer may be extrapolated: with the next frame's odometer already in
// (a paced replay announces it) it is interpolated and the plant is sent.
TEST(ActuationStage, AnOdometerSampleAheadKeepsASlowFrameActuated)
{
    const auto plants = strip(3);
    for (const bool ahead : {false, true}) {
        SCOPED_TRACE(ahead ? "next sample known" : "no sample ahead");
        ActuationConfig config = base_config();
        config.max_extrapolation_ns = 100'000'000;
        Stage run = make_stage(config);
        std::uint64_t no_odometry = 0;
        for (int k = 0; k < frames_for(plants); ++k) {
            const auto r = frame(plants, k);
            run.stage->on_capture(r->t_sample_ns, r->odom_mm);
            if (ahead)   // a second ahead, at the same speed
                run.stage->on_capture(r->t_sample_ns + 1'000'000'000, r->odom_mm + kSpeed);
            run.stage->on_frame(*r, r->t_sample_ns + 200'000'000);
            no_odometry = run.stage->counters().no_odometry.load();
        }
        if (ahead) {
            EXPECT_EQ(no_odometry, 0u);
            EXPECT_EQ(targets(*run.bus).size(), plants.size());
        } else {
            EXPECT_GT(no_odometry, 0u);
        }
    }
}

}  // namespace
}  // namespace stemd::runtime
