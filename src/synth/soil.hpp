// The ground under the plants: soil texture, clods and stones.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "random.hpp"

namespace stemd::synth {

// Smoothed value noise: a random grid of cell_px, bilinearly interpolated
// with a smoothstep weight, added to `field` times `amplitude`. Our own
// interpolation (not cv::resize) keeps it bit-exact on any CPU.
void add_value_noise(std::vector<float>& field, cv::Size size, double cell_px, float amplitude, Rng& rng);
// Soil colour and NIR over the whole image: brightness at several scales,
// moisture patches; `brightness` times the soil's base colour.
void render_soil_texture(cv::Mat& bgr, cv::Mat& nir, double px_per_mm, double brightness, Rng& rng);
// Dark clods with a lit top-left rim, and greyish stones; counts scale
// with the ground area so the texture density does not depend on size.
void render_clods_and_stones(cv::Mat& bgr, cv::Mat& nir, double px_per_mm, double clods_per_m2, double stones_per_m2,
                             Rng& rng);

}  // namespace stemd::synth
