#include "stemd/vision/classify.hpp"

#include "stemd/base/whole_file.hpp"
#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/cells.hpp"
#include "stemd/vision/index.hpp"
#include "stemd/vision/run_colour.hpp"

#include <algorithm>
#include <bit>
#include <cstdio>
#include <cstring>
#include <cmath>
#include <numbers>

#include <opencv2/core.hpp>

namespace stemd::vision {

namespace {

constexpr std::array<std::string_view, kPlantFeatureCount> kFeatureNames{
    "log_area_mm2", "perimeter_mm", "solidity",   "compactness", "elongation", "extent",   "leaves",
    "leaf_elongation", "vegetation_fill", "mean_width_mm", "r_mean", "g_mean", "b_mean", "r_std",
    "g_std",        "exg_mean",     "brightness_rel", "texture", "ndvi_mean", "ndvi_std", "lateral",
    "row_offset_mm", "row_band_share", "row_neighbours", "area_share",
};

double sq(double v) { return v * v; }

// Zeroes an image row by row: Mat::setTo allocates a scratch buffer.
void clear_rows(cv::Mat& image)
{
    for (int y = 0; y < image.rows; ++y)
        std::memset(image.ptr(y), 0, image.cols * image.elemSize());
}

// Population standard deviation from sums; 0 for fewer than two values.
double spread(double sum, double sum2, double n)
{
    if (n < 2)
        return 0;
    const double mean = sum / n;
    return std::sqrt(std::max(0.0, sum2 / n - mean * mean));
}

// The row features: O(plants²) over at most kMaxPlants plants, on the
// Detections only (no pixel is read again).
void row_context(const Detections& det, double gsd, std::size_t plants,
                 std::array<FeatureRow, kMaxPlants>& features)
{
    const double band_px = kRowHalfWidthMm / std::max(gsd, 1e-6);
    double total_area = 0, largest_area = 1;
    for (std::size_t i = 0; i < plants; ++i) {
        total_area += det.plants[i].area_px;
        largest_area = std::max(largest_area, static_cast<double>(det.plants[i].area_px));
    }
    total_area = std::max(total_area, 1.0);
    // Each plant's band: the area in it and how many others share it. The
    // band with most area is the dominant row.
    double best_area = -1;
    std::size_t best = 0;
    for (std::size_t i = 0; i < plants; ++i) {
        const double xi = det.plants[i].centre_of_mass.x;
        double area = 0;
        int neighbours = 0;
        for (std::size_t j = 0; j < plants; ++j) {
            if (std::abs(det.plants[j].centre_of_mass.x - xi) > band_px)
                continue;
            area += det.plants[j].area_px;
            neighbours += j != i;
        }
        features[i][f_row_band_share] = static_cast<float>(area / total_area);
        features[i][f_row_neighbours] = static_cast<float>(neighbours);
        features[i][f_area_share] = static_cast<float>(det.plants[i].area_px / largest_area);
        if (area > best_area) {
            best_area = area;
            best = i;
        }
    }
    double row_sum = 0, row_area = 0;
    for (std::size_t j = 0; j < plants; ++j)
        if (std::abs(det.plants[j].centre_of_mass.x - det.plants[best].centre_of_mass.x) <= band_px) {
            row_sum += det.plants[j].area_px * static_cast<double>(det.plants[j].centre_of_mass.x);
            row_area += det.plants[j].area_px;
        }
    const double row_x = row_sum / std::max(row_area, 1.0);
    for (std::size_t i = 0; i < plants; ++i)
        features[i][f_row_offset_mm] = static_cast<float>(std::abs(det.plants[i].centre_of_mass.x - row_x) * gsd);
}

// A YAML sequence of strings under `key`.
void write_list(cv::FileStorage& fs, const char* key, const std::vector<std::string>& items)
{
    fs << key << "[";
    for (const std::string& item : items)
        fs << item;
    fs << "]";
}

// The list name(0), ..., name(count - 1) under `key`: what same_names()
// checks on load.
void write_names(cv::FileStorage& fs, const char* key, int count, std::string_view (*name)(int))
{
    fs << key << "[";
    for (int f = 0; f < count; ++f)
        fs << std::string(name(f));
    fs << "]";
}

}  // namespace

std::string_view feature_name(int feature)
{
    return feature >= 0 && feature < kPlantFeatureCount ? kFeatureNames[static_cast<std::size_t>(feature)]
                                                        : std::string_view("?");
}

ClassifyWorkspace::ClassifyWorkspace(cv::Size frame_size, const Params&)
    : frame_size_(frame_size)
{
    const int width = std::max(frame_size.width, 0);
    const int height = std::max(frame_size.height, 0);
    plant_index_.create(height, width, CV_16UC1);
    clear_rows(plant_index_);
    written_.assign(static_cast<std::size_t>(height), cv::Range(0, 0));
}

double sampled_frame_brightness(const cv::Mat& bgr)
{
    CV_Assert(bgr.empty() || bgr.type() == CV_8UC3);
    // One definition of a frame's brightness, the chromatic index's. It
    // reads 1/16 of the frame's bytes in order, where every 4th pixel of
    // every 4th row touched a quarter of its cache lines.
    return bgr.empty() ? 1.0 : static_cast<double>(chromatic_mean_brightness(bgr));
}

int colour_row_step(int vegetation_px)
{
    int step = 4;
    while (vegetation_px / step > kPlantColourSamples)
        step *= 2;
    return step;
}

void plant_features(const FrameView& frame, const Params& params, const Workspace& dws, const Detections& det,
                    ClassifyWorkspace& ws)
{
    // A frame the workspaces were not made for, or without its rgb image,
    // gives no features: its plants stay unclassified.
    ws.plants_ = 0;
    ws.frame_brightness_ = 0;
    // Only what the last frame wrote, row by row: the whole map is 2.5 MB,
    // and even the plants' bounding rectangle took a fifth of this
    // function's time on frames with plants all over.
    for (std::size_t y = 0; y < ws.written_.size(); ++y) {
        cv::Range& span = ws.written_[y];
        if (span.start < span.end)
            std::memset(ws.plant_index_.ptr<std::uint16_t>(static_cast<int>(y)) + span.start, 0,
                        static_cast<std::size_t>(span.end - span.start) * sizeof(std::uint16_t));
        span = cv::Range(0, 0);
    }
    if (det.plants.empty() || frame.bgr.empty() || frame.bgr.size() != ws.frame_size_ ||
        frame.bgr.type() != CV_8UC3 || dws.frame_size() != ws.frame_size_)
        return;
    ws.plants_ = det.plants.size();
    const BitMask& vegetation = dws.vegetation();
    const int words = vegetation.words_per_row();
    const std::span<const std::uint16_t> piece_plant = dws.piece_plant();
    const bool has_nir = !frame.nir.empty() && frame.nir.size() == ws.frame_size_ && frame.nir.type() == CV_8UC1;

    // One pass over the closed mask, run by run, from its labelling: each
    // run gets its plant once, its index pixels in one fill, its moments in
    // closed form from its ends and its vegetation count by bit count. Only
    // colour, texture and NDVI read pixels, on every colour_row_step()-th
    // row of the plant's box: they are means, and a quarter of the rows
    // estimates them as well as half did (cross-validated on cwfid-train and
    // carrot-dev). The rows start at the box's third row, or its middle one
    // under four rows, so a seedling one row tall is read too and the top
    // edge's mixed pixels are not the only ones read from a small plant.
    std::fill(ws.sums_.begin(), ws.sums_.begin() + static_cast<std::ptrdiff_t>(ws.plants_), ClassifyWorkspace::Sums{});
    for (std::size_t i = 0; i < ws.plants_; ++i)
        ws.colour_row_step_[i] = colour_row_step(det.plants[i].area_px);
    const int width = ws.frame_size_.width, height = ws.frame_size_.height;
    const LabelScratch& pieces = dws.pieces();
    for (std::size_t k = 0; k < pieces.run_count(); ++k) {
        const LabelScratch::LabelledRun run = pieces.run(k);
        const std::uint16_t id = piece_plant[static_cast<std::size_t>(run.component)];
        if (id == 0)
            continue;
        const int y = run.y, run_start = run.x0, run_stop = run.x1 + 1;   // one past the run's end
        const std::uint64_t* vrow = vegetation.row(y);
        auto* index_row = ws.plant_index_.ptr<std::uint16_t>(y);
        const auto* bgr = frame.bgr.ptr<cv::Vec3b>(y);
        const auto* bgr_up = frame.bgr.ptr<cv::Vec3b>(std::max(y - 1, 0));
        const auto* bgr_down = frame.bgr.ptr<cv::Vec3b>(std::min(y + 1, height - 1));
        const std::uint8_t* nir = has_nir ? frame.nir.ptr<std::uint8_t>(y) : nullptr;
        ClassifyWorkspace::Sums& s = ws.sums_[id - 1u];
        const cv::Rect& box = det.plants[id - 1u].bbox;
        const int first_sampled_dy = std::min(box.height / 2, 2);
        const bool sample_row = ((y - box.y - first_sampled_dy) & (ws.colour_row_step_[id - 1u] - 1)) == 0;
        std::fill(index_row + run_start, index_row + run_stop, id);
        cv::Range& written = ws.written_[static_cast<std::size_t>(y)];
        written = written.start < written.end
                      ? cv::Range(std::min(written.start, run_start), std::max(written.end, run_stop))
                      : cv::Range(run_start, run_stop);
        // Pixels x0..x1 relative to the box corner, all on row dy.
        const double n = run_stop - run_start;
        const double x0 = run_start - box.x, x1 = run_stop - 1 - box.x, dy = y - box.y;
        const double sum_x = (x0 + x1) * n / 2;
        s.closed_px += run_stop - run_start;
        s.x += sum_x;
        s.y += dy * n;
        s.xx += (x1 * (x1 + 1) * (2 * x1 + 1) - (x0 - 1) * x0 * (2 * x0 - 1)) / 6;
        s.yy += dy * dy * n;
        s.xy += dy * sum_x;
        // The run's vegetation pixels: counted on an unsampled row,
        // visited run of vegetation by run of vegetation on a sampled one.
        long vegetation_px = 0, sampled_px = 0;
        RunColour c;
        const ColourRows rows{bgr, bgr_up, bgr_down, nir, width};
        if (!sample_row)
            vegetation_px = count_bits_in_range(vrow, run_start, run_stop);
        for (int x_start = sample_row ? next_bit(vrow, words, run_stop, run_start, true) : run_stop;
             x_start < run_stop;) {
            const int x_stop = next_bit(vrow, words, run_stop, x_start, false);   // one past the vegetation run
            add_vegetation_run(rows, x_start, x_stop, c);
            sampled_px += x_stop - x_start;
            x_start = next_bit(vrow, words, run_stop, x_stop, true);
        }
        if (sample_row)
            vegetation_px = sampled_px;   // every vegetation pixel of a sampled row is visited
        s.vegetation_px += vegetation_px;
        s.sampled_px += sampled_px;
        s.brightness += static_cast<double>(c.brightness);
        s.gradient += static_cast<double>(c.gradient);
        s.r += c.r;
        s.g += c.g;
        s.b += c.b;
        s.rr += c.rr;
        s.gg += c.gg;
        s.ndvi += c.ndvi;
        s.ndvi2 += c.ndvi2;
    }

    // 3. Features from the sums and the plant's own measures.
    const double frame_brightness = sampled_frame_brightness(frame.bgr);
    ws.frame_brightness_ = static_cast<float>(frame_brightness);
    const double gsd = params.gsd_mm_per_px;
    for (std::size_t i = 0; i < ws.plants_; ++i) {
        const Plant& plant = det.plants[i];
        const ClassifyWorkspace::Sums& s = ws.sums_[i];
        FeatureRow& f = ws.features_[i];
        const double closed_px = std::max<double>(static_cast<double>(s.closed_px), 1);
        // Means over the sampled rows; a plant with no vegetation pixel on
        // them (pieces of a group apart, rows the closing filled) has 0
        // colour, texture and NDVI.
        const double veg_px = std::max<double>(static_cast<double>(s.sampled_px), 1);
        const double area_mm2 = std::max(static_cast<double>(plant.area_px), 1.0) * gsd * gsd;
        const double width_mm = plant.mean_width_mm > 0 ? plant.mean_width_mm : 0.0;
        // Without a traced contour (centre-of-mass estimator) the perimeter
        // is that of a disc of the same area.
        const double perimeter_mm =
            width_mm > 0 ? 2.0 * area_mm2 / width_mm : 2.0 * std::sqrt(std::numbers::pi * area_mm2);
        const double mx = s.x / closed_px, my = s.y / closed_px;
        const double cxx = s.xx / closed_px - mx * mx, cyy = s.yy / closed_px - my * my;
        const double cxy = s.xy / closed_px - mx * my;
        const double half_trace = 0.5 * (cxx + cyy);
        const double root = std::sqrt(std::max(0.0, sq(0.5 * (cxx - cyy)) + cxy * cxy));
        const double major = half_trace + root, minor = std::max(half_trace - root, 1e-3);
        float leaf_elongation = 1;
        if (!plant.leaves.empty()) {
            double sum = 0;
            for (const Leaf& leaf : plant.leaves)
                sum += leaf.elongation;
            leaf_elongation = static_cast<float>(sum / static_cast<double>(plant.leaves.size()));
        }
        const double brightness = s.brightness / veg_px;
        f[f_log_area_mm2] = static_cast<float>(std::log10(area_mm2));
        f[f_perimeter_mm] = static_cast<float>(perimeter_mm);
        f[f_solidity] = plant.hull_fill;
        f[f_compactness] = static_cast<float>(4.0 * std::numbers::pi * area_mm2 / std::max(sq(perimeter_mm), 1e-9));
        f[f_elongation] = static_cast<float>(std::sqrt(std::max(major, 1e-3) / minor));
        f[f_extent] = static_cast<float>(closed_px / std::max(plant.bbox.area(), 1));
        f[f_leaves] = static_cast<float>(plant.leaves.size());
        f[f_leaf_elongation] = leaf_elongation;
        f[f_vegetation_fill] = static_cast<float>(static_cast<double>(s.vegetation_px) / closed_px);
        f[f_mean_width_mm] = static_cast<float>(width_mm);
        f[f_r_mean] = static_cast<float>(s.r / veg_px);
        f[f_g_mean] = static_cast<float>(s.g / veg_px);
        f[f_b_mean] = static_cast<float>(s.b / veg_px);
        f[f_r_std] = static_cast<float>(spread(s.r, s.rr, veg_px));
        f[f_g_std] = static_cast<float>(spread(s.g, s.gg, veg_px));
        f[f_exg_mean] = f[f_g_mean] * 2 - f[f_r_mean] - f[f_b_mean];
        f[f_brightness_rel] = static_cast<float>(brightness / frame_brightness);
        f[f_texture] = static_cast<float>(s.gradient / veg_px / std::max(brightness, 1.0));
        f[f_ndvi_mean] = has_nir ? static_cast<float>(s.ndvi / veg_px) : 0.0f;
        f[f_ndvi_std] = has_nir ? static_cast<float>(spread(s.ndvi, s.ndvi2, veg_px)) : 0.0f;
        f[f_lateral] = static_cast<float>(plant.centre_of_mass.x / std::max(width, 1));
    }
    row_context(det, gsd, ws.plants_, ws.features_);
}

std::uint64_t plant_classes_from_map(const cv::Mat& class_map, cv::Size frame_size,
                                     const Detections& detections,
                                     std::array<PlantClass, kMaxPlants>& out) noexcept
{
    std::uint64_t bad = 0;
    constexpr double kHalf = 4;   // the window's half-width in frame pixels
    const double sx = static_cast<double>(class_map.cols) / std::max(frame_size.width, 1);
    const double sy = static_cast<double>(class_map.rows) / std::max(frame_size.height, 1);
    for (std::size_t i = 0; i < detections.plants.size(); ++i) {
        const Plant& p = detections.plants[i];
        out[i] = PlantClass::Unknown;
        if (!p.has_stem || class_map.empty())
            continue;
        // The window's pixels in the map: the frame pixels' cells, however
        // coarse the map (one cell at least).
        const int x0 = std::max(static_cast<int>(std::floor((p.stem.x - kHalf) * sx)), 0);
        const int x1 = std::min(static_cast<int>(std::floor((p.stem.x + kHalf) * sx)), class_map.cols - 1);
        const int y0 = std::max(static_cast<int>(std::floor((p.stem.y - kHalf) * sy)), 0);
        const int y1 = std::min(static_cast<int>(std::floor((p.stem.y + kHalf) * sy)), class_map.rows - 1);
        int crop = 0, weed = 0, other = 0;
        for (int y = y0; y <= y1; ++y) {
            const std::uint8_t* row = class_map.ptr<std::uint8_t>(y);
            for (int x = x0; x <= x1; ++x) {
                crop += plant_class_from_value(row[x]) == PlantClass::Crop;
                weed += plant_class_from_value(row[x]) == PlantClass::Weed;
                other += row[x] > 2;
            }
        }
        out[i] = weed > crop ? PlantClass::Weed : crop > weed ? PlantClass::Crop : PlantClass::Unknown;
        bad += other > 0;
    }
    return bad;
}

PlantClass decide_class(float weed_probability, double min_confidence, double weed_confidence)
{
    // In float, as the probability is: 0.7f must pass a 0.7 bar.
    const auto bar = static_cast<float>(min_confidence);
    if (weed_probability >= std::max(bar, static_cast<float>(weed_confidence)))
        return PlantClass::Weed;
    if (1.0f - weed_probability >= bar)
        return PlantClass::Crop;
    return PlantClass::Unknown;
}

void class_map(const Workspace& dws, const ClassifyWorkspace& ws, std::span<const PlantClass> plant_classes,
               cv::Mat& out)
{
    const cv::Size size = ws.frame_size();
    if (out.size() != size || out.type() != CV_8UC1)
        out.create(size, CV_8UC1);
    clear_rows(out);
    const BitMask& vegetation = dws.vegetation();
    if (vegetation.width() != size.width || vegetation.height() != size.height)
        return;
    for (int y = 0; y < size.height; ++y) {
        const auto* index = ws.plant_index().ptr<std::uint16_t>(y);
        auto* dst = out.ptr<std::uint8_t>(y);
        vegetation.visit_row(y, [&](int x) {
            const std::size_t id = index[x];
            if (id > 0 && id <= plant_classes.size())
                dst[x] = to_value(plant_classes[id - 1]);
        });
    }
}

std::string_view channels_name(bool nir) { return nir ? "rgb+nir" : "rgb"; }

namespace {

// A forest on rows of `columns` features with labels 1 crop, 2 weed
// (internally 0 crop, 1 weed: PREDICT_SUM over the trees then counts the
// weed votes); null with `error` set if it cannot be trained.
cv::Ptr<cv::ml::RTrees> train_forest(const cv::Mat& samples, const cv::Mat& labels, int columns,
                                     const ForestOptions& options, std::string& error,
                                     const cv::Mat& weights = {})
{
    if (!weights.empty() && (weights.type() != CV_32FC1 || weights.total() != static_cast<std::size_t>(samples.rows))) {
        error = "sample weights must be one CV_32F value per row";
        return {};
    }
    if (samples.type() != CV_32FC1 || samples.cols != columns || labels.type() != CV_32SC1 ||
        labels.rows != samples.rows || labels.cols != 1) {
        error = "training data must be CV_32F rows of " + std::to_string(columns) +
                " features with one CV_32S label each";
        return {};
    }
    cv::Mat responses(labels.rows, 1, CV_32SC1);
    int counts[2] = {0, 0};
    double weighed[2] = {0, 0};   // the classes' summed weights, which the priors balance
    for (int i = 0; i < labels.rows; ++i) {
        const int label = labels.at<int>(i);
        if (label != to_value(PlantClass::Crop) && label != to_value(PlantClass::Weed)) {
            error = "label " + std::to_string(label) + " is neither crop (1) nor weed (2)";
            return {};
        }
        responses.at<int>(i) = label == to_value(PlantClass::Weed) ? 1 : 0;
        ++counts[responses.at<int>(i)];
        weighed[responses.at<int>(i)] += weights.empty() ? 1.0 : static_cast<double>(weights.at<float>(i));
    }
    if (counts[0] == 0 || counts[1] == 0) {
        error = "training needs crop and weed plants (" + std::to_string(counts[0]) + " crop, " +
                std::to_string(counts[1]) + " weed)";
        return {};
    }
    auto forest = cv::ml::RTrees::create();
    forest->setMaxDepth(options.max_depth);
    forest->setMinSampleCount(options.min_sample_count);
    forest->setActiveVarCount(0);   // sqrt of the feature count per split
    forest->setCalculateVarImportance(options.var_importance);
    forest->setTermCriteria(cv::TermCriteria(cv::TermCriteria::MAX_ITER, options.trees, 0));
    if (options.balance_classes) {
        const double total = weighed[0] + weighed[1];
        cv::Mat priors = (cv::Mat_<float>(1, 2) << static_cast<float>(total / (2.0 * weighed[0])),
                          static_cast<float>(total / (2.0 * weighed[1])));
        forest->setPriors(priors);
    }
    try {
        // The forest draws its bootstrap samples and split variables from
        // the thread's cv::theRNG(): seeded, the same data gives the same forest.
        cv::theRNG() = cv::RNG(options.seed);
        const auto data = weights.empty()
                              ? cv::ml::TrainData::create(samples, cv::ml::ROW_SAMPLE, responses)
                              : cv::ml::TrainData::create(samples, cv::ml::ROW_SAMPLE, responses, cv::noArray(),
                                                          cv::noArray(), weights.reshape(1, 1));
        if (!forest->train(data)) {
            error = "OpenCV RTrees training failed";
            return {};
        }
    } catch (const cv::Exception& e) {
        error = std::string("OpenCV RTrees training failed: ") + e.what();
        return {};
    }
    return forest;
}

}  // namespace

FlatForest flatten(const cv::ml::RTrees& forest)
{
    FlatForest flat;
    const auto& nodes = forest.getNodes();
    const auto& splits = forest.getSplits();
    const auto node_count = static_cast<int>(nodes.size());
    const int vars = forest.getVarCount();
    const auto valid = [&](int i) { return i >= 0 && i < node_count; };
    flat.nodes.reserve(nodes.size());
    flat.vote.reserve(nodes.size());
    for (int i = 0; i < node_count; ++i) {
        const auto& node = nodes[static_cast<std::size_t>(i)];
        FlatForest::Node n{0, 0.0f, {i, i}};
        if (node.split >= 0) {
            if (static_cast<std::size_t>(node.split) >= splits.size())
                return {};
            const auto& split = splits[static_cast<std::size_t>(node.split)];
            if (split.varIdx < 0 || split.varIdx >= vars || !valid(node.left) || !valid(node.right))
                return {};
            n.var = split.varIdx;
            n.threshold = split.c;
            // An inversed split sends values at or below c right.
            n.child = split.inversed ? std::array<int, 2>{node.right, node.left}
                                     : std::array<int, 2>{node.left, node.right};
        }
        flat.nodes.push_back(n);
        flat.vote.push_back(static_cast<float>(node.value));
    }
    // Each tree's depth, walking every path; a cycle or a tree deeper than
    // kMaxFlatDepth makes the forest one this walk refuses.
    std::vector<std::pair<int, int>> stack;
    for (const int root : forest.getRoots()) {
        if (!valid(root))
            return {};
        int depth = 0;
        stack.assign(1, {root, 0});
        while (!stack.empty()) {
            const auto [at, level] = stack.back();
            stack.pop_back();
            const FlatForest::Node& n = flat.nodes[static_cast<std::size_t>(at)];
            if (n.child[0] == at && n.child[1] == at) {
                depth = std::max(depth, level);
                continue;
            }
            if (level >= kMaxFlatDepth)
                return {};
            stack.emplace_back(n.child[0], level + 1);
            stack.emplace_back(n.child[1], level + 1);
        }
        flat.roots.push_back(root);
        flat.depths.push_back(depth);
    }
    return flat;
}

std::optional<PlantClassifier> PlantClassifier::train(const cv::Mat& samples, const cv::Mat& labels,
                                                      const ForestOptions& options, std::string& error)
{
    PlantClassifier model;
    // The plant forest keeps no importance to report: never worth its time.
    ForestOptions plant_options = options;
    plant_options.var_importance = false;
    model.forest_ = train_forest(samples, labels, kPlantFeatureCount, plant_options, error);
    if (!model.forest_)
        return std::nullopt;
    model.trees_ = static_cast<float>(std::max<std::size_t>(model.forest_->getRoots().size(), 1));
    model.info_.trees = static_cast<int>(model.trees_);
    model.info_.feature_names.assign(kFeatureNames.begin(), kFeatureNames.end());
    return model;
}

bool PlantClassifier::train_cells(const cv::Mat& samples, const cv::Mat& labels, const ForestOptions& options,
                                  double cell_mm, std::string& error, const cv::Mat& weights)
{
    auto forest = train_forest(samples, labels, kCellFeatureCount, options, error, weights);
    if (!forest)
        return false;
    cell_forest_ = forest;
    cell_flat_ = flatten(*forest);
    cell_importance_ = forest->getVarImportance();
    info_.cell_mm = cell_mm;
    info_.cell_trees = static_cast<int>(cell_flat_.roots.size());
    return true;
}

bool PlantClassifier::train_context(const cv::Mat& samples, const cv::Mat& labels, const ForestOptions& options,
                                    std::string& error, const cv::Mat& weights)
{
    if (!has_cells()) {
        error = "the context forest needs a cell forest first";
        return false;
    }
    auto forest = train_forest(samples, labels, kContextFeatureCount, options, error, weights);
    if (!forest)
        return false;
    context_forest_ = forest;
    context_flat_ = flatten(*forest);
    context_importance_ = forest->getVarImportance();
    info_.context_trees = static_cast<int>(context_flat_.roots.size());
    return true;
}

float PlantClassifier::weed_probability(const FeatureRow& features) const
{
    // A header over the caller's array: no copy, no allocation.
    const cv::Mat row(1, kPlantFeatureCount, CV_32FC1, const_cast<float*>(features.data()));
    const float votes = forest_->predict(row, cv::noArray(), cv::ml::DTrees::PREDICT_SUM);
    return std::clamp(votes / trees_, 0.0f, 1.0f);
}

bool PlantClassifier::save(const std::filesystem::path& path, ModelInfo info, std::string& error) const
{
    info.trees = static_cast<int>(trees_);
    info.features_version = kPlantFeaturesVersion;
    info.feature_names.assign(kFeatureNames.begin(), kFeatureNames.end());
    try {
        cv::FileStorage fs(path.string(), cv::FileStorage::WRITE);
        if (!fs.isOpened()) {
            error = path.string() + ": cannot write";
            return false;
        }
        fs << "stemd_plant_classifier" << "{";
        fs << "features_version" << info.features_version;
        write_list(fs, "feature_names", info.feature_names);
        fs << "gsd_mm_per_px" << info.gsd_mm_per_px;
        fs << "channels" << std::string(channels_name(info.nir));
        fs << "segmentation" << info.segmentation;
        write_list(fs, "recordings", info.recordings);
        fs << "trained_utc" << info.trained_utc;
        fs << "trees" << info.trees;
        fs << "cell_mm" << info_.cell_mm;
        fs << "cell_trees" << info_.cell_trees;
        fs << "map_weed_bar" << info_.map_weed_bar;
        write_names(fs, "cell_feature_names", kCellFeatureCount, cell_feature_name);
        fs << "context_trees" << info_.context_trees;
        if (context_forest_)
            write_names(fs, "context_feature_names", kContextFeatureCount, context_feature_name);
        fs << "cross_validation" << info.cross_validation;
        fs << "}";
        fs << "forest" << "{";
        forest_->write(fs);
        fs << "}";
        if (cell_forest_) {
            fs << "cell_forest" << "{";
            cell_forest_->write(fs);
            fs << "}";
        }
        if (context_forest_) {
            fs << "cell_context_forest" << "{";
            context_forest_->write(fs);
            fs << "}";
        }
    } catch (const cv::Exception& e) {
        error = path.string() + ": cannot write: " + e.what();
        return false;
    }
    return true;
}

namespace {

// Whether the list `node` is exactly name(0), ..., name(count - 1).
bool same_names(const cv::FileNode& node, int count, std::string_view (*name)(int))
{
    std::vector<std::string> read;
    for (const auto& n : node)
        read.push_back(static_cast<std::string>(n));
    if (read.size() != static_cast<std::size_t>(count))
        return false;
    for (int f = 0; f < count; ++f)
        if (read[static_cast<std::size_t>(f)] != name(f))
            return false;
    return true;
}

// The forest stored at `node` and its flat copy; false with `error`
// (starting with `what`) unless it is trained on `columns` features and
// every split is one flatten() can walk.
bool read_walkable_forest(const cv::FileNode& node, int columns, const std::string& what,
                          cv::Ptr<cv::ml::RTrees>& forest, FlatForest& flat, std::string& error)
{
    forest = cv::ml::RTrees::create();
    forest->read(node);
    if (!forest->isTrained() || forest->getVarCount() != columns) {
        error = what + " is no trained forest of " + std::to_string(columns) + " features";
        return false;
    }
    flat = flatten(*forest);
    if (flat.roots.empty()) {
        error = what + " has splits this build cannot walk";
        return false;
    }
    return true;
}

}  // namespace

std::optional<PlantClassifier> PlantClassifier::load(const std::filesystem::path& path, std::string& error)
{
    const std::string name = path.string();
    // Read here, not by cv::FileStorage from the path: it would wait forever
    // on a FIFO and read /dev/zero until the memory is gone.
    std::string text;
    const base::WholeFileResult read = base::read_whole_file(name.c_str(), kMaxModelFileBytes, text);
    if (!read.ok()) {
        error = name + ": cannot read the model file: " + base::why_unread(read, kMaxModelFileBytes);
        return std::nullopt;
    }
    try {
        // The format (YAML, JSON or XML) is told from the text's start.
        cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
        if (!fs.isOpened()) {
            error = name + ": cannot read the model file: not a FileStorage document";
            return std::nullopt;
        }
        const cv::FileNode meta = fs["stemd_plant_classifier"];
        if (meta.empty() || !meta.isMap()) {
            error = name + ": not a stemd plant classifier (no stemd_plant_classifier section)";
            return std::nullopt;
        }
        PlantClassifier model;
        ModelInfo& info = model.info_;
        info.features_version = static_cast<int>(meta["features_version"]);
        if (info.features_version != kPlantFeaturesVersion) {
            error = name + ": features version " + std::to_string(info.features_version) + ", this build computes " +
                    std::to_string(kPlantFeaturesVersion) + ": train the model again";
            return std::nullopt;
        }
        for (const auto& n : meta["feature_names"])
            info.feature_names.push_back(static_cast<std::string>(n));
        if (info.feature_names != std::vector<std::string>(kFeatureNames.begin(), kFeatureNames.end())) {
            error = name + ": its feature names differ from this build's: train the model again";
            return std::nullopt;
        }
        info.gsd_mm_per_px = static_cast<double>(meta["gsd_mm_per_px"]);
        const std::string channels = static_cast<std::string>(meta["channels"]);
        if (channels != channels_name(false) && channels != channels_name(true)) {
            error = name + ": channels '" + channels + "' is neither rgb nor rgb+nir";
            return std::nullopt;
        }
        info.nir = channels == channels_name(true);
        info.segmentation = static_cast<std::string>(meta["segmentation"]);
        for (const auto& n : meta["recordings"])
            info.recordings.push_back(static_cast<std::string>(n));
        info.trained_utc = static_cast<std::string>(meta["trained_utc"]);
        info.cross_validation = static_cast<std::string>(meta["cross_validation"]);
        if (!(info.gsd_mm_per_px > 0)) {
            error = name + ": no valid gsd_mm_per_px";
            return std::nullopt;
        }
        model.forest_ = cv::ml::RTrees::create();
        model.forest_->read(fs["forest"]);
        if (!model.forest_->isTrained() || model.forest_->getVarCount() != kPlantFeatureCount) {
            error = name + ": no trained forest of " + std::to_string(kPlantFeatureCount) + " features";
            return std::nullopt;
        }
        model.trees_ = static_cast<float>(std::max<std::size_t>(model.forest_->getRoots().size(), 1));
        info.trees = static_cast<int>(model.trees_);
        if (!same_names(meta["cell_feature_names"], kCellFeatureCount, cell_feature_name)) {
            error = name + ": its cell feature names differ from this build's: train the model again";
            return std::nullopt;
        }
        info.cell_mm = static_cast<double>(meta["cell_mm"]);
        // A model written before the map had its own bar: the most likely class.
        info.map_weed_bar = meta["map_weed_bar"].empty() ? 0.5 : static_cast<double>(meta["map_weed_bar"]);
        if (!(info.map_weed_bar > 0 && info.map_weed_bar < 1)) {
            error = name + ": map_weed_bar must lie between 0 and 1";
            return std::nullopt;
        }
        if (!fs["cell_forest"].empty()) {
            if (!(info.cell_mm > 0)) {
                error = name + ": a cell forest without its cell_mm";
                return std::nullopt;
            }
            if (!read_walkable_forest(fs["cell_forest"], kCellFeatureCount, name + ": the cell forest",
                                      model.cell_forest_, model.cell_flat_, error))
                return std::nullopt;
        }
        info.cell_trees = static_cast<int>(model.cell_flat_.roots.size());
        // A model from before the context stage has none: its cell forest decides.
        if (!fs["cell_context_forest"].empty()) {
            if (!same_names(meta["context_feature_names"], kContextFeatureCount, context_feature_name)) {
                error = name + ": its context feature names differ from this build's: train the model again";
                return std::nullopt;
            }
            if (!model.cell_forest_) {
                error = name + ": a cell context forest without a cell forest";
                return std::nullopt;
            }
            if (!read_walkable_forest(fs["cell_context_forest"], kContextFeatureCount, name + ": the cell context forest",
                                      model.context_forest_, model.context_flat_, error))
                return std::nullopt;
        }
        info.context_trees = static_cast<int>(model.context_flat_.roots.size());
        return model;
    } catch (const cv::Exception& e) {
        error = name + ": unreadable model: " + e.what();
        return std::nullopt;
    }
}

std::optional<std::string> PlantClassifier::mismatch(double gsd_mm_per_px, bool nir, std::string_view model_name) const
{
    const std::string name(model_name);
    if (!(gsd_mm_per_px > 0) || std::abs(info_.gsd_mm_per_px / gsd_mm_per_px - 1.0) > kModelGsdTolerance) {
        char text[160];
        std::snprintf(text, sizeof text,
                      ": trained at camera.gsd_mm_per_px %.4g, configured %.4g (more than %.0f %% apart)",
                      info_.gsd_mm_per_px, gsd_mm_per_px, kModelGsdTolerance * 100);
        return name + text;
    }
    if (info_.nir != nir)
        return name + ": trained on " + std::string(channels_name(info_.nir)) + " frames, the configuration reads " +
               std::string(channels_name(nir)) + " (segment.method)";
    return std::nullopt;
}

}  // namespace stemd::vision
