// Crop or weed, per plant: a fixed-length feature vector for each plant
// detect() found (colour, texture, shape in millimetres, lateral position),
// a random forest (OpenCV ml RTrees) that gives each plant a weed
// probability, and the per-pixel class map that follows from it. The
// model file also holds the cell forest of vision/cells, which classes
// each few millimetres of vegetation (and, through them, the plants) when
// present.
//
// The features are computed from the same frame, parameters and Workspace
// as detect(), so training (stemd-train) and use (stemd-detect, stemd) see
// the same plants. A trained model is one file (OpenCV FileStorage, YAML or
// JSON by extension) holding the forests and what they were trained on: feature
// names and version, camera GSD, channels, recordings, date and the
// cross-validated figures. A model only holds for the camera, GSD and crop
// it was trained on: loading checks the first two.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core/mat.hpp>
#include <opencv2/ml.hpp>

#include "stemd/base/plant_class.hpp"
#include "stemd/vision/detect.hpp"

namespace stemd::vision {

// Bumped whenever a feature is added, removed or computed differently: a
// model trained on other features is refused.
// Version 3 added the cell forest (vision/cells) to the model file.
inline constexpr int kPlantFeaturesVersion = 3;

// The features, in vector order. Shape is in physical units (via
// gsd_mm_per_px) so that a model carries over between resolutions of the
// same camera; colour is chromatic (r = R / (R + G + B)) so that it does not
// change with exposure.
enum PlantFeature : int {
    f_log_area_mm2,       // log10 of the plant's vegetation area in mm²
    f_perimeter_mm,       // outer contour length (2 area / mean width)
    f_solidity,           // vegetation area / convex hull area (detect's hull_fill)
    f_compactness,        // 4 pi area / perimeter² of the closed plant
    f_elongation,         // sqrt of the ratio of the principal second moments, >= 1
    f_extent,             // closed area / bounding box area
    f_leaves,             // leaves found by the leaf step
    f_leaf_elongation,    // mean elongation of those leaves (1 without leaves)
    f_vegetation_fill,    // vegetation pixels / closed pixels (lacy plants < 1)
    f_mean_width_mm,      // 2 area / perimeter
    f_r_mean,             // chromatic r, g, b over the plant's vegetation pixels (every 4th row of its box)
    f_g_mean,
    f_b_mean,
    f_r_std,
    f_g_std,
    f_exg_mean,           // 2g - r - b
    f_brightness_rel,     // mean R+G+B of the plant / the frame's
    f_texture,            // mean gradient magnitude of R+G+B / mean R+G+B, inside the plant
    f_ndvi_mean,          // (NIR - R) / (NIR + R), 0 without a NIR plane
    f_ndvi_std,
    f_lateral,            // the plant's centre x / frame width (across the travel with camera.forward up|down)
    // Frame context: crops are sown in rows along the travel (image y with
    // camera.forward up|down), weeds come anywhere. The dominant row is the
    // lateral band of kRowHalfWidthMm either side holding the most plant area.
    f_row_offset_mm,      // |centre x - the dominant row's area-weighted centre x|, in mm
    f_row_band_share,     // plant area in this plant's own lateral band / all plant area of the frame
    f_row_neighbours,     // other plants whose centre lies in this plant's lateral band
    f_area_share,         // this plant's area / the frame's largest plant's area
    kPlantFeatureCount
};

std::string_view feature_name(int feature);

using FeatureRow = std::array<float, kPlantFeatureCount>;

// Half the width of the lateral band the row features look at: about a
// sown row's width of seedlings either side of its line.
inline constexpr double kRowHalfWidthMm = 20.0;

// Colour, texture and NDVI are means over the vegetation pixels of every
// colour_row_step()-th row of a plant's box: every 4th row, and for a plant
// of more vegetation pixels than 4 kPlantColourSamples the next power of
// two that keeps its sample within kPlantColourSamples. A mean over 2^16
// pixels is as precise as one over a million, and the plant features' time
// then stops growing with a plant under a closed canopy. The largest plant
// of the shared real sets has 212 362 pixels: every real plant seen so far
// is read on every 4th row.
inline constexpr int kPlantColourSamples = 1 << 16;
int colour_row_step(int vegetation_px);

// What classify needs per frame, allocated once for a frame size; nothing
// is allocated by plant_features() afterwards.
class ClassifyWorkspace {
public:
    ClassifyWorkspace(cv::Size frame_size, const Params& params);
    cv::Size frame_size() const { return frame_size_; }

