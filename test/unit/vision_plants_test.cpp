#include <gtest/gtest.h>

#include <map>

#include <opencv2/imgproc.hpp>

#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/plants.hpp"
#include "vision_test_util.hpp"

using namespace stemd::vision;

namespace {

std::vector<Component> label(const cv::Mat& mask)
{
    return stemd::test::LabelledMask(mask).components;
}

}  // namespace

TEST(Plants, SameComponentsAsOpenCvEightConnected)
{
    for (std::uint64_t seed = 1; seed <= 30; ++seed) {
        const cv::Mat mask = stemd::test::random_blob_mask({150 + static_cast<int>(seed), 90}, seed, 25, 0.01);
        cv::Mat labels, stats, centroids;
        const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
        const auto ours = label(mask);
        ASSERT_EQ(static_cast<int>(ours.size()), n - 1) << "seed " << seed;
        // Match by the label OpenCV gives our first pixel.
        for (const Component& c : ours) {
            const int l = labels.at<int>(c.first_pixel.y, c.first_pixel.x);
            ASSERT_GT(l, 0);
            EXPECT_EQ(c.area_px, stats.at<int>(l, cv::CC_STAT_AREA));
            EXPECT_EQ(c.x_min, stats.at<int>(l, cv::CC_STAT_LEFT));
            EXPECT_EQ(c.y_min, stats.at<int>(l, cv::CC_STAT_TOP));
            EXPECT_EQ(c.x_max - c.x_min + 1, stats.at<int>(l, cv::CC_STAT_WIDTH));
            EXPECT_EQ(c.y_max - c.y_min + 1, stats.at<int>(l, cv::CC_STAT_HEIGHT));
            EXPECT_NEAR(c.sum_x / c.area_px, centroids.at<double>(l, 0), 1e-9);
            EXPECT_NEAR(c.sum_y / c.area_px, centroids.at<double>(l, 1), 1e-9);
        }
    }
}

TEST(Plants, ComponentsComeInRasterOrderOfTheirFirstPixel)
{
    const auto ours = label(stemd::test::random_blob_mask({300, 200}, 7, 40, 0.0));
    ASSERT_GT(ours.size(), 3u);
    for (std::size_t i = 1; i < ours.size(); ++i) {
        const auto& a = ours[i - 1].first_pixel;
        const auto& b = ours[i].first_pixel;
        EXPECT_TRUE(a.y < b.y || (a.y == b.y && a.x < b.x));
    }
    // The first pixel really is the top-most, then left-most one.
    for (const auto& c : ours)
        EXPECT_EQ(c.first_pixel.y, c.y_min);
}

TEST(Plants, HolesAreNotPlantsButIslandsAre)
{
    cv::Mat ring = cv::Mat::zeros(100, 100, CV_8UC1);
    cv::circle(ring, {50, 50}, 30, 255, 6);
    auto ours = label(ring);
    ASSERT_EQ(ours.size(), 1u);
    cv::circle(ring, {50, 50}, 5, 255, cv::FILLED);  // an island inside the hole
    ours = label(ring);
    EXPECT_EQ(ours.size(), 2u);
}

TEST(Plants, DiagonalNeighboursJoin)
{
    cv::Mat mask = cv::Mat::zeros(10, 10, CV_8UC1);
    for (int i = 0; i < 10; ++i)
        mask.at<std::uint8_t>(i, i) = 255;
    const auto ours = label(mask);
    ASSERT_EQ(ours.size(), 1u);
    EXPECT_EQ(ours[0].area_px, 10);
}

TEST(Plants, ComponentAtFindsThePixelsComponent)
{
    for (const std::uint64_t seed : {1u, 2u, 3u}) {
        const cv::Mat mask = stemd::test::random_blob_mask({131, 67}, seed, 10, 0.05);
        const stemd::test::LabelledMask labelled(mask);
        const std::vector<Component>& components = labelled.components;
        const LabelScratch& scratch = labelled.scratch;
        cv::Mat labels;
        const int n = cv::connectedComponents(mask, labels, 8, CV_32S, cv::CCL_DEFAULT);
        ASSERT_EQ(static_cast<int>(components.size()), n - 1);
        EXPECT_EQ(scratch.component_count(), components.size());
        // OpenCV's label of each component's first pixel names the same set.
        std::vector<int> ours_for_theirs(static_cast<std::size_t>(n), -2);
        for (int y = 0; y < mask.rows; ++y)
            for (int x = 0; x < mask.cols; ++x) {
                const int ours = component_at(scratch, {x, y});
                const int theirs = labels.at<int>(y, x);
                if (theirs == 0) {
                    ASSERT_EQ(ours, -1) << x << "," << y;
                    continue;
                }
                ASSERT_GE(ours, 0);
                int& seen = ours_for_theirs[static_cast<std::size_t>(theirs)];
                if (seen == -2)
                    seen = ours;
                ASSERT_EQ(seen, ours) << x << "," << y;
            }
        EXPECT_EQ(component_at(scratch, {-1, 0}), -1);
        EXPECT_EQ(component_at(scratch, {0, mask.rows}), -1);
    }
}

TEST(Plants, LabelledRunsTileTheMaskInRasterOrderWithTheirComponents)
{
    for (const std::uint64_t seed : {1u, 2u, 3u}) {
        const cv::Mat mask = stemd::test::random_blob_mask({131, 67}, seed, 10, 0.05);
        const stemd::test::LabelledMask labelled(mask);
        const LabelScratch& scratch = labelled.scratch;
        cv::Mat drawn = cv::Mat::zeros(mask.size(), CV_8UC1);
        int last_y = -1, last_x1 = -2;
        for (std::size_t k = 0; k < scratch.run_count(); ++k) {
            const LabelScratch::LabelledRun run = scratch.run(k);
            // Raster order, maximal runs: a run on the same row starts past
            // the gap after the one before it.
            ASSERT_TRUE(run.y > last_y || (run.y == last_y && run.x0 > last_x1 + 1)) << "run " << k;
            ASSERT_LE(run.x0, run.x1);
            if (run.x0 > 0) {
                ASSERT_EQ(mask.at<std::uint8_t>(run.y, run.x0 - 1), 0) << "run " << k;
            }
            if (run.x1 + 1 < mask.cols) {
                ASSERT_EQ(mask.at<std::uint8_t>(run.y, run.x1 + 1), 0) << "run " << k;
            }
            for (int x = run.x0; x <= run.x1; ++x) {
                drawn.at<std::uint8_t>(run.y, x) = 255;
                ASSERT_EQ(run.component, component_at(scratch, {x, run.y})) << x << "," << run.y;
            }
            last_y = run.y;
            last_x1 = run.x1;
        }
        EXPECT_EQ(cv::countNonZero(drawn != mask), 0);
    }
}
