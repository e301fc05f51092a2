#include "stemd/vision/run_colour.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <cstring>

#include <opencv2/core.hpp>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define STEMD_HAVE_SSSE3_KERNELS 1
#include <tmmintrin.h>
#endif

namespace stemd::vision {

namespace {

// Along a run each pixel's R+G+B is its right neighbour's left one: read
// once, not three times. Built once with and once without NIR, so the
// pixel loop does not ask.
template <bool kNir>
void add_run_baseline(const ColourRows& rows, int x_start, int x_stop, RunColour& c)
{
    if (x_start >= x_stop)
        return;
    const cv::Vec3b* bgr = rows.bgr;
    int left = brightness_sum(bgr[std::max(x_start - 1, 0)]), here = brightness_sum(bgr[x_start]);
    const auto add = [&](int x, int right) {
        const cv::Vec3b& p = bgr[x];
        c.brightness += here;
        const float inv = kColourReciprocal[static_cast<std::size_t>(here)];
        const float r = static_cast<float>(p[2]) * inv, g = static_cast<float>(p[1]) * inv;
        c.r += r;
        c.g += g;
        c.b += static_cast<float>(p[0]) * inv;
        c.rr += r * r;
        c.gg += g * g;
        c.gradient += std::abs(right - left) + std::abs(brightness_sum(rows.down[x]) - brightness_sum(rows.up[x]));
        if constexpr (kNir) {
            const int nv = rows.nir[x], red = p[2];
            const float ndvi = static_cast<float>(nv - red) * kColourReciprocal[static_cast<std::size_t>(nv + red)];
            c.ndvi += ndvi;
            c.ndvi2 += ndvi * ndvi;
        }
    };
    // Every column but the frame's last has a right neighbour; the last
    // one's is itself.
    const int inner_stop = std::min(x_stop, rows.width - 1);
    int x = x_start;
    for (; x < inner_stop; ++x) {
        const int right = brightness_sum(bgr[x + 1]);
        add(x, right);
        left = here;
        here = right;
    }
    if (x < x_stop)
        add(x, here);
}

// The pixels add_cell_samples() takes: x % 4 == 0.
constexpr std::uint64_t kEveryFourth = 0x1111111111111111ull;

// Boyer-Moore majority vote: the plant most of the cell's samples belong
// to, in constant memory.
inline void vote(std::uint16_t plant, std::uint16_t& leader, std::uint16_t& count)
{
    if (count == 0) {
        leader = plant;
        count = 1;
    } else {
        count = static_cast<std::uint16_t>(count + (leader == plant ? 1 : -1));
    }
}

// The samples with x in [x_start, x_stop). A cell's samples come one after
// another along the row, so its sums stay in a local copy (registers)
// until the next cell's sample, not a load and a store per sum and sample.
template <bool kNir>
void add_samples_baseline(const ColourRows& rows, const std::uint64_t* vegetation, int x_start, int x_stop,
                          const std::uint16_t* cell_of, const std::uint16_t* plant_of, CellSamples* cells)
{
    if (x_start >= x_stop)
        return;
    const int width = rows.width;
    const cv::Vec3b* bgr = rows.bgr;
    std::size_t current = cell_of[x_start];
    CellSamples s = cells[current];
    for (int w = x_start >> 6; w <= (x_stop - 1) >> 6; ++w) {
        const int base = w * 64;
        std::uint64_t bits = vegetation[w] & kEveryFourth;
        if (x_start > base)
            bits &= ~std::uint64_t{0} << (x_start - base);
        if (x_stop - base < 64)
            bits &= (std::uint64_t{1} << (x_stop - base)) - 1;
        for (; bits != 0; bits &= bits - 1) {
            const int x = base + std::countr_zero(bits);
            const std::size_t cell = cell_of[x];
            if (cell != current) {
                cells[current] = s;
                current = cell;
                s = cells[cell];
            }
            ++s.sampled_px;
            const cv::Vec3b& p = bgr[x];
            const int sum = brightness_sum(p);
            s.brightness += static_cast<float>(sum);
            const float inv = kColourReciprocal[static_cast<std::size_t>(sum)];
            const float r = static_cast<float>(p[2]) * inv, g = static_cast<float>(p[1]) * inv;
            s.r += r;
            s.g += g;
            s.rr += r * r;
            s.gg += g * g;
            const auto gx = static_cast<float>(brightness_sum(bgr[std::min(x + 1, width - 1)]) -
                                               brightness_sum(bgr[std::max(x - 1, 0)]));
            const auto gy = static_cast<float>(brightness_sum(rows.down[x]) - brightness_sum(rows.up[x]));
            s.gradient += std::abs(gx) + std::abs(gy);
            s.sxx += gx * gx;
            s.syy += gy * gy;
            s.sxy += gx * gy;
            if constexpr (kNir) {
                const int nv = rows.nir[x], red = p[2];
                const float ndvi = static_cast<float>(nv - red) * kColourReciprocal[static_cast<std::size_t>(nv + red)];
                s.ndvi += ndvi;
                s.ndvi2 += ndvi * ndvi;
            }
            vote(plant_of[x], s.plant_vote, s.plant_count);
        }
    }
    cells[current] = s;
}

#if defined(STEMD_HAVE_SSSE3_KERNELS)
// Four packed BGR pixels from `p` as 32-bit lanes of bytes (B, G, R, 0);
// 16 bytes are read.
__attribute__((target("ssse3"))) inline __m128i four_pixels(const cv::Vec3b* p)
{
    const __m128i spread = _mm_setr_epi8(0, 1, 2, -1, 3, 4, 5, -1, 6, 7, 8, -1, 9, 10, 11, -1);
    return _mm_shuffle_epi8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)), spread);
}

