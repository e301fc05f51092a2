#include <algorithm>
#include <cmath>

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

// The rule as the header states it, pixel by pixel: a pixel outside the
// plant and above the floor joins when the plant pixels of its window are
// at least a quarter of the window and its index is above the halfway
// point between the soil and their mean.
namespace {

BitMask extend_by_definition(const cv::Mat& index, const BitMask& plant, int floor, int r)
{
    BitMask out = plant;
    const long min_plant_px = static_cast<long>(2 * r + 1) * (2 * r + 1) / 4;
    for (int y = 0; y < index.rows; ++y)
        for (int x = 0; x < index.cols; ++x) {
            const int v = index.at<std::uint8_t>(y, x);
            if (plant.get(x, y) || v <= floor)
                continue;
            long n = 0, s = 0;
            for (int yy = std::max(y - r, 0); yy <= std::min(y + r, index.rows - 1); ++yy)
                for (int xx = std::max(x - r, 0); xx <= std::min(x + r, index.cols - 1); ++xx)
                    if (plant.get(xx, yy)) {
                        ++n;
                        s += index.at<std::uint8_t>(yy, xx);
                    }
            if (n >= min_plant_px && 2 * n * v > n * kSoil + s)
                out.set(x, y);
        }
    return out;
}

}  // namespace

// Sliding column sums against the definition: rows with a few candidates
// and rows with many, widths off the 64-pixel words, radii 1 to 9, floors
// above and under the soil's noise, the same bits.
TEST(MixedEdges, EqualsTheRulePixelByPixelOnRandomFrames)
{
    cv::RNG rng(20261206);
    int joined = 0;
    for (int trial = 0; trial < 40; ++trial) {
        const int width = 70 + static_cast<int>(rng.uniform(0, 200));
        const int height = 20 + static_cast<int>(rng.uniform(0, 40));
        const int r = 1 + trial % 9;
        cv::Mat index(height, width, CV_8UC1);
        rng.fill(index, cv::RNG::UNIFORM, kSoil - 20, kSoil + 20);
        // Leaves: discs of leaf index with mixed pixels around them.
        const int leaves = 1 + static_cast<int>(rng.uniform(0, 12));
        for (int k = 0; k < leaves; ++k) {
            const cv::Point c(rng.uniform(0, width), rng.uniform(0, height));
            const int radius = rng.uniform(2, 14);
            for (int y = std::max(c.y - radius - 3, 0); y < std::min(c.y + radius + 4, height); ++y)
                for (int x = std::max(c.x - radius - 3, 0); x < std::min(c.x + radius + 4, width); ++x) {
                    const double d = std::hypot(x - c.x, y - c.y) - radius;
                    std::uint8_t& v = index.at<std::uint8_t>(y, x);
                    if (d <= 0)
                        v = static_cast<std::uint8_t>(kLeaf - rng.uniform(0, 20));
                    else if (d < 3)
                        v = std::max(v, static_cast<std::uint8_t>(kLeaf - (kLeaf - kSoil) * d / 3 + rng.uniform(-15, 15)));
                }
        }
        const BitMask plant = above(index, 170);
        // A floor under the soil's noise makes every soil pixel a candidate.
        const int floor = kSoil - 25 + static_cast<int>(rng.uniform(0, 55));
        const BitMask got = extend(index, plant, floor, r);
        const BitMask want = extend_by_definition(index, plant, floor, r);
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) {
                ASSERT_EQ(got.get(x, y), want.get(x, y)) << "trial " << trial << " at (" << x << ", " << y << ")";
                joined += want.get(x, y) && !plant.get(x, y);
            }
    }
    EXPECT_GT(joined, 1000);   // the frames exercise the rule, not only the plant
}
