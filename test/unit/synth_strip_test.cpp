// The moving field strip: motion and odometer, the pixel <-> field
// convention checked against the daemon's geometry, ground truth against
// plants, layout rules, class maps, and the detector on strip frames.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>

#include <opencv2/core.hpp>

#include "synth_test_util.hpp"
#include "stemd/eval/eval.hpp"
#include "stemd/geometry/camera_model.hpp"
#include "stemd/geometry/field.hpp"
#include "stemd/synth/synth.hpp"
#include "stemd/vision/detect.hpp"

using namespace stemd;
using namespace stemd::synth;

namespace {

using stemd::test::expect_same_planes;
using stemd::test::same_bytes;

StripOptions options(Preset preset, double length_mm, std::uint64_t seed = 11)
{
    StripOptions o;
    o.preset = preset;
    o.seed = seed;
    o.length_mm = length_mm;
    return o;
}

// Generated once: each strip takes a second or two.
const Strip& late_strip()
{
    static const Strip strip = generate_strip(options(Preset::late, 1500));
    return strip;
}

const Strip& dense_strip()
{
    static const Strip strip = generate_strip(options(Preset::dense, 800));
    return strip;
}

geometry::CameraModel camera_of(const StripOptions& o)
{
    geometry::NadirParams p;
    p.gsd_mm_per_px = o.gsd_mm_per_px;
    p.principal_px = geometry::image_centre({o.width_px, o.height_px});
    p.mount = {.forward = geometry::Forward::up, .x_mm = 0, .y_mm = 0};
    return *geometry::CameraModel::nadir(p);
}

bool inside(const StripOptions& o, cv::Point2d px)
{
    return px.x >= 0 && px.y >= 0 && px.x <= o.width_px - 1 && px.y <= o.height_px - 1;
}

}  // namespace

TEST(SynthStrip, SameOptionsGiveSameBytes)
{
    const StripOptions o = options(Preset::dense, 400, 5);
    const Strip a = generate_strip(o), b = generate_strip(o);
    ASSERT_EQ(a.frame_count, b.frame_count);
    expect_same_planes(a, b);
    EXPECT_TRUE(same_bytes(a.plant_class, b.plant_class));
    ASSERT_EQ(a.plants.size(), b.plants.size());
    for (std::size_t i = 0; i < a.plants.size(); ++i) {
        EXPECT_EQ(a.plants[i].s_mm, b.plants[i].s_mm);
        EXPECT_EQ(a.plants[i].y_mm, b.plants[i].y_mm);
    }
    for (const int k : {0, a.frame_count / 2, a.frame_count - 1}) {
        const StripFrame fa = render_strip_frame(a, k), fb = render_strip_frame(b, k);
        EXPECT_TRUE(same_bytes(fa.bgr, fb.bgr));
        EXPECT_TRUE(same_bytes(fa.nir, fb.nir));
        EXPECT_EQ(fa.stems.size(), fb.stems.size());
    }
    const Strip other = generate_strip(options(Preset::dense, 400, 6));
    EXPECT_FALSE(same_bytes(a.bgr(cv::Rect(0, 0, 64, 64)).clone(), other.bgr(cv::Rect(0, 0, 64, 64)).clone()));
}

TEST(SynthStrip, FramesSizesAndTypes)
{
    const Strip& strip = late_strip();
    const StripFrame f = render_strip_frame(strip, 3);
    const cv::Size size(strip.options.width_px, strip.options.height_px);
    EXPECT_EQ(f.bgr.size(), size);
    EXPECT_EQ(f.bgr.type(), CV_8UC3);
    EXPECT_EQ(f.nir.type(), CV_8UC1);
    EXPECT_EQ(f.mask.type(), CV_8UC1);
    EXPECT_EQ(f.plant_class.type(), CV_8UC1);
    EXPECT_EQ(f.plant_class.size(), size);
    EXPECT_THROW(render_strip_frame(strip, -1), std::out_of_range);
    EXPECT_THROW(render_strip_frame(strip, strip.frame_count), std::out_of_range);
}

