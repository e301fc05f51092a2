// The colour, brightness, texture and NDVI sums of vegetation pixels on
// one row: the inner loops of the plant features (a run of pixels) and of
// the cell features (every fourth pixel, each to its cell).
#pragma once

#include <array>
#include <cstdint>

#include <opencv2/core/matx.hpp>

#include "stemd/vision/index.hpp"

namespace stemd::vision {

// A row of the frame, with the rows above and below it for the gradient
// (the row itself where the frame ends).
struct ColourRows {
    const cv::Vec3b* bgr;
    const cv::Vec3b* up;
    const cv::Vec3b* down;
    const std::uint8_t* nir;   // null without a NIR plane
    int width;
};

// Sums over pixels of a row, each added in pixel order: the float sums
// are what a model was trained on, so their rounding must not depend on
// how the loop is written.
struct RunColour {
    long brightness = 0;   // R + G + B
    long gradient = 0;     // |s(x+1) - s(x-1)| + |s(below) - s(above)| of s = R + G + B
    float r = 0, g = 0, b = 0, rr = 0, gg = 0;   // chromatic R/s, G/s, B/s and squares
    float ndvi = 0, ndvi2 = 0;                   // (NIR - R) / (NIR + R) and square; 0 without NIR
};

// A pixel's R+G+B: the brightness that the colour features divide by and
// the texture features differentiate, for the plant and the cell features
// alike.
inline int brightness_sum(const cv::Vec3b& bgr) { return bgr[0] + bgr[1] + bgr[2]; }

// What the scalar paths divide by: kColourReciprocal[i] = 1.0f / i for i
// in [1, 765] (an R+G+B, or a NIR+R), and [0] = 0, since a black pixel has
// no chromaticity. A division per pixel and channel would cost more than
// the rest of a pass. The compiler rounds each entry as IEEE division
// does at run time.
inline constexpr int kColourReciprocals = 3 * 255 + 1;
inline constexpr std::array<float, kColourReciprocals> kColourReciprocal = [] {
    std::array<float, kColourReciprocals> table{};
    for (int i = 1; i < kColourReciprocals; ++i)
        table[static_cast<std::size_t>(i)] = 1.0f / static_cast<float>(i);
    return table;
}();

// Adds pixels [x_start, x_stop) of `rows` to `sums`, 0 <= x_start <= x_stop
// <= rows.width; a pixel's left and right neighbours beyond the row are
// the pixel itself. The kernels give the same bits: the SSSE3 one divides
// where the baseline reads kColourReciprocal (IEEE division rounds both
// alike) and adds its lanes to the float sums one pixel after the other.
void add_vegetation_run(const ColourRows& rows, int x_start, int x_stop, RunColour& sums);
// The same with the given implementation; `kernel` must be available.
void add_vegetation_run(const ColourRows& rows, int x_start, int x_stop, RunColour& sums, Kernel kernel);

// The sums over a cell's sampled pixels. Each float sum takes its samples
// in pixel order, row after row, as add_cell_samples() adds them: a model
// was trained on these roundings.
struct CellSamples {
    int sampled_px = 0;
    float r = 0, g = 0, rr = 0, gg = 0;                // chromatic R/s, G/s and squares, s = R + G + B
    float brightness = 0, gradient = 0;                // s; |gx| + |gy|
    float sxx = 0, syy = 0, sxy = 0;                   // gx*gx, gy*gy, gx*gy: the structure tensor
    float ndvi = 0, ndvi2 = 0;                         // (NIR - R) / (NIR + R) and square; 0 without NIR
    std::uint16_t plant_vote = 0, plant_count = 0;     // Boyer-Moore majority vote of the samples' plants
};

// Adds the samples of a row to their cells: each pixel x with x % 4 == 0
// whose bit is set in `vegetation` (the row's bits, 64 pixels a word, none
// set past rows.width) goes to cells[cell_of[x]], voting for the plant
// plant_of[x]. gx = s(x+1) - s(x-1) and gy = s(below) - s(above), with a
// row's end its own neighbour. The kernels give the same bits: the SSSE3
// one takes four samples a step and adds them to the sums one after the
// other.
void add_cell_samples(const ColourRows& rows, const std::uint64_t* vegetation, const std::uint16_t* cell_of,
                      const std::uint16_t* plant_of, CellSamples* cells);
// The same with the given implementation; `kernel` must be available.
void add_cell_samples(const ColourRows& rows, const std::uint64_t* vegetation, const std::uint16_t* cell_of,
                      const std::uint16_t* plant_of, CellSamples* cells, Kernel kernel);

}  // namespace stemd::vision
