#include "stemd/vision/index.hpp"

#include <bit>
#include <algorithm>
#include <cmath>

#include <opencv2/core.hpp>
#include <opencv2/core/hal/intrin.hpp>

#if defined(__x86_64__)
#include <tmmintrin.h>
#endif

namespace stemd::vision {

#if CV_SIMD
namespace {

// One vector of BGR pixels, deinterleaved and widened to 16 bits (low and
// high halves), so sums of a few channels cannot overflow.
struct WideBgr {
    cv::v_uint16 b0, b1, g0, g1, r0, r1;
};

inline WideBgr load_wide_bgr(const std::uint8_t* src)
{
    cv::v_uint8 b, g, r;
    cv::v_load_deinterleave(src, b, g, r);
    WideBgr p;
    cv::v_expand(b, p.b0, p.b1);
    cv::v_expand(g, p.g0, p.g1);
    cv::v_expand(r, p.r0, p.r1);
    return p;
}

}  // namespace
#endif

int index_span_granule_px()
{
#if CV_SIMD
    return cv::v_uint8::nlanes;
#else
    return 1;
#endif
}

void excess_green_span(const cv::Mat& bgr, int y, int x_begin, int x_end, cv::Mat& index_u8)
{
    const std::uint8_t* src = bgr.ptr<std::uint8_t>(y);
    std::uint8_t* dst = index_u8.ptr<std::uint8_t>(y);
    int x = x_begin;
#if CV_SIMD
    // OpenCV's portable intrinsics (SSE/AVX/NEON): deinterleave, widen
    // to 16 bits, where (2G + 512) - (R + B) is in [2, 1022], shift, narrow.
    const int lanes = cv::v_uint8::nlanes;
    const cv::v_uint16 offset = cv::vx_setall_u16(512);
    for (; x + lanes <= x_end; x += lanes) {
        const WideBgr p = load_wide_bgr(src + 3 * x);
        const cv::v_uint16 lo = cv::v_shr<2>((p.g0 + p.g0 + offset) - (p.r0 + p.b0));
        const cv::v_uint16 hi = cv::v_shr<2>((p.g1 + p.g1 + offset) - (p.r1 + p.b1));
        cv::v_store(dst + x, cv::v_pack(lo, hi));
    }
#endif
    for (; x < x_end; ++x) {
        const int b = src[3 * x], g = src[3 * x + 1], r = src[3 * x + 2];
        dst[x] = static_cast<std::uint8_t>((2 * g - r - b + 512) >> 2);
    }
}

void excess_green(const cv::Mat& bgr, cv::Mat& index_u8)
{
    CV_Assert(bgr.type() == CV_8UC3);
    index_u8.create(bgr.size(), CV_8UC1);
    for (int y = 0; y < bgr.rows; ++y)
        excess_green_span(bgr, y, 0, bgr.cols, index_u8);
}

float chromatic_mean_brightness(const cv::Mat& bgr)
{
    CV_Assert(bgr.type() == CV_8UC3);
    // Every pixel of one row in 16 (row 4 of each 16-row band, as many
    // samples as every 4th pixel of every 4th row): a normalising constant
    // needs no more, and whole rows are 1/16 of the frame's bytes read in
    // order, where every 4th pixel of a row touches all its cache lines.
    // Row 4 is also a row the sparse index samples next, so it is read once.
    std::uint64_t sum = 0, samples = 0;
    const int row_bytes = 3 * bgr.cols;
    for (int band = 0; band < bgr.rows; band += kBrightnessRowStep) {
        const std::uint8_t* src = bgr.ptr<std::uint8_t>(std::min(band + 4, bgr.rows - 1));
        int i = 0;
#if defined(__x86_64__)
        // psadbw sums 16 bytes into two 64-bit lanes: two instructions per
        // 16 bytes, where the compiler's widening loop took about sixteen.
        const __m128i zero = _mm_setzero_si128();
        __m128i lanes = zero;
        for (; i + 16 <= row_bytes; i += 16)
            lanes = _mm_add_epi64(lanes, _mm_sad_epu8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(src + i)), zero));
        sum += static_cast<std::uint64_t>(_mm_cvtsi128_si64(lanes)) +
               static_cast<std::uint64_t>(_mm_cvtsi128_si64(_mm_unpackhi_epi64(lanes, lanes)));
#endif
        for (; i < row_bytes; ++i)
            sum += src[i];
        samples += static_cast<std::uint64_t>(bgr.cols);
    }
    // The floor keeps an all-black frame from dividing by zero; it is far
    // below any exposed frame's mean.
    return static_cast<float>(
        std::max(static_cast<double>(sum) / static_cast<double>(std::max<std::uint64_t>(samples, 1)), 1.0));
}


