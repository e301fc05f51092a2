// stemd-train: trains the crop/weed classifier (vision/classify) from
// recordings with a class column, prints cross-validated figures split by
// frame, and writes one model file.
//   stemd-train --out MODEL [--config FILE] [--set K=V]... [--folds N]
//               [--trees N] [--seed N] [--test-on RECORDING]...
//               [--test-set K=V]... RECORDING...
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "stemd/config/command_line.hpp"
#include "stemd/config/config.hpp"
#include "stemd/io/recording.hpp"
#include "stemd/vision/classify.hpp"
#include "stemd/vision/detect.hpp"
#include "tool_cli.hpp"
#include "tool_frames.hpp"

namespace fs = std::filesystem;
using namespace stemd;

namespace {

using tools::kUsageError;

// One plant of one frame: its features, the class the human class image
// gives it (by majority of its vegetation pixels), and those pixels' counts.
struct Sample {
    vision::FeatureRow features;
    int label = 0;          // 1 crop, 2 weed
    long crop_px = 0;       // the plant's vegetation pixels the class image calls crop
    long weed_px = 0;
};

struct FrameSamples {
    std::string name;
    std::vector<Sample> plants;
    long gt_crop_px = 0;    // every crop and weed pixel of the class image
    long gt_weed_px = 0;
    int unlabelled = 0;     // plants with no crop or weed pixel under them (soil found as vegetation)
};

// Runs the pipeline and the features on every frame that has a class image.
bool collect(const std::vector<std::string>& recordings, const config::ConfigArgs& config_args,
             std::vector<FrameSamples>& out, vision::Params& params_out, std::string& error)
{
    config::Config config;
    if (const auto config_error = config::build_config(config_args, config)) {
        error = config_error->to_string();
        return false;
    }
    const vision::Params params = config.settings().daemon.vision;
    params_out = params;
    for (const std::string& r : recordings) {
        if (!io::is_recording_dir(r)) {
            error = r + ": not a recording directory (frames.csv with a class column)";
            return false;
        }
    }
    std::vector<tools::FrameJob> jobs;
    if (!tools::collect_frames(recordings, params.segmentation, jobs, error))
        return false;
    std::unique_ptr<vision::Workspace> ws;
    std::unique_ptr<vision::ClassifyWorkspace> cws;
    auto det = std::make_unique<vision::Detections>();
    tools::LoadedFrame frame;
    cv::Mat class_image;
    for (const tools::FrameJob& job : jobs) {
        if (job.plant_class.empty()) {
            std::cerr << "stemd-train: " << job.image << ": no class image, skipped\n";
            continue;
        }
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
        }
        const vision::FrameView view{.bgr = frame.bgr, .nir = frame.nir, .mask = frame.mask};
        vision::detect(view, params, *ws, *det);
        if (det->status != vision::DetectStatus::ok) {
            error = job.image + ": " + std::string(vision::to_string(det->status));
            return false;
        }
        vision::plant_features(view, params, *ws, *det, *cws);

        FrameSamples fs_out;
        fs_out.name = job.image;
        std::vector<long> crop(det->plants.size(), 0), weed(det->plants.size(), 0);
        const vision::BitMask& vegetation = ws->vegetation();
        for (int y = 0; y < size.height; ++y) {
            const auto* cls = class_image.ptr<std::uint8_t>(y);
            const auto* index = cws->plant_index().ptr<std::uint16_t>(y);
            for (int x = 0; x < size.width; ++x) {
                const PlantClass c = plant_class_from_value(cls[x]);
                fs_out.gt_crop_px += c == PlantClass::Crop;
                fs_out.gt_weed_px += c == PlantClass::Weed;
                if (index[x] == 0 || !vegetation.get(x, y))
                    continue;
                crop[index[x] - 1u] += c == PlantClass::Crop;
                weed[index[x] - 1u] += c == PlantClass::Weed;
            }
        }
        for (std::size_t i = 0; i < det->plants.size(); ++i) {
            if (crop[i] + weed[i] == 0) {
                ++fs_out.unlabelled;
                continue;
            }
            Sample s;
            s.features = cws->features()[i];
            s.label = to_value(crop[i] >= weed[i] ? PlantClass::Crop : PlantClass::Weed);
            s.crop_px = crop[i];
            s.weed_px = weed[i];
            fs_out.plants.push_back(s);
        }
        out.push_back(std::move(fs_out));
    }
    if (out.empty()) {
        error = "no frame with a class image";
        return false;
    }
    return true;
}

