// Crop or weed per cell: the cell features, the cell forest in the model
// file, the class map from the cells, and each plant's class from the share
// of its cells.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <random>

#include <opencv2/imgproc.hpp>

#include "stemd/vision/cells.hpp"
#include "stemd/vision/classify.hpp"
#include "vision_classify_test_util.hpp"

namespace fs = std::filesystem;
using namespace stemd;
using namespace stemd::vision;

namespace {

Params test_params() { return test::classify_test_params(); }

// Soil with two plants touching side by side, so that detect() merges
// them into one: on the left a smooth, yellowish-green disc ("crop"), on
// the right a bluish-green disc striped with darker leaf veins ("weed").
// `truth` gets 1 under the crop and 2 under the weed.
void touching_pair(cv::Size size, cv::Point centre, int radius, cv::Mat& bgr, cv::Mat& truth)
{
    bgr.create(size, CV_8UC3);
    bgr.setTo(cv::Scalar(60, 80, 110));
    truth = cv::Mat::zeros(size, CV_8UC1);
    const cv::Point left = centre - cv::Point(radius, 0), right = centre + cv::Point(radius, 0);
    cv::circle(bgr, left, radius, cv::Scalar(30, 180, 120), cv::FILLED);
    cv::circle(truth, left, radius, cv::Scalar(1), cv::FILLED);
    cv::Mat weed(size, CV_8UC1, cv::Scalar(0));
    cv::circle(weed, right, radius, cv::Scalar(255), cv::FILLED);
    for (int y = 0; y < size.height; ++y)
        for (int x = 0; x < size.width; ++x) {
            if (!weed.at<std::uint8_t>(y, x))
                continue;
            const bool vein = (x + y) % 6 < 2;
            bgr.at<cv::Vec3b>(y, x) = vein ? cv::Vec3b(70, 120, 40) : cv::Vec3b(110, 190, 50);
            truth.at<std::uint8_t>(y, x) = 2;
        }
}

// Plant-forest rows that train at all (the cells are what is tested).
void plant_rows(cv::Mat& samples, cv::Mat& labels)
{
    samples.create(40, kPlantFeatureCount, CV_32FC1);
    labels.create(40, 1, CV_32SC1);
    cv::RNG rng(3);
    rng.fill(samples, cv::RNG::UNIFORM, 0, 1);
    for (int i = 0; i < labels.rows; ++i)
        labels.at<int>(i) = i % 2 ? to_value(PlantClass::Crop) : to_value(PlantClass::Weed);
}

struct Frame {
    Frame(const cv::Mat& image, const Params& params, double cell_mm)
        : bgr(image), ws(bgr.size(), params), cws(bgr.size(), params), cells(bgr.size(), params.gsd_mm_per_px, cell_mm)
    {
        detect({.bgr = bgr}, params, ws, det);
        plant_features({.bgr = bgr}, params, ws, det, cws);
        cell_features({.bgr = bgr}, params, ws, det, cws, cells);
    }
    cv::Mat bgr;
    Workspace ws;
    Detections det;
    ClassifyWorkspace cws;
    CellWorkspace cells;
};

// Cell rows of `frame` labelled by the majority of `truth` under each
// cell's vegetation.
void add_cells(const Frame& frame, const cv::Mat& truth, std::vector<CellRow>& rows, std::vector<int>& labels)
{
    std::vector<int> crop(frame.cells.cells(), 0), weed(frame.cells.cells(), 0);
    for (int y = 0; y < truth.rows; ++y)
        for (int x = 0; x < truth.cols; ++x) {
            if (!frame.ws.vegetation().get(x, y))
                continue;
            crop[frame.cells.cell_of(x, y)] += truth.at<std::uint8_t>(y, x) == 1;
            weed[frame.cells.cell_of(x, y)] += truth.at<std::uint8_t>(y, x) == 2;
        }
    for (const std::uint32_t c : frame.cells.vegetated())
        if (crop[c] + weed[c] > 0) {
            rows.push_back(frame.cells.row(c));
            labels.push_back(to_value(crop[c] >= weed[c] ? PlantClass::Crop : PlantClass::Weed));
        }
}

cv::Mat to_mat(const std::vector<CellRow>& rows)
{
    cv::Mat m(static_cast<int>(rows.size()), kCellFeatureCount, CV_32FC1);
    for (std::size_t i = 0; i < rows.size(); ++i)
        std::copy(rows[i].begin(), rows[i].end(), m.ptr<float>(static_cast<int>(i)));
    return m;
}

// A model whose cell forest learnt the touching pairs of a few frames.
PlantClassifier pair_model(const Params& params, double cell_mm, std::uint64_t seed)
{
    std::vector<CellRow> rows;
    std::vector<int> labels;
    std::mt19937 rng(11);
    for (int k = 0; k < 6; ++k) {
        cv::Mat bgr, truth;
        const int radius = 30 + static_cast<int>(rng() % 15);
        touching_pair({320, 240}, {160 + static_cast<int>(rng() % 40) - 20, 120 + static_cast<int>(rng() % 40) - 20},
                      radius, bgr, truth);
        const Frame frame(bgr, params, cell_mm);
        add_cells(frame, truth, rows, labels);
    }
    cv::Mat samples, plant_labels;
    plant_rows(samples, plant_labels);
    std::string error;
    auto model = PlantClassifier::train(samples, plant_labels, {.trees = 5}, error);
    EXPECT_TRUE(model) << error;
    const cv::Mat cell_labels = cv::Mat(labels, true).reshape(1, static_cast<int>(labels.size()));
    EXPECT_TRUE(model->train_cells(to_mat(rows), cell_labels, {.trees = 20, .max_depth = 6, .seed = seed}, cell_mm,
                                   error))
        << error;
    return std::move(*model);
}

// `model` with a context forest learnt on the touching pairs of a few
// frames: each labelled cell's row and its context from the cell forest's
// probabilities on its own frame.
void add_context(const Params& params, double cell_mm, std::uint64_t seed, PlantClassifier& model)
{
    cv::Mat samples(0, kContextFeatureCount, CV_32FC1);
    std::vector<int> labels;
    std::mt19937 rng(12);
    for (int k = 0; k < 6; ++k) {
        cv::Mat bgr, truth;
        touching_pair({320, 240}, {160 + static_cast<int>(rng() % 40) - 20, 120}, 30 + static_cast<int>(rng() % 15),
                      bgr, truth);
        const Frame frame(bgr, params, cell_mm);
        std::vector<CellRow> rows;
        std::vector<int> frame_labels;
        add_cells(frame, truth, rows, frame_labels);
        // Context over every vegetated cell, rows for the labelled ones.
        const auto cells = frame.cells.vegetated();
        std::vector<float> weight, first;
        std::vector<std::uint16_t> plant;
        for (const std::uint32_t c : cells) {
            weight.push_back(frame.cells.row(c)[c_fill]);
            plant.push_back(frame.cells.plant(c));
            first.push_back(model.cell_weed_probability(frame.cells.row(c)));
        }
        std::vector<CellContext> context(cells.size());
        CellContextScratch scratch(frame.cells.grid());
        cell_context({.grid = frame.cells.grid(), .cell_mm = cell_mm, .cells = cells, .weight = weight,
                      .plant = plant, .probability = first},
                     scratch, context);
        std::size_t r = 0;
        for (std::size_t k2 = 0; k2 < cells.size() && r < rows.size(); ++k2) {
            if (frame.cells.row(cells[k2]) != rows[r])
                continue;   // unlabelled
            cv::Mat row(1, kContextFeatureCount, CV_32FC1);
            std::copy(rows[r].begin(), rows[r].end(), row.ptr<float>());
            std::copy(context[k2].begin(), context[k2].end(), row.ptr<float>() + kCellFeatureCount);
            samples.push_back(row);
            labels.push_back(frame_labels[r]);
            ++r;
        }
        ASSERT_EQ(r, rows.size());
    }
    std::string error;
    const cv::Mat context_labels = cv::Mat(labels, true).reshape(1, static_cast<int>(labels.size()));
    ASSERT_TRUE(model.train_context(samples, context_labels, {.trees = 20, .max_depth = 6, .seed = seed}, error))
        << error;
}

fs::path temp_path(const std::string& name) { return test::classify_temp_path("stemd-cells", name); }

}  // namespace

