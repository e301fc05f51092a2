#include <gtest/gtest.h>

#include <array>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "stemd/vision/index.hpp"
#include "vision_test_util.hpp"

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

TEST(Ndvi, IndexIsTheNearestLevelHalvesUp)
{
    EXPECT_EQ(ndvi_index(0, 0), 128);      // no light: ndvi 0
    EXPECT_EQ(ndvi_index(255, 0), 255);    // +1
    EXPECT_EQ(ndvi_index(0, 255), 0);      // -1
    EXPECT_EQ(ndvi_index(100, 100), 128);  // 0: 127.5, rounded up
    EXPECT_EQ(ndvi_index(1, 9), 26);       // ndvi -0.8: 25.5 exactly, rounded up
    for (int nir = 0; nir < 256; ++nir) {
        for (int red = 0; red < 256; ++red) {
            if (nir + red == 0)
                continue;
            // The nearest level to (ndvi + 1) * 127.5.
            const double level = 255.0 * nir / (nir + red);
            const int index = ndvi_index(nir, red);
            ASSERT_LE(std::abs(index - level), 0.5) << nir << " " << red;
            if (std::abs(index - level) == 0.5) {
                ASSERT_GT(index, level) << nir << " " << red;
            }
        }
    }
}

TEST(Ndvi, EveryKernelEqualsTheIndexOnEveryPair)
{
    // Row = NIR, column = red (twice over, plus a tail the vector loops
    // leave to the scalar one), blue and green at random.
    cv::Mat bgr(256, 2 * 256 + 7, CV_8UC3), nir(bgr.size(), CV_8UC1);
    cv::randu(bgr, 0, 256);
    for (int y = 0; y < bgr.rows; ++y) {
        for (int x = 0; x < bgr.cols; ++x) {
            bgr.at<cv::Vec3b>(y, x)[2] = static_cast<std::uint8_t>(x % 256);
            nir.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(y);
        }
    }
    for (const Kernel kernel : kKernels) {
        if (!kernel_available(kernel)) {
            std::printf("this CPU lacks kernel %d: not checked\n", static_cast<int>(kernel));
            continue;
        }
        cv::Mat index;
        ndvi(bgr, nir, index, kernel);
        for (int y = 0; y < bgr.rows; ++y)
            for (int x = 0; x < bgr.cols; ++x)
                ASSERT_EQ(index.at<std::uint8_t>(y, x), ndvi_index(y, x % 256))
                    << "kernel " << static_cast<int>(kernel) << " nir " << y << " red " << x % 256;
    }
}

TEST(Ndvi, KernelsAgreeAtEveryWidthAndOnViews)
{
    // Widths around the sixteen-pixel steps and the two pixels the SSSE3
    // loads read past a step, and a view into a wider image (rows not
    // contiguous), so no load strays out of a row.
    cv::RNG rng(11);
    for (int width = 1; width <= 40; ++width) {
        cv::Mat wide_bgr(3, width + 5, CV_8UC3), wide_nir(3, width + 5, CV_8UC1);
        rng.fill(wide_bgr, cv::RNG::UNIFORM, 0, 256);
        rng.fill(wide_nir, cv::RNG::UNIFORM, 0, 256);
        const cv::Mat bgr = wide_bgr.colRange(2, 2 + width), nir = wide_nir.colRange(2, 2 + width);
        cv::Mat portable, best;
        ndvi(bgr, nir, portable, Kernel::baseline);
        ndvi(bgr, nir, best);
        for (int y = 0; y < bgr.rows; ++y)
            for (int x = 0; x < width; ++x) {
                const int expected = ndvi_index(nir.at<std::uint8_t>(y, x), bgr.at<cv::Vec3b>(y, x)[2]);
                ASSERT_EQ(portable.at<std::uint8_t>(y, x), expected) << "width " << width << " x " << x;
                ASSERT_EQ(best.at<std::uint8_t>(y, x), expected) << "width " << width << " x " << x;
            }
    }
}

