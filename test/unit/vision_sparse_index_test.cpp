// The smoothed index on fewer pixels against the whole-frame index.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "stemd/vision/detect.hpp"
#include "stemd/vision/index.hpp"
#include "stemd/vision/plants.hpp"
#include "stemd/vision/sparse_index.hpp"
#include "stemd/vision/threshold.hpp"

namespace stemd::vision {
namespace {

const cv::Scalar kSoil(70, 90, 110);    // BGR: brown
const cv::Scalar kLeaf(50, 150, 70);    // BGR: green

// Brown soil with sensor-like noise (sigma 4 per channel), deterministic.
cv::Mat soil_frame(cv::Size size, std::uint64_t seed)
{
    cv::Mat noise(size, CV_16SC3);
    cv::RNG rng(seed);
    rng.fill(noise, cv::RNG::NORMAL, 0, 4);
    cv::Mat frame(size, CV_16SC3, kSoil);
    frame += noise;
    cv::Mat out;
    frame.convertTo(out, CV_8UC3);
    return out;
}

// The whole-frame smoothed index and its histogram.
struct WholeFrame {
    cv::Mat raw, index;
    Histogram histogram{};
    WholeFrame(const cv::Mat& bgr, RgbIndex kind)
    {
        if (kind == RgbIndex::exg)
            excess_green(bgr, raw);
        else
            chromatic_excess_green(bgr, raw);
        std::vector<std::uint16_t> sums(static_cast<std::size_t>(bgr.cols));
        smooth_binomial3(raw, sums.data(), index);
        compute_histogram(index, histogram);
    }
};

struct Sparse {
    SparseIndexScratch scratch;
    cv::Mat raw, index;
    Histogram histogram{};
    int level = 0;
    Sparse(const cv::Mat& bgr, RgbIndex kind, int reach_px = 5)
    {
        scratch.reserve(bgr.cols, bgr.rows);
        raw.create(bgr.size(), CV_8UC1);
        index.create(bgr.size(), CV_8UC1);
        level = sparse_smoothed_index(bgr, kind, SparseLevel{}, reach_px, scratch, raw, index, histogram);
    }
};

long histogram_total(const Histogram& h)
{
    long n = 0;
    for (const auto c : h)
        n += c;
    return n;
}

bool same_bits(const BitMask& a, const BitMask& b)
{
    if (a.width() != b.width() || a.height() != b.height())
        return false;
    for (int y = 0; y < a.height(); ++y)
        for (int w = 0; w < a.words_per_row(); ++w)
            if (a.row(y)[w] != b.row(y)[w])
                return false;
    return true;
}

TEST(SmoothBinomial3Rect, TilesOfAnyShapeGiveTheWholeFrameSmoothing)
{
    cv::Mat src(37, 71, CV_8UC1);
    cv::RNG(3).fill(src, cv::RNG::UNIFORM, 0, 256);
    cv::Mat whole;
    std::vector<std::uint16_t> sums(71);
    smooth_binomial3(src, sums.data(), whole);
    cv::Mat pieces(src.size(), CV_8UC1, cv::Scalar(0));
    for (int y = 0; y < src.rows; y += 5)
        for (int x = 0; x < src.cols; x += 13)
            smooth_binomial3_rect(src, cv::Rect(x, y, 13, 5), sums.data(), pieces);
    EXPECT_EQ(cv::norm(whole, pieces, cv::NORM_INF), 0.0);
}

TEST(ChromaticExcessGreenSpan, SpansOfAnyWidthGiveTheWholeFrameIndex)
{
    cv::Mat bgr(9, 200, CV_8UC3);
    cv::RNG(5).fill(bgr, cv::RNG::UNIFORM, 0, 256);
    cv::Mat whole;
    chromatic_excess_green(bgr, whole);
    const float mean = chromatic_mean_brightness(bgr);
    cv::Mat spans(bgr.size(), CV_8UC1, cv::Scalar(0));
    const int g = index_span_granule_px();
    for (const Kernel kernel : kKernels) {
        if (!kernel_available(kernel))
            continue;
        // Spans of every width from 1 to 40 (around the sixteen-pixel steps
        // and the two pixels the SSSE3 loads read past a step), one after
        // another along each row, and spans that end at the row's end.
        spans.setTo(0);
        for (int y = 0; y < bgr.rows; ++y)
            for (int x = 0, width = 1 + y; x < bgr.cols; x += width, width = width % 40 + 1)
                chromatic_excess_green_span(bgr, y, x, std::min(x + width, bgr.cols), mean, spans, kernel);
        EXPECT_EQ(cv::norm(whole, spans, cv::NORM_INF), 0.0) << "kernel " << static_cast<int>(kernel);
        spans.setTo(0);
        for (int y = 0; y < bgr.rows; ++y)
            for (int x = 0; x < bgr.cols; x += 3 * g + 5)
                chromatic_excess_green_span(bgr, y, x, std::min(x + 3 * g + 5, bgr.cols), mean, spans, kernel);
        EXPECT_EQ(cv::norm(whole, spans, cv::NORM_INF), 0.0) << "kernel " << static_cast<int>(kernel);
    }
}

TEST(ChromaticExcessGreenSpan, EveryKernelStaysInsideTheRowsOfAView)
{
    // Views (rows not contiguous) of every width around the vector steps.
    // The input view ends where its buffer ends, so a load past the last
    // row's end is an overread (reported under ASan); the output view lies
    // between guard columns that must keep their value.
    cv::RNG rng(17);
    constexpr int kGuard = 3;
    constexpr std::uint8_t kGuardValue = 77;
    for (int width = 1; width <= 70; ++width) {
        cv::Mat wide(4, width + 2 * kGuard, CV_8UC3);
        rng.fill(wide, cv::RNG::UNIFORM, 0, 256);
        const cv::Mat bgr = wide.colRange(2 * kGuard, 2 * kGuard + width);
        const float mean = chromatic_mean_brightness(bgr);
        cv::Mat expected(bgr.size(), CV_8UC1);
        for (int y = 0; y < bgr.rows; ++y)
            for (int x = 0; x < width; ++x)
                chromatic_excess_green_span(bgr, y, x, x + 1, mean, expected, Kernel::baseline);
        for (const Kernel kernel : kKernels) {
            if (!kernel_available(kernel))
                continue;
            cv::Mat out(bgr.rows, width + 2 * kGuard, CV_8UC1, cv::Scalar(kGuardValue));
            cv::Mat got = out.colRange(kGuard, kGuard + width);
            for (int y = 0; y < bgr.rows; ++y)
                chromatic_excess_green_span(bgr, y, 0, width, mean, got, kernel);
            ASSERT_EQ(cv::norm(expected, got, cv::NORM_INF), 0.0)
                << "kernel " << static_cast<int>(kernel) << " width " << width;
            for (int y = 0; y < out.rows; ++y)
                for (int x = 0; x < kGuard; ++x) {
                    ASSERT_EQ(out.at<std::uint8_t>(y, x), kGuardValue) << "kernel " << static_cast<int>(kernel);
                    ASSERT_EQ(out.at<std::uint8_t>(y, kGuard + width + x), kGuardValue)
                        << "kernel " << static_cast<int>(kernel);
                }
        }
    }
}

TEST(ChromaticExcessGreenSpan, TheScalarPathGivesTheVectorPathsValueForEveryColour)
{
    // All 2^24 colours, 4096 to a row: the whole rows take the vector path,
    // spans of one pixel the scalar one.
    cv::Mat bgr(4096, 4096, CV_8UC3);
    for (int y = 0; y < bgr.rows; ++y)
        for (int x = 0; x < bgr.cols; ++x) {
            const int colour = y * 4096 + x;
            bgr.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<std::uint8_t>(colour & 255),
                                                static_cast<std::uint8_t>((colour >> 8) & 255),
                                                static_cast<std::uint8_t>(colour >> 16));
        }
    const float mean = chromatic_mean_brightness(bgr);
    cv::Mat whole(bgr.size(), CV_8UC1), single(bgr.size(), CV_8UC1);
    for (int y = 0; y < bgr.rows; ++y)
        for (int x = 0; x < bgr.cols; ++x)
            chromatic_excess_green_span(bgr, y, x, x + 1, mean, single);
    // Every vector kernel this CPU has.
    for (const Kernel kernel : kKernels) {
        if (!kernel_available(kernel)) {
            std::printf("this CPU lacks kernel %d: not checked\n", static_cast<int>(kernel));
            continue;
        }
        for (int y = 0; y < bgr.rows; ++y)
            chromatic_excess_green_span(bgr, y, 0, bgr.cols, mean, whole, kernel);
        EXPECT_EQ(cv::norm(whole, single, cv::NORM_INF), 0.0) << "kernel " << static_cast<int>(kernel);
    }
    for (int y = 0; y < 64; ++y) {
        excess_green_span(bgr, y, 0, bgr.cols, whole);
        for (int x = 0; x < bgr.cols; ++x)
            excess_green_span(bgr, y, x, x + 1, single);
    }
    EXPECT_EQ(cv::norm(whole.rowRange(0, 64), single.rowRange(0, 64), cv::NORM_INF), 0.0);
}

// The histogram of `index` with each band of kSparseRowStep rows counted
// from its sampled row (its row 4, or the frame's last row when the band
// has none), as many times as the band has rows.
Histogram sampled_rows_histogram(const cv::Mat& index)
{
    Histogram h{};
    for (int band = 0; band < index.rows; band += kSparseRowStep) {
        const int rows = std::min(kSparseRowStep, index.rows - band);
        const int y = std::min(band + kSparseRowStep / 2, index.rows - 1);
        for (int x = 0; x < index.cols; ++x)
            h[index.at<std::uint8_t>(y, x)] += static_cast<std::uint32_t>(rows);
    }
    return h;
}

TEST(SparseIndex, VegetationInEveryTileGivesTheWholeFrameIndexAndItsHistogram)
{
    // Grass-like green stripes across every tile, crossing every sampled
    // row; heights of whole bands of sampled rows, and ones whose last band
    // is shorter (195: sampled at the frame's last row). The small frames' few
    // sampled rows are counted exactly, the camera-sized frames' estimated.
    struct Case {
        cv::Size size;
        bool estimated;
    };
    for (const Case c : {Case{{300, 200}, false}, Case{{301, 195}, false}, Case{{1296, 968}, true},
                         Case{{1297, 966}, true}}) {
        const long sampled_pixels = static_cast<long>((c.size.height + kSparseRowStep - 1) / kSparseRowStep) * c.size.width;
        ASSERT_EQ(sampled_pixels >= kSampledPixelsForEstimate, c.estimated) << c.size;
        cv::Mat bgr = soil_frame(c.size, 11);
        for (int x = 10; x < bgr.cols; x += 30)
            cv::line(bgr, {x, 0}, {x + 20, bgr.rows - 1}, kLeaf, 3);
        for (const RgbIndex kind : {RgbIndex::chromatic_exg, RgbIndex::exg}) {
            const WholeFrame whole(bgr, kind);
            const Sparse sparse(bgr, kind);
            EXPECT_EQ(sparse.scratch.computed_tiles(), sparse.scratch.tiles()) << c.size;
            EXPECT_EQ(cv::norm(whole.index, sparse.index, cv::NORM_INF), 0.0) << c.size;
            EXPECT_EQ(histogram_total(sparse.histogram), static_cast<long>(c.size.area())) << c.size;
            if (!c.estimated) {
                EXPECT_EQ(sparse.histogram, whole.histogram) << c.size;
                continue;
            }
            EXPECT_EQ(sparse.histogram, sampled_rows_histogram(whole.index)) << c.size;
            // The estimate may move the threshold within the gap between
            // soil and leaf, but must not change which pixels are leaf:
            // few lie between the two thresholds.
            const int exact = auto_threshold(whole.histogram, ThresholdMethod::above_soil, 5.0);
            const int estimated = auto_threshold(sparse.histogram, ThresholdMethod::above_soil, 5.0);
            long between = 0, leaf = 0;
            for (int v = 0; v < 256; ++v) {
                between += v > std::min(exact, estimated) && v <= std::max(exact, estimated) ? whole.histogram[v] : 0;
                leaf += v > exact ? whole.histogram[v] : 0;
            }
            EXPECT_LE(between * 100, leaf) << c.size << ": thresholds " << exact << " and " << estimated;
        }
    }
}

TEST(SparseIndex, CompletingASparseIndexGivesTheWholeFrameResult)
{
    // A seedling in one tile (a few tiles computed), and a blade along a
    // tile row (whole rows of tiles computed, their rows' raw index kept
    // for the tile rows beside): completed, each is the whole frame's index.
    cv::Mat seedling = soil_frame({320, 256}, 12);
    cv::circle(seedling, {150, 100}, 6, kLeaf, cv::FILLED);
    cv::Mat blade = soil_frame({640, 480}, 31);
    cv::line(blade, {0, 199}, {639, 206}, kLeaf, 2);
    for (const cv::Mat* bgr : {&seedling, &blade}) {
        for (const RgbIndex kind : {RgbIndex::chromatic_exg, RgbIndex::exg}) {
            const WholeFrame whole(*bgr, kind);
            Sparse sparse(*bgr, kind);
            ASSERT_LT(sparse.scratch.computed_tiles(), sparse.scratch.tiles()) << "the frame must leave soil tiles";
            complete_sparse_index(*bgr, sparse.scratch, sparse.raw, sparse.index, sparse.histogram);
            EXPECT_EQ(sparse.scratch.computed_tiles(), sparse.scratch.tiles());
            EXPECT_EQ(cv::norm(whole.index, sparse.index, cv::NORM_INF), 0.0) << bgr->cols << " px wide";
            EXPECT_EQ(whole.histogram, sparse.histogram);
        }
    }
}

TEST(SparseIndex, BareSoilComputesLittleAndCountsEveryPixel)
{
    const cv::Mat bgr = soil_frame({640, 480}, 12);
    const Sparse sparse(bgr, RgbIndex::chromatic_exg);
    const WholeFrame whole(bgr, RgbIndex::chromatic_exg);
    EXPECT_LE(sparse.scratch.computed_tiles(), sparse.scratch.tiles() / 4);
    EXPECT_EQ(histogram_total(sparse.histogram), 640L * 480);
    // The soil tiles hold the soil level; the estimated histogram has the
    // whole frame's soil mode.
    EXPECT_EQ(histogram_mode(sparse.histogram), histogram_mode(whole.histogram));
    EXPECT_EQ(sparse.index.at<std::uint8_t>(100, 100) == sparse.scratch.soil_level() ||
                  sparse.scratch.computed(100 / kSparseTilePx, 100 / kSparseTilePx),
              true);
}

TEST(SparseIndex, BareSoilStaysBareSoil)
{
    const cv::Mat bgr = soil_frame({640, 480}, 13);
    Params params;
    params.gsd_mm_per_px = 0.4;
    Workspace ws(bgr.size(), params);
    Detections out;
    detect(FrameView{bgr, {}, {}}, params, ws, out);
    ASSERT_EQ(out.status, DetectStatus::ok);
    EXPECT_TRUE(out.plants.empty());
    EXPECT_EQ(ws.vegetation().count(), 0);
    EXPECT_GT(out.stats.index_tiles, 0);
}

// detect() with the sparse index and without it on the same frame.
void expect_same_detections(const cv::Mat& bgr, Params params)
{
    params.sparse_index = true;
    Workspace sparse_ws(bgr.size(), params);
    Detections sparse;
    detect(FrameView{bgr, {}, {}}, params, sparse_ws, sparse);
    params.sparse_index = false;
    Workspace whole_ws(bgr.size(), params);
    Detections whole;
    detect(FrameView{bgr, {}, {}}, params, whole_ws, whole);
    EXPECT_EQ(sparse.stats.threshold, whole.stats.threshold);
    EXPECT_TRUE(same_bits(sparse_ws.vegetation(), whole_ws.vegetation()));
    ASSERT_EQ(sparse.plants.size(), whole.plants.size());
    for (std::size_t i = 0; i < whole.plants.size(); ++i) {
        EXPECT_EQ(sparse.plants[i].area_px, whole.plants[i].area_px);
        EXPECT_EQ(sparse.plants[i].stem, whole.plants[i].stem);
    }
}

TEST(SparseIndex, ATinyPlantAtEveryOffsetBetweenSampledRowsIsFound)
{
    // A seedling 9 rows tall always touches a sampled row (every 8th), at
    // whatever height it lies; one with leaves 2 px wide as well.
    for (int offset = 0; offset < kSparseRowStep; ++offset) {
        cv::Mat bgr = soil_frame({400, 300}, 20 + static_cast<std::uint64_t>(offset));
        cv::ellipse(bgr, {150, 130 + offset}, {9, 4}, 0, 0, 360, kLeaf, cv::FILLED);  // rows -4..+4
        cv::line(bgr, {300, 60 + offset}, {330, 68 + offset}, kLeaf, 2);  // rows -1..+9
        Params params;
        params.gsd_mm_per_px = 0.4;
        params.min_plant_area_mm2 = 4.0;
        SCOPED_TRACE(offset);
        expect_same_detections(bgr, params);
        Workspace ws(bgr.size(), params);
        Detections out;
        detect(FrameView{bgr, {}, {}}, params, ws, out);
        EXPECT_EQ(out.plants.size(), 2u);
        EXPECT_LT(out.stats.index_tiles_computed, out.stats.index_tiles);
    }
}

TEST(SparseIndex, APlantAcrossManyTilesIsComputedWhole)
{
    // A thin blade lying almost along the rows reaches a sampled row (204)
    // only near its right end; the tiles to its left are reached by growing
    // from tile to tile along it.
    cv::Mat bgr = soil_frame({640, 480}, 30);
    cv::line(bgr, {20, 199}, {620, 206}, kLeaf, 2);
    const Sparse sparse(bgr, RgbIndex::chromatic_exg);
    for (int col = 0; col < 10; ++col)
        EXPECT_TRUE(sparse.scratch.computed(col, 198 / kSparseTilePx)) << col;
    Params params;
    params.gsd_mm_per_px = 0.4;
    expect_same_detections(bgr, params);
}

TEST(SparseIndex, ATileReachesTheNeighboursOnlyOnTheSidesItsVegetationIsNear)
{
    // Three frames, a leaf in tile (2, 2) (x and y 128..191) crossing the
    // sampled row 156 or 188, reach 5 px: in the middle it reaches no
    // neighbour; within reach of the right side, the right one; within reach
    // of the right and lower sides, those two and the one diagonally
    // between them. Soil without noise, so no tile but the leaf's is found.
    struct Case {
        cv::Rect leaf;
        std::vector<cv::Point> reached;   // tile (col, row)
    };
    const Case cases[] = {
        {{150, 152, 12, 8}, {}},
        {{176, 152, 12, 8}, {{3, 2}}},
        {{176, 180, 12, 8}, {{3, 2}, {2, 3}, {3, 3}}},
    };
    for (const Case& c : cases) {
        cv::Mat bgr(480, 640, CV_8UC3, kSoil);
        cv::rectangle(bgr, c.leaf, kLeaf, cv::FILLED);
        const Sparse sparse(bgr, RgbIndex::chromatic_exg, 5);
        for (int row = 0; row < 8; ++row)
            for (int col = 0; col < 10; ++col) {
                const bool own = col == 2 && row == 2;
                const bool reached = std::find(c.reached.begin(), c.reached.end(), cv::Point(col, row)) != c.reached.end();
                EXPECT_EQ(sparse.scratch.computed(col, row), own || reached)
                    << "leaf at " << c.leaf.x << "," << c.leaf.y << ": tile " << col << "," << row;
            }
    }
}

TEST(SparseIndex, APieceShorterThanTheStepBetweenSampledRowsAndFarFromPlantsIsMissed)
{
    // The bound, as documented: a piece 3 rows tall whose smoothed index
    // (5 rows) lies between two sampled rows (196 and 204; 316 and 324) and
    // whose raw index misses the rows beside them (197, 203; 317, 323), far
    // from any plant, stays soil. The same piece over a sampled row is
    // computed, and so is one whose raw core crosses a row beside one.
    cv::Mat bgr = soil_frame({640, 480}, 40);
    cv::rectangle(bgr, cv::Rect(300, 198, 30, 3), kLeaf, cv::FILLED);  // rows 198..200, smoothed 197..201
    cv::rectangle(bgr, cv::Rect(100, 318, 30, 3), kLeaf, cv::FILLED);  // rows 318..320, smoothed 317..321
    cv::rectangle(bgr, cv::Rect(500, 98, 30, 3), kLeaf, cv::FILLED);   // rows 98..100: row 100 is sampled
    cv::rectangle(bgr, cv::Rect(100, 429, 30, 3), kLeaf, cv::FILLED);  // rows 429..431: crosses raw row 429 beside 428
    const Sparse sparse(bgr, RgbIndex::chromatic_exg);
    const WholeFrame whole(bgr, RgbIndex::chromatic_exg);
    EXPECT_FALSE(sparse.scratch.computed(300 / kSparseTilePx, 197 / kSparseTilePx));
    EXPECT_FALSE(sparse.scratch.computed(100 / kSparseTilePx, 318 / kSparseTilePx));
    EXPECT_TRUE(sparse.scratch.computed(500 / kSparseTilePx, 98 / kSparseTilePx));
    EXPECT_TRUE(sparse.scratch.computed(100 / kSparseTilePx, 429 / kSparseTilePx));
    EXPECT_GT(whole.index.at<std::uint8_t>(199, 310), sparse.level);
    EXPECT_EQ(sparse.index.at<std::uint8_t>(199, 310), sparse.scratch.soil_level());
    EXPECT_EQ(sparse.index.at<std::uint8_t>(99, 510), whole.index.at<std::uint8_t>(99, 510));
}

TEST(SparseIndex, AThresholdBelowTheLevelFallsBackOnTheWholeFrame)
{
    // Otsu on bare soil splits the soil's own noise, far below the sparse
    // level: the whole frame is then computed and decides.
    const cv::Mat bgr = soil_frame({640, 480}, 50);
    Params params;
    params.gsd_mm_per_px = 0.4;
    params.threshold = ThresholdMethod::otsu;
    params.min_class_separation = 0;
    expect_same_detections(bgr, params);
    Workspace ws(bgr.size(), params);
    Detections out;
    detect(FrameView{bgr, {}, {}}, params, ws, out);
    EXPECT_EQ(out.stats.index_tiles_computed, out.stats.index_tiles);
}

// exg_and_ndvi's greenness test: the components of `mask` kept by it.
struct Greener {
    SparseIndexScratch scratch;
    cv::Mat raw, index;
    LabelScratch labels;
    std::vector<Component> components;
    std::vector<std::uint8_t> keep;
    int bar = 0;
    Greener(const cv::Mat& bgr, const BitMask& mask, const BitMask& seeds, double sigmas = 2.0)
    {
        scratch.reserve(bgr.cols, bgr.rows);
        raw.create(bgr.size(), CV_8UC1);
        index.create(bgr.size(), CV_8UC1);
        labels.reserve(bgr.cols, bgr.rows);
        label_components(mask, labels, components);
        bar = mark_green_seeded_components(bgr, sigmas, seeds, labels, scratch, raw, index, keep);
    }
};

// The seeds whose whole-frame smoothed index is above `bar`.
BitMask whole_frame_greener(const cv::Mat& bgr, const BitMask& seeds, int bar)
{
    const WholeFrame whole(bgr, RgbIndex::chromatic_exg);
    BitMask out;
    out.reset(bgr.cols, bgr.rows);
    for (int y = 0; y < bgr.rows; ++y)
        for (int x = 0; x < bgr.cols; ++x)
            if (seeds.get(x, y) && whole.index.at<std::uint8_t>(y, x) > bar)
                out.set(x, y);
    return out;
}

// Soil with green discs covering about `cover` of it.
cv::Mat soil_with_leaves(cv::Size size, double cover, std::uint64_t seed)
{
    cv::Mat bgr = soil_frame(size, seed);
    cv::RNG rng(seed + 1);
    const int radius = 12;
    const int discs = static_cast<int>(cover * size.area() / (3.14159 * radius * radius));
    for (int i = 0; i < discs; ++i)
        cv::circle(bgr, {rng.uniform(0, size.width), rng.uniform(0, size.height)}, radius, kLeaf, cv::FILLED);
    return bgr;
}

TEST(GreenerThanSoil, KeepsTheComponentsATestOfEverySeedOnTheWholeFrameKeeps)
{
    // 300 px wide (a last word of 44 px). Rectangles over leaves and soil
    // alike, on every border and across whole rows, most of them seeded at
    // random, one seeded on every pixel of two rows beside a sampled row.
    const cv::Mat bgr = soil_with_leaves({300, 200}, 0.1, 21);
    cv::Mat mask_u8(bgr.size(), CV_8UC1, cv::Scalar(0));
    cv::RNG rng(22);
    for (int i = 0; i < 40; ++i) {
        const int x = rng.uniform(-20, bgr.cols), y = rng.uniform(-20, bgr.rows);
        cv::rectangle(mask_u8, cv::Rect(x, y, rng.uniform(3, 60), rng.uniform(3, 40)), cv::Scalar(255), cv::FILLED);
    }
    mask_u8.rowRange(36, 39).setTo(255);
    BitMask mask, seeds;
    pack_mask(mask_u8, MaskVegetation::nonzero, mask);
    seeds.reset(bgr.cols, bgr.rows);
    for (int y = 0; y < bgr.rows; ++y)
        for (int x = 0; x < bgr.cols; ++x)
            if (mask.get(x, y) && (y == 3 || y == 5 || rng.uniform(0.0, 1.0) < 0.05))
                seeds.set(x, y);
    const Greener greener(bgr, mask, seeds);

    std::vector<std::uint8_t> expected;
    mark_seeded_components(greener.labels, whole_frame_greener(bgr, seeds, greener.bar), expected);
    ASSERT_EQ(greener.keep.size(), expected.size());
    EXPECT_EQ(greener.keep, expected);
    // Both outcomes occur, and components whose first seed fails the test
    // are kept by a later one: the test goes on until a seed passes.
    const auto kept = std::count(expected.begin(), expected.end(), std::uint8_t{1});
    EXPECT_GT(kept, 0);
    EXPECT_LT(kept, static_cast<long>(expected.size()));
    const BitMask passing = whole_frame_greener(bgr, seeds, greener.bar);
    std::vector<std::uint8_t> first_seed_seen(expected.size(), 0), first_seed_failed(expected.size(), 0);
    for (std::size_t i = 0; i < greener.labels.run_count(); ++i) {
        const LabelScratch::LabelledRun run = greener.labels.run(i);
        const auto c = static_cast<std::size_t>(run.component);
        for (int x = run.x0; x <= run.x1 && !first_seed_seen[c]; ++x)
            if (seeds.get(x, run.y)) {
                first_seed_seen[c] = 1;
                first_seed_failed[c] = !passing.get(x, run.y);
            }
    }
    int kept_after_a_failure = 0;
    for (std::size_t c = 0; c < expected.size(); ++c)
        kept_after_a_failure += expected[c] && first_seed_failed[c];
    EXPECT_GT(kept_after_a_failure, 0);
}

TEST(GreenerThanSoil, NoSeedsKeepNothingAndAnEmptyFrameHasNoBar)
{
    const cv::Mat bgr = soil_with_leaves({130, 70}, 0.2, 23);
    BitMask mask, seeds;
    mask.reset(bgr.cols, bgr.rows);
    seeds.reset(bgr.cols, bgr.rows);
    for (int x = 10; x < 60; ++x)
        mask.set(x, 30);
    const Greener greener(bgr, mask, seeds);
    ASSERT_EQ(greener.keep.size(), 1u);
    EXPECT_EQ(greener.keep[0], 0);
    EXPECT_LT(greener.bar, 255);

    SparseIndexScratch scratch;
    scratch.reserve(0, 0);
    cv::Mat empty_bgr(0, 0, CV_8UC3), raw(0, 0, CV_8UC1), index(0, 0, CV_8UC1);
    BitMask none;
    none.reset(0, 0);
    LabelScratch labels;
    labels.reserve(0, 0);
    std::vector<Component> components;
    label_components(none, labels, components);
    std::vector<std::uint8_t> keep;
    EXPECT_EQ(mark_green_seeded_components(empty_bgr, 2.0, none, labels, scratch, raw, index, keep), 255);
    EXPECT_TRUE(keep.empty());
}

TEST(GreenerThanSoil, TheSampledRowsGiveTheWholeFramesBar)
{
    // The bar is a statistic of the soil, and every row shows the same
    // soil: from 1 % to 30 % vegetation the sampled rows' bar is the whole
    // frame's.
    for (const double cover : {0.01, 0.1, 0.3}) {
        for (std::uint64_t seed = 31; seed < 34; ++seed) {
            const cv::Mat bgr = soil_with_leaves({1296, 966}, cover, seed);
            BitMask none;
            none.reset(bgr.cols, bgr.rows);
            const Greener greener(bgr, none, none);
            const WholeFrame whole(bgr, RgbIndex::chromatic_exg);
            EXPECT_EQ(greener.bar, soil_noise_threshold(whole.histogram, 2.0)) << "cover " << cover << " seed " << seed;
        }
    }
}

}  // namespace
}  // namespace stemd::vision