TEST(Cells, TouchingPlantsOfDifferentColourAndTextureGetDifferentClassesInTheMap)
{
    const Params params = test_params();
    const double cell_mm = 1.5;   // 5 px cells
    const PlantClassifier model = pair_model(params, cell_mm, 1);
    ASSERT_TRUE(model.has_cells());

    // A pair the forest has not seen, elsewhere in the frame.
    cv::Mat bgr, truth;
    touching_pair({320, 240}, {150, 110}, 36, bgr, truth);
    Frame frame(bgr, params, cell_mm);
    ASSERT_EQ(frame.det.plants.size(), 1u) << "the two plants must touch and be one blob";
    classify_cells(model, frame.cells);
    cv::Mat map;
    cell_class_map(frame.ws, frame.cells, map);
    // Each half of the blob: the share of its vegetation pixels the map
    // gives its own class. One class per blob would give at most one half.
    long crop_right = 0, crop_all = 0, weed_right = 0, weed_all = 0;
    for (int y = 0; y < map.rows; ++y)
        for (int x = 0; x < map.cols; ++x) {
            if (!frame.ws.vegetation().get(x, y))
                continue;
            const int t = truth.at<std::uint8_t>(y, x), said = map.at<std::uint8_t>(y, x);
            crop_all += t == 1;
            crop_right += t == 1 && said == 1;
            weed_all += t == 2;
            weed_right += t == 2 && said == 2;
        }
    ASSERT_GT(crop_all, 1000);
    ASSERT_GT(weed_all, 1000);
    EXPECT_GT(static_cast<double>(crop_right) / static_cast<double>(crop_all), 0.9);
    EXPECT_GT(static_cast<double>(weed_right) / static_cast<double>(weed_all), 0.9);
    // Soil stays soil.
    EXPECT_EQ(map.at<std::uint8_t>(5, 5), 0);

    // The one plant gets the class of the larger share of its cells, its
    // probability between the two halves' (both halves are the same size).
    std::array<float, kMaxPlants> p{};
    std::array<PlantClass, kMaxPlants> classes{};
    classify_plants(model, frame.cws, frame.cells, frame.det.plants.size(), 0.6, 0.85, p, classes);
    EXPECT_GT(p[0], 0.2f);
    EXPECT_LT(p[0], 0.8f);
    EXPECT_EQ(classes[0], PlantClass::Unknown) << "half crop, half weed: unsure";
}

TEST(Cells, CellTrainingIsDeterministicAndTheModelFileKeepsTheCellForest)
{
    const Params params = test_params();
    const PlantClassifier a = pair_model(params, 1.5, 7);
    const PlantClassifier b = pair_model(params, 1.5, 7);
    cv::Mat bgr, truth;
    touching_pair({320, 240}, {170, 130}, 32, bgr, truth);
    Frame frame(bgr, params, 1.5);
    ASSERT_GT(frame.cells.vegetated().size(), 50u);
    const fs::path path = temp_path("model.yaml");
    std::string error;
    ASSERT_TRUE(a.save(path, {.gsd_mm_per_px = 0.3}, error)) << error;
    const auto loaded = PlantClassifier::load(path, error);
    ASSERT_TRUE(loaded) << error;
    EXPECT_TRUE(loaded->has_cells());
    EXPECT_EQ(loaded->info().cell_mm, 1.5);
    EXPECT_EQ(loaded->info().cell_trees, 20);
    int split = 0;
    for (const std::uint32_t c : frame.cells.vegetated()) {
        const float p = a.cell_weed_probability(frame.cells.row(c));
        EXPECT_EQ(p, b.cell_weed_probability(frame.cells.row(c))) << "same data, same seed, same forest";
        EXPECT_EQ(p, loaded->cell_weed_probability(frame.cells.row(c))) << "the file holds the same trees";
        split += p > 0 && p < 1;
    }
    fs::remove(path);
    EXPECT_GT(split, 0) << "the check needs cells with split votes";
}

TEST(Cells, TheFlatForestVotesAsOpenCvDoes)
{
    // Overlapping clouds so that votes split.
    cv::Mat samples(300, kPlantFeatureCount, CV_32FC1), labels(300, 1, CV_32SC1);
    cv::RNG rng(5);
    rng.fill(samples, cv::RNG::NORMAL, 0, 1);
    for (int i = 0; i < samples.rows; ++i) {
        const bool weed = i % 3 == 0;
        samples.at<float>(i, 0) += weed ? 0.8f : 0.0f;
        labels.at<int>(i) = to_value(weed ? PlantClass::Weed : PlantClass::Crop);
    }
    const test::SavedPlantForest saved(samples, labels, 25, temp_path("flat.yaml"));
    ASSERT_TRUE(saved.model) << saved.error;
    const FlatForest flat = flatten(*saved.opencv);
    ASSERT_EQ(flat.roots.size(), 25u);
    int split = 0;
    for (int i = 0; i < samples.rows; ++i) {
        FeatureRow row;
        std::copy(samples.ptr<float>(i), samples.ptr<float>(i) + kPlantFeatureCount, row.begin());
        const float p = flat.weed_fraction(row.data());
        EXPECT_EQ(p, saved.model->weed_probability(row)) << "row " << i;
        split += p > 0 && p < 1;
    }
    EXPECT_GT(split, 0) << "the check needs split votes";

    // Rows walked in groups, with a short last group (300 and 297 rows are
    // no multiple of 8, 16 or 32), vote as each row alone.
    for (const int first : {0, 3}) {
        const auto count = static_cast<std::size_t>(samples.rows - first);
        std::vector<float> batch(count + 1, -1.0f);
        flat.weed_fractions(count, [&](std::size_t k) { return samples.ptr<float>(first + static_cast<int>(k)); },
                            batch.data());
        for (std::size_t k = 0; k < count; ++k)
            EXPECT_EQ(batch[k], flat.weed_fraction(samples.ptr<float>(first + static_cast<int>(k)))) << "row " << k;
        EXPECT_EQ(batch[count], -1.0f) << "nothing written past the rows";
    }
    // The same from rows packed back to back, with room between them (a
    // stride longer than the features), in whole groups and a short last one.
    constexpr std::size_t kStride = kPlantFeatureCount + 3;
    std::vector<float> packed(static_cast<std::size_t>(samples.rows) * kStride, 1e9f);
    for (int i = 0; i < samples.rows; ++i)
        std::copy(samples.ptr<float>(i), samples.ptr<float>(i) + kPlantFeatureCount,
                  packed.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(i) * kStride));
    for (const std::size_t count : {std::size_t{300}, std::size_t{297}, std::size_t{16}, std::size_t{5}, std::size_t{0}}) {
        std::vector<float> batch(count + 1, -1.0f);
        flat.weed_fractions_packed<kStride>(count, packed.data(), batch.data());
        for (std::size_t k = 0; k < count; ++k)
            EXPECT_EQ(batch[k], flat.weed_fraction(samples.ptr<float>(static_cast<int>(k)))) << count << " rows, row " << k;
        EXPECT_EQ(batch[count], -1.0f) << "nothing written past the rows";
    }
    for (std::size_t t = 0; t < flat.roots.size(); ++t) {
        EXPECT_GT(flat.depths[t], 0) << "tree " << t;
        EXPECT_LE(flat.depths[t], ForestOptions{}.max_depth) << "no deeper than the forest was allowed to grow";
    }
}

