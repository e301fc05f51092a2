#include "stemd/vision/cells.hpp"

#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/stem.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace stemd::vision {

namespace {

constexpr std::array<std::string_view, kCellOwnFeatureCount> kCellNames{
    "cell_fill",      "cell_r_mean",     "cell_g_mean",     "cell_r_std",    "cell_g_std",      "cell_brightness_rel",
    "cell_texture",   "cell_coherence",  "cell_orientation", "cell_ndvi_mean", "cell_ndvi_std",  "cell_width_mm",
    "cell_fill_near", "cell_fill_mid",   "cell_fill_far",   "cell_g_near",   "cell_r_near",     "cell_band_density",
    "cell_row_offset_mm", "cell_lateral", "cell_in_plant", "cell_r_rel", "cell_g_rel", "cell_brightness_veg",
    "cell_texture_rel", "cell_width_rel",
};

constexpr std::array<std::string_view, kCellContextCount> kContextNames{
    "context_near", "context_mid", "context_wide", "context_far", "context_band", "context_plant", "context_frame",
};

// Sum over the grid square [x0, x1] x [y0, y1] of an integral image with
// one extra row and column of zeros.
double box_sum(const std::vector<double>& integral, int stride, int x0, int y0, int x1, int y1)
{
    const auto at = [&](int x, int y) { return integral[static_cast<std::size_t>(y) * stride + x]; };
    return at(x1 + 1, y1 + 1) - at(x0, y1 + 1) - at(x1 + 1, y0) + at(x0, y0);
}

// Fills each of `integrals` (the grid with one extra row and column of
// zeros) with the sums of its entry of value(cell, gx, gy) over each square
// from the origin, all in one pass over the grid.
template <std::size_t N, class Value>
void fill_integrals(const std::array<std::vector<double>*, N>& integrals, cv::Size grid, Value value)
{
    const std::size_t stride = static_cast<std::size_t>(grid.width) + 1;
    for (std::vector<double>* integral : integrals)
        std::fill(integral->begin(), integral->begin() + static_cast<std::ptrdiff_t>(stride), 0.0);
    for (int gy = 0; gy < grid.height; ++gy) {
        std::array<double, N> row_sum{};
        const std::size_t above = static_cast<std::size_t>(gy) * stride, here = above + stride;
        for (std::vector<double>* integral : integrals)
            (*integral)[here] = 0;
        for (int gx = 0; gx < grid.width; ++gx) {
            const std::array<double, N> v = value(static_cast<std::size_t>(gy) * static_cast<std::size_t>(grid.width) + static_cast<std::size_t>(gx), gx, gy);
            const std::size_t at = static_cast<std::size_t>(gx) + 1;
            for (std::size_t k = 0; k < N; ++k) {
                row_sum[k] += v[k];
                (*integrals[k])[here + at] = (*integrals[k])[above + at] + row_sum[k];
            }
        }
    }
}

template <class Value>
void fill_integral(std::vector<double>& integral, cv::Size grid, Value value)
{
    fill_integrals<1>({&integral}, grid, [&](std::size_t i, int gx, int gy) { return std::array<double, 1>{value(i, gx, gy)}; });
}

// Pixels of cell (gx, gy) on the rows cell_features() samples: the even rows
// y with y + 1 < height.
double sampled_cell_px(int gx, int gy, int cell_px, cv::Size frame)
{
    const int w = std::min(cell_px, frame.width - gx * cell_px);
    const int y0 = gy * cell_px, y1 = std::min(y0 + cell_px, frame.height - 1);
    const int rows = y1 > y0 ? (y1 + 1) / 2 - (y0 + 1) / 2 : 0;
    return static_cast<double>(w) * rows;
}

}  // namespace

std::string_view cell_feature_name(int feature)
{
    if (feature >= 0 && feature < kCellOwnFeatureCount)
        return kCellNames[static_cast<std::size_t>(feature)];
    if (feature >= kCellOwnFeatureCount && feature < kCellFeatureCount)
        return feature_name(feature - kCellOwnFeatureCount);
    return "?";
}

std::string_view context_feature_name(int feature)
{
    if (feature >= kCellFeatureCount && feature < kContextFeatureCount)
        return kContextNames[static_cast<std::size_t>(feature - kCellFeatureCount)];
    return cell_feature_name(feature);
}

CellContextScratch::CellContextScratch(cv::Size grid) : grid_(grid)
{
    const std::size_t integral = static_cast<std::size_t>(grid.width + 1) * static_cast<std::size_t>(grid.height + 1);
    integral_p_.resize(integral);
    integral_w_.resize(integral);
    cell_p_.resize(static_cast<std::size_t>(std::max(grid.area(), 0)));
    cell_w_.resize(cell_p_.size());
    column_p_.resize(static_cast<std::size_t>(grid.width));
    column_w_.resize(static_cast<std::size_t>(grid.width));
}