void chromatic_excess_green(const cv::Mat& bgr, cv::Mat& index_u8)
{
    const float mean_brightness = chromatic_mean_brightness(bgr);
    index_u8.create(bgr.size(), CV_8UC1);
    for (int y = 0; y < bgr.rows; ++y)
        chromatic_excess_green_span(bgr, y, 0, bgr.cols, mean_brightness, index_u8);
}

void smooth_binomial3_rect(const cv::Mat& src_u8, cv::Rect rect, std::uint16_t* row_sums, cv::Mat& dst_u8)
{
    const int width = src_u8.cols, height = src_u8.rows;
    rect &= cv::Rect(0, 0, width, height);
    if (rect.empty())
        return;
    // Vertical sums for the rect's columns and one more on each side
    // (edges replicated), so row_sums[x] is column x's sum.
    const int xa = std::max(rect.x - 1, 0), xb = std::min(rect.x + rect.width + 1, width);
    const int x_end = rect.x + rect.width;
    for (int y = rect.y; y < rect.y + rect.height; ++y) {
        const std::uint8_t* above = src_u8.ptr<std::uint8_t>(std::max(y - 1, 0));
        const std::uint8_t* centre = src_u8.ptr<std::uint8_t>(y);
        const std::uint8_t* below = src_u8.ptr<std::uint8_t>(std::min(y + 1, height - 1));
        int x = xa;
#if CV_SIMD
        const int lanes16 = cv::v_uint16::nlanes;
        for (; x + lanes16 <= xb; x += lanes16) {
            const cv::v_uint16 c = cv::vx_load_expand(centre + x);
            cv::v_store(row_sums + x, cv::vx_load_expand(above + x) + c + c + cv::vx_load_expand(below + x));
        }
#endif
        for (; x < xb; ++x)
            row_sums[x] = static_cast<std::uint16_t>(above[x] + 2 * centre[x] + below[x]);
        std::uint8_t* dst = dst_u8.ptr<std::uint8_t>(y);
        if (width == 1) {
            dst[0] = static_cast<std::uint8_t>((4 * row_sums[0] + 8) >> 4);
            continue;
        }
        x = rect.x;
        if (x == 0) {
            dst[0] = static_cast<std::uint8_t>((3 * row_sums[0] + row_sums[1] + 8) >> 4);
            x = 1;
        }
        // Interior pixels: both neighbours exist. Integer arithmetic, so the
        // vector and scalar paths agree wherever a span starts.
        const int interior_end = std::min(x_end, width - 1);
#if CV_SIMD
        // At most 16 * 255 + 8: the sums fit in 16 bits.
        const cv::v_uint16 half = cv::vx_setall_u16(8);
        for (; x + lanes16 <= interior_end; x += lanes16) {
            const cv::v_uint16 c = cv::vx_load(row_sums + x);
            const cv::v_uint16 sum = cv::vx_load(row_sums + x - 1) + c + c + cv::vx_load(row_sums + x + 1) + half;
            cv::v_pack_store(dst + x, cv::v_shr<4>(sum));
        }
#endif
        for (; x < interior_end; ++x)
            dst[x] = static_cast<std::uint8_t>((row_sums[x - 1] + 2 * row_sums[x] + row_sums[x + 1] + 8) >> 4);
        if (x_end == width)
            dst[width - 1] = static_cast<std::uint8_t>((row_sums[width - 2] + 3 * row_sums[width - 1] + 8) >> 4);
    }
}

