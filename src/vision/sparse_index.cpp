#include "stemd/vision/sparse_index.hpp"

#include <algorithm>
#include <bit>
#include <cstring>

#include <opencv2/core.hpp>

#include "stemd/vision/index.hpp"

namespace stemd::vision {

void SparseIndexScratch::reserve(int width_px, int height_px)
{
    width_ = std::max(width_px, 0);
    height_ = std::max(height_px, 0);
    cols_ = (width_ + kSparseTilePx - 1) / kSparseTilePx;
    rows_ = (height_ + kSparseTilePx - 1) / kSparseTilePx;
    const auto tiles = static_cast<std::size_t>(cols_) * static_cast<std::size_t>(rows_);
    state_.assign(tiles, 0);
    queue_.reserve(tiles);
    raw_row_.assign(static_cast<std::size_t>(height_), 0);
    smoothed_row_.assign(static_cast<std::size_t>(height_), 0);
    row_sums_.assign(static_cast<std::size_t>(width_), 0);
    raw_range_.assign(static_cast<std::size_t>(height_), cv::Range(0, 0));
    computed_ = 0;
}

std::size_t SparseIndexScratch::reserved_bytes() const
{
    return state_.capacity() + queue_.capacity() * sizeof(int) + raw_row_.capacity() + smoothed_row_.capacity() +
           row_sums_.capacity() * sizeof(std::uint16_t) + raw_range_.capacity() * sizeof(cv::Range);
}

// The tile work of one frame, on the scratch's buffers.
struct SparseTiles {
    const cv::Mat& bgr;
    SparseIndexScratch& s;
    cv::Mat& raw;
    cv::Mat& index;

    void raw_span(int y, int x_begin, int x_end) const
    {
        if (s.kind_ == RgbIndex::exg)
            excess_green_span(bgr, y, x_begin, x_end, raw);
        else
            chromatic_excess_green_span(bgr, y, x_begin, x_end, s.mean_brightness_, raw);
    }

    cv::Rect tile_rect(int tile) const
    {
        const int x0 = (tile % s.cols_) * kSparseTilePx, y0 = (tile / s.cols_) * kSparseTilePx;
        return {x0, y0, std::min(kSparseTilePx, s.width_ - x0), std::min(kSparseTilePx, s.height_ - y0)};
    }

    // The raw index the smoothing of tiles [col_begin, col_end) of one tile
    // row reads (their rect and one pixel around it), then the smoothed
    // rect. Runs of neighbouring tiles share one pass: a tile is too narrow
    // for the work per row to pay alone. Rows already computed across the
    // frame are not computed again (the same values): the sampled rows and
    // those beside them, and a full-width run's rows, of which the first
    // and last are read again by the tile rows above and below.
    void compute_run(int row, int col_begin, int col_end) const
    {
        const int x0 = col_begin * kSparseTilePx, x1 = std::min(col_end * kSparseTilePx, s.width_);
        const int y0 = row * kSparseTilePx, y1 = std::min(y0 + kSparseTilePx, s.height_);
        const int xa = std::max(x0 - 1, 0), xb = std::min(x1 + 1, s.width_);
        const bool whole_rows = xa == 0 && xb == s.width_;
        for (int y = std::max(y0 - 1, 0); y <= std::min(y1, s.height_ - 1); ++y) {
            std::uint8_t& done = s.raw_row_[static_cast<std::size_t>(y)];
            if (!done)
                raw_span(y, xa, xb);
            done = done || whole_rows;
        }
        for (int y = y0; y < y1;) {
            int end = y;
            while (end < y1 && !s.smoothed_row_[static_cast<std::size_t>(end)])
                ++end;
            if (end > y)
                smooth_binomial3_rect(raw, cv::Rect(x0, y, x1 - x0, end - y), s.row_sums_.data(), index);
            y = end + 1;   // past a row smoothed already
        }
    }

    // Computes the queued tiles from `begin` on, run by run in raster order.
    void compute_queued(std::size_t begin) const
    {
        std::sort(s.queue_.begin() + static_cast<std::ptrdiff_t>(begin), s.queue_.end());
        for (std::size_t i = begin; i < s.queue_.size();) {
            const int first = s.queue_[i];
            std::size_t j = i + 1;
            while (j < s.queue_.size() && s.queue_[j] == s.queue_[j - 1] + 1 && s.queue_[j] / s.cols_ == first / s.cols_)
                ++j;
            compute_run(first / s.cols_, first % s.cols_, first % s.cols_ + static_cast<int>(j - i));
            i = j;
        }
    }

