#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include <opencv2/imgproc.hpp>

#include "stemd/vision/detect.hpp"
#include "vision_test_util.hpp"

using namespace stemd::vision;

namespace {

struct LeafSpec {
    double angle_deg;
    double petiole_px;      // from the stem to the blade
    double blade_length_px;
    double blade_half_width_px;
};

// A rosette drawn leaf by leaf: a petiole band of constant half width and
// an elliptic blade, both symmetric about the leaf's axis through `stem`.
cv::Mat draw_plant(cv::Size size, cv::Point stem, const std::vector<LeafSpec>& leaves, int petiole_half_width_px)
{
    cv::Mat mask = cv::Mat::zeros(size, CV_8UC1);
    for (const auto& leaf : leaves) {
        const double a = leaf.angle_deg * std::numbers::pi / 180.0;
        const cv::Point2d u(std::cos(a), std::sin(a));
        const cv::Point2d n(-u.y, u.x);
        const double end = leaf.petiole_px + 0.5 * leaf.blade_length_px;
        const double w = petiole_half_width_px;
        std::vector<cv::Point> band;
        for (const cv::Point2d p : {cv::Point2d(stem) + n * w, cv::Point2d(stem) + u * end + n * w,
                                    cv::Point2d(stem) + u * end - n * w, cv::Point2d(stem) - n * w})
            band.emplace_back(cvRound(p.x), cvRound(p.y));
        cv::fillConvexPoly(mask, band, 255, cv::LINE_8);
        const cv::Point2d blade_centre = cv::Point2d(stem) + u * (leaf.petiole_px + 0.5 * leaf.blade_length_px);
        cv::ellipse(mask, cv::RotatedRect(cv::Point2f(blade_centre), cv::Size2f(leaf.blade_length_px, 2 * leaf.blade_half_width_px),
                                          static_cast<float>(leaf.angle_deg)),
                    255, cv::FILLED, cv::LINE_8);
    }
    return mask;
}

Params mask_params()
{
    Params p;
    p.segmentation = Segmentation::mask;
    p.closing_radius_px = 0;
    p.min_plant_area_mm2 = 0;
    return p;
}

double distance(cv::Point2f a, cv::Point2f b) { return std::hypot(a.x - b.x, a.y - b.y); }

void expect_stems_inside_boxes(const Detections& d)
{
    for (const auto& plant : d.plants) {
        EXPECT_GE(plant.stem.x, plant.bbox.x - 0.5f);
        EXPECT_LE(plant.stem.x, plant.bbox.x + plant.bbox.width - 0.5f);
        EXPECT_GE(plant.stem.y, plant.bbox.y - 0.5f);
        EXPECT_LE(plant.stem.y, plant.bbox.y + plant.bbox.height - 0.5f);
    }
}

}  // namespace

TEST(Detect, SymmetricFourLeafPlantHasItsStemAtTheCentre)
{
    const cv::Point stem(200, 150);
    const cv::Mat mask = draw_plant({400, 300}, stem,
                                    {{0, 20, 60, 16}, {90, 20, 60, 16}, {180, 20, 60, 16}, {270, 20, 60, 16}}, 4);
    const Detections d = detect({.mask = mask}, mask_params());
    ASSERT_EQ(d.status, DetectStatus::ok);
    ASSERT_EQ(d.plants.size(), 1u);
    const Plant& p = d.plants[0];
    EXPECT_EQ(p.method, StemMethod::leaves);
    EXPECT_EQ(p.leaves.size(), 4u);
    EXPECT_LT(distance(p.stem, cv::Point2f(stem)), 0.5) << p.stem;
}

TEST(Detect, AsymmetricThreeLeafPlantIsRecoveredWhereTheCentreOfMassFails)
{
    const cv::Point stem(250, 200);
    const cv::Mat mask =
        draw_plant({500, 400}, stem, {{0, 25, 120, 28}, {100, 15, 40, 12}, {230, 15, 50, 14}}, 4);
    const Detections d = detect({.mask = mask}, mask_params());
    ASSERT_EQ(d.plants.size(), 1u);
    const Plant& p = d.plants[0];
    ASSERT_EQ(p.leaves.size(), 3u);
    EXPECT_EQ(p.method, StemMethod::leaves);
    EXPECT_GT(distance(p.centre_of_mass, cv::Point2f(stem)), 20.0) << "the test needs an off-centre mass";
    EXPECT_LT(distance(p.stem, cv::Point2f(stem)), 1.0) << p.stem;
}