void smooth_binomial3(const cv::Mat& src_u8, std::uint16_t* row_sums, cv::Mat& dst_u8)
{
    CV_Assert(src_u8.type() == CV_8UC1 && src_u8.data != dst_u8.data);
    dst_u8.create(src_u8.size(), CV_8UC1);
    smooth_binomial3_rect(src_u8, cv::Rect(0, 0, src_u8.cols, src_u8.rows), row_sums, dst_u8);
}

int ndvi_index(int nir, int red)
{
    // (ndvi + 1) * 127.5 = 255 NIR / (NIR + R), rounded half up in integers:
    // exact, where the same sum in doubles lands just below some halves.
    const int sum = nir + red;
    return sum == 0 ? 128 : (510 * nir + sum) / (2 * sum);
}

namespace {

void ndvi_baseline(const cv::Mat& bgr, const cv::Mat& nir, cv::Mat& index_u8)
{
    const int width = bgr.cols;
    for (int y = 0; y < bgr.rows; ++y) {
        const std::uint8_t* src = bgr.ptr<std::uint8_t>(y);
        const std::uint8_t* near_infrared = nir.ptr<std::uint8_t>(y);
        std::uint8_t* dst = index_u8.ptr<std::uint8_t>(y);
        int x = 0;
#if CV_SIMD
        // The quotient in float32, as fast as lookups in a 64 KiB table on a
        // quiet core and faster when other work shares the cache. Exact: 255 NIR
        // is exact in float32, and a quotient that is not a half lies at
        // least 1 / (2 (NIR + R)) >= 1 / 1020 from one, far beyond float32's
        // rounding at 255, so adding 0.5 and truncating rounds half up as
        // ndvi_index does (checked on all 65 536 pairs in the tests). A
        // zero sum becomes 128 / 1.
        const int lanes = cv::v_uint8::nlanes;
        const cv::v_float32 full_scale = cv::vx_setall_f32(255.0f), neutral = cv::vx_setall_f32(128.0f);
        const cv::v_float32 zero = cv::vx_setzero_f32(), one = cv::vx_setall_f32(1.0f), half = cv::vx_setall_f32(0.5f);
        auto quarter = [&](const cv::v_uint32& n, const cv::v_uint32& r) {
            const cv::v_float32 near = cv::v_cvt_f32(cv::v_reinterpret_as_s32(n));
            const cv::v_float32 sum = cv::v_cvt_f32(cv::v_reinterpret_as_s32(n + r));
            const cv::v_float32 numerator = near * full_scale + ((sum == zero) & neutral);
            return cv::v_trunc(numerator / cv::v_max(sum, one) + half);
        };
        for (; x + lanes <= width; x += lanes) {
            cv::v_uint8 b, g, r;
            cv::v_load_deinterleave(src + 3 * x, b, g, r);
            cv::v_uint16 n0, n1, r0, r1;
            cv::v_expand(cv::vx_load(near_infrared + x), n0, n1);
            cv::v_expand(r, r0, r1);
            cv::v_uint32 n00, n01, n10, n11, r00, r01, r10, r11;
            cv::v_expand(n0, n00, n01);
            cv::v_expand(n1, n10, n11);
            cv::v_expand(r0, r00, r01);
            cv::v_expand(r1, r10, r11);
            const cv::v_int16 lo = cv::v_pack(quarter(n00, r00), quarter(n01, r01));
            const cv::v_int16 hi = cv::v_pack(quarter(n10, r10), quarter(n11, r11));
            cv::v_store(dst + x, cv::v_pack_u(lo, hi));
        }
#endif
        for (; x < width; ++x)
            dst[x] = static_cast<std::uint8_t>(ndvi_index(near_infrared[x], src[3 * x + 2]));
    }
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define STEMD_HAVE_SSSE3_KERNELS 1
// The same arithmetic as ndvi_baseline, in plain SSE intrinsics, with the
// red bytes of four pixels shuffled straight into 32-bit lanes: without
// SSSE3 the three-channel deinterleave and the widening take about forty
// shuffles per sixteen pixels, which bound the baseline loop (1.19 ms a
// BoniRob frame against 0.85 ms here).
__attribute__((target("ssse3"))) void ndvi_ssse3(const cv::Mat& bgr, const cv::Mat& nir, cv::Mat& index_u8)
{
    const int width = bgr.cols;
    // Byte k of the output is taken from byte pick[k] of the input, or is
    // 0 where pick[k] is -1.
    const __m128i red_of_four = _mm_setr_epi8(2, -1, -1, -1, 5, -1, -1, -1, 8, -1, -1, -1, 11, -1, -1, -1);
    const __m128i nir_of_four[4] = {
        _mm_setr_epi8(0, -1, -1, -1, 1, -1, -1, -1, 2, -1, -1, -1, 3, -1, -1, -1),
        _mm_setr_epi8(4, -1, -1, -1, 5, -1, -1, -1, 6, -1, -1, -1, 7, -1, -1, -1),
        _mm_setr_epi8(8, -1, -1, -1, 9, -1, -1, -1, 10, -1, -1, -1, 11, -1, -1, -1),
        _mm_setr_epi8(12, -1, -1, -1, 13, -1, -1, -1, 14, -1, -1, -1, 15, -1, -1, -1)};
    const __m128 full_scale = _mm_set1_ps(255.0f), neutral = _mm_set1_ps(128.0f), zero = _mm_setzero_ps();
    const __m128 one = _mm_set1_ps(1.0f), half = _mm_set1_ps(0.5f);
    const auto quarter = [&](__m128i n, __m128i r) {
        const __m128 near = _mm_cvtepi32_ps(n);
        const __m128 sum = _mm_cvtepi32_ps(_mm_add_epi32(n, r));
        const __m128 numerator = _mm_add_ps(_mm_mul_ps(near, full_scale), _mm_and_ps(_mm_cmpeq_ps(sum, zero), neutral));
        return _mm_cvttps_epi32(_mm_add_ps(_mm_div_ps(numerator, _mm_max_ps(sum, one)), half));
    };
    for (int y = 0; y < bgr.rows; ++y) {
        const std::uint8_t* src = bgr.ptr<std::uint8_t>(y);
        const std::uint8_t* near_infrared = nir.ptr<std::uint8_t>(y);
        std::uint8_t* dst = index_u8.ptr<std::uint8_t>(y);
        int x = 0;
        // Sixteen pixels a step, read as four 16-byte loads 12 bytes apart:
        // the last one ends 4 bytes past the step's 48, so two pixels (6
        // bytes) must follow it in the row.
        for (; x + 18 <= width; x += 16) {
            const __m128i n = _mm_loadu_si128(reinterpret_cast<const __m128i*>(near_infrared + x));
            __m128i q[4];
            for (int k = 0; k < 4; ++k) {
                const __m128i pixels = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + 3 * x + 12 * k));
                q[k] = quarter(_mm_shuffle_epi8(n, nir_of_four[k]), _mm_shuffle_epi8(pixels, red_of_four));
            }
            _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + x),
                             _mm_packus_epi16(_mm_packs_epi32(q[0], q[1]), _mm_packs_epi32(q[2], q[3])));
        }
        for (; x < width; ++x)
            dst[x] = static_cast<std::uint8_t>(ndvi_index(near_infrared[x], src[3 * x + 2]));
    }
}
#endif