    // Queues the neighbours that a pixel above the level within reach_px of
    // the tile's sides can reach. Only the strips within reach of the sides
    // are read: a pixel anywhere else reaches no neighbour.
    void grow(int tile, int level, int reach_px) const
    {
        const cv::Rect r = tile_rect(tile);
        const auto t = static_cast<std::uint8_t>(level);
        const int reach_x = std::min(reach_px, r.width), reach_y = std::min(reach_px, r.height);
        const auto any_above = [t](const std::uint8_t* p, int n) {
            std::uint8_t any = 0;
            for (int i = 0; i < n; ++i)
                any |= static_cast<std::uint8_t>(p[i] > t);
            return any != 0;
        };
        bool left = false, right = false, up = false, down = false;
        for (int y = r.y; y < r.y + r.height; ++y) {
            const std::uint8_t* p = index.ptr<std::uint8_t>(y) + r.x;
            left = left || any_above(p, reach_x);
            right = right || any_above(p + r.width - reach_x, reach_x);
            const bool top = y < r.y + reach_y, bottom = y >= r.y + r.height - reach_y;
            if ((top && !up) || (bottom && !down)) {
                const bool any = any_above(p, r.width);
                up = up || (top && any);
                down = down || (bottom && any);
            }
        }
        const int col = tile % s.cols_, row = tile / s.cols_;
        for (int dy = -1; dy <= 1; ++dy) {
            if ((dy < 0 && !up) || (dy > 0 && !down) || row + dy < 0 || row + dy >= s.rows_)
                continue;
            for (int dx = -1; dx <= 1; ++dx) {
                if ((dx < 0 && !left) || (dx > 0 && !right) || col + dx < 0 || col + dx >= s.cols_)
                    continue;
                queue((row + dy) * s.cols_ + col + dx);
            }
        }
    }

