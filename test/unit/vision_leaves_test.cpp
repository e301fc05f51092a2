#include <gtest/gtest.h>

#include <set>

#include <opencv2/imgproc.hpp>

#include "stemd/vision/contour.hpp"
#include "stemd/vision/leaves.hpp"
#include "stemd/vision/plants.hpp"
#include "vision_test_util.hpp"

using namespace stemd::vision;

namespace {

std::vector<cv::Point> largest_contour(const cv::Mat& mask)
{
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(mask.clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
    std::size_t best = 0;
    for (std::size_t i = 0; i < contours.size(); ++i)
        if (contours[i].size() > contours[best].size())
            best = i;
    return contours.empty() ? std::vector<cv::Point>{} : contours[best];
}

// A plus: two 21 px wide bars across a 101 x 101 mask, its inner corners
// at (40|60, 40|60).
cv::Mat plus_mask()
{
    cv::Mat mask = cv::Mat::zeros(101, 101, CV_8UC1);
    mask(cv::Rect(40, 0, 21, 101)).setTo(255);
    mask(cv::Rect(0, 40, 101, 21)).setTo(255);
    return mask;
}

std::vector<int> hull_of(const std::vector<cv::Point>& contour)
{
    std::vector<int> hull, order;
    order.reserve(contour.size());
    hull.reserve(contour.size() + 1);
    convex_hull_indices(contour, hull, order);
    return hull;
}

}  // namespace

TEST(Hull, SameVerticesAsOpenCv)
{
    for (std::uint64_t seed = 1; seed <= 30; ++seed) {
        const auto contour = largest_contour(stemd::test::random_blob_mask({100, 100}, seed, 10, 0.0));
        if (contour.size() < 3)
            continue;
        const auto hull = hull_of(contour);
        std::set<std::pair<int, int>> ours, theirs;
        for (const int i : hull)
            ours.insert({contour[static_cast<std::size_t>(i)].x, contour[static_cast<std::size_t>(i)].y});
        std::vector<cv::Point> cv_hull;
        cv::convexHull(contour, cv_hull);
        for (const auto& p : cv_hull)
            theirs.insert({p.x, p.y});
        EXPECT_EQ(ours, theirs) << "seed " << seed;
        EXPECT_TRUE(std::is_sorted(hull.begin(), hull.end()));
    }
}

namespace {

// The contour's convexity defects deeper than min_depth_px.
std::vector<Defect> defects_of(const std::vector<cv::Point>& contour, float min_depth_px)
{
    std::vector<Defect> defects;
    defects.reserve(64);
    convexity_defects(contour, hull_of(contour), min_depth_px, defects);
    return defects;
}

}  // namespace

TEST(Defects, PlusShapeHasFourDeepCuts)
{
    const auto contour = largest_contour(plus_mask());
    const auto defects = defects_of(contour, 5.0f);
    ASSERT_EQ(defects.size(), 4u);
    for (const auto& d : defects) {
        const cv::Point cut = contour[static_cast<std::size_t>(d.deepest)];
        // At an inner corner of the plus, (40|60, 40|60); the 8-connected
        // border cuts the corner pixel itself diagonally, so allow one pixel.
        const int corner_x = cut.x < 50 ? 40 : 60, corner_y = cut.y < 50 ? 40 : 60;
        EXPECT_LE(std::abs(cut.x - corner_x) + std::abs(cut.y - corner_y), 1) << cut;
        EXPECT_NEAR(d.depth_px, 40.0 / std::sqrt(2.0) * 1.0, 1.5);
    }
    FixedVector<Leaf, kMaxLeaves> leaves;
    EXPECT_EQ(leaves_from_defects(contour, defects, leaves), 0);
    ASSERT_EQ(leaves.size(), 4u);
    for (const auto& leaf : leaves) {
        // Each arm: root at the arm's base, centre out along the arm's axis.
        const cv::Point2f dir = leaf.centre - leaf.root;
        EXPECT_GT(std::hypot(dir.x, dir.y), 10.0f);
        EXPECT_TRUE(std::abs(leaf.root.x - 50) <= 0.5f || std::abs(leaf.root.y - 50) <= 0.5f) << leaf.root;
    }
}

TEST(Defects, ThresholdIsStrict)
{
    const auto defects = defects_of(largest_contour(plus_mask()), 100.0f);
    EXPECT_TRUE(defects.empty());
}

TEST(Defects, NeverThrowWhereOpenCvConvexityDefectsDoes)
{
    // Random thin, self-touching shapes make OpenCV's hull indices
    // non-monotonous; the paper's code dies there. Ours must not.
    int opencv_threw = 0;
    for (std::uint64_t seed = 1; seed <= 400 && opencv_threw < 3; ++seed) {
        cv::Mat mask = cv::Mat::zeros(60, 60, CV_8UC1);
        cv::RNG rng(seed);
        for (int i = 0; i < 6; ++i)
            cv::line(mask, {rng.uniform(0, 60), rng.uniform(0, 60)}, {rng.uniform(0, 60), rng.uniform(0, 60)}, 255, 1);
        const auto contour = largest_contour(mask);
        if (contour.size() < 4)
            continue;
        std::vector<int> cv_hull;
        cv::convexHull(contour, cv_hull, false, false);
        std::vector<cv::Vec4i> cv_defects;
        try {
            cv::convexityDefects(contour, cv_hull, cv_defects);
        } catch (const cv::Exception&) {
            ++opencv_threw;
            const auto hull = hull_of(contour);
            std::vector<Defect> defects;
            defects.reserve(256);
            EXPECT_NO_THROW(convexity_defects(contour, hull, 2.0f, defects));
            FixedVector<Leaf, kMaxLeaves> leaves;
            EXPECT_NO_THROW(leaves_from_defects(contour, defects, leaves));
            for (const auto& d : defects)
                EXPECT_LT(static_cast<std::size_t>(d.deepest), contour.size());
        }
    }
    EXPECT_GT(opencv_threw, 0) << "no mask made OpenCV throw; the test shows nothing";
}

TEST(Leaves, FewerThanTwoCutsGiveNoLeaves)
{
    const std::vector<cv::Point> square{{0, 0}, {0, 1}, {1, 1}, {1, 0}};
    std::vector<Defect> one{{0, 2, 1, 5.0f}};
    FixedVector<Leaf, kMaxLeaves> leaves;
    EXPECT_EQ(leaves_from_defects(square, one, leaves), 0);
    EXPECT_TRUE(leaves.empty());
}

TEST(Hull, AreaCoversThePixelSquares)
{
    // Convex blobs: the hull around the pixel squares has their pixel count.
    cv::Mat mask = cv::Mat::zeros(60, 60, CV_8UC1);
    mask(cv::Rect(10, 20, 30, 12)).setTo(255);
    auto contour = largest_contour(mask);
    EXPECT_NEAR(convex_hull_area_px(contour, hull_of(contour)), 360.0, 1e-9);
    mask.setTo(0);
    mask(cv::Rect(5, 7, 25, 1)).setTo(255);  // a one-pixel line: its hull has no area inside
    contour = largest_contour(mask);
    EXPECT_NEAR(convex_hull_area_px(contour, hull_of(contour)), 25.0, 1e-9);
    mask.setTo(0);
    mask.at<std::uint8_t>(3, 4) = 255;
    contour = largest_contour(mask);
    EXPECT_NEAR(convex_hull_area_px(contour, hull_of(contour)), 1.0, 1e-9);
    cv::circle(mask, {30, 30}, 20, 255, cv::FILLED);
    contour = largest_contour(mask);
    EXPECT_NEAR(convex_hull_area_px(contour, hull_of(contour)) / cv::countNonZero(mask(cv::Rect(5, 5, 55, 55))), 1.0,
                0.05);
    EXPECT_EQ(convex_hull_area_px(contour, {}), 0.0);
}