// B + G + R of each lane of four_pixels(): bytes to pairs, pairs to lanes.
__attribute__((target("ssse3"))) inline __m128i brightness_of(__m128i pixels)
{
    return _mm_madd_epi16(_mm_maddubs_epi16(pixels, _mm_set1_epi8(1)), _mm_set1_epi16(1));
}

// 1 / s per lane, 0 where s is 0: the table's values, as IEEE division
// rounds alike wherever it runs.
__attribute__((target("ssse3"))) inline __m128 reciprocal_of(__m128 s)
{
    const __m128 one = _mm_set1_ps(1.0f);
    return _mm_and_ps(_mm_div_ps(one, _mm_max_ps(s, one)), _mm_cmpneq_ps(s, _mm_setzero_ps()));
}

__attribute__((target("ssse3"))) inline long lane_sum(__m128i v)
{
    alignas(16) std::int32_t lanes[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(lanes), v);
    return static_cast<long>(lanes[0]) + lanes[1] + lanes[2] + lanes[3];
}

// sum + pixel[0] + ... + pixel[n-1], added one after the other.
__attribute__((target("ssse3"))) inline __m128 add_in_order(__m128 sum, __m128 pixel0, __m128 pixel1, __m128 pixel2,
                                                            __m128 pixel3, int n)
{
    sum = _mm_add_ps(sum, pixel0);
    if (n > 1)
        sum = _mm_add_ps(sum, pixel1);
    if (n > 2)
        sum = _mm_add_ps(sum, pixel2);
    if (n > 3)
        sum = _mm_add_ps(sum, pixel3);
    return sum;
}

// The running state of add_run_ssse3: the pixels of the step, their
// brightness and the previous step's, and the sums so far.
struct Ssse3Run {
    __m128i centre, here, before;   // four_pixels(), its brightness, the last step's brightness
    __m128i brightness, gradient;   // lane sums
    __m128 colour;                  // r, g, b, rr
    __m128 rest;                    // gg, ndvi, ndvi2, unused
};

