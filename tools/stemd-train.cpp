// stemd-train: trains the crop/weed classifier (the plant forest of
// vision/classify and the cell forest of vision/cells) from recordings with
// a class column, prints cross-validated figures split by frame, and writes
// one model file.
//   stemd-train --out MODEL [--config FILE] [--set K=V]... [--folds N] [--split interleaved|blocks]
//               [--trees N] [--max-depth N] [--cell-mm MM] [--cell-trees N]
//               [--cell-max-depth N] [--cell-samples N] [--cell-context yes|no] [--seed N] [--jobs N]
//               [--cell-weights cells|pixels] [--test-on RECORDING]... [--test-set K=V]...
//               [--cells-csv FILE] RECORDING...
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "stemd/config/command_line.hpp"
#include "stemd/config/config.hpp"
#include "stemd/io/recording.hpp"
#include "stemd/vision/cells.hpp"
#include "stemd/vision/classify.hpp"
#include "stemd/vision/detect.hpp"
#include "tool_cli.hpp"
#include "tool_frames.hpp"

namespace fs = std::filesystem;
using namespace stemd;

namespace {

using tools::kUsageError;

// Inner folds of the context stage's out-of-fold first-stage probabilities
// (3 gives the same out-of-fold accuracy within 0.002 on cwfid-train, a
// prototype's measure; 5 keeps four fifths of the frames per inner forest,
// as the outer folds do).
constexpr std::size_t kContextInnerFolds = 5;

// One plant of one frame: its features, the class the human class image
// gives it (by majority of its vegetation pixels), and those pixels' counts.
struct Sample {
    vision::FeatureRow features;
    int label = 0;          // 1 crop, 2 weed
    long crop_px = 0;       // the plant's vegetation pixels the class image calls crop
    long weed_px = 0;
};

// One vegetated cell of one frame: its row and label (the majority of its
// segmented vegetation pixels' human classes; 0 when none is labelled: such
// cells train nothing but give the context stage its neighbours).
struct CellSample {
    vision::CellRow row;
    int label = 0;
    std::uint32_t cell = 0;    // grid index
    std::uint16_t plant = 0;   // 1 + plant index, 0 none
    int crop_px = 0;           // its segmented vegetation pixels the class image calls crop
    int weed_px = 0;           // and weed
    int labelled_px() const { return crop_px + weed_px; }
};

struct FrameSamples {
    std::size_t job = 0;    // index into the frame jobs, to run the frame again for scoring
    std::string name;
    std::vector<Sample> plants;
    std::vector<CellSample> cells;   // every vegetated cell, in grid order
    cv::Size grid;
};

// detect(), the plant features and the cell features of one frame, and its
// class image; the workspaces follow the frame size.
struct Pipeline {
    vision::Params params;
    double cell_mm = 3;
    std::unique_ptr<vision::Workspace> ws;
    std::unique_ptr<vision::ClassifyWorkspace> cws;
    std::unique_ptr<vision::CellWorkspace> cells;
    std::unique_ptr<vision::Detections> det = std::make_unique<vision::Detections>();
    tools::LoadedFrame frame;
    cv::Mat class_image;

    bool run(const tools::FrameJob& job, std::string& error)
    {
        if (!tools::load_frame(job, params.segmentation, true, frame, error))
            return false;
        if (frame.bgr.empty()) {
            error = job.image + ": the features need the rgb image";
            return false;
        }
        if (!io::load_image(job.plant_class, cv::IMREAD_GRAYSCALE, class_image, error))
            return false;
        if (class_image.size() != frame.bgr.size()) {
            error = job.plant_class.string() + ": class image size differs from its rgb image";
            return false;
        }
        const cv::Size size = frame.bgr.size();
        if (!ws || ws->frame_size() != size) {
            ws = std::make_unique<vision::Workspace>(size, params);
            cws = std::make_unique<vision::ClassifyWorkspace>(size, params);
            cells = std::make_unique<vision::CellWorkspace>(size, params.gsd_mm_per_px, cell_mm);
        }
        const vision::FrameView view{.bgr = frame.bgr, .nir = frame.nir, .mask = frame.mask};
        vision::detect(view, params, *ws, *det);
        if (det->status != vision::DetectStatus::ok) {
            error = job.image + ": " + std::string(vision::to_string(det->status));
            return false;
        }
        vision::plant_features(view, params, *ws, *det, *cws);
        vision::cell_features(view, params, *ws, *det, *cws, *cells);
        return true;
    }