    // After plant_features(): per pixel of the closed mask, 1 + the index of
    // its plant in the Detections; 0 for soil and for pieces dropped as too
    // small or over capacity. CV_16UC1.
    const cv::Mat& plant_index() const { return plant_index_; }
    // After plant_features(): one row per plant of the Detections.
    std::span<const FeatureRow> features() const { return {features_.data(), plants_}; }
    // After plant_features(): the frame's mean R+G+B (sampled), which the
    // cells share.
    float frame_brightness() const { return frame_brightness_; }

private:
    friend void plant_features(const FrameView&, const Params&, const Workspace&, const Detections&,
                               ClassifyWorkspace&);
    struct Sums {
        long closed_px, vegetation_px, sampled_px;   // sampled: on the rows colour is read from
        double r, g, b, rr, gg, brightness, gradient, ndvi, ndvi2;
        double x, y, xx, yy, xy;   // closed pixels, relative to the bbox corner
    };
    cv::Size frame_size_;
    cv::Mat plant_index_;
    // Per row, the columns [start, end) that plant_index_ may hold nonzero
    // values in: the span of the last frame's plant runs on that row.
    std::vector<cv::Range> written_;
    std::array<Sums, kMaxPlants> sums_{};
    std::array<int, kMaxPlants> colour_row_step_{};
    std::array<FeatureRow, kMaxPlants> features_{};
    std::size_t plants_ = 0;
    float frame_brightness_ = 0;
};

// The features of every plant `detections` holds. `detect_workspace` and
// `detections` must come from detect() on this frame with these params.
// The frame's bgr is required (with mask segmentation too): without it, or
// on a frame of another size, features() is empty. Its nir is used when
// present (NDVI features), else they are 0.
void plant_features(const FrameView& frame, const Params& params, const Workspace& detect_workspace,
                    const Detections& detections, ClassifyWorkspace& workspace);

// The frame's mean R+G+B as the chromatic index measures it
// (chromatic_mean_brightness: every pixel of one row in kBrightnessRowStep,
// at least 1): the classifier's brightness normaliser, as its models were
// trained. CV_8UC3; an empty frame gives 1.
double sampled_frame_brightness(const cv::Mat& bgr);

// The class of a plant from its weed probability, asymmetric because a
// crop called weed is stamped and a weed called crop is only left standing:
// weed at or above the higher of weed_confidence and min_confidence, crop at
// or below 1 - min_confidence, else unknown.
PlantClass decide_class(float weed_probability, double min_confidence, double weed_confidence);

// The per-pixel class map: every vegetation pixel of a plant gets its
// plant's class (0 soil, 1 crop, 2 weed; unknown plants are 0 too, as
// PlantClass has it). `out` is CV_8UC1 of the frame size, (re)created
// only when its size differs.
void class_map(const Workspace& detect_workspace, const ClassifyWorkspace& workspace,
               std::span<const PlantClass> plant_classes, cv::Mat& out);

// The class of each plant with a stem from a class map (0 soil, 1 crop,
// 2 weed) of the frame's size or smaller (scaled on each axis): the
// majority of crop and weed pixels in a 9x9 window of the frame around the
// stem (the stem itself may lie on soil between leaves); unknown when there
// are none, and for plants without a stem. Returns the number of plants
// whose window holds values above 2, which are no class.
std::uint64_t plant_classes_from_map(const cv::Mat& class_map, cv::Size frame_size,
                                     const Detections& detections,
                                     std::array<PlantClass, kMaxPlants>& out) noexcept;

// What a model file says about itself.
struct ModelInfo {
    int features_version = kPlantFeaturesVersion;
    std::vector<std::string> feature_names{};
    double gsd_mm_per_px = 0;
    bool nir = false;                      // channels: rgb+nir (true) or rgb
    std::string segmentation{};            // segment.method of the training
    std::vector<std::string> recordings{};
    std::string trained_utc{};
    int trees = 0;
    double cell_mm = 0;                    // the cell forest's cell side (vision/cells)
    int cell_trees = 0;
    int context_trees = 0;                 // the cell context forest's (0: none, the cell forest decides)
    // The class map's decision per cell: weed at a probability of at least
    // this, crop below (the most likely class, not the treat decision).
    // stemd-train fits it on the out-of-fold per-pixel balanced accuracy.
    double map_weed_bar = 0.5;
    std::string cross_validation{};        // the figures stemd-train printed, as text
};

// "rgb" or "rgb+nir".
std::string_view channels_name(bool nir);

// A model whose GSD differs from the configuration's by more than this
// fraction is refused: sizes in mm² would be read off the wrong scale.
inline constexpr double kModelGsdTolerance = 0.10;

struct ForestOptions {
    int trees = 100;
    int max_depth = 12;
    int min_sample_count = 4;
    // Weigh the two classes equally whatever their counts (a field may
    // hold ten weeds per crop plant).
    bool balance_classes = true;
    std::uint64_t seed = 1;
    // Compute OpenCV's out-of-bag variable importance (cell and context
    // forests; the plant forest never does). Only a report reads it, and it
    // predicts every out-of-bag sample once per feature and tree: more than
    // half of a cell forest's training time.
    bool var_importance = false;
};

// A trained forest as flat arrays, walked without OpenCV's per-call
// bookkeeping: the cells call it hundreds of times a frame. A node's two
// children sit side by side and a leaf points to itself twice, so a walk
// takes each tree's depth in steps that pick a child by index instead of
// by a branch (half of which a CPU mispredicts on noisy splits), and
// several rows can walk one tree at once.
struct FlatForest {
    struct Node {
        int var;                    // a leaf: 0, read and ignored
        float threshold;            // child[0] when value <= threshold, else child[1]
        std::array<int, 2> child;   // a leaf: its own index twice
    };
    std::vector<Node> nodes{};
    std::vector<float> vote{};      // per node; a leaf's vote: 1 weed, 0 crop
    std::vector<int> roots{};
    std::vector<int> depths{};      // per tree: its longest root-to-leaf walk

