#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <stdexcept>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "synth_test_util.hpp"
#include "stemd/synth/synth.hpp"

using namespace stemd::synth;
using stemd::PlantClass;

namespace {

constexpr double kGsdMmPerPx = 0.33;

Frame make(Preset preset, std::uint64_t seed, int index, double fragmentation = -1)
{
    Options options;
    options.preset = preset;
    options.seed = seed;
    options.fragmentation = fragmentation;
    return generate_frame(options, index);
}

using stemd::test::expect_same_planes;
using stemd::test::same_bytes;

// Connected regions of the mask (8-connected), as the detector sees them.
struct Regions {
    cv::Mat labels;   // CV_32S
    cv::Mat stats;
    cv::Mat centroids;
    int count = 0;    // including background 0
};

Regions regions_of(const cv::Mat& mask)
{
    Regions r;
    r.count = cv::connectedComponentsWithStats(mask, r.labels, r.stats, r.centroids, 8, CV_32S);
    return r;
}

bool touches_border(const Regions& r, int label)
{
    const int x = r.stats.at<int>(label, cv::CC_STAT_LEFT), y = r.stats.at<int>(label, cv::CC_STAT_TOP);
    return x == 0 || y == 0 || x + r.stats.at<int>(label, cv::CC_STAT_WIDTH) == r.labels.cols ||
           y + r.stats.at<int>(label, cv::CC_STAT_HEIGHT) == r.labels.rows;
}

// The region on or within 2 px of the stem; 0 if none.
int region_at(const Regions& r, const GroundTruthStem& stem)
{
    const int cx = static_cast<int>(std::lround(stem.x_px)), cy = static_cast<int>(std::lround(stem.y_px));
    for (int radius = 0; radius <= 2; ++radius)
        for (int y = cy - radius; y <= cy + radius; ++y)
            for (int x = cx - radius; x <= cx + radius; ++x)
                if (x >= 0 && y >= 0 && x < r.labels.cols && y < r.labels.rows && r.labels.at<int>(y, x) != 0)
                    return r.labels.at<int>(y, x);
    return 0;
}

struct PresetRanges {
    Preset preset;
    int crops_lo, crops_hi, weeds_lo, weeds_hi, crop_leaves_lo, crop_leaves_hi;
};

// The ranges of the brief (paper datasets B, A, C), not the generator's table.
constexpr PresetRanges kRanges[] = {
    {Preset::early, 4, 7, 6, 12, 2, 4},
    {Preset::late, 2, 4, 2, 5, 4, 8},
    {Preset::dense, 6, 10, 5, 10, 4, 7},
};

}  // namespace

TEST(SynthPreset, ParseAndName)
{
    for (const Preset p : {Preset::early, Preset::late, Preset::dense, Preset::seedling, Preset::canopy})
        EXPECT_EQ(parse_preset(to_string(p)), p);
    EXPECT_EQ(to_string(Preset::dense), "dense");
    EXPECT_FALSE(parse_preset("Late").has_value());
    EXPECT_FALSE(parse_preset("").has_value());
}

TEST(SynthDeterminism, SameInputsGiveSameBytes)
{
    const Frame a = make(Preset::dense, 42, 3);
    const Frame b = make(Preset::dense, 42, 3);
    expect_same_planes(a, b);
    ASSERT_EQ(a.stems.size(), b.stems.size());
    for (std::size_t i = 0; i < a.stems.size(); ++i) {
        EXPECT_EQ(a.stems[i].x_px, b.stems[i].x_px);
        EXPECT_EQ(a.stems[i].y_px, b.stems[i].y_px);
        EXPECT_EQ(a.stems[i].kind, b.stems[i].kind);
        EXPECT_EQ(a.stems[i].leaves, b.stems[i].leaves);
    }
}

