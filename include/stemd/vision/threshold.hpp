// Automatic thresholds on an 8-bit index and binarisation into bits.
#pragma once

#include <array>
#include <cstdint>
#include <optional>

#include <opencv2/core/mat.hpp>

#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/types.hpp"

namespace stemd::vision {

using Histogram = std::array<std::uint32_t, 256>;

void compute_histogram(const cv::Mat& index_u8, Histogram& out);

// A histogram counted in four partial tables, each value into the table
// of its position modulo four: a run of equal values (smoothed soil) then
// increments four counters in turn instead of waiting on one.
struct PartialHistograms {
    std::array<std::array<std::uint32_t, 256>, 4> counts{};

    // Counts `n` values from `values`, each `weight` times.
    void add(const std::uint8_t* values, int n, std::uint32_t weight = 1);
    // The four tables summed into `out`.
    void sum(Histogram& out) const;
};

// Both return t such that "index > t" is vegetation, as cv::threshold does.
// Otsu: maximises the between-class variance. Triangle (Zack et al. 1977):
// the level farthest from the line joining the histogram peak to the far
// end of its longer tail. Both equal OpenCV's THRESH_OTSU/THRESH_TRIANGLE.
int otsu_threshold(const Histogram& histogram);
int triangle_threshold(const Histogram& histogram);
// Kittler & Illingworth (1986) minimum error thresholding: fits two
// Gaussians of their own weight and spread and picks the level that
// minimises the classification error. Unlike Otsu it does not pull the
// threshold into the smaller class when vegetation covers little of the
// frame (on CWFID: mean IoU 0.912 against 0.867 for Otsu).
int min_error_threshold(const Histogram& histogram);
// The upper edge of the soil's own spread: soil_mode plus `sigmas`
// standard deviations, measured on the mode's lower side only, which
// vegetation (above) does not reach. Valid for any small vegetation cover,
// where Otsu and min_error split the soil itself. Mode and sigma are read
// between levels (a parabola at the mode, a quantile of the lower side),
// as a soil's spread is often only a level or two.
int soil_noise_threshold(const Histogram& histogram, double sigmas);

// The mode of the histogram smoothed over three levels, so that a
// quantisation comb does not pick a spike. 0 when empty.
int histogram_mode(const Histogram& histogram);

// Every index here maps its zero (a grey surface; NIR equal to red) to
// this level, and vegetation above it.
inline constexpr int kIndexZeroLevel = 128;
// The soil's index level. Usually the mode: soil covers more of a field
// frame than any one leaf level does. When vegetation covers most of it
// (from about half of a real frame's window, three quarters of a
// synthetic frame), the mode is a leaf level and the soil is a lower
// mode. So the soil is a lower peak instead when
// - it rises above the valley between it and the mode by a fifth of its
//   count and by three times its counting noise, so it is a mode of its
//   own, not the mode's shoulder or a dip in its noisy tail;
// - the levels up to that valley hold at least 1 % of the pixels;
// - the mode lies at least 12 levels above it (a leaf's separation from
//   soil);
// - and it lies nearer kIndexZeroLevel than the mode: soil is grey to
//   brown, a leaf strongly green (or bright in NIR). A red or dark patch
//   below the soil is farther from zero than the soil and stays out.
// 0 when empty.
int soil_mode(const Histogram& histogram);
// That lower peak, and the lowest level between it and the mode (the
// first from the mode when several are equal): nullopt when the soil is
// the mode.
struct SoilUnderLeaves {
    int soil_level;
    int valley_level;
};
std::optional<SoilUnderLeaves> soil_under_leaves(const Histogram& histogram);
// Otsu where it separates two classes, never inside the soil's spread.
// Under mostly leaves (soil_under_leaves), the valley between the soil
// and the leaves instead: Otsu splits the leaves then, and the soil
// between dense leaves is shaded and mixed, too wide for a bar of sigmas.
int above_soil_threshold(const Histogram& histogram, double sigmas);
// `soil_sigmas` is used by above_soil only.
int auto_threshold(const Histogram& histogram, ThresholdMethod method, double soil_sigmas = 5.0);

// Difference of the mean index of the two classes the threshold makes,
// mean(index > t) - mean(index <= t), from the histogram alone; 0 when
// either class is empty. Every automatic threshold splits a histogram even
// when it has one mode (bare soil); a small separation says there was no
// second class to find.
double class_separation(const Histogram& histogram, int threshold);

// index > threshold -> set bit. `out` is resized if needed.
void threshold_to_bits(const cv::Mat& index_u8, int threshold, BitMask& out);

}  // namespace stemd::vision