    // Each plant's crop and weed pixels: the class image under its
    // segmented vegetation pixels.
    void plant_truth(std::vector<long>& crop, std::vector<long>& weed) const
    {
        crop.assign(det->plants.size(), 0);
        weed.assign(det->plants.size(), 0);
        const vision::BitMask& vegetation = ws->vegetation();
        for (int y = 0; y < class_image.rows; ++y) {
            const auto* cls = class_image.ptr<std::uint8_t>(y);
            const auto* index = cws->plant_index().ptr<std::uint16_t>(y);
            for (int x = 0; x < class_image.cols; ++x) {
                if (index[x] == 0 || !vegetation.get(x, y))
                    continue;
                crop[index[x] - 1u] += plant_class_from_value(cls[x]) == PlantClass::Crop;
                weed[index[x] - 1u] += plant_class_from_value(cls[x]) == PlantClass::Weed;
            }
        }
    }
};

// Loads the configuration's vision parameters.
bool load_params(const config::ConfigArgs& config_args, vision::Params& params, std::string& error)
{
    config::Config config;
    if (const auto config_error = config::build_config(config_args, config)) {
        error = config_error->to_string();
        return false;
    }
    params = config.settings().daemon.vision;
    return true;
}

// The recordings' frames with a class image; segment.method auto is
// resolved on them (params.segmentation then names the method that ran).
bool frame_jobs(const std::vector<std::string>& recordings, vision::Params& params,
                std::vector<tools::FrameJob>& jobs, std::string& error)
{
    for (const std::string& r : recordings) {
        if (!io::is_recording_dir(r)) {
            error = r + ": not a recording directory (frames.csv with a class column)";
            return false;
        }
    }
    std::vector<tools::FrameJob> all;
    if (!tools::collect_frames(recordings, params.segmentation, all, error))
        return false;
    for (tools::FrameJob& job : all) {
        if (job.plant_class.empty())
            std::cerr << "stemd-train: " << job.image << ": no class image, skipped\n";
        else
            jobs.push_back(std::move(job));
    }
    if (jobs.empty()) {
        error = "no frame with a class image";
        return false;
    }
    params.segmentation = tools::frames_segmentation(params.segmentation, jobs);
    return true;
}

// The training rows of every frame: plants and cells.
bool collect(const std::vector<tools::FrameJob>& jobs, Pipeline& pipeline, std::vector<FrameSamples>& out,
             std::string& error)
{
    for (std::size_t j = 0; j < jobs.size(); ++j) {
        if (!pipeline.run(jobs[j], error))
            return false;
        FrameSamples fs_out;
        fs_out.job = j;
        fs_out.name = jobs[j].image;
        std::vector<long> crop, weed;
        pipeline.plant_truth(crop, weed);
        for (std::size_t i = 0; i < pipeline.det->plants.size(); ++i) {
            if (crop[i] + weed[i] == 0)
                continue;
            Sample s;
            s.features = pipeline.cws->features()[i];
            s.label = to_value(crop[i] >= weed[i] ? PlantClass::Crop : PlantClass::Weed);
            s.crop_px = crop[i];
            s.weed_px = weed[i];
            fs_out.plants.push_back(s);
        }
        // Each cell's crop and weed pixels among its segmented vegetation.
        const vision::CellWorkspace& cells = *pipeline.cells;
        std::vector<int> cell_crop(cells.cells(), 0), cell_weed(cells.cells(), 0);
        const vision::BitMask& vegetation = pipeline.ws->vegetation();
        for (int y = 0; y < pipeline.class_image.rows; ++y) {
            const auto* cls = pipeline.class_image.ptr<std::uint8_t>(y);
            for (int x = 0; x < pipeline.class_image.cols; ++x) {
                if (!vegetation.get(x, y))
                    continue;
                const std::size_t c = cells.cell_of(x, y);
                cell_crop[c] += plant_class_from_value(cls[x]) == PlantClass::Crop;
                cell_weed[c] += plant_class_from_value(cls[x]) == PlantClass::Weed;
            }
        }
        for (const std::uint32_t c : cells.vegetated()) {
            const int labelled = cell_crop[c] + cell_weed[c];
            fs_out.cells.push_back(
                {cells.row(c),
                 labelled == 0 ? 0 : to_value(cell_crop[c] >= cell_weed[c] ? PlantClass::Crop : PlantClass::Weed),
                 c, cells.plant(c), cell_crop[c], cell_weed[c]});
        }
        fs_out.grid = cells.grid();
        out.push_back(std::move(fs_out));
    }
    return true;
}

// The fold of item i of n: interleaved puts item i in fold i mod folds;
// blocks cuts the items, in their order, into `folds` runs of consecutive
// ones (sizes differing by at most one), so that a frame's neighbours (the
// same light, the same patch of field) are not among its model's training
// frames.
int fold_of(std::size_t i, std::size_t n, int folds, bool blocks)
{
    const auto k = static_cast<std::size_t>(folds);
    return static_cast<int>(blocks ? i * k / std::max<std::size_t>(n, 1) : i % k);
}

// Every vegetated cell of every frame as one CSV line, for analysis
// outside stemd (the rows the forests train on, with their pixel counts).
bool write_cells_csv(const std::string& path, const std::vector<FrameSamples>& frames, int folds, bool blocks,
                     std::string& error)
{
    std::ofstream out(path);
    if (!out) {
        error = path + ": cannot write (" + std::strerror(errno) + ")";
        return false;
    }
    out << "frame,image,fold,cell,gx,gy,plant,crop_px,weed_px";
    for (int f = 0; f < vision::kCellFeatureCount; ++f)
        out << ',' << vision::cell_feature_name(f);
    out << '\n' << std::setprecision(9);
    for (std::size_t i = 0; i < frames.size(); ++i) {
        const FrameSamples& frame = frames[i];
        const auto width = static_cast<std::uint32_t>(std::max(frame.grid.width, 1));
        for (const CellSample& c : frame.cells) {
            out << i << ',' << frame.name << ',' << fold_of(i, frames.size(), folds, blocks) << ',' << c.cell << ','
                << c.cell % width << ',' << c.cell / width << ',' << c.plant << ',' << c.crop_px << ',' << c.weed_px;
            for (const float v : c.row)
                out << ',' << v;
            out << '\n';
        }
    }
    out.flush();
    if (!out) {
        error = path + ": write failed (" + std::strerror(errno) + ")";
        return false;
    }
    return true;
}

void plant_matrices(const std::vector<FrameSamples>& frames, const std::vector<std::size_t>& which, cv::Mat& samples,
                    cv::Mat& labels)
{
    int rows = 0;
    for (const std::size_t f : which)
        rows += static_cast<int>(frames[f].plants.size());
    samples.create(rows, vision::kPlantFeatureCount, CV_32FC1);
    labels.create(rows, 1, CV_32SC1);
    int r = 0;
    for (const std::size_t f : which)
        for (const Sample& s : frames[f].plants) {
            std::copy(s.features.begin(), s.features.end(), samples.ptr<float>(r));
            labels.at<int>(r) = s.label;
            ++r;
        }
}

// The labelled cells of the frames `which` as training rows of `columns`
// (`write_row(frame, cell in the frame, destination)` fills one); at most
// `limit` of them, taken at an even stride so that every frame keeps its
// share (deterministic). With `weights`, each row's weight: its labelled
// vegetation pixels.
template <class WriteRow>
void cell_matrices(const std::vector<FrameSamples>& frames, const std::vector<std::size_t>& which, int limit,
                   int columns, WriteRow write_row, cv::Mat& samples, cv::Mat& labels, cv::Mat* weights)
{
    long total = 0;
    for (const std::size_t f : which)
        for (const CellSample& s : frames[f].cells)
            total += s.label != 0;
    const double stride = std::max(1.0, static_cast<double>(total) / std::max(limit, 1));
    const int rows = static_cast<int>(static_cast<double>(total) / stride);
    samples.create(rows, columns, CV_32FC1);
    labels.create(rows, 1, CV_32SC1);
    if (weights)
        weights->create(rows, 1, CV_32FC1);
    long k = 0;
    int r = 0;
    double next = 0;
    for (const std::size_t f : which)
        for (std::size_t c = 0; c < frames[f].cells.size(); ++c) {
            const CellSample& s = frames[f].cells[c];
            if (s.label == 0)
                continue;
            if (static_cast<double>(k++) >= next && r < rows) {
                write_row(f, c, samples.ptr<float>(r));
                labels.at<int>(r) = s.label;
                if (weights)
                    weights->at<float>(r) = static_cast<float>(s.labelled_px());
                ++r;
                next += stride;
            }
        }
    if (r < rows) {
        samples = samples.rowRange(0, r).clone();
        labels = labels.rowRange(0, r).clone();
        if (weights)
            *weights = weights->rowRange(0, r).clone();
    }
}

// How a weed probability becomes a class (classify.*).
struct Decision {
    double min_confidence;
    double weed_confidence;
};

// Where a plant's class comes from.
enum class PlantSource { forest, cells, stem };
constexpr const char* kSourceNames[] = {"the plant forest", "the share of its cells",
                                        "the class map around its stem (9x9 window)"};

// The class map's weed bars stemd-train tries, out of fold.
constexpr double kMapBars[] = {0.30, 0.35, 0.40, 0.45, 0.50, 0.55, 0.60, 0.65, 0.70};
constexpr int kMapBarCount = static_cast<int>(std::size(kMapBars));

// Figures over held-out frames, for one decision.
struct Figures {
    long plants[3][3][3] = {};   // [source][truth crop/weed][said unknown/crop/weed]
    long px_crop_total = 0, px_weed_total = 0;
    long px_crop_right = 0, px_weed_right = 0;
    long px_crop_as_weed = 0;
    long px_crop_ceiling = 0, px_weed_ceiling = 0;   // every segmented pixel right
    // Every segmented pixel its cell's true majority class: what cells of
    // this size could reach with a perfect cell classifier.
    long px_crop_cell_ceiling = 0, px_weed_cell_ceiling = 0;
    // The class map at each of kMapBars: weed at p >= bar, crop below.
    long bar_crop_right[kMapBarCount] = {}, bar_weed_right[kMapBarCount] = {};
    int frames = 0, unlabelled = 0;
    std::vector<int> cell_crop, cell_weed;

