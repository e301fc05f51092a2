#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/core.hpp>

#include "stemd/vision/index.hpp"

using namespace stemd::vision;

TEST(ExcessGreen, MapsTheFullRangeLinearly)
{
    // B, G, R triples and 2G - R - B.
    const int pixels[][3] = {{0, 0, 0}, {0, 255, 0}, {255, 0, 255}, {10, 200, 30}, {128, 128, 128}, {0, 0, 255}};
    cv::Mat bgr(1, 6, CV_8UC3);
    for (int i = 0; i < 6; ++i)
        bgr.at<cv::Vec3b>(0, i) = cv::Vec3b(pixels[i][0], pixels[i][1], pixels[i][2]);
    cv::Mat index;
    excess_green(bgr, index);
    ASSERT_EQ(index.type(), CV_8UC1);
    EXPECT_EQ(index.at<std::uint8_t>(0, 0), 128);   // 0 -> (0 + 512) / 4
    EXPECT_EQ(index.at<std::uint8_t>(0, 1), 255);   // +510 -> 255
    EXPECT_EQ(index.at<std::uint8_t>(0, 2), 0);     // -510 -> 0
    EXPECT_EQ(index.at<std::uint8_t>(0, 3), (2 * 200 - 30 - 10 + 512) / 4);
    EXPECT_EQ(index.at<std::uint8_t>(0, 4), 128);   // grey is neutral
    EXPECT_EQ(index.at<std::uint8_t>(0, 5), (512 - 255) / 4);
}

TEST(Ndvi, TableMatchesTheFormula)
{
    const NdviTable table;
    EXPECT_EQ(table(0, 0), 128);      // no light: ndvi 0
    EXPECT_EQ(table(255, 0), 255);    // +1
    EXPECT_EQ(table(0, 255), 0);      // -1
    EXPECT_EQ(table(100, 100), 128);  // 0
    for (int nir = 0; nir < 256; nir += 17) {
        for (int red = 1; red < 256; red += 13) {
            const double ndvi = static_cast<double>(nir - red) / (nir + red);
            EXPECT_EQ(table(nir, red), std::lround((ndvi + 1) * 127.5)) << nir << " " << red;
        }
    }
}

TEST(Ndvi, UsesTheRedPlaneAndTheNirImage)
{
    cv::Mat bgr(2, 2, CV_8UC3, cv::Scalar(7, 9, 50));  // red = 50
    cv::Mat nir(2, 2, CV_8UC1, cv::Scalar(150));
    const NdviTable table;
    cv::Mat index;
    ndvi(bgr, nir, table, index);
    EXPECT_EQ(index.at<std::uint8_t>(1, 1), table(150, 50));
    EXPECT_EQ(index.at<std::uint8_t>(1, 1), std::lround((100.0 / 200.0 + 1) * 127.5));
}

TEST(ExcessGreen, VectorPathEqualsTheFormulaOnEveryPixel)
{
    cv::Mat bgr(9, 1301, CV_8UC3);  // wide enough for the SIMD loop plus a scalar tail
    cv::randu(bgr, 0, 256);
    cv::Mat index;
    excess_green(bgr, index);
    for (int y = 0; y < bgr.rows; ++y) {
        for (int x = 0; x < bgr.cols; ++x) {
            const cv::Vec3b p = bgr.at<cv::Vec3b>(y, x);
            ASSERT_EQ(index.at<std::uint8_t>(y, x), (2 * p[1] - p[2] - p[0] + 512) / 4) << x << "," << y;
        }
    }
}