// Adds pixels x..x+n-1 (1 <= n <= 4) of a step at x. The float sums take
// one pixel after the other (a 4 x 4 transpose puts pixel i's r, g, b, rr
// in one vector, added to the vector of the four sums), so no sum is
// reassociated; the integer sums are exact in any order.
template <bool kNir>
__attribute__((target("ssse3"))) inline void add_step(const ColourRows& rows, int x, int n, Ssse3Run& s)
{
    const __m128i low_byte = _mm_set1_epi32(0xff);
    const __m128i next = four_pixels(rows.bgr + x + 4);
    const __m128i ahead = brightness_of(next);
    const __m128i left = _mm_alignr_epi8(s.here, s.before, 12);   // pixels x-1..x+2
    const __m128i right = _mm_alignr_epi8(ahead, s.here, 4);      // pixels x+1..x+4
    const __m128i above = brightness_of(four_pixels(rows.up + x));
    const __m128i below = brightness_of(four_pixels(rows.down + x));
    __m128i gradient = _mm_add_epi32(_mm_abs_epi32(_mm_sub_epi32(right, left)),
                                     _mm_abs_epi32(_mm_sub_epi32(below, above)));
    __m128i brightness = s.here;
    if (n < 4) {
        const __m128i kept = _mm_cmpgt_epi32(_mm_set1_epi32(n), _mm_setr_epi32(0, 1, 2, 3));
        gradient = _mm_and_si128(gradient, kept);
        brightness = _mm_and_si128(brightness, kept);
    }
    s.brightness = _mm_add_epi32(s.brightness, brightness);
    s.gradient = _mm_add_epi32(s.gradient, gradient);
    const __m128 inv = reciprocal_of(_mm_cvtepi32_ps(s.here));
    const __m128i red = _mm_srli_epi32(s.centre, 16);   // byte 3 is 0
    __m128 r = _mm_mul_ps(_mm_cvtepi32_ps(red), inv);
    __m128 g = _mm_mul_ps(_mm_cvtepi32_ps(_mm_and_si128(_mm_srli_epi32(s.centre, 8), low_byte)), inv);
    __m128 b = _mm_mul_ps(_mm_cvtepi32_ps(_mm_and_si128(s.centre, low_byte)), inv);
    __m128 rr = _mm_mul_ps(r, r);
    __m128 gg = _mm_mul_ps(g, g);
    _MM_TRANSPOSE4_PS(r, g, b, rr);   // now pixel x, x+1, x+2, x+3
    s.colour = add_in_order(s.colour, r, g, b, rr, n);
    if constexpr (kNir) {
        const __m128i nir_spread = _mm_setr_epi8(0, -1, -1, -1, 1, -1, -1, -1, 2, -1, -1, -1, 3, -1, -1, -1);
        std::int32_t nir_bytes;
        std::memcpy(&nir_bytes, rows.nir + x, sizeof nir_bytes);
        const __m128i nir = _mm_shuffle_epi8(_mm_cvtsi32_si128(nir_bytes), nir_spread);
        __m128 ndvi = _mm_mul_ps(_mm_cvtepi32_ps(_mm_sub_epi32(nir, red)),
                                 reciprocal_of(_mm_cvtepi32_ps(_mm_add_epi32(nir, red))));
        __m128 ndvi2 = _mm_mul_ps(ndvi, ndvi);
        __m128 none = _mm_setzero_ps();
        _MM_TRANSPOSE4_PS(gg, ndvi, ndvi2, none);
        s.rest = add_in_order(s.rest, gg, ndvi, ndvi2, none, n);
    } else {
        // gg alone: lane 0 of `rest` takes each pixel's in turn.
        s.rest = _mm_add_ss(s.rest, gg);
        if (n > 1)
            s.rest = _mm_add_ss(s.rest, _mm_shuffle_ps(gg, gg, 1));
        if (n > 2)
            s.rest = _mm_add_ss(s.rest, _mm_shuffle_ps(gg, gg, 2));
        if (n > 3)
            s.rest = _mm_add_ss(s.rest, _mm_shuffle_ps(gg, gg, 3));
    }
    s.before = s.here;
    s.here = ahead;
    s.centre = next;
}

template <bool kNir>
__attribute__((target("ssse3"))) void add_run_ssse3(const ColourRows& rows, int x_start, int x_stop, RunColour& c)
{
    // A step at x adds pixels x..x+3 (or fewer, the run's last) and reads
    // the left neighbour x-1 and, 16 bytes from pixel x+4, the next step's
    // pixels: so 1 <= x <= width - 10. The pixels outside (the row's first
    // and last few) go through the baseline, in order.
    int x = std::max(x_start, 1);
    const int last_step = rows.width - 10;
    if (x >= x_stop || x > last_step) {
        add_run_baseline<kNir>(rows, x_start, x_stop, c);
        return;
    }
    add_run_baseline<kNir>(rows, x_start, x, c);

    Ssse3Run s;
    s.centre = four_pixels(rows.bgr + x);
    s.here = brightness_of(s.centre);
    s.before = _mm_set1_epi32(brightness_sum(rows.bgr[x - 1]));   // lane 3 is pixel x-1
    s.brightness = _mm_setzero_si128();
    s.gradient = _mm_setzero_si128();
    s.colour = _mm_setr_ps(c.r, c.g, c.b, c.rr);
    s.rest = _mm_setr_ps(c.gg, c.ndvi, c.ndvi2, 0.0f);
    // Lanes hold at most 765 and 1530 a step: int32 holds them for any
    // row under a million steps.
    for (; x + 4 <= x_stop && x <= last_step; x += 4)
        add_step<kNir>(rows, x, 4, s);
    if (x < x_stop && x <= last_step) {
        add_step<kNir>(rows, x, x_stop - x, s);   // fewer than four left
        x = x_stop;
    }
    alignas(16) float sums[8];
    _mm_store_ps(sums, s.colour);
    _mm_store_ps(sums + 4, s.rest);
    c.r = sums[0];
    c.g = sums[1];
    c.b = sums[2];
    c.rr = sums[3];
    c.gg = sums[4];
    if constexpr (kNir) {
        c.ndvi = sums[5];
        c.ndvi2 = sums[6];
    }
    c.brightness += lane_sum(s.brightness);
    c.gradient += lane_sum(s.gradient);
    add_run_baseline<kNir>(rows, x, x_stop, c);
}