    double map_balanced_accuracy(int bar) const
    {
        return 0.5 * (static_cast<double>(bar_crop_right[bar]) / static_cast<double>(std::max(px_crop_total, 1L)) +
                      static_cast<double>(bar_weed_right[bar]) / static_cast<double>(std::max(px_weed_total, 1L)));
    }

    // Scores the frame `p` ran last: its class map from the cells, and its
    // plants by each source. `probabilities` (per plant, from the cells) out.
    void add(Pipeline& p, const vision::PlantClassifier& model, const Decision& decision, cv::Mat& map,
             std::vector<std::pair<int, float>>* out_of_fold)
    {
        ++frames;
        vision::classify_cells(model, *p.cells);
        const vision::BitMask& vegetation = p.ws->vegetation();
        const vision::CellWorkspace& cells = *p.cells;
        // The stem-window source reads a class map as a replayed class
        // column or a socket provider would give it for treating: here the
        // cells at this decision (unknown cells 0), not the class map's most
        // likely class (--class-out), which is no treat decision.
        map.create(p.class_image.size(), CV_8UC1);
        map.setTo(0);
        for (int y = 0; y < map.rows; ++y) {
            auto* row = map.ptr<std::uint8_t>(y);
            for (int x = 0; x < map.cols; ++x) {
                if (!vegetation.get(x, y))
                    continue;
                const std::size_t c = cells.cell_of(x, y);
                if (cells.cell_class(c) != PlantClass::Unknown)
                    row[x] = to_value(vision::decide_class(cells.weed_probability(c), decision.min_confidence,
                                                           decision.weed_confidence));
            }
        }
        // Each cell's true crop and weed pixels among its segmented vegetation.
        cell_crop.assign(cells.cells(), 0);
        cell_weed.assign(cells.cells(), 0);
        for (int y = 0; y < map.rows; ++y) {
            const auto* cls = p.class_image.ptr<std::uint8_t>(y);
            for (int x = 0; x < map.cols; ++x)
                if (vegetation.get(x, y)) {
                    cell_crop[cells.cell_of(x, y)] += plant_class_from_value(cls[x]) == PlantClass::Crop;
                    cell_weed[cells.cell_of(x, y)] += plant_class_from_value(cls[x]) == PlantClass::Weed;
                }
        }
        // Each human crop or weed pixel, segmented or not: its cell's class
        // at this decision (the asymmetric one leaves cells unknown), the
        // class map at each bar, and the cell-size ceiling.
        for (int y = 0; y < map.rows; ++y) {
            const auto* cls = p.class_image.ptr<std::uint8_t>(y);
            for (int x = 0; x < map.cols; ++x) {
                const PlantClass truth = plant_class_from_value(cls[x]);
                if (truth != PlantClass::Crop && truth != PlantClass::Weed)
                    continue;
                const bool crop = truth == PlantClass::Crop;
                (crop ? px_crop_total : px_weed_total) += 1;
                if (!vegetation.get(x, y))
                    continue;
                (crop ? px_crop_ceiling : px_weed_ceiling) += 1;
                const std::size_t c = cells.cell_of(x, y);
                const bool cell_says_crop = cell_crop[c] >= cell_weed[c];
                (crop ? px_crop_cell_ceiling : px_weed_cell_ceiling) += cell_says_crop == crop;
                if (cells.cell_class(c) == PlantClass::Unknown)
                    continue;   // a cell without sampled vegetation has no probability
                const float weed_p = cells.weed_probability(c);
                const PlantClass s = vision::decide_class(weed_p, decision.min_confidence, decision.weed_confidence);
                px_crop_right += crop && s == PlantClass::Crop;
                px_weed_right += !crop && s == PlantClass::Weed;
                px_crop_as_weed += crop && s == PlantClass::Weed;
                for (int b = 0; b < kMapBarCount; ++b) {
                    const bool weed = weed_p >= static_cast<float>(kMapBars[b]);
                    (crop ? bar_crop_right[b] : bar_weed_right[b]) += weed != crop;
                }
            }
        }
        std::vector<long> crop, weed;
        p.plant_truth(crop, weed);
        const std::size_t n = p.det->plants.size();
        std::array<float, vision::kMaxPlants> share{};
        vision::plant_probabilities_from_cells(*p.cells, n, share);
        std::array<PlantClass, vision::kMaxPlants> stem{};
        vision::plant_classes_from_map(map, map.size(), *p.det, stem);
        for (std::size_t i = 0; i < n; ++i) {
            if (crop[i] + weed[i] == 0) {
                ++unlabelled;
                continue;
            }
            const int label = to_value(crop[i] >= weed[i] ? PlantClass::Crop : PlantClass::Weed);
            const PlantClass said[3] = {
                vision::decide_class(model.weed_probability(p.cws->features()[i]), decision.min_confidence,
                                     decision.weed_confidence),
                share[i] < 0 ? PlantClass::Unknown
                             : vision::decide_class(share[i], decision.min_confidence, decision.weed_confidence),
                stem[i]};
            for (int s = 0; s < 3; ++s)
                ++plants[s][label][to_value(said[s])];
            if (out_of_fold && share[i] >= 0)
                out_of_fold->emplace_back(label, share[i]);
        }
    }