void to_matrices(const std::vector<FrameSamples>& frames, const std::vector<std::size_t>& which, cv::Mat& samples,
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

// How a weed probability becomes a class (classify.*).
struct Decision {
    double min_confidence;
    double weed_confidence;
};

// Figures over held-out frames.
struct Figures {
    long plants[3][3] = {};   // [truth crop/weed][said unknown/crop/weed]
    long px_crop_total = 0, px_weed_total = 0;
    long px_crop_right = 0, px_weed_right = 0;
    long px_crop_as_weed = 0;
    long px_crop_ceiling = 0, px_weed_ceiling = 0;   // every plant given its majority class
    int frames = 0, unlabelled = 0;

    void add(const FrameSamples& frame, const vision::PlantClassifier& model, const Decision& decision)
    {
        ++frames;
        unlabelled += frame.unlabelled;
        px_crop_total += frame.gt_crop_px;
        px_weed_total += frame.gt_weed_px;
        for (const Sample& s : frame.plants) {
            (s.label == to_value(PlantClass::Crop) ? px_crop_ceiling : px_weed_ceiling) +=
                s.label == to_value(PlantClass::Crop) ? s.crop_px : s.weed_px;
            const PlantClass said = vision::decide_class(model.weed_probability(s.features), decision.min_confidence,
                                                         decision.weed_confidence);
            ++plants[s.label][to_value(said)];
            if (said == PlantClass::Crop)
                px_crop_right += s.crop_px;
            if (said == PlantClass::Weed) {
                px_weed_right += s.weed_px;
                px_crop_as_weed += s.crop_px;
            }
        }
    }

    std::string text(const std::string& title, const Decision& decision) const
    {
        auto ratio = [](double a, double b) { return b > 0 ? a / b : 0.0; };
        const int C = to_value(PlantClass::Crop), W = to_value(PlantClass::Weed), U = to_value(PlantClass::Unknown);
        const double crop_plants = plants[C][U] + plants[C][C] + plants[C][W];
        const double weed_plants = plants[W][U] + plants[W][C] + plants[W][W];
        const double crop_recall = ratio(plants[C][C], crop_plants);
        const double weed_recall = ratio(plants[W][W], weed_plants);
        const double crop_precision = ratio(plants[C][C], plants[C][C] + plants[W][C]);
        const double weed_precision = ratio(plants[W][W], plants[W][W] + plants[C][W]);
        const double px_crop_recall = ratio(px_crop_right, px_crop_total);
        const double px_weed_recall = ratio(px_weed_right, px_weed_total);
        char buf[1024];
        std::snprintf(
            buf, sizeof buf,
            "%s (%d frames, min_confidence %.2f, weed_confidence %.2f)\n"
            "  plants: %.0f crop, %.0f weed (%d more found on soil, not scored)\n"
            "  crop: precision %.3f recall %.3f | weed: precision %.3f recall %.3f | unknown: %ld crop, %ld weed\n"
            "  crop safety: %ld of %.0f crop plants called weed (%.1f %%)\n"
            "  pixels of vegetation: crop recall %.3f, weed recall %.3f, balanced accuracy %.3f; crop pixels called "
            "weed %.1f %%\n"
            "  (per-plant ceiling, every plant right: balanced accuracy %.3f; the rest is plants of both classes "
            "merged into one, and vegetation the segmentation missed)\n",
            title.c_str(), frames, decision.min_confidence, decision.weed_confidence, crop_plants, weed_plants, unlabelled, crop_precision, crop_recall,
            weed_precision, weed_recall, plants[C][U], plants[W][U], plants[C][W], crop_plants,
            100 * ratio(plants[C][W], crop_plants), px_crop_recall, px_weed_recall,
            0.5 * (px_crop_recall + px_weed_recall), 100 * ratio(px_crop_as_weed, px_crop_total),
            0.5 * (ratio(px_crop_ceiling, px_crop_total) + ratio(px_weed_ceiling, px_weed_total)));
        return buf;
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
    vision::ForestOptions forest;
    app.add_option("--out", out_path, "model file to write (.yaml or .json)")->required();
    tools::add_config_options(app, config_args);
    app.add_option("--folds", folds, "cross-validation folds; frame i is in fold i mod N")
        ->check(CLI::Range(2, 100));
    app.add_option("--trees", forest.trees, "trees in the forest")->check(CLI::Range(1, 1000));
    app.add_option("--max-depth", forest.max_depth, "depth limit of each tree")->check(CLI::Range(1, 50));
    app.add_option("--seed", forest.seed, "seed of the forest's random draws");
    app.add_option("--test-on", test_recordings,
                   "also score the final model on this recording (another camera or field)")
        ->allow_extra_args(false);
    app.add_option("--test-set", test_sets, "a configuration override for the --test-on recordings only")
        ->allow_extra_args(false);
    app.add_option("RECORDING", recordings, "recording directories with a class column")->required();
    if (const auto exit_code = tools::parse(app, argc, argv, {.tool = "stemd-train", .after = " (see --help)"}))
        return *exit_code;

    std::vector<FrameSamples> frames;
    vision::Params params;
    std::string error;
    if (!collect(recordings, config_args, frames, params, error)) {
        std::cerr << "stemd-train: " << error << "\n";
        return kUsageError;
    }
    config::Config config;
    (void)config::build_config(config_args, config);   // checked by collect()
    const Decision decision{config.settings().daemon.classify.min_confidence,
                            config.settings().daemon.classify.weed_confidence};
    const Decision symmetric{0.5, 0.5};
    if (static_cast<int>(frames.size()) < folds) {
        std::cerr << "stemd-train: " << frames.size() << " frames, fewer than " << folds << " folds\n";
        return kUsageError;
    }

    // Cross-validation by frame: every plant of a frame is in the same fold,
    // so no plant is scored by a forest that saw its own frame.
    Figures cv_figures, cv_figures_half;
    std::vector<std::pair<int, float>> out_of_fold;   // (label, weed probability)
    for (int k = 0; k < folds; ++k) {
        std::vector<std::size_t> train, test;
        for (std::size_t f = 0; f < frames.size(); ++f)
            (static_cast<int>(f % static_cast<std::size_t>(folds)) == k ? test : train).push_back(f);
        cv::Mat samples, labels;
        to_matrices(frames, train, samples, labels);
        const auto model = vision::PlantClassifier::train(samples, labels, forest, error);
        if (!model) {
            std::cerr << "stemd-train: fold " << k << ": " << error << "\n";
            return 1;
        }
        for (const std::size_t f : test) {
            cv_figures.add(frames[f], *model, decision);
            cv_figures_half.add(frames[f], *model, symmetric);
            for (const Sample& s : frames[f].plants)
                out_of_fold.emplace_back(s.label, model->weed_probability(s.features));
        }
    }
    std::ostringstream sweep;
    {
        // What each weed bar would give, out of fold: the trade-off between
        // crop safety and weeds treated that classify.weed_confidence picks.
        sweep << "  weed bar (out of fold): crop plants called weed / weed recall:";
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
    std::ostringstream report;
    report << cv_figures_half.text(std::to_string(folds) + "-fold cross-validation by frame", symmetric)
           << cv_figures.text(std::to_string(folds) + "-fold cross-validation by frame", decision) << sweep.str();

    std::vector<std::size_t> all(frames.size());
    for (std::size_t f = 0; f < frames.size(); ++f)
        all[f] = f;
    cv::Mat samples, labels;
    to_matrices(frames, all, samples, labels);
    const auto model = vision::PlantClassifier::train(samples, labels, forest, error);
    if (!model) {
        std::cerr << "stemd-train: " << error << "\n";
        return 1;
    }
    std::cout << report.str();

    if (!test_recordings.empty()) {
        config::ConfigArgs test_args = config_args;
        test_args.sets.insert(test_args.sets.end(), test_sets.begin(), test_sets.end());
        std::vector<FrameSamples> test_frames;
        vision::Params test_params;
        if (!collect(test_recordings, test_args, test_frames, test_params, error)) {
            std::cerr << "stemd-train: --test-on: " << error << "\n";
            return kUsageError;
        }
        Figures test_figures;
        for (const FrameSamples& f : test_frames)
            test_figures.add(f, *model, decision);
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
    std::cout << out_path << ": " << samples.rows << " plants from " << frames.size() << " frames, "
              << model->info().trees << " trees, " << vision::channels_name(info.nir) << ", camera.gsd_mm_per_px "
              << info.gsd_mm_per_px << "\n";
    return 0;
}
