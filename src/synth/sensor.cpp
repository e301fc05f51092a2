#include "sensor.hpp"

#include <algorithm>
#include <cmath>

namespace stemd::synth {
namespace {

// Approximately Gaussian noise from the sum of four random bytes (mean 510,
// standard deviation 147.8), in integers so it is exact everywhere.
void add_sensor_noise(cv::Mat& image, double sigma, Rng& rng)
{
    const std::int64_t scale_q16 = std::llround(sigma / 147.8 * 65536);
    std::uint64_t bits = 0;
    int bytes_left = 0;
    auto sample = [&] {
        if (bytes_left == 0)
            bits = rng.bits(), bytes_left = 8;
        int sum = 0;
        for (int i = 0; i < 4; ++i, bits >>= 8)
            sum += static_cast<int>(bits & 0xFF);
        bytes_left -= 4;
        return static_cast<int>(((sum - 510) * scale_q16 + (1 << 15)) >> 16);
    };
    const int values_per_row = image.cols * image.channels();
    for (int y = 0; y < image.rows; ++y) {
        std::uint8_t* row = image.ptr<std::uint8_t>(y);
        for (int i = 0; i < values_per_row; ++i)
            row[i] = cv::saturate_cast<std::uint8_t>(row[i] + sample());
    }
}

// A camera of its own: one exposure, colour saturation (a dull colour
// matrix, as on BoniRob's camera) and colour cast per frame,
// a radial vignetting falloff, red and blue planes one pixel off the green
// one horizontally (lateral chromatic aberration: coloured fringes at every
// edge), then sensor noise that grows as the gain lowers the signal.
void apply_real_camera(cv::Mat& bgr, cv::Mat& nir, Rng& rng)
{
    const double exposure = rng.uniform(0.55, 1.25);
    const double cast[3] = {rng.uniform(0.85, 1.15), rng.uniform(0.9, 1.1), rng.uniform(0.85, 1.15)};
    const double vignetting = rng.uniform(0.15, 0.35);
    const double saturation = rng.uniform(0.4, 0.7);
    const double cx = (bgr.cols - 1) / 2.0, cy = (bgr.rows - 1) / 2.0;
    const double r2_max = cx * cx + cy * cy;
    const cv::Mat source = bgr.clone();
    for (int y = 0; y < bgr.rows; ++y) {
        const auto* in = source.ptr<cv::Vec3b>(y);
        auto* out = bgr.ptr<cv::Vec3b>(y);
        std::uint8_t* near_infrared = nir.ptr<std::uint8_t>(y);
        for (int x = 0; x < bgr.cols; ++x) {
            const double r2 = ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / r2_max;
            const double light = exposure * (1 - vignetting * r2);
            const int from_blue = std::min(x + 1, bgr.cols - 1), from_red = std::max(x - 1, 0);
            const double b = in[from_blue][0], g = in[x][1], r = in[from_red][2];
            const double grey = (b + g + r) / 3;
            auto channel = [&](double v, double gain) {
                return cv::saturate_cast<std::uint8_t>((grey + saturation * (v - grey)) * light * gain);
            };
            out[x] = cv::Vec3b(channel(b, cast[0]), channel(g, cast[1]), channel(r, cast[2]));
            near_infrared[x] = cv::saturate_cast<std::uint8_t>(near_infrared[x] * light);
        }
    }
    add_sensor_noise(bgr, 2.5 / std::sqrt(exposure), rng);
    add_sensor_noise(nir, 2.0 / std::sqrt(exposure), rng);
}

}  // namespace

void apply_camera(const PresetSpec& spec, cv::Mat& bgr, cv::Mat& nir, Rng camera, Rng sensor)
{
    if (spec.real_camera) {
        apply_real_camera(bgr, nir, camera);
        return;
    }
    add_sensor_noise(bgr, 2.5, sensor);
    add_sensor_noise(nir, 2.0, sensor);
}

}  // namespace stemd::synth
