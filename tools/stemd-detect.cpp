// stemd-detect: offline stem detection on images or recording directories.
//   stemd-detect [--config FILE] [--set KEY=VALUE]... [--segment METHOD]
//                [--csv OUT] [--mask-out DIR] [--class-out DIR] [--overlay DIR] [--timing] INPUT...
#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <ctime>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "stemd/base/clock.hpp"
#include "stemd/io/csv.hpp"
#include "stemd/io/recording.hpp"
#include "stemd/config/config.hpp"
#include "stemd/runtime/daemon_config.hpp"
#include "stemd/vision/cells.hpp"
#include "stemd/vision/classify.hpp"
#include "stemd/vision/detect.hpp"
#include "stemd/viz/overlay.hpp"
#include "tool_cli.hpp"
#include "tool_frames.hpp"

namespace fs = std::filesystem;
using namespace stemd;

namespace {

using tools::kUsageError;

const char* const kUsage =
    "usage: stemd-detect [--config FILE] [--set KEY=VALUE]... [--segment METHOD]\n"
    "                    [--csv OUT] [--mask-out DIR] [--class-out DIR] [--overlay DIR] [--timing]\n"
    "                    INPUT...\n"
    "  INPUT       image files (RGB; masks with --segment mask, nonzero = vegetation)\n"
    "              or recording directories (frames.csv: t_ns,rgb,nir,mask)\n"
    "  --config    configuration file (see config/stemd.yaml)\n"
    "  --set       override one configuration key, e.g. --set closing.radius_px=6\n"
    "  --segment   shorthand for --set segment.method=METHOD: auto (the default:\n"
    "              exg_and_ndvi when every frame has a nir plane, else chromatic_exg),\n"
    "              chromatic_exg, exg, ndvi, exg_and_ndvi (recordings with nir), mask\n"
    "  --csv       write image,plant,x,y,method,leaves,area_px,estimator,confidence\n"
    "              ('-' = stdout); plants without a stem (grass) are not written;\n"
    "              with classify.model, then class (crop|weed|unknown),weed_probability,\n"
    "              and the weed parts of other plants (classify.weed_parts) after them\n"
    "  --mask-out  write each frame's vegetation mask (255 = vegetation) as PNG\n"
    "  --class-out write each frame's class map (0 soil, 1 crop, 2 weed) as PNG;\n"
    "              needs classify.model (a model from stemd-train)\n"
    "  --overlay   write overlays (contour, hull, cuts, leaves, stem, centre of mass)\n"
    "  --timing    per-frame stage times (and the sparse index's tiles computed) on stderr, medians at the end\n";

struct Args {
    config::ConfigArgs config;
    std::string csv_path;
    std::string mask_dir;
    std::string class_dir;
    std::string overlay_dir;
    bool timing = false;
    std::vector<std::string> inputs;
};

const tools::CommandLine kCommandLine{.tool = "stemd-detect", .usage = kUsage, .usage_after_error = true};

// The arguments into `args` and the configuration they name into `config`;
// the exit code after --help, a usage error or a configuration error.
std::optional<int> parse_args(int argc, char** argv, Args& args, config::Config& config)
{
    CLI::App app{"stemd-detect"};
    tools::add_config_options(app, args.config);
    app.add_option_function<std::string>(
           "--segment", [&](const std::string& method) { args.config.sets.push_back("segment.method=" + method); })
        ->trigger_on_parse();
    app.add_option("--csv", args.csv_path);
    app.add_option("--mask-out", args.mask_dir);
    app.add_option("--class-out", args.class_dir);
    app.add_option("--overlay", args.overlay_dir);
    app.add_flag("--timing", args.timing);
    app.add_option("INPUT", args.inputs);
    if (const auto exit_code = tools::parse(app, argc, argv, kCommandLine))
        return *exit_code;
    if (args.inputs.empty())
        return tools::usage_error(kCommandLine, "no INPUT given");
    return tools::load_config(kCommandLine, args.config, config);
}

double median(std::vector<double> v)
{
    if (v.empty())
        return 0;
    std::sort(v.begin(), v.end());
    return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// This thread's CPU time: on a loaded machine the wall time also holds the
// time other processes had the core.
std::int64_t thread_cpu_ns()
{
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

bool ensure_dir(const std::string& dir, std::string& error)
{
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) {
        error = dir + ": cannot create directory: " + ec.message();
        return false;
    }
    return true;
}

}  // namespace

int main(int argc, char** argv)
{
    Args args;
    config::Config config;
    if (const auto exit_code = parse_args(argc, argv, args, config))
        return *exit_code;
    std::string error;
    vision::Params params = config.settings().daemon.vision;
    const runtime::ClassifyConfig& classify = config.settings().daemon.classify;
    const vision::ModelClassParams class_params =
        runtime::model_class_params(classify, config.settings().camera.mount.forward);
    std::vector<tools::FrameJob> jobs;
    if (!tools::collect_frames(args.inputs, params.segmentation, jobs, error)) {
        std::cerr << "stemd-detect: " << error << "\n";
        return kUsageError;
    }
    if (params.segmentation == vision::Segmentation::automatic) {
        params.segmentation = tools::frames_segmentation(params.segmentation, jobs);
        std::cerr << "stemd-detect: segment.method auto: " << vision::to_string(params.segmentation)
                  << (vision::uses_nir(params.segmentation) ? " (every frame has a nir image)\n"
                                                            : " (not every frame has a nir image)\n");
    }
    std::optional<vision::PlantClassifier> model;
    if (!classify.model.empty()) {
        model = vision::PlantClassifier::load(classify.model, error);
        if (!model) {
            std::cerr << "stemd-detect: classify.model: " << error << "\n";
            return kUsageError;
        }
        if (const auto why = model->mismatch(params.gsd_mm_per_px, vision::uses_nir(params.segmentation), classify.model)) {
            std::cerr << "stemd-detect: classify.model: " << *why << "\n";
            return kUsageError;
        }
    }
    if (!args.class_dir.empty() && !model) {
        std::cerr << "stemd-detect: --class-out needs classify.model (train one with stemd-train)\n";
        return kUsageError;
    }

    for (const std::string* dir : {&args.mask_dir, &args.class_dir, &args.overlay_dir}) {
        if (!dir->empty() && !ensure_dir(*dir, error)) {
            std::cerr << "stemd-detect: " << error << "\n";
            return 1;
        }
    }

    std::ofstream csv_file;
    std::ostream* csv = nullptr;
    if (args.csv_path == "-") {
        csv = &std::cout;
    } else if (!args.csv_path.empty()) {
        csv_file.open(args.csv_path);
        if (!csv_file) {
            std::cerr << "stemd-detect: " << args.csv_path << ": cannot write\n";
            return 1;
        }
        csv = &csv_file;
    }
    std::ostream& report = args.csv_path == "-" ? std::cerr : std::cout;
    if (csv)
        *csv << "image,plant,x,y,method,leaves,area_px,estimator,confidence" << (model ? ",class,weed_probability" : "")
             << "\n";

    std::unique_ptr<vision::Workspace> workspace;
    std::unique_ptr<vision::ClassifyWorkspace> classify_workspace;
    std::unique_ptr<vision::CellWorkspace> cell_workspace;
    std::array<float, vision::kMaxPlants> weed_probability{};
    std::array<PlantClass, vision::kMaxPlants> plant_class{};
    cv::Mat class_image;
    std::vector<double> classify_ms, classify_cpu_ms;
    auto detections = std::make_unique<vision::Detections>();
    std::vector<double> stage_ms[6];
    std::vector<double> tiles_computed_pct;   // per frame on the sparse index
    int skipped = 0, plants_total = 0, stemless_total = 0;
    long long over_capacity_total = 0;   // plants beyond the per-frame capacity: found, not reported
    std::size_t cells_over_budget_total = 0;   // vegetated cells left unclassified by classify.max_cells
    tools::LoadedFrame frame;
    for (const tools::FrameJob& job : jobs) {
        if (!tools::load_frame(job, params.segmentation, !args.overlay_dir.empty() || model.has_value(), frame, error)) {
            std::cerr << "stemd-detect: skipped frame: " << error << "\n";
            ++skipped;
            continue;
        }
        const cv::Mat& bgr = frame.bgr;
        const cv::Mat& mask = frame.mask;
        const cv::Size size = params.segmentation == vision::Segmentation::mask ? mask.size() : bgr.size();
        if (!workspace || workspace->frame_size() != size)
            workspace = std::make_unique<vision::Workspace>(size, params);
        if (model && (!classify_workspace || classify_workspace->frame_size() != size)) {
            classify_workspace = std::make_unique<vision::ClassifyWorkspace>(size, params);
            cell_workspace = std::make_unique<vision::CellWorkspace>(size, params.gsd_mm_per_px, model->info().cell_mm);
        }
        vision::StageTimes times;
        vision::detect({.bgr = bgr, .nir = frame.nir, .mask = mask}, params, *workspace, *detections, &times);
        if (detections->status != vision::DetectStatus::ok) {
            std::cerr << "stemd-detect: skipped frame: " << job.image << ": " << vision::to_string(detections->status)
                      << "\n";
            ++skipped;
            continue;
        }
        const auto& d = *detections;
        if (model) {
            if (bgr.empty() || bgr.size() != size) {
                std::cerr << "stemd-detect: skipped frame: " << job.image << ": the classifier needs its rgb image\n";
                ++skipped;
                continue;
            }
            const std::int64_t t0 = base::monotonic_ns(), cpu0 = thread_cpu_ns();
            const vision::FrameView view{.bgr = bgr, .nir = frame.nir, .mask = mask};
            cells_over_budget_total +=
                vision::classify_frame(*model, class_params, view, params, *workspace, *detections,
                                       *classify_workspace, *cell_workspace, weed_probability, plant_class)
                    .cells_over_budget;
            classify_ms.push_back(static_cast<double>(base::monotonic_ns() - t0) / 1e6);
            classify_cpu_ms.push_back(static_cast<double>(thread_cpu_ns() - cpu0) / 1e6);
        }
        int from_leaves = 0, with_stem = 0;
        for (std::size_t i = 0; i < d.plants.size(); ++i) {
            const auto& p = d.plants[i];
            if (!p.has_stem)
                continue;  // grass or too unsure: no stem to report
            ++with_stem;
            from_leaves += p.method == vision::StemMethod::leaves;
            if (csv) {
                char xy[64], confidence[16];
                std::snprintf(xy, sizeof xy, "%.3f,%.3f", p.stem.x, p.stem.y);
                std::snprintf(confidence, sizeof confidence, "%.3f", p.confidence);
                *csv << io::csv_field(job.image) << ',' << i << ',' << xy << ',' << vision::to_string(p.method) << ','
                     << p.leaves.size() << ',' << p.area_px << ',' << vision::to_string(p.estimator) << ','
                     << confidence;
                if (model) {
                    char probability[16];
                    // Empty when no classified cell holds the plant.
                    if (weed_probability[i] >= 0)
                        std::snprintf(probability, sizeof probability, "%.3f", weed_probability[i]);
                    else
                        probability[0] = '\0';
                    *csv << ',' << to_string(plant_class[i]) << ',' << probability;
                }
                *csv << '\n';
            }
        }
        plants_total += with_stem;
        stemless_total += d.stats.stemless;
        over_capacity_total += d.stats.plants_over_capacity;
        report << job.image << ": " << with_stem << " stems (" << from_leaves << " from leaves, " << with_stem - from_leaves
               << " centre of mass), " << d.stats.stemless << " stemless, threshold " << d.stats.threshold << "\n";

        const std::string out_name = fs::path(job.image).filename().replace_extension(".png").string();
        if (!args.mask_dir.empty()) {
            cv::Mat veg;
            vision::unpack_mask(workspace->vegetation(), veg);
            const auto path = (fs::path(args.mask_dir) / out_name).string();
            if (!cv::imwrite(path, veg)) {
                std::cerr << "stemd-detect: " << path << ": cannot write\n";
                return 1;
            }
        }
        if (!args.class_dir.empty()) {
            if (model->has_cells())
                vision::cell_class_map(*workspace, *cell_workspace, class_image);
            else
                vision::class_map(*workspace, *classify_workspace, {plant_class.data(), d.plants.size()}, class_image);
            const auto path = (fs::path(args.class_dir) / out_name).string();
            if (!cv::imwrite(path, class_image)) {
                std::cerr << "stemd-detect: " << path << ": cannot write\n";
                return 1;
            }
        }
        if (!args.overlay_dir.empty()) {
            cv::Mat canvas;
            if (!bgr.empty())
                canvas = bgr.clone();
            else
                cv::cvtColor(mask, canvas, cv::COLOR_GRAY2BGR);
            viz::draw_overlay(canvas, d, workspace->closed());
            const auto path = (fs::path(args.overlay_dir) / out_name).string();
            if (!cv::imwrite(path, canvas)) {
                std::cerr << "stemd-detect: " << path << ": cannot write\n";
                return 1;
            }
        }
        if (args.timing) {
            const double ms[6] = {times.index_ns / 1e6,  times.threshold_ns / 1e6, times.closing_ns / 1e6,
                                  times.plants_ns / 1e6, times.leaves_ns / 1e6,    times.total_ns / 1e6};
            for (int s = 0; s < 6; ++s)
                stage_ms[s].push_back(ms[s]);
            std::fprintf(stderr,
                         "timing %s: index %.3f threshold %.3f closing %.3f plants %.3f leaves %.3f total %.3f ms",
                         job.image.c_str(), ms[0], ms[1], ms[2], ms[3], ms[4], ms[5]);
            // The sparse index's share says why a frame's index cost what
            // it did: soil whose spread crosses the level computes whole.
            if (d.stats.index_tiles > 0) {
                std::fprintf(stderr, ", index tiles computed %d of %d", d.stats.index_tiles_computed,
                             d.stats.index_tiles);
                tiles_computed_pct.push_back(100.0 * d.stats.index_tiles_computed / d.stats.index_tiles);
            }
            std::fputc('\n', stderr);
        }
    }
    if (args.timing && !stage_ms[5].empty())
        std::fprintf(stderr,
                     "timing median over %zu frames: index %.3f threshold %.3f closing %.3f plants %.3f leaves %.3f "
                     "total %.3f ms\n",
                     stage_ms[5].size(), median(stage_ms[0]), median(stage_ms[1]), median(stage_ms[2]),
                     median(stage_ms[3]), median(stage_ms[4]), median(stage_ms[5]));
    if (args.timing && !tiles_computed_pct.empty())
        std::fprintf(stderr, "timing median over %zu frames: index tiles computed %.1f %%\n", tiles_computed_pct.size(),
                     median(tiles_computed_pct));
    if (args.timing && !classify_ms.empty())
        std::fprintf(stderr,
                     "timing median over %zu frames: classify %.3f ms, thread CPU %.3f ms (plant and cell features, "
                     "forests, decisions)\n",
                     classify_ms.size(), median(classify_ms), median(classify_cpu_ms));
    report << jobs.size() - skipped << " frames, " << plants_total << " stems, " << stemless_total
           << " stemless plants, " << over_capacity_total << " plants over capacity (" << vision::kMaxPlants
           << " a frame)";
    if (cells_over_budget_total > 0)
        report << ", " << cells_over_budget_total << " vegetated cells left unclassified (classify.max_cells "
               << classify.max_cells << ")";
    if (skipped)
        report << ", " << skipped << " frames skipped";
    report << "\n";
    return skipped ? 1 : 0;
}