// The vector kernel reads r..gg and brightness..syy as one vector each.
static_assert(offsetof(CellSamples, gg) == offsetof(CellSamples, r) + 3 * sizeof(float));
static_assert(offsetof(CellSamples, syy) == offsetof(CellSamples, brightness) + 3 * sizeof(float));

// The sums of the cell that add_cell_samples_ssse3 is adding to, in
// vectors: (r, g, rr, gg), (brightness, gradient, sxx, syy) and
// (sxy, ndvi, ndvi2, unused).
struct Ssse3Cell {
    CellSamples* cells;
    std::size_t current;
    __m128 colour, texture, rest;
    int sampled_px;
    std::uint16_t plant_vote, plant_count;
};

__attribute__((target("ssse3"))) inline void load_cell(Ssse3Cell& c, std::size_t cell)
{
    const CellSamples& s = c.cells[cell];
    c.current = cell;
    c.colour = _mm_loadu_ps(&s.r);
    c.texture = _mm_loadu_ps(&s.brightness);
    c.rest = _mm_setr_ps(s.sxy, s.ndvi, s.ndvi2, 0.0f);
    c.sampled_px = s.sampled_px;
    c.plant_vote = s.plant_vote;
    c.plant_count = s.plant_count;
}

__attribute__((target("ssse3"))) inline void store_cell(const Ssse3Cell& c)
{
    CellSamples& s = c.cells[c.current];
    _mm_storeu_ps(&s.r, c.colour);
    _mm_storeu_ps(&s.brightness, c.texture);
    alignas(16) float rest[4];
    _mm_store_ps(rest, c.rest);
    s.sxy = rest[0];
    s.ndvi = rest[1];
    s.ndvi2 = rest[2];
    s.sampled_px = c.sampled_px;
    s.plant_vote = c.plant_vote;
    s.plant_count = c.plant_count;
}

// Pixels p[0], p[4], p[8] and p[12] as 32-bit lanes of bytes (B, G, R, 0);
// reads 40 bytes.
__attribute__((target("ssse3"))) inline __m128i every_fourth_pixel(const cv::Vec3b* p)
{
    const auto* bytes = reinterpret_cast<const std::uint8_t*>(p);
    const __m128i first = _mm_loadu_si128(reinterpret_cast<const __m128i*>(bytes));        // pixels 0 and 4
    const __m128i second = _mm_loadu_si128(reinterpret_cast<const __m128i*>(bytes + 24));  // pixels 8 and 12
    return _mm_or_si128(
        _mm_shuffle_epi8(first, _mm_setr_epi8(0, 1, 2, -1, 12, 13, 14, -1, -1, -1, -1, -1, -1, -1, -1, -1)),
        _mm_shuffle_epi8(second, _mm_setr_epi8(-1, -1, -1, -1, -1, -1, -1, -1, 0, 1, 2, -1, 12, 13, 14, -1)));
}