    // The fraction of the trees voting weed for `features`.
    float weed_fraction(const float* features) const
    {
        float votes = 0;
        for (std::size_t t = 0; t < roots.size(); ++t) {
            int at = roots[t];
            for (int step = 0; step < depths[t]; ++step) {
                const Node& node = nodes[static_cast<std::size_t>(at)];
                at = node.child[features[node.var] <= node.threshold ? 0 : 1];
            }
            votes += vote[static_cast<std::size_t>(at)];
        }
        return roots.empty() ? 0.0f : votes / static_cast<float>(roots.size());
    }

    // weed_fraction() of `count` rows at once, row k at row_of(k), into
    // out[k]: each tree is walked by sixteen rows side by side while its
    // nodes are in cache, so their loads overlap (8 lanes gave 1.44 ms on
    // the bench, 16 1.30, 32 1.46: spills). The same values as
    // weed_fraction() (the votes are summed in the same tree order);
    // allocates nothing.
    template <class RowOf>
    void weed_fractions(std::size_t count, const RowOf& row_of, float* out) const
    {
        constexpr std::size_t kLanes = 16;
        std::fill(out, out + count, 0.0f);
        for (std::size_t t = 0; t < roots.size(); ++t) {
            for (std::size_t first = 0; first < count; first += kLanes) {
                const std::size_t lanes = std::min(kLanes, count - first);
                std::array<const float*, kLanes> row;
                std::array<int, kLanes> at;
                // A short last group walks its last row again in the spare
                // lanes, so that every group takes the same unrolled steps.
                for (std::size_t j = 0; j < kLanes; ++j) {
                    row[j] = row_of(first + std::min(j, lanes - 1));
                    at[j] = roots[t];
                }
                for (int step = 0; step < depths[t]; ++step)
                    for (std::size_t j = 0; j < kLanes; ++j) {
                        const Node& node = nodes[static_cast<std::size_t>(at[j])];
                        at[j] = node.child[row[j][node.var] <= node.threshold ? 0 : 1];
                    }
                for (std::size_t j = 0; j < lanes; ++j)
                    out[first + j] += vote[static_cast<std::size_t>(at[j])];
            }
        }
        if (roots.empty())
            return;
        for (std::size_t k = 0; k < count; ++k)
            out[k] /= static_cast<float>(roots.size());
    }