    std::string text(const std::string& title, const Decision& decision) const
    {
        auto ratio = [](double a, double b) { return b > 0 ? a / b : 0.0; };
        const int C = to_value(PlantClass::Crop), W = to_value(PlantClass::Weed), U = to_value(PlantClass::Unknown);
        const double px_crop_recall = ratio(px_crop_right, px_crop_total);
        const double px_weed_recall = ratio(px_weed_right, px_weed_total);
        std::string out;
        char buf[1024];
        std::snprintf(buf, sizeof buf,
                      "%s (%d frames, min_confidence %.2f, weed_confidence %.2f)\n"
                      "  pixels of vegetation (each cell's class at this decision): crop recall %.3f, weed recall "
                      "%.3f, balanced accuracy %.3f; crop pixels called weed %.1f %%\n"
                      "  (segmentation ceiling, every segmented pixel right: balanced accuracy %.3f; cell ceiling, "
                      "every segmented pixel its cell's majority class: %.3f)\n",
                      title.c_str(), frames, decision.min_confidence, decision.weed_confidence, px_crop_recall,
                      px_weed_recall, 0.5 * (px_crop_recall + px_weed_recall),
                      100 * ratio(px_crop_as_weed, px_crop_total),
                      0.5 * (ratio(px_crop_ceiling, px_crop_total) + ratio(px_weed_ceiling, px_weed_total)),
                      0.5 * (ratio(px_crop_cell_ceiling, px_crop_total) + ratio(px_weed_cell_ceiling, px_weed_total)));
        out += buf;
        for (int s = 0; s < 3; ++s) {
            const auto& m = plants[s];
            const double crop_plants = m[C][U] + m[C][C] + m[C][W];
            const double weed_plants = m[W][U] + m[W][C] + m[W][W];
            std::snprintf(
                buf, sizeof buf,
                "  plants by %s: %.0f crop, %.0f weed (%d more found on soil, not scored)\n"
                "    crop: precision %.3f recall %.3f | weed: precision %.3f recall %.3f | unknown: %ld crop, %ld "
                "weed\n"
                "    crop safety: %ld of %.0f crop plants called weed (%.1f %%)\n",
                kSourceNames[s], crop_plants, weed_plants, unlabelled, ratio(m[C][C], m[C][C] + m[W][C]),
                ratio(m[C][C], crop_plants), ratio(m[W][W], m[W][W] + m[C][W]), ratio(m[W][W], weed_plants), m[C][U],
                m[W][U], m[C][W], crop_plants, 100 * ratio(m[C][W], crop_plants));
            out += buf;
        }
        return out;
    }
};

std::string utc_now()
{
    const std::time_t now = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&now, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return buf;
}

}  // namespace

