#include "stemd/vision/run_colour.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
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

// A row's vegetation bits, each pixel set with probability `density`.
std::vector<std::uint64_t> random_vegetation(int width, double density, cv::RNG& rng)
{
    std::vector<std::uint64_t> bits(static_cast<std::size_t>((width + 63) / 64), 0);
    for (int x = 0; x < width; ++x)
        if (rng.uniform(0.0, 1.0) < density)
            bits[static_cast<std::size_t>(x >> 6)] |= std::uint64_t{1} << (x & 63);
    return bits;
}

// Cells already holding earlier rows' samples.
std::vector<CellSamples> earlier_rows(std::size_t cells, cv::RNG& rng)
{
    std::vector<CellSamples> out(cells);
    for (CellSamples& c : out) {
        c.sampled_px = rng.uniform(0, 1000);
        for (float* v : {&c.r, &c.g, &c.rr, &c.gg, &c.brightness, &c.gradient, &c.sxx, &c.syy, &c.sxy, &c.ndvi,
                         &c.ndvi2})
            *v = rng.uniform(-500.0f, 500.0f);
        c.plant_vote = static_cast<std::uint16_t>(rng.uniform(0, 4));
        c.plant_count = static_cast<std::uint16_t>(rng.uniform(0, 5));
    }
    return out;
}

void expect_same_bits(const CellSamples& a, const CellSamples& b, const std::string& where)
{
    EXPECT_EQ(a.sampled_px, b.sampled_px) << where;
    EXPECT_EQ(a.plant_vote, b.plant_vote) << where;
    EXPECT_EQ(a.plant_count, b.plant_count) << where;
    const std::array<std::pair<float, float>, 11> floats{{{a.r, b.r},
                                                          {a.g, b.g},
                                                          {a.rr, b.rr},
                                                          {a.gg, b.gg},
                                                          {a.brightness, b.brightness},
                                                          {a.gradient, b.gradient},
                                                          {a.sxx, b.sxx},
                                                          {a.syy, b.syy},
                                                          {a.sxy, b.sxy},
                                                          {a.ndvi, b.ndvi},
                                                          {a.ndvi2, b.ndvi2}}};
    for (std::size_t i = 0; i < floats.size(); ++i)
        EXPECT_EQ(std::bit_cast<std::uint32_t>(floats[i].first), std::bit_cast<std::uint32_t>(floats[i].second))
            << where << " sum " << i << ": " << floats[i].first << " vs " << floats[i].second;
}

TEST(CellSamples, KernelsGiveTheSameBitsForEveryRow)
{
    if (!kernel_available(Kernel::ssse3))
        GTEST_SKIP() << "this CPU has no SSSE3: only the baseline kernel runs";
    cv::RNG rng(11);
    std::vector<int> widths;
    for (int w = 1; w <= 100; ++w)
        widths.push_back(w);
    widths.push_back(1296);
    for (const int width : widths)
        for (const double density : {0.1, 0.5, 0.9, 1.0})
            for (const bool with_nir : {false, true}) {
                const Rows rows = random_rows(width, rng);
                const std::vector<std::uint64_t> vegetation = random_vegetation(width, density, rng);
                // Cells of 2-40 px, and plants in runs, as on a frame.
                const int cell_px = rng.uniform(2, 41);
                std::vector<std::uint16_t> cell_of(static_cast<std::size_t>(width)), plant_of(cell_of.size());
                std::uint16_t plant = 0;
                for (int x = 0; x < width; ++x) {
                    cell_of[static_cast<std::size_t>(x)] = static_cast<std::uint16_t>(x / cell_px);
                    if (rng.uniform(0, 6) == 0)
                        plant = static_cast<std::uint16_t>(rng.uniform(0, 4));
                    plant_of[static_cast<std::size_t>(x)] = plant;
                }
                const std::vector<CellSamples> before = earlier_rows(static_cast<std::size_t>(width / cell_px + 1), rng);
                std::vector<CellSamples> baseline = before, vector = before;
                add_cell_samples(rows.view(with_nir), vegetation.data(), cell_of.data(), plant_of.data(),
                                 baseline.data(), Kernel::baseline);
                add_cell_samples(rows.view(with_nir), vegetation.data(), cell_of.data(), plant_of.data(),
                                 vector.data(), Kernel::ssse3);
                for (std::size_t c = 0; c < baseline.size(); ++c)
                    expect_same_bits(baseline[c], vector[c],
                                     "width " + std::to_string(width) + ", density " + std::to_string(density) +
                                         ", nir " + std::to_string(with_nir) + ", cell " + std::to_string(c));
                if (::testing::Test::HasFailure())
                    return;
            }
}