TEST(SynthStrip, OdometerAndTimeAdvanceAtTheSpeed)
{
    const Strip& strip = late_strip();
    const StripOptions& o = strip.options;
    const double step_mm = o.speed_kmh / 3.6 * 1000 / o.fps;   // 46.3 mm at 5 km/h, 30 fps
    const std::int64_t period_ns = std::llround(1e9 / o.fps);
    ASSERT_GT(strip.frame_count, 30);
    EXPECT_EQ(strip.odom_mm(0), 0.0);
    EXPECT_EQ(strip.t_ns(0), kStripT0Ns);
    for (int k = 1; k < strip.frame_count; ++k) {
        EXPECT_NEAR(strip.odom_mm(k) - strip.odom_mm(k - 1), step_mm, o.gsd_mm_per_px) << k;
        EXPECT_NEAR(strip.odom_mm(k), k * step_mm, o.gsd_mm_per_px / 2 + 1e-9) << k;
        EXPECT_EQ(strip.t_ns(k) - strip.t_ns(k - 1), period_ns);
        // An odometer of whole pixels: the frames are exact crops.
        EXPECT_NEAR(strip.odom_mm(k) / o.gsd_mm_per_px, std::round(strip.odom_mm(k) / o.gsd_mm_per_px), 1e-6);
    }
    const StripFrame f = render_strip_frame(strip, 7);
    EXPECT_EQ(f.odom_mm, strip.odom_mm(7));
    EXPECT_EQ(f.t_ns, strip.t_ns(7));
}

// The mask has no noise: frame k + 1 is frame k moved down the image by the
// odometer's advance (forward = image up).
TEST(SynthStrip, PlantsMoveDownTheImageAsTheOdometerGrows)
{
    const Strip& strip = late_strip();
    const double gsd = strip.options.gsd_mm_per_px;
    int compared = 0;
    for (int k = 0; k + 1 < strip.frame_count; k += 5) {
        const StripFrame a = render_strip_frame(strip, k), b = render_strip_frame(strip, k + 1);
        const int d = static_cast<int>(std::lround((b.odom_mm - a.odom_mm) / gsd));
        ASSERT_GT(d, 0);
        const int rows = a.mask.rows - d;
        EXPECT_TRUE(same_bytes(a.mask.rowRange(0, rows).clone(), b.mask.rowRange(d, d + rows).clone())) << k;
        EXPECT_TRUE(same_bytes(a.plant_class.rowRange(0, rows).clone(), b.plant_class.rowRange(d, d + rows).clone()));
        compared += cv::countNonZero(a.mask.rowRange(0, rows)) > 0;
    }
    EXPECT_GT(compared, 3);
}

// The convention must be the daemon's: geometry::field_position with a
// nadir camera (forward up, at x = 0, y = 0) maps a rendered stem back to
// its plant's field position.
TEST(SynthStrip, StemPixelsMapBackToFieldPositionsWithTheDaemonsGeometry)
{
    const Strip& strip = late_strip();
    const StripOptions& o = strip.options;
    const geometry::CameraModel camera = camera_of(o);
    int checked = 0;
    for (int k = 0; k < strip.frame_count; ++k) {
        const StripFrame f = render_strip_frame(strip, k);
        for (std::size_t i = 0; i < f.stems.size(); ++i) {
            const StripPlant& plant = strip.plants[static_cast<std::size_t>(f.plant_ids[i])];
            const cv::Point2d px(f.stems[i].x_px, f.stems[i].y_px);
            // Exact in doubles...
            const auto g = camera.pixel_to_ground(px);
            ASSERT_TRUE(g.has_value());
            EXPECT_NEAR(f.odom_mm + g->forward_mm, plant.s_mm, 1e-6);
            EXPECT_NEAR(g->y_mm, plant.y_mm, 1e-6);
            // ... and through field_position (its pixel is a float: ~1e-4 px).
            const auto field = geometry::field_position(camera, cv::Point2f(px), f.odom_mm);
            ASSERT_TRUE(field.has_value());
            EXPECT_NEAR(field->s_mm, plant.s_mm, 1e-3);
            EXPECT_NEAR(field->y_mm, plant.y_mm, 1e-3);
            // And the other way.
            const auto back = camera.ground_to_pixel(plant.s_mm - f.odom_mm, plant.y_mm);
            ASSERT_TRUE(back.has_value());
            EXPECT_NEAR(back->x, px.x, 1e-6);
            EXPECT_NEAR(back->y, px.y, 1e-6);
            ++checked;
        }
    }
    EXPECT_GT(checked, 100);
}