TEST(Cells, CellFeaturesMeasureColourWidthAndTheRow)
{
    // A column of discs (a crop row along the travel) and one thin line far
    // to the side.
    const Params params = test_params();
    cv::Mat bgr(300, 400, CV_8UC3, cv::Scalar(60, 80, 110));
    for (const int y : {50, 150, 250})
        cv::circle(bgr, {100, y}, 30, cv::Scalar(40, 170, 60), cv::FILLED);
    cv::line(bgr, {330, 100}, {330, 200}, cv::Scalar(40, 170, 60), 3);
    Frame frame(bgr, params, 3.0);   // 10 px cells
    ASSERT_EQ(frame.cells.cell_px(), 10);
    const CellRow& disc = frame.cells.row(frame.cells.cell_of(100, 150));
    const CellRow& line = frame.cells.row(frame.cells.cell_of(330, 150));
    EXPECT_NEAR(disc[c_g_mean], 170.0 / 270.0, 0.01);
    EXPECT_NEAR(disc[c_fill], 1.0, 0.01) << "a cell inside a disc is all vegetation";
    EXPECT_LT(line[c_fill], 0.5f);
    // Leaf thickness: the segmented line's width (the mixed-edge step
    // widens the drawn 3 px), 2 area / boundary of a long strip.
    int width_px = 0;
    for (int x = 300; x < 360; ++x)
        width_px += frame.ws.vegetation().get(x, 150);
    ASSERT_GE(width_px, 3);
    EXPECT_NEAR(line[c_width_mm], width_px * 0.3, 0.3);
    EXPECT_GT(disc[c_width_mm], 3 * line[c_width_mm]) << "a disc's cell is solid leaf";
    EXPECT_GT(disc[c_band_density], line[c_band_density]);
    EXPECT_LE(disc[c_row_offset_mm], 3.0f);
    EXPECT_NEAR(line[c_row_offset_mm], 230 * 0.3, 3.0 + 0.5);
    EXPECT_EQ(disc[c_in_plant], 1.0f);
    EXPECT_EQ(disc[c_ndvi_mean], 0.0f) << "no NIR plane";
    // The plant's own features follow the cell's.
    const std::size_t plant = frame.cells.plant(frame.cells.cell_of(100, 150));
    ASSERT_GT(plant, 0u);
    EXPECT_EQ(disc[static_cast<std::size_t>(kCellOwnFeatureCount) + f_log_area_mm2], frame.cws.features()[plant - 1][f_log_area_mm2]);
}

TEST(Cells, APlantWithoutClassifiedCellsIsUnknownAndAModelWithoutCellsUsesThePlantForest)
{
    const Params params = test_params();
    cv::Mat bgr(200, 200, CV_8UC3, cv::Scalar(60, 80, 110));
    cv::circle(bgr, {100, 100}, 20, cv::Scalar(40, 170, 60), cv::FILLED);
    Frame frame(bgr, params, 3.0);
    ASSERT_EQ(frame.det.plants.size(), 1u);
    cv::Mat samples, labels;
    plant_rows(samples, labels);
    std::string error;
    const auto plants_only = PlantClassifier::train(samples, labels, {.trees = 5}, error);
    ASSERT_TRUE(plants_only) << error;
    ASSERT_FALSE(plants_only->has_cells());
    classify_cells(*plants_only, frame.cells);
    for (const std::uint32_t c : frame.cells.vegetated())
        EXPECT_EQ(frame.cells.cell_class(c), PlantClass::Unknown);
    std::array<float, kMaxPlants> p{};
    std::array<PlantClass, kMaxPlants> classes{};
    classify_plants(*plants_only, frame.cws, frame.cells, 1, 0.6, 0.85, p, classes);
    EXPECT_EQ(p[0], plants_only->weed_probability(frame.cws.features()[0]));

    // With cells, but on a frame without its rgb image: no cell, unknown.
    const PlantClassifier with_cells = pair_model(params, 3.0, 1);
    cell_features({}, params, frame.ws, frame.det, frame.cws, frame.cells);
    EXPECT_TRUE(frame.cells.vegetated().empty());
    classify_cells(with_cells, frame.cells);
    classify_plants(with_cells, frame.cws, frame.cells, 1, 0.6, 0.85, p, classes);
    EXPECT_EQ(classes[0], PlantClass::Unknown);
    EXPECT_LT(p[0], 0.0f);
}

