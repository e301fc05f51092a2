// What each preset draws: plant counts and sizes, soil and camera.
#pragma once

#include "stemd/synth/synth.hpp"

namespace stemd::synth {

struct Range {
    double lo = 0, hi = 0;
};
struct IntRange {
    int lo = 0, hi = 0;
};
struct PlantClassSpec {
    IntRange count;
    Range radius_mm;   // stem to tip of the longest leaf (grass: longest blade)
    IntRange leaves;   // grass: blades per tuft
};
struct PresetSpec {
    PlantClassSpec crop, weed, grass;
    double fragmentation = 0;
    double soil_brightness = 1;   // times the soil's base colour
    double clods_per_m2 = 500;
    double stones_per_m2 = 250;
    bool real_camera = false;     // exposure, colour cast, vignetting, fringes, gain noise
    // How far two plants' extents may overlap, as a share of their sum: 0
    // keeps a gap between them, 0.5 lets stems come to half their summed
    // extents, so leaves lie over leaves.
    double overlap = 0;
};

// Counts are per frame (the paper's field of view is ~428 x 319 mm); plants
// that do not fit are shrunk, see layout.cpp.
PresetSpec preset_spec(Preset preset);

}  // namespace stemd::synth
