#include "stemd/vision/run_colour.hpp"

#include <array>
#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace stemd::vision {
namespace {

// Three rows and a NIR row, each its own allocation of exactly `width`
// pixels, so that a sanitizer build catches a read past a row's end.
struct Rows {
    std::vector<cv::Vec3b> up, here, down;
    std::vector<std::uint8_t> nir;

    ColourRows view(bool with_nir) const
    {
        return {here.data(), up.data(), down.data(), with_nir ? nir.data() : nullptr, static_cast<int>(here.size())};
    }
};

// Random pixels, one in eight black and one in eight with NIR and red both
// 0, where the reciprocals are 0.
Rows random_rows(int width, cv::RNG& rng)
{
    Rows rows{std::vector<cv::Vec3b>(static_cast<std::size_t>(width)),
              std::vector<cv::Vec3b>(static_cast<std::size_t>(width)),
              std::vector<cv::Vec3b>(static_cast<std::size_t>(width)),
              std::vector<std::uint8_t>(static_cast<std::size_t>(width))};
    for (std::vector<cv::Vec3b>* row : {&rows.up, &rows.here, &rows.down})
        for (cv::Vec3b& p : *row)
            p = rng.uniform(0, 8) == 0 ? cv::Vec3b(0, 0, 0)
                                       : cv::Vec3b(static_cast<std::uint8_t>(rng.uniform(0, 256)),
                                                   static_cast<std::uint8_t>(rng.uniform(0, 256)),
                                                   static_cast<std::uint8_t>(rng.uniform(0, 256)));
    for (std::size_t x = 0; x < rows.nir.size(); ++x) {
        if (rng.uniform(0, 8) == 0) {
            rows.nir[x] = 0;
            rows.here[x][2] = 0;
        } else {
            rows.nir[x] = static_cast<std::uint8_t>(rng.uniform(0, 256));
        }
    }
    return rows;
}

// Sums already holding other runs' values, so that a kernel must carry on
// from them rather than start from 0.
RunColour earlier_runs(cv::RNG& rng)
{
    RunColour c;
    c.brightness = rng.uniform(0, 100000);
    c.gradient = rng.uniform(0, 100000);
    c.r = rng.uniform(0.0f, 500.0f);
    c.g = rng.uniform(0.0f, 500.0f);
    c.b = rng.uniform(0.0f, 500.0f);
    c.rr = rng.uniform(0.0f, 200.0f);
    c.gg = rng.uniform(0.0f, 200.0f);
    c.ndvi = rng.uniform(-100.0f, 100.0f);
    c.ndvi2 = rng.uniform(0.0f, 100.0f);
    return c;
}

void expect_same_bits(const RunColour& a, const RunColour& b, const char* where)
{
    EXPECT_EQ(a.brightness, b.brightness) << where;
    EXPECT_EQ(a.gradient, b.gradient) << where;
    const std::array<std::pair<float, float>, 7> floats{
        {{a.r, b.r}, {a.g, b.g}, {a.b, b.b}, {a.rr, b.rr}, {a.gg, b.gg}, {a.ndvi, b.ndvi}, {a.ndvi2, b.ndvi2}}};
    for (std::size_t i = 0; i < floats.size(); ++i)
        EXPECT_EQ(std::bit_cast<std::uint32_t>(floats[i].first), std::bit_cast<std::uint32_t>(floats[i].second))
            << where << " sum " << i << ": " << floats[i].first << " vs " << floats[i].second;
}

TEST(RunColour, TheReciprocalTableHoldsWhatDivisionGivesAtRunTime)
{
    // volatile: the divisions below run on this machine, not in the compiler.
    volatile float one = 1.0f;
    EXPECT_EQ(kColourReciprocal[0], 0.0f);
    for (int i = 1; i < kColourReciprocals; ++i)
        ASSERT_EQ(std::bit_cast<std::uint32_t>(kColourReciprocal[static_cast<std::size_t>(i)]),
                  std::bit_cast<std::uint32_t>(one / static_cast<float>(i)))
            << "1 / " << i;
}

TEST(RunColour, SumsFollowTheirDefinitionsWithTheRowEndsAsTheirOwnNeighbours)
{
    cv::RNG rng(5);
    for (const int width : {1, 2, 5, 23}) {
        const Rows rows = random_rows(width, rng);
        for (const bool with_nir : {false, true}) {
            double r = 0, g = 0, b = 0, rr = 0, gg = 0, ndvi = 0, ndvi2 = 0;
            long brightness = 0, gradient = 0;
            const auto s = [&](const std::vector<cv::Vec3b>& row, int x) {
                const cv::Vec3b& p = row[static_cast<std::size_t>(std::clamp(x, 0, width - 1))];
                return p[0] + p[1] + p[2];
            };
            for (int x = 0; x < width; ++x) {
                const cv::Vec3b& p = rows.here[static_cast<std::size_t>(x)];
                const int sum = s(rows.here, x);
                brightness += sum;
                gradient += std::abs(s(rows.here, x + 1) - s(rows.here, x - 1)) +
                            std::abs(s(rows.down, x) - s(rows.up, x));
                if (sum > 0) {
                    r += p[2] / double(sum);
                    g += p[1] / double(sum);
                    b += p[0] / double(sum);
                    rr += (p[2] / double(sum)) * (p[2] / double(sum));
                    gg += (p[1] / double(sum)) * (p[1] / double(sum));
                }
                const int nv = rows.nir[static_cast<std::size_t>(x)];
                if (with_nir && nv + p[2] > 0) {
                    const double v = double(nv - p[2]) / double(nv + p[2]);
                    ndvi += v;
                    ndvi2 += v * v;
                }
            }
            for (const Kernel kernel : kKernels) {
                if (!kernel_available(kernel))
                    continue;
                RunColour c;
                add_vegetation_run(rows.view(with_nir), 0, width, c, kernel);
                EXPECT_EQ(c.brightness, brightness) << "width " << width;
                EXPECT_EQ(c.gradient, gradient) << "width " << width;
                EXPECT_NEAR(c.r, r, 1e-4) << "width " << width;
                EXPECT_NEAR(c.g, g, 1e-4);
                EXPECT_NEAR(c.b, b, 1e-4);
                EXPECT_NEAR(c.rr, rr, 1e-4);
                EXPECT_NEAR(c.gg, gg, 1e-4);
                EXPECT_NEAR(c.ndvi, ndvi, 1e-4) << "nir " << with_nir;
                EXPECT_NEAR(c.ndvi2, ndvi2, 1e-4);
            }
        }
    }
}

TEST(RunColour, KernelsGiveTheSameBitsForEveryRun)
{
    if (!kernel_available(Kernel::ssse3))
        GTEST_SKIP() << "this CPU lacks SSSE3: only the baseline runs here";
    cv::RNG rng(17);
    char where[96];
    // Every run of rows up to 40 pixels wide, around the four-pixel steps,
    // the step's look-ahead and the row's ends.
    for (int width = 1; width <= 40; ++width) {
        const Rows rows = random_rows(width, rng);
        for (const bool with_nir : {false, true})
            for (int x_start = 0; x_start <= width; ++x_start)
                for (int x_stop = x_start; x_stop <= width; ++x_stop) {
                    const RunColour earlier = earlier_runs(rng);
                    RunColour baseline = earlier, vector = earlier;
                    add_vegetation_run(rows.view(with_nir), x_start, x_stop, baseline, Kernel::baseline);
                    add_vegetation_run(rows.view(with_nir), x_start, x_stop, vector, Kernel::ssse3);
                    std::snprintf(where, sizeof where, "width %d, run [%d, %d), nir %d", width, x_start, x_stop,
                                  int{with_nir});
                    expect_same_bits(baseline, vector, where);
                    if (::testing::Test::HasFailure())
                        return;
                }
    }
    // A camera's row, with random runs.
    const int width = 1296;
    const Rows rows = random_rows(width, rng);
    for (int k = 0; k < 2000; ++k) {
        const int a = rng.uniform(0, width + 1), b = rng.uniform(0, width + 1);
        const bool with_nir = (k & 1) != 0;
        const RunColour earlier = earlier_runs(rng);
        RunColour baseline = earlier, vector = earlier;
        add_vegetation_run(rows.view(with_nir), std::min(a, b), std::max(a, b), baseline, Kernel::baseline);
        add_vegetation_run(rows.view(with_nir), std::min(a, b), std::max(a, b), vector, Kernel::ssse3);
        std::snprintf(where, sizeof where, "width %d, run [%d, %d), nir %d", width, std::min(a, b), std::max(a, b),
                      int{with_nir});
        expect_same_bits(baseline, vector, where);
        if (::testing::Test::HasFailure())
            return;
    }
}

}  // namespace
}  // namespace stemd::vision