TEST(Cells, TheClassMapTakesEachCellsMostLikelyClassAtTheModelsBar)
{
    const Params params = test_params();
    PlantClassifier model = pair_model(params, 1.5, 3);
    EXPECT_EQ(model.info().map_weed_bar, 0.5) << "a trained model starts at the most likely class";
    cv::Mat bgr, truth;
    touching_pair({320, 240}, {160, 120}, 34, bgr, truth);
    Frame frame(bgr, params, 1.5);
    ASSERT_GT(frame.cells.vegetated().size(), 50u);
    // Unlike the treat decision, the map leaves no vegetated cell unknown:
    // weed from the bar up, crop below it.
    for (const double bar : {0.5, 0.3, 0.7}) {
        model.set_map_weed_bar(bar);
        classify_cells(model, frame.cells);
        int weed = 0, crop = 0;
        for (const std::uint32_t c : frame.cells.vegetated()) {
            const float p = frame.cells.weed_probability(c);
            EXPECT_EQ(frame.cells.cell_class(c), p >= static_cast<float>(bar) ? PlantClass::Weed : PlantClass::Crop)
                << "bar " << bar << ", p " << p;
            weed += frame.cells.cell_class(c) == PlantClass::Weed;
            crop += frame.cells.cell_class(c) == PlantClass::Crop;
        }
        EXPECT_GT(weed, 0);
        EXPECT_GT(crop, 0);
    }
    // The bar travels in the model file; a file without one reads 0.5.
    const fs::path path = temp_path("bar.yaml");
    std::string error;
    ASSERT_TRUE(model.save(path, {.gsd_mm_per_px = 0.3}, error)) << error;
    const auto loaded = PlantClassifier::load(path, error);
    ASSERT_TRUE(loaded) << error;
    EXPECT_EQ(loaded->info().map_weed_bar, 0.7);
    {
        // The same file without map_weed_bar, as models written before it.
        std::ostringstream all;
        all << std::ifstream(path).rdbuf();
        std::string text = all.str();
        const auto at = text.find("map_weed_bar");
        ASSERT_NE(at, std::string::npos);
        const auto line = text.rfind('\n', at) + 1;
        text.erase(line, text.find('\n', at) - line + 1);
        std::ofstream(path.string() + ".old.yaml") << text;
    }
    const auto old = PlantClassifier::load(path.string() + ".old.yaml", error);
    ASSERT_TRUE(old) << error << "\n" << std::ifstream(path.string() + ".old.yaml").rdbuf();
    EXPECT_EQ(old->info().map_weed_bar, 0.5);
    fs::remove(path);
    fs::remove(path.string() + ".old.yaml");
}

TEST(Cells, TrainingCellsCanBeWeighedAndTheClassesStayBalancedByWeight)
{
    // Where feature 0 is negative, the crop and weed rows are as many but
    // the weeds weigh 9 times more; where positive, the crops do. Both
    // classes weigh 500 in all, so the balance changes nothing, and only
    // the weights tell the two halves apart.
    const int n = 200;
    cv::Mat samples(n, kCellFeatureCount, CV_32FC1, cv::Scalar(0)), labels(n, 1, CV_32SC1), weights(n, 1, CV_32FC1);
    cv::RNG rng(9);
    for (int i = 0; i < n; ++i) {
        const bool left = i < n / 2, weed = i % 2 == 0;
        samples.at<float>(i, 0) = static_cast<float>(left ? rng.uniform(-2.0, -0.5) : rng.uniform(0.5, 2.0));
        // Every feature tells the halves apart, so that every split does.
        for (int f = 1; f < kCellFeatureCount; ++f)
            samples.at<float>(i, f) = samples.at<float>(i, 0);
        labels.at<int>(i) = to_value(weed ? PlantClass::Weed : PlantClass::Crop);
        weights.at<float>(i) = (left == weed) ? 9.0f : 1.0f;
    }
    cv::Mat plant_samples, plant_labels;
    plant_rows(plant_samples, plant_labels);
    std::string error;
    auto model = PlantClassifier::train(plant_samples, plant_labels, {.trees = 5}, error);
    ASSERT_TRUE(model) << error;
    ASSERT_TRUE(model->train_cells(samples, labels, {.trees = 30, .max_depth = 4}, 3.0, error, weights)) << error;
    CellRow row{};
    row.fill(-1.2f);
    const float left = model->cell_weed_probability(row);
    row.fill(1.2f);
    const float right = model->cell_weed_probability(row);
    // Unweighed, each half is a coin toss; weighed, its heavy class wins
    // the majority of the trees.
    EXPECT_GT(left, 0.5f) << "the heavy weeds";
    EXPECT_LT(right, 0.5f) << "the heavy crops";
    // Weights that do not fit the rows are refused.
    EXPECT_FALSE(model->train_cells(samples, labels, {.trees = 3}, 3.0, error, weights.rowRange(0, 10)));
    EXPECT_NE(error.find("weights"), std::string::npos) << error;
}

TEST(Cells, VariableImportanceIsComputedOnlyWhenAskedForAndLeavesTheForestAsUsable)
{
    // Feature 3 alone tells the classes apart; the others are noise.
    const int n = 300;
    cv::Mat samples(n, kCellFeatureCount, CV_32FC1), labels(n, 1, CV_32SC1);
    cv::RNG rng(5);
    rng.fill(samples, cv::RNG::UNIFORM, -1.0, 1.0);
    for (int i = 0; i < n; ++i) {
        const bool weed = i % 2 == 0;
        samples.at<float>(i, 3) = static_cast<float>(weed ? rng.uniform(0.5, 1.5) : rng.uniform(-1.5, -0.5));
        labels.at<int>(i) = to_value(weed ? PlantClass::Weed : PlantClass::Crop);
    }
    cv::Mat plant_samples, plant_labels;
    plant_rows(plant_samples, plant_labels);
    std::string error;
    for (const bool importance : {false, true}) {
        SCOPED_TRACE(importance ? "with importance" : "without");
        auto model = PlantClassifier::train(plant_samples, plant_labels, {.trees = 5}, error);
        ASSERT_TRUE(model) << error;
        ASSERT_TRUE(model->train_cells(samples, labels, {.trees = 20, .max_depth = 4, .var_importance = importance},
                                       3.0, error))
            << error;
        // Only the trees whose drawn features include feature 3 can tell,
        // so the forest leans to the right class rather than agreeing.
        CellRow row{};
        row[3] = 1.0f;
        EXPECT_GT(model->cell_weed_probability(row), 0.5f);
        row[3] = -1.0f;
        EXPECT_LT(model->cell_weed_probability(row), 0.5f);
        if (!importance) {
            EXPECT_TRUE(model->cell_importance().empty());
            continue;
        }
        ASSERT_EQ(model->cell_importance().total(), static_cast<std::size_t>(kCellFeatureCount));
        cv::Point most;
        cv::minMaxLoc(model->cell_importance().reshape(1, 1), nullptr, nullptr, nullptr, &most);
        EXPECT_EQ(most.x, 3) << "the one telling feature ranks first";
    }
}