void chromatic_excess_green_span_baseline(const cv::Mat& bgr, int y, int x_begin, int x_end, float mean_brightness,
                                          cv::Mat& index_u8)
{
    const std::uint8_t* src = bgr.ptr<std::uint8_t>(y);
    std::uint8_t* dst = index_u8.ptr<std::uint8_t>(y);
    int x = x_begin;
#if CV_SIMD
    // 2G - R - B and R + G + B in 16 bits, the quotient in float32,
    // rounded, and packed back with saturation (the clamp to [0, 255]).
    const int lanes = cv::v_uint8::nlanes;
    const cv::v_float32 mean = cv::vx_setall_f32(mean_brightness);
    const cv::v_float32 scale = cv::vx_setall_f32(160.0f);
    const cv::v_float32 neutral = cv::vx_setall_f32(128.0f);
    auto quarter = [&](const cv::v_int32& e, const cv::v_int32& s) {
        return cv::v_round(cv::v_cvt_f32(e) * scale / (cv::v_cvt_f32(s) + mean) + neutral);
    };
    auto half = [&](const cv::v_uint16& b, const cv::v_uint16& g, const cv::v_uint16& r) {
        const cv::v_int16 e = cv::v_reinterpret_as_s16(g + g) - cv::v_reinterpret_as_s16(r + b);
        const cv::v_int16 s = cv::v_reinterpret_as_s16(r + g + b);
        cv::v_int32 e0, e1, s0, s1;
        cv::v_expand(e, e0, e1);
        cv::v_expand(s, s0, s1);
        return cv::v_pack(quarter(e0, s0), quarter(e1, s1));
    };
    for (; x + lanes <= x_end; x += lanes) {
        const WideBgr p = load_wide_bgr(src + 3 * x);
        cv::v_store(dst + x, cv::v_pack_u(half(p.b0, p.g0, p.r0), half(p.b1, p.g1, p.r1)));
    }
#endif
    for (; x < x_end; ++x) {
        const float b = src[3 * x], g = src[3 * x + 1], r = src[3 * x + 2];
        const float value = 128.0f + 160.0f * (2.0f * g - r - b) / (r + g + b + mean_brightness);
        dst[x] = cv::saturate_cast<std::uint8_t>(cvRound(value));
    }
}

