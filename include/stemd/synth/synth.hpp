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
#include <opencv2/core/types.hpp>

#include "stemd/base/plant_class.hpp"

namespace stemd::synth {

// Echo the paper's datasets: early = B (small crops, tiny weeds),
// late = A (few medium crops, scattered weeds), dense = C (many crops,
// weeds, grass tufts, fragmented masks). seedling: what real frames at
// weeding time look like (BoniRob, sugar beet at two to four leaves): about
// 1 % vegetation on dark, cloddy soil with bright clods, seen by a camera
// with an exposure and a colour cast of its own, vignetting, gain noise and
// colour fringes (its red and blue planes one pixel off the green one).
// canopy: a field where the leaves have closed over the soil (late crops,
// a dense weed patch): large plants overlapping, vegetation over most of
// the view, through the same real camera.
enum class Preset { early, late, dense, seedling, canopy };

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
    PlantClass kind = PlantClass::Unknown;   // Crop or Weed
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

// ---------------------------------------------------------------- strips
//
// A moving field strip: one long strip of field, seen frame after frame by
// a nadir camera on a machine driving along it at constant speed (the
// actuation end-to-end test, replay with odometry).
//
// Field coordinates (as include/stemd/geometry/field.hpp): s_mm along the
// track (the odometer reading at which a point is under the principal
// point), y_mm lateral, left of the machine's centre line > 0. The camera:
// nadir, camera.forward = up, principal point c = ((w - 1) / 2, (h - 1) / 2)
// at machine x = 0, y = 0, gsd_mm_per_px. A field point (s, y) appears in
// the frame captured at odometer o at
//     u = cx - y / gsd,   v = cy - (s - o) / gsd
// (forward = image up: plants move down the image as o grows; left of the
// machine = image left), which is geometry::field_position inverted; see
// strip_pixel().
//
// The strip is width_px * gsd wide (y in [-W/2, W/2], exactly the view's
// width) and has plants along length_mm: stems in [lead_mm, lead_mm +
// length_mm), where lead_mm = half the view's length + the preset's largest
// plant radius + 10 mm, so the first frame (odometer 0) sees no plant at
// all. The preset's plant counts per frame become a density: each
// view-length block of the strip draws them as generate_frame does. Stems
// are at least 15 mm inside the lateral edges (leaves may cross them and are
// clipped) and at least 20 mm from each other (kStripMinStemSpacingMm; in
// fact plants do not overlap, as in generate_frame, so they are usually
// much farther apart); a plant that finds no room is shrunk, then left out.
//
// Motion: frame k is captured at t_ns = 1e9 + k * round(1e9 / fps) with the
// odometer at o_k = round(k * v / fps / gsd) * gsd (v = speed_kmh in mm/s):
// the whole strip is rendered once into a canvas and frame k is the crop at
// an integer row offset, so o_k is the exact odometer of what the frame
// shows (the speed then jitters by < gsd per frame period). Frames go on
// until the last plant (grass included) has left the view at the trailing
// edge by 10 mm.
//
// Memory: the canvas is about 6 bytes/px, plus ~18 bytes/px while it is
// generated (3 m at the defaults: ~12000 x 1296 px, ~300 MB peak).

inline constexpr double kStripMinStemSpacingMm = 20;
inline constexpr double kStripEdgeMarginMm = 15;
inline constexpr std::int64_t kStripT0Ns = 1'000'000'000;

struct StripOptions {
    Preset preset = Preset::late;
    std::uint64_t seed = 1;
    double length_mm = 3000;       // along-track length of the planted strip
    int width_px = 1296;
    int height_px = 966;
    double gsd_mm_per_px = 0.33;
    double speed_kmh = 5;
    double fps = 30;
    double fragmentation = -1;     // < 0: the preset's default; else 0..1
};

// A stemmed plant (crop or weed) of the strip, in field coordinates.
struct StripPlant {
    int id = 0;             // index in Strip::plants, in order of s_mm
    double s_mm = 0;
    double y_mm = 0;
    PlantClass kind = PlantClass::Unknown;   // Crop or Weed
    int leaves = 0;
    double radius_mm = 0;   // stem to the farthest point of a leaf
    // The pixels this plant put into the mask, on the canvas (for the
    // per-frame area and centre of mass of the ground truth).
    cv::Rect canvas_box;
    cv::Mat canvas_mask;    // CV_8UC1 over canvas_box, 255 = this plant
};

struct Strip {
    StripOptions options;
    double view_length_mm = 0;   // height_px * gsd (along track)
    double width_mm = 0;         // width_px * gsd (lateral)
    double lead_mm = 0;          // the first stem's lowest possible s_mm
    int frame_count = 0;
    std::vector<StripPlant> plants;   // stemmed plants (grass is not listed), by s_mm
    int grass_tufts = 0;

    // The whole strip, rendered once (the optics' blur applied, no sensor
    // noise): row r shows s = top_s_mm - r * gsd, column u shows y = (cx - u) * gsd.
    cv::Mat bgr;           // CV_8UC3
    cv::Mat nir;           // CV_8UC1
    cv::Mat mask;          // CV_8UC1, 255 = vegetation
    cv::Mat plant_class;   // CV_8UC1, PlantClass values; grass counts as weed
    double top_s_mm = 0;

    // Frame k: its odometer (exact), capture time, row offset in the canvas.
    double odom_mm(int k) const;
    std::int64_t t_ns(int k) const;
    int canvas_row(int k) const;
};

struct StripFrame {
    int index = 0;
    std::int64_t t_ns = 0;
    double odom_mm = 0;
    cv::Mat bgr;           // CV_8UC3
    cv::Mat nir;           // CV_8UC1
    cv::Mat mask;          // CV_8UC1, 255 = vegetation
    cv::Mat plant_class;   // CV_8UC1, PlantClass values
    // Stems inside the image (as generate_frame: 0 <= x <= w - 1, same for
    // y), with area and centre of mass of the plant's pixels in this frame.
    std::vector<GroundTruthStem> stems;
    std::vector<int> plant_ids;   // parallel to stems: index in Strip::plants
};

// Deterministic in the options: the same bytes on every run. Throws
// std::invalid_argument for the Options limits, length_mm not in (0, 1e6],
// speed_kmh not in (0, 1000], fps not in (0, 10000], a canvas above 2^26 px
// or more than 1000000 frames.
Strip generate_strip(const StripOptions& options);

// Frame k (0 <= k < frame_count; else std::out_of_range): the canvas crop,
// with sensor noise seeded by (options, k).
StripFrame render_strip_frame(const Strip& strip, int k);

// Where the field point (s_mm, y_mm) appears in the frame captured at odom_mm.
cv::Point2d strip_pixel(const StripOptions& options, double s_mm, double y_mm, double odom_mm);

}  // namespace stemd::synth