int main(int argc, char** argv)
{
    CLI::App app{"stemd-train: trains the crop/weed classifier from recordings with a class column "
                 "(0 soil, 1 crop, 2 weed), prints cross-validated figures split by frame, writes MODEL."};
    std::string out_path;
    config::ConfigArgs config_args;
    std::vector<std::string> test_sets;
    std::vector<std::string> test_recordings;
    std::vector<std::string> recordings;
    int folds = 5;
    std::string split = "interleaved";
    vision::ForestOptions forest;
    vision::ForestOptions cell_forest = vision::kDefaultCellForest;
    double cell_mm = vision::kDefaultCellMm;
    int cell_samples = 40000;
    std::string cell_weights = "cells";
    std::string cell_context = "yes";
    std::string cells_csv;
    int threads = static_cast<int>(std::clamp(std::thread::hardware_concurrency(), 1u, 256u));
    app.add_option("--out", out_path, "model file to write (.yaml or .json)")->required();
    tools::add_config_options(app, config_args);
    app.add_option("--folds", folds, "cross-validation folds")->check(CLI::Range(2, 100));
    app.add_option("--split", split,
                   "how frames fall into folds: interleaved (frame i in fold i mod N, the default) or blocks (runs "
                   "of consecutive frames, so a frame's neighbours are never in its model's training frames; also "
                   "the context stage's inner folds)")
        ->check(CLI::IsMember({"interleaved", "blocks"}));
    app.add_option("--trees", forest.trees, "trees in the plant forest")->check(CLI::Range(1, 1000));
    app.add_option("--max-depth", forest.max_depth, "depth limit of each plant tree")->check(CLI::Range(1, 50));
    app.add_option("--cell-mm", cell_mm, "side of the classified cells, in mm")->check(CLI::Range(0.5, 50.0));
    app.add_option("--cell-trees", cell_forest.trees, "trees in the cell forest")->check(CLI::Range(1, 1000));
    app.add_option("--cell-max-depth", cell_forest.max_depth, "depth limit of each cell tree")
        ->check(CLI::Range(1, 50));
    app.add_option("--cell-samples", cell_samples, "at most this many cells train a cell forest (an even stride)")
        ->check(CLI::Range(100, 10000000));
    app.add_option("--cell-weights", cell_weights,
                   "what weighs a training cell: cells (each 1) or pixels (its labelled vegetation pixels); the "
                   "classes are balanced either way")
        ->check(CLI::IsMember({"cells", "pixels"}));
    app.add_option("--cell-context", cell_context,
                   "yes: a second cell forest reads each cell's row and the first forest's probabilities around it "
                   "(its squares, band, plant and frame); no: the first forest decides")
        ->check(CLI::IsMember({"yes", "no"}));
    app.add_option("--seed", forest.seed, "seed of the forests' random draws");
    app.add_option("--jobs", threads,
                   "threads that train the folds' models and the final one (default: the CPU count); the models and "
                   "figures do not depend on it")
        ->check(CLI::Range(1, 256));
    app.add_option("--cells-csv", cells_csv,
                   "also write every vegetated cell's row as CSV (frame, image, fold, cell, gx, gy, plant, crop_px, "
                   "weed_px, then the cell features by name)");
    app.add_option("--test-on", test_recordings,
                   "also score the final model on this recording (another camera or field)")
        ->allow_extra_args(false);
    app.add_option("--test-set", test_sets, "a configuration override for the --test-on recordings only")
        ->allow_extra_args(false);
    app.add_option("RECORDING", recordings, "recording directories with a class column")->required();
    if (const auto exit_code = tools::parse(app, argc, argv, {.tool = "stemd-train", .after = " (see --help)"}))
        return *exit_code;
    cell_forest.seed = forest.seed;
    const bool blocks = split == "blocks";

    std::string error;
    Pipeline pipeline;
    pipeline.cell_mm = cell_mm;
    std::vector<tools::FrameJob> jobs;
    std::vector<FrameSamples> frames;
    if (!load_params(config_args, pipeline.params, error) || !frame_jobs(recordings, pipeline.params, jobs, error) ||
        !collect(jobs, pipeline, frames, error)) {
        std::cerr << "stemd-train: " << error << "\n";
        return kUsageError;
    }
    const vision::Params params = pipeline.params;
    config::Config config;
    (void)config::build_config(config_args, config);   // checked by load_params()
    const Decision decision{config.settings().daemon.classify.min_confidence,
                            config.settings().daemon.classify.weed_confidence};
    const Decision symmetric{0.5, 0.5};
    if (static_cast<int>(frames.size()) < folds) {
        std::cerr << "stemd-train: " << frames.size() << " frames, fewer than " << folds << " folds\n";
        return kUsageError;
    }
    if (!cells_csv.empty() && !write_cells_csv(cells_csv, frames, folds, blocks, error)) {
        std::cerr << "stemd-train: --cells-csv " << error << "\n";
        return 1;
    }

    auto own_row = [&](std::size_t f, std::size_t c, float* out) {
        const vision::CellRow& row = frames[f].cells[c].row;
        std::copy(row.begin(), row.end(), out);
    };
    // Only the final model's importance is printed: the folds' forests skip
    // computing it (see ForestOptions::var_importance).
    auto forest_options = [&](bool importance) {
        vision::ForestOptions options = cell_forest;
        options.var_importance = importance;
        return options;
    };
    auto train_cell_forest = [&](const std::vector<std::size_t>& which, vision::PlantClassifier& model,
                                 bool importance, std::string& why) {
        cv::Mat samples, labels, weights;
        cell_matrices(frames, which, cell_samples, vision::kCellFeatureCount, own_row, samples, labels,
                      cell_weights == "pixels" ? &weights : nullptr);
        if (model.train_cells(samples, labels, forest_options(importance), cell_mm, why, weights))
            return true;
        why = "cells: " + why;
        return false;
    };
    // The context stage learns from first-stage probabilities as a forest
    // that never saw the frame gives them (the frame path's case): each of
    // `which` gets them from a cell forest trained on the other inner folds.
    auto train_context = [&](const std::vector<std::size_t>& which, vision::PlantClassifier& model,
                             bool importance, std::string& why) {
        const std::size_t inner = std::min<std::size_t>(kContextInnerFolds, which.size());
        std::vector<std::vector<float>> first(frames.size());
        for (std::size_t k = 0; k < inner; ++k) {
            std::vector<std::size_t> fit, held_out;
            for (std::size_t i = 0; i < which.size(); ++i)
                (static_cast<std::size_t>(fold_of(i, which.size(), static_cast<int>(inner), blocks)) == k
                     ? held_out
                     : fit)
                    .push_back(which[i]);
            vision::PlantClassifier stage;
            if (!train_cell_forest(fit, stage, false, why)) {
                why = "context, inner fold " + std::to_string(k) + ": " + why;
                return false;
            }
            for (const std::size_t f : held_out)
                for (const CellSample& c : frames[f].cells)
                    first[f].push_back(stage.cell_weed_probability(c.row));
        }
        std::vector<std::vector<vision::CellContext>> context(frames.size());
        for (const std::size_t f : which) {
            const FrameSamples& frame = frames[f];
            const std::size_t n = frame.cells.size();
            std::vector<std::uint32_t> cells(n);
            std::vector<float> weight(n);
            std::vector<std::uint16_t> plant(n);
            for (std::size_t c = 0; c < n; ++c) {
                cells[c] = frame.cells[c].cell;
                weight[c] = frame.cells[c].row[vision::c_fill];
                plant[c] = frame.cells[c].plant;
            }
            vision::CellContextScratch scratch(frame.grid);
            context[f].resize(n);
            vision::cell_context({.grid = frame.grid, .cell_mm = cell_mm, .cells = cells, .weight = weight,
                                  .plant = plant, .probability = first[f]},
                                 scratch, context[f]);
        }
        cv::Mat samples, labels, weights;
        cell_matrices(
            frames, which, cell_samples, vision::kContextFeatureCount,
            [&](std::size_t f, std::size_t c, float* out) {
                own_row(f, c, out);
                std::copy(context[f][c].begin(), context[f][c].end(), out + vision::kCellFeatureCount);
            },
            samples, labels, cell_weights == "pixels" ? &weights : nullptr);
        if (model.train_context(samples, labels, forest_options(importance), why, weights))
            return true;
        why = "context: " + why;
        return false;
    };
    auto train = [&](const std::vector<std::size_t>& which, bool importance,
                     std::string& why) -> std::optional<vision::PlantClassifier> {
        cv::Mat samples, labels;
        plant_matrices(frames, which, samples, labels);
        auto model = vision::PlantClassifier::train(samples, labels, forest, why);
        if (!model || !train_cell_forest(which, *model, importance, why))
            return std::nullopt;
        if (cell_context == "yes" && !train_context(which, *model, importance, why))
            return std::nullopt;
        return model;
    };

    // Cross-validation by frame: every plant and cell of a frame is in the
    // same fold, so none is scored by a forest that saw its own frame.
    // Model k < folds is fold k's; model `folds` is the final one, on every
    // frame. They are independent, so `threads` threads train them. Each
    // forest seeds its own thread's cv::theRNG() (train_forest), so no
    // model depends on the thread count or the order.
    const auto in_fold = [&](std::size_t f, int k) { return fold_of(f, frames.size(), folds, blocks) == k; };
    const int model_count = folds + 1;
    std::vector<std::optional<vision::PlantClassifier>> models(static_cast<std::size_t>(model_count));
    std::vector<std::string> model_errors(static_cast<std::size_t>(model_count));
    std::atomic<int> next_model{0};
    const auto train_models = [&] {
        for (int k = next_model.fetch_add(1); k < model_count; k = next_model.fetch_add(1)) {
            const auto i = static_cast<std::size_t>(k);
            std::vector<std::size_t> which;
            for (std::size_t f = 0; f < frames.size(); ++f)
                if (k == folds || !in_fold(f, k))
                    which.push_back(f);
            try {
                models[i] = train(which, k == folds, model_errors[i]);
            } catch (const std::exception& e) {   // out of memory, or OpenCV outside train_forest's guard
                model_errors[i] = e.what();
                models[i].reset();
            }
        }
    };
    {
        std::vector<std::thread> helpers;
        for (int t = 1; t < std::min(threads, model_count); ++t) {
            try {
                helpers.emplace_back(train_models);
            } catch (const std::system_error&) {
                break;   // no more threads (a process limit): the ones running take the rest
            }
        }
        train_models();
        for (std::thread& t : helpers)
            t.join();
    }
    Figures cv_figures, cv_figures_half;
    std::vector<std::pair<int, float>> out_of_fold;   // (label, weed probability from the cells)
    cv::Mat map;
    for (int k = 0; k < folds; ++k) {
        const auto& model = models[static_cast<std::size_t>(k)];
        if (!model) {
            std::cerr << "stemd-train: fold " << k << ": " << model_errors[static_cast<std::size_t>(k)] << "\n";
            return 1;
        }
        for (std::size_t f = 0; f < frames.size(); ++f) {
            if (!in_fold(f, k))
                continue;
            if (!pipeline.run(jobs[frames[f].job], error)) {
                std::cerr << "stemd-train: " << error << "\n";
                return 1;
            }
            cv_figures_half.add(pipeline, *model, symmetric, map, nullptr);
            cv_figures.add(pipeline, *model, decision, map, &out_of_fold);
        }
    }
    std::ostringstream sweep;
    {
        // What each weed bar would give, out of fold: the trade-off between
        // crop safety and weeds treated that classify.weed_confidence picks.
        sweep << "  weed bar (out of fold, plants by the share of their cells): crop plants called weed / weed "
                 "recall:";
        for (int bar = 50; bar <= 95; bar += 5) {
            long crops = 0, crop_weed = 0, weeds = 0, weed_weed = 0;
            for (const auto& [label, p] : out_of_fold) {
                const bool weed = p >= bar / 100.0f;
                (label == to_value(PlantClass::Crop) ? crops : weeds) += 1;
                (label == to_value(PlantClass::Crop) ? crop_weed : weed_weed) += weed;
            }
            char text[96];
            std::snprintf(text, sizeof text, "%s %.2f: %.1f %% / %.3f", bar % 25 == 0 ? "\n   " : ";", bar / 100.0,
                          100.0 * static_cast<double>(crop_weed) / static_cast<double>(std::max(crops, 1L)),
                          static_cast<double>(weed_weed) / static_cast<double>(std::max(weeds, 1L)));
            sweep << text;
        }
        sweep << "\n";
    }
    // The class map's bar: the most likely class, fitted on the out-of-fold
    // per-pixel balanced accuracy (ties to the bar nearest 0.5).
    int map_bar = 0;
    for (int b = 0; b < kMapBarCount; ++b) {
        const double a = cv_figures_half.map_balanced_accuracy(b), best = cv_figures_half.map_balanced_accuracy(map_bar);
        if (a > best || (a == best && std::abs(kMapBars[b] - 0.5) < std::abs(kMapBars[map_bar] - 0.5)))
            map_bar = b;
    }
    {
        sweep << "  class map bar (out of fold, per pixel of vegetation: weed at p >= bar): balanced accuracy";
        for (int b = 0; b < kMapBarCount; ++b) {
            char text[48];
            std::snprintf(text, sizeof text, "%s %.2f: %.3f", b ? ";" : "", kMapBars[b],
                          cv_figures_half.map_balanced_accuracy(b));
            sweep << text;
        }
        char text[160];
        std::snprintf(text, sizeof text, "\n  class map bar fitted: %.2f (balanced accuracy %.3f out of fold, tuned on "
                                         "these frames)\n",
                      kMapBars[map_bar], cv_figures_half.map_balanced_accuracy(map_bar));
        sweep << text;
    }
    // The default's title is the one earlier models carry.
    const std::string cv_title = std::to_string(folds) + "-fold cross-validation by frame" +
                                 (blocks ? " (folds of consecutive frames)" : "");
    std::ostringstream report;
    char cells_line[200];
    std::snprintf(cells_line, sizeof cells_line,
                  "cells of %.2f mm (%d px), cell forest %d trees of depth %d%s, training cells weighed by %s\n",
                  cell_mm, pipeline.cells ? pipeline.cells->cell_px() : 0, cell_forest.trees, cell_forest.max_depth,
                  cell_context == "yes" ? " and a context forest as large" : "",
                  cell_weights == "pixels" ? "their vegetation pixels" : "one each");
    report << cells_line
           << cv_figures_half.text(cv_title, symmetric) << cv_figures.text(cv_title, decision) << sweep.str();

    auto& model = models[static_cast<std::size_t>(folds)];
    if (!model) {
        std::cerr << "stemd-train: " << model_errors[static_cast<std::size_t>(folds)] << "\n";
        return 1;
    }
    model->set_map_weed_bar(kMapBars[map_bar]);
    std::cout << report.str();
    // Which features carry each forest (OpenCV's permutation importance).
    auto print_importance = [](const char* title, const cv::Mat& importance, std::string_view (*name)(int)) {
        std::vector<std::pair<float, int>> ranked;
        for (int f = 0; f < importance.cols * importance.rows; ++f)
            ranked.emplace_back(importance.at<float>(f), f);
        std::sort(ranked.rbegin(), ranked.rend());
        std::cout << title << ":";
        for (std::size_t i = 0; i < ranked.size() && i < 12; ++i)
            std::cout << (i ? ", " : " ") << name(ranked[i].second) << " " << std::setprecision(3) << ranked[i].first;
        std::cout << "\n";
    };
    print_importance("cell feature importance", model->cell_importance(), vision::cell_feature_name);
    if (model->has_context())
        print_importance("context forest feature importance", model->context_importance(),
                         vision::context_feature_name);

    if (!test_recordings.empty()) {
        config::ConfigArgs test_args = config_args;
        test_args.sets.insert(test_args.sets.end(), test_sets.begin(), test_sets.end());
        Pipeline test_pipeline;
        test_pipeline.cell_mm = cell_mm;
        std::vector<tools::FrameJob> test_jobs;
        if (!load_params(test_args, test_pipeline.params, error) ||
            !frame_jobs(test_recordings, test_pipeline.params, test_jobs, error)) {
            std::cerr << "stemd-train: --test-on: " << error << "\n";
            return kUsageError;
        }
        Figures test_figures;
        for (const tools::FrameJob& job : test_jobs) {
            if (!test_pipeline.run(job, error)) {
                std::cerr << "stemd-train: --test-on: " << error << "\n";
                return kUsageError;
            }
            test_figures.add(test_pipeline, *model, decision, map, nullptr);
        }
        std::cout << test_figures.text("the model (all training frames) on --test-on", decision);
    }

    vision::ModelInfo info;
    info.gsd_mm_per_px = params.gsd_mm_per_px;
    info.nir = vision::uses_nir(params.segmentation);
    info.segmentation = std::string(vision::to_string(params.segmentation));
    for (const std::string& r : recordings)
        info.recordings.push_back(fs::absolute(r).lexically_normal().string());
    info.trained_utc = utc_now();
    info.cross_validation = report.str();
    if (!model->save(out_path, info, error)) {
        std::cerr << "stemd-train: " << error << "\n";
        return 1;
    }
    long plants = 0, cells = 0;
    for (const FrameSamples& f : frames) {
        plants += static_cast<long>(f.plants.size());
        for (const CellSample& c : f.cells)
            cells += c.label != 0;
    }
    std::cout << out_path << ": " << plants << " plants and " << cells << " labelled cells from " << frames.size()
              << " frames, " << model->info().trees << " plant trees, " << model->info().cell_trees
              << " cell trees, " << model->info().context_trees << " context trees, " << vision::channels_name(info.nir) << ", camera.gsd_mm_per_px "
              << info.gsd_mm_per_px << "\n";
    return 0;
}