#if defined(STEMD_HAVE_SSSE3_KERNELS)
// The same arithmetic as the baseline span, in plain SSE intrinsics, with
// each channel of four pixels shuffled straight into 32-bit lanes (twelve
// shuffles per sixteen pixels against about forty).
__attribute__((target("ssse3"))) void chromatic_excess_green_span_ssse3(const cv::Mat& bgr, int y, int x_begin,
                                                                       int x_end, float mean_brightness,
                                                                       cv::Mat& index_u8)
{
    const std::uint8_t* src = bgr.ptr<std::uint8_t>(y);
    std::uint8_t* dst = index_u8.ptr<std::uint8_t>(y);
    const __m128i blue_of_four = _mm_setr_epi8(0, -1, -1, -1, 3, -1, -1, -1, 6, -1, -1, -1, 9, -1, -1, -1);
    const __m128i green_of_four = _mm_setr_epi8(1, -1, -1, -1, 4, -1, -1, -1, 7, -1, -1, -1, 10, -1, -1, -1);
    const __m128i red_of_four = _mm_setr_epi8(2, -1, -1, -1, 5, -1, -1, -1, 8, -1, -1, -1, 11, -1, -1, -1);
    const __m128 mean = _mm_set1_ps(mean_brightness), scale = _mm_set1_ps(160.0f), neutral = _mm_set1_ps(128.0f);
    int x = x_begin;
    // Four 16-byte loads 12 bytes apart: the last ends 4 bytes past the
    // step's 48, inside the row when two more pixels follow (they may lie
    // past x_end: they are read, not written).
    for (; x + 16 <= x_end && x + 18 <= bgr.cols; x += 16) {
        __m128i q[4];
        for (int k = 0; k < 4; ++k) {
            const __m128i pixels = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + 3 * x + 12 * k));
            const __m128i b = _mm_shuffle_epi8(pixels, blue_of_four);
            const __m128i g = _mm_shuffle_epi8(pixels, green_of_four);
            const __m128i r = _mm_shuffle_epi8(pixels, red_of_four);
            const __m128i e = _mm_sub_epi32(_mm_add_epi32(g, g), _mm_add_epi32(r, b));
            const __m128i s = _mm_add_epi32(_mm_add_epi32(r, g), b);
            const __m128 value =
                _mm_add_ps(_mm_div_ps(_mm_mul_ps(_mm_cvtepi32_ps(e), scale), _mm_add_ps(_mm_cvtepi32_ps(s), mean)),
                           neutral);
            q[k] = _mm_cvtps_epi32(value);   // to nearest, ties to even, as cvRound
        }
        _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + x),
                         _mm_packus_epi16(_mm_packs_epi32(q[0], q[1]), _mm_packs_epi32(q[2], q[3])));
    }
    if (x < x_end)
        chromatic_excess_green_span_baseline(bgr, y, x, x_end, mean_brightness, index_u8);
}
#endif