TEST(CellContext, EachFeatureIsTheVegetationWeighedMeanOfTheFirstStageOverItsReach)
{
    // 3 mm cells: squares of 1, 2, 5 and 13 cells either side, the band 7
    // columns either side (20 mm).
    const cv::Size grid(20, 6);
    const std::vector<std::uint32_t> cells{21, 22, 88, 109, 115};   // (1,1) (2,1) (8,4) (9,5) (15,5)
    const std::vector<float> weight{1.0f, 0.5f, 1.0f, 1.0f, 0.0f};
    const std::vector<std::uint16_t> plant{1, 1, 2, 0, 3};
    const std::vector<float> first{1.0f, 0.0f, 0.5f, 0.25f, 0.8f};
    std::vector<CellContext> out(cells.size());
    CellContextScratch scratch(grid);
    cell_context({.grid = grid, .cell_mm = 3.0, .cells = cells, .weight = weight, .plant = plant, .probability = first},
                 scratch, out);
    // (1,1): its 3x3, 5x5 and 11x11 squares hold it and (2,1): (1 + 0) /
    // 1.5; the 27x27 square the whole frame: (1 + 0 + 0.5 + 0.25) / 3.5.
    EXPECT_FLOAT_EQ(out[0][x_near], 2.0f / 3.0f);
    EXPECT_FLOAT_EQ(out[0][x_mid], 2.0f / 3.0f);
    EXPECT_FLOAT_EQ(out[0][x_wide], 2.0f / 3.0f);
    EXPECT_FLOAT_EQ(out[0][x_far], 0.5f);
    // Columns 0-8: (1,1), (2,1), (8,4).
    EXPECT_FLOAT_EQ(out[0][x_band], 1.5f / 2.5f);
    EXPECT_FLOAT_EQ(out[0][x_plant], 2.0f / 3.0f);
    EXPECT_FLOAT_EQ(out[0][x_frame], 0.5f);
    // (9,5): its 3x3 holds (8,4); no plant, so its own probability; its
    // band, columns 2-16, holds (2,1), (8,4), itself and the weightless (15,5).
    EXPECT_FLOAT_EQ(out[3][x_near], 0.75f / 2.0f);
    EXPECT_FLOAT_EQ(out[3][x_plant], 0.25f);
    EXPECT_FLOAT_EQ(out[3][x_band], 0.75f / 2.5f);
    EXPECT_FLOAT_EQ(out[2][x_plant], 0.5f);
    // (15,5) weighs nothing: alone in its squares up to 11x11 (columns
    // 10-19) and in its plant it keeps its own probability; the 27x27
    // square (columns 2-19) sees (2,1), (8,4) and (9,5).
    EXPECT_FLOAT_EQ(out[4][x_near], 0.8f);
    EXPECT_FLOAT_EQ(out[4][x_wide], 0.8f);
    EXPECT_FLOAT_EQ(out[4][x_plant], 0.8f);
    EXPECT_FLOAT_EQ(out[4][x_far], 0.75f / 2.5f);
    EXPECT_FLOAT_EQ(out[4][x_frame], 0.5f);

    // A scratch of another grid size computes nothing rather than read out
    // of its buffers.
    std::vector<CellContext> untouched(cells.size(), CellContext{});
    CellContextScratch small({4, 4});
    cell_context({.grid = grid, .cell_mm = 3.0, .cells = cells, .weight = weight, .plant = plant, .probability = first},
                 small, untouched);
    EXPECT_EQ(untouched[0][x_near], 0.0f);
}

TEST(CellContext, AModelWithAContextForestUsesItAndTheFileKeepsIt)
{
    const Params params = test_params();
    const double cell_mm = 1.5;
    PlantClassifier model = pair_model(params, cell_mm, 1);
    std::string error;
    {
        // No context forest before a cell forest.
        cv::Mat samples, labels;
        plant_rows(samples, labels);
        auto plants_only = PlantClassifier::train(samples, labels, {.trees = 5}, error);
        ASSERT_TRUE(plants_only) << error;
        cv::Mat rows(4, kContextFeatureCount, CV_32FC1, cv::Scalar(0)), four(4, 1, CV_32SC1, cv::Scalar(1));
        EXPECT_FALSE(plants_only->train_context(rows, four, {.trees = 3}, error));
        EXPECT_NE(error.find("cell forest first"), std::string::npos) << error;
    }
    const PlantClassifier first_stage_only = model;
    add_context(params, cell_mm, 1, model);
    ASSERT_TRUE(model.has_context());
    EXPECT_EQ(model.info().context_trees, 20);
    EXPECT_FALSE(first_stage_only.has_context());

    // A pair it has not seen: the halves keep their classes in the map.
    cv::Mat bgr, truth;
    touching_pair({320, 240}, {150, 110}, 36, bgr, truth);
    Frame frame(bgr, params, cell_mm);
    ASSERT_EQ(frame.det.plants.size(), 1u);
    classify_cells(model, frame.cells);
    cv::Mat map;
    cell_class_map(frame.ws, frame.cells, map);
    long right = 0, all = 0;
    for (int y = 0; y < map.rows; ++y)
        for (int x = 0; x < map.cols; ++x)
            if (frame.ws.vegetation().get(x, y) && truth.at<std::uint8_t>(y, x) != 0) {
                ++all;
                right += map.at<std::uint8_t>(y, x) == truth.at<std::uint8_t>(y, x);
            }
    ASSERT_GT(all, 2000);
    EXPECT_GT(static_cast<double>(right) / static_cast<double>(all), 0.9);

    // The file holds the context forest: the same probabilities after load.
    std::vector<float> before;
    for (const std::uint32_t c : frame.cells.vegetated())
        before.push_back(frame.cells.weed_probability(c));
    const fs::path path = temp_path("context.yaml");
    ASSERT_TRUE(model.save(path, {.gsd_mm_per_px = 0.3}, error)) << error;
    const auto loaded = PlantClassifier::load(path, error);
    ASSERT_TRUE(loaded) << error;
    EXPECT_TRUE(loaded->has_context());
    EXPECT_EQ(loaded->info().context_trees, 20);
    classify_cells(*loaded, frame.cells);
    std::size_t k = 0, differ_from_first_stage = 0;
    Frame again(bgr, params, cell_mm);
    classify_cells(first_stage_only, again.cells);
    for (const std::uint32_t c : frame.cells.vegetated()) {
        EXPECT_EQ(frame.cells.weed_probability(c), before[k++]);
        differ_from_first_stage += again.cells.weed_probability(c) != frame.cells.weed_probability(c);
    }
    EXPECT_GT(differ_from_first_stage, 0u) << "the context forest decides, not the cell forest alone";

    // A file whose context features are not this build's is refused.
    std::ostringstream text;
    text << std::ifstream(path).rdbuf();
    std::string renamed = text.str();
    const auto at = renamed.find("context_plant");
    ASSERT_NE(at, std::string::npos);
    renamed.replace(at, 13, "context_xxxxx");
    std::ofstream(path.string() + ".renamed.yaml") << renamed;
    EXPECT_FALSE(PlantClassifier::load(path.string() + ".renamed.yaml", error));
    EXPECT_NE(error.find("context feature names"), std::string::npos) << error;
    fs::remove(path);
    fs::remove(path.string() + ".renamed.yaml");
}

// add_weed_parts()'s settings at the default bars.
WeedTargetParams targets(double clearance_mm, double cover_radius_mm = 0, std::size_t max_targets = 16)
{
    return {.min_confidence = 0.6,
            .weed_confidence = 0.85,
            .clearance_mm = clearance_mm,
            .cover_radius_mm = cover_radius_mm,
            .max_targets_per_weed = max_targets};
}

// The centre of a cell of 5 px (image coordinates, pixel centres at integers).
cv::Point2f centre_of_cell(const CellWorkspace& cells, std::uint32_t c)
{
    const auto gw = static_cast<std::uint32_t>(cells.grid().width);
    return {static_cast<float>(static_cast<int>(c % gw) * 5 + 2), static_cast<float>(static_cast<int>(c / gw) * 5 + 2)};
}

