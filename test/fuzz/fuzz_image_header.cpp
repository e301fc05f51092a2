// Image headers (PNG, JPEG, BMP, PNM) read before anything is decoded, and
// whether the file runs to its end: any bytes give a size or a reason,
// never a read past the buffer.
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "stemd/io/recording.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::span<const unsigned char> bytes(data, size);
    std::string why;
    (void)stemd::io::declared_image_size(bytes, why);
    (void)stemd::io::check_image_header(bytes, cv::Size(1296, 966), why);
    // Any size: the check goes on to the file's end (the seeds are small).
    (void)stemd::io::check_image_header(bytes, cv::Size(), why);
    return 0;
}
