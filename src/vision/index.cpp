#include "stemd/vision/index.hpp"

#include <cmath>

#include <opencv2/core.hpp>
#include <opencv2/core/hal/intrin.hpp>

namespace stemd::vision {

void excess_green(const cv::Mat& bgr, cv::Mat& index_u8)
{
    CV_Assert(bgr.type() == CV_8UC3);
    index_u8.create(bgr.size(), CV_8UC1);
    const int width = bgr.cols;
    for (int y = 0; y < bgr.rows; ++y) {
        const std::uint8_t* src = bgr.ptr<std::uint8_t>(y);
        std::uint8_t* dst = index_u8.ptr<std::uint8_t>(y);
        int x = 0;
#if CV_SIMD
        // OpenCV's portable intrinsics (SSE/AVX/NEON): deinterleave, widen
        // to 16 bits, where (2G + 512) - (R + B) is in [2, 1022], shift, narrow.
        const int lanes = cv::v_uint8::nlanes;
        const cv::v_uint16 offset = cv::vx_setall_u16(512);
        for (; x + lanes <= width; x += lanes) {
            cv::v_uint8 b, g, r;
            cv::v_load_deinterleave(src + 3 * x, b, g, r);
            cv::v_uint16 b0, b1, g0, g1, r0, r1;
            cv::v_expand(b, b0, b1);
            cv::v_expand(g, g0, g1);
            cv::v_expand(r, r0, r1);
            const cv::v_uint16 lo = cv::v_shr<2>((g0 + g0 + offset) - (r0 + b0));
            const cv::v_uint16 hi = cv::v_shr<2>((g1 + g1 + offset) - (r1 + b1));
            cv::v_store(dst + x, cv::v_pack(lo, hi));
        }
#endif
        for (; x < width; ++x) {
            const int b = src[3 * x], g = src[3 * x + 1], r = src[3 * x + 2];
            dst[x] = static_cast<std::uint8_t>((2 * g - r - b + 512) >> 2);
        }
    }
}

NdviTable::NdviTable()
{
    for (int nir = 0; nir < 256; ++nir) {
        for (int red = 0; red < 256; ++red) {
            const int sum = nir + red;
            const double ndvi = sum == 0 ? 0.0 : static_cast<double>(nir - red) / sum;
            table_[(nir << 8) | red] = static_cast<std::uint8_t>(std::lround((ndvi + 1.0) * 127.5));
        }
    }
}

void ndvi(const cv::Mat& bgr, const cv::Mat& nir, const NdviTable& table, cv::Mat& index_u8)
{
    CV_Assert(bgr.type() == CV_8UC3 && nir.type() == CV_8UC1 && bgr.size() == nir.size());
    index_u8.create(bgr.size(), CV_8UC1);
    const int width = bgr.cols;
    for (int y = 0; y < bgr.rows; ++y) {
        const std::uint8_t* src = bgr.ptr<std::uint8_t>(y);
        const std::uint8_t* near_infrared = nir.ptr<std::uint8_t>(y);
        std::uint8_t* dst = index_u8.ptr<std::uint8_t>(y);
        for (int x = 0; x < width; ++x)
            dst[x] = table(near_infrared[x], src[3 * x + 2]);
    }
}

}  // namespace stemd::vision
