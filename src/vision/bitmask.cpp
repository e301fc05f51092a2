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

// The words and edge masks of a row's pixels [x0, x1), x0 < x1: worked out
// once where several rows are counted over the same pixels.
struct RangeMasks {
    int w0, w1;
    std::uint64_t first, last;
    RangeMasks(int x0, int x1)
        : w0(x0 >> 6), w1((x1 - 1) >> 6), first(~std::uint64_t{0} << (x0 & 63)),
          last((x1 & 63) != 0 ? ~std::uint64_t{0} >> (64 - (x1 & 63)) : ~std::uint64_t{0})
    {
    }
};

[[gnu::always_inline]] inline long count_masked(const std::uint64_t* row, const RangeMasks& m)
{
    if (m.w0 == m.w1)
        return __builtin_popcountll(row[m.w0] & m.first & m.last);
    long n = __builtin_popcountll(row[m.w0] & m.first) + __builtin_popcountll(row[m.w1] & m.last);
    for (int w = m.w0 + 1; w < m.w1; ++w)
        n += __builtin_popcountll(row[w]);
    return n;
}

[[gnu::always_inline]] inline long count_range(const std::uint64_t* row, int x0, int x1)
{
    return x1 <= x0 ? 0 : count_masked(row, RangeMasks(x0, x1));
}

[[gnu::always_inline]] inline bool any_masked(const std::uint64_t* row, const RangeMasks& m)
{
    if (m.w0 == m.w1)
        return (row[m.w0] & m.first & m.last) != 0;
    if ((row[m.w0] & m.first) != 0 || (row[m.w1] & m.last) != 0)
        return true;
    for (int w = m.w0 + 1; w < m.w1; ++w)
        if (row[w] != 0)
            return true;
    return false;
}

[[gnu::always_inline]] inline void add_gated_spans(const GatedSpanRows& rows, int width_px, int span_px,
                                                   int* counts, int* pair_counts)
{
    const int words = (width_px + 63) / 64;
    int next_span = 0;
    for (int w = 0; w < words; ++w) {
        if (rows.gate[w] == 0)
            continue;
        const int last_span = std::min(w * 64 + 63, width_px - 1) / span_px;
        for (int c = std::max(w * 64 / span_px, next_span); c <= last_span; ++c) {
            const int x0 = c * span_px;
            const RangeMasks m(x0, std::min(x0 + span_px, width_px));
            if (!any_masked(rows.gate, m))
                continue;
            counts[c] += static_cast<int>(count_masked(rows.counted, m));
            pair_counts[c] += static_cast<int>(count_masked(rows.pair[0], m) + count_masked(rows.pair[1], m));
        }
        next_span = last_span + 1;
    }
}

long count_bits_portable(const std::uint64_t* words, std::size_t n) { return count_words(words, n); }
long count_range_portable(const std::uint64_t* row, int x0, int x1) { return count_range(row, x0, x1); }
void add_gated_spans_portable(const GatedSpanRows& rows, int width_px, int span_px, int* counts, int* pair_counts)
{
    add_gated_spans(rows, width_px, span_px, counts, pair_counts);
}

struct Counters {
    long (*words)(const std::uint64_t*, std::size_t);
    long (*range)(const std::uint64_t*, int, int);
    void (*gated_spans)(const GatedSpanRows&, int, int, int*, int*);
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
__attribute__((target("popcnt"))) void add_gated_spans_popcnt(const GatedSpanRows& rows, int width_px, int span_px,
                                                               int* counts, int* pair_counts)
{
    add_gated_spans(rows, width_px, span_px, counts, pair_counts);
}
#endif

Counters pick_counters()
{
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
    __builtin_cpu_init();
    if (__builtin_cpu_supports("popcnt"))
        return {count_bits_popcnt, count_range_popcnt, add_gated_spans_popcnt};
#endif
    return {count_bits_portable, count_range_portable, add_gated_spans_portable};
}

// Constant-initialised to the portable loops, so a caller that runs before
// this file's dynamic initialisation still counts correctly; replaced once
// at start, never on the frame path.
Counters counters = {count_bits_portable, count_range_portable, add_gated_spans_portable};
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

void add_gated_span_bit_counts(const GatedSpanRows& rows, int width_px, int span_px, int* counts, int* pair_counts)
{
    if (span_px > 0)
        counters.gated_spans(rows, width_px, span_px, counts, pair_counts);
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