TEST(Detect, ComMethodReportsTheCentreOfMass)
{
    const cv::Mat mask = draw_plant({400, 300}, {200, 150}, {{0, 20, 60, 16}, {120, 20, 30, 10}, {240, 20, 40, 12}}, 4);
    Params params = mask_params();
    params.stem_estimator = StemEstimator::com;
    const Detections d = detect({.mask = mask}, params);
    ASSERT_EQ(d.plants.size(), 1u);
    EXPECT_EQ(d.plants[0].method, StemMethod::com);
    EXPECT_EQ(d.plants[0].com_reason, ComReason::method_com);
    const cv::Moments m = cv::moments(mask, true);
    EXPECT_NEAR(d.plants[0].stem.x, m.m10 / m.m00, 1e-3);
    EXPECT_NEAR(d.plants[0].stem.y, m.m01 / m.m00, 1e-3);
    EXPECT_EQ(d.plants[0].area_px, cv::countNonZero(mask));
}

// Grass: thin blades fanned out from one base leave most of the convex hull
// empty; a weed rosette with thin leaf stalks is as thin on average
// (2 area / perimeter) but fills much more of its hull.
TEST(Detect, GrassTuftIsStemlessButAThinStalkedRosetteIsNot)
{
    cv::Mat tuft = cv::Mat::zeros(300, 300, CV_8UC1);
    const cv::Point2d base(150, 220);
    for (int i = 0; i < 7; ++i) {
        const double a = (-90 + 22 * (i - 3)) * std::numbers::pi / 180.0;
        const cv::Point2d u(std::cos(a), std::sin(a)), n(-u.y, u.x);
        const double length = 120 + 10 * (i % 3), half_width = 3;  // ~40 mm long, 2 mm wide at 0.33 mm/px
        std::vector<cv::Point> blade;
        for (const cv::Point2d p : {base + n * half_width, base + u * length, base - n * half_width})
            blade.emplace_back(cvRound(p.x), cvRound(p.y));
        cv::fillConvexPoly(tuft, blade, 255, cv::LINE_8);
    }
    const cv::Mat rosette =
        draw_plant({300, 300}, {150, 150}, {{0, 6, 26, 6}, {90, 6, 24, 6}, {180, 6, 26, 6}, {270, 6, 24, 6}}, 1);
    const Params params = mask_params();
    const Detections grass = detect({.mask = tuft}, params);
    const Detections weed = detect({.mask = rosette}, params);
    ASSERT_EQ(grass.plants.size(), 1u);
    ASSERT_EQ(weed.plants.size(), 1u);
    const Plant& g = grass.plants[0];
    const Plant& w = weed.plants[0];
    const double px_mm2 = params.gsd_mm_per_px * params.gsd_mm_per_px;
    // Both are large and thin enough for the width test alone.
    for (const Plant* p : {&g, &w}) {
        EXPECT_GE(p->area_px * px_mm2, params.grass_min_area_mm2);
        EXPECT_LT(p->mean_width_mm, params.grass_max_width_mm);
    }
    EXPECT_LT(g.hull_fill, params.grass_max_hull_fill);
    EXPECT_GT(w.hull_fill, params.grass_max_hull_fill);
    EXPECT_FALSE(g.has_stem);
    EXPECT_EQ(g.confidence, 0.0f);
    EXPECT_TRUE(w.has_stem);
    EXPECT_EQ(grass.stats.stemless, 1);
    EXPECT_EQ(weed.stats.stemless, 0);

    // With the width test alone (the rule before hull_fill) the rosette was grass too.
    Params width_only = params;
    width_only.grass_max_hull_fill = 1.5;
    EXPECT_FALSE(detect({.mask = rosette}, width_only).plants[0].has_stem);
}

TEST(Detect, EmptyFrameHasNoPlants)
{
    const cv::Mat mask = cv::Mat::zeros(120, 160, CV_8UC1);
    const Detections d = detect({.mask = mask}, mask_params());
    EXPECT_EQ(d.status, DetectStatus::ok);
    EXPECT_TRUE(d.plants.empty());
}

TEST(Detect, AllVegetationIsOnePlantWithAStemInside)
{
    const cv::Mat mask(120, 160, CV_8UC1, cv::Scalar(255));
    Params params = mask_params();
    params.closing_radius_px = 10;
    const Detections d = detect({.mask = mask}, params);
    ASSERT_EQ(d.plants.size(), 1u);
    EXPECT_EQ(d.plants[0].area_px, 120 * 160);
    expect_stems_inside_boxes(d);
}

TEST(Detect, OnePixelPlants)
{
    cv::Mat mask = cv::Mat::zeros(50, 50, CV_8UC1);
    mask.at<std::uint8_t>(10, 10) = 255;
    mask.at<std::uint8_t>(0, 49) = 255;
    mask.at<std::uint8_t>(49, 0) = 255;
    const Detections d = detect({.mask = mask}, mask_params());
    ASSERT_EQ(d.plants.size(), 3u);
    EXPECT_EQ(d.plants[0].stem, cv::Point2f(49, 0));
    EXPECT_EQ(d.plants[1].stem, cv::Point2f(10, 10));
    for (const auto& p : d.plants)
        EXPECT_EQ(p.com_reason, ComReason::too_few_leaves);
}