TEST(Ndvi, UsesTheRedPlaneAndTheNirImage)
{
    cv::Mat bgr(2, 2, CV_8UC3, cv::Scalar(7, 9, 50));  // red = 50
    cv::Mat nir(2, 2, CV_8UC1, cv::Scalar(150));
    cv::Mat index;
    ndvi(bgr, nir, index);
    EXPECT_EQ(index.at<std::uint8_t>(1, 1), ndvi_index(150, 50));
    EXPECT_EQ(index.at<std::uint8_t>(1, 1), std::lround((100.0 / 200.0 + 1) * 127.5));  // 191.25
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

namespace {

// A frame of `soil` with one `leaf`-coloured square; the index at the leaf's centre.
int chromatic_index_at_leaf(cv::Vec3b soil, cv::Vec3b leaf)
{
    cv::Mat bgr(60, 60, CV_8UC3, cv::Scalar(soil[0], soil[1], soil[2]));
    bgr(cv::Rect(20, 20, 20, 20)).setTo(cv::Scalar(leaf[0], leaf[1], leaf[2]));
    cv::Mat index;
    chromatic_excess_green(bgr, index);
    return index.at<std::uint8_t>(30, 30);
}

}  // namespace

TEST(ChromaticExcessGreen, GreyIsNeutralAndGreenIsHigh)
{
    // Grey everywhere but at x = 1 (green) and x = 2 (black): the mean
    // brightness, over every pixel of the one row, is (6 * 300 + 170) / 8.
    cv::Mat bgr(1, 8, CV_8UC3, cv::Scalar(100, 100, 100));
    bgr.at<cv::Vec3b>(0, 1) = {30, 90, 50};
    bgr.at<cv::Vec3b>(0, 2) = {0, 0, 0};
    cv::Mat index;
    chromatic_excess_green(bgr, index);
    ASSERT_EQ(index.type(), CV_8UC1);
    // 128 + 160 e / (s + mean)
    EXPECT_EQ(index.at<std::uint8_t>(0, 0), 128);
    EXPECT_EQ(index.at<std::uint8_t>(0, 1), std::lround(128 + 160 * 100 / (170 + (6 * 300 + 170) / 8.0)));
    EXPECT_EQ(index.at<std::uint8_t>(0, 2), 128);  // black is neutral, not a division by zero
}

TEST(ChromaticExcessGreen, MeanBrightnessIsTheMeanOfRowFourOfEveryBand)
{
    // Rows 4, 20 and 36 of a 40-row frame (bands of 16 rows) are the
    // samples; every other row is far brighter and must not count.
    static_assert(kBrightnessRowStep == 16);
    cv::Mat bgr(40, 24, CV_8UC3, cv::Scalar(250, 250, 250));
    bgr.row(4).setTo(cv::Scalar(10, 20, 30));   // s = 60
    bgr.row(20).setTo(cv::Scalar(40, 40, 40));  // s = 120
    bgr.row(36).setTo(cv::Scalar(0, 0, 0));     // s = 0
    bgr.at<cv::Vec3b>(36, 5) = {90, 90, 90};    // one pixel of s = 270 in 24
    EXPECT_FLOAT_EQ(chromatic_mean_brightness(bgr), (24 * 60 + 24 * 120 + 270) / 72.0f);
    // A band shorter than 5 rows is sampled at the frame's last row.
    cv::Mat short_frame(3, 4, CV_8UC3, cv::Scalar(250, 250, 250));
    short_frame.row(2).setTo(cv::Scalar(10, 10, 10));
    EXPECT_FLOAT_EQ(chromatic_mean_brightness(short_frame), 30.0f);
    // An all-black frame gets the floor, not a division by zero.
    EXPECT_FLOAT_EQ(chromatic_mean_brightness(cv::Mat(20, 8, CV_8UC3, cv::Scalar::all(0))), 1.0f);
    // Random rows of every width around the 16-byte blocks, and a view into
    // a larger frame: the mean of the sampled rows' bytes, as defined.
    cv::RNG rng(5);
    cv::Mat big(40, 120, CV_8UC3);
    rng.fill(big, cv::RNG::UNIFORM, 0, 256);
    for (int width = 1; width <= 100; ++width) {
        const cv::Mat frame = big(cv::Rect(3, 1, width, 37));
        double sum = 0;
        for (const int y : {4, 20, 36})
            for (int x = 0; x < width; ++x)
                for (int c = 0; c < 3; ++c)
                    sum += frame.at<cv::Vec3b>(y, x)[c];
        EXPECT_FLOAT_EQ(chromatic_mean_brightness(frame), static_cast<float>(sum / (3.0 * width))) << width;
    }
}

TEST(ChromaticExcessGreen, DoesNotChangeWithExposure)
{
    // Halving every channel (half the exposure or gain) keeps the index
    // within one level; plain Excess Green halves its distance from neutral.
    const cv::Vec3b soil{60, 80, 110}, leaf{40, 120, 70};
    const cv::Vec3b dark_soil{30, 40, 55}, dark_leaf{20, 60, 35};
    EXPECT_NEAR(chromatic_index_at_leaf(soil, leaf), chromatic_index_at_leaf(dark_soil, dark_leaf), 1);
    EXPECT_GT(chromatic_index_at_leaf(soil, leaf), 150);
}

TEST(SmoothBinomial3, EqualsOpenCvGaussian3x3WithReplicatedEdges)
{
    cv::RNG rng(7);
    for (const cv::Size size : {cv::Size(1, 1), cv::Size(1, 5), cv::Size(7, 1), cv::Size(33, 17), cv::Size(130, 40)}) {
        cv::Mat src(size, CV_8UC1);
        rng.fill(src, cv::RNG::UNIFORM, 0, 256);
        // Integer reference: (sum of [1 2 1] x [1 2 1] weights * pixels + 8) / 16.
        cv::Mat expected(size, CV_8UC1);
        for (int y = 0; y < size.height; ++y)
            for (int x = 0; x < size.width; ++x) {
                int sum = 0;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int yy = std::clamp(y + dy, 0, size.height - 1);
                        const int xx = std::clamp(x + dx, 0, size.width - 1);
                        sum += (dy == 0 ? 2 : 1) * (dx == 0 ? 2 : 1) * src.at<std::uint8_t>(yy, xx);
                    }
                expected.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>((sum + 8) / 16);
            }
        std::vector<std::uint16_t> row(static_cast<std::size_t>(size.width));
        cv::Mat actual;
        smooth_binomial3(src, row.data(), actual);
        ASSERT_EQ(cv::countNonZero(expected != actual), 0) << size;
    }
}

