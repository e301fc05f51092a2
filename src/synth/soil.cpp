#include "soil.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include <opencv2/imgproc.hpp>

#include "polygon.hpp"

namespace stemd::synth {

void add_value_noise(std::vector<float>& field, cv::Size size, double cell_px, float amplitude, Rng& rng)
{
    cell_px = std::max(cell_px, 2.0);
    const int grid_w = static_cast<int>((size.width - 1) / cell_px) + 2;
    const int grid_h = static_cast<int>((size.height - 1) / cell_px) + 2;
    std::vector<float> grid(static_cast<std::size_t>(grid_w) * grid_h);
    for (float& g : grid)
        g = static_cast<float>(rng.uniform(-1, 1));
    auto smooth = [](double f) { return static_cast<float>(f * f * (3 - 2 * f)); };
    std::vector<int> ix(size.width);
    std::vector<float> fx(size.width);
    for (int x = 0; x < size.width; ++x) {
        ix[x] = static_cast<int>(x / cell_px);
        fx[x] = smooth(x / cell_px - ix[x]);
    }
    std::vector<float> row(grid_w);
    for (int y = 0; y < size.height; ++y) {
        const int iy = static_cast<int>(y / cell_px);
        const float fy = smooth(y / cell_px - iy);
        for (int j = 0; j < grid_w; ++j)
            row[j] = grid[iy * grid_w + j] * (1 - fy) + grid[(iy + 1) * grid_w + j] * fy;
        float* out = field.data() + static_cast<std::size_t>(y) * size.width;
        for (int x = 0; x < size.width; ++x)
            out[x] += amplitude * (row[ix[x]] * (1 - fx[x]) + row[ix[x] + 1] * fx[x]);
    }
}

void render_soil_texture(cv::Mat& bgr, cv::Mat& nir, double px_per_mm, double brightness, Rng& rng)
{
    const cv::Size size = bgr.size();
    const std::size_t n = static_cast<std::size_t>(size.area());
    // Brightness at several scales (lumps to grains), and moisture patches.
    std::vector<float> light(n, 0.0f), moisture(n, 0.0f);
    constexpr std::array<double, 5> kCellMm{45, 15, 5, 1.6, 0.7};
    constexpr std::array<float, 5> kAmplitude{0.25f, 0.2f, 0.2f, 0.18f, 0.12f};
    for (std::size_t i = 0; i < kCellMm.size(); ++i)
        add_value_noise(light, size, kCellMm[i] * px_per_mm, kAmplitude[i], rng);
    add_value_noise(moisture, size, 80 * px_per_mm, 1.0f, rng);
    const cv::Vec3d base = cv::Vec3d{rng.uniform(55, 70), rng.uniform(85, 100), rng.uniform(115, 135)} * brightness;
    for (int y = 0; y < size.height; ++y) {
        auto* colour = bgr.ptr<cv::Vec3b>(y);
        std::uint8_t* near_infrared = nir.ptr<std::uint8_t>(y);
        for (int x = 0; x < size.width; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * size.width + x;
            const double l = 1 + 0.22 * light[i];
            const double m = 0.5 + 0.5 * moisture[i];   // wet soil: darker, a little redder
            colour[x] = cv::Vec3b(cv::saturate_cast<std::uint8_t>(base[0] * l * (1 - 0.25 * m)),
                                  cv::saturate_cast<std::uint8_t>(base[1] * l * (1 - 0.2 * m)),
                                  cv::saturate_cast<std::uint8_t>(base[2] * l * (1 - 0.15 * m)));
            near_infrared[x] = cv::saturate_cast<std::uint8_t>(std::clamp(80 + 22 * light[i] - 12 * m, 50.0, 110.0));
        }
    }
}

void render_clods_and_stones(cv::Mat& bgr, cv::Mat& nir, double px_per_mm, double clods_per_m2, double stones_per_m2,
                             Rng& rng)
{
    const double area_mm2 = bgr.size().area() / (px_per_mm * px_per_mm);
    const int clods = static_cast<int>(area_mm2 * clods_per_m2 / 1e6);
    const int stones = static_cast<int>(area_mm2 * stones_per_m2 / 1e6);
    const cv::Size size = bgr.size();
    for (int i = 0; i < clods + stones; ++i) {
        const bool stone = i >= clods;
        const cv::Point2d centre{rng.uniform(0, size.width - 1), rng.uniform(0, size.height - 1)};
        const double radius_px = (stone ? rng.uniform(1, 5) : rng.uniform(1, 4.5)) * px_per_mm;
        const double aspect = rng.uniform(0.5, 1.0), angle_rad = rng.uniform(0, std::numbers::pi);
        const Polygon body = circle_polygon(centre, radius_px, radius_px * aspect, angle_rad, 24);
        cv::Scalar colour, nir_value;
        if (stone) {
            const double grey = rng.uniform(110, 170);
            colour = {grey * 0.92, grey * 0.97, grey};
            nir_value = cv::Scalar(70 + 0.25 * grey);
        } else {
            const double dark = rng.uniform(0.55, 0.8);
            colour = {65 * dark, 88 * dark, 112 * dark};
            nir_value = cv::Scalar(rng.uniform(50, 70));
        }
        fill(bgr, body, {0, 0}, colour, cv::LINE_AA);
        fill(nir, body, {0, 0}, nir_value, cv::LINE_AA);
        const cv::Point2d lit = centre - cv::Point2d(0.25, 0.25) * radius_px;
        fill(bgr, circle_polygon(lit, radius_px * 0.6, radius_px * 0.6 * aspect, angle_rad, 16), {0, 0},
             colour * 1.15, cv::LINE_AA);
    }
}

}  // namespace stemd::synth