// Left of the machine (y > 0) is image left; ahead (s > o) is image up.
TEST(SynthStrip, PixelConventionDirections)
{
    const StripOptions o;
    const cv::Point2d c = strip_pixel(o, 100, 0, 100);
    EXPECT_DOUBLE_EQ(c.x, (o.width_px - 1) / 2.0);
    EXPECT_DOUBLE_EQ(c.y, (o.height_px - 1) / 2.0);
    EXPECT_LT(strip_pixel(o, 100, 10, 100).x, c.x);
    EXPECT_LT(strip_pixel(o, 110, 0, 100).y, c.y);
    EXPECT_NEAR(strip_pixel(o, 100, 0, 100 + 33).y - c.y, 100, 1e-9);
}

// Per-frame truth = the plants whose stems the formula puts inside the view,
// and every plant is seen (the step is far below the view's length).
TEST(SynthStrip, EveryPlantIsGroundTruthInTheFramesThatSeeIt)
{
    const Strip& strip = late_strip();
    const StripOptions& o = strip.options;
    ASSERT_GT(strip.plants.size(), 10u);
    std::map<int, int> frames_seen;
    for (int k = 0; k < strip.frame_count; ++k) {
        const StripFrame f = render_strip_frame(strip, k);
        ASSERT_EQ(f.stems.size(), f.plant_ids.size());
        std::set<int> expected, got(f.plant_ids.begin(), f.plant_ids.end());
        for (const StripPlant& p : strip.plants)
            if (inside(o, strip_pixel(o, p.s_mm, p.y_mm, f.odom_mm)))
                expected.insert(p.id);
        EXPECT_EQ(got, expected) << "frame " << k;
        for (std::size_t i = 0; i < f.stems.size(); ++i) {
            const StripPlant& p = strip.plants[static_cast<std::size_t>(f.plant_ids[i])];
            const cv::Point2d px = strip_pixel(o, p.s_mm, p.y_mm, f.odom_mm);
            EXPECT_DOUBLE_EQ(f.stems[i].x_px, px.x);
            EXPECT_DOUBLE_EQ(f.stems[i].y_px, px.y);
            EXPECT_EQ(f.stems[i].kind, p.kind);
            EXPECT_EQ(f.stems[i].leaves, p.leaves);
            EXPECT_GT(f.stems[i].area_px, 0);
            ++frames_seen[p.id];
        }
    }
    // A stem crosses the view's length (319 mm) in about 6.9 steps of 46.3 mm.
    for (const StripPlant& p : strip.plants) {
        EXPECT_GE(frames_seen[p.id], 6) << "plant " << p.id;
        EXPECT_LE(frames_seen[p.id], 7) << "plant " << p.id;
    }
}