TEST(LeafColour, SoilColourIsTheMeanOfTheSampledRowsOutsideTheVegetation)
{
    // Rows 4 and 20 of a 24-row frame are the samples. Their vegetation
    // pixels, and every other row, must not count.
    static_assert(kBrightnessRowStep == 16);
    cv::Mat bgr(24, 8, CV_8UC3, cv::Scalar(0, 255, 0));
    bgr.row(4).setTo(cv::Scalar(10, 20, 30));
    bgr.row(20).setTo(cv::Scalar(30, 40, 50));
    BitMask vegetation(8, 24);
    for (int x = 0; x < 4; ++x) {
        vegetation.set(x, 20);
        bgr.at<cv::Vec3b>(20, x) = {0, 250, 0};
    }
    const SoilColour soil = soil_colour(bgr, vegetation);
    EXPECT_EQ(soil.pixels, 12);
    EXPECT_DOUBLE_EQ(soil.b, (8 * 10 + 4 * 30) / 12.0);
    EXPECT_DOUBLE_EQ(soil.g, (8 * 20 + 4 * 40) / 12.0);
    EXPECT_DOUBLE_EQ(soil.r, (8 * 30 + 4 * 50) / 12.0);
}

namespace {

// Which of a leaf, a yellowish clod and a dark straw pixel keep their bit,
// in a frame of brown soil, with every channel scaled by `gains` (B, G, R).
std::vector<bool> leaf_colour_kept(cv::Vec3d gains)
{
    const auto cast = [&](cv::Vec3d bgr) {
        return cv::Vec3b(cv::saturate_cast<std::uint8_t>(bgr[0] * gains[0]),
                         cv::saturate_cast<std::uint8_t>(bgr[1] * gains[1]),
                         cv::saturate_cast<std::uint8_t>(bgr[2] * gains[2]));
    };
    cv::Mat bgr(16, 8, CV_8UC3);
    bgr.setTo(cv::Scalar(cast({60, 70, 85})));  // soil: G/R 0.82
    const std::array<cv::Vec3d, 3> probes{cv::Vec3d{40, 100, 75},   // leaf: G/R 1.33, 1.6 times the soil's
                                          cv::Vec3d{70, 95, 100},   // clod: G/R 0.95, 1.16 times
                                          cv::Vec3d{50, 60, 80}};   // straw: G/R 0.75
    BitMask mask(8, 16);
    for (int i = 0; i < 3; ++i) {
        bgr.at<cv::Vec3b>(8, i) = cast(probes[static_cast<std::size_t>(i)]);
        mask.set(i, 8);
    }
    keep_greener_than_red(bgr, soil_colour(bgr, mask), 1.25, mask);
    return {mask.get(0, 8), mask.get(1, 8), mask.get(2, 8)};
}

}  // namespace

