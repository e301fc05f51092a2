#include <gtest/gtest.h>

#include <initializer_list>

#include <opencv2/imgproc.hpp>

#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/closing.hpp"
#include "vision_test_util.hpp"

using namespace stemd::vision;

namespace {

cv::Mat opencv_close(const cv::Mat& mask, int radius)
{
    if (radius == 0)
        return mask.clone();
    const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1));
    cv::Mat out;
    cv::morphologyEx(mask, out, cv::MORPH_CLOSE, kernel);
    return out;
}

// `morphology` (close_mask, open_mask, dilate_mask, erode_mask) of a 0/255 mask.
using Morphology = void (*)(const BitMask&, int, BitMask&, ClosingScratch&);
cv::Mat ours(Morphology morphology, const cv::Mat& mask, int radius)
{
    BitMask in, out;
    ClosingScratch scratch;
    pack_mask(mask, MaskVegetation::nonzero, in);
    morphology(in, radius, out, scratch);
    cv::Mat result;
    unpack_mask(out, result);
    return result;
}

cv::Mat our_close(const cv::Mat& mask, int radius)
{
    return ours(close_mask, mask, radius);
}

// `morphology` against cv::morphologyEx(`opencv_op`) with the same ellipse
// and OpenCV's default border, on random blob masks of every size and radius.
void expect_like_opencv(Morphology morphology, int opencv_op, std::uint64_t seed, std::initializer_list<cv::Size> sizes,
                        std::initializer_list<int> radii)
{
    for (const cv::Size size : sizes) {
        for (const int radius : radii) {
            const cv::Mat mask = stemd::test::random_blob_mask(size, seed++, 6, 0.02);
            cv::Mat expected = mask.clone();
            if (radius > 0)
                cv::morphologyEx(mask, expected, opencv_op,
                                 cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1)));
            const cv::Mat actual = ours(morphology, mask, radius);
            ASSERT_EQ(cv::countNonZero(expected != actual), 0) << "size " << size << " radius " << radius;
        }
    }
}

}  // namespace

TEST(Closing, KernelRowsAreCentredRuns)
{
    for (int r = 0; r <= 30; ++r) {
        const auto widths = ellipse_half_widths(r);
        ASSERT_EQ(widths.size(), static_cast<std::size_t>(2 * r + 1));
        EXPECT_EQ(widths[static_cast<std::size_t>(r)], r);  // the middle row spans the whole kernel
        for (int dy = 0; dy <= r; ++dy)
            EXPECT_EQ(widths[static_cast<std::size_t>(r + dy)], widths[static_cast<std::size_t>(r - dy)]);
    }
}

TEST(Closing, BitExactWithOpenCvOnRandomMasks)
{
    const cv::Size sizes[] = {{1, 1}, {1, 17}, {63, 9}, {64, 64}, {65, 33}, {130, 70}, {257, 41}};
    std::uint64_t seed = 1;
    for (const cv::Size size : sizes) {
        for (const int radius : {0, 1, 2, 3, 5, 6, 10, 13, 20}) {
            for (const double salt : {0.0, 0.02, 0.3}) {
                const cv::Mat mask = stemd::test::random_blob_mask(size, seed++, 8, salt);
                const cv::Mat expected = opencv_close(mask, radius);
                const cv::Mat actual = our_close(mask, radius);
                ASSERT_EQ(cv::countNonZero(expected != actual), 0)
                    << "size " << size << " radius " << radius << " salt " << salt;
            }
        }
    }
}

TEST(Closing, BorderBehavesLikeOpenCv)
{
    // Vegetation along every edge and in the corners: the erosion must not
    // eat it (outside counts as vegetation for the erosion, as in OpenCV).
    cv::Mat mask = cv::Mat::zeros(50, 70, CV_8UC1);
    mask.row(0).setTo(255);
    mask.col(69).setTo(255);
    mask(cv::Rect(0, 40, 10, 10)).setTo(255);
    for (const int radius : {1, 4, 10, 25}) {
        EXPECT_EQ(cv::countNonZero(opencv_close(mask, radius) != our_close(mask, radius)), 0) << radius;
    }
}

TEST(Closing, AllSetAndEmptyStayAsTheyAre)
{
    const cv::Mat full(40, 100, CV_8UC1, cv::Scalar(255));
    const cv::Mat empty = cv::Mat::zeros(40, 100, CV_8UC1);
    EXPECT_EQ(cv::countNonZero(our_close(full, 10)), full.total());
    EXPECT_EQ(cv::countNonZero(our_close(empty, 10)), 0);
}

TEST(Closing, ScratchIsReusableAcrossRadii)
{
    const cv::Mat mask = stemd::test::random_blob_mask({200, 90}, 99, 15, 0.01);
    BitMask in, out;
    ClosingScratch scratch;
    scratch.reserve(200, 90, 12);
    pack_mask(mask, MaskVegetation::nonzero, in);
    for (const int radius : {12, 3, 7, 12, 20, 1}) {
        close_mask(in, radius, out, scratch);
        cv::Mat actual;
        unpack_mask(out, actual);
        EXPECT_EQ(cv::countNonZero(actual != opencv_close(mask, radius)), 0) << radius;
    }
}

