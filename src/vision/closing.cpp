#include "stemd/vision/closing.hpp"

#include <algorithm>
#include <cstring>
#include <memory>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace stemd::vision {

std::vector<int> ellipse_half_widths(int radius_px)
{
    const int size = 2 * radius_px + 1;
    const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(size, size));
    std::vector<int> half_widths(static_cast<std::size_t>(size), -1);
    for (int row = 0; row < size; ++row) {
        const std::uint8_t* k = kernel.ptr<std::uint8_t>(row);
        int first = -1, last = -1;
        for (int col = 0; col < size; ++col) {
            if (k[col]) {
                if (first < 0)
                    first = col;
                last = col;
            }
        }
        // OpenCV's ellipse rows are single runs centred on the anchor.
        CV_Assert(first < 0 || (radius_px - first == last - radius_px));
        half_widths[static_cast<std::size_t>(row)] = first < 0 ? -1 : radius_px - first;
    }
    return half_widths;
}

void ClosingScratch::reserve(int width_px, int height_px, int max_radius_px)
{
    dilated_.reset(width_px, height_px);
    const std::size_t words = static_cast<std::size_t>(dilated_.words_per_row());
    const std::size_t rows = static_cast<std::size_t>(2 * max_radius_px + 1);
    const std::size_t slots = static_cast<std::size_t>(max_radius_px + 1);
    ring_.resize(rows * slots * words);
    row_tmp_.resize(2 * words);
    row_clear_ = std::make_unique<bool[]>(rows);
    width_slot_.reserve(rows);
    slot_half_width_.reserve(slots);
}

std::size_t ClosingScratch::reserved_bytes() const
{
    return dilated_.reserved_bytes() + (ring_.capacity() + row_tmp_.capacity()) * sizeof(std::uint64_t) +
           static_cast<std::size_t>(2 * std::max(kernel_radius_, kMaxClosingRadiusPx) + 1) * sizeof(bool);
}

