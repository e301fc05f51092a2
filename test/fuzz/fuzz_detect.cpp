// The stem pipeline past the threshold (closing, plants, contours, leaves,
// stems) on arbitrary vegetation masks of bounded size, and the index and
// threshold on arbitrary colour: any frame gives plants or none, within
// the fixed capacities, never a read outside a buffer.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include <opencv2/core/mat.hpp>

#include "stemd/vision/detect.hpp"

namespace {

constexpr int kSidePx = 96;   // big enough for several leaves, small enough to be fast

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    namespace v = stemd::vision;
    if (size < 2)
        return 0;
    // Byte 0: the method and the closing radius; byte 1: the GSD; the rest
    // paints the mask (one bit per pixel) or the colour (a byte per channel).
    static v::Params params;
    params.segmentation = (data[0] & 1) ? v::Segmentation::mask : v::Segmentation::chromatic_exg;
    params.closing_radius_px = (data[0] >> 1) % 12;
    params.gsd_mm_per_px = 0.1 + data[1] / 64.0;
    static v::Workspace workspace(cv::Size(kSidePx, kSidePx), v::Params{});
    static v::Detections detections;
    static cv::Mat mask(kSidePx, kSidePx, CV_8UC1);
    static cv::Mat bgr(kSidePx, kSidePx, CV_8UC3);
    mask.setTo(0);
    bgr.setTo(0);
    const std::uint8_t* paint = data + 2;
    const std::size_t paint_size = size - 2;
    if (params.segmentation == v::Segmentation::mask) {
        for (std::size_t bit = 0; bit < std::min<std::size_t>(paint_size * 8, kSidePx * kSidePx); ++bit)
            if (paint[bit / 8] & (1u << (bit % 8)))
                mask.data[bit] = 255;
    } else {
        std::memcpy(bgr.data, paint, std::min<std::size_t>(paint_size, bgr.total() * 3));
    }
    v::detect(v::FrameView{.bgr = bgr, .nir = {}, .mask = mask}, params, workspace, detections, nullptr);
    return 0;
}