// The samples x0, x0+4, x0+8 and x0+12 whose bits (0, 4, 8, 12) are set in
// `samples`; 1 <= x0 <= width - 17, as pixels x0-1 .. x0+16 are read. The
// four samples' values are computed side by side, then a 4 x 4 transpose
// gives each sample's as vectors that are added to the cell's sums one
// sample after the other, so no sum is reassociated.
template <bool kNir>
__attribute__((target("ssse3"))) inline void add_sample_group(const ColourRows& rows, int x0, unsigned samples,
                                                              const std::uint16_t* cell_of,
                                                              const std::uint16_t* plant_of, Ssse3Cell& cell)
{
    const cv::Vec3b* p = rows.bgr + x0;
    // Lanes j of pk: pixel x0 + 4k - 1 + j; transposed, each sample's
    // left neighbour, itself and its right neighbour.
    const __m128i p0 = four_pixels(p - 1), p1 = four_pixels(p + 3), p2 = four_pixels(p + 7), p3 = four_pixels(p + 11);
    const __m128i low01 = _mm_unpacklo_epi32(p0, p1), low23 = _mm_unpacklo_epi32(p2, p3);
    const __m128i high01 = _mm_unpackhi_epi32(p0, p1), high23 = _mm_unpackhi_epi32(p2, p3);
    const __m128i centre = _mm_unpackhi_epi64(low01, low23);
    const __m128i left = brightness_of(_mm_unpacklo_epi64(low01, low23));
    const __m128i right = brightness_of(_mm_unpacklo_epi64(high01, high23));
    const __m128i above = brightness_of(every_fourth_pixel(rows.up + x0));
    const __m128i below = brightness_of(every_fourth_pixel(rows.down + x0));
    const __m128i red = _mm_srli_epi32(centre, 16);   // byte 3 is 0

    __m128 brightness = _mm_cvtepi32_ps(brightness_of(centre));
    const __m128 inv = reciprocal_of(brightness);
    __m128 r = _mm_mul_ps(_mm_cvtepi32_ps(red), inv);
    __m128 g = _mm_mul_ps(_mm_cvtepi32_ps(_mm_and_si128(_mm_srli_epi32(centre, 8), _mm_set1_epi32(0xff))), inv);
    __m128 rr = _mm_mul_ps(r, r);
    __m128 gg = _mm_mul_ps(g, g);
    const __m128 gx = _mm_cvtepi32_ps(_mm_sub_epi32(right, left));
    const __m128 gy = _mm_cvtepi32_ps(_mm_sub_epi32(below, above));
    const __m128 magnitude = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
    __m128 gradient = _mm_add_ps(_mm_and_ps(gx, magnitude), _mm_and_ps(gy, magnitude));
    __m128 sxx = _mm_mul_ps(gx, gx);
    __m128 syy = _mm_mul_ps(gy, gy);
    __m128 sxy = _mm_mul_ps(gx, gy);
    // Without NIR the NDVI lanes add 0, which leaves their sums (0) as
    // they are.
    __m128 ndvi = _mm_setzero_ps(), ndvi2 = _mm_setzero_ps(), unused = _mm_setzero_ps();
    if constexpr (kNir) {
        const __m128i nir = _mm_shuffle_epi8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(rows.nir + x0)),
                                             _mm_setr_epi8(0, -1, -1, -1, 4, -1, -1, -1, 8, -1, -1, -1, 12, -1, -1, -1));
        ndvi = _mm_mul_ps(_mm_cvtepi32_ps(_mm_sub_epi32(nir, red)),
                          reciprocal_of(_mm_cvtepi32_ps(_mm_add_epi32(nir, red))));
        ndvi2 = _mm_mul_ps(ndvi, ndvi);
    }
    _MM_TRANSPOSE4_PS(r, g, rr, gg);                      // now samples 0, 1, 2, 3
    _MM_TRANSPOSE4_PS(brightness, gradient, sxx, syy);
    _MM_TRANSPOSE4_PS(sxy, ndvi, ndvi2, unused);
    const auto add = [&](int k, __m128 colour, __m128 texture, __m128 rest) {
        if (((samples >> (4 * k)) & 1u) == 0)
            return;
        const int x = x0 + 4 * k;
        const std::size_t target = cell_of[x];
        if (target != cell.current) {
            store_cell(cell);
            load_cell(cell, target);
        }
        cell.colour = _mm_add_ps(cell.colour, colour);
        cell.texture = _mm_add_ps(cell.texture, texture);
        cell.rest = _mm_add_ps(cell.rest, rest);
        ++cell.sampled_px;
        vote(plant_of[x], cell.plant_vote, cell.plant_count);
    };
    add(0, r, brightness, sxy);
    add(1, g, gradient, ndvi);
    add(2, rr, sxx, ndvi2);
    add(3, gg, syy, unused);
}

