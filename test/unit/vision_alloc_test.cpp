// Real-time discipline: once a Workspace exists, detect() must not touch
// the heap. Every operator new in this test binary is counted.
#include <gtest/gtest.h>

#include "counting_new.hpp"

#include <atomic>
#include <cstdlib>
#include <memory>
#include <new>

#include <opencv2/imgproc.hpp>

#include "stemd/vision/cells.hpp"
#include "stemd/vision/classify.hpp"
#include "stemd/vision/detect.hpp"
#include "vision_test_util.hpp"


using namespace stemd::vision;

namespace {

// A busy frame: many plants (bright in the NIR plane too), noise,
// vegetation on the border.
struct BusyFrame {
    BusyFrame(cv::Size size, std::uint64_t seed)
        : plants(stemd::test::random_blob_mask(size, seed, 150, 0.001)),
          bgr(size, CV_8UC3, cv::Scalar(60, 80, 110)),
          nir(size, CV_8UC1, cv::Scalar(80))
    {
        bgr.setTo(cv::Scalar(40, 160, 50), plants);
        nir.setTo(220, plants);
    }
    cv::Mat plants, bgr, nir;
};

}  // namespace

TEST(RealTime, DetectAllocatesNothingOnceTheWorkspaceExists)
{
    const cv::Size size(1296, 966);
    const BusyFrame busy(size, 77);
    const cv::Mat &bgr = busy.bgr, &nir = busy.nir, &plants = busy.plants;

    Params params;
    params.min_plant_area_mm2 = 0;
    params.defect_depth_mm = 0.5;
    params.closing_radius_px = 3;
    params.min_leaves = 2;
    auto ws = std::make_unique<Workspace>(size, params);
    auto out = std::make_unique<Detections>();
    EXPECT_GT(ws->reserved_bytes(), 0u);

    for (const Segmentation seg :
         {Segmentation::exg, Segmentation::ndvi, Segmentation::mask, Segmentation::exg_and_ndvi, Segmentation::automatic}) {
        for (const ThresholdMethod t : {ThresholdMethod::otsu, ThresholdMethod::triangle, ThresholdMethod::min_error}) {
            params.segmentation = seg;
            params.threshold = t;
            StageTimes times;
            const FrameView frame{bgr, nir, plants};
            const long before = stemd::test::allocations();
            detect(frame, params, *ws, *out, &times);
            const long after = stemd::test::allocations();
            ASSERT_EQ(out->status, DetectStatus::ok);
            EXPECT_GT(out->plants.size(), 10u);
            EXPECT_EQ(after - before, 0) << "heap allocations in detect(): " << to_string(seg) << " " << to_string(t);
        }
    }
}

TEST(RealTime, TheCounterSeesAllocations)
{
    // Guards the test above: if operator new were not replaced it would pass vacuously.
    const long before = stemd::test::allocations();
    auto p = std::make_unique<int>(3);
    EXPECT_EQ(stemd::test::allocations() - before, 1);
    EXPECT_EQ(*p, 3);
}

TEST(RealTime, ClassifierAllocatesNothingOnceWarm)
{
    const cv::Size size(1296, 966);
    const BusyFrame busy(size, 78);
    const cv::Mat &bgr = busy.bgr, &nir = busy.nir;
    Params params;
    auto ws = std::make_unique<Workspace>(size, params);
    auto out = std::make_unique<Detections>();
    const FrameView frame{bgr, nir, {}};
    detect(frame, params, *ws, *out);
    ASSERT_GT(out->plants.size(), 10u);

    cv::Mat samples(40, kPlantFeatureCount, CV_32FC1), labels(40, 1, CV_32SC1);
    cv::RNG rng(4);
    rng.fill(samples, cv::RNG::UNIFORM, 0, 1);
    for (int i = 0; i < labels.rows; ++i)
        labels.at<int>(i) = i % 2 ? 1 : 2;
    std::string error;
    const auto model = PlantClassifier::train(samples, labels, {.trees = 30}, error);
    ASSERT_TRUE(model) << error;
    auto cws = std::make_unique<ClassifyWorkspace>(size, params);
    std::array<stemd::PlantClass, kMaxPlants> classes{};
    cv::Mat map(size, CV_8UC1);

    long before = stemd::test::allocations();
    plant_features(frame, params, *ws, *out, *cws);
    EXPECT_EQ(stemd::test::allocations() - before, 0) << "heap allocations in plant_features";
    float sum = 0;
    before = stemd::test::allocations();
    for (std::size_t i = 0; i < cws->features().size(); ++i) {
        const float p = model->weed_probability(cws->features()[i]);
        sum += p;
        classes[i] = decide_class(p, 0.6, 0.85);
    }
    EXPECT_EQ(stemd::test::allocations() - before, 0) << "heap allocations in weed_probability";
    before = stemd::test::allocations();
    class_map(*ws, *cws, {classes.data(), cws->features().size()}, map);
    EXPECT_EQ(stemd::test::allocations() - before, 0) << "heap allocations in class_map";
    EXPECT_GE(sum, 0.0f);

    // The cells: features, both forests and the context between them, class
    // map, the plants' share and the weed parts.
    cv::Mat cell_samples(60, kCellFeatureCount, CV_32FC1), cell_labels(60, 1, CV_32SC1);
    rng.fill(cell_samples, cv::RNG::UNIFORM, 0, 1);
    for (int i = 0; i < cell_labels.rows; ++i)
        cell_labels.at<int>(i) = i % 2 ? 1 : 2;
    auto cell_model = PlantClassifier::train(samples, labels, {.trees = 5}, error);
    ASSERT_TRUE(cell_model) << error;
    ASSERT_TRUE(cell_model->train_cells(cell_samples, cell_labels, {.trees = 30}, 3.0, error)) << error;
    cv::Mat context_samples(60, kContextFeatureCount, CV_32FC1);
    rng.fill(context_samples, cv::RNG::UNIFORM, 0, 1);
    ASSERT_TRUE(cell_model->train_context(context_samples, cell_labels, {.trees = 30}, error)) << error;
    auto cells = std::make_unique<CellWorkspace>(size, 0.11, 3.0);
    std::array<float, kMaxPlants> probabilities{};
    auto with_parts = std::make_unique<Detections>();
    for (int round = 0; round < 2; ++round) {   // the second frame reuses what the first left
        before = stemd::test::allocations();
        cell_features(frame, params, *ws, *out, *cws, *cells);
        // Over a budget too: the cells nearest the first edge are picked in
        // the workspace's own buffers.
        EXPECT_GT(classify_cells(*cell_model, *cells, {.max_cells = 50, .first_edge = ImageEdge::right}), 0u);
        classify_cells(*cell_model, *cells);
        cell_class_map(*ws, *cells, map);
        classify_plants(*cell_model, *cws, *cells, out->plants.size(), 0.6, 0.85, probabilities, classes);
        *with_parts = *out;
        add_weed_parts(*cells, {.min_confidence = 0.5, .weed_confidence = 0.5, .clearance_mm = 1.0, .cover_radius_mm = 2.0},
                       *with_parts, classes, probabilities);
        EXPECT_EQ(stemd::test::allocations() - before, 0) << "heap allocations in the cells, round " << round;
    }
    EXPECT_GT(cells->vegetated().size(), 100u);
}
