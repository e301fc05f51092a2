#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/threshold.hpp"
#include "vision_test_util.hpp"

using namespace stemd::vision;

namespace {

// Images with very different histograms: bimodal, skewed, flat, two levels.
cv::Mat test_image(int kind, std::uint64_t seed)
{
    cv::RNG rng(seed);
    cv::Mat img(61, 97, CV_8UC1);
    for (int y = 0; y < img.rows; ++y) {
        for (int x = 0; x < img.cols; ++x) {
            double v = 0;
            switch (kind) {
            case 0: v = rng.uniform(0, 3) == 0 ? rng.gaussian(20) + 180 : rng.gaussian(15) + 60; break;
            case 1: v = rng.uniform(0, 10) == 0 ? rng.uniform(100, 256) : rng.gaussian(6) + 110; break;
            case 2: v = rng.uniform(0, 256); break;
            case 3: v = rng.uniform(0, 2) ? 40 : 200; break;
            default: v = rng.uniform(0, 20) == 0 ? rng.gaussian(8) + 40 : rng.gaussian(10) + 200; break;
            }
            img.at<std::uint8_t>(y, x) = cv::saturate_cast<std::uint8_t>(v);
        }
    }
    return img;
}

}  // namespace

TEST(Threshold, OtsuEqualsOpenCv)
{
    for (int kind = 0; kind < 5; ++kind) {
        for (std::uint64_t seed = 1; seed <= 20; ++seed) {
            const cv::Mat img = test_image(kind, seed);
            Histogram h;
            compute_histogram(img, h);
            cv::Mat ignored;
            const int expected = static_cast<int>(cv::threshold(img, ignored, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU));
            EXPECT_EQ(otsu_threshold(h), expected) << "kind " << kind << " seed " << seed;
        }
    }
}

TEST(Threshold, TriangleEqualsOpenCv)
{
    for (int kind = 0; kind < 5; ++kind) {
        for (std::uint64_t seed = 1; seed <= 20; ++seed) {
            const cv::Mat img = test_image(kind, seed);
            Histogram h;
            compute_histogram(img, h);
            cv::Mat ignored;
            const int expected =
                static_cast<int>(cv::threshold(img, ignored, 0, 255, cv::THRESH_BINARY | cv::THRESH_TRIANGLE));
            EXPECT_EQ(triangle_threshold(h), expected) << "kind " << kind << " seed " << seed;
        }
    }
}

TEST(Threshold, DegenerateHistogramsDoNotCrash)
{
    Histogram empty{};
    EXPECT_EQ(otsu_threshold(empty), 0);
    EXPECT_EQ(triangle_threshold(empty), 0);
    Histogram single{};
    single[77] = 1000;
    EXPECT_GE(otsu_threshold(single), 0);
    EXPECT_LE(triangle_threshold(single), 255);
}

TEST(Threshold, HistogramCountsEveryPixel)
{
    const cv::Mat img = test_image(0, 3);
    Histogram h;
    compute_histogram(img, h);
    long total = 0;
    for (const auto n : h)
        total += n;
    EXPECT_EQ(total, img.total());
    EXPECT_EQ(h[img.at<std::uint8_t>(5, 7)] > 0, true);
}

TEST(Threshold, BitsEqualComparisonForAnyWidth)
{
    for (const int width : {1, 63, 64, 65, 127, 128, 200}) {
        cv::Mat img(7, width, CV_8UC1);
        cv::randu(img, 0, 256);
        for (const int t : {0, 1, 127, 128, 200, 254, 255}) {
            BitMask bits;
            threshold_to_bits(img, t, bits);
            for (int y = 0; y < img.rows; ++y)
                for (int x = 0; x < width; ++x)
                    ASSERT_EQ(bits.get(x, y), img.at<std::uint8_t>(y, x) > t) << width << " " << t;
            // Bits past the width stay clear.
            EXPECT_EQ(bits.row(0)[bits.words_per_row() - 1] & ~bits.last_word_mask(), 0u);
        }
    }
}

TEST(BitMask, PackUnpackRoundTripAndZeroVegetation)
{
    const cv::Mat mask = stemd::test::random_blob_mask({130, 40}, 5, 20, 0.01);
    BitMask bits;
    pack_mask(mask, MaskVegetation::nonzero, bits);
    cv::Mat back;
    unpack_mask(bits, back);
    EXPECT_EQ(cv::countNonZero(back != mask), 0);
    EXPECT_EQ(bits.count(), cv::countNonZero(mask));

    pack_mask(mask, MaskVegetation::zero, bits);
    EXPECT_EQ(bits.count(), static_cast<long>(mask.total()) - cv::countNonZero(mask));
    EXPECT_EQ(bits.row(3)[bits.words_per_row() - 1] & ~bits.last_word_mask(), 0u);
}
