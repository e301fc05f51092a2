// What frames and strips share: the option checks and the ground under
// the plants.
#pragma once

#include "plant_render.hpp"
#include "presets.hpp"
#include "random.hpp"
#include "stemd/synth/synth.hpp"

namespace stemd::synth {

// Throws std::invalid_argument as generate_frame documents.
void validate(const Options& options, int frame_index);

// Soil, clods and stones into the canvas's colour and NIR, and the leaf
// texture the plants will be drawn with.
void render_ground(Canvas& canvas, const PresetSpec& spec, double px_per_mm, Rng& soil);

}  // namespace stemd::synth