TEST(SynthDeterminism, SeedPresetAndIndexChangeTheFrame)
{
    const Frame base = make(Preset::late, 42, 3);
    EXPECT_FALSE(same_bytes(base.bgr, make(Preset::late, 43, 3).bgr));
    EXPECT_FALSE(same_bytes(base.bgr, make(Preset::late, 42, 4).bgr));
    EXPECT_FALSE(same_bytes(base.mask, make(Preset::late, 43, 3).mask));
    EXPECT_FALSE(same_bytes(base.mask, make(Preset::early, 42, 3).mask));
}

TEST(SynthFrame, SizesAndTypesFollowOptions)
{
    for (const Preset p : {Preset::early, Preset::late, Preset::dense, Preset::seedling, Preset::canopy}) {
        Options options;
        options.preset = p;
        options.width_px = 320;
        options.height_px = 200;
        options.gsd_mm_per_px = 0.5;
        const Frame f = generate_frame(options, 0);
        EXPECT_EQ(f.bgr.type(), CV_8UC3);
        EXPECT_EQ(f.nir.type(), CV_8UC1);
        EXPECT_EQ(f.mask.type(), CV_8UC1);
        for (const cv::Mat* m : {&f.bgr, &f.nir, &f.mask})
            EXPECT_EQ(m->size(), cv::Size(320, 200));
        // Binary mask: only 0 and 255.
        const cv::Mat other = (f.mask != 0) & (f.mask != 255);
        EXPECT_EQ(cv::countNonZero(other), 0);
        EXPECT_GT(cv::countNonZero(f.mask), 0);
    }
}

TEST(SynthFrame, RejectsBadOptions)
{
    Options o;
    o.width_px = 8;
    EXPECT_THROW(generate_frame(o, 0), std::invalid_argument);
    o = Options{};
    o.gsd_mm_per_px = 0;
    EXPECT_THROW(generate_frame(o, 0), std::invalid_argument);
    o = Options{};
    o.fragmentation = 1.5;
    EXPECT_THROW(generate_frame(o, 0), std::invalid_argument);
    EXPECT_THROW(generate_frame(Options{}, -1), std::invalid_argument);
}

TEST(SynthGroundTruth, StemsInsideImageAndOnMask)
{
    for (const Preset p : {Preset::early, Preset::late, Preset::dense}) {
        for (int index = 0; index < 2; ++index) {
            const Frame f = make(p, 7, index);
            ASSERT_FALSE(f.stems.empty());
            const Regions r = regions_of(f.mask);
            for (const GroundTruthStem& s : f.stems) {
                EXPECT_GE(s.x_px, 0);
                EXPECT_GE(s.y_px, 0);
                EXPECT_LE(s.x_px, f.mask.cols - 1);
                EXPECT_LE(s.y_px, f.mask.rows - 1);
                EXPECT_NE(region_at(r, s), 0) << to_string(p) << " frame " << index << " stem " << s.x_px << ","
                                              << s.y_px;
            }
        }
    }
}

TEST(SynthGroundTruth, CountsWithinPresetRanges)
{
    for (const PresetRanges& range : kRanges) {
        for (int index = 0; index < 3; ++index) {
            const Frame f = make(range.preset, 11, index);
            int crops = 0, weeds = 0;
            for (const GroundTruthStem& s : f.stems) {
                ASSERT_TRUE(s.kind == PlantClass::Crop || s.kind == PlantClass::Weed) << to_string(s.kind);
                if (s.kind == PlantClass::Crop) {
                    ++crops;
                    EXPECT_GE(s.leaves, range.crop_leaves_lo);
                    EXPECT_LE(s.leaves, range.crop_leaves_hi);
                } else {
                    ++weeds;
                    EXPECT_GE(s.leaves, 2);
                    EXPECT_LE(s.leaves, 4);
                }
            }
            const std::string where = std::string(to_string(range.preset)) + " frame " + std::to_string(index);
            EXPECT_GE(crops, range.crops_lo) << where;
            EXPECT_LE(crops, range.crops_hi) << where;
            EXPECT_GE(weeds, range.weeds_lo) << where;
            EXPECT_LE(weeds, range.weeds_hi) << where;
        }
    }
}