TEST(LeafColour, KeepsLeavesAndNotClodsWhateverTheColourOfTheLight)
{
    const std::vector<bool> leaf_only{true, false, false};
    EXPECT_EQ(leaf_colour_kept({1, 1, 1}), leaf_only);
    // Warm light (evening sun; a white balance set for shade) makes the leaf
    // redder than neutral grey; cool light makes the clod greener than red.
    EXPECT_EQ(leaf_colour_kept({0.75, 1, 1.3}), leaf_only);
    EXPECT_EQ(leaf_colour_kept({1.3, 1, 0.75}), leaf_only);
    EXPECT_EQ(leaf_colour_kept({0.5, 0.5, 0.5}), leaf_only);
}

TEST(LeafColour, WithoutSoilInViewTheSoilIsNeutralGrey)
{
    // All vegetation: no soil pixel to compare with, so G must exceed R by
    // the factor itself.
    cv::Mat bgr(16, 2, CV_8UC3, cv::Scalar(40, 100, 75));  // G/R 1.33
    bgr.at<cv::Vec3b>(0, 1) = {40, 100, 85};                // G/R 1.18
    BitMask mask(2, 16);
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 2; ++x)
            mask.set(x, y);
    const SoilColour soil = soil_colour(bgr, mask);
    EXPECT_EQ(soil.pixels, 0);
    keep_greener_than_red(bgr, soil, 1.25, mask);
    EXPECT_TRUE(mask.get(0, 0));
    EXPECT_FALSE(mask.get(1, 0));
    EXPECT_TRUE(mask.get(1, 1));
}

TEST(LeafColour, EveryGreenAndRedPairIsJudgedByTheRatioRule)
{
    // All 65536 (G, R) pairs, in words wholly set and in scattered bits,
    // for a few soils and factors: a pixel stays exactly when its G/R
    // exceeds min_ratio times the soil's (G > R for a neutral soil). Pairs
    // within rounding of the boundary are not judged.
    cv::Mat bgr(256, 256, CV_8UC3);
    for (int red = 0; red < 256; ++red)
        for (int green = 0; green < 256; ++green)
            bgr.at<cv::Vec3b>(red, green) = cv::Vec3b(90, static_cast<std::uint8_t>(green), static_cast<std::uint8_t>(red));
    struct Case {
        double soil_g, soil_r, min_ratio;
    };
    for (const Case c : {Case{70, 85, 1.25}, Case{120, 60, 1.25}, Case{33.3, 41.7, 1.1}, Case{0.5, 80, 1.25},
                         Case{200, 200, 2.0}}) {
        SoilColour soil;
        soil.g = c.soil_g;
        soil.r = c.soil_r;
        soil.pixels = 1000;
        const bool neutral = c.soil_g < 1.0 || c.soil_r < 1.0;
        const double soil_ratio = neutral ? 1.0 : c.soil_g / c.soil_r;
        for (const bool scattered : {false, true}) {
            BitMask before(256, 256);
            for (int y = 0; y < 256; ++y)
                for (int x = 0; x < 256; ++x)
                    if (!scattered || (x * 7 + y * 3) % 5 != 0)
                        before.set(x, y);
            // Every kernel the CPU has keeps exactly the baseline's pixels.
            BitMask mask = before;
            keep_greener_than_red(bgr, soil, c.min_ratio, mask, Kernel::baseline);
            if (kernel_available(Kernel::ssse3)) {
                BitMask vector = before;
                keep_greener_than_red(bgr, soil, c.min_ratio, vector, Kernel::ssse3);
                for (int y = 0; y < 256; ++y)
                    for (int x = 0; x < 256; ++x)
                        ASSERT_EQ(vector.get(x, y), mask.get(x, y)) << "G " << x << " R " << y;
            }
            for (int red = 0; red < 256; ++red)
                for (int green = 0; green < 256; ++green) {
                    if (!before.get(green, red)) {
                        ASSERT_FALSE(mask.get(green, red));
                        continue;
                    }
                    const double margin = green - red * c.min_ratio * soil_ratio;
                    if (std::abs(margin) < 1e-3 * (1 + red))
                        continue;
                    ASSERT_EQ(mask.get(green, red), margin > 0)
                        << "G " << green << " R " << red << " soil G/R " << soil_ratio << " x" << c.min_ratio;
                }
        }
    }
}

