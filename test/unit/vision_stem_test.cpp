#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/core.hpp>

#include "stemd/vision/stem.hpp"

using namespace stemd::vision;

namespace {

Leaf leaf(cv::Point2f root, cv::Point2f centre)
{
    Leaf l;
    l.root = root;
    l.centre = centre;
    return l;
}

}  // namespace

TEST(Stem, PerpendicularLinesMeetWhereExpected)
{
    // Lines y = 10 (through (20,10)->(30,10)) and x = 5 (through (5,40)->(5,50)).
    const std::vector<Leaf> leaves{leaf({20, 10}, {30, 10}), leaf({5, 40}, {5, 50})};
    const auto p = mean_leaf_intersection(leaves, 0.0);
    ASSERT_TRUE(p.has_value());
    EXPECT_NEAR(p->x, 5.0f, 1e-4);
    EXPECT_NEAR(p->y, 10.0f, 1e-4);
}

TEST(Stem, MeanOfAllPairwiseIntersections)
{
    // Three lines: x = 0, y = 0, x + y = 6 meet pairwise at (0,0), (0,6), (6,0).
    const std::vector<Leaf> leaves{leaf({0, 1}, {0, 2}), leaf({1, 0}, {2, 0}), leaf({3, 3}, {4, 2})};
    const auto p = mean_leaf_intersection(leaves, 0.0);
    ASSERT_TRUE(p.has_value());
    EXPECT_NEAR(p->x, 2.0f, 1e-4);
    EXPECT_NEAR(p->y, 2.0f, 1e-4);
}

TEST(Stem, ParallelAndDirectionlessLeavesAreSkipped)
{
    const std::vector<Leaf> parallel{leaf({0, 0}, {10, 0}), leaf({0, 5}, {-10, 5}), leaf({3, 3}, {3, 3})};
    EXPECT_FALSE(mean_leaf_intersection(parallel, 0.0).has_value());
}

TEST(Stem, MinimumAngleSkipsNearlyParallelPairs)
{
    // Two lines 5 degrees apart and a perpendicular one.
    const float s = std::sin(5.0f * 3.14159265f / 180.0f), c = std::cos(5.0f * 3.14159265f / 180.0f);
    const std::vector<Leaf> leaves{leaf({0, 0}, {10, 0}), leaf({0, 1}, {10 * c, 1 + 10 * s}), leaf({2, 5}, {2, 9})};
    EXPECT_TRUE(mean_leaf_intersection({leaves.data(), 2}, 4.0).has_value());
    EXPECT_FALSE(mean_leaf_intersection({leaves.data(), 2}, 6.0).has_value());
    // With the third leaf, only its two intersections count at 6 degrees.
    const auto p = mean_leaf_intersection(leaves, 6.0);
    ASSERT_TRUE(p.has_value());
    EXPECT_NEAR(p->x, 2.0f, 1e-4);
}

TEST(Stem, PaperFallbacksSayWhy)
{
    Params params;
    params.stem_estimator = StemEstimator::paper;
    params.min_leaves = 3;
    const cv::Point2f com(50, 50);
    const cv::Rect box(0, 0, 100, 100);
    const std::vector<Leaf> two{leaf({20, 10}, {30, 10}), leaf({5, 40}, {5, 50})};
    auto e = estimate_stem(two, com, box, 30, params);
    EXPECT_EQ(e.method, StemMethod::com);
    EXPECT_EQ(e.com_reason, ComReason::too_few_leaves);
    EXPECT_EQ(e.stem, com);

    params.min_leaves = 2;
    e = estimate_stem(two, com, box, 30, params);
    EXPECT_EQ(e.method, StemMethod::leaves);
    EXPECT_EQ(e.estimator, StemEstimator::paper);
    EXPECT_NEAR(e.stem.x, 5.0f, 1e-4);

    // The same lines meeting outside the plant's box.
    e = estimate_stem(two, com, cv::Rect(10, 20, 50, 50), 30, params);
    EXPECT_EQ(e.com_reason, ComReason::outside_box);
    EXPECT_EQ(e.stem, com);

    params.stem_estimator = StemEstimator::com;
    e = estimate_stem(two, com, box, 30, params);
    EXPECT_EQ(e.com_reason, ComReason::method_com);
    EXPECT_EQ(e.estimator, StemEstimator::com);

    params.stem_estimator = StemEstimator::paper;
    const std::vector<Leaf> parallel{leaf({0, 0}, {10, 0}), leaf({0, 5}, {10, 5})};
    e = estimate_stem(parallel, com, box, 30, params);
    EXPECT_EQ(e.com_reason, ComReason::no_intersections);
}

namespace {

// Leaves radiating from `stem` at the given angles (degrees): root `r0`
// from the stem, centre `r1` from it; cuts halfway to the neighbours.
std::vector<Leaf> rosette(cv::Point2f stem, const std::vector<double>& angles_deg, float r0, float r1)
{
    std::vector<Leaf> leaves;
    for (const double a : angles_deg) {
        const double rad = a * 3.14159265358979 / 180.0;
        const cv::Point2f u(static_cast<float>(std::cos(rad)), static_cast<float>(std::sin(rad)));
        Leaf l = leaf(stem + u * r0, stem + u * r1);
        l.cut_a = stem + cv::Point2f(-u.y, u.x) * r0;
        l.cut_b = stem - cv::Point2f(-u.y, u.x) * r0;
        leaves.push_back(l);
    }
    return leaves;
}

}  // namespace

