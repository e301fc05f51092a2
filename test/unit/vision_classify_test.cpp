// The crop/weed classifier: per-plant features on detect()'s plants, the
// forest's weed probability, the class decision, model files and their
// refusal.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include <sys/stat.h>

#include <opencv2/imgproc.hpp>

#include "stemd/vision/classify.hpp"
#include "stemd/vision/index.hpp"
#include "vision_classify_test_util.hpp"
#include "vision_test_util.hpp"

namespace fs = std::filesystem;
using namespace stemd;
using namespace stemd::vision;

namespace {

// Green plants on brown soil: discs (round, "crop") and thin lines
// ("weed"), some of them drawn as pieces a few pixels apart that detect()
// groups into one plant.
cv::Mat plants_frame(cv::Size size, std::uint64_t seed)
{
    cv::Mat bgr(size, CV_8UC3, cv::Scalar(60, 80, 110));
    cv::RNG rng(seed);
    for (int i = 0; i < 12; ++i) {
        const cv::Point c(rng.uniform(30, size.width - 30), rng.uniform(30, size.height - 30));
        cv::circle(bgr, c, rng.uniform(8, 18), cv::Scalar(40, 170, 60), cv::FILLED);
        // A leaf drawn apart from its disc: one plant once grouped.
        cv::circle(bgr, c + cv::Point(22, 0), 4, cv::Scalar(40, 170, 60), cv::FILLED);
    }
    for (int i = 0; i < 12; ++i) {
        const cv::Point c(rng.uniform(30, size.width - 30), rng.uniform(30, size.height - 30));
        cv::line(bgr, c, c + cv::Point(rng.uniform(-25, 25), rng.uniform(-25, 25)), cv::Scalar(50, 150, 90), 3);
    }
    return bgr;
}

Params test_params() { return test::classify_test_params(); }

// detect() then plant_features() on one frame; the workspaces stay for the checks.
struct Classified {
    Classified(const cv::Mat& bgr, const Params& params, const cv::Mat& nir = {})
        : ws(bgr.size(), params), cws(bgr.size(), params)
    {
        detect({.bgr = bgr, .nir = nir}, params, ws, det);
        plant_features({.bgr = bgr, .nir = nir}, params, ws, det, cws);
    }
    Workspace ws;
    Detections det;
    ClassifyWorkspace cws;
};

// Two separable clouds of feature rows: crop with large area, weed small.
void toy_data(int rows, std::uint32_t seed, cv::Mat& samples, cv::Mat& labels)
{
    std::mt19937 rng(seed);
    std::normal_distribution<float> noise(0, 0.15f);
    samples.create(rows, kPlantFeatureCount, CV_32FC1);
    labels.create(rows, 1, CV_32SC1);
    for (int i = 0; i < rows; ++i) {
        const bool weed = i % 3 == 0;   // unbalanced on purpose
        for (int f = 0; f < kPlantFeatureCount; ++f)
            samples.at<float>(i, f) = noise(rng);
        samples.at<float>(i, f_log_area_mm2) += weed ? 1.0f : 2.5f;
        samples.at<float>(i, f_g_mean) += weed ? 0.4f : 0.5f;
        labels.at<int>(i) = weed ? to_value(PlantClass::Weed) : to_value(PlantClass::Crop);
    }
}

fs::path temp_path(const std::string& name) { return test::classify_temp_path("stemd-classify", name); }

// Rows of four greens, one per row modulo 4 from the plant's top row:
// which rows the colour features read shows in their mean.
cv::Mat striped_plant(cv::Size size, cv::Rect plant)
{
    static const cv::Scalar kGreens[4] = {{40, 170, 60}, {60, 150, 40}, {30, 140, 90}, {50, 190, 110}};
    cv::Mat bgr(size, CV_8UC3, cv::Scalar(60, 80, 110));
    for (int y = plant.y; y < plant.y + plant.height; ++y)
        bgr(cv::Rect(plant.x, y, plant.width, 1)).setTo(kGreens[(y - plant.y) % 4]);
    return bgr;
}

double chromatic_g(const cv::Vec3b& p) { return p[1] / static_cast<double>(p[0] + p[1] + p[2]); }

}  // namespace

