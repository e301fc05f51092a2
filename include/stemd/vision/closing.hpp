// Morphological closing (and opening) of a bit mask with OpenCV's elliptic kernel of
// size (2r+1)x(2r+1). Bit for bit equal to cv::morphologyEx(MORPH_CLOSE)
// with the default border (outside is background for the dilation and
// vegetation for the erosion), at a fraction of its cost.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "stemd/vision/bitmask.hpp"

namespace stemd::vision {

// Scratch memory of the closing or opening; reserve() once, then they
// allocate nothing for that width and any radius up to the reserved one.
// Changing the radius recomputes the kernel: keep one scratch per radius.
class ClosingScratch {
public:
    void reserve(int width_px, int height_px, int max_radius_px);
    std::size_t reserved_bytes() const;

private:
    friend struct MorphologyAccess;
    BitMask dilated_;
    std::vector<std::uint64_t> ring_;      // horizontally dilated rows, one per kernel width
    std::vector<std::uint64_t> row_tmp_;
    std::unique_ptr<bool[]> row_clear_;    // per ring row: entirely clear
    std::vector<int> width_slot_;          // kernel row -> slot of its half width
    std::vector<int> slot_half_width_;     // distinct half widths, ascending
    int kernel_radius_ = -1;
};

// Kernel row half-widths of getStructuringElement(MORPH_ELLIPSE, 2r+1):
// entry dy + r is the half width of row dy (every row is one centred run).
std::vector<int> ellipse_half_widths(int radius_px);

// out = close(in) with the (2r+1)-pixel ellipse. r = 0 copies. `in` and
// `out` must be different objects.
void close_mask(const BitMask& in, int radius_px, BitMask& out, ClosingScratch& scratch);

// out = open(in) with the same kernel, equal to cv::morphologyEx(MORPH_OPEN)
// (outside is vegetation for the erosion, background for the dilation).
void open_mask(const BitMask& in, int radius_px, BitMask& out, ClosingScratch& scratch);

// out = dilate(in) with the same kernel (outside is background).
void dilate_mask(const BitMask& in, int radius_px, BitMask& out, ClosingScratch& scratch);

// out = erode(in) with the same kernel (outside is vegetation), the first
// half of open_mask. A connected set holds a pixel of open(in) exactly when
// it holds one of erode(in): each opened pixel lies in a kernel placed
// wholly inside `in` (the kernel is connected, so within one component) at
// an eroded pixel. Where only which components survive the opening
// matters, the erosion answers it at half the cost.
void erode_mask(const BitMask& in, int radius_px, BitMask& out, ClosingScratch& scratch);

}  // namespace stemd::vision