TEST(Detect, MinimumAreaIsInSquareMillimetres)
{
    cv::Mat mask = cv::Mat::zeros(100, 100, CV_8UC1);
    mask(cv::Rect(10, 10, 10, 10)).setTo(255);  // 100 px = 10.89 mm2 at 0.33 mm/px
    mask(cv::Rect(50, 50, 9, 9)).setTo(255);    // 81 px = 8.82 mm2
    Params params = mask_params();
    params.min_plant_area_mm2 = 10.0;
    const Detections d = detect({.mask = mask}, params);
    ASSERT_EQ(d.plants.size(), 1u);
    EXPECT_EQ(d.plants[0].area_px, 100);
    EXPECT_EQ(d.stats.small_components, 1);
}

TEST(Detect, PlantTouchingTheBorder)
{
    const cv::Mat mask = draw_plant({300, 200}, {5, 100}, {{0, 20, 60, 16}, {90, 20, 60, 16}, {180, 20, 60, 16}, {270, 20, 60, 16}}, 4);
    const Detections d = detect({.mask = mask}, mask_params());
    ASSERT_EQ(d.plants.size(), 1u);
    EXPECT_EQ(d.plants[0].bbox.x, 0);
    expect_stems_inside_boxes(d);
}

TEST(Detect, PlantWithAHoleIsOnePlant)
{
    cv::Mat mask = cv::Mat::zeros(200, 200, CV_8UC1);
    cv::circle(mask, {100, 100}, 60, 255, cv::FILLED);
    cv::circle(mask, {100, 100}, 20, 0, cv::FILLED);
    const Detections d = detect({.mask = mask}, mask_params());
    ASSERT_EQ(d.plants.size(), 1u);
    EXPECT_EQ(d.plants[0].area_px, cv::countNonZero(mask));
}

TEST(Detect, SpiralDoesNotBreakAnything)
{
    cv::Mat mask = cv::Mat::zeros(300, 300, CV_8UC1);
    std::vector<cv::Point> spiral;
    for (double t = 0; t < 6 * std::numbers::pi; t += 0.02)
        spiral.emplace_back(cvRound(150 + 6 * t * std::cos(t)), cvRound(150 + 6 * t * std::sin(t)));
    cv::polylines(mask, spiral, false, 255, 3);
    Params params = mask_params();
    params.min_leaves = 2;
    const Detections d = detect({.mask = mask}, params);
    ASSERT_EQ(d.plants.size(), 1u);
    expect_stems_inside_boxes(d);
}

TEST(Detect, BadFramesAreRejectedNotCrashedOn)
{
    Params params;
    Workspace ws({64, 48}, params);
    Detections d;
    detect({}, params, ws, d);
    EXPECT_EQ(d.status, DetectStatus::empty_frame);
    detect({.bgr = cv::Mat(48, 64, CV_8UC1)}, params, ws, d);
    EXPECT_EQ(d.status, DetectStatus::bad_format);
    detect({.bgr = cv::Mat(40, 64, CV_8UC3)}, params, ws, d);
    EXPECT_EQ(d.status, DetectStatus::size_mismatch);
    params.segmentation = Segmentation::ndvi;
    detect({.bgr = cv::Mat(48, 64, CV_8UC3, cv::Scalar::all(0))}, params, ws, d);
    EXPECT_EQ(d.status, DetectStatus::missing_nir);
    params.segmentation = Segmentation::mask;
    detect({.bgr = cv::Mat(48, 64, CV_8UC3)}, params, ws, d);
    EXPECT_EQ(d.status, DetectStatus::missing_mask);
    EXPECT_TRUE(d.plants.empty());
}

TEST(Detect, ExcessGreenFindsAGreenPlantOnSoil)
{
    cv::Mat bgr(300, 400, CV_8UC3, cv::Scalar(60, 80, 110));  // brownish soil
    cv::RNG rng(3);
    cv::Mat noise(bgr.size(), CV_8UC3);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 20);
    bgr += noise;
    const cv::Point stem(200, 150);
    const cv::Mat plant = draw_plant(bgr.size(), stem, {{10, 20, 70, 18}, {100, 20, 60, 16}, {200, 20, 70, 18}, {290, 20, 50, 16}}, 4);
    bgr.setTo(cv::Scalar(40, 150, 50), plant);
    Params params;
    params.closing_radius_px = 2;
    const Detections d = detect({.bgr = bgr}, params);
    ASSERT_EQ(d.status, DetectStatus::ok);
    ASSERT_EQ(d.plants.size(), 1u);
    EXPECT_EQ(d.plants[0].method, StemMethod::leaves);
    EXPECT_LT(distance(d.plants[0].stem, cv::Point2f(stem)), 1.5);
    EXPECT_GT(d.stats.threshold, 128);
}