TEST(CellSamples, EachCellSumsEveryFourthVegetationPixelAsDefined)
{
    cv::RNG rng(12);
    for (const int width : {1, 7, 40, 97}) {
        const Rows rows = random_rows(width, rng);
        const std::vector<std::uint64_t> vegetation = random_vegetation(width, 0.7, rng);
        const int cell_px = 12;
        const std::size_t cells = static_cast<std::size_t>(width / cell_px + 1);
        std::vector<std::uint16_t> cell_of(static_cast<std::size_t>(width)), plant_of(cell_of.size());
        for (int x = 0; x < width; ++x) {
            cell_of[static_cast<std::size_t>(x)] = static_cast<std::uint16_t>(x / cell_px);
            plant_of[static_cast<std::size_t>(x)] = x % 12 < 8 ? 5 : 6;   // plant 5 holds the most of every cell
        }
        for (const bool with_nir : {false, true}) {
            std::vector<std::array<double, 11>> expected(cells, std::array<double, 11>{});
            std::vector<int> count(cells, 0), plant5(cells, 0);
            const auto s = [&](const std::vector<cv::Vec3b>& row, int x) {
                const cv::Vec3b& p = row[static_cast<std::size_t>(std::clamp(x, 0, width - 1))];
                return p[0] + p[1] + p[2];
            };
            for (int x = 0; x < width; x += 4) {
                if (((vegetation[static_cast<std::size_t>(x >> 6)] >> (x & 63)) & 1u) == 0)
                    continue;
                const std::size_t c = cell_of[static_cast<std::size_t>(x)];
                ++count[c];
                plant5[c] += plant_of[static_cast<std::size_t>(x)] == 5;
                const cv::Vec3b& p = rows.here[static_cast<std::size_t>(x)];
                const int sum = s(rows.here, x);
                const double r = sum > 0 ? p[2] / double(sum) : 0, g = sum > 0 ? p[1] / double(sum) : 0;
                const double gx = s(rows.here, x + 1) - s(rows.here, x - 1), gy = s(rows.down, x) - s(rows.up, x);
                const int nv = rows.nir[static_cast<std::size_t>(x)];
                const double ndvi = with_nir && nv + p[2] > 0 ? double(nv - p[2]) / double(nv + p[2]) : 0;
                const std::array<double, 11> v{r, g, r * r, g * g, double(sum), std::abs(gx) + std::abs(gy),
                                               gx * gx, gy * gy, gx * gy, ndvi, ndvi * ndvi};
                for (std::size_t k = 0; k < v.size(); ++k)
                    expected[c][k] += v[k];
            }
            for (const Kernel kernel : kKernels) {
                if (!kernel_available(kernel))
                    continue;
                std::vector<CellSamples> got(cells);
                add_cell_samples(rows.view(with_nir), vegetation.data(), cell_of.data(), plant_of.data(), got.data(),
                                 kernel);
                for (std::size_t c = 0; c < cells; ++c) {
                    const CellSamples& a = got[c];
                    const std::array<float, 11> sums{a.r,   a.g,   a.rr,  a.gg,   a.brightness, a.gradient,
                                                     a.sxx, a.syy, a.sxy, a.ndvi, a.ndvi2};
                    EXPECT_EQ(a.sampled_px, count[c]) << "width " << width << ", cell " << c;
                    for (std::size_t k = 0; k < sums.size(); ++k)
                        EXPECT_NEAR(sums[k], expected[c][k], 1e-5 * std::max(1.0, std::abs(expected[c][k])))
                            << "width " << width << ", nir " << with_nir << ", cell " << c << ", sum " << k;
                    // With plant 5 on most of the samples, the vote ends on it.
                    if (2 * plant5[c] > count[c]) {
                        EXPECT_EQ(a.plant_vote, 5) << "width " << width << ", cell " << c;
                    }
                }
            }
        }
    }
}

}  // namespace
}  // namespace stemd::vision