TEST(Classify, EveryPlantGetsExactlyItsOwnPixels)
{
    const cv::Size size(400, 300);
    const Params params = test_params();
    for (std::uint64_t seed = 1; seed <= 5; ++seed) {
        const cv::Mat bgr = plants_frame(size, seed);
        const Classified c(bgr, params);
        ASSERT_EQ(c.det.status, DetectStatus::ok);
        ASSERT_GT(c.det.plants.size(), 5u);
        ASSERT_EQ(c.cws.features().size(), c.det.plants.size());
        std::vector<int> counted(c.det.plants.size() + 1, 0);
        for (int y = 0; y < size.height; ++y)
            for (int x = 0; x < size.width; ++x) {
                const int id = c.cws.plant_index().at<std::uint16_t>(y, x);
                ASSERT_LE(id, static_cast<int>(c.det.plants.size()));
                ++counted[static_cast<std::size_t>(id)];
                if (id > 0) {
                    const cv::Rect& box = c.det.plants[static_cast<std::size_t>(id - 1)].bbox;
                    EXPECT_TRUE(box.contains({x, y})) << "pixel outside its plant's box";
                }
            }
        for (std::size_t i = 0; i < c.det.plants.size(); ++i)
            EXPECT_EQ(counted[i + 1], c.det.plants[i].area_px) << "plant " << i << " seed " << seed;
    }
}

TEST(Classify, AReusedWorkspaceHoldsOnlyTheLatestFramesPlants)
{
    // Frames with plants in different places, through one pair of
    // workspaces: the plant map and features must equal a fresh pair's,
    // whatever the previous frame left.
    const cv::Size size(400, 300);
    const Params params = test_params();
    Workspace ws(size, params);
    ClassifyWorkspace cws(size, params);
    Detections det;
    const cv::Mat soil(size, CV_8UC3, cv::Scalar(60, 80, 110));
    for (const std::uint64_t seed : {1u, 2u, 3u, 4u, 5u, 6u, 7u, 8u}) {
        // The third frame is bare soil: nothing of the frame before may stay.
        const cv::Mat bgr = seed == 3 ? soil : plants_frame(size, seed);
        detect({.bgr = bgr}, params, ws, det);
        plant_features({.bgr = bgr}, params, ws, det, cws);
        const Classified fresh(bgr, params);
        ASSERT_EQ(det.plants.size(), fresh.det.plants.size()) << "seed " << seed;
        EXPECT_EQ(cv::countNonZero(cws.plant_index() != fresh.cws.plant_index()), 0) << "seed " << seed;
        ASSERT_EQ(cws.features().size(), fresh.cws.features().size());
        for (std::size_t i = 0; i < cws.features().size(); ++i)
            EXPECT_EQ(cws.features()[i], fresh.cws.features()[i]) << "plant " << i << " seed " << seed;
    }
    // A frame that gives no features (no rgb image) leaves no plant either.
    detect({.bgr = plants_frame(size, 9)}, params, ws, det);
    ASSERT_GT(det.plants.size(), 0u);
    plant_features({}, params, ws, det, cws);
    EXPECT_EQ(cws.features().size(), 0u);
    EXPECT_EQ(cv::countNonZero(cws.plant_index()), 0);
}

TEST(Classify, ShapeFeaturesTellADiscFromALine)
{
    const cv::Size size(300, 200);
    cv::Mat bgr(size, CV_8UC3, cv::Scalar(60, 80, 110));
    cv::circle(bgr, {80, 100}, 20, cv::Scalar(40, 170, 60), cv::FILLED);
    cv::line(bgr, {180, 40}, {260, 160}, cv::Scalar(40, 170, 60), 3);
    const Params params = test_params();
    Classified c(bgr, params);
    ASSERT_EQ(c.det.plants.size(), 2u);
    // Plants come in raster order of their top-most pixel: the line first.
    const std::size_t disc_index = c.det.plants[0].centre_of_mass.x < 150 ? 0 : 1;
    const FeatureRow& disc = c.cws.features()[disc_index];
    const FeatureRow& line = c.cws.features()[1 - disc_index];
    // Disc of radius 20 px at 0.3 mm/px: pi 400 0.09 = 113 mm².
    EXPECT_NEAR(std::pow(10.0f, disc[f_log_area_mm2]), 113.1, 113.1 * 0.05);
    EXPECT_NEAR(disc[f_elongation], 1.0, 0.05);
    EXPECT_GT(line[f_elongation], 10);
    EXPECT_GT(disc[f_compactness], line[f_compactness]);
    // Both are the same green: chromatic g of (40, 170, 60) is 170 / 270.
    EXPECT_NEAR(disc[f_g_mean], 170.0 / 270.0, 0.01);
    EXPECT_LT(disc[f_lateral], 0.5f);
    EXPECT_GT(line[f_lateral], 0.5f);
    EXPECT_EQ(disc[f_ndvi_mean], 0.0f) << "no NIR plane: NDVI features are 0";
}