namespace {

// Brownish soil with uniform noise: one mode in Excess Green.
cv::Mat soil_frame(cv::Size size, std::uint64_t seed)
{
    cv::Mat bgr(size, CV_8UC3, cv::Scalar(60, 80, 110));
    cv::RNG rng(seed);
    cv::Mat noise(bgr.size(), CV_8UC3);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 20);
    return bgr + noise;
}

}  // namespace

TEST(Detect, AColourFringeAlongABrightStrawIsNoPlant)
{
    // A bright straw on bare soil, the green plane then slid one pixel
    // right (lateral chromatic aberration, Bayer interpolation) and the
    // frame blurred as by the lens: the straw's right edge becomes a band a
    // few pixels wide, green in chromatic ExG and for its red, with a core
    // the opening keeps. Without the fringe test it is a plant.
    cv::Mat bgr = soil_frame({400, 300}, 5);
    cv::Mat straw = cv::Mat::zeros(bgr.size(), CV_8UC1);
    cv::line(straw, {60, 60}, {140, 240}, 255, 9);
    bgr.setTo(cv::Scalar(170, 200, 215), straw);
    stemd::test::slide_green_plane_right(bgr);
    cv::GaussianBlur(bgr, bgr, {5, 5}, 0.8);
    Params params;
    params.gsd_mm_per_px = 0.395;
    const Detections d = detect({.bgr = bgr}, params);
    ASSERT_EQ(d.status, DetectStatus::ok);
    EXPECT_EQ(d.plants.size(), 0u) << "the straw's fringe must not be a plant";
    EXPECT_GE(d.stats.colour_fringes, 1);
    // A leaf on the same soil keeps its green whichever way the plane slides.
    const cv::Point stem(290, 150);
    const cv::Mat plant = draw_plant(bgr.size(), stem, {{10, 20, 70, 18}, {100, 20, 60, 16}, {200, 20, 70, 18}, {290, 20, 50, 16}}, 4);
    bgr.setTo(cv::Scalar(40, 150, 50), plant);
    const Detections with_plant = detect({.bgr = bgr}, params);
    ASSERT_EQ(with_plant.plants.size(), 1u);
    EXPECT_LT(distance(with_plant.plants[0].stem, cv::Point2f(stem)), 1.5);
}

TEST(Detect, BareSoilHasNoPlantsWithEveryAutomaticThreshold)
{
    const cv::Mat bgr = soil_frame({400, 300}, 3);
    for (const ThresholdMethod m : {ThresholdMethod::otsu, ThresholdMethod::triangle, ThresholdMethod::min_error}) {
        SCOPED_TRACE(std::string(to_string(m)));
        // The plain index without smoothing or opening, where the split
        // soil reaches the mask.
        Params params;
        params.segmentation = Segmentation::exg;
        params.smooth_index = false;
        params.opening_radius_px = 0;
        params.threshold = m;
        Detections d = detect({.bgr = bgr}, params);
        ASSERT_EQ(d.status, DetectStatus::ok);
        EXPECT_TRUE(d.plants.empty());
        EXPECT_TRUE(d.stats.no_vegetation);
        EXPECT_LT(d.stats.class_separation, params.min_class_separation);
        EXPECT_EQ(d.stats.vegetation_px, 0);
        EXPECT_EQ(d.stats.components, 0);
        EXPECT_GE(d.stats.threshold, 0);  // still reported
        // Without the check the soil is split; Otsu cuts it in the middle
        // and the closing makes a phantom plant of it (the leaf colour test,
        // another guard, is off to show this one alone).
        params.min_class_separation = 0;
        params.leaf_colour = false;
        d = detect({.bgr = bgr}, params);
        EXPECT_FALSE(d.stats.no_vegetation);
        EXPECT_GT(d.stats.vegetation_px, 0);
        if (m == ThresholdMethod::otsu) {
            EXPECT_FALSE(d.plants.empty());
        }
    }
}

TEST(Detect, BareSoilHasNoPlantsWithTheDefaultsEvenWithoutTheSeparationCheck)
{
    // The default threshold stays above the soil's own spread, so the
    // separation check is a second line, not the only one.
    for (const std::uint64_t seed : {3u, 4u, 5u}) {
        const cv::Mat bgr = soil_frame({400, 300}, seed);
        Params params;
        params.min_class_separation = 0;
        const Detections d = detect({.bgr = bgr}, params);
        ASSERT_EQ(d.status, DetectStatus::ok);
        EXPECT_TRUE(d.plants.empty()) << "seed " << seed;
        EXPECT_LT(d.stats.vegetation_px, 10) << "seed " << seed;
    }
}

