// A PNG whose header declares a size its pixels do not have (the IHDR
// rewritten, its CRC fixed up): what a hostile or broken file looks like to
// the readers, which must refuse it from the header alone.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/imgcodecs.hpp>

namespace stemd::test {

inline std::uint32_t png_crc32(const unsigned char* p, std::size_t n)
{
    std::uint32_t crc = 0xFFFFFFFFu;
    for (std::size_t i = 0; i < n; ++i) {
        crc ^= p[i];
        for (int k = 0; k < 8; ++k)
            crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

// An 8x8 PNG with an IHDR saying width x height.
inline std::vector<unsigned char> png_declaring(std::uint32_t width, std::uint32_t height)
{
    std::vector<unsigned char> png;
    cv::imencode(".png", cv::Mat(8, 8, CV_8UC3, cv::Scalar::all(90)), png);
    auto put = [&png](std::size_t at, std::uint32_t v) {
        for (int i = 0; i < 4; ++i)
            png[at + static_cast<std::size_t>(i)] = static_cast<unsigned char>(v >> (24 - 8 * i));
    };
    put(16, width);    // after the signature (8), the chunk length (4) and "IHDR" (4)
    put(20, height);
    put(29, png_crc32(png.data() + 12, 17));   // over "IHDR" and its 13 bytes
    return png;
}

}  // namespace stemd::test