void cell_context(const CellContextInput& in, CellContextScratch& scratch, std::span<CellContext> out)
{
    const std::size_t count = std::min({in.cells.size(), in.weight.size(), in.plant.size(), in.probability.size(), out.size()});
    const cv::Size grid = in.grid;
    if (grid != scratch.grid_ || grid.area() <= 0)
        return;
    const int stride = grid.width + 1;
    // Integral images of p·w and w over the grid, built from the listed
    // cells (the others hold no vegetation: zero). The per-cell grids are
    // zero between calls: only the listed cells are written, and cleared
    // after.
    std::fill(scratch.column_p_.begin(), scratch.column_p_.end(), 0.0);
    std::fill(scratch.column_w_.begin(), scratch.column_w_.end(), 0.0);
    scratch.plant_p_.fill(0.0);
    scratch.plant_w_.fill(0.0);
    double frame_p = 0, frame_w = 0;
    for (std::size_t k = 0; k < count; ++k) {
        const std::uint32_t c = in.cells[k];
        if (c >= static_cast<std::uint32_t>(grid.area()))
            continue;
        const int gx = static_cast<int>(c % static_cast<std::uint32_t>(grid.width));
        const double w = in.weight[k], pw = w * static_cast<double>(in.probability[k]);
        scratch.cell_p_[c] = pw;
        scratch.cell_w_[c] = w;
        scratch.column_p_[static_cast<std::size_t>(gx)] += pw;
        scratch.column_w_[static_cast<std::size_t>(gx)] += w;
        const std::uint16_t id = in.plant[k] <= kMaxPlants ? in.plant[k] : 0;
        scratch.plant_p_[id] += pw;
        scratch.plant_w_[id] += w;
        frame_p += pw;
        frame_w += w;
    }
    fill_integrals<2>({&scratch.integral_p_, &scratch.integral_w_}, grid, [&](std::size_t i, int, int) {
        return std::array<double, 2>{scratch.cell_p_[i], scratch.cell_w_[i]};
    });
    for (std::size_t k = 0; k < count; ++k) {
        const std::uint32_t c = in.cells[k];
        if (c < static_cast<std::uint32_t>(grid.area()))
            scratch.cell_p_[c] = scratch.cell_w_[c] = 0;
    }
    std::array<int, kContextRingsMm.size()> ring{};
    for (std::size_t r = 0; r < ring.size(); ++r)
        ring[r] = std::max(1, static_cast<int>(std::lround(kContextRingsMm[r] / std::max(in.cell_mm, 1e-6))));
    const int band = std::max(0, static_cast<int>(std::lround(kRowHalfWidthMm / std::max(in.cell_mm, 1e-6))));
    const auto mean = [](double p, double w, float own) { return w > 0 ? static_cast<float>(p / w) : own; };
    for (std::size_t k = 0; k < count; ++k) {
        const std::uint32_t c = in.cells[k];
        const float own = in.probability[k];
        CellContext& x = out[k];
        if (c >= static_cast<std::uint32_t>(grid.area())) {
            x.fill(own);
            continue;
        }
        const int gx = static_cast<int>(c % static_cast<std::uint32_t>(grid.width));
        const int gy = static_cast<int>(c / static_cast<std::uint32_t>(grid.width));
        for (std::size_t r = 0; r < ring.size(); ++r) {
            const int x0 = std::max(gx - ring[r], 0), x1 = std::min(gx + ring[r], grid.width - 1);
            const int y0 = std::max(gy - ring[r], 0), y1 = std::min(gy + ring[r], grid.height - 1);
            x[x_near + r] = mean(box_sum(scratch.integral_p_, stride, x0, y0, x1, y1),
                                 box_sum(scratch.integral_w_, stride, x0, y0, x1, y1), own);
        }
        double band_p = 0, band_w = 0;
        for (int b = std::max(gx - band, 0); b <= std::min(gx + band, grid.width - 1); ++b) {
            band_p += scratch.column_p_[static_cast<std::size_t>(b)];
            band_w += scratch.column_w_[static_cast<std::size_t>(b)];
        }
        x[x_band] = mean(band_p, band_w, own);
        const std::uint16_t id = in.plant[k] <= kMaxPlants ? in.plant[k] : 0;
        x[x_plant] = id > 0 ? mean(scratch.plant_p_[id], scratch.plant_w_[id], own) : own;
        x[x_frame] = mean(frame_p, frame_w, own);
    }
}

CellWorkspace::CellWorkspace(cv::Size frame_size, double gsd_mm_per_px, double cell_mm)
    : frame_size_(frame_size), gsd_(std::max(gsd_mm_per_px, 1e-6)), cell_mm_(cell_mm)
{
    cell_px_ = std::max(2, static_cast<int>(std::lround(cell_mm / gsd_)));
    const int width = std::max(frame_size.width, 0), height = std::max(frame_size.height, 0);
    grid_ = cv::Size((width + cell_px_ - 1) / cell_px_, (height + cell_px_ - 1) / cell_px_);
    const std::size_t n = cells();
    cell_x_.resize(static_cast<std::size_t>(width));
    for (int x = 0; x < width; ++x)
        cell_x_[static_cast<std::size_t>(x)] = static_cast<std::uint16_t>(x / cell_px_);
    transitions_.resize(static_cast<std::size_t>((width + 63) / 64) + 1);
    vertical_.resize(transitions_.size());
    either_.resize(transitions_.size());
    row_counts_.resize(2 * static_cast<std::size_t>(grid_.width));
    sums_.resize(n);
    samples_.resize(n);
    const std::size_t integral = static_cast<std::size_t>(grid_.width + 1) * static_cast<std::size_t>(grid_.height + 1);
    for (auto* v : {&integral_fill_, &integral_px_, &integral_g_, &integral_r_, &integral_n_})
        v->resize(integral);
    column_fill_.resize(static_cast<std::size_t>(grid_.width));
    column_px_.resize(static_cast<std::size_t>(grid_.width));
    // The sampled pixels depend on the geometry alone.
    fill_integral(integral_px_, grid_, [&](std::size_t, int gx, int gy) { return sampled_cell_px(gx, gy, cell_px_, frame_size); });
    for (int gx = 0; gx < grid_.width; ++gx)
        column_px_[static_cast<std::size_t>(gx)] = box_sum(integral_px_, grid_.width + 1, gx, 0, gx, grid_.height - 1);
    rows_.resize(n);
    plant_.resize(n);
    vegetated_.resize(n);
    probability_.resize(n);
    raw_.resize(n);
    class_.resize(n);
    listed_weight_.resize(n);
    listed_probability_.resize(n);
    listed_plant_.resize(n);
    context_.resize(n);
    context_rows_.resize(n * kContextFeatureCount);
    context_scratch_ = CellContextScratch(grid_);
    budgeted_.resize(n);
    in_budget_.resize(n);
    edge_steps_.resize(static_cast<std::size_t>(std::max(grid_.width, grid_.height)));
    in_part_.resize(n);
    part_stack_.resize(n);
    cover_d2_.resize(n);
}