TEST(Detect, SeparationCheckLeavesAFrameWithPlantsUnchanged)
{
    cv::Mat bgr = soil_frame({400, 300}, 3);
    const cv::Point stem(200, 150);
    const cv::Mat plant = draw_plant(bgr.size(), stem, {{10, 20, 70, 18}, {100, 20, 60, 16}, {200, 20, 70, 18}, {290, 20, 50, 16}}, 4);
    bgr.setTo(cv::Scalar(40, 150, 50), plant);
    // A small second plant: a frame mostly soil still has two classes.
    cv::circle(bgr, {60, 60}, 12, cv::Scalar(40, 150, 50), cv::FILLED);
    for (const ThresholdMethod m : {ThresholdMethod::otsu, ThresholdMethod::triangle, ThresholdMethod::min_error}) {
        SCOPED_TRACE(std::string(to_string(m)));
        Params params;
        params.threshold = m;
        params.closing_radius_px = 2;
        const Detections with = detect({.bgr = bgr}, params);
        params.min_class_separation = 0;
        const Detections without = detect({.bgr = bgr}, params);
        ASSERT_EQ(with.status, DetectStatus::ok);
        EXPECT_FALSE(with.stats.no_vegetation);
        EXPECT_GT(with.stats.class_separation, 3 * Params{}.min_class_separation);
        EXPECT_EQ(with.stats.threshold, without.stats.threshold);
        EXPECT_EQ(with.stats.vegetation_px, without.stats.vegetation_px);
        ASSERT_EQ(with.plants.size(), 2u);
        ASSERT_EQ(with.plants.size(), without.plants.size());
        for (std::size_t i = 0; i < with.plants.size(); ++i) {
            EXPECT_EQ(with.plants[i].area_px, without.plants[i].area_px);
            EXPECT_EQ(with.plants[i].stem, without.plants[i].stem);
        }
    }
}

TEST(Detect, AFrameMostlyCoveredByLeavesKeepsItsLeaves)
{
    // Leaves drawn over half to 95 % of a soil frame. Above about three
    // quarters, the leaves' level is the histogram's mode; taken for the
    // soil's, it put the threshold above the leaves and the mask was empty.
    for (const double target_cover : {0.5, 0.8, 0.9, 0.95}) {
        SCOPED_TRACE(target_cover);
        cv::Mat bgr = soil_frame({400, 300}, 7);
        cv::Mat leaves = cv::Mat::zeros(bgr.size(), CV_8UC1);
        cv::RNG rng(11);
        while (cv::countNonZero(leaves) < target_cover * leaves.total()) {
            const cv::Point2f centre(rng.uniform(0.f, 400.f), rng.uniform(0.f, 300.f));
            cv::ellipse(leaves, cv::RotatedRect(centre, cv::Size2f(rng.uniform(20.f, 60.f), rng.uniform(8.f, 20.f)),
                                                rng.uniform(0.f, 180.f)),
                        255, cv::FILLED);
        }
        cv::Mat leaf_colour(bgr.size(), CV_8UC3, cv::Scalar(40, 150, 50));
        cv::Mat noise(bgr.size(), CV_8UC3);
        rng.fill(noise, cv::RNG::UNIFORM, 0, 20);
        leaf_colour += noise;
        leaf_colour.copyTo(bgr, leaves);
        // NIR: soil a little brighter than in red (NDVI about 0.1), leaves
        // far brighter (about 0.6).
        cv::Mat nir(bgr.size(), CV_8UC1);
        rng.fill(nir, cv::RNG::UNIFORM, 130, 150);
        cv::Mat leaf_nir(bgr.size(), CV_8UC1);
        rng.fill(leaf_nir, cv::RNG::UNIFORM, 180, 220);
        leaf_nir.copyTo(nir, leaves);
        for (const Segmentation method : {Segmentation::chromatic_exg, Segmentation::exg_and_ndvi}) {
            SCOPED_TRACE(std::string(to_string(method)));
            Params params;
            params.segmentation = method;
            params.closing_radius_px = 0;
            Workspace ws(bgr.size(), params);
            Detections d;
            detect({.bgr = bgr, .nir = method == Segmentation::exg_and_ndvi ? nir : cv::Mat()}, params, ws, d);
            ASSERT_EQ(d.status, DetectStatus::ok);
            EXPECT_FALSE(d.stats.no_vegetation);
            cv::Mat found;
            unpack_mask(ws.vegetation(), found);
            const double overlap = cv::countNonZero(found & leaves);
            const double either = cv::countNonZero(found | leaves);
            EXPECT_GT(overlap / either, 0.97) << "vegetation found " << cv::countNonZero(found) << " px of "
                                              << cv::countNonZero(leaves);
            EXPECT_FALSE(d.plants.empty());
        }
    }
}

