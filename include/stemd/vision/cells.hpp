// Crop or weed per cell: the frame is cut into square cells of a size in
// millimetres (through gsd_mm_per_px), and every cell holding vegetation
// gets a fixed-length feature row from its own pixels, its neighbourhood,
// the frame's rows of plants and the plant it belongs to. A forest (in the
// same model file as the plant forest, vision/classify) gives each cell a
// weed probability, and the class map paints each vegetation pixel with its
// cell's class. Unlike one class per plant, two touching plants (a weed
// grown into a crop row, merged by the segmentation) can then get
// different classes.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "stemd/base/plant_class.hpp"
#include "stemd/vision/classify.hpp"
#include "stemd/vision/detect.hpp"
#include "stemd/vision/run_colour.hpp"

namespace stemd::vision {

// The cell's own features, in vector order; the features of the plant the
// cell belongs to (PlantFeature, zero without one) follow them.
enum CellFeature : int {
    c_fill,              // vegetation pixels / cell pixels
    c_r_mean,            // chromatic r and g over the cell's vegetation pixels
    c_g_mean,
    c_r_std,
    c_g_std,
    c_brightness_rel,    // mean R+G+B of the vegetation / the frame's
    c_texture,           // mean |gradient| of R+G+B / mean R+G+B
    c_coherence,         // structure tensor: 1 for one edge direction, 0 for none
    c_orientation,       // (gx² - gy²) / (gx² + gy²): edges across the travel (image x) or along it
    c_ndvi_mean,         // (NIR - R) / (NIR + R), 0 without a NIR plane
    c_ndvi_std,
    c_width_mm,          // leaf thickness: 2 vegetation area / boundary length, in mm
    c_fill_near,         // vegetation density in squares around the cell, kCellRingsMm
    c_fill_mid,
    c_fill_far,
    c_g_near,            // chromatic g of the vegetation in the near square
    c_r_near,
    c_band_density,      // vegetation density of the cell's lateral band (kRowHalfWidthMm either side,
                         // the whole frame along the travel) / the frame's density
    c_row_offset_mm,     // lateral distance from the frame's dominant row: the centre of the densest band
    c_lateral,           // the cell's centre x / frame width
    c_in_plant,          // 1 when the cell's vegetation belongs to a plant detect() kept, else 0
    // The cell against the frame's vegetation as a whole: light, exposure
    // and growth stage change from frame to frame, the contrast between
    // a crop and the weeds beside it much less.
    c_r_rel,             // c_r_mean - the frame's vegetation r
    c_g_rel,
    c_brightness_veg,    // mean R+G+B / the frame's vegetation's
    c_texture_rel,       // c_texture / the frame's vegetation's
    c_width_rel,         // c_width_mm / the frame's vegetation's
    kCellOwnFeatureCount
};
inline constexpr int kCellFeatureCount = static_cast<int>(kCellOwnFeatureCount) + static_cast<int>(kPlantFeatureCount);

// classify_cells() averages each cell's probability over the cells this
// many steps around it (weighed by their vegetation): neighbouring cells
// mostly hold the same plant, and one cell's features are noisy
// (cross-validated per-pixel balanced accuracy on cwfid-train 0.77 without,
// 0.80 with radius 1 or 2).
inline constexpr int kCellSmoothRadius = 1;

// What stemd-train uses unless told otherwise: 3 mm cells, 30 trees of
// depth 8 (shallow trees generalise across frames better: on cwfid-train
// out of fold per-pixel balanced accuracy 0.78 at depth 5-8, 0.74 at 12).
inline constexpr double kDefaultCellMm = 3.0;
inline constexpr ForestOptions kDefaultCellForest{.trees = 30, .max_depth = 8, .min_sample_count = 8};

// Half sides of the squares the c_fill_* features look at.
inline constexpr std::array<double, 3> kCellRingsMm{6.0, 15.0, 40.0};

std::string_view cell_feature_name(int feature);

using CellRow = std::array<float, kCellFeatureCount>;

// The second stage (auto-context): a cell's first-stage weed probability as
// seen from around it. A weed is mostly small, alone or at a row's edge, a
// crop large and in the row, so what the first stage says about a cell's
// neighbours, its plant and its band tells more than the cell's own pixels
// (out of fold, per segmented pixel: cwfid-train 0.86 -> 0.89, carrot-dev
// 0.87 -> 0.89). Each is a mean of first-stage probabilities weighed by the
// cells' vegetation (c_fill). The context forest reads a cell's CellRow
// followed by these.
enum CellContextFeature : int {
    x_near,      // the squares of kContextRingsMm half side around the cell
    x_mid,
    x_wide,
    x_far,
    x_band,      // the cell's lateral band (kRowHalfWidthMm either side, the whole frame along the travel)
    x_plant,     // the cells of the cell's plant (the cell's own probability without one)
    x_frame,     // every vegetated cell of the frame
    kCellContextCount
};
inline constexpr std::array<double, 4> kContextRingsMm{3.0, 6.0, 15.0, 40.0};
inline constexpr int kContextFeatureCount = kCellFeatureCount + static_cast<int>(kCellContextCount);
using CellContext = std::array<float, kCellContextCount>;
using ContextRow = std::array<float, kContextFeatureCount>;

// Names over a whole ContextRow: the cell features', then the context's.
std::string_view context_feature_name(int feature);

// One frame's vegetated cells as the context needs them, each span in the
// same order (`cells`: grid indices, row-major, each once).
struct CellContextInput {
    cv::Size grid;
    double cell_mm = 3;
    std::span<const std::uint32_t> cells;
    std::span<const float> weight;            // the cell's c_fill
    std::span<const std::uint16_t> plant;     // 1 + plant index, 0 none (at most kMaxPlants)
    std::span<const float> probability;       // the first stage's weed probability
};

// Buffers for cell_context() on grids of one size, allocated once.
class CellContextScratch {
public:
    CellContextScratch() = default;
    explicit CellContextScratch(cv::Size grid);
    cv::Size grid() const { return grid_; }

private:
    friend void cell_context(const CellContextInput&, CellContextScratch&, std::span<CellContext>);
    cv::Size grid_;
    std::vector<double> integral_p_, integral_w_, column_p_, column_w_;
    std::vector<double> cell_p_, cell_w_;   // p·w and w per cell, zero but while a call runs
    std::array<double, kMaxPlants + 1> plant_p_{}, plant_w_{};
};

// Each listed cell's context (out[k] for input.cells[k]); allocates
// nothing. The same function serves training (stemd-train, on out-of-fold
// first-stage probabilities) and the frame path (classify_cells()).
void cell_context(const CellContextInput& input, CellContextScratch& scratch, std::span<CellContext> out);

enum class ImageEdge : std::uint8_t { top, bottom, left, right };

// How many vegetated cells classify_cells() classifies in one frame. Its
// time grows with them, up to every cell of the grid under a closed canopy;
// the budget bounds it. Over the budget, the cells nearest `first_edge` go
// first. The daemon puts there the edge plants enter the view by: its
// tracker fixes a target's class when it confirms the target, a few frames
// after the plant came into view, so the cells nearer the exit belong to
// plants already confirmed.
struct CellBudget {
    std::size_t max_cells = std::numeric_limits<std::size_t>::max();
    ImageEdge first_edge = ImageEdge::top;
};

// Everything the cells need per frame, allocated once for a frame size, GSD
// and cell size; cell_features() and what follows allocate nothing.
struct WeedTargetParams;
struct WeedTargetCounts;

class CellWorkspace {
public:
    CellWorkspace(cv::Size frame_size, double gsd_mm_per_px, double cell_mm);
    cv::Size frame_size() const { return frame_size_; }
    int cell_px() const { return cell_px_; }
    cv::Size grid() const { return grid_; }
    std::size_t cells() const { return static_cast<std::size_t>(grid_.area()); }