bool cpu_has_ssse3()
{
#if defined(STEMD_HAVE_SSSE3_KERNELS)
    __builtin_cpu_init();
    return __builtin_cpu_supports("ssse3");
#else
    return false;
#endif
}

// Picked once at start, never on the frame path.
const bool kSsse3 = cpu_has_ssse3();

#if !defined(STEMD_HAVE_SSSE3_KERNELS)
// No SSSE3 kernels on this architecture: kernel_available() never offers
// them, and these names stand for the baseline's so that pick() compiles.
constexpr auto& ndvi_ssse3 = ndvi_baseline;
constexpr auto& chromatic_excess_green_span_ssse3 = chromatic_excess_green_span_baseline;
#endif

Kernel best_kernel() { return kSsse3 ? Kernel::ssse3 : Kernel::baseline; }

// The implementation `kernel` names, of a baseline and SSSE3 pair.
template <class Function>
Function pick(Kernel kernel, Function baseline, Function ssse3)
{
    CV_Assert(kernel_available(kernel));
    return kernel == Kernel::ssse3 ? ssse3 : baseline;
}

}  // namespace

bool kernel_available(Kernel kernel)
{
    // Asks the CPU, not kSsse3: other files pick their kernel during static
    // initialisation, perhaps before this file's.
    return kernel == Kernel::baseline || (kernel == Kernel::ssse3 && cpu_has_ssse3());
}

void ndvi(const cv::Mat& bgr, const cv::Mat& nir, cv::Mat& index_u8, Kernel kernel)
{
    CV_Assert(bgr.type() == CV_8UC3 && nir.type() == CV_8UC1 && bgr.size() == nir.size());
    index_u8.create(bgr.size(), CV_8UC1);
    pick(kernel, &ndvi_baseline, &ndvi_ssse3)(bgr, nir, index_u8);
}

void ndvi(const cv::Mat& bgr, const cv::Mat& nir, cv::Mat& index_u8)
{
    ndvi(bgr, nir, index_u8, best_kernel());
}

void chromatic_excess_green_span(const cv::Mat& bgr, int y, int x_begin, int x_end, float mean_brightness,
                                 cv::Mat& index_u8, Kernel kernel)
{
    pick(kernel, &chromatic_excess_green_span_baseline, &chromatic_excess_green_span_ssse3)(
        bgr, y, x_begin, x_end, mean_brightness, index_u8);
}

void chromatic_excess_green_span(const cv::Mat& bgr, int y, int x_begin, int x_end, float mean_brightness,
                                 cv::Mat& index_u8)
{
    chromatic_excess_green_span(bgr, y, x_begin, x_end, mean_brightness, index_u8, best_kernel());
}