// Whether every vegetated cell of 5 px whose square comes within
// clearance_px of `at` is weed at the default bar.
bool only_weed_within(const CellWorkspace& cells, cv::Point2f at, double clearance_px)
{
    for (const std::uint32_t c : cells.vegetated()) {
        const cv::Point2f centre = centre_of_cell(cells, c);
        const double dx = std::max({centre.x - 2.5 - at.x, 0.0, at.x - (centre.x + 2.5)});
        const double dy = std::max({centre.y - 2.5 - at.y, 0.0, at.y - (centre.y + 2.5)});
        if (dx * dx + dy * dy <= clearance_px * clearance_px && cells.weed_probability(c) < 0.85f)
            return false;
    }
    return true;
}

// A crop and a weed of `radius` px touching, found as one plant whose
// cells a model trained on such pairs has classified; the plant is
// unknown (half crop, half weed: the blob is not treated).
struct UnsurePair {
    static constexpr int radius = 36;
    const cv::Point crop_centre{114, 110}, weed_centre{186, 110};
    const Params params = test_params();   // 0.3 mm/px: 5 px cells of 1.5 mm
    const PlantClassifier model = pair_model(params, 1.5, 1);
    cv::Mat truth;
    Frame frame{image(truth), params, 1.5};
    std::array<float, kMaxPlants> p{};
    std::array<PlantClass, kMaxPlants> classes{};

    UnsurePair()
    {
        classify_cells(model, frame.cells);
        classify_plants(model, frame.cws, frame.cells, 1, 0.6, 0.85, p, classes);
    }
    static cv::Mat image(cv::Mat& truth)
    {
        cv::Mat bgr;
        touching_pair({320, 240}, {150, 110}, radius, bgr, truth);
        return bgr;
    }
};

TEST(WeedParts, AWeedGrownIntoAnUnsurePlantBecomesATargetOfItsOwnClearOfTheCrop)
{
    UnsurePair pair;
    auto& [crop_centre, weed_centre, params, model, truth, frame, p, classes] = pair;
    const int radius = UnsurePair::radius;
    ASSERT_EQ(frame.det.plants.size(), 1u);
    ASSERT_EQ(classes[0], PlantClass::Unknown) << "half crop, half weed: the blob is not treated";

    const double clearance_mm = 1.5;
    Detections det = frame.det;
    const std::size_t added = add_weed_parts(frame.cells, targets(clearance_mm), det, classes, p).total();
    ASSERT_GE(added, 1u);
    ASSERT_EQ(det.plants.size(), 1 + added);
    const double clearance_px = clearance_mm / params.gsd_mm_per_px;
    for (std::size_t i = 1; i < det.plants.size(); ++i) {
        const Plant& part = det.plants[i];
        EXPECT_EQ(classes[i], PlantClass::Weed);
        EXPECT_GE(p[i], 0.85f);
        EXPECT_TRUE(part.has_stem);
        EXPECT_EQ(part.com_reason, ComReason::weed_part);
        EXPECT_LT(cv::norm(part.stem - cv::Point2f(weed_centre)), radius) << "the target lies on the weed";
        EXPECT_GT(cv::norm(part.stem - cv::Point2f(crop_centre)), radius + clearance_px) << "and clear of the crop";
        // Every classified cell the clearance reaches is weed.
        for (const std::uint32_t c : frame.cells.vegetated()) {
            const int cx = static_cast<int>(c % static_cast<std::uint32_t>(frame.cells.grid().width)) * 5;
            const int cy = static_cast<int>(c / static_cast<std::uint32_t>(frame.cells.grid().width)) * 5;
            const double dx = std::max({cx - 0.5 - part.stem.x, 0.0, part.stem.x - (cx + 4.5)});
            const double dy = std::max({cy - 0.5 - part.stem.y, 0.0, part.stem.y - (cy + 4.5)});
            if (dx * dx + dy * dy <= clearance_px * clearance_px) {
                EXPECT_GE(frame.cells.weed_probability(c), 0.85f) << "cell " << c << " within the clearance";
            }
        }
    }

    // A clearance wider than the weed reaches the crop: no part.
    Detections wide = frame.det;
    EXPECT_EQ(add_weed_parts(frame.cells, targets(30.0), wide, classes, p).total(), 0u);
    EXPECT_EQ(wide.plants.size(), 1u);
    // A plant classed weed keeps its one stem.
    Detections weed = frame.det;
    std::array<PlantClass, kMaxPlants> weed_class{};
    weed_class[0] = PlantClass::Weed;
    EXPECT_EQ(add_weed_parts(frame.cells, targets(clearance_mm), weed, weed_class, p).total(), 0u);
    // No room left among the plants: counted, not written.
    Detections full = frame.det;
    std::array<PlantClass, kMaxPlants> room{};
    room[0] = PlantClass::Unknown;
    EXPECT_EQ(add_weed_parts(frame.cells, targets(clearance_mm), full, std::span<PlantClass>(room.data(), 1),
                             std::span<float>(p.data(), 1)).total(),
              0u);
    EXPECT_EQ(full.stats.plants_over_capacity, frame.det.stats.plants_over_capacity + static_cast<int>(added));
}

TEST(WeedParts, AWeedWithoutAStemOfItsOwnIsStruckAtItsWeedCells)
{
    UnsurePair pair;
    auto& [crop_centre, weed_centre, params, model, truth, frame, p, classes] = pair;
    const int radius = UnsurePair::radius;
    ASSERT_EQ(frame.det.plants.size(), 1u);
    ASSERT_TRUE(frame.det.plants[0].has_stem);
    const double clearance_mm = 1.5;
    std::array<PlantClass, kMaxPlants> weed{};
    weed[0] = PlantClass::Weed;

    // Classed weed with a stem: struck at that stem, nothing added.
    Detections with_stem = frame.det;
    EXPECT_EQ(add_weed_parts(frame.cells, targets(clearance_mm), with_stem, weed, p).total(), 0u);
    // Classed weed without one (grass, or a stem below min_confidence):
    // its weed cells are struck, still clear of every other class.
    Detections stemless = frame.det;
    stemless.plants[0].has_stem = false;
    const std::size_t added = add_weed_parts(frame.cells, targets(clearance_mm), stemless, weed, p).total();
    ASSERT_GE(added, 1u);
    ASSERT_EQ(stemless.plants.size(), 1 + added);
    EXPECT_FALSE(stemless.plants[0].has_stem) << "the plant itself stays stemless";
    const double clearance_px = clearance_mm / params.gsd_mm_per_px;
    for (std::size_t i = 1; i < stemless.plants.size(); ++i) {
        const Plant& part = stemless.plants[i];
        EXPECT_EQ(weed[i], PlantClass::Weed);
        EXPECT_TRUE(part.has_stem);
        EXPECT_EQ(part.com_reason, ComReason::stemless_weed);
        EXPECT_EQ(to_string(part.com_reason), "stemless_weed");
        EXPECT_LT(cv::norm(part.stem - cv::Point2f(weed_centre)), radius) << "on the weed cells";
        EXPECT_GT(cv::norm(part.stem - cv::Point2f(crop_centre)), radius + clearance_px) << "clear of the crop";
    }
}

