#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/edges.hpp"

using namespace stemd::vision;

namespace {

constexpr int kSoil = 100;
constexpr int kLeaf = 200;

// Soil at kSoil with a leaf (index kLeaf) filling columns [20, 40) of every
// row; the two columns left of it are mixed pixels at `outer` (x 18) and
// `inner` (x 19).
cv::Mat leaf_edge(int outer, int inner)
{
    cv::Mat index(30, 60, CV_8UC1, cv::Scalar(kSoil));
    index(cv::Rect(20, 0, 20, 30)).setTo(kLeaf);
    index.col(18).setTo(outer);
    index.col(19).setTo(inner);
    return index;
}

BitMask above(const cv::Mat& index, int threshold)
{
    BitMask bits(index.cols, index.rows);
    for (int y = 0; y < index.rows; ++y)
        for (int x = 0; x < index.cols; ++x)
            if (index.at<std::uint8_t>(y, x) > threshold)
                bits.set(x, y);
    return bits;
}

BitMask extend(const cv::Mat& index, const BitMask& plant, int floor, int radius_px)
{
    EdgeScratch scratch;
    scratch.reserve(index.cols, index.rows);
    BitMask out(index.cols, index.rows);
    extend_to_mixed_edges(index, plant, kSoil, floor, radius_px, out, scratch);
    return out;
}

}  // namespace

TEST(MixedEdges, PixelsMoreThanHalfLeafJoinThePlantAndLessThanHalfDoNot)
{
    // Halfway between soil (100) and leaf (200) is 150: 160 is mostly leaf,
    // 140 mostly soil. The threshold (180) took neither.
    const cv::Mat index = leaf_edge(140, 160);
    const BitMask plant = above(index, 180);
    const BitMask out = extend(index, plant, kSoil, 3);
    for (int y = 0; y < index.rows; ++y) {
        EXPECT_TRUE(out.get(19, y)) << y;
        EXPECT_FALSE(out.get(18, y)) << y;
        for (int x = 20; x < 40; ++x)
            ASSERT_TRUE(out.get(x, y));
        EXPECT_FALSE(out.get(40, y));
    }
    EXPECT_EQ(out.count(), plant.count() + index.rows);
}

TEST(MixedEdges, NothingBeyondTheRadiusNorBelowTheFloor)
{
    cv::Mat index = leaf_edge(kSoil, 160);
    // Farther than the radius (2) from the leaf: never added, however green.
    index.col(5).setTo(170);
    const BitMask plant = above(index, 180);
    const BitMask out = extend(index, plant, kSoil, 2);
    EXPECT_EQ(out.count(), plant.count() + index.rows);
    EXPECT_FALSE(out.get(5, 10));
    // A floor above the mixed pixels keeps them out.
    EXPECT_EQ(extend(index, plant, 170, 2).count(), plant.count());
    // Radius 0: the plant as it was.
    EXPECT_EQ(extend(index, plant, kSoil, 0).count(), plant.count());
}

TEST(MixedEdges, AnEmptyPlantMaskStaysEmpty)
{
    const cv::Mat index = leaf_edge(160, 160);
    const BitMask none(index.cols, index.rows);
    EXPECT_EQ(extend(index, none, kSoil, 5).count(), 0);
}

TEST(MixedEdges, ASpeckDoesNotGrowIntoTheSoil)
{
    // A 2x2 speck at the leaf level, ringed by pixels just above halfway:
    // it fills far less than a quarter of the 7x7 window, so it is no leaf
    // edge and stays as it was.
    cv::Mat index(30, 30, CV_8UC1, cv::Scalar(kSoil));
    index(cv::Rect(12, 12, 6, 6)).setTo(160);
    index(cv::Rect(14, 14, 2, 2)).setTo(kLeaf);
    const BitMask plant = above(index, 180);
    ASSERT_EQ(plant.count(), 4);
    EXPECT_EQ(extend(index, plant, kSoil, 3).count(), 4);
}

TEST(MixedEdges, SoilLevelIsTheHistogramMode)
{
    Histogram h{};
    h[99] = 50;
    h[100] = 60;
    h[101] = 55;
    h[200] = 100;  // one level of leaf, narrower than the soil's three
    EXPECT_EQ(histogram_mode(h), 100);
}
