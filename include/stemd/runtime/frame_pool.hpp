// The frame slots: every pixel buffer the daemon will ever use, allocated
// once for the configured frame size. Slots travel between the threads as
// pointers (SpscRing<drivers::Frame*>); nothing is copied or reallocated.
#pragma once

#include <cstddef>
#include <memory>

#include <opencv2/core/types.hpp>

#include "stemd/drivers/frame_source.hpp"
#include "stemd/vision/types.hpp"

namespace stemd::runtime {

// What a frame slot holds: frames of the `size`, with the planes
// `segmentation` reads (bgr for exg and ndvi, nir for ndvi, mask for mask)
// and plant_class with `class_maps`. Slots of one shape are interchangeable.
struct FrameShape {
    cv::Size size;
    vision::Segmentation segmentation = vision::Segmentation::automatic;
    bool class_maps = false;
    bool operator==(const FrameShape&) const = default;
};

class FramePool {
public:
    // `count` slots of `shape`. Throws std::bad_alloc.
    FramePool(const FrameShape& shape, std::size_t count);
    FramePool(cv::Size size, vision::Segmentation segmentation, std::size_t count, bool class_maps = false)
        : FramePool(FrameShape{size, segmentation, class_maps}, count)
    {
    }
    FramePool(const FramePool&) = delete;
    FramePool& operator=(const FramePool&) = delete;

    std::size_t size() const { return count_; }
    const FrameShape& shape() const { return shape_; }
    drivers::Frame& operator[](std::size_t i) { return slots_[i]; }
    // Pixel memory held by the pool.
    std::size_t bytes() const;

private:
    FrameShape shape_;
    std::size_t count_;
    std::unique_ptr<drivers::Frame[]> slots_;
};

}  // namespace stemd::runtime