void cell_features(const FrameView& frame, const Params& /*params*/, const Workspace& dws, const Detections& det,
                   const ClassifyWorkspace& plants, CellWorkspace& ws)
{
    ws.vegetated_count_ = 0;
    std::fill(ws.class_.begin(), ws.class_.end(), PlantClass::Unknown);
    std::fill(ws.probability_.begin(), ws.probability_.end(), 0.0f);
    if (frame.bgr.empty() || frame.bgr.size() != ws.frame_size_ || frame.bgr.type() != CV_8UC3 ||
        dws.frame_size() != ws.frame_size_ || plants.frame_size() != ws.frame_size_)
        return;
    const int width = ws.frame_size_.width, height = ws.frame_size_.height;
    const cv::Size grid = ws.grid_;
    const int cell_px = ws.cell_px_;
    const BitMask& vegetation = dws.vegetation();
    const int words = vegetation.words_per_row();
    const bool has_nir = !frame.nir.empty() && frame.nir.size() == ws.frame_size_ && frame.nir.type() == CV_8UC1;
    const auto features = plants.features();
    std::fill(ws.sums_.begin(), ws.sums_.end(), CellWorkspace::Sums{});
    std::fill(ws.samples_.begin(), ws.samples_.end(), CellSamples{});

    // One pass over every other row (the features are means and ratios:
    // half the rows estimate them well). Vegetation and boundary counts by
    // bit counts per cell; colour, gradients and the plant vote on every
    // fourth vegetation pixel of the row (add_cell_samples()).
    for (int y = 0; y + 1 < height; y += 2) {
        const std::uint64_t* vrow = vegetation.row(y);
        const std::uint64_t* below = vegetation.row(y + 1);
        std::uint64_t any = 0;
        for (int w = 0; w < words; ++w) {
            ws.either_[static_cast<std::size_t>(w)] = vrow[w] | below[w];
            any |= ws.either_[static_cast<std::size_t>(w)];
        }
        if (any == 0)
            continue;   // soil only: nothing to count
        // Boundaries: a pixel differing from its right neighbour, or from
        // the one below. Per cell: the row's vegetation and, where either
        // row has some (a cell with neither takes no boundary, not even its
        // right edge's), the two boundary counts, in one counting call.
        for (int w = 0; w < words; ++w) {
            const std::uint64_t next = w + 1 < words ? vrow[w + 1] : 0;
            const std::uint64_t right = (vrow[w] >> 1) | (next << 63);
            std::uint64_t edge = vrow[w] ^ right;
            if (w + 1 == words)
                edge &= vegetation.last_word_mask() >> 1;   // the frame's right border is no boundary
            ws.transitions_[static_cast<std::size_t>(w)] = edge;
            ws.vertical_[static_cast<std::size_t>(w)] = vrow[w] ^ below[w];
        }
        const std::size_t gw = static_cast<std::size_t>(grid.width);
        int* const row_vegetation = ws.row_counts_.data();
        int* const row_boundary = row_vegetation + gw;
        std::fill(row_vegetation, row_boundary + gw, 0);
        add_gated_span_bit_counts({ws.either_.data(), vrow, {ws.transitions_.data(), ws.vertical_.data()}}, width,
                                  cell_px, row_vegetation, row_boundary);
        const std::size_t grid_row = static_cast<std::size_t>(y / cell_px) * gw;
        // Only cells that meet vegetation in either row can count anything.
        std::size_t next_cell = 0;
        for (int w = 0; w < words; ++w) {
            if (ws.either_[static_cast<std::size_t>(w)] == 0)
                continue;
            const std::size_t last_cell = ws.cell_x_[static_cast<std::size_t>(std::min(w * 64 + 63, width - 1))];
            for (std::size_t cx = std::max<std::size_t>(ws.cell_x_[static_cast<std::size_t>(w * 64)], next_cell);
                 cx <= last_cell; ++cx) {
                CellWorkspace::Sums& s = ws.sums_[grid_row + cx];
                s.vegetation_px += row_vegetation[cx];
                s.boundary += row_boundary[cx];
            }
            next_cell = last_cell + 1;
        }
        const auto* bgr = frame.bgr.ptr<cv::Vec3b>(y);
        const auto* bgr_up = frame.bgr.ptr<cv::Vec3b>(std::max(y - 1, 0));
        const auto* bgr_down = frame.bgr.ptr<cv::Vec3b>(y + 1);
        const std::uint8_t* nir = has_nir ? frame.nir.ptr<std::uint8_t>(y) : nullptr;
        const auto* index = plants.plant_index().ptr<std::uint16_t>(y);
        add_cell_samples({bgr, bgr_up, bgr_down, nir, width}, vrow, ws.cell_x_.data(), index,
                         ws.samples_.data() + grid_row);
    }

    // The frame's mean R+G+B as plant_features() measured it; a frame with
    // no plant has none, then measured here alike.
    double frame_brightness = plants.frame_brightness();
    if (frame_brightness <= 0)
        frame_brightness = sampled_frame_brightness(frame.bgr);
    frame_brightness = std::max(frame_brightness, 1.0);

    // Grid sums for the neighbourhoods: vegetation and pixels on the sampled
    // rows, colour over the sampled vegetation pixels.
    const std::size_t n = ws.cells();
    const int stride = grid.width + 1;
    fill_integrals<4>({&ws.integral_fill_, &ws.integral_g_, &ws.integral_r_, &ws.integral_n_}, grid,
                      [&](std::size_t i, int, int) {
                          const CellSamples& c = ws.samples_[i];
                          return std::array<double, 4>{static_cast<double>(ws.sums_[i].vegetation_px),
                                                       static_cast<double>(c.g), static_cast<double>(c.r),
                                                       static_cast<double>(c.sampled_px)};
                      });
    double frame_fill = 0, frame_px = 0;
    for (int gx = 0; gx < grid.width; ++gx) {
        ws.column_fill_[static_cast<std::size_t>(gx)] = box_sum(ws.integral_fill_, stride, gx, 0, gx, grid.height - 1);
        frame_fill += ws.column_fill_[static_cast<std::size_t>(gx)];
        frame_px += ws.column_px_[static_cast<std::size_t>(gx)];
    }
    const double frame_density = std::max(frame_fill / std::max(frame_px, 1.0), 1e-6);
    // Lateral bands (across the travel, image x) and the densest one.
    const int band = std::max(0, static_cast<int>(std::lround(kRowHalfWidthMm / ws.cell_mm_)));
    auto band_density = [&](int gx) {
        const int a = std::max(gx - band, 0), b = std::min(gx + band, grid.width - 1);
        double v = 0, p = 0;
        for (int c = a; c <= b; ++c) {
            v += ws.column_fill_[static_cast<std::size_t>(c)];
            p += ws.column_px_[static_cast<std::size_t>(c)];
        }
        return v / std::max(p, 1.0) / frame_density;
    };
    int row_column = 0;
    double best = -1;
    for (int gx = 0; gx < grid.width; ++gx) {
        const double d = band_density(gx);
        if (d > best) {
            best = d;
            row_column = gx;
        }
    }
    // The row's line: the vegetation-weighted centre of the densest band
    // (the band's density is flat while the row lies anywhere inside it).
    double row_x = row_column;
    {
        double sum = 0, weight = 0;
        for (int c = std::max(row_column - band, 0); c <= std::min(row_column + band, grid.width - 1); ++c) {
            sum += c * ws.column_fill_[static_cast<std::size_t>(c)];
            weight += ws.column_fill_[static_cast<std::size_t>(c)];
        }
        if (weight > 0)
            row_x = sum / weight;
    }
    // The frame's vegetation as a whole.
    double veg_n = 0, veg_r = 0, veg_g = 0, veg_brightness = 0, veg_gradient = 0, veg_px = 0, veg_boundary = 0;
    for (const CellSamples& c : ws.samples_) {
        veg_n += c.sampled_px;
        veg_r += c.r;
        veg_g += c.g;
        veg_brightness += c.brightness;
        veg_gradient += c.gradient;
    }
    for (const CellWorkspace::Sums& s : ws.sums_) {
        veg_px += s.vegetation_px;
        veg_boundary += s.boundary;
    }
    veg_n = std::max(veg_n, 1.0);
    const double frame_r = veg_r / veg_n, frame_g = veg_g / veg_n;
    const double frame_veg_brightness = std::max(veg_brightness / veg_n, 1.0);
    const double frame_texture = std::max(veg_gradient / veg_n / frame_veg_brightness, 1e-6);
    const double frame_width_mm = std::max(2.0 * veg_px / std::max(veg_boundary, 1.0) * ws.gsd_, 1e-6);
    std::array<int, 3> ring{};
    for (std::size_t k = 0; k < ring.size(); ++k)
        ring[k] = std::max(1, static_cast<int>(std::lround(kCellRingsMm[k] / ws.cell_mm_)));

    for (std::size_t i = 0; i < n; ++i) {
        const CellWorkspace::Sums& s = ws.sums_[i];
        const CellSamples& c = ws.samples_[i];
        if (c.sampled_px == 0)
            continue;
        const int gx = static_cast<int>(i % static_cast<std::size_t>(grid.width));
        const int gy = static_cast<int>(i / static_cast<std::size_t>(grid.width));
        CellRow& f = ws.rows_[i];
        const float count = static_cast<float>(c.sampled_px);
        const float r = c.r / count, g = c.g / count;
        const float brightness = c.brightness / count;
        f[c_fill] = static_cast<float>(s.vegetation_px / std::max(sampled_cell_px(gx, gy, cell_px, ws.frame_size_), 1.0));
        f[c_r_mean] = r;
        f[c_g_mean] = g;
        f[c_r_std] = std::sqrt(std::max(0.0f, c.rr / count - r * r));
        f[c_g_std] = std::sqrt(std::max(0.0f, c.gg / count - g * g));
        f[c_brightness_rel] = static_cast<float>(brightness / frame_brightness);
        f[c_texture] = c.gradient / count / std::max(brightness, 1.0f);
        const float trace = c.sxx + c.syy;
        f[c_coherence] = trace > 0 ? std::sqrt((c.sxx - c.syy) * (c.sxx - c.syy) + 4 * c.sxy * c.sxy) / trace : 0.0f;
        f[c_orientation] = trace > 0 ? (c.sxx - c.syy) / trace : 0.0f;
        f[c_ndvi_mean] = has_nir ? c.ndvi / count : 0.0f;
        f[c_ndvi_std] = has_nir ? std::sqrt(std::max(0.0f, c.ndvi2 / count - f[c_ndvi_mean] * f[c_ndvi_mean])) : 0.0f;
        f[c_width_mm] = static_cast<float>(2.0 * s.vegetation_px / std::max(s.boundary, 1) * ws.gsd_);
        for (std::size_t k = 0; k < ring.size(); ++k) {
            const int x0 = std::max(gx - ring[k], 0), x1 = std::min(gx + ring[k], grid.width - 1);
            const int y0 = std::max(gy - ring[k], 0), y1 = std::min(gy + ring[k], grid.height - 1);
            const double v = box_sum(ws.integral_fill_, stride, x0, y0, x1, y1);
            const double p = box_sum(ws.integral_px_, stride, x0, y0, x1, y1);
            f[c_fill_near + static_cast<int>(k)] = static_cast<float>(v / std::max(p, 1.0));
            if (k == 0) {
                const double m = std::max(box_sum(ws.integral_n_, stride, x0, y0, x1, y1), 1.0);
                f[c_g_near] = static_cast<float>(box_sum(ws.integral_g_, stride, x0, y0, x1, y1) / m);
                f[c_r_near] = static_cast<float>(box_sum(ws.integral_r_, stride, x0, y0, x1, y1) / m);
            }
        }
        f[c_band_density] = static_cast<float>(band_density(gx));
        f[c_row_offset_mm] = static_cast<float>(std::abs(gx - row_x) * ws.cell_mm_);
        f[c_lateral] = static_cast<float>((gx + 0.5) * cell_px / std::max(width, 1));
        const std::uint16_t id = c.plant_vote;
        const bool in_plant = id > 0 && id <= features.size() && id <= det.plants.size();
        f[c_in_plant] = in_plant ? 1.0f : 0.0f;
        ws.plant_[i] = in_plant ? id : 0;
        if (in_plant)
            std::copy(features[id - 1u].begin(), features[id - 1u].end(), f.begin() + kCellOwnFeatureCount);
        else
            std::fill(f.begin() + kCellOwnFeatureCount, f.end(), 0.0f);
        f[c_r_rel] = static_cast<float>(r - frame_r);
        f[c_g_rel] = static_cast<float>(g - frame_g);
        f[c_brightness_veg] = static_cast<float>(brightness / frame_veg_brightness);
        f[c_texture_rel] = static_cast<float>(f[c_texture] / frame_texture);
        f[c_width_rel] = static_cast<float>(f[c_width_mm] / frame_width_mm);
        ws.vegetated_[ws.vegetated_count_++] = static_cast<std::uint32_t>(i);
    }
}