TEST(Classify, NdviFeaturesComeFromTheNirPlane)
{
    const cv::Size size(200, 200);
    cv::Mat bgr(size, CV_8UC3, cv::Scalar(60, 80, 110));
    cv::circle(bgr, {100, 100}, 20, cv::Scalar(40, 170, 60), cv::FILLED);
    cv::Mat nir(size, CV_8UC1, cv::Scalar(180));   // (180 - 60) / (180 + 60) = 0.5 on the plant
    const Params params = test_params();
    Classified c(bgr, params, nir);
    ASSERT_EQ(c.det.plants.size(), 1u);
    EXPECT_NEAR(c.cws.features()[0][f_ndvi_mean], 0.5, 1e-4);
    EXPECT_NEAR(c.cws.features()[0][f_ndvi_std], 0.0, 1e-4);
}

TEST(Classify, ColourIsReadOnEveryFourthRowOfThePlantsBoxFromItsThirdOrMiddleRow)
{
    const Params params = test_params();
    for (const int height : {3, 4, 9, 41}) {
        const cv::Rect drawn(60, 50, 50, height);
        const cv::Mat bgr = striped_plant({200, 160}, drawn);
        Classified c(bgr, params);
        ASSERT_EQ(c.det.plants.size(), 1u) << height << " rows";
        const cv::Rect box = c.det.plants[0].bbox;
        ASSERT_EQ(box, drawn) << "the plant is its rectangle: no mixed pixels on a uniform soil";
        // The rows the definition names, every vegetation pixel on them.
        double g = 0;
        int rows = 0;
        for (int y = box.y + std::min(box.height / 2, 2); y < box.y + box.height; y += 4, ++rows)
            g += chromatic_g(bgr.at<cv::Vec3b>(y, box.x + box.width / 2));
        ASSERT_GT(rows, 0);
        EXPECT_NEAR(c.cws.features()[0][f_g_mean], g / rows, 1e-4) << height << " rows";
        // Rows 4 apart have one green: a row between them would add another.
        EXPECT_NEAR(c.cws.features()[0][f_g_std], 0.0, 2e-3) << height << " rows";
    }
}

