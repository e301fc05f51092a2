#include "stemd/vision/bitmask.hpp"

#include <algorithm>
#include <bit>

#include <opencv2/core.hpp>

#include "stemd/vision/threshold.hpp"

namespace stemd::vision {

namespace {

using CountBits = long (*)(const std::uint64_t*, std::size_t);

long count_bits_portable(const std::uint64_t* words, std::size_t n)
{
    long total = 0;
    for (std::size_t i = 0; i < n; ++i)
        total += std::popcount(words[i]);
    return total;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
__attribute__((target("popcnt"))) long count_bits_popcnt(const std::uint64_t* words, std::size_t n)
{
    long total = 0;
    for (std::size_t i = 0; i < n; ++i)
        total += __builtin_popcountll(words[i]);
    return total;
}
#endif

CountBits pick_count_bits()
{
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
    __builtin_cpu_init();
    if (__builtin_cpu_supports("popcnt"))
        return count_bits_popcnt;
#endif
    return count_bits_portable;
}

// Constant-initialised to the portable loop, so a caller that runs before
// this file's dynamic initialisation still counts correctly; replaced once
// at start, never on the frame path.
CountBits count_bits_impl = count_bits_portable;
[[maybe_unused]] const bool count_bits_picked = (count_bits_impl = pick_count_bits(), true);

}  // namespace

long count_bits(const std::uint64_t* words, std::size_t n)
{
    return count_bits_impl(words, n);
}

void BitMask::reset(int width_px, int height_px)
{
    width_px_ = std::max(width_px, 0);
    height_px_ = std::max(height_px, 0);
    words_per_row_ = (width_px_ + 63) / 64;
    const int tail_bits = width_px_ & 63;
    last_word_mask_ = tail_bits == 0 ? ~std::uint64_t{0} : (std::uint64_t{1} << tail_bits) - 1;
    words_.assign(static_cast<std::size_t>(words_per_row_) * height_px_, 0);
}

void BitMask::clear()
{
    std::fill(words_.begin(), words_.end(), 0);
}

long BitMask::count() const
{
    return count_bits(words_.data(), words_.size());
}

void pack_mask(const cv::Mat& mask_u8, MaskVegetation vegetation, BitMask& out)
{
    CV_Assert(mask_u8.type() == CV_8UC1);
    if (vegetation == MaskVegetation::nonzero) {
        threshold_to_bits(mask_u8, 0, out);
        return;
    }
    // Vegetation is 0: set where the pixel is not above 0, i.e. invert the nonzero bits.
    threshold_to_bits(mask_u8, 0, out);
    for (int y = 0; y < out.height(); ++y) {
        std::uint64_t* row = out.row(y);
        for (int i = 0; i < out.words_per_row(); ++i)
            row[i] = ~row[i];
        row[out.words_per_row() - 1] &= out.last_word_mask();
    }
}

void and_masks(const BitMask& mask, BitMask& inout)
{
    const std::size_t words = static_cast<std::size_t>(inout.words_per_row()) * static_cast<std::size_t>(inout.height());
    const std::uint64_t* a = mask.row(0);
    std::uint64_t* b = inout.row(0);
    for (std::size_t i = 0; i < words && inout.height() > 0; ++i)
        b[i] &= a[i];
}

void unpack_mask(const BitMask& bits, cv::Mat& out_u8)
{
    out_u8.create(bits.height(), bits.width(), CV_8UC1);
    for (int y = 0; y < bits.height(); ++y) {
        const std::uint64_t* row = bits.row(y);
        std::uint8_t* dst = out_u8.ptr<std::uint8_t>(y);
        for (int x = 0; x < bits.width(); ++x)
            dst[x] = ((row[x >> 6] >> (x & 63)) & 1u) ? 255 : 0;
    }
}

}  // namespace stemd::vision