    void queue(int tile) const
    {
        std::uint8_t& state = s.state_[static_cast<std::size_t>(tile)];
        if (state)
            return;
        state = 1;
        ++s.computed_;
        s.queue_.push_back(tile);  // reserved for every tile: no allocation
    }
};

namespace {

// Each band of 8 rows (from row 0) is sampled at its row 4, or at the
// frame's last row when the last band is shorter.
constexpr int kRawRunPx = 4;

int sample_row(int band_start, int height)
{
    return std::min(band_start + kSparseRowStep / 2, height - 1);
}

// Step 1: every band's sampled row, smoothed from the raw index on it and
// beside it (those raw rows flagged in raw_row_; the smoothed rows in
// smoothed_row unless it is null), and their histogram.
Histogram sampled_rows(const SparseTiles& tiles, std::uint8_t* raw_row, std::uint16_t* row_sums,
                       std::uint8_t* smoothed_row)
{
    const int width = tiles.bgr.cols, height = tiles.bgr.rows;
    PartialHistograms partial;
    for (int band = 0; band < height; band += kSparseRowStep) {
        const int y = sample_row(band, height);
        for (int r = std::max(y - 1, 0); r <= std::min(y + 1, height - 1); ++r) {
            if (!raw_row[r])
                tiles.raw_span(r, 0, width);
            raw_row[r] = 1;
        }
        smooth_binomial3_rect(tiles.raw, cv::Rect(0, y, width, 1), row_sums, tiles.index);
        if (smoothed_row != nullptr)
            smoothed_row[y] = 1;
        partial.add(tiles.index.ptr<std::uint8_t>(y), width);
    }
    Histogram sampled{};
    partial.sum(sampled);
    return sampled;
}

// The histogram once every tile is computed, counted exactly: step 1
// counted the sampled rows, which keep those values (no tile smooths them
// again), so only the other rows are counted.
void whole_histogram(const cv::Mat& index_u8, const Histogram& sampled, Histogram& out)
{
    const int width = index_u8.cols, height = index_u8.rows;
    PartialHistograms partial;
    for (int band = 0; band < height; band += kSparseRowStep) {
        const int sampled_y = sample_row(band, height);
        for (int y = band; y < std::min(band + kSparseRowStep, height); ++y)
            if (y != sampled_y)
                partial.add(index_u8.ptr<std::uint8_t>(y), width);
    }
    partial.sum(out);
    for (std::size_t v = 0; v < out.size(); ++v)
        out[v] += sampled[v];
}

// The histogram once every tile is computed, estimated: each band's sampled
// row (step 1's counts) stands for the band's rows, as in a soil tile.
void sampled_rows_for_their_bands(const cv::Mat& index_u8, const Histogram& sampled, Histogram& out)
{
    const int height = index_u8.rows;
    for (std::size_t v = 0; v < out.size(); ++v)
        out[v] = sampled[v] * kSparseRowStep;
    const int last_band = (height - 1) / kSparseRowStep * kSparseRowStep;
    const auto missing_rows = static_cast<std::uint32_t>(kSparseRowStep - (height - last_band));
    if (height == 0 || missing_rows == 0)
        return;
    const std::uint8_t* last_row = index_u8.ptr<std::uint8_t>(sample_row(last_band, height));
    for (int x = 0; x < index_u8.cols; ++x)
        out[last_row[x]] -= missing_rows;
}

}  // namespace

int sparse_smoothed_index(const cv::Mat& bgr, RgbIndex kind, const SparseLevel& level, int reach_px,
                          SparseIndexScratch& scratch, cv::Mat& raw_u8, cv::Mat& index_u8, Histogram& histogram)
{
    CV_Assert(bgr.type() == CV_8UC3 && bgr.cols == scratch.width_ && bgr.rows == scratch.height_);
    CV_Assert(raw_u8.type() == CV_8UC1 && raw_u8.size() == bgr.size());
    CV_Assert(index_u8.type() == CV_8UC1 && index_u8.size() == bgr.size());
    SparseIndexScratch& s = scratch;
    const int width = s.width_, height = s.height_;
    s.kind_ = kind;
    s.mean_brightness_ = kind == RgbIndex::chromatic_exg ? chromatic_mean_brightness(bgr) : 0.0f;
    std::fill(s.state_.begin(), s.state_.end(), std::uint8_t{0});
    std::fill(s.raw_row_.begin(), s.raw_row_.end(), std::uint8_t{0});
    std::fill(s.smoothed_row_.begin(), s.smoothed_row_.end(), std::uint8_t{0});
    s.queue_.clear();
    s.computed_ = 0;
    const SparseTiles tiles{bgr, s, raw_u8, index_u8};

    // 1. The sampled rows, smoothed, and their histogram.
    const Histogram sampled = sampled_rows(tiles, s.raw_row_.data(), s.row_sums_.data(), s.smoothed_row_.data());
    const bool any_sample = height > 0 && width > 0;
    s.soil_ = soil_mode(sampled);
    if (any_sample) {
        // One soil sigma (at least one level) below the sampled threshold.
        const int sigma = std::max(soil_noise_threshold(sampled, 1.0) - s.soil_, 1);
        s.level_ = std::max(auto_threshold(sampled, level.method, level.soil_sigmas) - sigma, 0);
    } else {
        s.level_ = -1;
    }

    // 2. Tiles where a sampled row rises above the level, and what they reach.
    if (!any_sample) {
        for (int t = 0; t < s.tiles(); ++t)
            tiles.queue(t);
    } else {
        // The smoothed sampled row; and on the raw rows beside it (computed
        // for its smoothing anyway) a run of kRawRunPx pixels above the level,
        // which single noisy pixels do not make: a seedling whose core
        // crosses those rows is found too, even between sampled rows.
        const auto t = static_cast<std::uint8_t>(s.level_);
        for (int band = 0; band < height; band += kSparseRowStep) {
            const int y = sample_row(band, height);
            const int row = y / kSparseTilePx;
            const std::uint8_t* smoothed = index_u8.ptr<std::uint8_t>(y);
            const std::uint8_t* beside[2] = {nullptr, nullptr};
            int n = 0;
            if (y - 1 >= band)
                beside[n++] = raw_u8.ptr<std::uint8_t>(y - 1);
            if (y + 1 < std::min(band + kSparseRowStep, height))
                beside[n++] = raw_u8.ptr<std::uint8_t>(y + 1);
            for (int col = 0; col < s.cols_; ++col) {
                const int x0 = col * kSparseTilePx, x1 = std::min(x0 + kSparseTilePx, width);
                std::uint8_t any = 0;
                for (int x = x0; x < x1; ++x)
                    any |= static_cast<std::uint8_t>(smoothed[x] > t);
                const int run_end = std::min(x1, width - kRawRunPx + 1);
                for (int k = 0; k < n && !any; ++k) {
                    const std::uint8_t* p = beside[k];
                    for (int x = x0; x < run_end; ++x)
                        any |= static_cast<std::uint8_t>((p[x] > t) & (p[x + 1] > t) & (p[x + 2] > t) & (p[x + 3] > t));
                }
                if (any)
                    tiles.queue(row * s.cols_ + col);
            }
            // Enough found for every tile to be computed (below): the
            // rest of the scan would change nothing.
            if (3 * static_cast<int>(s.queue_.size()) >= s.tiles())
                break;
        }
    }
    // Vegetation in a third of the tiles or more: growing would reach most
    // of the rest, and the whole frame in full rows costs less than tiles.
    if (3 * static_cast<int>(s.queue_.size()) >= s.tiles())
        for (int t = 0; t < s.tiles(); ++t)
            tiles.queue(t);
    // In waves: the tiles found so far, then those they reach, and so on.
    const int reach = std::clamp(reach_px, 1, kSparseTilePx);
    for (std::size_t begin = 0; begin < s.queue_.size();) {
        const std::size_t end = s.queue_.size();
        tiles.compute_queued(begin);
        for (std::size_t i = begin; i < end && s.computed_ < s.tiles(); ++i)
            tiles.grow(s.queue_[i], s.level_, reach);
        begin = end;
    }

    // 3. Soil tiles: their sampled rows stand for their bands in the
    // histogram, then they take the soil level.
    if (s.computed_ == s.tiles()) {
        // Vegetation fills a third of the tiles or more: on a camera's frame
        // the sampled rows then hold tens of thousands of its pixels, and
        // counting the other rows cost about a tenth of the frame's time.
        if (static_cast<long>((height + kSparseRowStep - 1) / kSparseRowStep) * width >= kSampledPixelsForEstimate)
            sampled_rows_for_their_bands(index_u8, sampled, histogram);
        else
            whole_histogram(index_u8, sampled, histogram);
        return s.level_;
    }
    PartialHistograms partial;
    const auto soil = static_cast<std::uint8_t>(s.soil_);
    for (int tile = 0; tile < s.tiles(); ++tile) {
        const cv::Rect r = tiles.tile_rect(tile);
        if (s.state_[static_cast<std::size_t>(tile)]) {
            for (int y = r.y; y < r.y + r.height; ++y)
                partial.add(index_u8.ptr<std::uint8_t>(y) + r.x, r.width);
            continue;
        }
        for (int band = r.y; band < r.y + r.height; band += kSparseRowStep) {
            const int y = sample_row(band, height);
            const auto band_rows = static_cast<std::uint32_t>(std::min(kSparseRowStep, height - band));
            partial.add(index_u8.ptr<std::uint8_t>(y) + r.x, r.width, band_rows);
        }
        for (int y = r.y; y < r.y + r.height; ++y) {
            std::memset(index_u8.ptr<std::uint8_t>(y) + r.x, soil, static_cast<std::size_t>(r.width));
            s.smoothed_row_[static_cast<std::size_t>(y)] = 0;   // complete_sparse_index smooths it again
        }
    }
    partial.sum(histogram);
    return s.level_;
}

void complete_sparse_index(const cv::Mat& bgr, SparseIndexScratch& scratch, cv::Mat& raw_u8, cv::Mat& index_u8,
                           Histogram& histogram)
{
    CV_Assert(bgr.type() == CV_8UC3 && bgr.cols == scratch.width_ && bgr.rows == scratch.height_);
    const SparseTiles tiles{bgr, scratch, raw_u8, index_u8};
    const std::size_t begin = scratch.queue_.size();
    for (int tile = 0; tile < scratch.tiles(); ++tile)
        tiles.queue(tile);
    tiles.compute_queued(begin);
    compute_histogram(index_u8, histogram);
}

int mark_green_seeded_components(const cv::Mat& bgr, double sigmas, const BitMask& seeds, const LabelScratch& labels,
                                 SparseIndexScratch& scratch, cv::Mat& raw_u8, cv::Mat& index_u8,
                                 std::vector<std::uint8_t>& keep)
{
    CV_Assert(bgr.type() == CV_8UC3 && bgr.cols == scratch.width_ && bgr.rows == scratch.height_);
    CV_Assert(raw_u8.type() == CV_8UC1 && raw_u8.size() == bgr.size());
    CV_Assert(index_u8.type() == CV_8UC1 && index_u8.size() == bgr.size());
    CV_Assert(seeds.width() == bgr.cols && seeds.height() == bgr.rows);
    keep.assign(labels.component_count(), 0);
    SparseIndexScratch& s = scratch;
    const int width = s.width_, height = s.height_;
    if (width == 0 || height == 0)
        return 255;
    s.kind_ = RgbIndex::chromatic_exg;
    s.mean_brightness_ = chromatic_mean_brightness(bgr);
    std::fill(s.raw_row_.begin(), s.raw_row_.end(), std::uint8_t{0});
    // Its index is another image: no row of the tiles' index is known
    // smoothed any more.
    std::fill(s.smoothed_row_.begin(), s.smoothed_row_.end(), std::uint8_t{0});
    std::fill(s.raw_range_.begin(), s.raw_range_.end(), cv::Range(0, 0));
    const SparseTiles tiles{bgr, s, raw_u8, index_u8};

    // 1. The soil's noise from the sampled rows, as the sparse index reads
    // it: the bar is a statistic of the soil, which every row shows alike.
    const int bar = soil_noise_threshold(sampled_rows(tiles, s.raw_row_.data(), s.row_sums_.data(), nullptr), sigmas);

    // The raw index of row r on [a, b) at least, grown from what the row
    // already holds (the same values wherever it is computed).
    const auto need_raw = [&](int r, int a, int b) {
        if (s.raw_row_[static_cast<std::size_t>(r)])
            return;
        cv::Range& have = s.raw_range_[static_cast<std::size_t>(r)];
        if (have.start >= have.end) {
            tiles.raw_span(r, a, b);
            have = cv::Range(a, b);
            return;
        }
        if (a < have.start) {
            tiles.raw_span(r, a, have.start);
            have.start = a;
        }
        if (b > have.end) {
            tiles.raw_span(r, have.end, b);
            have.end = b;
        }
    };

    // 2. Row by row, the seeds of components not yet kept: the smoothed
    // index from the first to the last of them, and each component's seeds
    // tested until one passes.
    for (std::size_t begin = 0; begin < labels.run_count();) {
        const int y = labels.run(begin).y;
        std::size_t end = begin;
        while (end < labels.run_count() && labels.run(end).y == y)
            ++end;
        const std::uint64_t* seed_row = seeds.row(y);
        int lo = width, hi = 0;
        for (std::size_t i = begin; i < end; ++i) {
            const LabelScratch::LabelledRun run = labels.run(i);
            if (keep[static_cast<std::size_t>(run.component)])
                continue;
            for (int w = run.x0 >> 6; w <= (run.x1 >> 6); ++w)
                if (const std::uint64_t bits = seed_row[w] & range_bits_of_word(w, run.x0, run.x1)) {
                    lo = std::min(lo, 64 * w + std::countr_zero(bits));
                    break;
                }
            for (int w = run.x1 >> 6; w >= (run.x0 >> 6); --w)
                if (const std::uint64_t bits = seed_row[w] & range_bits_of_word(w, run.x0, run.x1)) {
                    hi = std::max(hi, 64 * w + 64 - std::countl_zero(bits));
                    break;
                }
        }
        if (lo < hi) {
            const int a = std::max(lo - 1, 0), b = std::min(hi + 1, width);
            for (int r = std::max(y - 1, 0); r <= std::min(y + 1, height - 1); ++r)
                need_raw(r, a, b);
            smooth_binomial3_rect(raw_u8, cv::Rect(lo, y, hi - lo, 1), s.row_sums_.data(), index_u8);
            const std::uint8_t* green = index_u8.ptr<std::uint8_t>(y);
            for (std::size_t i = begin; i < end; ++i) {
                const LabelScratch::LabelledRun run = labels.run(i);
                std::uint8_t& kept = keep[static_cast<std::size_t>(run.component)];
                for (int w = run.x0 >> 6; w <= (run.x1 >> 6) && !kept; ++w)
                    for (std::uint64_t bits = seed_row[w] & range_bits_of_word(w, run.x0, run.x1); bits != 0 && !kept;
                         bits &= bits - 1)
                        kept = green[64 * w + std::countr_zero(bits)] > bar;
            }
        }
        begin = end;
    }
    return bar;
}

}  // namespace stemd::vision