TEST(WeedParts, AWeedWhoseCentreLiesNearTheCropIsStruckAtItsNearestClearCell)
{
    UnsurePair pair;
    auto& [crop_centre, weed_centre, params, model, truth, frame, p, classes] = pair;
    const int radius = UnsurePair::radius;
    ASSERT_EQ(frame.det.plants.size(), 1u);
    ASSERT_EQ(classes[0], PlantClass::Unknown);

    // Wider than the weed's radius, so the crop lies within it of the
    // weed's centre; narrower than its diameter, so its far side is clear.
    const double clearance_px = 1.3 * radius;
    const double clearance_mm = clearance_px * params.gsd_mm_per_px;
    Detections det = frame.det;
    const std::size_t added = add_weed_parts(frame.cells, targets(clearance_mm), det, classes, p).total();
    ASSERT_GE(added, 1u);
    const int grid_width = frame.cells.grid().width;
    const auto cell_centre = [&](std::uint32_t c) {
        return cv::Point2f(static_cast<float>(static_cast<int>(c % static_cast<std::uint32_t>(grid_width)) * 5 + 2),
                           static_cast<float>(static_cast<int>(c / static_cast<std::uint32_t>(grid_width)) * 5 + 2));
    };
    // Every classified cell within the clearance of `at` is weed.
    const auto clear = [&](cv::Point2f at) {
        for (const std::uint32_t c : frame.cells.vegetated()) {
            const cv::Point2f centre = cell_centre(c);
            const double dx = std::max({centre.x - 2.5 - at.x, 0.0, at.x - (centre.x + 2.5)});
            const double dy = std::max({centre.y - 2.5 - at.y, 0.0, at.y - (centre.y + 2.5)});
            if (dx * dx + dy * dy <= clearance_px * clearance_px && frame.cells.weed_probability(c) < 0.85f)
                return false;
        }
        return true;
    };
    for (std::size_t i = 1; i < det.plants.size(); ++i) {
        const Plant& part = det.plants[i];
        EXPECT_EQ(classes[i], PlantClass::Weed);
        EXPECT_EQ(part.com_reason, ComReason::weed_part);
        EXPECT_FALSE(clear(part.centre_of_mass)) << "the crop lies within the clearance of the weed's centre";
        EXPECT_TRUE(clear(part.stem)) << "the strike has only weed within its clearance";
        EXPECT_LT(cv::norm(part.stem - cv::Point2f(weed_centre)), radius) << "on the weed";
        // No clear weed cell of the plant lies nearer the weed's centre.
        const double moved = cv::norm(part.stem - part.centre_of_mass);
        EXPECT_GT(moved, 0.0);
        for (const std::uint32_t c : frame.cells.vegetated()) {
            if (frame.cells.plant(c) == 1 && frame.cells.weed_probability(c) >= 0.85f && clear(cell_centre(c))) {
                EXPECT_GE(cv::norm(cell_centre(c) - part.centre_of_mass), moved - 1e-3) << "cell " << c;
            }
        }
    }
}

TEST(WeedParts, AWeedWiderThanTheCoverRadiusGetsTargetsUntilEveryClearWeedCellIsInReach)
{
    UnsurePair pair;
    auto& [crop_centre, weed_centre, params, model, truth, frame, p, classes] = pair;
    const int radius = UnsurePair::radius;   // 10.8 mm
    ASSERT_EQ(frame.det.plants.size(), 1u);
    ASSERT_TRUE(frame.det.plants[0].has_stem);
    const double clearance_mm = 1.5, cover_mm = 3.0;
    const double clearance_px = clearance_mm / params.gsd_mm_per_px, cover_px = cover_mm / params.gsd_mm_per_px;
    std::array<PlantClass, kMaxPlants> weed{};
    weed[0] = PlantClass::Weed;

    // Classed weed, once with its own stem (covered from the stem), once
    // without (its weed cells' target first, then cover).
    for (const bool stemless : {false, true}) {
        SCOPED_TRACE(stemless ? "stemless weed plant" : "weed plant with a stem");
        Detections det = frame.det;
        det.plants[0].has_stem = !stemless;
        std::array<PlantClass, kMaxPlants> cls = weed;
        std::array<float, kMaxPlants> prob = p;
        const WeedTargetCounts added = add_weed_parts(frame.cells, targets(clearance_mm, cover_mm, 64), det, cls, prob);
        EXPECT_EQ(added.parts, 0u);
        EXPECT_EQ(added.stemless, stemless ? 1u : 0u);
        ASSERT_GE(added.cover, 3u) << "a weed 7 radii across needs several";
        ASSERT_EQ(det.plants.size(), 1 + added.total());
        std::vector<cv::Point2f> strikes;
        if (!stemless)
            strikes.push_back(det.plants[0].stem);
        for (std::size_t i = 1; i < det.plants.size(); ++i) {
            const Plant& t = det.plants[i];
            EXPECT_EQ(cls[i], PlantClass::Weed);
            EXPECT_TRUE(t.has_stem);
            EXPECT_EQ(t.com_reason, i == 1 && stemless ? ComReason::stemless_weed : ComReason::weed_cover);
            EXPECT_LT(cv::norm(t.stem - cv::Point2f(weed_centre)), radius + 3) << "on the weed";
            EXPECT_TRUE(only_weed_within(frame.cells, t.stem, clearance_px)) << "clear of the crop";
            for (const cv::Point2f& s : strikes)
                EXPECT_GT(cv::norm(t.stem - s), cover_px) << "each further target beyond the reach of the others";
            strikes.push_back(t.stem);
        }
        // Every clear weed cell of the plant lies within reach of a target.
        std::size_t clear_weed_cells = 0;
        for (const std::uint32_t c : frame.cells.vegetated()) {
            const cv::Point2f at = centre_of_cell(frame.cells, c);
            if (frame.cells.plant(c) != 1 || frame.cells.weed_probability(c) < 0.85f ||
                !only_weed_within(frame.cells, at, clearance_px))
                continue;
            ++clear_weed_cells;
            double nearest = 1e9;
            for (const cv::Point2f& s : strikes)
                nearest = std::min(nearest, cv::norm(at - s));
            EXPECT_LE(nearest, cover_px + 1e-3) << "cell " << c;
        }
        EXPECT_GT(clear_weed_cells, 20u);

        // No cover radius: one target per weed; a cap: no more than it.
        Detections one = frame.det;
        one.plants[0].has_stem = !stemless;
        std::array<PlantClass, kMaxPlants> cls_one = weed;
        const WeedTargetCounts single = add_weed_parts(frame.cells, targets(clearance_mm, 0, 64), one, cls_one, prob);
        EXPECT_EQ(single.cover, 0u);
        EXPECT_EQ(single.total(), stemless ? 1u : 0u);
        Detections capped = frame.det;
        capped.plants[0].has_stem = !stemless;
        std::array<PlantClass, kMaxPlants> cls_capped = weed;
        EXPECT_EQ(add_weed_parts(frame.cells, targets(clearance_mm, cover_mm, 3), capped, cls_capped, prob).cover, 2u)
            << "the first target and two more";
    }

    // The same weed grown into a plant the classifier is unsure of: its part
    // is struck once, not covered, since the plant itself is not a weed.
    Detections part = frame.det;
    ASSERT_EQ(classes[0], PlantClass::Unknown);
    const WeedTargetCounts parts = add_weed_parts(frame.cells, targets(clearance_mm, cover_mm, 64), part, classes, p);
    EXPECT_EQ(parts.parts, 1u);
    EXPECT_EQ(parts.cover, 0u);
}

