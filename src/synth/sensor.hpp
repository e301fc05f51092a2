// The camera after the optics: sensor noise, or a real camera's exposure,
// colour cast, vignetting, colour fringes and gain noise.
#pragma once

#include <opencv2/core.hpp>

#include "presets.hpp"
#include "random.hpp"

namespace stemd::synth {

// The preset's camera: a real one, or only sensor noise.
void apply_camera(const PresetSpec& spec, cv::Mat& bgr, cv::Mat& nir, Rng camera, Rng sensor);

}  // namespace stemd::synth
