// Plants drawn from a preset, and placed without overlap in one frame.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "plant.hpp"
#include "presets.hpp"
#include "random.hpp"

namespace stemd::synth {

// A rosette (crop or weed) of spec's radius and leaf count.
Plant make_rosette(PlantClass plant_class, const PlantClassSpec& spec, double px_per_mm, Rng& rng);
// A tuft: thin tapering blades fanned around one direction, no stem.
Plant make_grass_tuft(const PlantClassSpec& spec, double px_per_mm, Rng& rng);
// A frame's plants, their stems inside `size`; see place_plant().
std::vector<Plant> make_layout(const PresetSpec& spec, cv::Size size, double px_per_mm, Rng& rng);

}  // namespace stemd::synth