namespace {

// Brown soil with a bright straw (columns 5-12) and a leaf disc, the green
// plane then slid one pixel to the right, as a lens and the Bayer
// interpolation misregister it: the column right of the straw takes the
// straw's green over the soil's red, a band greener for its red than any
// leaf. Also a leaf three pixels wide. Returns the frame; `mask` gets the
// pixels that pass the leaf-colour test, labelled into `labels`.
cv::Mat misregistered_frame(BitMask& mask, LabelScratch& labels, std::vector<Component>& components)
{
    cv::Mat bgr(40, 48, CV_8UC3, cv::Scalar(60, 70, 85));               // soil: G/R 0.82
    cv::rectangle(bgr, cv::Rect(5, 4, 8, 32), cv::Scalar(150, 190, 200), cv::FILLED);  // straw: G/R 0.95
    cv::circle(bgr, {30, 12}, 5, cv::Scalar(40, 100, 75), cv::FILLED);   // leaf: G/R 1.33
    cv::rectangle(bgr, cv::Rect(22, 30, 20, 3), cv::Scalar(40, 100, 75), cv::FILLED);  // a thin leaf
    stemd::test::slide_green_plane_right(bgr);
    mask.reset(bgr.cols, bgr.rows);
    for (int y = 0; y < bgr.rows; ++y)
        for (int x = 0; x < bgr.cols; ++x)
            mask.set(x, y);
    keep_greener_than_red(bgr, soil_colour(bgr, BitMask(bgr.cols, bgr.rows)), 1.25, mask);
    labels.reserve(bgr.cols, bgr.rows);
    label_components(mask, labels, components);
    return bgr;
}

}  // namespace

TEST(ColourFringes, AFringeAlongABrightStrawIsDroppedAndLeavesAreKept)
{
    BitMask mask;
    LabelScratch labels;
    std::vector<Component> components;
    const cv::Mat bgr = misregistered_frame(mask, labels, components);
    // The band right of the straw passes the leaf-colour test by itself.
    ASSERT_TRUE(mask.get(13, 20));
    ASSERT_FALSE(mask.get(9, 20));
    ASSERT_EQ(components.size(), 3u) << "the fringe, the leaf and the thin leaf";
    std::vector<std::uint8_t> keep(components.size(), 1), passed;
    const SoilColour soil = soil_colour(bgr, mask);
    EXPECT_EQ(drop_colour_fringes(bgr, soil, 1.25, labels, keep, passed), 1);
    for (std::size_t c = 0; c < components.size(); ++c) {
        const bool fringe = components[c].x_max <= 14;
        EXPECT_EQ(keep[c], fringe ? 0 : 1) << "component at x " << components[c].x_min << "-" << components[c].x_max;
    }
}

TEST(ColourFringes, ComponentsAlreadyDroppedAreLeftAlone)
{
    BitMask mask;
    LabelScratch labels;
    std::vector<Component> components;
    const cv::Mat bgr = misregistered_frame(mask, labels, components);
    std::vector<std::uint8_t> keep(components.size(), 0), passed;
    EXPECT_EQ(drop_colour_fringes(bgr, soil_colour(bgr, mask), 1.25, labels, keep, passed), 0);
    EXPECT_EQ(std::count(keep.begin(), keep.end(), 0), static_cast<long>(components.size()));
}