TEST(SynthStrip, LayoutRules)
{
    for (const Strip* strip : {&late_strip(), &dense_strip()}) {
        const StripOptions& o = strip->options;
        const double half_view = o.height_px * o.gsd_mm_per_px / 2;
        EXPECT_DOUBLE_EQ(strip->width_mm, o.width_px * o.gsd_mm_per_px);
        double max_radius = 0;
        for (std::size_t i = 0; i < strip->plants.size(); ++i) {
            const StripPlant& p = strip->plants[i];
            EXPECT_EQ(p.id, static_cast<int>(i));
            if (i > 0) {
                EXPECT_GE(p.s_mm, strip->plants[i - 1].s_mm);
            }
            EXPECT_GE(p.s_mm, strip->lead_mm);
            EXPECT_LT(p.s_mm, strip->lead_mm + o.length_mm);
            EXPECT_GE(p.s_mm - p.radius_mm, half_view + 10);
            EXPECT_LE(std::abs(p.y_mm), strip->width_mm / 2 - kStripEdgeMarginMm);
            for (std::size_t j = 0; j < i; ++j)
                EXPECT_GE(std::hypot(p.s_mm - strip->plants[j].s_mm, p.y_mm - strip->plants[j].y_mm),
                          kStripMinStemSpacingMm);
            max_radius = std::max(max_radius, p.radius_mm);
        }
        // Counts per view-sized block as generate_frame's per frame.
        const double blocks = o.length_mm / strip->view_length_mm;
        int crops = 0;
        for (const StripPlant& p : strip->plants)
            crops += p.kind == PlantClass::Crop;
        if (o.preset == Preset::late) {
            EXPECT_GE(crops, 2 * std::floor(blocks) - 1);
            EXPECT_LE(crops, 4 * std::ceil(blocks));
        } else {
            EXPECT_GT(strip->grass_tufts, 0);
        }
        // The last frame: every leaf has left the view by 10 mm.
        const double last_odom = strip->odom_mm(strip->frame_count - 1);
        for (const StripPlant& p : strip->plants)
            EXPECT_LE(p.s_mm + p.radius_mm + 10, last_odom - half_view + 1e-9);
        EXPECT_LT(strip->odom_mm(strip->frame_count - 2) - half_view, strip->plants.back().s_mm + max_radius + 10);
    }
}

TEST(SynthStrip, FirstAndLastFramesSeeNoPlant)
{
    for (const Strip* strip : {&late_strip(), &dense_strip()}) {
        for (const int k : {0, strip->frame_count - 1}) {
            const StripFrame f = render_strip_frame(*strip, k);
            EXPECT_TRUE(f.stems.empty()) << k;
            EXPECT_EQ(cv::countNonZero(f.mask), 0) << k;
            EXPECT_EQ(cv::countNonZero(f.plant_class), 0) << k;
        }
    }
}

TEST(SynthStrip, ClassMapMatchesKindsAndMask)
{
    for (const Strip* strip : {&late_strip(), &dense_strip()}) {
        cv::Mat vegetation = strip->mask != 0, classed = strip->plant_class != 0;
        EXPECT_EQ(cv::countNonZero(vegetation != classed), 0);
        double lo = 0, hi = 0;
        cv::minMaxLoc(strip->plant_class, &lo, &hi);
        EXPECT_EQ(hi, 2);
        int checked = 0;
        for (int k = 0; k < strip->frame_count; k += 3) {
            const StripFrame f = render_strip_frame(*strip, k);
            for (const GroundTruthStem& s : f.stems) {
                const int value = f.plant_class.at<std::uint8_t>(static_cast<int>(std::lround(s.y_px)),
                                                                  static_cast<int>(std::lround(s.x_px)));
                EXPECT_EQ(value, s.kind == PlantClass::Crop ? 1 : 2) << "frame " << k;
                ++checked;
            }
        }
        EXPECT_GT(checked, 20);
    }
    // Dense grass (no stem) is weed in the class map: more weed pixels than
    // the stemmed weeds' own.
    const Strip& dense = dense_strip();
    long weed_px = cv::countNonZero(dense.plant_class == 2), stemmed_weed_px = 0;
    for (const StripPlant& p : dense.plants)
        if (p.kind == PlantClass::Weed)
            stemmed_weed_px += cv::countNonZero(p.canvas_mask);
    EXPECT_GT(weed_px, stemmed_weed_px);
}