namespace {

enum class Op { dilate, erode };

// One horizontal step: every pixel takes the OR (dilate) or AND (erode) of
// itself and its two neighbours. Outside the row counts as 0 for dilation
// and 1 for erosion, as in OpenCV's default morphology border.
template <Op op>
void horizontal_step(const std::uint64_t* in, std::uint64_t* out, int words)
{
    constexpr std::uint64_t outside = op == Op::dilate ? 0 : ~std::uint64_t{0};
    auto step = [&](int i, std::uint64_t previous, std::uint64_t next) {
        const std::uint64_t to_right = (in[i] << 1) | (previous >> 63);
        const std::uint64_t to_left = (in[i] >> 1) | (next << 63);
        if constexpr (op == Op::dilate)
            out[i] = in[i] | to_right | to_left;
        else
            out[i] = in[i] & to_right & to_left;
    };
    if (words == 1) {
        step(0, outside, outside);
        return;
    }
    step(0, outside, in[1]);
    // The interior without the border's conditions, so the compiler
    // vectorises it.
    for (int i = 1; i + 1 < words; ++i)
        step(i, in[i - 1], in[i + 1]);
    step(words - 1, in[words - 2], outside);
}

struct Kernel {
    int radius;
    const std::vector<int>& width_slot;       // per kernel row
    const std::vector<int>& slot_half_width;  // ascending
};

// dst = src (+) kernel or src (-) kernel, streaming rows through a ring of
// 2r+1 rows, each kept at every half width the kernel uses.
template <Op op>
void morph_pass(const BitMask& src, BitMask& dst, const Kernel& kernel, std::uint64_t* ring, std::uint64_t* tmp,
                bool* row_clear_flags)
{
    const int words = src.words_per_row();
    const int height = src.height();
    const int radius = kernel.radius;
    const int ring_rows = 2 * radius + 1;
    const int slots = static_cast<int>(kernel.slot_half_width.size());
    const std::size_t slot_words = static_cast<std::size_t>(words);
    const std::size_t row_words = slot_words * slots;
    constexpr std::uint64_t outside = op == Op::dilate ? 0 : ~std::uint64_t{0};
    const std::uint64_t pad_bits = ~src.last_word_mask();

    // Rows that are entirely clear stay clear at every width: they are only
    // marked, which makes sparse frames cheap. For the erosion a clear row
    // anywhere in the window clears the output row.
    bool* row_clear = row_clear_flags;
    auto load = [&](int y) {
        const int slot_row = (y + ring_rows) % ring_rows;
        std::uint64_t* slot0 = ring + static_cast<std::size_t>(slot_row) * row_words;
        if (y < 0 || y >= height) {
            std::fill(slot0, slot0 + row_words, outside);
            row_clear[slot_row] = op == Op::dilate;
            return;
        }
        const std::uint64_t* in = src.row(y);
        std::uint64_t any = 0;
        for (int i = 0; i < words; ++i)
            any |= in[i];
        row_clear[slot_row] = any == 0;
        if (any == 0)
            return;
        std::uint64_t* a = tmp;
        std::uint64_t* b = tmp + slot_words;
        std::memcpy(a, in, slot_words * sizeof(std::uint64_t));
        if constexpr (op == Op::erode)
            a[words - 1] |= pad_bits;  // beyond the width is outside: 1 for erosion
        int width = 0;
        for (int s = 0; s < slots; ++s) {
            while (width < kernel.slot_half_width[static_cast<std::size_t>(s)]) {
                horizontal_step<op>(a, b, words);
                std::swap(a, b);
                ++width;
            }
            std::memcpy(slot0 + s * slot_words, a, slot_words * sizeof(std::uint64_t));
        }
    };

    for (int y = -radius; y < radius; ++y)
        load(y);
    // The window's rows in ring order: its top row's place moves on by one
    // per output row, so no division per kernel row.
    int top = ring_rows - radius;   // row -radius
    for (int y = 0; y < height; ++y, top = top + 1 == ring_rows ? 0 : top + 1) {
        load(y + radius);
        std::uint64_t* out = dst.row(y);
        std::fill(out, out + words, 0);
        auto window_row = [&](int k) { return top + k < ring_rows ? top + k : top + k - ring_rows; };
        if constexpr (op == Op::erode) {
            bool any_clear = false;
            for (int k = 0; k < ring_rows && !any_clear; ++k)
                any_clear = row_clear[window_row(k)];
            if (any_clear)
                continue;
            std::fill(out, out + words, ~std::uint64_t{0});
        }
        // The window's rows combined four at a time: one read and write of
        // the output row per four input rows instead of per row. A short
        // last group repeats its first row, which changes neither OR nor AND.
        const std::uint64_t* group[4] = {};
        int grouped = 0;
        auto combine_group = [&] {
            for (int g = grouped; g < 4; ++g)
                group[g] = group[0];
            grouped = 0;
            const std::uint64_t *a = group[0], *b = group[1], *c = group[2], *d = group[3];
            if constexpr (op == Op::dilate)
                for (int i = 0; i < words; ++i)
                    out[i] |= (a[i] | b[i]) | (c[i] | d[i]);
            else
                for (int i = 0; i < words; ++i)
                    out[i] &= (a[i] & b[i]) & (c[i] & d[i]);
        };
        for (int k = 0; k < ring_rows; ++k) {
            const int ring_index = window_row(k);
            if (op == Op::dilate && row_clear[ring_index])
                continue;
            const int slot = kernel.width_slot[static_cast<std::size_t>(k)];
            group[grouped++] = ring + static_cast<std::size_t>(ring_index) * row_words + slot * slot_words;
            if (grouped == 4)
                combine_group();
        }
        if (grouped > 0)
            combine_group();
        out[words - 1] &= src.last_word_mask();
    }
}

// Radius 0 (or an empty mask): out = in. Returns whether it copied.
bool copy_if_trivial(const BitMask& in, int radius_px, BitMask& out)
{
    if (out.width() != in.width() || out.height() != in.height())
        out.reset(in.width(), in.height());
    if (radius_px > 0 && in.width() > 0 && in.height() > 0)
        return false;
    for (int y = 0; y < in.height(); ++y)
        std::copy(in.row(y), in.row(y) + in.words_per_row(), out.row(y));
    return true;
}

}  // namespace