namespace {

// The vegetated cells within the budget, in grid order, into ws.budgeted_:
// every cell fewer steps from the first edge than the step where the budget
// runs out, then that step's cells in grid order while it lasts.
std::span<const std::uint32_t> cells_in_budget(std::span<const std::uint32_t> vegetated, const CellBudget& budget,
                                               cv::Size grid, std::vector<std::uint32_t>& steps,
                                               std::vector<std::uint32_t>& budgeted)
{
    const auto gw = static_cast<std::uint32_t>(grid.width), gh = static_cast<std::uint32_t>(grid.height);
    const auto step = [&](std::uint32_t c) {
        const std::uint32_t gx = c % gw, gy = c / gw;
        switch (budget.first_edge) {
        case ImageEdge::top: return gy;
        case ImageEdge::bottom: return gh - 1 - gy;
        case ImageEdge::left: return gx;
        case ImageEdge::right: return gw - 1 - gx;
        }
        return gy;
    };
    std::fill(steps.begin(), steps.end(), 0u);
    for (const std::uint32_t c : vegetated)
        ++steps[step(c)];
    // The first step the budget cannot take whole, and what is left for it.
    std::uint32_t last = 0;
    std::size_t left = budget.max_cells;
    while (last < steps.size() && steps[last] <= left)
        left -= steps[last++];
    std::size_t count = 0;
    for (const std::uint32_t c : vegetated) {
        const std::uint32_t s = step(c);
        if (s < last || (s == last && left > 0)) {
            if (s == last)
                --left;
            budgeted[count++] = c;
        }
    }
    return {budgeted.data(), count};
}

}  // namespace