TEST(Detect, ExternalMasksAreNeverVegetationFree)
{
    const Detections d = detect({.mask = cv::Mat(48, 64, CV_8UC1, cv::Scalar(0))}, mask_params());
    EXPECT_FALSE(d.stats.no_vegetation);
    EXPECT_EQ(d.stats.class_separation, 0.0f);
}

TEST(Detect, NdviFindsThePlantFromTheNirImage)
{
    cv::Mat bgr(200, 200, CV_8UC3, cv::Scalar(80, 80, 90));
    cv::Mat nir(200, 200, CV_8UC1, cv::Scalar(85));
    cv::circle(nir, {100, 100}, 30, 220, cv::FILLED);
    const Detections d = detect({.bgr = bgr, .nir = nir}, Params{.segmentation = Segmentation::ndvi});
    ASSERT_EQ(d.status, DetectStatus::ok);
    ASSERT_EQ(d.plants.size(), 1u);
    EXPECT_NEAR(d.plants[0].centre_of_mass.x, 100, 0.5);
    EXPECT_NEAR(d.plants[0].area_px, 2821, 60);  // about pi * 30^2
}

// A leaf is green and bright in NIR; a greenish clod is green but dark in
// NIR; dead straw is bright in NIR but no greener than the soil. Each index
// alone takes one impostor for a plant, the two together take neither.
TEST(Detect, ExgAndNdviNeedBothSignaturesOfALeaf)
{
    cv::Mat bgr(240, 360, CV_8UC3, cv::Scalar(60, 70, 90));   // brown soil ...
    cv::Mat nir(240, 360, CV_8UC1, cv::Scalar(90));
    cv::Mat noise(bgr.size(), CV_8UC3);
    cv::RNG rng(7);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 6);                   // ... with some texture
    bgr += noise;
    cv::circle(bgr, {60, 120}, 25, cv::Scalar(40, 150, 60), cv::FILLED);   // leaf: green ...
    cv::circle(nir, {60, 120}, 25, 230, cv::FILLED);                        // ... and bright in NIR
    cv::circle(bgr, {180, 120}, 25, cv::Scalar(50, 140, 90), cv::FILLED);  // clod: greenish, NIR as soil
    cv::circle(bgr, {300, 120}, 25, cv::Scalar(80, 85, 110), cv::FILLED);  // straw: pale, less green than soil ...
    cv::circle(nir, {300, 120}, 25, 230, cv::FILLED);                       // ... bright in NIR
    const auto centres = [&](Segmentation method) {
        std::vector<int> xs;
        for (const Plant& p : detect({.bgr = bgr, .nir = nir}, Params{.segmentation = method}).plants)
            xs.push_back(static_cast<int>(std::lround(p.centre_of_mass.x)));
        return xs;
    };
    EXPECT_EQ(centres(Segmentation::chromatic_exg), (std::vector<int>{60, 180}));
    EXPECT_EQ(centres(Segmentation::ndvi), (std::vector<int>{60, 300}));
    EXPECT_EQ(centres(Segmentation::exg_and_ndvi), (std::vector<int>{60}));

    // auto (the default) reads the frame's planes: with NIR it needs both
    // signatures, from RGB alone it is chromatic Excess Green.
    ASSERT_EQ(Params{}.segmentation, Segmentation::automatic);
    EXPECT_EQ(centres(Segmentation::automatic), (std::vector<int>{60}));
    std::vector<int> rgb_only;
    for (const Plant& p : detect({.bgr = bgr}, Params{.segmentation = Segmentation::automatic}).plants)
        rgb_only.push_back(static_cast<int>(std::lround(p.centre_of_mass.x)));
    EXPECT_EQ(rgb_only, (std::vector<int>{60, 180}));
}

TEST(Detect, AutoSegmentationResolvesFromTheNirPlane)
{
    EXPECT_EQ(resolve_segmentation(Segmentation::automatic, true), Segmentation::exg_and_ndvi);
    EXPECT_EQ(resolve_segmentation(Segmentation::automatic, false), Segmentation::chromatic_exg);
    for (const Segmentation s : {Segmentation::exg, Segmentation::chromatic_exg, Segmentation::ndvi,
                                 Segmentation::mask, Segmentation::exg_and_ndvi})
        for (const bool nir : {false, true})
            EXPECT_EQ(resolve_segmentation(s, nir), s) << to_string(s);
    EXPECT_EQ(parse_segmentation("auto"), Segmentation::automatic);
    EXPECT_EQ(to_string(Segmentation::automatic), "auto");
}

