#include "stemd/vision/detect.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <span>
#include <type_traits>

#include "stemd/base/clock.hpp"
#include "stemd/vision/contour.hpp"
#include "stemd/vision/leaves.hpp"
#include "stemd/vision/stem.hpp"

namespace stemd::vision {

namespace {

DetectStatus check_frame(const FrameView& frame, const Params& params, cv::Size expected)
{
    const cv::Mat& primary = params.segmentation == Segmentation::mask ? frame.mask : frame.bgr;
    if (params.segmentation == Segmentation::mask && frame.mask.empty())
        return DetectStatus::missing_mask;
    if (primary.empty())
        return DetectStatus::empty_frame;
    if (primary.type() != (params.segmentation == Segmentation::mask ? CV_8UC1 : CV_8UC3))
        return DetectStatus::bad_format;
    if (primary.size() != expected)
        return DetectStatus::size_mismatch;
    if (uses_nir(params.segmentation)) {
        if (frame.nir.empty() || frame.nir.size() != expected)
            return DetectStatus::missing_nir;
        if (frame.nir.type() != CV_8UC1)
            return DetectStatus::bad_format;
    }
    return DetectStatus::ok;
}

// Length of a closed 8-connected contour: 1 per straight step, sqrt(2) per diagonal.
double contour_length_px(const std::vector<cv::Point>& contour)
{
    if (contour.size() < 2)
        return static_cast<double>(contour.size());
    int straight = 0, diagonal = 0;
    for (std::size_t i = 0; i < contour.size(); ++i) {
        const cv::Point d = contour[(i + 1) % contour.size()] - contour[i];
        (d.x != 0 && d.y != 0 ? diagonal : straight) += 1;
    }
    return straight + std::numbers::sqrt2 * diagonal;
}

// Pieces are grouped on a mask of kGroupCellPx x kGroupCellPx cells, where
// a dilation by half the gap is cheap: pieces at most the gap apart always
// join, pieces up to about two cells farther may.
constexpr int kGroupCellPx = 4;

// exg_and_ndvi: how far above the soil's chromatic ExG mode (in the soil's
// standard deviations) a seed must be green; 2 is beyond the soil's noise.
constexpr double kGreenerThanSoilSigmas = 2.0;

// A mixed edge pixel must also lie beyond the soil's noise (the same bar
// as exg_and_ndvi's greenness): the halfway point next to a faint speck is
// inside the soil's spread.
constexpr double kEdgeAboveSoilSigmas = 2.0;

// RGB: a seed's G/R exceeds the soil's G/R (seen under the same light) by
// this factor. Leaves measured 1.25 (their 10th percentile) to 1.5 (median)
// times their soil's G/R on carrot-dev and BoniRob; at BoniRob's soil (G/R
// 0.835) 1.25 is the absolute rule it replaced (G over R by 2 % of the
// brightness), which failed under a colour cast.
constexpr double kLeafGreenOverSoil = 1.25;

// The dilation radius in cells, 0 when grouping is off.
int group_radius_cells(const Params& params)
{
    if (params.group_gap_mm <= 0 || params.gsd_mm_per_px <= 0)
        return 0;
    const double radius_px = params.group_gap_mm / (2.0 * params.gsd_mm_per_px);
    return std::clamp(static_cast<int>(std::ceil(radius_px / kGroupCellPx)), 1, kMaxClosingRadiusPx);
}

// The contour point nearest `target`: where a leaf that is a piece of its
// own meets the rest of its plant.
cv::Point2f nearest_point(std::span<const cv::Point> contour, cv::Point2f target)
{
    cv::Point2f best = contour.empty() ? target : cv::Point2f(contour[0]);
    float best_d2 = std::numeric_limits<float>::max();
    for (const cv::Point& p : contour) {
        const cv::Point2f d = cv::Point2f(p) - target;
        const float d2 = d.dot(d);
        if (d2 < best_d2) {
            best_d2 = d2;
            best = cv::Point2f(p);
        }
    }
    return best;
}

}  // namespace

// The depth a convexity defect must reach to cut a plant (or piece) of
// this equivalent radius: a fixed depth over-cuts large plants' wavy
// edges and under-cuts small ones, so it also scales with the plant.
float cut_depth_px(const Params& params, double radius_px)
{
    return static_cast<float>(
        std::max(params.defect_depth_mm / params.gsd_mm_per_px, params.defect_depth_rel * radius_px));
}

// One past the last of the pieces in ws.piece_order_ (sorted by group)
// that share the group of the piece at `begin`.
int group_end(const Workspace& ws, int begin)
{
    const int pieces = static_cast<int>(ws.piece_order_.size());
    const int group = ws.piece_group_[static_cast<std::size_t>(ws.piece_order_[static_cast<std::size_t>(begin)])];
    int end = begin + 1;
    while (end < pieces && ws.piece_group_[static_cast<std::size_t>(ws.piece_order_[static_cast<std::size_t>(end)])] == group)
        ++end;
    return end;
}

// Pieces by group, then raster order, so each group's first piece is its
// top-most one (std::sort: stable_sort would allocate).
void sort_pieces_by_group(Workspace& ws)
{
    for (std::size_t i = 0; i < ws.piece_order_.size(); ++i)
        ws.piece_order_[i] = static_cast<int>(i);
    std::sort(ws.piece_order_.begin(), ws.piece_order_.end(), [&](int a, int b) {
        const int group_a = ws.piece_group_[static_cast<std::size_t>(a)];
        const int group_b = ws.piece_group_[static_cast<std::size_t>(b)];
        return group_a != group_b ? group_a < group_b : a < b;
    });
}

// Whether a piece is a plant with leaves of its own: its outline has three
// or more cuts at the depth detect() would cut a plant of its size (a
// single leaf can show two shallow ones where its blade meets the
// petiole). A contour too long to trace is no single leaf either.
bool has_own_leaves(const Component& piece, const Params& params, Workspace& ws)
{
    if (static_cast<double>(piece.area_px) * params.gsd_mm_per_px * params.gsd_mm_per_px < params.min_plant_area_mm2)
        return false;
    if (!trace_outer_contour(ws.closed_, piece.first_pixel, ws.contour_))
        return true;
    convex_hull_indices(ws.contour_, ws.hull_, ws.hull_order_);
    const double radius_px = std::sqrt(static_cast<double>(piece.area_px) / std::numbers::pi);
    convexity_defects(ws.contour_, ws.hull_, cut_depth_px(params, radius_px), ws.defects_);
    return ws.defects_.size() >= 3;
}

// The group gap joins a leaf whose petiole fell below the threshold to its
// plant, but also neighbours that merely grew close. Within a group:
//  - a piece with leaves of its own (three or more cuts) has a stem of its
//    own and is a plant;
//  - a detached leaf is elongated and its midrib points at its plant's
//    stem: a piece whose long axis passes within a plant's equivalent
//    radius of that plant's centre joins it (the nearest such plant,
//    measured from the plant's equivalent circle); a speck below the
//    plant size joins the nearest plant;
//  - any other piece (a compact seedling, a leaf pointing elsewhere) is a
//    plant of its own.
// A group without such a plant stays one plant (every leaf of a seedling
// apart). ws.piece_order_ must be sorted by group. Returns whether any
// group was split; the groups are then renumbered in the raster order of
// their first piece.
bool split_groups_at_rosettes(const Params& params, Workspace& ws)
{
    const int pieces = static_cast<int>(ws.piece_order_.size());
    auto& rosette = ws.piece_rosette_;
    rosette.assign(static_cast<std::size_t>(pieces), 0);
    const double pixel_area_mm2 = params.gsd_mm_per_px * params.gsd_mm_per_px;
    int next_group = 0;
    for (const int g : ws.piece_group_)
        next_group = std::max(next_group, g + 1);
    bool split = false;
    for (int begin = 0; begin < pieces;) {
        const int group = ws.piece_group_[static_cast<std::size_t>(ws.piece_order_[static_cast<std::size_t>(begin)])];
        const int end = group_end(ws, begin);
        const std::span<const int> members(ws.piece_order_.data() + begin, static_cast<std::size_t>(end - begin));
        begin = end;
        if (members.size() < 2)
            continue;
        int rosettes = 0;
        for (const int m : members) {
            rosette[static_cast<std::size_t>(m)] = has_own_leaves(ws.components_[static_cast<std::size_t>(m)], params, ws);
            rosettes += rosette[static_cast<std::size_t>(m)];
        }
        if (rosettes == 0)
            continue;
        // The group's first rosette keeps its number; every other plant
        // takes a new one.
        bool first = true;
        for (const int m : members) {
            if (!rosette[static_cast<std::size_t>(m)])
                continue;
            if (!first) {
                ws.piece_group_[static_cast<std::size_t>(m)] = next_group++;
                split = true;
            }
            first = false;
        }
        for (const int m : members) {
            if (rosette[static_cast<std::size_t>(m)])
                continue;
            const Component& piece = ws.components_[static_cast<std::size_t>(m)];
            const bool speck = static_cast<double>(piece.area_px) * pixel_area_mm2 < params.min_plant_area_mm2;
            Leaf leaf;
            if (!speck && trace_outer_contour(ws.closed_, piece.first_pixel, ws.contour_))
                leaf = leaf_from_polygon(ws.contour_, 0, static_cast<int>(ws.contour_.size()) - 1);
            const bool has_axis = !speck && leaf.elongation >= kMinElongationForAxis;
            double best = std::numeric_limits<double>::max();
            int joined = -1;
            for (const int r : members) {
                if (!rosette[static_cast<std::size_t>(r)])
                    continue;
                const Component& plant = ws.components_[static_cast<std::size_t>(r)];
                const double area = static_cast<double>(plant.area_px);
                const double cx = plant.sum_x / area, cy = plant.sum_y / area;
                const double radius = std::sqrt(area / std::numbers::pi);
                if (has_axis) {
                    const double off_axis = std::abs((cx - leaf.centre.x) * leaf.axis.y - (cy - leaf.centre.y) * leaf.axis.x);
                    if (off_axis > radius)
                        continue;
                } else if (!speck) {
                    continue;
                }
                const double dx = std::max({piece.x_min - cx, 0.0, cx - piece.x_max});
                const double dy = std::max({piece.y_min - cy, 0.0, cy - piece.y_max});
                const double gap = std::hypot(dx, dy) - radius;
                if (gap < best) {
                    best = gap;
                    joined = r;
                }
            }
            if (joined >= 0) {
                ws.piece_group_[static_cast<std::size_t>(m)] = ws.piece_group_[static_cast<std::size_t>(joined)];
                split = split || ws.piece_group_[static_cast<std::size_t>(joined)] != group;
            } else {
                ws.piece_group_[static_cast<std::size_t>(m)] = next_group++;
                split = true;
            }
        }
    }
    if (!split)
        return false;
    // Renumber by first piece: pieces are in the raster order of their
    // top-most pixel.
    ws.group_rank_.assign(static_cast<std::size_t>(next_group), -1);
    int ranked = 0;
    for (int i = 0; i < pieces; ++i) {
        int& rank = ws.group_rank_[static_cast<std::size_t>(ws.piece_group_[static_cast<std::size_t>(i)])];
        if (rank < 0)
            rank = ranked++;
        ws.piece_group_[static_cast<std::size_t>(i)] = rank;
    }
    return true;
}

// How far from a pixel above the sparse index's level the index must be
// known: the mixed-edge window, and the closing's reach, so that a piece
// the sampled rows miss but the closing would join to a plant is computed
// with it. (The grouping's reach, 28 px at 0.33 mm/px, cost 6 % more index
// work on the bench's late frames for pieces that rare.)
int sparse_reach_px(const Params& params)
{
    const int edge = std::clamp(params.edge_radius_px, 0, kMaxClosingRadiusPx);
    const int closing = 2 * std::clamp(params.closing_radius_px, 0, kMaxClosingRadiusPx);
    return std::clamp(std::max(edge, closing), 1, kSparseTilePx);
}

// The index `method` computes, smoothed, into ws.index_, and its histogram.
// `allow_sparse`: the caller thresholds it with auto_threshold and
// completes it when the threshold falls below the sparse level.
void compute_index(const FrameView& frame, Segmentation method, const Params& params, Workspace& ws,
                   bool allow_sparse)
{
    ws.sparse_pending_ = false;
    const bool rgb = method == Segmentation::chromatic_exg || method == Segmentation::exg;
    if (allow_sparse && rgb && params.sparse_index && params.smooth_index) {
        const SparseLevel level{.method = params.threshold, .soil_sigmas = params.soil_sigmas};
        sparse_smoothed_index(frame.bgr, method == Segmentation::exg ? RgbIndex::exg : RgbIndex::chromatic_exg, level,
                              sparse_reach_px(params), ws.sparse_, ws.raw_index_, ws.index_, ws.histogram_);
        ws.sparse_pending_ = ws.sparse_.computed_tiles() < ws.sparse_.tiles();
        return;
    }
    cv::Mat& index = params.smooth_index ? ws.raw_index_ : ws.index_;
    if (method == Segmentation::ndvi)
        ndvi(frame.bgr, frame.nir, index);
    else if (method == Segmentation::chromatic_exg)
        chromatic_excess_green(frame.bgr, index);
    else
        excess_green(frame.bgr, index);
    if (params.smooth_index)
        smooth_binomial3(ws.raw_index_, ws.smooth_row_.data(), ws.index_);
    compute_histogram(ws.index_, ws.histogram_);
}

// The index `method` computes, thresholded automatically into `bits`; the
// threshold and the class separation go into `stats`. `t_indexed_ns`: when
// the index (and its smoothing) was done, for the stage times.
void threshold_index(const FrameView& frame, Segmentation method, const Params& params, Workspace& ws,
                     DetectStats& stats, BitMask& bits, std::int64_t& t_indexed_ns)
{
    compute_index(frame, method, params, ws, true);
    stats.threshold = auto_threshold(ws.histogram_, params.threshold, params.soil_sigmas);
    if (ws.sparse_pending_ && stats.threshold < ws.sparse_.level()) {
        // Pixels between the threshold and the level may lie in soil tiles:
        // the whole frame, and its exact histogram, decide instead.
        complete_sparse_index(frame.bgr, ws.sparse_, ws.raw_index_, ws.index_, ws.histogram_);
        ws.sparse_pending_ = false;
        stats.threshold = auto_threshold(ws.histogram_, params.threshold, params.soil_sigmas);
    }
    if (ws.sparse_.tiles() > 0 && params.sparse_index && params.smooth_index &&
        (method == Segmentation::chromatic_exg || method == Segmentation::exg)) {
        stats.index_tiles = ws.sparse_.tiles();
        stats.index_tiles_computed = ws.sparse_.computed_tiles();
    }
    t_indexed_ns = base::monotonic_ns();
    const double separation = class_separation(ws.histogram_, stats.threshold);
    stats.class_separation = static_cast<float>(separation);
    stats.no_vegetation = separation < params.min_class_separation;
    // No second class: an empty mask (index > 255 never holds), so the rest
    // of the pipeline runs as usual and finds nothing.
    threshold_to_bits(ws.index_, stats.no_vegetation ? 255 : stats.threshold, bits);
}

Workspace::Workspace(cv::Size frame_size, const Params& params)
    : frame_size_(frame_size)
{
    const int width = std::max(frame_size.width, 0);
    const int height = std::max(frame_size.height, 0);
    raw_index_.create(height, width, CV_8UC1);
    index_.create(height, width, CV_8UC1);
    green_index_.create(height, width, CV_8UC1);
    smooth_row_.resize(static_cast<std::size_t>(width));
    sparse_.reserve(width, height);
    vegetation_.reset(width, height);
    thresholded_.reset(width, height);
    second_.reset(width, height);
    opened_.reset(width, height);
    edged_.reset(width, height);
    edges_.reserve(width, height);
    closed_.reset(width, height);
    reserved_radius_px_ = std::clamp(params.closing_radius_px, 0, kMaxClosingRadiusPx);
    closing_.reserve(width, height, kMaxClosingRadiusPx);
    labels_.reserve(width, height);
    // 8-connected components are at least one pixel apart in both directions.
    const std::size_t max_components =
        static_cast<std::size_t>((width + 1) / 2) * static_cast<std::size_t>((height + 1) / 2);
    components_.reserve(max_components);
    groups_.reserve(max_components);
    piece_group_.reserve(max_components);
    piece_order_.reserve(max_components);
    group_rank_.reserve(max_components);
    piece_plant_.reserve(max_components);
    piece_rosette_.reserve(max_components);
    keep_.reserve(max_components);
    fringe_passed_.reserve(max_components);
    cells_.reset(width / kGroupCellPx + 1, height / kGroupCellPx + 1);
    grouped_.reset(cells_.width(), cells_.height());
    group_labels_.reserve(cells_.width(), cells_.height());
    // Room for ordinary plants; longer (comb-like) contours are truncated,
    // counted, and the plant falls back to its centre of mass.
    contour_.reserve(static_cast<std::size_t>(2 * (width + height)) * 8);
    hull_.reserve(contour_.capacity() + 2);  // the monotone chain holds one extra point while building
    hull_order_.reserve(contour_.capacity());
    defects_.reserve(kMaxLeaves * 4);
    // Set the kernels up once so the first frame allocates nothing either.
    if (width > 0 && height > 0) {
        close_mask(vegetation_, reserved_radius_px_, closed_, closing_);
        open_mask(thresholded_, std::clamp(params.opening_radius_px, 0, kMaxClosingRadiusPx), opened_, opening_);
        dilate_mask(cells_, group_radius_cells(params), grouped_, grouping_);
    }
}

void detect(const FrameView& frame, const Params& params, Workspace& ws, Detections& out, StageTimes* times)
{
    if (params.segmentation == Segmentation::automatic) {
        // The frame's planes pick the method; Params holds no heap memory,
        // so the copy allocates nothing.
        static_assert(std::is_trivially_copyable_v<Params>);
        Params resolved = params;
        resolved.segmentation = resolve_segmentation(params.segmentation, !frame.nir.empty());
        detect(frame, resolved, ws, out, times);
        return;
    }
    out.plants.clear();
    out.stats = DetectStats{};
    out.status = check_frame(frame, params, ws.frame_size_);
    if (out.status != DetectStatus::ok)
        return;
    StageTimes t;
    const std::int64_t t0 = base::monotonic_ns();

    // 1. Vegetation index and threshold (or the external mask).
    std::int64_t t_index = t0;
    if (params.segmentation == Segmentation::mask) {
        pack_mask(frame.mask, params.mask_vegetation, ws.vegetation_);
        t_index = base::monotonic_ns();
    } else {
        // exg_and_ndvi: NIR outlines the plants, and a piece of it is a plant
        // only where it is green too (a seed must lie in the ExG mask).
        const bool green_seeds = params.segmentation == Segmentation::exg_and_ndvi;
        threshold_index(frame, green_seeds ? Segmentation::ndvi : params.segmentation, params, ws, out.stats,
                        ws.thresholded_, t_index);
        // Specks and fringes vanish under the opening; whatever survives it
        // keeps its whole component, thin petioles and grass blades included.
        // From RGB alone, a seed must also have a leaf's colour: more green
        // for its red than the soil under the same light (a yellowish clod
        // or a fringe is as green in ExG).
        const bool leaf_colour_seeds =
            params.leaf_colour &&
            (params.segmentation == Segmentation::exg || params.segmentation == Segmentation::chromatic_exg);
        const int opening_radius = std::clamp(params.opening_radius_px, 0, kMaxClosingRadiusPx);
        if (opening_radius > 0 || green_seeds || leaf_colour_seeds) {
            // The seeds: the opening of the pixels that pass every test, so a
            // seed is a compact core, not one lucky pixel. The NIR path tests
            // every opened pixel's greenness, so it needs the opening itself.
            const BitMask* to_open = &ws.thresholded_;
            SoilColour soil;
            if (leaf_colour_seeds) {
                ws.second_ = ws.thresholded_;   // same size: no allocation
                soil = soil_colour(frame.bgr, ws.thresholded_);
                keep_greener_than_red(frame.bgr, soil, kLeafGreenOverSoil, ws.second_);
                to_open = &ws.second_;
            }
            if (opening_radius > 0 && green_seeds)
                open_mask(*to_open, opening_radius, ws.opened_, ws.opening_);
            else if (opening_radius > 0)
                // Only which components hold a seed matters below, and the
                // erosion tells that as the opening does (erode_mask).
                erode_mask(*to_open, opening_radius, ws.opened_, ws.opening_);
            else
                ws.opened_ = *to_open;
            label_components(ws.thresholded_, ws.labels_, ws.components_);
            if (green_seeds)
                // Greener than the soil's own spread: a live leaf is, dead
                // straw and leaves (bright in NIR too) are not. Thin and dark
                // seedlings are far less green than a sugar-beet leaf, hence
                // the low bar. Only seeds of components not yet kept are
                // tested, so the index is needed only on their rows.
                mark_green_seeded_components(frame.bgr, kGreenerThanSoilSigmas, ws.opened_, ws.labels_, ws.sparse_,
                                             ws.raw_index_, ws.green_index_, ws.keep_);
            else
                mark_seeded_components(ws.labels_, ws.opened_, ws.keep_);
            if (leaf_colour_seeds)
                out.stats.colour_fringes = drop_colour_fringes(frame.bgr, soil, kLeafGreenOverSoil, ws.labels_,
                                                               ws.keep_, ws.fringe_passed_);
            paint_kept_components(ws.labels_, ws.keep_, ws.vegetation_);
        } else {
            std::swap(ws.thresholded_, ws.vegetation_);
        }
        // The threshold decides which plants there are; their outline then
        // takes the mixed pixels that are at least half leaf. RGB indices
        // only: with NDVI it cost BoniRob a sugar-beet stem.
        const int edge_radius = std::clamp(params.edge_radius_px, 0, kMaxClosingRadiusPx);
        const bool rgb_index =
            params.segmentation == Segmentation::exg || params.segmentation == Segmentation::chromatic_exg;
        if (edge_radius > 0 && rgb_index && !out.stats.no_vegetation) {
            // Every plant pixel is above the threshold, so a pixel must be
            // above the halfway point between the soil and the threshold to
            // be more than halfway to the plant's mean: an exact bound that
            // leaves far fewer pixels to look at.
            const int soil = soil_mode(ws.histogram_);
            const int floor = std::max(soil_noise_threshold(ws.histogram_, kEdgeAboveSoilSigmas),
                                       (soil + out.stats.threshold) / 2);
            extend_to_mixed_edges(ws.index_, ws.vegetation_, soil, floor, edge_radius, ws.edged_, ws.edges_);
            std::swap(ws.vegetation_, ws.edged_);
        }
    }
    const std::int64_t t_threshold = base::monotonic_ns();
    out.stats.vegetation_px = static_cast<int>(ws.vegetation_.count());

    // 2. Closing.
    close_mask(ws.vegetation_, std::clamp(params.closing_radius_px, 0, kMaxClosingRadiusPx), ws.closed_,
               ws.closing_);
    const std::int64_t t_closing = base::monotonic_ns();

    // 3. Plants: pieces of the closed mask, grouped when they lie closer
    // than the group gap.
    label_components(ws.closed_, ws.labels_, ws.components_);
    const int pieces = static_cast<int>(ws.components_.size());
    out.stats.components = pieces;
    ws.piece_group_.resize(static_cast<std::size_t>(pieces));
    ws.piece_order_.resize(static_cast<std::size_t>(pieces));
    ws.piece_plant_.assign(static_cast<std::size_t>(pieces), 0);
    const int group_radius = group_radius_cells(params);
    if (group_radius > 0 && pieces > 1) {
        reduce_labelled_mask(ws.labels_, kGroupCellPx, ws.cells_);
        dilate_mask(ws.cells_, group_radius, ws.grouped_, ws.grouping_);
        label_components(ws.grouped_, ws.group_labels_, ws.groups_);
        // Groups numbered in the order of their first piece, so plants keep
        // the raster order of their top-most pixel.
        ws.group_rank_.assign(ws.groups_.size(), -1);
        int ranked = 0;
        for (int i = 0; i < pieces; ++i) {
            const cv::Point first = ws.components_[static_cast<std::size_t>(i)].first_pixel;
            const int g = component_at(ws.group_labels_, {first.x / kGroupCellPx, first.y / kGroupCellPx});
            int& rank = ws.group_rank_[static_cast<std::size_t>(g)];
            if (rank < 0)
                rank = ranked++;
            ws.piece_group_[static_cast<std::size_t>(i)] = rank;
        }
    } else {
        for (int i = 0; i < pieces; ++i)
            ws.piece_group_[static_cast<std::size_t>(i)] = i;
    }
    sort_pieces_by_group(ws);
    if (group_radius > 0 && pieces > 1 && split_groups_at_rosettes(params, ws))
        sort_pieces_by_group(ws);
    const std::int64_t t_plants = base::monotonic_ns();

    // 4. Leaves and stems, plant by plant.
    const double pixel_area_mm2 = params.gsd_mm_per_px * params.gsd_mm_per_px;
    for (int begin = 0; begin < pieces;) {
        const int end = group_end(ws, begin);
        const std::span<const int> members(ws.piece_order_.data() + begin, static_cast<std::size_t>(end - begin));
        begin = end;
        auto add_plant = [&](const Plant& plant) {
            out.plants.push_back(plant);
            for (const int m : members)
                ws.piece_plant_[static_cast<std::size_t>(m)] = static_cast<std::uint16_t>(out.plants.size());
        };

        long area_px = 0;
        double sum_x = 0, sum_y = 0;
        int x_min = std::numeric_limits<int>::max(), y_min = x_min, x_max = -1, y_max = -1;
        for (const int m : members) {
            const Component& c = ws.components_[static_cast<std::size_t>(m)];
            area_px += c.area_px;
            sum_x += c.sum_x;
            sum_y += c.sum_y;
            x_min = std::min(x_min, c.x_min);
            y_min = std::min(y_min, c.y_min);
            x_max = std::max(x_max, c.x_max);
            y_max = std::max(y_max, c.y_max);
        }
        if (static_cast<double>(area_px) * pixel_area_mm2 < params.min_plant_area_mm2) {
            ++out.stats.small_components;
            continue;
        }
        if (out.plants.full()) {
            ++out.stats.plants_over_capacity;
            continue;
        }
        Plant plant;
        plant.area_px = static_cast<int>(area_px);
        plant.bbox = cv::Rect(x_min, y_min, x_max - x_min + 1, y_max - y_min + 1);
        plant.centre_of_mass = {static_cast<float>(sum_x / static_cast<double>(area_px)),
                                static_cast<float>(sum_y / static_cast<double>(area_px))};
        plant.first_pixel = ws.components_[static_cast<std::size_t>(members.front())].first_pixel;

        const double radius_px = std::sqrt(static_cast<double>(area_px) / std::numbers::pi);
        if (params.stem_estimator != StemEstimator::com) {
            const float depth_px = cut_depth_px(params, radius_px);
            bool overflow = false;
            double hull_area_px = 0, perimeter_px = 0;
            for (const int m : members) {
                const Component& c = ws.components_[static_cast<std::size_t>(m)];
                if (!trace_outer_contour(ws.closed_, c.first_pixel, ws.contour_)) {
                    overflow = true;
                    break;
                }
                convex_hull_indices(ws.contour_, ws.hull_, ws.hull_order_);
                convexity_defects(ws.contour_, ws.hull_, depth_px, ws.defects_);
                plant.defects += static_cast<int>(ws.defects_.size());
                FixedVector<Leaf, kMaxLeaves> piece_leaves;
                out.stats.leaves_over_capacity += leaves_from_defects(ws.contour_, ws.defects_, piece_leaves);
                if (piece_leaves.empty() && members.size() > 1) {
                    // A piece without cuts is one leaf, rooted where it
                    // comes nearest the plant's centre.
                    Leaf leaf = leaf_from_polygon(ws.contour_, 0, static_cast<int>(ws.contour_.size()) - 1);
                    leaf.root = leaf.cut_a = leaf.cut_b = nearest_point(ws.contour_, plant.centre_of_mass);
                    piece_leaves.push_back(leaf);
                }
                for (const Leaf& leaf : piece_leaves)
                    if (!plant.leaves.push_back(leaf))
                        ++out.stats.leaves_over_capacity;
                hull_area_px += convex_hull_area_px(ws.contour_, ws.hull_);
                perimeter_px += contour_length_px(ws.contour_);
            }
            if (overflow) {
                ++out.stats.contour_overflows;
                plant.leaves.clear();
                plant.stem = plant.centre_of_mass;
                plant.com_reason = ComReason::contour_overflow;
                plant.confidence = 0;
                plant.has_stem = false;
                ++out.stats.stemless;
                add_plant(plant);
                continue;
            }
            plant.hull_fill = static_cast<float>(static_cast<double>(area_px) / std::max(hull_area_px, 1.0));
            plant.mean_width_mm = static_cast<float>(2.0 * static_cast<double>(area_px) /
                                                     std::max(perimeter_px, 1.0) * params.gsd_mm_per_px);
        }
        const StemEstimate stem = estimate_stem({plant.leaves.begin(), plant.leaves.size()}, plant.centre_of_mass,
                                                plant.bbox, radius_px, params);
        plant.stem = stem.stem;
        plant.method = stem.method;
        plant.estimator = stem.estimator;
        plant.confidence = stem.confidence;
        plant.com_reason = stem.com_reason;
        if (stem.com_reason == ComReason::outside_box)
            ++out.stats.outside_box_fallbacks;
        // Linear-leaved blobs (grass) have no stem to strike: thin on
        // average and mostly empty hull (blades fanned out from the base).
        const bool grass = params.stem_estimator == StemEstimator::robust &&
                           static_cast<double>(area_px) * pixel_area_mm2 >= params.grass_min_area_mm2 &&
                           plant.mean_width_mm < params.grass_max_width_mm &&
                           plant.hull_fill < params.grass_max_hull_fill;
        if (grass)
            plant.confidence = 0;
        if (grass || plant.confidence < params.min_confidence) {
            plant.has_stem = false;
            ++out.stats.stemless;
        }
        add_plant(plant);
    }
    const std::int64_t t_leaves = base::monotonic_ns();
    if (times) {
        t.index_ns = t_index - t0;
        t.threshold_ns = t_threshold - t_index;
        t.closing_ns = t_closing - t_threshold;
        t.plants_ns = t_plants - t_closing;
        t.leaves_ns = t_leaves - t_plants;
        t.total_ns = t_leaves - t0;
        *times = t;
    }
}

std::size_t Workspace::reserved_bytes() const
{
    return (raw_index_.total() + index_.total() + green_index_.total()) * index_.elemSize() + smooth_row_.capacity() * sizeof(std::uint16_t) +
           vegetation_.reserved_bytes() + thresholded_.reserved_bytes() + second_.reserved_bytes() + opened_.reserved_bytes() + edged_.reserved_bytes() + edges_.reserved_bytes() + keep_.capacity() + fringe_passed_.capacity() + closed_.reserved_bytes() +
           opening_.reserved_bytes() + closing_.reserved_bytes() + cells_.reserved_bytes() +
           grouped_.reserved_bytes() + grouping_.reserved_bytes() + group_labels_.reserved_bytes() + (groups_.capacity()) * sizeof(Component) +
           (piece_group_.capacity() + piece_order_.capacity() + group_rank_.capacity()) * sizeof(int) +
           piece_plant_.capacity() * sizeof(std::uint16_t) + piece_rosette_.capacity() + labels_.reserved_bytes() + components_.capacity() * sizeof(Component) +
           contour_.capacity() * sizeof(cv::Point) + (hull_.capacity() + hull_order_.capacity()) * sizeof(int) +
           defects_.capacity() * sizeof(Defect) + sparse_.reserved_bytes();
}

Detections detect(const FrameView& frame, const Params& params)
{
    const cv::Mat& primary = params.segmentation == Segmentation::mask ? frame.mask : frame.bgr;
    Workspace ws(primary.size(), params);
    Detections out;
    detect(frame, params, ws, out);
    return out;
}

}  // namespace stemd::vision