std::size_t classify_cells(const PlantClassifier& model, CellWorkspace& ws, const CellBudget& budget)
{
    if (!model.has_cells())
        return 0;   // every cell stays Unknown
    const auto cells = ws.vegetated().size() > budget.max_cells
                           ? cells_in_budget(ws.vegetated(), budget, ws.grid_, ws.edge_steps_, ws.budgeted_)
                           : ws.vegetated();
    for (const std::uint32_t c : ws.vegetated()) {
        ws.in_budget_[c] = 0;
        ws.class_[c] = PlantClass::Unknown;
        ws.probability_[c] = 0;
    }
    for (const std::uint32_t c : cells)
        ws.in_budget_[c] = 1;
    // The forest's probability of each cell, then its mean over the 3x3
    // cells around it weighed by their vegetation: neighbouring cells are
    // mostly the same plant, and one cell's features are noisy.
    // Each cell's features go first into its row of the second stage, back
    // to back: both forests walk rows at constant offsets from one pointer.
    constexpr std::size_t kStride = kContextFeatureCount;
    float* const rows = ws.context_rows_.data();
    for (std::size_t k = 0; k < cells.size(); ++k) {
        const CellRow& own = ws.rows_[cells[k]];
        std::copy(own.begin(), own.end(), rows + k * kStride);
    }
    model.cell_weed_probabilities_packed<kStride>(cells.size(), rows, ws.listed_probability_.data());
    if (model.has_context()) {
        // The second stage: each cell's row and what the first stage said
        // around it.
        for (std::size_t k = 0; k < cells.size(); ++k) {
            ws.listed_weight_[k] = ws.rows_[cells[k]][c_fill];
            ws.listed_plant_[k] = ws.plant_[cells[k]];
        }
        const CellContextInput input{.grid = ws.grid_,
                                     .cell_mm = ws.cell_mm_,
                                     .cells = cells,
                                     .weight = {ws.listed_weight_.data(), cells.size()},
                                     .plant = {ws.listed_plant_.data(), cells.size()},
                                     .probability = {ws.listed_probability_.data(), cells.size()}};
        cell_context(input, ws.context_scratch_, {ws.context_.data(), cells.size()});
        for (std::size_t k = 0; k < cells.size(); ++k)
            std::copy(ws.context_[k].begin(), ws.context_[k].end(), rows + k * kStride + kCellFeatureCount);
        model.context_weed_probabilities_packed<kStride>(cells.size(), rows, ws.listed_probability_.data());
    }
    for (std::size_t k = 0; k < cells.size(); ++k)
        ws.raw_[cells[k]] = ws.listed_probability_[k];
    const int gw = ws.grid_.width, gh = ws.grid_.height;
    const int radius = kCellSmoothRadius;
    const auto bar = static_cast<float>(model.info().map_weed_bar);
    for (const std::uint32_t i : cells) {
        const int gx = static_cast<int>(i % static_cast<std::uint32_t>(gw)), gy = static_cast<int>(i / static_cast<std::uint32_t>(gw));
        float sum = 0, weight = 0;
        for (int y = std::max(gy - radius, 0); y <= std::min(gy + radius, gh - 1); ++y)
            for (int x = std::max(gx - radius, 0); x <= std::min(gx + radius, gw - 1); ++x) {
                const std::size_t j = static_cast<std::size_t>(y) * static_cast<std::size_t>(gw) + static_cast<std::size_t>(x);
                if (ws.samples_[j].sampled_px == 0 || !ws.in_budget_[j])
                    continue;
                const float w = ws.rows_[j][c_fill];
                sum += w * ws.raw_[j];
                weight += w;
            }
        const float p = weight > 0 ? sum / weight : ws.raw_[i];
        ws.probability_[i] = p;
        ws.class_[i] = p >= bar ? PlantClass::Weed : PlantClass::Crop;
    }
    return ws.vegetated().size() - cells.size();
}