struct MorphologyAccess {
    // Sizes the scratch for `in` and sets the kernel up for `radius_px` (> 0).
    // Allocates only when the size or a larger radius is new.
    static Kernel prepare_kernel(const BitMask& in, int radius_px, ClosingScratch& scratch);
    // `ops` (one or two) in turn from `in` to `out` with a kernel of
    // `radius_px`, two through the scratch's intermediate mask. Radius 0 or
    // an empty mask copies.
    template <Op first, Op... second>
    static void apply(const BitMask& in, int radius_px, BitMask& out, ClosingScratch& scratch)
    {
        static_assert(sizeof...(second) <= 1);
        CV_Assert(&in != &out);
        radius_px = std::max(radius_px, 0);
        if (copy_if_trivial(in, radius_px, out))
            return;
        const Kernel kernel = prepare_kernel(in, radius_px, scratch);
        if constexpr (sizeof...(second) == 0) {
            pass<first>(in, out, kernel, scratch);
        } else {
            pass<first>(in, scratch.dilated_, kernel, scratch);
            pass<second...>(scratch.dilated_, out, kernel, scratch);
        }
    }
    template <Op op>
    static void pass(const BitMask& from, BitMask& to, const Kernel& kernel, ClosingScratch& scratch)
    {
        morph_pass<op>(from, to, kernel, scratch.ring_.data(), scratch.row_tmp_.data(), scratch.row_clear_.get());
    }
};

Kernel MorphologyAccess::prepare_kernel(const BitMask& in, int radius_px, ClosingScratch& scratch)
{
    const std::size_t words = static_cast<std::size_t>(in.words_per_row());
    const std::size_t ring_needed = static_cast<std::size_t>(2 * radius_px + 1) * (radius_px + 1) * words;
    if (scratch.dilated_.width() != in.width() || scratch.dilated_.height() != in.height() ||
        scratch.ring_.size() < ring_needed)
        scratch.reserve(in.width(), in.height(), std::max(radius_px, scratch.kernel_radius_));

    if (scratch.kernel_radius_ != radius_px) {
        // The kernel's shape, computed once per radius (allocation-free once reserved).
        const std::vector<int> half_widths = ellipse_half_widths(radius_px);
        scratch.slot_half_width_.clear();
        for (const int w : half_widths)
            if (std::find(scratch.slot_half_width_.begin(), scratch.slot_half_width_.end(), w) ==
                scratch.slot_half_width_.end())
                scratch.slot_half_width_.push_back(w);
        std::sort(scratch.slot_half_width_.begin(), scratch.slot_half_width_.end());
        scratch.width_slot_.clear();
        for (const int w : half_widths)
            scratch.width_slot_.push_back(static_cast<int>(
                std::find(scratch.slot_half_width_.begin(), scratch.slot_half_width_.end(), w) -
                scratch.slot_half_width_.begin()));
        scratch.kernel_radius_ = radius_px;
    }
    return Kernel{radius_px, scratch.width_slot_, scratch.slot_half_width_};
}


void close_mask(const BitMask& in, int radius_px, BitMask& out, ClosingScratch& scratch)
{
    MorphologyAccess::apply<Op::dilate, Op::erode>(in, radius_px, out, scratch);
}

void open_mask(const BitMask& in, int radius_px, BitMask& out, ClosingScratch& scratch)
{
    MorphologyAccess::apply<Op::erode, Op::dilate>(in, radius_px, out, scratch);
}

void dilate_mask(const BitMask& in, int radius_px, BitMask& out, ClosingScratch& scratch)
{
    MorphologyAccess::apply<Op::dilate>(in, radius_px, out, scratch);
}

void erode_mask(const BitMask& in, int radius_px, BitMask& out, ClosingScratch& scratch)
{
    MorphologyAccess::apply<Op::erode>(in, radius_px, out, scratch);
}

}  // namespace stemd::vision
