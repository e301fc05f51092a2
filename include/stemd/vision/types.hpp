// Result and parameter types of the stem pipeline. Fixed capacity so that
// a Detections object allocated once can be refilled every frame without
// touching the heap.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>

#include <opencv2/core/types.hpp>

#include "stemd/base/enum_names.hpp"

namespace stemd::vision {

// A vector with its storage inline; push_back reports overflow instead of
// growing, so the caller can count it.
template <class T, std::size_t Capacity>
class FixedVector {
public:
    static constexpr std::size_t capacity() { return Capacity; }
    std::size_t size() const { return size_; }
    bool empty() const { return size_ == 0; }
    bool full() const { return size_ == Capacity; }
    void clear() { size_ = 0; }
    bool push_back(const T& value)
    {
        if (size_ == Capacity)
            return false;
        items_[size_++] = value;
        return true;
    }
    T& back() { return items_[size_ - 1]; }
    T& operator[](std::size_t i) { return items_[i]; }
    const T& operator[](std::size_t i) const { return items_[i]; }
    T* begin() { return items_.data(); }
    T* end() { return items_.data() + size_; }
    const T* begin() const { return items_.data(); }
    const T* end() const { return items_.data() + size_; }

private:
    std::array<T, Capacity> items_{};
    std::size_t size_ = 0;
};

// exg: 2G - R - B. chromatic_exg: the same divided by the pixel's brightness
// plus the frame's mean brightness, so that the index does not change with
// exposure, gain or shadow, and dark pixels (where chromaticity is mostly
// sensor noise) are pulled towards 0. exg_and_ndvi (RGB + NIR): vegetation
// is where both chromatic_exg and NDVI lie above their soil: chlorophyll
// makes a leaf green and its cells make it bright in NIR, while a greenish
// clod or a colour fringe fakes only the first and dead straw only the second.
// automatic: the frames decide, exg_and_ndvi when they carry a NIR plane and
// chromatic_exg when they do not (resolve_segmentation), so one
// configuration serves an RGB and an RGB+NIR camera at its best.
enum class Segmentation : std::uint8_t { exg, chromatic_exg, ndvi, mask, exg_and_ndvi, automatic };

// The method reads the frame's NIR image.
constexpr bool uses_nir(Segmentation s)
{
    return s == Segmentation::ndvi || s == Segmentation::exg_and_ndvi;
}

// The method that runs on frames with (or without) a NIR plane: automatic
// becomes exg_and_ndvi or chromatic_exg, every other method stays.
constexpr Segmentation resolve_segmentation(Segmentation s, bool nir_plane)
{
    if (s != Segmentation::automatic)
        return s;
    return nir_plane ? Segmentation::exg_and_ndvi : Segmentation::chromatic_exg;
}
// above_soil: Otsu, but never inside the soil's own spread: max(Otsu,
// soil mode + soil_sigmas standard deviations of the soil).
enum class ThresholdMethod : std::uint8_t { otsu, triangle, min_error, above_soil };
// Which pixel value of an external mask means vegetation.
enum class MaskVegetation : std::uint8_t { nonzero, zero };
// What a stem point came from: the plant's leaves or its centre of mass.
enum class StemMethod : std::uint8_t { leaves, com };
// Which estimator is asked for:
//  robust: weighted least-squares point nearest all leaf lines, outlier
//          leaves down-weighted, kept where the leaves meet (the default);
//  paper:  the mean of the pairwise intersections, as the paper words it;
//  com:    the centre of mass.
enum class StemEstimator : std::uint8_t { robust, paper, com };
// Why a plant's stem is its centre of mass.
enum class ComReason : std::uint8_t {
    none,             // the stem came from the leaves
    method_com,       // the centre-of-mass method was asked for
    too_few_leaves,   // fewer than min_leaves leaves
    no_intersections, // every pair of leaf directions was (nearly) parallel
    outside_box,      // the leaf estimate left the plant's bounding box
    contour_overflow, // the outer contour was longer than the workspace holds
    ill_conditioned,  // the leaf lines do not pin a point down (robust estimator)
    weed_part,        // a weed part of a larger plant, found by the crop/weed cells (vision/cells)
    stemless_weed,    // a plant classed weed without a stem of its own (grass, low confidence): its weed cells (vision/cells)
    weed_cover,       // a further target on a weed wider than a strike's reach (vision/cells)
};

// The words of the configurable enums, in the order config files list them
// (the schema takes its choices from these tables).
inline constexpr base::EnumName<Segmentation> kSegmentationNames[]{
    {Segmentation::automatic, "auto"}, {Segmentation::chromatic_exg, "chromatic_exg"}, {Segmentation::exg, "exg"},
    {Segmentation::ndvi, "ndvi"},      {Segmentation::mask, "mask"},                   {Segmentation::exg_and_ndvi, "exg_and_ndvi"}};
inline constexpr base::EnumName<ThresholdMethod> kThresholdMethodNames[]{
    {ThresholdMethod::above_soil, "above_soil"}, {ThresholdMethod::otsu, "otsu"},
    {ThresholdMethod::triangle, "triangle"}, {ThresholdMethod::min_error, "min_error"}};
inline constexpr base::EnumName<MaskVegetation> kMaskVegetationNames[]{{MaskVegetation::nonzero, "nonzero"},
                                                                       {MaskVegetation::zero, "zero"}};
inline constexpr base::EnumName<StemEstimator> kStemEstimatorNames[]{
    {StemEstimator::robust, "robust"}, {StemEstimator::paper, "paper"}, {StemEstimator::com, "com"}};

std::string_view to_string(Segmentation v);
std::string_view to_string(ThresholdMethod v);
std::string_view to_string(MaskVegetation v);
std::string_view to_string(StemMethod v);
std::string_view to_string(StemEstimator v);
std::string_view to_string(ComReason v);
std::optional<Segmentation> parse_segmentation(std::string_view s);
std::optional<ThresholdMethod> parse_threshold_method(std::string_view s);
std::optional<MaskVegetation> parse_mask_vegetation(std::string_view s);
std::optional<StemEstimator> parse_stem_estimator(std::string_view s);

// The pipeline's parameters, in the units their names carry. Ranges are
// enforced by the config schema (config/schema), not here.
struct Params {
    Segmentation segmentation = Segmentation::automatic;
    ThresholdMethod threshold = ThresholdMethod::above_soil;
    MaskVegetation mask_vegetation = MaskVegetation::nonzero;
    // Automatic thresholds: if the mean index of the two classes differs by
    // less than this (index units; ExG: 1 unit = 4 of 2G-R-B, NDVI: 1/127.5),
    // the histogram has no second class and the frame has no vegetation.
    // 0 disables the check.
    double min_class_separation = 12.0;
    // above_soil: the threshold lies at least this many standard deviations
    // of the soil (measured on the soil mode's side away from vegetation)
    // above the soil mode.
    double soil_sigmas = 5.0;
    // 3x3 binomial smoothing of the index before the threshold: single-pixel
    // sensor noise then no longer crosses it.
    bool smooth_index = true;
    // The smoothed RGB index (exg, chromatic_exg) computed in full only in
    // 64 px tiles near vegetation found on every 8th row (vision/
    // sparse_index); the rest of the frame is soil. False: every pixel.
    bool sparse_index = true;
    // RGB (exg, chromatic_exg): a plant's seed pixels must be more green than
    // red, as chlorophyll makes a leaf; yellowish clods and colour fringes,
    // as green in ExG, are not.
    bool leaf_colour = true;
    // Opening with a 3x3 square before the closing: removes vegetation
    // specks and colour fringes one or two pixels wide (0 disables).
    int opening_radius_px = 1;
    // Mixed pixels at a plant's edge: within this radius of the thresholded
    // plant, a pixel is vegetation when its index is above the halfway point
    // between the soil mode and the plant pixels around it (at least half
    // leaf). 0 disables.
    int edge_radius_px = 5;
    int closing_radius_px = 5;          // paper's m
    double gsd_mm_per_px = 0.33;        // ground sampling distance
    double min_plant_area_mm2 = 10.0;   // smaller plants are noise
    // Pieces of the closed mask at most this far apart are one plant: a
    // seedling's petioles and shaded centre often fall below the threshold
    // and leave its leaves apart. Each piece then adds its leaves (a piece
    // without cuts is one leaf) to the plant's. Grouping works on 4 px
    // cells, so pieces up to about 8 px farther apart may join too.
    // 0: every piece is a plant.
    double group_gap_mm = 6.0;
    double defect_depth_mm = 1.0;       // the paper used 3.3 (10 px at 0.33 mm/px)
    // Scale-aware cut: a defect must also be deeper than this fraction of
    // the plant's equivalent radius sqrt(area / pi); 0 = the fixed depth only.
    double defect_depth_rel = 0.15;
    int min_leaves = 3;                 // paper's N
    // Paper estimator: pairs of leaf lines meeting at a smaller angle are
    // skipped (0: only exactly parallel ones, as the paper words it). A 1 px
    // error in a root moves an intersection by about 1/sin(angle) px.
    double min_intersection_angle_deg = 0.0;
    StemEstimator stem_estimator = StemEstimator::robust;
    // Plants whose stem confidence is below this are reported without a stem.
    double min_confidence = 0.05;
    // Grass and other linear-leaved blobs: at least this large and thinner
    // than this on average (2 * area / perimeter) have no stem to strike.
    double grass_min_area_mm2 = 100.0;
    double grass_max_width_mm = 3.0;
    // ... and covering less than this fraction of their convex hull: a tuft
    // of blades fanned out from one point leaves most of its hull empty, a
    // rosette of thin-stalked leaves does not. 1 (or more): width alone.
    double grass_max_hull_fill = 0.4;
};

inline constexpr std::size_t kMaxLeaves = 16;
inline constexpr std::size_t kMaxPlants = 256;
inline constexpr int kMaxClosingRadiusPx = 50;  // larger radii are clamped

struct Leaf {
    cv::Point2f cut_a;   // convexity defect starting the leaf (contour order)
    cv::Point2f cut_b;   // convexity defect ending the leaf
    cv::Point2f root;    // mean of the two cut points
    cv::Point2f centre;  // area centroid of the leaf polygon
    cv::Point2f axis;    // unit principal axis of the leaf polygon (its long direction)
    float elongation = 1;  // ratio of the principal second moments, >= 1
};

struct Plant {
    cv::Point2f stem;            // sub-pixel, image coordinates (pixel centres at integers)
    bool has_stem = true;        // false: stemless (grass) or below min_confidence
    StemMethod method = StemMethod::com;
    StemEstimator estimator = StemEstimator::com;  // the estimator that produced `stem`
    float confidence = 0;        // [0, 1]
    ComReason com_reason = ComReason::none;
    FixedVector<Leaf, kMaxLeaves> leaves;
    int defects = 0;             // convexity defects deeper than the threshold
    int area_px = 0;             // vegetation pixels (holes excluded)
    cv::Rect bbox;               // inclusive of every plant pixel
    cv::Point2f centre_of_mass;
    cv::Point first_pixel;       // top-most, then left-most pixel: where its outer contour starts
    float mean_width_mm = 0;     // 2 * area / perimeter of the outer contour
    float hull_fill = 0;         // area / convex hull area (0 when not traced)
};

// Per-frame counters of the pipeline; the daemon sums them into its status.
struct DetectStats {
    int threshold = -1;             // on the 8-bit index; -1 for external masks
    float class_separation = 0;     // mean index above minus below the threshold; 0 for external masks
    bool no_vegetation = false;     // separation below min_class_separation: no plants looked for
    int vegetation_px = 0;          // after thresholding, before closing
    int components = 0;             // 8-connected components after closing
    int small_components = 0;       // dropped below min_plant_area
    int colour_fringes = 0;         // seeded pieces dropped as colour fringes (leaf_colour)
    int plants_over_capacity = 0;   // plants beyond kMaxPlants, not reported
    int leaves_over_capacity = 0;   // leaves beyond kMaxLeaves, ignored
    int outside_box_fallbacks = 0;  // leaf estimates replaced by the centre of mass
    int contour_overflows = 0;      // contours longer than the workspace holds
    int stemless = 0;               // plants reported without a stem (grass, low confidence)
    int index_tiles = 0;            // sparse index: the frame's 64 px tiles (0: index on every pixel)
    int index_tiles_computed = 0;   // ... of which computed in full
};

enum class DetectStatus : std::uint8_t {
    ok,
    empty_frame,       // no pixels
    bad_format,        // wrong channel count or depth
    size_mismatch,     // frame does not match the workspace it was given
    missing_nir,       // NDVI asked for without a NIR image of the same size
    missing_mask,      // mask segmentation without a mask
};
std::string_view to_string(DetectStatus v);

struct Detections {
    DetectStatus status = DetectStatus::ok;
    FixedVector<Plant, kMaxPlants> plants;
    DetectStats stats;
};

// Wall time of each stage of one detect() call, CLOCK_MONOTONIC nanoseconds.
struct StageTimes {
    std::int64_t index_ns = 0;       // the index and its smoothing (exg_and_ndvi: both indices)
    std::int64_t threshold_ns = 0;   // histogram threshold, opening, seeds, mixed edges
    std::int64_t closing_ns = 0;
    std::int64_t plants_ns = 0;
    std::int64_t leaves_ns = 0;   // contours, hulls, defects, leaves and stems
    std::int64_t total_ns = 0;
};

}  // namespace stemd::vision