SoilColour soil_colour(const cv::Mat& bgr, const BitMask& vegetation)
{
    CV_Assert(bgr.type() == CV_8UC3 && bgr.cols == vegetation.width() && bgr.rows == vegetation.height());
    std::uint64_t sum_b = 0, sum_g = 0, sum_r = 0;
    long pixels = 0;
    for (int band = 0; band < bgr.rows; band += kBrightnessRowStep) {
        const int y = std::min(band + 4, bgr.rows - 1);
        const cv::Vec3b* px = bgr.ptr<cv::Vec3b>(y);
        for (int x = 0; x < bgr.cols; ++x) {
            if (vegetation.get(x, y))
                continue;
            sum_b += px[x][0];
            sum_g += px[x][1];
            sum_r += px[x][2];
            ++pixels;
        }
    }
    SoilColour soil;
    soil.pixels = pixels;
    if (pixels > 0) {
        const double n = static_cast<double>(pixels);
        soil.b = static_cast<double>(sum_b) / n;
        soil.g = static_cast<double>(sum_g) / n;
        soil.r = static_cast<double>(sum_r) / n;
    }
    return soil;
}

namespace {

// g / r > min_ratio * soil.g / soil.r, without a division: g * red_weight
// > r * green_weight.
struct GreenOverRed {
    float red_weight, green_weight;
    GreenOverRed(const SoilColour& soil, double min_ratio)
    {
        const bool neutral = soil.g < 1.0 || soil.r < 1.0;
        red_weight = static_cast<float>(neutral ? 1.0 : soil.r);
        green_weight = static_cast<float>(min_ratio * (neutral ? 1.0 : soil.g));
    }
    bool passes(int green, int red) const
    {
        return static_cast<float>(green) * red_weight > static_cast<float>(red) * green_weight;
    }
};

}  // namespace

namespace {

// Clears the bits of `bits` (pixels x0 .. x0 + 63 of a row) whose pixel fails.
std::uint64_t keep_passing(const cv::Vec3b* px, int x0, std::uint64_t bits, const GreenOverRed& test)
{
    visit_bits(bits, x0, [&](int x) {
        const cv::Vec3b& p = px[x];
        if (!test.passes(p[1], p[2]))
            bits &= ~(std::uint64_t{1} << (x - x0));
    });
    return bits;
}

void keep_greener_than_red_baseline(const cv::Mat& bgr, const GreenOverRed& test, BitMask& mask)
{
    for (int y = 0; y < mask.height(); ++y) {
        const cv::Vec3b* px = bgr.ptr<cv::Vec3b>(y);
        std::uint64_t* words = mask.row(y);
        for (int w = 0; w < mask.words_per_row(); ++w)
            if (words[w] != 0)
                words[w] = keep_passing(px, 64 * w, words[w], test);
    }
}

#if defined(STEMD_HAVE_SSSE3_KERNELS)
// Sixteen pixels a step wherever a step holds a set bit, with green and red
// shuffled straight into 32-bit lanes and the same float products and
// comparison as GreenOverRed::passes, instead of a walk bit by bit with a
// branch per pixel.
__attribute__((target("ssse3"))) void keep_greener_than_red_ssse3(const cv::Mat& bgr, const GreenOverRed& test,
                                                                 BitMask& mask)
{
    const __m128i green_of_four = _mm_setr_epi8(1, -1, -1, -1, 4, -1, -1, -1, 7, -1, -1, -1, 10, -1, -1, -1);
    const __m128i red_of_four = _mm_setr_epi8(2, -1, -1, -1, 5, -1, -1, -1, 8, -1, -1, -1, 11, -1, -1, -1);
    const __m128 red_weight = _mm_set1_ps(test.red_weight), green_weight = _mm_set1_ps(test.green_weight);
    const int width = bgr.cols;
    for (int y = 0; y < mask.height(); ++y) {
        const cv::Vec3b* px = bgr.ptr<cv::Vec3b>(y);
        const auto* src = reinterpret_cast<const std::uint8_t*>(px);
        std::uint64_t* words = mask.row(y);
        for (int w = 0; w < mask.words_per_row(); ++w) {
            const std::uint64_t bits = words[w];
            if (bits == 0)
                continue;
            const int x0 = 64 * w;
            // Four 16-byte loads 12 bytes apart read two pixels past a step.
            if (x0 + 64 + 2 > width) {
                words[w] = keep_passing(px, x0, bits, test);
                continue;
            }
            std::uint64_t passing = 0;
            for (int step = 0; step < 4; ++step) {
                if (((bits >> (16 * step)) & 0xFFFF) == 0)
                    continue;
                std::uint64_t step_bits = 0;
                for (int k = 0; k < 4; ++k) {
                    const __m128i pixels =
                        _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + 3 * (x0 + 16 * step) + 12 * k));
                    const __m128 green = _mm_cvtepi32_ps(_mm_shuffle_epi8(pixels, green_of_four));
                    const __m128 red = _mm_cvtepi32_ps(_mm_shuffle_epi8(pixels, red_of_four));
                    const int pass = _mm_movemask_ps(_mm_cmpgt_ps(_mm_mul_ps(green, red_weight), _mm_mul_ps(red, green_weight)));
                    step_bits |= static_cast<std::uint64_t>(pass) << (4 * k);
                }
                passing |= step_bits << (16 * step);
            }
            words[w] = bits & passing;
        }
    }
}
#else
constexpr auto& keep_greener_than_red_ssse3 = keep_greener_than_red_baseline;
#endif

}  // namespace

