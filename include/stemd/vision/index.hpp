// Vegetation indices, as 8-bit images so that the threshold works on a
// 256-bin histogram.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>

#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/plants.hpp"

namespace stemd::vision {

// The implementations of the chromatic index, NDVI, the leaf-colour test
// and a plant's colour sums (vision/run_colour): the build's baseline
// (x86-64: SSE2, through OpenCV's universal intrinsics) and, on x86-64
// CPUs that have it, SSSE3, whose byte shuffle
// picks a channel out of packed BGR in one instruction. The functions
// without a Kernel argument run the best the CPU has, picked once at
// start; the build itself stays at the baseline, as the robot's CPU is not
// known when it is built. Both give the same bytes.
enum class Kernel { baseline, ssse3 };
inline constexpr std::array<Kernel, 2> kKernels{Kernel::baseline, Kernel::ssse3};
// Whether this CPU runs `kernel`.
bool kernel_available(Kernel kernel);

// Excess Green 2G - R - B in [-510, 510], mapped linearly to [0, 255]:
// index = (2G - R - B + 512) / 4, rounded down. `bgr` is CV_8UC3.
void excess_green(const cv::Mat& bgr, cv::Mat& index_u8);

// The spans below compute pixels [x_begin, x_end) of row y into an
// allocated `index_u8` of the frame's size, and give the whole-frame
// functions' bytes for any span: the vector path (granules of
// index_span_granule_px() pixels from x_begin) and the scalar path do the
// same arithmetic in the same order (integers; for the chromatic index
// float32 with round-to-nearest-even).
int index_span_granule_px();
void excess_green_span(const cv::Mat& bgr, int y, int x_begin, int x_end, cv::Mat& index_u8);

// Chromatic Excess Green e / (s + mean_s), where e = 2G - R - B, s = R + G + B
// and mean_s is the frame's mean of s (every pixel of row 4 of each band of
// kBrightnessRowStep rows from row 0, or of the last row when a band is
// shorter): exposure and gain scale e, s and
// mean_s alike and cancel, shadows keep their leaves, and in dark pixels
// (s << mean_s) the noisy chromaticity is damped. Mapped to
// round(128 + 160 * value), clamped to [0, 255]: neutral soil sits near 128.
inline constexpr int kBrightnessRowStep = 16;
void chromatic_excess_green(const cv::Mat& bgr, cv::Mat& index_u8);
// Its two parts: the frame's mean_s, and the index on a span given it.
float chromatic_mean_brightness(const cv::Mat& bgr);
void chromatic_excess_green_span(const cv::Mat& bgr, int y, int x_begin, int x_end, float mean_brightness,
                                 cv::Mat& index_u8);
// The same with the given implementation (the tests compare them);
// `kernel` must be available.
void chromatic_excess_green_span(const cv::Mat& bgr, int y, int x_begin, int x_end, float mean_brightness,
                                 cv::Mat& index_u8, Kernel kernel);

// 3x3 binomial ([1 2 1] x [1 2 1] / 16, rounded; edges replicated).
// `row_sums` is scratch of at least src.cols entries; `dst` must not be `src`.
void smooth_binomial3(const cv::Mat& src_u8, std::uint16_t* row_sums, cv::Mat& dst_u8);
// The same smoothing for the pixels of `rect` only (clipped to the frame):
// reads src rows rect.y - 1 .. rect.y + rect.height and columns one beyond
// the rect on each side (edges replicated as above), writes dst's rect.
// `dst` must be allocated at src's size.
void smooth_binomial3_rect(const cv::Mat& src_u8, cv::Rect rect, std::uint16_t* row_sums, cv::Mat& dst_u8);

// NDVI (NIR - R) / (NIR + R) in [-1, 1], mapped to (ndvi + 1) * 127.5 =
// 255 NIR / (NIR + R) rounded half up; NIR + R = 0 gives 128 (ndvi 0).
int ndvi_index(int nir, int red);
// `bgr` is CV_8UC3 (its red plane is used), `nir` CV_8UC1 of the same size;
// equal to ndvi_index on every pixel.
void ndvi(const cv::Mat& bgr, const cv::Mat& nir, cv::Mat& index_u8);

// ndvi() with the given implementation (the tests compare them); `kernel`
// must be available.
void ndvi(const cv::Mat& bgr, const cv::Mat& nir, cv::Mat& index_u8, Kernel kernel);

// The soil's colour under this frame's light: the mean B, G and R of the
// pixels outside `vegetation` on row 4 of each band of kBrightnessRowStep
// rows (the rows chromatic_mean_brightness reads), and how many there were.
struct SoilColour {
    double b = 0, g = 0, r = 0;
    long pixels = 0;
};
SoilColour soil_colour(const cv::Mat& bgr, const BitMask& vegetation);

// Leaf colour: chlorophyll absorbs red, so under any light a leaf reflects
// more green for its red than the soil beside it; brown soil, yellowish
// clods and straw do not. A cast of the light (or of the camera's white
// balance) scales each channel alike for leaf and soil, so the ratio of
// the two G/R ratios does not move with it. Clears the bits of `mask` (the
// size of `bgr`) whose pixel's G/R does not exceed the soil's G/R by
// `min_ratio`. Only the set bits' pixels are read. A soil whose mean red or
// green is below one level (or no soil in view) is taken as neutral grey.
void keep_greener_than_red(const cv::Mat& bgr, const SoilColour& soil, double min_ratio, BitMask& mask);
// The same with the given implementation; `kernel` must be available.
void keep_greener_than_red(const cv::Mat& bgr, const SoilColour& soil, double min_ratio, BitMask& mask, Kernel kernel);

// Colour fringes: the Bayer pattern's interpolation and the lens's lateral
// chromatic aberration misregister the green plane against the red by about
// a pixel, so along the edge of a bright clod or straw a thin band can be
// greener for its red than a leaf. That green belongs to the edge beside
// it: slid back by the misregistration, the green plane leaves no pixel of
// the band greener than the soil. A leaf's green is its own: whichever way
// the plane slides by one pixel, some of its pixels stay greener for their
// red than the soil by `min_ratio` (as keep_greener_than_red tests).
// After label_components on a mask of bgr's size: clears keep[c] of each
// kept component with a direction, of the eight one-pixel slides, in which
// none of its pixels passes. `passed` is scratch with room for one entry per
// component. Returns how many components it cleared.
int drop_colour_fringes(const cv::Mat& bgr, const SoilColour& soil, double min_ratio, const LabelScratch& components,
                        std::vector<std::uint8_t>& keep, std::vector<std::uint8_t>& passed);

}  // namespace stemd::vision