TEST(Stem, LeastSquaresFindsTheCommonPointExactly)
{
    const cv::Point2f stem(120.25f, 80.75f);
    const auto leaves = rosette(stem, {10, 100, 190, 280, 330}, 6, 40);
    const auto fit = fit_leaf_lines(leaves, 2.0);
    ASSERT_TRUE(fit.has_value());
    EXPECT_NEAR(fit->point.x, stem.x, 1e-3);
    EXPECT_NEAR(fit->point.y, stem.y, 1e-3);
    EXPECT_NEAR(fit->rms_px, 0.0, 1e-3);
    EXPECT_EQ(fit->leaves_used, 5);
    EXPECT_GT(fit->conditioning, 0.5);
}

TEST(Stem, AnOutlierLeafLosesItsSay)
{
    const cv::Point2f stem(100, 100);
    auto leaves = rosette(stem, {0, 72, 144, 216, 288}, 6, 40);
    // One leaf cut in the wrong place: its line misses the stem by 25 px.
    leaves[2].root += cv::Point2f(0, 25);
    leaves[2].centre += cv::Point2f(0, 25);
    const auto fit = fit_leaf_lines(leaves, 2.0);
    ASSERT_TRUE(fit.has_value());
    EXPECT_LT(cv::norm(fit->point - stem), 1.0) << fit->point;
    EXPECT_EQ(fit->leaves_used, 4);
    // The plain mean of intersections is pulled much further.
    const auto paper = mean_leaf_intersection(leaves, 0.0);
    ASSERT_TRUE(paper.has_value());
    EXPECT_GT(cv::norm(*paper - stem), 3.0);
}

TEST(Stem, ParallelLinesGiveNoFit)
{
    const std::vector<Leaf> parallel{leaf({0, 0}, {10, 0}), leaf({0, 5}, {-10, 5})};
    const auto fit = fit_leaf_lines(parallel, 2.0);
    ASSERT_TRUE(fit.has_value());
    EXPECT_LT(fit->conditioning, 1e-6);
    EXPECT_FALSE(fit_leaf_lines({parallel.data(), 1}, 2.0).has_value());
}

TEST(Stem, RobustEstimateAndItsConfidence)
{
    Params params;  // robust by default
    const cv::Point2f stem(100, 100), com(130, 95);
    const cv::Rect box(40, 40, 120, 120);
    auto five = rosette(stem, {0, 72, 144, 216, 288}, 6, 40);
    auto e = estimate_stem(five, com, box, 40, params);
    EXPECT_EQ(e.estimator, StemEstimator::robust);
    EXPECT_EQ(e.method, StemMethod::leaves);
    EXPECT_LT(cv::norm(e.stem - stem), 1e-3);
    EXPECT_GT(e.confidence, 0.7f);
    EXPECT_LE(e.confidence, 1.0f);

    // Two leaves give a fix too, with less confidence than five.
    const auto two = rosette(stem, {0, 90}, 6, 40);
    const auto e2 = estimate_stem(two, com, box, 40, params);
    EXPECT_EQ(e2.method, StemMethod::leaves);
    EXPECT_LT(e2.confidence, e.confidence);

    // Nearly opposite leaves do not pin a point down: the cut points' mean.
    const auto opposite = rosette(stem, {0, 178}, 6, 40);
    const auto e3 = estimate_stem(opposite, com, box, 40, params);
    EXPECT_EQ(e3.estimator, StemEstimator::robust);
    EXPECT_LT(cv::norm(e3.stem - stem), 1.0);
    EXPECT_LT(e3.confidence, e2.confidence);

    // No leaves: the centre of mass, low confidence.
    const auto e4 = estimate_stem({}, com, box, 40, params);
    EXPECT_EQ(e4.method, StemMethod::com);
    EXPECT_EQ(e4.com_reason, ComReason::too_few_leaves);
    EXPECT_EQ(e4.stem, com);
    EXPECT_GT(e4.confidence, 0.0f);
    EXPECT_LT(e4.confidence, e3.confidence + 0.1f);
}

TEST(Stem, ElongatedLeavesUseTheirAxisNotTheirRoot)
{
    // Radial leaves whose roots were pushed sideways (a neighbour overlapped
    // the cut): the principal axes through the centroids still meet at the stem.
    const cv::Point2f stem(60, 60);
    auto leaves = rosette(stem, {0, 120, 240}, 6, 40);
    const float shift_px[] = {5.0f, -3.0f, 0.0f};  // unequal, so no symmetry hides the bias
    for (std::size_t i = 0; i < leaves.size(); ++i) {
        Leaf& l = leaves[i];
        const cv::Point2f u = (l.centre - stem) * (1.0f / 40.0f);
        l.axis = u;
        l.elongation = 4;
        l.root += cv::Point2f(-u.y, u.x) * shift_px[i];  // off the midrib
    }
    const auto fit = fit_leaf_lines(leaves, 2.0);
    ASSERT_TRUE(fit.has_value());
    EXPECT_LT(cv::norm(fit->point - stem), 1e-3);

    // Round leaves (no clear axis) fall back to root -> centre, which the
    // displaced roots now bend away from the stem.
    for (Leaf& l : leaves)
        l.elongation = 1.2f;
    const auto round = fit_leaf_lines(leaves, 2.0);
    ASSERT_TRUE(round.has_value());
    EXPECT_GT(cv::norm(round->point - stem), 0.3);
}