void cell_class_map(const Workspace& dws, const CellWorkspace& ws, cv::Mat& out)
{
    const cv::Size size = ws.frame_size();
    if (out.size() != size || out.type() != CV_8UC1)
        out.create(size, CV_8UC1);
    for (int y = 0; y < out.rows; ++y)
        std::memset(out.ptr(y), 0, static_cast<std::size_t>(out.cols));
    const BitMask& vegetation = dws.vegetation();
    if (vegetation.width() != size.width || vegetation.height() != size.height)
        return;
    for (int y = 0; y < size.height; ++y) {
        auto* dst = out.ptr<std::uint8_t>(y);
        vegetation.visit_row(y, [&](int x) { dst[x] = to_value(ws.cell_class(ws.cell_of(x, y))); });
    }
}

void plant_probabilities_from_cells(const CellWorkspace& ws, std::size_t plants, std::span<float> out)
{
    const std::size_t count = std::min(plants, out.size());
    // Weighted sums in the output, the weights in the sign-free second pass:
    // a plant's weight is at most the frame's pixels, exact in float.
    std::array<float, kMaxPlants> weight{};
    std::array<bool, kMaxPlants> seen_in_part{};
    std::fill(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(count), 0.0f);
    for (const std::uint32_t i : ws.vegetated()) {
        const std::uint16_t id = ws.plant(i);
        if (id == 0 || id > count)
            continue;
        if (ws.cell_class(i) == PlantClass::Unknown) {
            seen_in_part[id - 1u] = true;
            continue;
        }
        const auto w = ws.row(i)[c_fill];
        out[id - 1u] += w * ws.weed_probability(i);
        weight[id - 1u] += w;
    }
    for (std::size_t p = 0; p < count; ++p)
        out[p] = weight[p] > 0 && !seen_in_part[p] ? out[p] / weight[p] : -1.0f;
}

}  // namespace stemd::vision

namespace stemd::vision {

void classify_plants(const PlantClassifier& model, const ClassifyWorkspace& plants, const CellWorkspace& cells,
                     std::size_t count, double min_confidence, double weed_confidence,
                     std::span<float> probabilities, std::span<PlantClass> classes)
{
    count = std::min({count, probabilities.size(), classes.size()});
    const auto features = plants.features();
    if (model.has_cells())
        plant_probabilities_from_cells(cells, count, probabilities);
    for (std::size_t i = 0; i < count; ++i) {
        if (!model.has_cells())
            probabilities[i] = i < features.size() ? model.weed_probability(features[i]) : -1.0f;
        classes[i] = probabilities[i] < 0 ? PlantClass::Unknown
                                          : decide_class(probabilities[i], min_confidence, weed_confidence);
    }
}

}  // namespace stemd::vision

