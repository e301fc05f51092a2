#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "stemd/vision/contour.hpp"
#include "stemd/vision/plants.hpp"
#include "vision_test_util.hpp"

using namespace stemd::vision;

namespace {

std::vector<cv::Point> ours(const cv::Mat& mask, cv::Point start, std::size_t capacity = 100000)
{
    BitMask bits;
    pack_mask(mask, MaskVegetation::nonzero, bits);
    std::vector<cv::Point> contour;
    contour.reserve(capacity);
    EXPECT_TRUE(trace_outer_contour(bits, start, contour));
    return contour;
}

}  // namespace

TEST(Contour, SamePointsInSameOrderAsFindContours)
{
    for (std::uint64_t seed = 1; seed <= 40; ++seed) {
        const cv::Mat mask = stemd::test::random_blob_mask({120, 80}, seed, 12, seed % 3 ? 0.0 : 0.01);
        const stemd::test::LabelledMask labelled(mask);
        const std::vector<Component>& components = labelled.components;

        std::vector<std::vector<cv::Point>> expected;
        cv::findContours(mask.clone(), expected, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
        ASSERT_EQ(expected.size(), components.size()) << "seed " << seed;
        for (const auto& c : components) {
            const auto contour = ours(mask, c.first_pixel);
            // Find OpenCV's contour starting at the same pixel.
            const auto it = std::find_if(expected.begin(), expected.end(),
                                         [&](const auto& e) { return !e.empty() && e.front() == c.first_pixel; });
            ASSERT_NE(it, expected.end()) << "seed " << seed;
            EXPECT_EQ(contour, *it) << "seed " << seed << " start " << c.first_pixel;
        }
    }
}

TEST(Contour, SinglePixelAndLines)
{
    cv::Mat mask = cv::Mat::zeros(20, 20, CV_8UC1);
    mask.at<std::uint8_t>(5, 5) = 255;
    EXPECT_EQ(ours(mask, {5, 5}), std::vector<cv::Point>{cv::Point(5, 5)});

    mask.setTo(0);
    cv::line(mask, {2, 10}, {12, 10}, 255);
    const auto line = ours(mask, {2, 10});
    EXPECT_EQ(line.size(), 20u);  // out along the line and back
}

TEST(Contour, TouchingTheImageBorder)
{
    cv::Mat mask = cv::Mat::zeros(30, 40, CV_8UC1);
    mask(cv::Rect(0, 0, 40, 10)).setTo(255);
    std::vector<std::vector<cv::Point>> expected;
    cv::findContours(mask.clone(), expected, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
    ASSERT_EQ(expected.size(), 1u);
    EXPECT_EQ(ours(mask, {0, 0}), expected[0]);
}

TEST(Contour, ReportsTruncationInsteadOfOverflowing)
{
    cv::Mat mask = cv::Mat::zeros(50, 50, CV_8UC1);
    cv::circle(mask, {25, 25}, 20, 255, cv::FILLED);
    BitMask bits;
    pack_mask(mask, MaskVegetation::nonzero, bits);
    std::vector<cv::Point> contour;
    contour.reserve(10);
    const std::size_t capacity = contour.capacity();
    EXPECT_FALSE(trace_outer_contour(bits, {25, 5}, contour));
    EXPECT_EQ(contour.size(), capacity);
    EXPECT_EQ(contour.capacity(), capacity);
}
