#include "stemd/vision/bitmask.hpp"

#include <algorithm>
#include <bit>

#include <opencv2/core.hpp>

#include "stemd/vision/threshold.hpp"

namespace stemd::vision {

namespace {

// The counting loops, written once and inlined into a plain and a popcnt
// build of each entry point: __builtin_popcountll becomes the instruction
// or the software count by the target of the function it lands in.
[[gnu::always_inline]] inline long count_words(const std::uint64_t* words, std::size_t n)
{
    long total = 0;
    for (std::size_t i = 0; i < n; ++i)
        total += __builtin_popcountll(words[i]);
    return total;
}

[[gnu::always_inline]] inline long count_range(const std::uint64_t* row, int x0, int x1)
{
    if (x1 <= x0)
        return 0;
    const int w0 = x0 >> 6, w1 = (x1 - 1) >> 6;
    const std::uint64_t first = ~std::uint64_t{0} << (x0 & 63);
    const std::uint64_t last = (x1 & 63) != 0 ? ~std::uint64_t{0} >> (64 - (x1 & 63)) : ~std::uint64_t{0};
    if (w0 == w1)
        return __builtin_popcountll(row[w0] & first & last);
    long n = __builtin_popcountll(row[w0] & first) + __builtin_popcountll(row[w1] & last);
    for (int w = w0 + 1; w < w1; ++w)
        n += __builtin_popcountll(row[w]);
    return n;
}

// Only the spans that meet a nonzero word are counted: on a sparse row that
// is a few of them, not all.
[[gnu::always_inline]] inline void add_spans(const std::uint64_t* row, int width_px, int span_px, int* counts)
{
    const int words = (width_px + 63) / 64;
    int next_span = 0;   // spans before it are counted
    for (int w = 0; w < words; ++w) {
        if (row[w] == 0)
            continue;
        const int last_span = std::min(w * 64 + 63, width_px - 1) / span_px;
        for (int c = std::max(w * 64 / span_px, next_span); c <= last_span; ++c) {
            const int x0 = c * span_px;
            counts[c] += static_cast<int>(count_range(row, x0, std::min(x0 + span_px, width_px)));
        }
        next_span = last_span + 1;
    }
}

long count_bits_portable(const std::uint64_t* words, std::size_t n) { return count_words(words, n); }
long count_range_portable(const std::uint64_t* row, int x0, int x1) { return count_range(row, x0, x1); }
void add_spans_portable(const std::uint64_t* row, int width_px, int span_px, int* counts)
{
    add_spans(row, width_px, span_px, counts);
}

struct Counters {
    long (*words)(const std::uint64_t*, std::size_t);
    long (*range)(const std::uint64_t*, int, int);
    void (*spans)(const std::uint64_t*, int, int, int*);
};

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
__attribute__((target("popcnt"))) long count_bits_popcnt(const std::uint64_t* words, std::size_t n)
{
    return count_words(words, n);
}
__attribute__((target("popcnt"))) long count_range_popcnt(const std::uint64_t* row, int x0, int x1)
{
    return count_range(row, x0, x1);
}
__attribute__((target("popcnt"))) void add_spans_popcnt(const std::uint64_t* row, int width_px, int span_px,
                                                         int* counts)
{
    add_spans(row, width_px, span_px, counts);
}
#endif

Counters pick_counters()
{
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
    __builtin_cpu_init();
    if (__builtin_cpu_supports("popcnt"))
        return {count_bits_popcnt, count_range_popcnt, add_spans_popcnt};
#endif
    return {count_bits_portable, count_range_portable, add_spans_portable};
}

// Constant-initialised to the portable loops, so a caller that runs before
// this file's dynamic initialisation still counts correctly; replaced once
// at start, never on the frame path.
Counters counters = {count_bits_portable, count_range_portable, add_spans_portable};
[[maybe_unused]] const bool counters_picked = (counters = pick_counters(), true);

}  // namespace

long count_bits(const std::uint64_t* words, std::size_t n)
{
    return counters.words(words, n);
}

long count_bits_in_range(const std::uint64_t* row, int x0, int x1)
{
    return counters.range(row, x0, x1);
}

void add_span_bit_counts(const std::uint64_t* row, int width_px, int span_px, int* counts)
{
    if (span_px > 0)
        counters.spans(row, width_px, span_px, counts);
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
