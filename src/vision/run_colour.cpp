#include "stemd/vision/run_colour.hpp"

#include <algorithm>
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

// Picked once at start, never on the frame path.
const bool kSsse3 = kernel_available(Kernel::ssse3);
#else
template <bool kNir>
void add_run_ssse3(const ColourRows& rows, int x_start, int x_stop, RunColour& c)
{
    add_run_baseline<kNir>(rows, x_start, x_stop, c);
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

}  // namespace

void add_vegetation_run(const ColourRows& rows, int x_start, int x_stop, RunColour& sums,
                        Kernel kernel)
{
    CV_Assert(kernel_available(kernel));
    CV_Assert(0 <= x_start && x_start <= x_stop && x_stop <= rows.width);
    add_run(rows, x_start, x_stop, sums, kernel);
}

void add_vegetation_run(const ColourRows& rows, int x_start, int x_stop, RunColour& sums)
{
    add_run(rows, x_start, x_stop, sums, kSsse3 ? Kernel::ssse3 : Kernel::baseline);
}

}  // namespace stemd::vision
