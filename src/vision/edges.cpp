#include "stemd/vision/edges.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>

#include <opencv2/core.hpp>

namespace stemd::vision {

void EdgeScratch::reserve(int width_px, int height_px)
{
    const auto width = static_cast<std::size_t>(std::max(width_px, 0));
    count_.assign(width, 0);
    sum_.assign(width, 0);
    row_mask_.assign(128, 0);  // one word of two rows, unpacked
    candidates_.reset(std::max(width_px, 0), std::max(height_px, 0));
}

namespace {

constexpr int kMaxRadiusPx = 50;  // keeps a column's sum of 101 rows of 255 in 16 bits

// Byte b to eight bytes, each 0 or 1: bit i of b in byte i.
constexpr std::array<std::uint64_t, 256> make_unpack_table()
{
    std::array<std::uint64_t, 256> table{};
    for (int b = 0; b < 256; ++b)
        for (int i = 0; i < 8; ++i)
            table[static_cast<std::size_t>(b)] |= static_cast<std::uint64_t>((b >> i) & 1) << (8 * i);
    return table;
}
constexpr std::array<std::uint64_t, 256> kUnpack = make_unpack_table();

// Bit i of `bits` to byte i of `bytes`, 0 or 1.
void unpack_word(std::uint64_t bits, std::uint8_t* bytes)
{
    for (int k = 0; k < 8; ++k) {
        const std::uint64_t eight = kUnpack[(bits >> (8 * k)) & 0xFFu];
        std::memcpy(bytes + 8 * k, &eight, sizeof eight);
    }
}

// Slides the column sums down a row: adds row `enter`'s plant pixels (and
// their index) and takes away row `leave`'s, either -1 for none, in one
// pass over the 64 columns of each word where either row has plant pixels:
// branch-free inside a word, so the compiler vectorises it. The 16-bit sums
// end where adding and taking away one after the other would.
void slide_columns(const cv::Mat& index_u8, const BitMask& plant, int enter, int leave, std::uint16_t* count,
                   std::uint16_t* sum, std::uint8_t* word_masks)
{
    const std::uint64_t* entering = enter >= 0 ? plant.row(enter) : nullptr;
    const std::uint64_t* leaving = leave >= 0 ? plant.row(leave) : nullptr;
    const std::uint8_t* enter_index = enter >= 0 ? index_u8.ptr<std::uint8_t>(enter) : nullptr;
    const std::uint8_t* leave_index = leave >= 0 ? index_u8.ptr<std::uint8_t>(leave) : nullptr;
    std::uint8_t* in_mask = word_masks;
    std::uint8_t* out_mask = word_masks + 64;
    const int width = plant.width();
    for (int w = 0; w < plant.words_per_row(); ++w) {
        const std::uint64_t in = entering != nullptr ? entering[w] : 0;
        const std::uint64_t out = leaving != nullptr ? leaving[w] : 0;
        if ((in | out) == 0)
            continue;
        const int x0 = w * 64, n = std::min(64, width - x0);
        std::uint16_t* c = count + x0;
        std::uint16_t* s = sum + x0;
        if (out == 0) {
            unpack_word(in, in_mask);
            const std::uint8_t* v = enter_index + x0;
            for (int i = 0; i < n; ++i) {
                c[i] = static_cast<std::uint16_t>(c[i] + in_mask[i]);
                s[i] = static_cast<std::uint16_t>(s[i] + in_mask[i] * v[i]);
            }
        } else if (in == 0) {
            unpack_word(out, out_mask);
            const std::uint8_t* v = leave_index + x0;
            for (int i = 0; i < n; ++i) {
                c[i] = static_cast<std::uint16_t>(c[i] - out_mask[i]);
                s[i] = static_cast<std::uint16_t>(s[i] - out_mask[i] * v[i]);
            }
        } else {
            unpack_word(in, in_mask);
            unpack_word(out, out_mask);
            const std::uint8_t* v_in = enter_index + x0;
            const std::uint8_t* v_out = leave_index + x0;
            for (int i = 0; i < n; ++i) {
                c[i] = static_cast<std::uint16_t>(c[i] + in_mask[i] - out_mask[i]);
                s[i] = static_cast<std::uint16_t>(s[i] + in_mask[i] * v_in[i] - out_mask[i] * v_out[i]);
            }
        }
    }
}

long row_count(const BitMask& plant, int y)
{
    return count_bits(plant.row(y), static_cast<std::size_t>(plant.words_per_row()));
}

}  // namespace

void extend_to_mixed_edges(const cv::Mat& index_u8, const BitMask& plant, int soil_level, int floor, int radius_px,
                           BitMask& out, EdgeScratch& scratch)
{
    CV_Assert(index_u8.type() == CV_8UC1 && index_u8.cols == plant.width() && index_u8.rows == plant.height());
    CV_Assert(&out != &plant && out.width() == plant.width() && out.height() == plant.height());
    const int width = plant.width(), height = plant.height();
    CV_Assert(scratch.candidates_.width() == width && scratch.candidates_.height() == height);
    out = plant;  // same size: copies the words, allocates nothing
    const int r = std::min(radius_px, kMaxRadiusPx);
    if (r <= 0 || width == 0 || height == 0)
        return;
    // Only pixels above the floor and outside the plant can join it.
    BitMask& candidates = scratch.candidates_;
    threshold_to_bits(index_u8, std::clamp(floor, 0, 255), candidates);
    std::uint16_t* count = scratch.count_.data();
    std::uint16_t* sum = scratch.sum_.data();
    std::uint8_t* row_mask = scratch.row_mask_.data();
    std::fill(count, count + width, std::uint16_t{0});
    std::fill(sum, sum + width, std::uint16_t{0});
    // An edge pixel of a leaf wider than the window sees the leaf over about
    // half of it; a speck of a few pixels fills much less, and is left as it is.
    const long min_plant_px = static_cast<long>(2 * r + 1) * (2 * r + 1) / 4;
    const long soil = soil_level;
    // Column sums over rows [y - r, y + r], slid down one row at a time.
    long window_pixels = 0;
    for (int y = 0; y < std::min(r, height); ++y) {
        slide_columns(index_u8, plant, y, -1, count, sum, row_mask);
        window_pixels += row_count(plant, y);
    }
    for (int y = 0; y < height; ++y) {
        const int enter = y + r < height ? y + r : -1, leave = y - r - 1;
        slide_columns(index_u8, plant, enter, leave, count, sum, row_mask);
        if (enter >= 0)
            window_pixels += row_count(plant, enter);
        if (leave >= 0)
            window_pixels -= row_count(plant, leave);
        if (window_pixels < min_plant_px)
            continue;  // too little plant within reach of this row
        const std::uint8_t* index = index_u8.ptr<std::uint8_t>(y);
        const std::uint64_t* inside = plant.row(y);
        std::uint64_t* cand = candidates.row(y);
        std::uint64_t* row = out.row(y);
        // The window [lo, hi] of the last candidate and its sums. Candidates
        // come left to right and mostly in clusters along a leaf's edge, so
        // the next window is the last one slid by a few columns: the
        // columns it leaves and enters cost less than summing it afresh.
        int lo = 0, hi = -1;
        long n = 0, s = 0;
        visit_row_bits(
            0, candidates.words_per_row(), [&](int w) { return cand[w] & ~inside[w]; },
            [&](int x) {
                const int next_lo = std::max(x - r, 0), next_hi = std::min(x + r, width - 1);
                if (2 * (next_lo - lo) < next_hi - next_lo + 1 && next_lo <= hi) {
                    for (int c = lo; c < next_lo; ++c) {
                        n -= count[c];
                        s -= sum[c];
                    }
                    for (int c = hi + 1; c <= next_hi; ++c) {
                        n += count[c];
                        s += sum[c];
                    }
                } else {
                    n = 0;
                    s = 0;
                    for (int c = next_lo; c <= next_hi; ++c) {
                        n += count[c];
                        s += sum[c];
                    }
                }
                lo = next_lo;
                hi = next_hi;
                // index > soil + (s / n - soil) / 2, in integers.
                if (n >= min_plant_px && 2 * n * index[x] > n * soil + s)
                    row[x >> 6] |= std::uint64_t{1} << (x & 63);
            });
    }
}

}  // namespace stemd::vision
