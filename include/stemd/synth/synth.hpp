// Synthetic field frames: a sugar-beet field seen by a downward camera,
// with ground-truth stems, for tests, the benchmark, accuracy evaluation and
// the demo. Plants are rosettes of petiole + blade leaves of unequal length
// at irregular angles, so that the outline has concavities between leaves
// (what the leaf cutting relies on) and the centre of mass is not the stem
// (what makes the stem estimate worth having).
//
// Pixel convention: pixel centres at integer coordinates, x right, y down;
// ground-truth stems are sub-pixel.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace stemd::synth {

// Echo the paper's datasets: early = B (small crops, tiny weeds),
// late = A (few medium crops, scattered weeds), dense = C (many crops,
// weeds, grass tufts, fragmented masks).
enum class Preset { early, late, dense };

std::optional<Preset> parse_preset(std::string_view name);
std::string_view to_string(Preset preset);

// Plant counts are per frame whatever the size (the presets are made for
// the default ~428 x 319 mm view); a plant that finds no room is shrunk and
// in the end left out. Stems are always placed inside the image; leaves
// may cross the border.
struct Options {
    Preset preset = Preset::late;
    std::uint64_t seed = 1;
    int width_px = 1296;
    int height_px = 966;
    double gsd_mm_per_px = 0.33;   // ground sampling distance
    double fragmentation = -1;     // < 0: the preset's default; else 0..1
};

struct GroundTruthStem {
    double x_px = 0;
    double y_px = 0;
    std::string kind;       // "crop" | "weed"
    int leaves = 0;
    // Extras for evaluation and tests, from the pixels this plant put into
    // the mask (inside the image, after fragmentation).
    double radius_mm = 0;   // stem to the farthest point of a leaf
    int area_px = 0;
    double mass_x_px = 0;   // centre of mass of those pixels
    double mass_y_px = 0;
};

struct Frame {
    cv::Mat bgr;    // CV_8UC3
    cv::Mat nir;    // CV_8UC1
    cv::Mat mask;   // CV_8UC1, 255 = vegetation (crops, weeds and grass)
    std::vector<GroundTruthStem> stems;   // stems inside the image; grass has none
};

// Deterministic in (options, frame_index): the same bytes on every run.
// Throws std::invalid_argument for sizes < 16 px, gsd_mm_per_px not in
// (0, 100], fragmentation > 1 or frame_index < 0.
Frame generate_frame(const Options& options, int frame_index);

}  // namespace stemd::synth
