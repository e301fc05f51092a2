// A binary image packed 64 pixels to a word: the closing and labelling
// stages work on whole words, which is what makes them cheap.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "stemd/vision/types.hpp"

namespace stemd::vision {

// visit(x) for each set bit of `bits`, lowest first, bit 0 being pixel x0.
// Inline templates: the walk compiles to the same loop written by hand.
template <class Visit>
inline void visit_bits(std::uint64_t bits, int x0, Visit&& visit)
{
    for (; bits != 0; bits &= bits - 1)
        visit(x0 + std::countr_zero(bits));
}

// In a row of `words` 64-bit words: the position of the first set
// (want_set) or clear bit at or after x, or `width` when there is none
// before it. Runs of set bits are [next_bit(.., x, true), next_bit(.., that,
// false)).
inline int next_bit(const std::uint64_t* row, int words, int width, int x, bool want_set)
{
    int i = x >> 6;
    if (i >= words)
        return width;
    std::uint64_t w = want_set ? row[i] : ~row[i];
    w &= ~std::uint64_t{0} << (x & 63);
    while (w == 0) {
        if (++i >= words)
            return width;
        w = want_set ? row[i] : ~row[i];
    }
    return std::min(width, (i << 6) + std::countr_zero(w));
}

// The bits of word w of a row that hold pixels x0..x1 (inclusive).
inline std::uint64_t range_bits_of_word(int w, int x0, int x1)
{
    std::uint64_t bits = ~std::uint64_t{0};
    if (w == (x0 >> 6))
        bits &= ~std::uint64_t{0} << (x0 & 63);
    if (w == (x1 >> 6) && (x1 & 63) != 63)
        bits &= (std::uint64_t{1} << ((x1 & 63) + 1)) - 1;
    return bits;
}

// The row visitor: visit(x) for each set pixel of words [w0, w1) of a row,
// word w taken as word_of(w) (a mask row's word, or that word filtered or
// combined with others). word_of(w) is read once, before its bits are
// visited, so a visit may change the row it came from.
template <class WordOf, class Visit>
inline void visit_row_bits(int w0, int w1, WordOf&& word_of, Visit&& visit)
{
    for (int w = w0; w < w1; ++w)
        visit_bits(word_of(w), w * 64, visit);
}

class BitMask {
public:
    BitMask() = default;
    BitMask(int width_px, int height_px) { reset(width_px, height_px); }

    // Allocates (or keeps) storage for the size and clears every bit.
    void reset(int width_px, int height_px);
    void clear();

    int width() const { return width_px_; }
    int height() const { return height_px_; }
    int words_per_row() const { return words_per_row_; }
    std::uint64_t* row(int y) { return words_.data() + static_cast<std::size_t>(y) * words_per_row_; }
    const std::uint64_t* row(int y) const { return words_.data() + static_cast<std::size_t>(y) * words_per_row_; }

    bool get(int x, int y) const { return (row(y)[x >> 6] >> (x & 63)) & 1u; }
    // Outside the image reads as background.
    bool get_or_zero(int x, int y) const
    {
        return x >= 0 && y >= 0 && x < width_px_ && y < height_px_ && get(x, y);
    }
    void set(int x, int y) { row(y)[x >> 6] |= std::uint64_t{1} << (x & 63); }
    // visit(x) for each set pixel of row y, left to right.
    template <class Visit>
    void visit_row(int y, Visit&& visit) const
    {
        const std::uint64_t* words = row(y);
        visit_row_bits(0, words_per_row_, [words](int w) { return words[w]; }, visit);
    }
    long count() const;
    std::size_t reserved_bytes() const { return words_.capacity() * sizeof(std::uint64_t); }

    // Mask of the valid bits of the last word of a row (bits past the width stay zero).
    std::uint64_t last_word_mask() const { return last_word_mask_; }

private:
    int width_px_ = 0;
    int height_px_ = 0;
    int words_per_row_ = 0;
    std::uint64_t last_word_mask_ = 0;
    std::vector<std::uint64_t> words_;
};

// The set bits of `n` words. With the CPU's popcnt instruction where it has
// one: the robot's CPU is not known at build time, so the build targets the
// plain x86-64 baseline (a software popcount per word) and the instruction is
// picked once at program start when the CPU reports it.
long count_bits(const std::uint64_t* words, std::size_t n);
// The set bits of a row's pixels [x0, x1) (0 when x1 <= x0), counted alike.
long count_bits_in_range(const std::uint64_t* row, int x0, int x1);
// Rows of one width for add_gated_span_bit_counts().
struct GatedSpanRows {
    const std::uint64_t* gate;
    const std::uint64_t* counted;
    std::array<const std::uint64_t*, 2> pair;
};
// A grid's per-cell counts for one row in one pass, counted alike: for
// every span of pixels [c * span_px, min((c + 1) * span_px, width_px))
// (ceil(width_px / span_px) of them) in which `gate` has a set bit, adds
// the set bits of `counted` there to counts[c] and those of both `pair`
// rows to pair_counts[c]; other spans are left as they are (a cell's
// vegetation, and its boundaries where either of two rows has some).
// Nothing when span_px < 1.
void add_gated_span_bit_counts(const GatedSpanRows& rows, int width_px, int span_px, int* counts, int* pair_counts);

// An 8-bit mask to bits: a pixel is set when it is nonzero (or zero, for
// masks that mark vegetation with 0). `out` is resized if needed.
void pack_mask(const cv::Mat& mask_u8, MaskVegetation vegetation, BitMask& out);
// Bits to an 8-bit mask, 255 = set. `out` is (re)created with the mask's size.
void unpack_mask(const BitMask& bits, cv::Mat& out_u8);

}  // namespace stemd::vision