TEST(Opening, BitExactWithOpenCvOnRandomMasks)
{
    const cv::Size sizes[] = {{1, 1}, {1, 17}, {63, 9}, {64, 64}, {65, 33}, {130, 70}, {257, 41}};
    std::uint64_t seed = 100;
    for (const cv::Size size : sizes) {
        for (const int radius : {0, 1, 2, 3, 6}) {
            for (const double salt : {0.0, 0.02, 0.3}) {
                const cv::Mat mask = stemd::test::random_blob_mask(size, seed++, 8, salt);
                cv::Mat expected = mask.clone();
                if (radius > 0)
                    cv::morphologyEx(mask, expected, cv::MORPH_OPEN,
                                     cv::getStructuringElement(cv::MORPH_ELLIPSE,
                                                               cv::Size(2 * radius + 1, 2 * radius + 1)));
                const cv::Mat actual = ours(open_mask, mask, radius);
                ASSERT_EQ(cv::countNonZero(expected != actual), 0)
                    << "size " << size << " radius " << radius << " salt " << salt;
            }
        }
    }
}

TEST(Opening, RemovesSpecksAndKeepsBlobs)
{
    cv::Mat mask = cv::Mat::zeros(40, 80, CV_8UC1);
    mask.at<std::uint8_t>(5, 5) = 255;                  // a single-pixel speck
    mask(cv::Rect(10, 20, 40, 1)).setTo(255);           // a one-pixel-wide fringe
    mask(cv::Rect(60, 10, 12, 12)).setTo(255);          // a leaf-sized blob
    BitMask in, out;
    ClosingScratch scratch;
    pack_mask(mask, MaskVegetation::nonzero, in);
    open_mask(in, 1, out, scratch);
    EXPECT_FALSE(out.get(5, 5));
    EXPECT_FALSE(out.get(30, 20));
    EXPECT_TRUE(out.get(65, 15));
    EXPECT_TRUE(out.get(60, 15));  // straight edges survive a cross-shaped opening
}

TEST(Erosion, BitExactWithOpenCv)
{
    // cv::erode's default border is the largest value: outside is vegetation.
    expect_like_opencv(erode_mask, cv::MORPH_ERODE, 400,
                       {cv::Size(1, 1), cv::Size(63, 9), cv::Size(65, 33), cv::Size(130, 70)}, {0, 1, 2, 4, 10});
}

TEST(Erosion, SeedsExactlyTheComponentsTheOpeningSeeds)
{
    // Which 8-connected components of a mask hold a pixel of its opening,
    // and which hold one of its erosion: the same, for blobs, specks,
    // fringes and the frame's border.
    std::uint64_t seed = 500;
    long components_seen = 0, seeded = 0;
    for (const cv::Size size : {cv::Size(40, 30), cv::Size(65, 33), cv::Size(130, 70), cv::Size(257, 41)}) {
        for (const int radius : {1, 2, 3, 6}) {
            for (const double salt : {0.02, 0.1, 0.3}) {
                const cv::Mat mask = stemd::test::random_blob_mask(size, seed++, 10, salt);
                cv::Mat labels;
                const int count = cv::connectedComponents(mask, labels, 8, CV_32S);
                const cv::Mat opened = ours(open_mask, mask, radius), eroded = ours(erode_mask, mask, radius);
                std::vector<std::uint8_t> by_opening(static_cast<std::size_t>(count), 0), by_erosion(by_opening);
                for (int y = 0; y < mask.rows; ++y)
                    for (int x = 0; x < mask.cols; ++x) {
                        const auto label = static_cast<std::size_t>(labels.at<int>(y, x));
                        by_opening[label] |= opened.at<std::uint8_t>(y, x) != 0;
                        by_erosion[label] |= eroded.at<std::uint8_t>(y, x) != 0;
                    }
                for (int c = 1; c < count; ++c) {
                    ASSERT_EQ(by_opening[static_cast<std::size_t>(c)], by_erosion[static_cast<std::size_t>(c)])
                        << "component " << c << ", size " << size << " radius " << radius << " salt " << salt;
                    seeded += by_opening[static_cast<std::size_t>(c)];
                }
                components_seen += count - 1;
            }
        }
    }
    // Both answers occur often enough for the comparison to mean something.
    EXPECT_GT(seeded, 50);
    EXPECT_GT(components_seen - seeded, 50);
}

TEST(Dilation, BitExactWithOpenCv)
{
    expect_like_opencv(dilate_mask, cv::MORPH_DILATE, 300, {cv::Size(1, 1), cv::Size(63, 9), cv::Size(130, 70)},
                       {0, 1, 4, 10});
}