    // weed_fractions() of `count` rows of kStride floats laid out one after
    // another from `rows`. A lane's row is then a constant offset from one
    // pointer instead of a pointer of its own, which frees the registers the
    // sixteen walks need. The same values.
    template <std::size_t kStride>
    void weed_fractions_packed(std::size_t count, const float* rows, float* out) const
    {
        constexpr std::size_t kLanes = 16;
        const std::size_t whole = count - count % kLanes;
        std::fill(out, out + whole, 0.0f);
        for (std::size_t t = 0; t < roots.size(); ++t) {
            for (std::size_t first = 0; first < whole; first += kLanes) {
                const float* group = rows + first * kStride;
                std::array<int, kLanes> at;
                at.fill(roots[t]);
                for (int step = 0; step < depths[t]; ++step)
                    for (std::size_t j = 0; j < kLanes; ++j) {
                        const Node& node = nodes[static_cast<std::size_t>(at[j])];
                        at[j] = node.child[group[j * kStride + static_cast<std::size_t>(node.var)] <= node.threshold ? 0 : 1];
                    }
                for (std::size_t j = 0; j < kLanes; ++j)
                    out[first + j] += vote[static_cast<std::size_t>(at[j])];
            }
        }
        if (!roots.empty())
            for (std::size_t k = 0; k < whole; ++k)
                out[k] /= static_cast<float>(roots.size());
        // The rows after the last whole group.
        weed_fractions(
            count - whole, [&](std::size_t k) { return rows + (whole + k) * kStride; }, out + whole);
    }
};

// The same trees as `forest`, whose variables must all be ordered (as
// CV_32F rows without a type list train them). Empty (no roots) when the
// forest is not one it can walk: a child out of range, a variable beyond
// the forest's, or a tree deeper than kMaxFlatDepth.
inline constexpr int kMaxFlatDepth = 64;
FlatForest flatten(const cv::ml::RTrees& forest);

// Far above a model's size (CWFID's example: 2.5 MB; a forest grown to
// its depth limit on noisy labels, tens of MB), far below the memory.
inline constexpr std::size_t kMaxModelFileBytes = std::size_t{256} << 20;

class PlantClassifier {
public:
    // Trains on one row per plant (samples CV_32F, kPlantFeatureCount
    // columns) with labels CV_32S: 1 crop, 2 weed. Deterministic for a
    // given options.seed (it reseeds the calling thread's cv::theRNG()).
    static std::optional<PlantClassifier> train(const cv::Mat& samples, const cv::Mat& labels,
                                                const ForestOptions& options, std::string& error);
    // Reads a model file (a regular file of at most kMaxModelFileBytes);
    // error names the file and the reason.
    static std::optional<PlantClassifier> load(const std::filesystem::path& path, std::string& error);
    // Writes the forest with `info` (its trees field is filled in here).
    bool save(const std::filesystem::path& path, ModelInfo info, std::string& error) const;