TEST(SynthStrip, RejectsBadOptions)
{
    auto with = [](auto change) {
        StripOptions o = options(Preset::late, 300);
        change(o);
        return o;
    };
    EXPECT_THROW(generate_strip(with([](StripOptions& o) { o.length_mm = 0; })), std::invalid_argument);
    EXPECT_THROW(generate_strip(with([](StripOptions& o) { o.speed_kmh = 0; })), std::invalid_argument);
    EXPECT_THROW(generate_strip(with([](StripOptions& o) { o.fps = -1; })), std::invalid_argument);
    EXPECT_THROW(generate_strip(with([](StripOptions& o) { o.gsd_mm_per_px = 0; })), std::invalid_argument);
    EXPECT_THROW(generate_strip(with([](StripOptions& o) { o.width_px = 8; })), std::invalid_argument);
    EXPECT_THROW(generate_strip(with([](StripOptions& o) { o.length_mm = 200000; })), std::invalid_argument);
}

// The detector finds the stems of the strip's frames as well as those of
// generate_frame's: plants wholly in view, default Params. (The detector's
// recall within 3 mm is ~0.75 on generate_frame's late frames, so "most"
// within 3 mm is >= 0.6 here, and >= 0.8 within eval_accuracy's 5 mm.)
TEST(SynthStrip, DetectorFindsTheStems)
{
    const Strip& strip = late_strip();
    const StripOptions& o = strip.options;
    const vision::Params params;
    vision::Workspace ws({o.width_px, o.height_px}, params);
    auto detections = std::make_unique<vision::Detections>();
    std::vector<eval::StemPoint> truth, predictions;
    auto add = [&](const cv::Mat& bgr, const std::vector<GroundTruthStem>& stems, const std::string& image) {
        vision::detect({.bgr = bgr}, params, ws, *detections);
        ASSERT_EQ(detections->status, vision::DetectStatus::ok);
        for (const GroundTruthStem& s : stems) {
            const double r_px = s.radius_mm / o.gsd_mm_per_px;
            if (s.x_px - r_px >= 0 && s.y_px - r_px >= 0 && s.x_px + r_px <= o.width_px - 1 &&
                s.y_px + r_px <= o.height_px - 1)
                truth.push_back({image, s.x_px, s.y_px});
        }
        for (const auto& p : detections->plants)
            if (p.has_stem)
                predictions.push_back({image, p.stem.x, p.stem.y});
    };
    for (int k = 4; k < strip.frame_count; k += 3) {
        const StripFrame f = render_strip_frame(strip, k);
        add(f.bgr, f.stems, std::to_string(k));
    }
    ASSERT_GT(truth.size(), 30u);
    const eval::MatchResult within_3mm = eval::match_stems(truth, predictions, 3.0, o.gsd_mm_per_px);
    const eval::MatchResult within_5mm = eval::match_stems(truth, predictions, 5.0, o.gsd_mm_per_px);
    EXPECT_GE(within_3mm.recall, 0.6) << within_3mm.true_positives << " of " << within_3mm.ground_truth;
    EXPECT_GE(within_5mm.recall, 0.8) << within_5mm.true_positives << " of " << within_5mm.ground_truth;

    // generate_frame's frames of the same preset and seed, scored alike.
    truth.clear();
    predictions.clear();
    Options frame_options;
    frame_options.seed = o.seed;
    for (int i = 0; i < 8; ++i) {
        const Frame f = generate_frame(frame_options, i);
        add(f.bgr, f.stems, std::to_string(i));
    }
    const eval::MatchResult frames_5mm = eval::match_stems(truth, predictions, 5.0, o.gsd_mm_per_px);
    // ~50 stems on each side: the standard error of a difference of two
    // recalls near 0.9 is ~0.06, so 0.15 (2.5 of them) separates "as
    // detectable" from "worse" without failing on sampling noise.
    EXPECT_GE(within_5mm.recall, frames_5mm.recall - 0.15)
        << within_5mm.true_positives << " of " << within_5mm.ground_truth << " against "
        << frames_5mm.true_positives << " of " << frames_5mm.ground_truth;
}