void keep_greener_than_red(const cv::Mat& bgr, const SoilColour& soil, double min_ratio, BitMask& mask, Kernel kernel)
{
    pick(kernel, &keep_greener_than_red_baseline, &keep_greener_than_red_ssse3)(bgr, GreenOverRed(soil, min_ratio),
                                                                                mask);
}

void keep_greener_than_red(const cv::Mat& bgr, const SoilColour& soil, double min_ratio, BitMask& mask)
{
    keep_greener_than_red(bgr, soil, min_ratio, mask, best_kernel());
}

int drop_colour_fringes(const cv::Mat& bgr, const SoilColour& soil, double min_ratio, const LabelScratch& components,
                        std::vector<std::uint8_t>& keep, std::vector<std::uint8_t>& passed)
{
    CV_Assert(bgr.type() == CV_8UC3);
    const GreenOverRed test(soil, min_ratio);
    constexpr std::uint8_t kEveryDirection = 0xFF;
    passed.assign(keep.size(), 0);
    const int width = bgr.cols, height = bgr.rows;
    for (std::size_t i = 0; i < components.run_count(); ++i) {
        const LabelScratch::LabelledRun run = components.run(i);
        const auto c = static_cast<std::size_t>(run.component);
        if (c >= keep.size() || !keep[c] || passed[c] == kEveryDirection)
            continue;   // a leaf shows its own green within its first pixels
        const cv::Vec3b* up = bgr.ptr<cv::Vec3b>(std::max(run.y - 1, 0));
        const cv::Vec3b* row = bgr.ptr<cv::Vec3b>(run.y);
        const cv::Vec3b* down = bgr.ptr<cv::Vec3b>(std::min(run.y + 1, height - 1));
        std::uint8_t bits = passed[c];
        for (int x = run.x0; x <= run.x1 && bits != kEveryDirection; ++x) {
            const int red = row[x][2];
            const int left = std::max(x - 1, 0), right = std::min(x + 1, width - 1);
            // The green plane slid by (dx, dy): this pixel's red against
            // the green of its neighbour at (-dx, -dy).
            const int greens[8] = {up[left][1], up[x][1],  up[right][1],  row[left][1],
                                   row[right][1], down[left][1], down[x][1], down[right][1]};
            for (int k = 0; k < 8; ++k)
                if (test.passes(greens[k], red))
                    bits = static_cast<std::uint8_t>(bits | (1u << k));
        }
        passed[c] = bits;
    }
    int dropped = 0;
    for (std::size_t c = 0; c < keep.size(); ++c)
        if (keep[c] && passed[c] != kEveryDirection) {
            keep[c] = 0;
            ++dropped;
        }
    return dropped;
}

}  // namespace stemd::vision