// A yellow clod is as green as a leaf in Excess Green (2G - R - B) but has
// less green for its red than the soil (G/R 0.78 here); chlorophyll leaves
// have far more.
TEST(Detect, LeafColourTellsALeafFromAYellowClod)
{
    cv::Mat bgr(240, 240, CV_8UC3, cv::Scalar(60, 70, 90));   // brown soil
    cv::Mat noise(bgr.size(), CV_8UC3);
    cv::RNG rng(11);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 6);
    bgr += noise;
    cv::circle(bgr, {60, 120}, 25, cv::Scalar(40, 150, 60), cv::FILLED);    // leaf: G > R
    cv::circle(bgr, {180, 120}, 25, cv::Scalar(10, 150, 165), cv::FILLED);  // clod: ExG as high, G < R
    for (const Segmentation method : {Segmentation::exg, Segmentation::chromatic_exg}) {
        SCOPED_TRACE(std::string(to_string(method)));
        Params params{.segmentation = method};
        const auto centres = [&] {
            std::vector<int> xs;
            for (const Plant& p : detect({.bgr = bgr}, params).plants)
                xs.push_back(static_cast<int>(std::lround(p.centre_of_mass.x)));
            return xs;
        };
        EXPECT_EQ(centres(), (std::vector<int>{60}));
        params.leaf_colour = false;
        EXPECT_EQ(centres(), (std::vector<int>{60, 180}));
    }
}

TEST(Detect, RandomMasksNeverThrowAndStemsStayInTheirBoxes)
{
    Params params;
    params.segmentation = Segmentation::mask;
    params.min_plant_area_mm2 = 0;
    params.min_leaves = 2;
    params.defect_depth_mm = 0.5;
    Workspace ws({257, 130}, params);
    Detections d;
    int outside_box = 0;
    for (std::uint64_t seed = 1; seed <= 150; ++seed) {
        params.closing_radius_px = static_cast<int>(seed % 12);
        params.stem_estimator = seed % 2 ? StemEstimator::paper : StemEstimator::robust;
        const cv::Mat mask = stemd::test::random_blob_mask({257, 130}, seed, 30, (seed % 4) * 0.02);
        ASSERT_NO_THROW(detect({.mask = mask}, params, ws, d));
        ASSERT_EQ(d.status, DetectStatus::ok);
        expect_stems_inside_boxes(d);
        int counted = 0;
        for (const auto& p : d.plants) {
            EXPECT_EQ(p.method == StemMethod::leaves, p.com_reason == ComReason::none);
            EXPECT_LE(p.leaves.size(), kMaxLeaves);
            counted += p.com_reason == ComReason::outside_box;
        }
        EXPECT_EQ(d.stats.outside_box_fallbacks, counted);
        outside_box += counted;
    }
    // Random shapes do produce paper estimates outside the plant: the fallback is exercised.
    EXPECT_GT(outside_box, 0);
}

TEST(Detect, ReusedWorkspaceGivesTheSameResult)
{
    const cv::Mat a = stemd::test::random_blob_mask({200, 100}, 11, 20, 0.0);
    const cv::Mat b = stemd::test::random_blob_mask({200, 100}, 12, 20, 0.0);
    Params params = mask_params();
    params.closing_radius_px = 4;
    Workspace ws({200, 100}, params);
    Detections first, again;
    detect({.mask = a}, params, ws, first);
    detect({.mask = b}, params, ws, again);
    detect({.mask = a}, params, ws, again);
    ASSERT_EQ(first.plants.size(), again.plants.size());
    for (std::size_t i = 0; i < first.plants.size(); ++i)
        EXPECT_EQ(first.plants[i].stem, again.plants[i].stem);
}

TEST(Detect, LeavesCutOffFromTheirStemAreOnePlant)
{
    // A five-leaf rosette whose petioles and centre fell below the
    // threshold: a hole of radius 14 px leaves five pieces, neighbours
    // 2 * 14 * sin(36 deg) = 16.5 px (5.4 mm) apart at their inner ends.
    const cv::Point stem(200, 150);
    cv::Mat mask = draw_plant(
        {400, 300}, stem, {{10, 20, 60, 16}, {82, 20, 60, 16}, {154, 20, 60, 16}, {226, 20, 60, 16}, {298, 20, 60, 16}}, 4);
    cv::circle(mask, stem, 14, 0, cv::FILLED);
    Params params = mask_params();
    params.group_gap_mm = 0;
    EXPECT_EQ(detect({.mask = mask}, params).plants.size(), 5u);

    params.group_gap_mm = 6;
    const Detections d = detect({.mask = mask}, params);
    ASSERT_EQ(d.plants.size(), 1u);
    EXPECT_EQ(d.stats.components, 5);
    const Plant& p = d.plants[0];
    EXPECT_EQ(p.area_px, cv::countNonZero(mask));
    EXPECT_EQ(p.leaves.size(), 5u);
    EXPECT_EQ(p.method, StemMethod::leaves);
    // Each piece's long axis points at the stem.
    EXPECT_LT(distance(p.stem, cv::Point2f(stem)), 1.0) << p.stem;
}