    // The fraction of the trees that vote weed. OpenCV's predict() on one
    // CV_32F row with PREDICT_SUM and no output array walks each tree and
    // sums its leaf values: it allocates nothing (a unit test counts).
    float weed_probability(const FeatureRow& features) const;

    const ModelInfo& info() const { return info_; }
    // The class map's weed bar (ModelInfo::map_weed_bar), kept by save().
    void set_map_weed_bar(double bar) { info_.map_weed_bar = bar; }

    // The cell forest: rows of kCellFeatureCount (vision/cells), labels as
    // for train(), cells of cell_mm. Deterministic for options.seed.
    // `weights` (CV_32F, one per row, or empty for 1 each) weigh the rows,
    // and the classes are then balanced by their summed weights.
    bool train_cells(const cv::Mat& samples, const cv::Mat& labels, const ForestOptions& options, double cell_mm,
                     std::string& error, const cv::Mat& weights = {});
    bool has_cells() const { return !cell_flat_.roots.empty(); }
    // The fraction of the cell forest's trees that vote weed for one row
    // of kCellFeatureCount features; allocates nothing.
    float cell_weed_probability(std::span<const float> row) const { return cell_flat_.weed_fraction(row.data()); }
    // cell_weed_probability() of `count` rows, row k at row_of(k) (a const
    // float* to kCellFeatureCount values), into out[k]; allocates nothing.
    template <class RowOf>
    void cell_weed_probabilities(std::size_t count, const RowOf& row_of, float* out) const
    {
        cell_flat_.weed_fractions(count, row_of, out);
    }
    // The same for `count` rows laid out kStride floats apart from `rows`,
    // each starting with its kCellFeatureCount features (the faster walk).
    template <std::size_t kStride>
    void cell_weed_probabilities_packed(std::size_t count, const float* rows, float* out) const
    {
        cell_flat_.weed_fractions_packed<kStride>(count, rows, out);
    }
    // Variable importance of the cell forest (training with var_importance only,
    // empty otherwise and after load).
    const cv::Mat& cell_importance() const { return cell_importance_; }

    // The context forest (vision/cells, the second stage): rows of
    // kContextFeatureCount, a cell's row and its context from the cell
    // forest's probabilities; labels and weights as for train_cells().
    // Needs the cell forest first.
    bool train_context(const cv::Mat& samples, const cv::Mat& labels, const ForestOptions& options,
                       std::string& error, const cv::Mat& weights = {});
    bool has_context() const { return !context_flat_.roots.empty(); }
    // The fraction of the context forest's trees that vote weed for one
    // row of kContextFeatureCount features; allocates nothing.
    float context_weed_probability(std::span<const float> row) const { return context_flat_.weed_fraction(row.data()); }
    // The same for `count` rows of kContextFeatureCount values.
    template <class RowOf>
    void context_weed_probabilities(std::size_t count, const RowOf& row_of, float* out) const
    {
        context_flat_.weed_fractions(count, row_of, out);
    }
    template <std::size_t kStride>
    void context_weed_probabilities_packed(std::size_t count, const float* rows, float* out) const
    {
        context_flat_.weed_fractions_packed<kStride>(count, rows, out);
    }
    const cv::Mat& context_importance() const { return context_importance_; }

    // Empty when the model fits a configuration of this GSD and channels;
    // else the reason, naming `model_name` (the file).
    std::optional<std::string> mismatch(double gsd_mm_per_px, bool nir, std::string_view model_name) const;

private:
    cv::Ptr<cv::ml::RTrees> forest_;
    cv::Ptr<cv::ml::RTrees> cell_forest_;
    FlatForest cell_flat_;
    cv::Mat cell_importance_;
    cv::Ptr<cv::ml::RTrees> context_forest_;
    FlatForest context_flat_;
    cv::Mat context_importance_;
    ModelInfo info_;
    float trees_ = 1;
};

}  // namespace stemd::vision
