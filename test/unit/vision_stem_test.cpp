#include <gtest/gtest.h>

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

TEST(Stem, FallbacksSayWhy)
{
    Params params;
    params.min_leaves = 3;
    const cv::Point2f com(50, 50);
    const cv::Rect box(0, 0, 100, 100);
    const std::vector<Leaf> two{leaf({20, 10}, {30, 10}), leaf({5, 40}, {5, 50})};
    auto e = estimate_stem(two, com, box, params);
    EXPECT_EQ(e.method, StemMethod::com);
    EXPECT_EQ(e.com_reason, ComReason::too_few_leaves);
    EXPECT_EQ(e.stem, com);

    params.min_leaves = 2;
    e = estimate_stem(two, com, box, params);
    EXPECT_EQ(e.method, StemMethod::leaves);
    EXPECT_NEAR(e.stem.x, 5.0f, 1e-4);

    // The same lines meeting outside the plant's box.
    e = estimate_stem(two, com, cv::Rect(10, 20, 50, 50), params);
    EXPECT_EQ(e.com_reason, ComReason::outside_box);
    EXPECT_EQ(e.stem, com);

    params.stem_method = StemMethod::com;
    e = estimate_stem(two, com, box, params);
    EXPECT_EQ(e.com_reason, ComReason::method_com);

    params.stem_method = StemMethod::leaves;
    const std::vector<Leaf> parallel{leaf({0, 0}, {10, 0}), leaf({0, 5}, {10, 5})};
    e = estimate_stem(parallel, com, box, params);
    EXPECT_EQ(e.com_reason, ComReason::no_intersections);
}