// Without fragmentation every plant is one region (a plant cut by the image
// border may leave extra pieces there); grass tufts are the regions no
// ground-truth stem touches.
TEST(SynthGroundTruth, GrassIsNotGroundTruth)
{
    auto stemless_regions = [](const Frame& f, bool skip_border) {
        const Regions r = regions_of(f.mask);
        std::vector<bool> has_stem(r.count, false);
        for (const GroundTruthStem& s : f.stems)
            has_stem[region_at(r, s)] = true;
        int count = 0;
        for (int label = 1; label < r.count; ++label)
            count += !has_stem[label] && r.stats.at<int>(label, cv::CC_STAT_AREA) >= 20 &&
                     !(skip_border && touches_border(r, label));
        return count;
    };
    for (int index = 0; index < 2; ++index) {
        EXPECT_GE(stemless_regions(make(Preset::dense, 5, index, 0.0), false), 3) << "dense frame " << index;
        EXPECT_EQ(stemless_regions(make(Preset::late, 5, index, 0.0), true), 0) << "late frame " << index;
    }
}

TEST(SynthPlants, EarlyCropsAreSmallerThanLateCrops)
{
    auto mean_crop_area_px = [](Preset p) {
        double sum = 0;
        int n = 0;
        for (int index = 0; index < 2; ++index) {
            const Frame f = make(p, 3, index);
            const Regions r = regions_of(f.mask);
            for (const GroundTruthStem& s : f.stems) {
                if (s.kind != PlantClass::Crop)
                    continue;
                sum += r.stats.at<int>(region_at(r, s), cv::CC_STAT_AREA);
                ++n;
            }
        }
        return n > 0 ? sum / n : 0.0;
    };
    const double early = mean_crop_area_px(Preset::early), late = mean_crop_area_px(Preset::late);
    EXPECT_GT(early, 0);
    EXPECT_LT(early * 3, late) << "early " << early << " px, late " << late << " px";
}

// The point of the generator: the centre of mass of a plant is not its stem.
// Crops cut by the border are left out: their offset would be trivial.
TEST(SynthPlants, LateCropCentreOfMassIsOffTheStem)
{
    double sum_mm = 0;
    int n = 0;
    for (int index = 0; index < 5; ++index) {
        const Frame f = make(Preset::late, 9, index);
        const Regions r = regions_of(f.mask);
        for (const GroundTruthStem& s : f.stems) {
            if (s.kind != PlantClass::Crop)
                continue;
            const int label = region_at(r, s);
            ASSERT_NE(label, 0);
            if (touches_border(r, label))
                continue;
            const double cx = r.centroids.at<double>(label, 0), cy = r.centroids.at<double>(label, 1);
            // The generator's own bookkeeping agrees with the mask.
            EXPECT_EQ(s.area_px, r.stats.at<int>(label, cv::CC_STAT_AREA));
            EXPECT_NEAR(s.mass_x_px, cx, 1e-6);
            EXPECT_NEAR(s.mass_y_px, cy, 1e-6);
            sum_mm += std::hypot(cx - s.x_px, cy - s.y_px) * kGsdMmPerPx;
            ++n;
        }
    }
    ASSERT_GE(n, 3);
    EXPECT_GT(sum_mm / n, 3.0) << "mean centre-of-mass offset over " << n << " crops";
}