namespace stemd::vision {

WeedTargetCounts add_weed_parts(CellWorkspace& ws, const WeedTargetParams& params, Detections& det,
                                std::span<PlantClass> classes, std::span<float> probabilities)
{
    const std::size_t plants = std::min({det.plants.size(), classes.size(), probabilities.size()});
    const std::size_t capacity = std::min(classes.size(), probabilities.size());
    const int gw = ws.grid_.width, gh = ws.grid_.height, cell_px = ws.cell_px_;
    const auto classified = [&](std::size_t c) { return ws.class_[c] != PlantClass::Unknown; };
    const auto weed_cell = [&](std::size_t c) {
        return classified(c) &&
               decide_class(ws.probability_[c], params.min_confidence, params.weed_confidence) == PlantClass::Weed;
    };
    const double clearance_px = std::max(params.clearance_mm, 0.0) / ws.gsd_;
    const double cover_px = std::max(params.cover_radius_mm, 0.0) / ws.gsd_;
    // Cell centres in image coordinates (pixel centres at integers); a
    // last, partial cell's centre may lie past the frame's edge.
    const auto cell_centre = [&](int g) { return (g + 0.5) * cell_px - 0.5; };
    const auto strike_point = [&](std::uint32_t c) {
        return cv::Point2f(
            static_cast<float>(std::min(cell_centre(static_cast<int>(c % static_cast<std::uint32_t>(gw))),
                                        ws.frame_size_.width - 1.0)),
            static_cast<float>(std::min(cell_centre(static_cast<int>(c / static_cast<std::uint32_t>(gw))),
                                        ws.frame_size_.height - 1.0)));
    };
    // Whether every vegetated cell whose square comes within clearance_px
    // of `at` is weed (one the budget left out is not known to be).
    const auto clear_at = [&](cv::Point2f at) {
        const int reach = static_cast<int>(std::ceil(clearance_px / cell_px)) + 1;
        const int cx = static_cast<int>(at.x + 0.5f) / cell_px, cy = static_cast<int>(at.y + 0.5f) / cell_px;
        for (int ny = std::max(cy - reach, 0); ny <= std::min(cy + reach, gh - 1); ++ny)
            for (int nx = std::max(cx - reach, 0); nx <= std::min(cx + reach, gw - 1); ++nx) {
                const std::size_t n = static_cast<std::size_t>(ny) * static_cast<std::size_t>(gw) + static_cast<std::size_t>(nx);
                if (ws.samples_[n].sampled_px == 0 || weed_cell(n))
                    continue;
                // Distance to the cell's square (pixel edges at -0.5).
                const double left = nx * cell_px - 0.5, top_edge = ny * cell_px - 0.5;
                const double dx = std::max({left - at.x, 0.0, at.x - (left + cell_px)});
                const double dy = std::max({top_edge - at.y, 0.0, at.y - (top_edge + cell_px)});
                if (dx * dx + dy * dy <= clearance_px * clearance_px)
                    return false;
            }
        return true;
    };
    WeedTargetCounts counts;
    // A new weed target at `at`; false when the plants are full (counted).
    const auto add_target = [&](cv::Point2f at, ComReason reason, double area_px, cv::Rect bbox, cv::Point2f centre,
                                double width_mm, double probability) {
        if (det.plants.full() || det.plants.size() >= capacity) {
            ++det.stats.plants_over_capacity;
            return false;
        }
        Plant target;
        target.stem = at;
        target.has_stem = true;
        target.method = StemMethod::com;
        target.estimator = StemEstimator::com;
        target.confidence = kCentreOfMassConfidence;
        target.com_reason = reason;
        target.area_px = static_cast<int>(std::lround(area_px));
        target.bbox = bbox & cv::Rect(0, 0, ws.frame_size_.width, ws.frame_size_.height);
        target.centre_of_mass = centre;
        target.first_pixel = target.bbox.tl();
        target.mean_width_mm = static_cast<float>(width_mm);
        const std::size_t index = det.plants.size();
        det.plants.push_back(target);
        classes[index] = PlantClass::Weed;
        probabilities[index] = static_cast<float>(probability);
        (reason == ComReason::weed_part ? counts.parts
                                        : reason == ComReason::stemless_weed ? counts.stemless : counts.cover)++;
        return true;
    };
    // Cover the weed cells listed in ws.part_stack_[begin, end), one target
    // at `first` already: farthest clear cell first, until every clear one
    // lies within cover_px of a target.
    const auto cover = [&](std::size_t begin, std::size_t end, cv::Point2f first) {
        for (std::size_t k = begin; k < end; ++k) {
            const cv::Point2f at = strike_point(ws.part_stack_[k]);
            ws.cover_d2_[k] = clear_at(at) ? static_cast<float>((at - first).dot(at - first)) : -1.0f;
        }
        for (std::size_t targets = 1; targets < params.max_targets_per_weed; ++targets) {
            std::size_t farthest = end;
            auto farthest_d2 = static_cast<float>(cover_px * cover_px);
            for (std::size_t k = begin; k < end; ++k)
                if (ws.cover_d2_[k] > farthest_d2) {
                    farthest_d2 = ws.cover_d2_[k];
                    farthest = k;
                }
            if (farthest == end)
                return;
            const std::uint32_t c = ws.part_stack_[farthest];
            const cv::Point2f at = strike_point(c);
            const int gx = static_cast<int>(c % static_cast<std::uint32_t>(gw)), gy = static_cast<int>(c / static_cast<std::uint32_t>(gw));
            if (!add_target(at, ComReason::weed_cover, ws.rows_[c][c_fill] * cell_px * cell_px,
                            cv::Rect(gx * cell_px, gy * cell_px, cell_px, cell_px), at, ws.rows_[c][c_width_mm],
                            ws.probability_[c]))
                return;
            for (std::size_t k = begin; k < end; ++k)
                if (ws.cover_d2_[k] >= 0) {
                    const cv::Point2f d = strike_point(ws.part_stack_[k]) - at;
                    ws.cover_d2_[k] = std::min(ws.cover_d2_[k], d.dot(d));
                }
        }
    };
    const bool covering = cover_px > 0 && params.max_targets_per_weed > 1;
    for (const std::uint32_t c : ws.vegetated())
        ws.in_part_[c] = 0;
    for (const std::uint32_t seed : ws.vegetated()) {
        const std::uint16_t id = ws.plant_[seed];
        if (ws.in_part_[seed] || !weed_cell(seed) || id == 0 || id > plants)
            continue;
        // A weed with a stem of its own is struck there (and covered below);
        // one without (grass, or a stem below min_confidence) is still a
        // weed to treat.
        const bool stemless_weed = classes[id - 1u] == PlantClass::Weed;
        if (stemless_weed && det.plants[id - 1u].has_stem)
            continue;
        // The group: the plant's weed cells 8-connected to the seed, listed
        // in ws.part_stack_[0, listed) as they are found.
        std::size_t listed = 0;
        ws.part_stack_[listed++] = seed;
        ws.in_part_[seed] = 1;
        double sum_x = 0, sum_y = 0, sum_w = 0, sum_p = 0, width_mm = 0, area_px = 0;
        int x0 = gw, y0 = gh, x1 = -1, y1 = -1;
        for (std::size_t next = 0; next < listed; ++next) {
            const std::uint32_t c = ws.part_stack_[next];
            const int gx = static_cast<int>(c % static_cast<std::uint32_t>(gw)), gy = static_cast<int>(c / static_cast<std::uint32_t>(gw));
            const double w = ws.rows_[c][c_fill];
            sum_x += w * cell_centre(gx);
            sum_y += w * cell_centre(gy);
            sum_w += w;
            sum_p += w * ws.probability_[c];
            width_mm += w * ws.rows_[c][c_width_mm];
            area_px += w * cell_px * cell_px;
            x0 = std::min(x0, gx), y0 = std::min(y0, gy), x1 = std::max(x1, gx), y1 = std::max(y1, gy);
            for (int ny = std::max(gy - 1, 0); ny <= std::min(gy + 1, gh - 1); ++ny)
                for (int nx = std::max(gx - 1, 0); nx <= std::min(gx + 1, gw - 1); ++nx) {
                    const std::size_t n = static_cast<std::size_t>(ny) * static_cast<std::size_t>(gw) + static_cast<std::size_t>(nx);
                    if (ws.in_part_[n] || ws.plant_[n] != id || !weed_cell(n))
                        continue;
                    ws.in_part_[n] = 1;
                    ws.part_stack_[listed++] = static_cast<std::uint32_t>(n);
                }
        }
        if (sum_w <= 0)
            continue;
        const cv::Point2f centre(static_cast<float>(sum_x / sum_w), static_cast<float>(sum_y / sum_w));
        // The strike goes to the group's centre when it is clear; else to
        // the clear centre of one of its cells nearest to it, so that a
        // weed whose centre lies near the crop it grew into is still
        // struck, with nothing but weed within the clearance.
        cv::Point2f strike = centre;
        if (!clear_at(centre)) {
            double best_d2 = std::numeric_limits<double>::max();
            for (std::size_t k = 0; k < listed; ++k) {
                const cv::Point2f at = strike_point(ws.part_stack_[k]);
                const double d2 = (at - centre).dot(at - centre);
                if (d2 < best_d2 && clear_at(at)) {
                    best_d2 = d2;
                    strike = at;
                }
            }
            if (best_d2 == std::numeric_limits<double>::max())
                continue;
        }
        if (add_target(strike, stemless_weed ? ComReason::stemless_weed : ComReason::weed_part, area_px,
                       cv::Rect(x0 * cell_px, y0 * cell_px, (x1 - x0 + 1) * cell_px, (y1 - y0 + 1) * cell_px),
                       centre, width_mm / sum_w, sum_p / sum_w) &&
            covering && stemless_weed)
            cover(0, listed, strike);
    }
    if (!covering)
        return counts;
    // Weeds with a stem: their weed cells, listed plant by plant in
    // ws.part_stack_ (a counting sort over the plant ids), covered from the
    // stem.
    const std::size_t weeds = std::min(plants, kMaxPlants);
    std::array<std::uint32_t, kMaxPlants + 2> start{};
    for (const std::uint32_t c : ws.vegetated()) {
        const std::uint16_t id = ws.plant_[c];
        if (id != 0 && id <= weeds && weed_cell(c))
            ++start[id + 1u];
    }
    for (std::size_t i = 1; i < start.size(); ++i)
        start[i] += start[i - 1];
    std::array<std::uint32_t, kMaxPlants + 1> next{};
    std::copy_n(start.begin(), next.size(), next.begin());
    for (const std::uint32_t c : ws.vegetated()) {
        const std::uint16_t id = ws.plant_[c];
        if (id != 0 && id <= weeds && weed_cell(c))
            ws.part_stack_[next[id]++] = c;
    }
    for (std::size_t p = 0; p < weeds; ++p)
        if (classes[p] == PlantClass::Weed && det.plants[p].has_stem)
            cover(start[p + 1], start[p + 2], det.plants[p].stem);
    return counts;
}

}  // namespace stemd::vision

namespace stemd::vision {

ModelClassCounts classify_frame(const PlantClassifier& model, const ModelClassParams& params, const FrameView& frame,
                                const Params& detect_params, const Workspace& detect_workspace, Detections& det,
                                ClassifyWorkspace& plants, CellWorkspace& cells, std::span<float> probabilities,
                                std::span<PlantClass> classes)
{
    ModelClassCounts counts;
    const std::size_t count = std::min({det.plants.size(), probabilities.size(), classes.size()});
    std::fill_n(classes.begin(), count, PlantClass::Unknown);
    std::fill_n(probabilities.begin(), count, -1.0f);
    plant_features(frame, detect_params, detect_workspace, det, plants);
    cell_features(frame, detect_params, detect_workspace, det, plants, cells);
    counts.cells_over_budget = classify_cells(model, cells, params.budget);
    if (plants.features().size() != det.plants.size())
        return counts;
    classify_plants(model, plants, cells, count, params.decision.min_confidence, params.decision.weed_confidence,
                    probabilities, classes);
    // Weeds grown into a crop get targets of their own.
    if (params.weed_parts)
        counts.weed_targets = add_weed_parts(cells, params.decision, det, classes, probabilities);
    return counts;
}

}  // namespace stemd::vision