// A leaf on its own, as a threshold leaves it when its petiole is too
// thin or pale: an ellipse whose long axis runs along `angle_deg`.
void draw_leaf(cv::Mat& mask, cv::Point2f centre, double angle_deg, double length_px, double half_width_px)
{
    cv::ellipse(mask, cv::RotatedRect(centre, cv::Size2f(static_cast<float>(length_px), static_cast<float>(2 * half_width_px)),
                                      static_cast<float>(angle_deg)),
                255, cv::FILLED, cv::LINE_8);
}

const std::vector<LeafSpec> kFourLeaves{{0, 20, 60, 16}, {90, 20, 60, 16}, {180, 20, 60, 16}, {270, 20, 60, 16}};

TEST(Detect, ADetachedLeafFartherThanTheGroupGapStaysApart)
{
    // A four-leaf plant whose right leaf ends at x = 180, and a leaf on its
    // own pointing at its stem, 40 background pixels (13.2 mm at
    // 0.33 mm/px) beyond. Grouping works on 4 px cells: pieces within the
    // gap always join, pieces up to about 8 px farther may.
    const cv::Point stem(100, 150);
    cv::Mat mask = draw_plant({400, 300}, stem, kFourLeaves, 4);
    draw_leaf(mask, {251, 150}, 0, 60, 16);  // from x = 221
    Params params = mask_params();
    params.group_gap_mm = 10;  // 30 px: more than 8 px short of the 40
    const Detections apart = detect({.mask = mask}, params);
    ASSERT_EQ(apart.plants.size(), 2u);
    EXPECT_LT(distance(apart.plants[0].stem, cv::Point2f(stem)), 0.5);
    params.group_gap_mm = 13.5;  // at least the 13.2 mm between them
    const Detections joined = detect({.mask = mask}, params);
    ASSERT_EQ(joined.plants.size(), 1u);
    EXPECT_EQ(joined.plants[0].area_px, cv::countNonZero(mask));
    EXPECT_LT(distance(joined.plants[0].stem, cv::Point2f(stem)), 1.0) << joined.plants[0].stem;
}

TEST(Detect, NeighboursWithinTheGroupGapAreApartWhenEachHasItsOwnStem)
{
    // Two four-leaf plants whose leaf tips are 39 px apart, well within a
    // 13 mm (39.4 px) gap, each with a stem where its leaves meet.
    const cv::Point left(100, 150), right(300, 150);
    cv::Mat mask = draw_plant({400, 300}, left, kFourLeaves, 4);
    mask |= draw_plant({400, 300}, right, kFourLeaves, 4);
    Params params = mask_params();
    params.group_gap_mm = 13;
    const Detections d = detect({.mask = mask}, params);
    ASSERT_EQ(d.plants.size(), 2u);
    EXPECT_LT(distance(d.plants[0].stem, cv::Point2f(left)), 0.5);
    EXPECT_LT(distance(d.plants[1].stem, cv::Point2f(right)), 0.5);
}

TEST(Detect, ADetachedLeafJoinsThePlantItPointsAtAndNotANeighbour)
{
    // Between two four-leaf plants, 10 px below the right one's lower
    // leaf: a leaf pointing up at the right plant's stem (it joins it), and
    // beside the left plant's lower leaf a round seedling with no cuts and
    // no long axis (a plant of its own).
    const cv::Point left(100, 120), right(300, 120);
    cv::Mat mask = draw_plant({400, 300}, left, kFourLeaves, 4);
    mask |= draw_plant({400, 300}, right, kFourLeaves, 4);
    draw_leaf(mask, {300, 240}, 90, 60, 14);             // 200..210: from y = 210, 10 px below the leaf tip at 200
    cv::circle(mask, {140, 185}, 12, 255, cv::FILLED);  // 10 px right of the lower leaf's edge
    Params params = mask_params();
    params.group_gap_mm = 13;
    const Detections d = detect({.mask = mask}, params);
    ASSERT_EQ(d.plants.size(), 3u);
    EXPECT_LT(distance(d.plants[0].stem, cv::Point2f(left)), 0.5);
    EXPECT_LT(distance(d.plants[1].stem, cv::Point2f(right)), 1.0) << d.plants[1].stem;
    EXPECT_LT(distance(d.plants[2].stem, {140, 185}), 0.5) << d.plants[2].stem;
    EXPECT_EQ(d.plants[1].area_px, cv::countNonZero(draw_plant({400, 300}, right, kFourLeaves, 4)) +
                                       [] {
                                           cv::Mat leaf = cv::Mat::zeros(300, 400, CV_8UC1);
                                           draw_leaf(leaf, {300, 240}, 90, 60, 14);
                                           return cv::countNonZero(leaf);
                                       }());
}