TEST(Classify, ColourRowStepKeepsAPlantsSampleWithinTheBound)
{
    EXPECT_EQ(colour_row_step(0), 4);
    EXPECT_EQ(colour_row_step(4 * kPlantColourSamples), 4);
    EXPECT_EQ(colour_row_step(4 * kPlantColourSamples + 4), 8);
    EXPECT_EQ(colour_row_step(8 * kPlantColourSamples + 8), 16);
    for (const int px : {1000, 300'000, 1'251'936, 5'000'000}) {
        const int step = colour_row_step(px);
        EXPECT_LE(px / step, kPlantColourSamples) << px;
        if (step > 4) {
            EXPECT_GT(px / (step / 2), kPlantColourSamples) << px << ": the smallest step within the bound";
        }
    }
}

TEST(Classify, ColourOfAPlantOverTheSampleBoundIsReadOnFewerRowsOfItsBox)
{
    // 600 x 500 px of vegetation: over 4 kPlantColourSamples, within 8.
    const Params params = test_params();
    const cv::Rect drawn(40, 30, 600, 500);
    ASSERT_EQ(colour_row_step(drawn.area()), 8);
    static const cv::Scalar kGreens[8] = {{40, 170, 60}, {60, 150, 40},  {30, 140, 90}, {50, 190, 110},
                                          {45, 160, 70}, {35, 180, 100}, {55, 145, 50}, {40, 200, 80}};
    cv::Mat bgr(cv::Size(680, 560), CV_8UC3, cv::Scalar(60, 80, 110));
    for (int y = drawn.y; y < drawn.y + drawn.height; ++y)
        bgr(cv::Rect(drawn.x, y, drawn.width, 1)).setTo(kGreens[(y - drawn.y) % 8]);
    Classified c(bgr, params);
    ASSERT_EQ(c.det.plants.size(), 1u);
    const Plant& plant = c.det.plants[0];
    ASSERT_EQ(colour_row_step(plant.area_px), 8) << plant.area_px << " px";
    // Every 8th row from the box's third: one green, that row's. Every 4th
    // row would mix in another.
    const double third_row_g = chromatic_g(bgr.at<cv::Vec3b>(plant.bbox.y + 2, plant.bbox.x + plant.bbox.width / 2));
    EXPECT_NEAR(c.cws.features()[0][f_g_mean], third_row_g, 1e-4);
    EXPECT_NEAR(c.cws.features()[0][f_g_std], 0.0, 2e-3);
    // The vegetation fill still counts every row.
    EXPECT_NEAR(c.cws.features()[0][f_vegetation_fill], 1.0, 1e-3);
}

TEST(Classify, FrameBrightnessIsTheChromaticIndexsNormaliser)
{
    // One definition of a frame's brightness: chromatic_mean_brightness,
    // whose samples ChromaticExcessGreen.MeanBrightnessIsTheMeanOfRowFourOfEveryBand
    // checks. Here: the classifier takes exactly it, on views into a larger
    // frame (rows not contiguous) of heights around the 16-row bands.
    cv::RNG rng(21);
    cv::Mat big(60, 120, CV_8UC3);
    rng.fill(big, cv::RNG::UNIFORM, 0, 256);
    for (const int width : {1, 3, 17, 100}) {
        for (const int height : {1, 4, 5, 16, 21, 33, 50}) {
            const cv::Mat frame = big(cv::Rect(5, 2, width, height));
            EXPECT_EQ(sampled_frame_brightness(frame), static_cast<double>(chromatic_mean_brightness(frame)))
                << width << "x" << height;
        }
    }
    EXPECT_EQ(sampled_frame_brightness(cv::Mat(8, 8, CV_8UC3, cv::Scalar::all(0))), 1.0) << "a black frame: the floor";
    EXPECT_EQ(sampled_frame_brightness(cv::Mat()), 1.0) << "an empty frame";
}

TEST(Classify, DecisionLeavesTheUnsureMiddleUnknown)
{
    // weed_confidence at min_confidence or below: the symmetric decision.
    EXPECT_EQ(decide_class(0.9f, 0.7, 0.5), PlantClass::Weed);
    EXPECT_EQ(decide_class(0.7f, 0.7, 0.5), PlantClass::Weed);
    EXPECT_EQ(decide_class(0.69f, 0.7, 0.5), PlantClass::Unknown);
    EXPECT_EQ(decide_class(0.31f, 0.7, 0.5), PlantClass::Unknown);
    EXPECT_EQ(decide_class(0.25f, 0.7, 0.5), PlantClass::Crop);
    EXPECT_EQ(decide_class(0.5f, 0.5, 0.5), PlantClass::Weed);
    EXPECT_EQ(decide_class(0.49f, 0.5, 0.5), PlantClass::Crop);
    EXPECT_EQ(decide_class(0.9f, 1.0, 0.5), PlantClass::Unknown);
}

TEST(Classify, WeedNeedsTheHigherWeedBarWhileCropKeepsMinConfidence)
{
    // Crop safety: between min_confidence and weed_confidence a plant is
    // unknown, never weed; the crop side is unchanged.
    EXPECT_EQ(decide_class(0.84f, 0.6, 0.85), PlantClass::Unknown);
    EXPECT_EQ(decide_class(0.6f, 0.6, 0.85), PlantClass::Unknown);
    EXPECT_EQ(decide_class(0.85f, 0.6, 0.85), PlantClass::Weed);
    EXPECT_EQ(decide_class(0.4f, 0.6, 0.85), PlantClass::Crop);
    EXPECT_EQ(decide_class(0.41f, 0.6, 0.85), PlantClass::Unknown);
}

TEST(Classify, RowFeaturesFindTheDominantRowAndItsNeighbours)
{
    // Three large discs in a column (a crop row along the travel) and one
    // small disc far to the side (a weed between rows).
    cv::Mat bgr(400, 400, CV_8UC3, cv::Scalar(60, 80, 110));
    const cv::Scalar green(40, 170, 60);
    for (const int y : {60, 200, 340})
        cv::circle(bgr, {100, y}, 20, green, cv::FILLED);
    cv::circle(bgr, {330, 200}, 8, green, cv::FILLED);
    const Params params = test_params();
    Classified c(bgr, params);
    ASSERT_EQ(c.det.plants.size(), 4u);
    ASSERT_EQ(c.cws.features().size(), 4u);
    const double band_px = kRowHalfWidthMm / params.gsd_mm_per_px;
    ASSERT_GT(230.0, band_px) << "the weed must lie outside the row's band";
    for (std::size_t i = 0; i < 4; ++i) {
        const FeatureRow& f = c.cws.features()[i];
        const bool weed = c.det.plants[i].centre_of_mass.x > 200;
        if (weed) {
            EXPECT_NEAR(f[f_row_offset_mm], 230 * params.gsd_mm_per_px, 1.0);
            EXPECT_EQ(f[f_row_neighbours], 0.0f);
            EXPECT_LT(f[f_area_share], 0.25f);
            EXPECT_LT(f[f_row_band_share], 0.1f);
        } else {
            EXPECT_NEAR(f[f_row_offset_mm], 0.0, 0.5);
            EXPECT_EQ(f[f_row_neighbours], 2.0f);
            EXPECT_NEAR(f[f_area_share], 1.0f, 0.05f);
            EXPECT_GT(f[f_row_band_share], 0.9f);
        }
    }
}

TEST(Classify, ClassMapPaintsEachVegetationPixelWithItsPlantsClass)
{
    const cv::Size size(300, 200);
    cv::Mat bgr(size, CV_8UC3, cv::Scalar(60, 80, 110));
    cv::circle(bgr, {80, 100}, 20, cv::Scalar(40, 170, 60), cv::FILLED);
    cv::circle(bgr, {220, 100}, 20, cv::Scalar(40, 170, 60), cv::FILLED);
    const Params params = test_params();
    Classified c(bgr, params);
    ASSERT_EQ(c.det.plants.size(), 2u);
    const std::array classes{PlantClass::Crop, PlantClass::Weed};
    cv::Mat map;
    class_map(c.ws, c.cws, classes, map);
    ASSERT_EQ(map.size(), size);
    EXPECT_EQ(map.at<std::uint8_t>(100, 80), 1);
    EXPECT_EQ(map.at<std::uint8_t>(100, 220), 2);
    EXPECT_EQ(map.at<std::uint8_t>(10, 10), 0);
    cv::Mat veg;
    unpack_mask(c.ws.vegetation(), veg);
    EXPECT_EQ(cv::countNonZero(map), cv::countNonZero(veg)) << "every vegetation pixel of a plant, nothing else";
}

TEST(Classify, TrainingIsDeterministicAndSeparatesSeparableClasses)
{
    cv::Mat samples, labels;
    toy_data(300, 7, samples, labels);
    std::string error;
    const auto a = PlantClassifier::train(samples, labels, {}, error);
    ASSERT_TRUE(a) << error;
    const auto b = PlantClassifier::train(samples, labels, {}, error);
    ASSERT_TRUE(b) << error;
    cv::Mat test_samples, test_labels;
    toy_data(90, 8, test_samples, test_labels);
    int right = 0;
    for (int i = 0; i < test_samples.rows; ++i) {
        FeatureRow row;
        for (int f = 0; f < kPlantFeatureCount; ++f)
            row[static_cast<std::size_t>(f)] = test_samples.at<float>(i, f);
        const float p = a->weed_probability(row);
        EXPECT_EQ(p, b->weed_probability(row)) << "same data, same forest";
        EXPECT_GE(p, 0.0f);
        EXPECT_LE(p, 1.0f);
        right += (p >= 0.5f) == (test_labels.at<int>(i) == to_value(PlantClass::Weed));
    }
    // The clouds are 10 standard deviations apart on one feature.
    EXPECT_EQ(right, test_samples.rows);
}

TEST(Classify, WeedProbabilityIsTheFractionOfTreesVotingWeed)
{
    cv::Mat samples, labels;
    toy_data(200, 3, samples, labels);
    // Overlapping clouds, so that some votes are split.
    samples.col(f_log_area_mm2) *= 0.05;
    const test::SavedPlantForest saved(samples, labels, 25, temp_path("votes.yaml"));
    ASSERT_TRUE(saved.model) << saved.error;
    // The same forest through OpenCV's own vote count.
    cv::Mat votes;
    saved.opencv->getVotes(samples, votes, 0);
    // getVotes: a header row of class labels (0 crop, 1 weed), then counts.
    ASSERT_EQ(votes.cols, 2);
    ASSERT_EQ(votes.at<int>(0, 1), 1);
    int split = 0;
    for (int i = 0; i < samples.rows; ++i) {
        FeatureRow row;
        for (int f = 0; f < kPlantFeatureCount; ++f)
            row[static_cast<std::size_t>(f)] = samples.at<float>(i, f);
        const int weed_votes = votes.at<int>(i + 1, 1);
        split += weed_votes > 0 && weed_votes < 25;
        EXPECT_FLOAT_EQ(saved.model->weed_probability(row), weed_votes / 25.0f);
    }
    EXPECT_GT(split, 0) << "the check needs some split votes";
}

TEST(Classify, ModelFileRoundTripsWithItsMetadata)
{
    cv::Mat samples, labels;
    toy_data(150, 11, samples, labels);
    std::string error;
    const auto model = PlantClassifier::train(samples, labels, {.trees = 20}, error);
    ASSERT_TRUE(model) << error;
    for (const char* ext : {".yaml", ".json"}) {
        const fs::path path = temp_path(std::string("model") + ext);
        ModelInfo info;
        info.gsd_mm_per_px = 0.11;
        info.nir = true;
        info.segmentation = "exg_and_ndvi";
        info.recordings = {"a/rec", "b/rec"};
        info.trained_utc = "2026-11-24T04:00:00Z";
        info.cross_validation = "balanced accuracy 0.9";
        ASSERT_TRUE(model->save(path, info, error)) << error;
        const auto loaded = PlantClassifier::load(path, error);
        ASSERT_TRUE(loaded) << error;
        EXPECT_EQ(loaded->info().gsd_mm_per_px, 0.11);
        EXPECT_TRUE(loaded->info().nir);
        EXPECT_EQ(loaded->info().segmentation, "exg_and_ndvi");
        EXPECT_EQ(loaded->info().recordings, info.recordings);
        EXPECT_EQ(loaded->info().trained_utc, info.trained_utc);
        EXPECT_EQ(loaded->info().cross_validation, info.cross_validation);
        EXPECT_EQ(loaded->info().trees, 20);
        ASSERT_EQ(loaded->info().feature_names.size(), static_cast<std::size_t>(kPlantFeatureCount));
        EXPECT_EQ(loaded->info().feature_names[f_texture], "texture");
        for (int i = 0; i < samples.rows; ++i) {
            FeatureRow row;
            for (int f = 0; f < kPlantFeatureCount; ++f)
                row[static_cast<std::size_t>(f)] = samples.at<float>(i, f);
            EXPECT_EQ(loaded->weed_probability(row), model->weed_probability(row));
        }
        fs::remove(path);
    }
}

TEST(Classify, MismatchedGsdOrChannelsAreRefusedNamingTheFile)
{
    cv::Mat samples, labels;
    toy_data(90, 5, samples, labels);
    std::string error;
    auto model = PlantClassifier::train(samples, labels, {.trees = 5}, error);
    ASSERT_TRUE(model) << error;
    const fs::path path = temp_path("rgb.yaml");
    ASSERT_TRUE(model->save(path, {.gsd_mm_per_px = 0.11, .nir = false}, error)) << error;
    const auto loaded = PlantClassifier::load(path, error);
    ASSERT_TRUE(loaded) << error;
    EXPECT_FALSE(loaded->mismatch(0.11, false, "m.yaml"));
    EXPECT_FALSE(loaded->mismatch(0.11 * (1 + kModelGsdTolerance * 0.9), false, "m.yaml"));
    const auto gsd = loaded->mismatch(0.33, false, "m.yaml");
    ASSERT_TRUE(gsd);
    EXPECT_NE(gsd->find("m.yaml"), std::string::npos) << *gsd;
    EXPECT_NE(gsd->find("gsd"), std::string::npos) << *gsd;
    const auto channels = loaded->mismatch(0.11, true, "m.yaml");
    ASSERT_TRUE(channels);
    EXPECT_NE(channels->find("m.yaml"), std::string::npos) << *channels;
    EXPECT_NE(channels->find("rgb+nir"), std::string::npos) << *channels;
    fs::remove(path);
}

TEST(Classify, UnusableModelFilesAreRefusedNamingTheFile)
{
    const fs::path missing = temp_path("missing.yaml");
    std::string error;
    EXPECT_FALSE(PlantClassifier::load(missing, error));
    EXPECT_NE(error.find(missing.string()), std::string::npos) << error;

    const fs::path other = temp_path("other.yaml");
    std::ofstream(other) << "%YAML:1.0\n---\nsomething: 1\n";
    EXPECT_FALSE(PlantClassifier::load(other, error));
    EXPECT_NE(error.find(other.string()), std::string::npos) << error;
    fs::remove(other);

    const fs::path old = temp_path("old.yaml");
    std::ofstream(old) << "%YAML:1.0\n---\nstemd_plant_classifier:\n  features_version: 0\n  gsd_mm_per_px: 0.1\n";
    EXPECT_FALSE(PlantClassifier::load(old, error));
    EXPECT_NE(error.find("features version"), std::string::npos) << error;
    fs::remove(old);

    const fs::path garbage = temp_path("garbage.yaml");
    std::ofstream(garbage) << "\x01\x02 not yaml {{{";
    EXPECT_FALSE(PlantClassifier::load(garbage, error));
    EXPECT_NE(error.find(garbage.string()), std::string::npos) << error;
    fs::remove(garbage);

    // A FIFO no one writes (a blocking open would hang here until ctest's
    // timeout), a device that never ends, a directory: refused at once.
    const fs::path fifo = temp_path("fifo.yaml");
    fs::remove(fifo);
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    for (const fs::path& path : {fifo, fs::path("/dev/zero"), fifo.parent_path()}) {
        EXPECT_FALSE(PlantClassifier::load(path, error));
        EXPECT_EQ(error, path.string() + ": cannot read the model file: not a regular file");
    }
    fs::remove(fifo);
}

TEST(Classify, TrainingRefusesOneClassOrBadLabels)
{
    cv::Mat samples, labels;
    toy_data(30, 5, samples, labels);
    std::string error;
    cv::Mat crops(labels.size(), CV_32SC1, cv::Scalar(to_value(PlantClass::Crop)));
    EXPECT_FALSE(PlantClassifier::train(samples, crops, {}, error));
    EXPECT_NE(error.find("crop and weed"), std::string::npos) << error;
    labels.at<int>(0) = 0;
    EXPECT_FALSE(PlantClassifier::train(samples, labels, {}, error));
    EXPECT_FALSE(PlantClassifier::train(samples.colRange(0, 3), labels, {}, error));
}

TEST(Classify, AFrameWithoutItsRgbImageGivesNoFeatures)
{
    const cv::Size size(200, 200);
    cv::Mat bgr(size, CV_8UC3, cv::Scalar(60, 80, 110));
    cv::circle(bgr, {100, 100}, 20, cv::Scalar(40, 170, 60), cv::FILLED);
    const Params params = test_params();
    Classified c(bgr, params);
    ASSERT_EQ(c.det.plants.size(), 1u);
    ASSERT_EQ(c.cws.features().size(), 1u);
    plant_features({}, params, c.ws, c.det, c.cws);
    EXPECT_TRUE(c.cws.features().empty());
    EXPECT_EQ(cv::countNonZero(c.cws.plant_index()), 0);
    ClassifyWorkspace other(cv::Size(100, 100), params);
    plant_features({.bgr = bgr}, params, c.ws, c.det, other);
    EXPECT_TRUE(other.features().empty()) << "a workspace of another size";
}
