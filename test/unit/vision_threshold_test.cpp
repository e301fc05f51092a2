#include <gtest/gtest.h>

#include <cmath>
#include <vector>

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

// `ours` gives OpenCV's threshold for `opencv_method` on every test image.
void expect_equals_opencv(int (*ours)(const Histogram&), int opencv_method)
{
    for (int kind = 0; kind < 5; ++kind) {
        for (std::uint64_t seed = 1; seed <= 20; ++seed) {
            const cv::Mat img = test_image(kind, seed);
            Histogram h;
            compute_histogram(img, h);
            cv::Mat ignored;
            const int expected = static_cast<int>(cv::threshold(img, ignored, 0, 255, cv::THRESH_BINARY | opencv_method));
            EXPECT_EQ(ours(h), expected) << "kind " << kind << " seed " << seed;
        }
    }
}

}  // namespace

TEST(Threshold, OtsuEqualsOpenCv)
{
    expect_equals_opencv(otsu_threshold, cv::THRESH_OTSU);
}

TEST(Threshold, TriangleEqualsOpenCv)
{
    expect_equals_opencv(triangle_threshold, cv::THRESH_TRIANGLE);
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

namespace {

// The naive count of `img`'s values, each `weight` times.
Histogram naive_histogram(const cv::Mat& img, std::uint32_t weight = 1)
{
    Histogram h{};
    for (int y = 0; y < img.rows; ++y)
        for (int x = 0; x < img.cols; ++x)
            h[img.at<std::uint8_t>(y, x)] += weight;
    return h;
}

}  // namespace

TEST(Threshold, HistogramEqualsTheNaiveCountForAnyWidthAndStart)
{
    // Widths around the eight values a load reads at once, and views that
    // start at an odd column (an unaligned first load) or skip columns at
    // the end of each row.
    for (const int width : {1, 3, 7, 8, 9, 15, 16, 17, 90}) {
        for (const int kind : {0, 2, 3}) {
            const cv::Mat whole = test_image(kind, static_cast<std::uint64_t>(width));
            const cv::Mat img = whole(cv::Rect(3, 2, width, 40));
            Histogram h;
            compute_histogram(img, h);
            EXPECT_EQ(h, naive_histogram(img)) << "width " << width << " kind " << kind;
        }
    }
}

TEST(Threshold, PartialHistogramsWeighEveryValueAndSum)
{
    const cv::Mat img = test_image(1, 9);
    PartialHistograms partial;
    for (int y = 0; y < img.rows; ++y)
        partial.add(img.ptr<std::uint8_t>(y) + 1, img.cols - 1, 5);
    Histogram h;
    partial.sum(h);
    EXPECT_EQ(h, naive_histogram(img(cv::Rect(1, 0, img.cols - 1, img.rows)), 5));
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

TEST(BitMask, CountBitsCountsEverySetBitOfEveryWord)
{
    // Against a bit-by-bit count: all-zero, all-one, single bits at both
    // ends and random words, for lengths 0 to 70 words.
    cv::RNG rng(11);
    std::vector<std::uint64_t> words(70);
    for (std::size_t i = 0; i < words.size(); ++i) {
        const std::uint64_t random = (static_cast<std::uint64_t>(rng.next()) << 32) | rng.next();
        const std::uint64_t kinds[] = {0, ~std::uint64_t{0}, std::uint64_t{1}, std::uint64_t{1} << 63, random};
        words[i] = kinds[i % 5];
    }
    for (std::size_t n = 0; n <= words.size(); ++n) {
        long expected = 0;
        for (std::size_t i = 0; i < n; ++i)
            for (int bit = 0; bit < 64; ++bit)
                expected += static_cast<long>((words[i] >> bit) & 1);
        ASSERT_EQ(count_bits(words.data(), n), expected) << n << " words";
    }
}

TEST(BitMask, NextBitFindsTheNextSetOrClearBitBeforeTheWidth)
{
    // Against a bit-by-bit search: rows of 1 to 3 words with zero, full,
    // single-bit and random words, every start, the width both the row's
    // and a shorter one (the end of a run), past which nothing is found.
    cv::RNG rng(13);
    for (const int words : {1, 2, 3}) {
        for (int trial = 0; trial < 8; ++trial) {
            std::vector<std::uint64_t> row(static_cast<std::size_t>(words));
            for (int w = 0; w < words; ++w) {
                const std::uint64_t random = (static_cast<std::uint64_t>(rng.next()) << 32) | rng.next();
                const std::uint64_t kinds[] = {0, ~std::uint64_t{0}, std::uint64_t{1} << 63, random,
                                               random & (random >> 2)};
                row[static_cast<std::size_t>(w)] = kinds[(trial + w) % 5];
            }
            auto bit = [&](int x) { return ((row[static_cast<std::size_t>(x >> 6)] >> (x & 63)) & 1) != 0; };
            for (const int width : {64 * words, 64 * words - 5, 37}) {
                if (width > 64 * words || width <= 0)
                    continue;
                for (int x = 0; x <= width; ++x)
                    for (const bool want_set : {true, false}) {
                        int expected = x;
                        while (expected < width && bit(expected) != want_set)
                            ++expected;
                        ASSERT_EQ(next_bit(row.data(), words, width, x, want_set), expected)
                            << words << " words, width " << width << ", from " << x << (want_set ? " set" : " clear");
                    }
            }
        }
    }
}

TEST(BitMask, RangeAndSpanCountsCountEverySetBitOfTheirPixels)
{
    // Rows of 1 to 3 words, the last one partial or whole, with zero, full
    // and random words; every range and span size up to past the row. The
    // span counts take four such rows: a gate, a counted row and a pair.
    cv::RNG rng(12);
    for (const int width : {1, 63, 64, 65, 150, 192}) {
        const int words = (width + 63) / 64;
        for (int trial = 0; trial < 6; ++trial) {
            std::array<std::vector<std::uint64_t>, 4> rows;   // counted, gate, pair
            for (std::size_t r = 0; r < rows.size(); ++r) {
                rows[r].resize(static_cast<std::size_t>(words));
                for (int w = 0; w < words; ++w) {
                    const std::uint64_t random = (static_cast<std::uint64_t>(rng.next()) << 32) | rng.next();
                    const std::uint64_t kinds[] = {0, ~std::uint64_t{0}, random, random & (random >> 3)};
                    rows[r][static_cast<std::size_t>(w)] = kinds[(trial + w + static_cast<int>(r)) % 4];
                }
                if (width % 64 != 0)
                    rows[r].back() &= (std::uint64_t{1} << (width % 64)) - 1;   // past the width: clear, as BitMask keeps it
            }
            const std::vector<std::uint64_t>& row = rows[0];
            auto bits = [&](std::size_t r, int x0, int x1) {
                int n = 0;
                for (int x = x0; x < x1; ++x)
                    n += static_cast<int>((rows[r][static_cast<std::size_t>(x >> 6)] >> (x & 63)) & 1);
                return n;
            };
            for (int x0 = 0; x0 <= width; ++x0)
                for (int x1 = x0 - 1; x1 <= width; ++x1)
                    ASSERT_EQ(count_bits_in_range(row.data(), x0, x1), x1 > x0 ? bits(0, x0, x1) : 0)
                        << width << ": " << x0 << ".." << x1;
            for (int span = 1; span <= width + 1; ++span) {
                const int spans = (width + span - 1) / span;
                // Added to, with one guard past the end.
                std::vector<int> counts(static_cast<std::size_t>(spans) + 1, 7), pair(counts.size(), 9);
                add_gated_span_bit_counts({rows[1].data(), row.data(), {rows[2].data(), rows[3].data()}}, width, span,
                                          counts.data(), pair.data());
                for (int c = 0; c < spans; ++c) {
                    const int x0 = c * span, x1 = std::min((c + 1) * span, width);
                    const bool gated = bits(1, x0, x1) > 0;
                    ASSERT_EQ(counts[static_cast<std::size_t>(c)], 7 + (gated ? bits(0, x0, x1) : 0))
                        << width << ": span " << span << " #" << c;
                    ASSERT_EQ(pair[static_cast<std::size_t>(c)], 9 + (gated ? bits(2, x0, x1) + bits(3, x0, x1) : 0))
                        << width << ": span " << span << " #" << c;
                }
                ASSERT_EQ(counts.back(), 7) << width << ": span " << span << " wrote past its last span";
                ASSERT_EQ(pair.back(), 9) << width << ": span " << span << " wrote past its last span";
            }
        }
    }
    int untouched = 5;
    add_gated_span_bit_counts({nullptr, nullptr, {nullptr, nullptr}}, 64, 0, &untouched, &untouched);
    EXPECT_EQ(untouched, 5);
}

namespace {

// The textbook criterion, computed directly for every level.
int brute_force_min_error(const Histogram& h)
{
    double total = 0;
    for (const auto v : h)
        total += v;
    double best_j = 0;
    int best = -1;
    for (int t = 0; t < 255; ++t) {
        double n1 = 0, n2 = 0, m1 = 0, m2 = 0;
        for (int i = 0; i <= t; ++i) { n1 += h[i]; m1 += i * double(h[i]); }
        for (int i = t + 1; i < 256; ++i) { n2 += h[i]; m2 += i * double(h[i]); }
        if (n1 < 1 || n2 < 1)
            continue;
        m1 /= n1;
        m2 /= n2;
        double v1 = 0, v2 = 0;
        for (int i = 0; i <= t; ++i) v1 += h[i] * (i - m1) * (i - m1);
        for (int i = t + 1; i < 256; ++i) v2 += h[i] * (i - m2) * (i - m2);
        v1 /= n1;
        v2 /= n2;
        if (v1 <= 1e-9 || v2 <= 1e-9)
            continue;
        const double p1 = n1 / total, p2 = n2 / total;
        const double j = 1 + 2 * (p1 * std::log(std::sqrt(v1)) + p2 * std::log(std::sqrt(v2))) -
                         2 * (p1 * std::log(p1) + p2 * std::log(p2));
        if (best < 0 || j < best_j) {
            best_j = j;
            best = t;
        }
    }
    return best;
}

}  // namespace

TEST(Threshold, MinErrorEqualsTheTextbookCriterion)
{
    for (int kind = 0; kind < 5; ++kind) {
        for (std::uint64_t seed = 1; seed <= 10; ++seed) {
            Histogram h;
            compute_histogram(test_image(kind, seed), h);
            const int expected = brute_force_min_error(h);
            if (expected >= 0) {
                EXPECT_EQ(min_error_threshold(h), expected) << "kind " << kind << " seed " << seed;
            }
        }
    }
}

TEST(Threshold, MinErrorFindsTheBayesBoundaryOfTwoGaussians)
{
    // A 10 % narrow bright class at 180 over a 90 % wide dark class at 100:
    // the weighted densities cross at 166 (solved numerically), so the
    // error-minimising rule is "index > 165".
    Histogram h{};
    for (int v = 0; v < 256; ++v) {
        h[v] = static_cast<std::uint32_t>(9000 * std::exp(-0.5 * std::pow((v - 100) / 20.0, 2)) +
                                          1000 * std::exp(-0.5 * std::pow((v - 180) / 6.0, 2)));
    }
    const int min_error = min_error_threshold(h);
    EXPECT_NEAR(min_error, 165, 2);
    EXPECT_EQ(auto_threshold(h, ThresholdMethod::min_error), min_error);
}

TEST(Threshold, ClassSeparationIsTheDifferenceOfTheClassMeans)
{
    Histogram h{};
    h[40] = 300;
    h[60] = 100;  // below: mean 45
    h[200] = 50;
    h[220] = 50;  // above: mean 210
    EXPECT_DOUBLE_EQ(class_separation(h, 100), 165.0);
    EXPECT_DOUBLE_EQ(class_separation(h, 40), (200.0 * 50 + 220 * 50 + 60 * 100) / 200 - 40);
    EXPECT_EQ(class_separation(h, 255), 0.0);  // nothing above
    EXPECT_EQ(class_separation(Histogram{}, 128), 0.0);
}

TEST(Threshold, EveryMethodSplitsUnimodalSoilButWithASmallSeparation)
{
    // Bare soil's Excess Green: one mode near 130 (ExG about 8). Each
    // automatic threshold still splits it, into two classes whose means are
    // only a few index units apart; real soil and plants are far more.
    cv::RNG rng(11);
    cv::Mat soil(240, 320, CV_8UC1);
    for (int y = 0; y < soil.rows; ++y)
        for (int x = 0; x < soil.cols; ++x)
            soil.at<std::uint8_t>(y, x) = cv::saturate_cast<std::uint8_t>(rng.uniform(126, 135));
    Histogram h{};
    compute_histogram(soil, h);
    for (const ThresholdMethod m : {ThresholdMethod::otsu, ThresholdMethod::triangle, ThresholdMethod::min_error}) {
        SCOPED_TRACE(std::string(to_string(m)));
        const int t = auto_threshold(h, m);
        EXPECT_GE(t, 126);
        EXPECT_LT(t, 134);
        EXPECT_GT(class_separation(h, t), 0.0);
        EXPECT_LT(class_separation(h, t), Params{}.min_class_separation);
    }
    // Bimodal: separated far beyond the default.
    const cv::Mat bimodal = test_image(0, 5);
    compute_histogram(bimodal, h);
    EXPECT_GT(class_separation(h, otsu_threshold(h)), 5 * Params{}.min_class_separation);
}

namespace {

// A histogram of a Gaussian soil (mode `soil`, spread `sigma`) plus
// `vegetation_fraction` of the pixels around `vegetation`.
Histogram soil_and_vegetation(double soil, double sigma, double vegetation, double vegetation_fraction)
{
    Histogram h{};
    const double total = 1e6;
    for (int v = 0; v < 256; ++v) {
        const double z = (v - soil) / sigma;
        double n = (1 - vegetation_fraction) * total * std::exp(-0.5 * z * z) / (sigma * std::sqrt(2 * M_PI));
        const double zv = (v - vegetation) / 6.0;
        n += vegetation_fraction * total * std::exp(-0.5 * zv * zv) / (6.0 * std::sqrt(2 * M_PI));
        h[static_cast<std::size_t>(v)] = static_cast<std::uint32_t>(std::lround(n));
    }
    return h;
}

}  // namespace

TEST(Threshold, SoilNoiseThresholdIsTheModePlusSigmasOfTheLowerSide)
{
    // No vegetation, no tail: mode 100, sigma 3.
    const Histogram h = soil_and_vegetation(100, 3, 0, 0);
    EXPECT_NEAR(soil_noise_threshold(h, 5), 115, 1);
    EXPECT_NEAR(soil_noise_threshold(h, 3), 109, 1);
    // Vegetation does not move it: only the soil mode's lower side counts.
    EXPECT_NEAR(soil_noise_threshold(soil_and_vegetation(100, 3, 160, 0.2), 5), 115, 1);
    EXPECT_EQ(soil_noise_threshold(Histogram{}, 5), 255);  // empty: nothing is vegetation
}

TEST(Threshold, SoilNoiseThresholdFollowsASoilAsNarrowAsTheLevels)
{
    // A soil whose mode lies between two levels and whose spread is a level
    // or two (dark frames, NDVI's table): read in whole levels, mode and
    // sigma both came out low, and the threshold two levels below mode +
    // 5 sigma (105 for 107), inside the soil's own noise.
    struct Soil {
        double mode, sigma;
    };
    for (const Soil soil : {Soil{100.25, 1.0}, Soil{100.5, 1.2}, Soil{100.5, 2.0}, Soil{100.75, 1.5}}) {
        const Histogram h = soil_and_vegetation(soil.mode, soil.sigma, 160, 0.01);
        EXPECT_NEAR(soil_noise_threshold(h, 5), std::ceil(soil.mode + 5 * soil.sigma), 1)
            << "soil mode " << soil.mode << ", sigma " << soil.sigma;
    }
}

TEST(Threshold, AboveSoilKeepsOtsuWhereItSeparatesAndRisesAboveTheSoilWhereItDoesNot)
{
    // 1 % vegetation: Otsu splits the soil near its mode, above_soil stays
    // 5 sigma above it and below the vegetation.
    const Histogram sparse = soil_and_vegetation(100, 8, 160, 0.01);
    EXPECT_LT(otsu_threshold(sparse), 110);
    EXPECT_NEAR(above_soil_threshold(sparse, 5), 140, 1);
    // 30 % vegetation: Otsu already separates the classes, and is kept.
    const Histogram dense = soil_and_vegetation(100, 3, 140, 0.3);
    EXPECT_GT(otsu_threshold(dense), 115);
    EXPECT_EQ(above_soil_threshold(dense, 5), otsu_threshold(dense));
    EXPECT_EQ(auto_threshold(dense, ThresholdMethod::above_soil, 5), above_soil_threshold(dense, 5));
}

namespace {

struct Mode {
    double level, sigma, fraction;
};

// A histogram of a million pixels drawn from Gaussian modes.
Histogram mixture(std::initializer_list<Mode> modes)
{
    Histogram h{};
    for (int v = 0; v < 256; ++v) {
        double n = 0;
        for (const Mode& m : modes) {
            const double z = (v - m.level) / m.sigma;
            n += m.fraction * 1e6 * std::exp(-0.5 * z * z) / (m.sigma * std::sqrt(2 * M_PI));
        }
        h[static_cast<std::size_t>(v)] = static_cast<std::uint32_t>(std::lround(n));
    }
    return h;
}

}  // namespace

TEST(Threshold, UnderMostlyLeavesTheSoilIsTheLowerModeNearZero)
{
    // Leaves over 90 % of the frame: their level is the histogram's mode,
    // and the soil a lower mode at the index's zero.
    for (const double leaves : {0.8, 0.9, 0.97}) {
        SCOPED_TRACE(leaves);
        const Histogram h = mixture({{128, 2, 1 - leaves}, {200, 8, leaves}});
        ASSERT_NEAR(histogram_mode(h), 200, 1);  // what the soil was taken for
        EXPECT_EQ(soil_mode(h), 128);
        EXPECT_NEAR(soil_noise_threshold(h, 5), 138, 1);
        // The threshold is the valley between the two modes: Otsu would
        // split the leaves, as it splits the soil when leaves are few.
        const int t = above_soil_threshold(h, 5);
        const auto under = soil_under_leaves(h);
        ASSERT_TRUE(under);
        EXPECT_EQ(t, under->valley_level);
        for (int v = 129; v < 200; ++v)
            EXPECT_GE(h[static_cast<std::size_t>(v)] + h[static_cast<std::size_t>(v - 1)] + h[static_cast<std::size_t>(v + 1)],
                      h[static_cast<std::size_t>(t)] + h[static_cast<std::size_t>(t - 1)] + h[static_cast<std::size_t>(t + 1)])
                << "level " << v;
        EXPECT_GT(t, 135);
        EXPECT_LT(t, 180);
        EXPECT_GT(class_separation(h, t), 5 * Params{}.min_class_separation);
    }
    // A carrot-like index: soil just below zero, leaves 25 levels above it.
    EXPECT_EQ(soil_mode(mixture({{125, 3, 0.2}, {150, 4, 0.8}})), 125);
}

TEST(Threshold, ALowerModeIsSoilOnlyWhenItIsNearerZeroFarEnoughBelowAndNotAFewPixels)
{
    // Soil with a red patch (clay, a painted part) below it: the patch is
    // farther from zero than the soil, which stays the soil.
    EXPECT_EQ(soil_mode(mixture({{100, 4, 0.3}, {127, 3, 0.7}})), 127);
    // Soil with a green cast over a dark border (dark pixels sit at zero):
    // 7 levels is no leaf's separation from soil.
    EXPECT_EQ(soil_mode(mixture({{128, 0.7, 0.2}, {135, 2, 0.8}})), 135);
    // Leaves over the whole frame but for 0.5 %: too few pixels to be the soil.
    EXPECT_EQ(soil_mode(mixture({{128, 2, 0.005}, {200, 8, 0.995}})), 200);
    // One mode: itself.
    EXPECT_EQ(soil_mode(mixture({{200, 8, 1.0}})), 200);
    EXPECT_EQ(soil_mode(Histogram{}), 0);
    // Where the soil is the mode, above_soil is what it was: Otsu, never
    // inside the soil's spread.
    const Histogram sparse = mixture({{127, 3, 0.95}, {190, 8, 0.05}});
    EXPECT_FALSE(soil_under_leaves(sparse));
    EXPECT_EQ(above_soil_threshold(sparse, 5), std::max(otsu_threshold(sparse), soil_noise_threshold(sparse, 5)));
    // A shoulder below the leaves' mode, with no valley: no second mode.
    EXPECT_EQ(soil_mode(mixture({{185, 8, 0.4}, {200, 8, 0.6}})), histogram_mode(mixture({{185, 8, 0.4}, {200, 8, 0.6}})));
}

TEST(Threshold, ALeafLevelsNoisyLowerTailIsNoSoil)
{
    // Leaves filling a small window, with a long lower tail (shaded and
    // mixed pixels), counted from random pixels: the counts dip and rise
    // by their counting noise, which must not make a peak of their own.
    for (std::uint64_t seed = 1; seed <= 50; ++seed) {
        cv::RNG rng(seed);
        cv::Mat window(160, 160, CV_8UC1);
        for (int y = 0; y < window.rows; ++y)
            for (int x = 0; x < window.cols; ++x)
                window.at<std::uint8_t>(y, x) = cv::saturate_cast<std::uint8_t>(
                    rng.uniform(0, 10) < 3 ? 195 - std::abs(rng.gaussian(30)) : 200 + rng.gaussian(8));
        Histogram h{};
        compute_histogram(window, h);
        EXPECT_FALSE(soil_under_leaves(h)) << "seed " << seed << ": soil at " << soil_under_leaves(h)->soil_level;
    }
}

