// The smoothed RGB index on fewer pixels. Its pass is bound by reading and
// widening every pixel, not by its arithmetic, and soil covers most of a
// field frame: the index is computed in full only in 64x64 tiles near
// vegetation, found from every 8th row.
//
// 1. Every 8th row (rows 4, 12, 20, ...; the frame's last row when the
//    last band is too short for its row 4) is smoothed, from the raw index
//    on it and its two neighbours. Its histogram gives the soil mode and
//    the "vegetation possible" level: soil_noise_threshold(sampled, sigmas).
// 2. A tile is computed when its part of a sampled row has a pixel above
//    that level, or the raw index on a row beside it (computed for the
//    smoothing anyway) has a run of 4 pixels above it (single noisy pixels
//    do not make one). A computed tile with a pixel above the level within
//    `reach_px` of a side (or corner) also has the neighbour across it
//    computed, and so on: every 8-connected piece of pixels above the level
//    that touches a sampled row is computed whole, with a margin of
//    reach_px around it. When a third of the tiles or more are found at
//    once, every tile is computed (the whole-frame result).
// 3. The other tiles are set to the soil mode. The histogram is exact on
//    computed tiles; a soil tile adds its sampled rows, each counted for
//    the rows of its band (8), so the counts sum to the frame's pixels.
//    When every tile is computed and the sampled rows hold at least
//    kSampledPixelsForEstimate pixels, every tile's sampled rows stand for
//    their bands in the same way: vegetation then fills a third of the
//    tiles or more, and an eighth of its pixels gives its statistics (on
//    CWFID's and carrot-dev's frames the threshold is the exact
//    histogram's, or one level above). A smaller frame is counted exactly:
//    its few sampled rows would make a noisy soil mode and spread.
//
// The bound: a piece above the level is missed only when it touches no
// sampled row (it lies within the 7 rows between two of them), its raw
// core crosses neither row beside them (so in practice it is at most 5
// rows tall) and it lies in no computed tile (farther than reach_px from
// any other piece found). With a final threshold at or above the level,
// every pixel above the threshold lies in a computed tile but for such
// pieces; a threshold below the level needs complete_sparse_index, which
// gives the whole-frame result.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/plants.hpp"
#include "stemd/vision/threshold.hpp"

namespace stemd::vision {

inline constexpr int kSparseTilePx = 64;    // one BitMask word wide
inline constexpr int kSparseRowStep = 8;    // a sampled row every 8 rows
// The fewest sampled pixels from which the histogram of a frame computed
// whole is estimated (step 3). On 160 px windows (3 200 sampled pixels)
// the estimate lost leaves; a 1280x720 frame's 90 sampled rows hold
// 115 200 pixels.
inline constexpr long kSampledPixelsForEstimate = 1L << 16;

enum class RgbIndex : std::uint8_t { exg, chromatic_exg };

// The "vegetation possible" level: the automatic threshold of the sampled
// rows' histogram less one soil sigma of it (at least one level), since
// the frame's own threshold comes from the final histogram and may fall a
// little lower.
struct SparseLevel {
    ThresholdMethod method = ThresholdMethod::above_soil;
    double soil_sigmas = 5.0;
};

// Scratch for one frame size, allocated once (no allocation per frame).
class SparseIndexScratch {
public:
    void reserve(int width_px, int height_px);
    std::size_t reserved_bytes() const;
    int tile_cols() const { return cols_; }
    int tile_rows() const { return rows_; }
    int tiles() const { return cols_ * rows_; }
    int computed_tiles() const { return computed_; }
    bool computed(int tile_col, int tile_row) const { return state_[static_cast<std::size_t>(tile_row * cols_ + tile_col)] != 0; }
    // The last frame's level and soil mode (from the sampled rows).
    int level() const { return level_; }
    int soil_level() const { return soil_; }

private:
    friend int sparse_smoothed_index(const cv::Mat&, RgbIndex, const SparseLevel&, int, SparseIndexScratch&, cv::Mat&,
                                     cv::Mat&, Histogram&);
    friend void complete_sparse_index(const cv::Mat&, SparseIndexScratch&, cv::Mat&, cv::Mat&, Histogram&);
    friend int mark_green_seeded_components(const cv::Mat&, double, const BitMask&, const LabelScratch&,
                                            SparseIndexScratch&, cv::Mat&, cv::Mat&, std::vector<std::uint8_t>&);
    friend struct SparseTiles;
    int width_ = 0, height_ = 0, cols_ = 0, rows_ = 0, computed_ = 0;
    int level_ = 255, soil_ = 0;
    RgbIndex kind_ = RgbIndex::chromatic_exg;
    float mean_brightness_ = 0;
    std::vector<std::uint8_t> state_;        // per tile: 0 soil, 1 computed (or queued)
    std::vector<int> queue_;                 // tiles to compute
    std::vector<std::uint8_t> raw_row_;      // per row: raw index computed for the whole row
    std::vector<std::uint8_t> smoothed_row_; // per row: the index holds the whole row smoothed
    std::vector<std::uint16_t> row_sums_;    // smoothing scratch, one per column
    std::vector<cv::Range> raw_range_;       // per row: the columns whose raw index the greenness test computed
};

// The smoothed index (3x3 binomial of excess_green or chromatic_excess_green)
// into `index_u8` on the computed tiles and the soil mode elsewhere, the
// raw index into `raw_u8` where it was needed, and the histogram estimated
// as above. `raw_u8` and `index_u8` are allocated at bgr's size; reach_px
// is at most kSparseTilePx. Returns the level. When every tile is computed
// (or the sampled rows leave no soil mode), the index is the whole frame's
// and so is the histogram, estimated from the sampled rows on a frame
// whose sampled rows hold kSampledPixelsForEstimate pixels or more.
int sparse_smoothed_index(const cv::Mat& bgr, RgbIndex kind, const SparseLevel& level, int reach_px,
                          SparseIndexScratch& scratch, cv::Mat& raw_u8, cv::Mat& index_u8, Histogram& histogram);

// Computes the tiles the last sparse_smoothed_index left at the soil level
// and the exact histogram: then equal to smoothing the whole-frame index.
void complete_sparse_index(const cv::Mat& bgr, SparseIndexScratch& scratch, cv::Mat& raw_u8, cv::Mat& index_u8,
                           Histogram& histogram);

// exg_and_ndvi's greenness test, computed only where it decides something:
// keep (one entry per component of `labels`, resized; reserve it) = 1 for
// each component holding a pixel of `seeds` (a subset of the labelled mask)
// whose smoothed chromatic Excess Green lies above the soil's noise,
// soil_noise_threshold(sampled, sigmas) of the histogram of the sampled
// rows alone (step 1 above). Row by row, only the seeds of components not
// yet kept are tested, and the index is computed from the first to the
// last of them (the raw index one pixel further, for the smoothing); there
// it is the whole-frame index. So for the same bar the components kept are
// those the test on every seed pixel of the whole frame keeps, and a
// component is done once one of its seeds passes: under a closed canopy
// most rows need no index at all. The index goes into `raw_u8` and
// `index_u8` where it was computed. Returns the bar (255 when the frame is
// empty).
int mark_green_seeded_components(const cv::Mat& bgr, double sigmas, const BitMask& seeds, const LabelScratch& labels,
                                 SparseIndexScratch& scratch, cv::Mat& raw_u8, cv::Mat& index_u8,
                                 std::vector<std::uint8_t>& keep);

}  // namespace stemd::vision
