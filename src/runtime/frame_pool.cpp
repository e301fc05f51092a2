#include "stemd/runtime/frame_pool.hpp"

#include <opencv2/core/mat.hpp>

namespace stemd::runtime {

FramePool::FramePool(const FrameShape& shape, std::size_t count)
    : shape_(shape), count_(count), slots_(std::make_unique<drivers::Frame[]>(count))
{
    using vision::Segmentation;
    const cv::Size size = shape.size;
    const Segmentation segmentation = shape.segmentation;
    const bool class_maps = shape.class_maps;
    for (std::size_t i = 0; i < count; ++i) {
        drivers::Frame& f = slots_[i];
        // Zeroed, not just allocated, so that every page is touched now
        // (and locked, with mlockall) rather than on the first frame.
        if (segmentation != Segmentation::mask)
            f.bgr = cv::Mat::zeros(size, CV_8UC3);
        if (uses_nir(segmentation))
            f.nir = cv::Mat::zeros(size, CV_8UC1);
        if (segmentation == Segmentation::mask)
            f.mask = cv::Mat::zeros(size, CV_8UC1);
        if (class_maps)
            f.plant_class = cv::Mat::zeros(size, CV_8UC1);
    }
}

std::size_t FramePool::bytes() const
{
    std::size_t total = 0;
    for (std::size_t i = 0; i < count_; ++i)
        for (const cv::Mat* m : {&slots_[i].bgr, &slots_[i].nir, &slots_[i].mask, &slots_[i].plant_class})
            total += m->total() * m->elemSize();
    return total;
}

}  // namespace stemd::runtime