    // After cell_features(): the grid cell (row-major) of frame pixel (x, y).
    std::size_t cell_of(int x, int y) const
    {
        return static_cast<std::size_t>(y / cell_px_) * static_cast<std::size_t>(grid_.width) +
               static_cast<std::size_t>(x / cell_px_);
    }
    // Cells holding vegetation, in grid order, and their rows.
    std::span<const std::uint32_t> vegetated() const { return {vegetated_.data(), vegetated_count_}; }
    const CellRow& row(std::size_t cell) const { return rows_[cell]; }
    // The plant (1 + index into the Detections, 0 none) most of the cell's
    // vegetation belongs to.
    std::uint16_t plant(std::size_t cell) const { return plant_[cell]; }

    // After classify_cells(): each cell's weed probability and class
    // (Unknown for cells without vegetation, and for vegetated cells the
    // budget left out, whose probability is 0).
    float weed_probability(std::size_t cell) const { return probability_[cell]; }
    PlantClass cell_class(std::size_t cell) const { return class_[cell]; }

private:
    friend void cell_features(const FrameView&, const Params&, const Workspace&, const Detections&,
                              const ClassifyWorkspace&, CellWorkspace&);
    friend std::size_t classify_cells(const PlantClassifier&, CellWorkspace&, const CellBudget&);
    friend WeedTargetCounts add_weed_parts(CellWorkspace&, const WeedTargetParams&, Detections&,
                                           std::span<PlantClass>, std::span<float>);
    struct Sums {
        int vegetation_px, boundary;   // on the sampled rows
    };
    cv::Size frame_size_;
    double gsd_ = 1;
    double cell_mm_ = 1;
    int cell_px_ = 1;
    cv::Size grid_;
    std::vector<std::uint16_t> cell_x_;        // grid column of each frame column
    std::vector<std::uint64_t> transitions_, vertical_, either_;   // one row of bits each
    std::vector<int> row_counts_;   // one row's per-cell counts, two to a column
    std::vector<Sums> sums_;
    std::vector<CellSamples> samples_;   // every fourth vegetation pixel of the sampled rows
    std::vector<double> integral_fill_, integral_px_, integral_g_, integral_r_, integral_n_;
    std::vector<double> column_fill_, column_px_;
    std::vector<CellRow> rows_;
    std::vector<std::uint16_t> plant_;
    std::vector<std::uint32_t> vegetated_;
    std::size_t vegetated_count_ = 0;
    // classify_cells(): the vegetated cells within the budget (grid order),
    // a flag per cell for them, and the vegetated cells per step from the
    // budget's first edge.
    std::vector<std::uint32_t> budgeted_;
    std::vector<std::uint8_t> in_budget_;
    std::vector<std::uint32_t> edge_steps_;
    std::vector<float> probability_, raw_;
    std::vector<PlantClass> class_;
    // The context stage's inputs and output, one entry per vegetated cell.
    std::vector<float> listed_weight_, listed_probability_;
    std::vector<std::uint16_t> listed_plant_;
    std::vector<CellContext> context_;
    std::vector<float> context_rows_;   // a ContextRow per vegetated cell, back to back
    CellContextScratch context_scratch_;
    // add_weed_parts(): cells already in a part, the flood fill's stack (or
    // a weed plant's cells), and each listed cell's squared distance to
    // the nearest target (-1: not clear).
    std::vector<std::uint8_t> in_part_;
    std::vector<std::uint32_t> part_stack_;
    std::vector<float> cover_d2_;
};

// The rows of every cell holding vegetation. `detect_workspace`,
// `detections` and `plants` (plant_features()) must come from this frame
// with these params; a frame without its bgr image, or of another size,
// gives no cells.
void cell_features(const FrameView& frame, const Params& params, const Workspace& detect_workspace,
                   const Detections& detections, const ClassifyWorkspace& plants, CellWorkspace& workspace);

// Each vegetated cell's weed probability from the model's cell forest (and
// then its context forest, when the model has one) and its most likely class for the class map: weed at the model's
// map_weed_bar or above, crop below. The map describes the scene; whether
// a plant is treated is decided per plant (classify_plants(), with the
// asymmetric decide_class()). Every cell Unknown when the model has no
// cell forest. With more vegetated cells than budget.max_cells, only the
// budget's cells nearest budget.first_edge are classified (whole steps from
// the edge, then the next step's cells in grid order), as if the others
// held no vegetation; the others stay Unknown. Returns how many vegetated
// cells the budget left out.
std::size_t classify_cells(const PlantClassifier& model, CellWorkspace& workspace, const CellBudget& budget = {});

// The class map from the cells: each vegetation pixel gets its cell's class
// (0 soil, 1 crop, 2 weed; cells without a class 0). `out` CV_8UC1 of the
// frame size, (re)created only when its size differs.
void cell_class_map(const Workspace& detect_workspace, const CellWorkspace& workspace, cv::Mat& out);

// Each plant's weed probability from its cells: the mean of their
// probabilities weighted by the plant's sampled vegetation in each; -1 for
// a plant with no classified cell, or with a vegetated cell the budget left
// out (a plant seen in part is not judged).
void plant_probabilities_from_cells(const CellWorkspace& workspace, std::size_t plants,
                                    std::span<float> out);

// Each plant's weed probability and class: from the share of its cells
// (plant_probabilities_from_cells, after classify_cells()) when the model
// has a cell forest, else from the plant forest on plant_features(). A plant
// without a probability (no classified cell) is Unknown and -1.
void classify_plants(const PlantClassifier& model, const ClassifyWorkspace& plants, const CellWorkspace& cells,
                     std::size_t count, double min_confidence, double weed_confidence,
                     std::span<float> probabilities, std::span<PlantClass> classes);

// How add_weed_parts() places weed targets.
struct WeedTargetParams {
    double min_confidence = 0.6;    // decide_class()'s bars, per cell
    double weed_confidence = 0.85;
    double clearance_mm = 3;        // no vegetated cell that is not weed this near a target
    // A weed wider than a strike's reach: further targets until every clear
    // weed cell of it lies within this of one; 0, one target per weed.
    double cover_radius_mm = 0;
    std::size_t max_targets_per_weed = 16;   // the first included, >= 1
};

// What add_weed_parts() added, by kind.
struct WeedTargetCounts {
    std::size_t parts = 0;      // ComReason::weed_part
    std::size_t stemless = 0;   // ComReason::stemless_weed
    std::size_t cover = 0;      // ComReason::weed_cover
    std::size_t total() const { return parts + stemless + cover; }
};

// A weed grown into a crop, or into a plant the classifier is unsure of, is
// one blob with it, and that blob's one stem is not on the weed; its cells
// still tell it apart. Each 8-connected group of a crop or unknown plant's
// cells that decide_class() calls weed becomes a plant of its own in `det`,
// classed weed. Its stem is where no vegetated cell that is not weed (a
// cell the budget left out is not) lies within `clearance_mm`, so what a
// tool strikes there is weed, not crop:
// the group's vegetation-weighted centre (the centre of mass, a small
// plant's stem) when that is clear, else the centre of the group's cell
// nearest to it that is clear (Plant::centre_of_mass keeps the group's
// centre); a group with no clear cell gets none.
// Plants classed weed keep their one stem; those without one (grass, or a
// stem below min_confidence) get targets the same way, from their weed
// cells (stem reason stemless_weed), so that "weeds only" treats them too.
// With a cover radius, a plant classed weed wider than the radius (from its
// stem, or each group of a stemless one from its target) gets more targets
// (stem reason weed_cover): each at the centre of its clear weed cell
// farthest from every target so far, for as long as that lies beyond the
// radius and max_targets_per_weed allows. Touching weeds are found as one
// plant with one stem; a stamp at that stem leaves the others, and a spray
// there reaches no farther than its footprint. The weed parts of crop and
// unknown plants are not covered: their plant's own class is not weed, and
// further targets would reach deeper into it.
// `classes` and `probabilities` get the new plants' entries; targets beyond
// the plants' capacity are counted in det.stats.plants_over_capacity.
// Allocates nothing.
WeedTargetCounts add_weed_parts(CellWorkspace& cells, const WeedTargetParams& params, Detections& det,
                                std::span<PlantClass> classes, std::span<float> probabilities);

// How a frame's plants get their classes from a model with a cell forest.
struct ModelClassParams {
    WeedTargetParams decision;   // its min_confidence and weed_confidence decide each plant too
    bool weed_parts = true;      // add_weed_parts() after the plants' classes
    CellBudget budget;
};

// What classify_frame() left out and added.
struct ModelClassCounts {
    std::size_t cells_over_budget = 0;   // vegetated cells left unclassified by the budget
    WeedTargetCounts weed_targets;
};

// One frame's classes from `model`, after detect(): plant_features(),
// cell_features(), classify_cells(), classify_plants() and, with
// params.weed_parts, add_weed_parts(). `classes` and `probabilities` (at
// least kMaxPlants each) get an entry per plant of `det`, Unknown and -1
// when the plants' features cannot be computed (a frame without its bgr
// image). The daemon's in-box provider and stemd-detect both run this.
ModelClassCounts classify_frame(const PlantClassifier& model, const ModelClassParams& params, const FrameView& frame,
                                const Params& detect_params, const Workspace& detect_workspace, Detections& det,
                                ClassifyWorkspace& plants, CellWorkspace& cells, std::span<float> probabilities,
                                std::span<PlantClass> classes);

}  // namespace stemd::vision
