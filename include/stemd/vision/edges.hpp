// Mixed pixels at a plant's edge: a pixel straddling leaf and soil has an
// index between the two, and one global threshold keeps or drops the whole
// band at once, whatever the leaf's own level.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/threshold.hpp"

namespace stemd::vision {

// Scratch for one frame size, allocated once.
class EdgeScratch {
public:
    void reserve(int width_px, int height_px);
    std::size_t reserved_bytes() const
    {
        return (count_.capacity() + sum_.capacity()) * sizeof(std::uint16_t) + row_mask_.capacity() +
               candidates_.reserved_bytes();
    }

private:
    friend void extend_to_mixed_edges(const cv::Mat&, const BitMask&, int, int, int, BitMask&, EdgeScratch&);
    std::vector<std::uint16_t> count_;    // per column: plant pixels in the window's rows (<= 101)
    std::vector<std::uint16_t> sum_;      // per column: their index sum (<= 101 * 255)
    std::vector<std::uint8_t> row_mask_;  // 64 plant pixels of two rows as 0/1 bytes
    BitMask candidates_;                  // index above the floor, outside the plant
};

// `out` = `plant` plus every pixel within a (2 radius_px + 1)^2 window of a
// plant pixel whose index is above the halfway point between `soil_level`
// and the mean index of the plant pixels in that window (at least half of
// it is leaf, if the index mixes linearly) and above `floor` (beyond the
// soil's own noise, so that a faint speck does not grow into the soil
// around it). Nothing is removed, and nothing
// farther than radius_px from the plant is added, so an empty plant mask
// stays empty. `index_u8` is the image the plant was thresholded from;
// `out` must not be `plant` and has its size; radius_px is at most 50.
// Allocates nothing once `scratch` is reserved for the frame size.
void extend_to_mixed_edges(const cv::Mat& index_u8, const BitMask& plant, int soil_level, int floor, int radius_px,
                           BitMask& out, EdgeScratch& scratch);

}  // namespace stemd::vision