template <bool kNir>
__attribute__((target("ssse3"))) void add_samples_ssse3(const ColourRows& rows, const std::uint64_t* vegetation,
                                                         const std::uint16_t* cell_of, const std::uint16_t* plant_of,
                                                         CellSamples* cells)
{
    // Groups of 16 pixels from x0 = 16 while x0 <= width - 17; the row's
    // first 16 pixels and those after the last group go through the
    // baseline, in order.
    const int width = rows.width;
    const int last_group = width - 17;
    if (last_group < 16) {
        add_samples_baseline<kNir>(rows, vegetation, 0, width, cell_of, plant_of, cells);
        return;
    }
    add_samples_baseline<kNir>(rows, vegetation, 0, 16, cell_of, plant_of, cells);
    Ssse3Cell cell{cells, 0, {}, {}, {}, 0, 0, 0};
    load_cell(cell, cell_of[16]);
    int x0 = 16;
    for (; x0 <= last_group; x0 += 16) {
        const std::uint64_t word = vegetation[x0 >> 6] & kEveryFourth;
        if (word == 0) {
            x0 |= 48;   // the word's last group: the next step starts the next word
            continue;
        }
        const auto samples = static_cast<unsigned>(word >> (x0 & 63)) & 0x1111u;
        if (samples != 0)
            add_sample_group<kNir>(rows, x0, samples, cell_of, plant_of, cell);
    }
    store_cell(cell);
    // x0 is past the last group (or the last word's, where it held no
    // sample): the rest of the row.
    add_samples_baseline<kNir>(rows, vegetation, x0, width, cell_of, plant_of, cells);
}

// Picked once at start, never on the frame path.
const bool kSsse3 = kernel_available(Kernel::ssse3);
#else
template <bool kNir>
void add_run_ssse3(const ColourRows& rows, int x_start, int x_stop, RunColour& c)
{
    add_run_baseline<kNir>(rows, x_start, x_stop, c);
}
template <bool kNir>
void add_samples_ssse3(const ColourRows& rows, const std::uint64_t* vegetation, const std::uint16_t* cell_of,
                       const std::uint16_t* plant_of, CellSamples* cells)
{
    add_samples_baseline<kNir>(rows, vegetation, 0, rows.width, cell_of, plant_of, cells);
}
const bool kSsse3 = false;
#endif

void add_run(const ColourRows& rows, int x_start, int x_stop, RunColour& sums, Kernel kernel)
{
    if (kernel == Kernel::ssse3) {
        if (rows.nir != nullptr)
            add_run_ssse3<true>(rows, x_start, x_stop, sums);
        else
            add_run_ssse3<false>(rows, x_start, x_stop, sums);
    } else {
        if (rows.nir != nullptr)
            add_run_baseline<true>(rows, x_start, x_stop, sums);
        else
            add_run_baseline<false>(rows, x_start, x_stop, sums);
    }
}

void add_samples(const ColourRows& rows, const std::uint64_t* vegetation, const std::uint16_t* cell_of,
                 const std::uint16_t* plant_of, CellSamples* cells, Kernel kernel)
{
    if (kernel == Kernel::ssse3) {
        if (rows.nir != nullptr)
            add_samples_ssse3<true>(rows, vegetation, cell_of, plant_of, cells);
        else
            add_samples_ssse3<false>(rows, vegetation, cell_of, plant_of, cells);
    } else {
        if (rows.nir != nullptr)
            add_samples_baseline<true>(rows, vegetation, 0, rows.width, cell_of, plant_of, cells);
        else
            add_samples_baseline<false>(rows, vegetation, 0, rows.width, cell_of, plant_of, cells);
    }
}

}  // namespace

void add_vegetation_run(const ColourRows& rows, int x_start, int x_stop, RunColour& sums, Kernel kernel)
{
    CV_Assert(kernel_available(kernel));
    CV_Assert(0 <= x_start && x_start <= x_stop && x_stop <= rows.width);
    add_run(rows, x_start, x_stop, sums, kernel);
}

void add_vegetation_run(const ColourRows& rows, int x_start, int x_stop, RunColour& sums)
{
    add_run(rows, x_start, x_stop, sums, kSsse3 ? Kernel::ssse3 : Kernel::baseline);
}

void add_cell_samples(const ColourRows& rows, const std::uint64_t* vegetation, const std::uint16_t* cell_of,
                      const std::uint16_t* plant_of, CellSamples* cells, Kernel kernel)
{
    CV_Assert(kernel_available(kernel));
    CV_Assert(rows.width >= 0);
    add_samples(rows, vegetation, cell_of, plant_of, cells, kernel);
}

void add_cell_samples(const ColourRows& rows, const std::uint64_t* vegetation, const std::uint16_t* cell_of,
                      const std::uint16_t* plant_of, CellSamples* cells)
{
    add_samples(rows, vegetation, cell_of, plant_of, cells, kSsse3 ? Kernel::ssse3 : Kernel::baseline);
}

}  // namespace stemd::vision