TEST(SynthSegmentation, ExcessGreenOtsuMatchesTheTrueMask)
{
    for (int index = 0; index < 2; ++index) {
        const Frame f = make(Preset::late, 13, index);
        cv::Mat bgr_f32;
        f.bgr.convertTo(bgr_f32, CV_32F);
        std::vector<cv::Mat> ch;
        cv::split(bgr_f32, ch);
        const cv::Mat exg = 2 * ch[1] - ch[2] - ch[0];
        cv::Mat exg_u8, segmented;
        cv::normalize(exg, exg_u8, 0, 255, cv::NORM_MINMAX, CV_8U);
        cv::threshold(exg_u8, segmented, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
        const double intersection = cv::countNonZero(segmented & f.mask);
        const double uni = cv::countNonZero(segmented | f.mask);
        ASSERT_GT(uni, 0);
        EXPECT_GT(intersection / uni, 0.85) << "frame " << index;
        // ...but not identical: edges are anti-aliased, blurred and noisy.
        EXPECT_LT(intersection / uni, 1.0);
    }
}

TEST(SynthSegmentation, NirIsBrightOnVegetationAndDarkOnSoil)
{
    const Frame f = make(Preset::late, 17, 0);
    cv::Mat inner, soil;
    cv::erode(f.mask, inner, cv::Mat());   // away from the blurred edges
    cv::dilate(f.mask, soil, cv::Mat(), cv::Point(-1, -1), 2);
    soil = soil == 0;
    const double vegetation_nir = cv::mean(f.nir, inner)[0], soil_nir = cv::mean(f.nir, soil)[0];
    EXPECT_GE(vegetation_nir, 170);
    EXPECT_LE(vegetation_nir, 235);
    EXPECT_GE(soil_nir, 50);
    EXPECT_LE(soil_nir, 110);
}

TEST(SynthFragmentation, BreaksTheMaskButKeepsTheLayout)
{
    const Frame whole = make(Preset::dense, 21, 0, 0.0);
    const Frame broken = make(Preset::dense, 21, 0, 1.0);
    ASSERT_EQ(whole.stems.size(), broken.stems.size());
    for (std::size_t i = 0; i < whole.stems.size(); ++i) {
        EXPECT_EQ(whole.stems[i].x_px, broken.stems[i].x_px);
        EXPECT_EQ(whole.stems[i].y_px, broken.stems[i].y_px);
    }
    EXPECT_LT(cv::countNonZero(broken.mask), cv::countNonZero(whole.mask));
    EXPECT_GT(regions_of(broken.mask).count, regions_of(whole.mask).count + 10);
    // Every removed pixel was vegetation in the unbroken frame.
    EXPECT_EQ(cv::countNonZero(broken.mask & ~whole.mask), 0);
}

TEST(SynthSeedling, SparseVegetationOnDarkSoilThroughADullCamera)
{
    // What real frames at weeding time look like: about 1 % vegetation
    // (0.2 to 1.5 % per frame), soil darker than the other presets', and
    // identical bytes for identical inputs.
    double soil_seedling = 0, soil_late = 0;
    for (int i = 0; i < 4; ++i) {
        const Frame f = make(Preset::seedling, 7, i);
        const double vegetation = cv::countNonZero(f.mask) / static_cast<double>(f.mask.total());
        EXPECT_GT(vegetation, 0.002) << i;
        EXPECT_LT(vegetation, 0.015) << i;
        EXPECT_FALSE(f.stems.empty()) << i;
        soil_seedling += cv::mean(f.bgr, f.mask == 0)[1];
        const Frame late = make(Preset::late, 7, i);
        soil_late += cv::mean(late.bgr, late.mask == 0)[1];
    }
    EXPECT_LT(soil_seedling, 0.8 * soil_late);
    EXPECT_TRUE(same_bytes(make(Preset::seedling, 7, 2).bgr, make(Preset::seedling, 7, 2).bgr));
}

TEST(SynthPreset, CanopyCoversMostOfTheViewAndLeavesSomeSoil)
{
    // The canopy preset is there to show what a frame mostly covered by
    // leaves does to the pipeline: most of every frame is vegetation, from
    // many plants, and some soil stays in view.
    for (int i = 0; i < 4; ++i) {
        const Frame f = make(Preset::canopy, 7, i);
        const double cover = cv::countNonZero(f.mask) / static_cast<double>(f.mask.total());
        EXPECT_GE(cover, 0.6) << "frame " << i;
        EXPECT_LT(cover, 0.98) << "frame " << i << ": some soil stays in view";
        EXPECT_GE(f.stems.size(), 30u) << "frame " << i;
    }
}