// Steps of a cell of `cells` from `edge` (0 on the edge's row or column).
int steps_from(const CellWorkspace& cells, std::uint32_t c, ImageEdge edge)
{
    const int gw = cells.grid().width, gh = cells.grid().height;
    const int gx = static_cast<int>(c) % gw, gy = static_cast<int>(c) / gw;
    switch (edge) {
    case ImageEdge::top: return gy;
    case ImageEdge::bottom: return gh - 1 - gy;
    case ImageEdge::left: return gx;
    case ImageEdge::right: return gw - 1 - gx;
    }
    return -1;
}

TEST(CellBudget, OverTheBudgetOnlyTheCellsNearestTheFirstEdgeAreClassified)
{
    UnsurePair pair;
    auto& [crop_centre, weed_centre, params, model, truth, frame, p, classes] = pair;
    const std::size_t vegetated = frame.cells.vegetated().size();
    ASSERT_GT(vegetated, 40u);
    // Within the budget (and at exactly its size) nothing changes.
    std::vector<float> unlimited;
    for (const std::uint32_t c : frame.cells.vegetated())
        unlimited.push_back(frame.cells.weed_probability(c));
    for (const std::size_t budget : {vegetated, vegetated + 1}) {
        EXPECT_EQ(classify_cells(model, frame.cells, {.max_cells = budget, .first_edge = ImageEdge::left}), 0u);
        for (std::size_t k = 0; k < vegetated; ++k) {
            EXPECT_EQ(frame.cells.weed_probability(frame.cells.vegetated()[k]), unlimited[k]);
            EXPECT_NE(frame.cells.cell_class(frame.cells.vegetated()[k]), PlantClass::Unknown);
        }
    }
    // Over it: exactly the budget is classified, and no cell left out lies
    // nearer the first edge than a classified one.
    const std::size_t budget = vegetated / 3;
    for (const ImageEdge edge : {ImageEdge::top, ImageEdge::bottom, ImageEdge::left, ImageEdge::right}) {
        SCOPED_TRACE(static_cast<int>(edge));
        EXPECT_EQ(classify_cells(model, frame.cells, {.max_cells = budget, .first_edge = edge}), vegetated - budget);
        std::size_t classified = 0;
        int farthest_classified = -1, nearest_left_out = std::numeric_limits<int>::max();
        for (const std::uint32_t c : frame.cells.vegetated()) {
            const int steps = steps_from(frame.cells, c, edge);
            if (frame.cells.cell_class(c) == PlantClass::Unknown) {
                EXPECT_EQ(frame.cells.weed_probability(c), 0.0f);
                nearest_left_out = std::min(nearest_left_out, steps);
            } else {
                ++classified;
                farthest_classified = std::max(farthest_classified, steps);
            }
        }
        EXPECT_EQ(classified, budget);
        EXPECT_LE(farthest_classified, nearest_left_out);
        // The class map leaves the cells left out at 0.
        cv::Mat map;
        cell_class_map(frame.ws, frame.cells, map);
        for (int y = 0; y < map.rows; ++y)
            for (int x = 0; x < map.cols; ++x) {
                if (frame.ws.vegetation().get(x, y) &&
                    frame.cells.cell_class(frame.cells.cell_of(x, y)) == PlantClass::Unknown) {
                    ASSERT_EQ(map.at<std::uint8_t>(y, x), 0) << x << "," << y;
                }
            }
    }
}

TEST(CellBudget, APlantSeenInPartIsUnknownAndItsWeedPartsStayClearOfTheCellsLeftOut)
{
    UnsurePair pair;
    auto& [crop_centre, weed_centre, params, model, truth, frame, p, classes] = pair;
    ASSERT_EQ(frame.det.plants.size(), 1u);
    // From the right edge: a budget of the cells from the weed's
    // centre rightwards classifies the weed's right half only.
    const int first_column = weed_centre.x / frame.cells.cell_px();
    std::size_t budget = 0;
    for (const std::uint32_t c : frame.cells.vegetated())
        budget += static_cast<int>(c) % frame.cells.grid().width >= first_column ? 1 : 0;
    ASSERT_GT(budget, 10u);
    ASSERT_GT(classify_cells(model, frame.cells, {.max_cells = budget, .first_edge = ImageEdge::right}), budget);

    // What it saw is weed, but it saw only a part: the plant is not judged.
    float share = 0, weight = 0;
    for (const std::uint32_t c : frame.cells.vegetated())
        if (frame.cells.cell_class(c) != PlantClass::Unknown) {
            share += frame.cells.row(c)[c_fill] * frame.cells.weed_probability(c);
            weight += frame.cells.row(c)[c_fill];
        }
    ASSERT_GE(share / weight, 0.85f) << "the cells seen would call the whole plant weed";
    classify_plants(model, frame.cws, frame.cells, 1, 0.6, 0.85, p, classes);
    EXPECT_EQ(p[0], -1.0f);
    EXPECT_EQ(classes[0], PlantClass::Unknown);

    // Its weed cells still get a target, but none within the clearance of
    // a cell left out: that cell may be crop. The clearance is wider than
    // the distance from the weed cells' centre to the cells left out, so
    // the target moves away from them.
    const double clearance_px = 25;
    Detections det = frame.det;
    const std::size_t added =
        add_weed_parts(frame.cells, targets(clearance_px * params.gsd_mm_per_px), det, classes, p).total();
    ASSERT_GE(added, 1u);
    const int cell_px = frame.cells.cell_px(), gw = frame.cells.grid().width;
    for (std::size_t i = 1; i < det.plants.size(); ++i) {
        const cv::Point2f at = det.plants[i].stem;
        EXPECT_LT(cv::norm(at - cv::Point2f(weed_centre)), UnsurePair::radius) << "on the weed";
        for (const std::uint32_t c : frame.cells.vegetated()) {
            if (frame.cells.cell_class(c) != PlantClass::Unknown)
                continue;
            const double left = static_cast<int>(c) % gw * cell_px - 0.5, top = static_cast<int>(c) / gw * cell_px - 0.5;
            const double dx = std::max({left - at.x, 0.0, at.x - (left + cell_px)});
            const double dy = std::max({top - at.y, 0.0, at.y - (top + cell_px)});
            EXPECT_GT(dx * dx + dy * dy, clearance_px * clearance_px) << "cell " << c << " left out, near the target";
        }
    }
}
