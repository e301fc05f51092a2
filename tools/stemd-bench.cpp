// stemd-bench: per-stage and whole-pipeline timings on synthetic
// 1296x966 frames, one thread, with one cv::cvtColor BGR->GRAY pass over the
// same frames as a yardstick of this machine's speed.
//   stemd-bench [--json] [--preset early|late|dense|seedling|canopy] [--frames N] [--radius M] [--edge-radius R]
//               [--sparse-index 0|1] [benchmark flags]
// (defaults: late, 8 frames, the pipeline's default closing radius)
// Each repetition is one frame; medians and p90 are over repetitions.
// "actuation" is the actuator thread's work per frame (field positions,
// tracker, scheduler, TARGET encoding; the bus discards the frames) on the
// detections of a 1 m moving strip of the same preset, driven over again
// and again.
// "classify" is the crop/weed classifier after detect() (features, forest,
// decision, for every plant), with --model FILE or else a forest of the
// default size trained at start on the bench frames' own plants.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <map>
#include <optional>
#include <array>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <benchmark/benchmark.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "stemd/runtime/actuation_stage.hpp"
#include "stemd/runtime/daemon_config.hpp"
#include "stemd/runtime/logging.hpp"
#include "stemd/synth/synth.hpp"
#include "stemd/vision/cells.hpp"
#include "stemd/vision/classify.hpp"
#include "stemd/vision/detect.hpp"
#include "tool_cli.hpp"

using namespace stemd;

namespace {

struct Setup {
    std::vector<synth::Frame> frames;
    vision::Params params;
    std::unique_ptr<vision::Workspace> workspace;
    vision::Detections detections;
    std::size_t next = 0;
};

Setup* g_setup = nullptr;  // benchmark callbacks are plain functions

struct ClassifySetup {
    std::unique_ptr<vision::ClassifyWorkspace> workspace;
    std::unique_ptr<vision::CellWorkspace> cells;
    std::array<float, vision::kMaxPlants> probabilities{};
    std::optional<vision::PlantClassifier> model;
    std::array<PlantClass, vision::kMaxPlants> classes{};
};
ClassifySetup* g_classify = nullptr;

std::int64_t thread_cpu_ns()
{
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

void bench_classify(benchmark::State& state)
{
    Setup& s = *g_setup;
    ClassifySetup& c = *g_classify;
    const runtime::ClassifyConfig decision;
    std::size_t over_budget = 0;
    for (auto _ : state) {
        const synth::Frame& f = s.frames[s.next++ % s.frames.size()];
        const vision::FrameView view{.bgr = f.bgr, .nir = f.nir, .mask = f.mask};
        vision::detect(view, s.params, *s.workspace, s.detections);
        const std::int64_t cpu0 = thread_cpu_ns();
        const auto t0 = std::chrono::steady_clock::now();
        vision::plant_features(view, s.params, *s.workspace, s.detections, *c.workspace);
        const std::int64_t cpu_plants = thread_cpu_ns();
        vision::cell_features(view, s.params, *s.workspace, s.detections, *c.workspace, *c.cells);
        const std::int64_t cpu_cells = thread_cpu_ns();
        // The daemon's default budget (classify.max_cells), camera.forward up
        // (the cells nearest the top first).
        over_budget = vision::classify_cells(*c.model, *c.cells, {.max_cells = decision.max_cells});
        const std::int64_t cpu_forests = thread_cpu_ns();
        vision::classify_plants(*c.model, *c.workspace, *c.cells, s.detections.plants.size(), decision.min_confidence,
                                decision.weed_confidence, c.probabilities, c.classes);
        const auto t1 = std::chrono::steady_clock::now();
        const std::int64_t cpu1 = thread_cpu_ns();
        benchmark::DoNotOptimize(c.classes.data());
        state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
        // The thread's own CPU time: on a loaded machine the wall time also
        // holds the time other processes had the core. Its parts show what a
        // model costs: the features are the frame's, the forests the model's.
        state.counters["cpu_ms"] = static_cast<double>(cpu1 - cpu0) / 1e6;
        state.counters["plant_features_ms"] = static_cast<double>(cpu_plants - cpu0) / 1e6;
        state.counters["cell_features_ms"] = static_cast<double>(cpu_cells - cpu_plants) / 1e6;
        state.counters["cell_forests_ms"] = static_cast<double>(cpu_forests - cpu_cells) / 1e6;
    }
    state.counters["plants"] = static_cast<double>(s.detections.plants.size());
    state.counters["cells"] = static_cast<double>(c.cells->vegetated().size());
    state.counters["cells_classified"] = static_cast<double>(c.cells->vegetated().size() - over_budget);
}

// Without a model file: a forest of the default size on the bench frames'
// plants, labelled by area with every third label flipped, so that the
// trees grow to their depth limit as on hard real data (predict's cost is
// the trees' count and depth, not what they learned).
std::optional<vision::PlantClassifier> bench_forest(Setup& s, vision::ClassifyWorkspace& workspace,
                                                    vision::CellWorkspace& cells, std::string& error)
{
    std::vector<vision::FeatureRow> rows;
    std::vector<vision::CellRow> cell_rows;
    for (const synth::Frame& f : s.frames) {
        const vision::FrameView view{.bgr = f.bgr, .nir = f.nir, .mask = f.mask};
        vision::detect(view, s.params, *s.workspace, s.detections);
        vision::plant_features(view, s.params, *s.workspace, s.detections, workspace);
        rows.insert(rows.end(), workspace.features().begin(), workspace.features().end());
        vision::cell_features(view, s.params, *s.workspace, s.detections, workspace, cells);
        for (const std::uint32_t c : cells.vegetated())
            cell_rows.push_back(cells.row(c));
    }
    if (rows.size() < 4) {
        error = "too few plants on the bench frames to train a forest";
        return std::nullopt;
    }
    std::vector<float> areas;
    for (const auto& r : rows)
        areas.push_back(r[vision::f_log_area_mm2]);
    std::nth_element(areas.begin(), areas.begin() + static_cast<std::ptrdiff_t>(areas.size() / 2), areas.end());
    const float median = areas[areas.size() / 2];
    cv::Mat samples(static_cast<int>(rows.size()), vision::kPlantFeatureCount, CV_32FC1);
    cv::Mat labels(static_cast<int>(rows.size()), 1, CV_32SC1);
    for (std::size_t i = 0; i < rows.size(); ++i) {
        std::copy(rows[i].begin(), rows[i].end(), samples.ptr<float>(static_cast<int>(i)));
        const bool weed = (rows[i][vision::f_log_area_mm2] < median) != (i % 3 == 0);
        labels.at<int>(static_cast<int>(i)) = to_value(weed ? PlantClass::Weed : PlantClass::Crop);
    }
    auto model = vision::PlantClassifier::train(samples, labels, vision::ForestOptions{}, error);
    if (!model || cell_rows.size() < 4)
        return model;
    // The cells alike: labelled by fill, every third flipped.
    cv::Mat cell_samples(static_cast<int>(cell_rows.size()), vision::kCellFeatureCount, CV_32FC1);
    cv::Mat cell_labels(static_cast<int>(cell_rows.size()), 1, CV_32SC1);
    for (std::size_t i = 0; i < cell_rows.size(); ++i) {
        std::copy(cell_rows[i].begin(), cell_rows[i].end(), cell_samples.ptr<float>(static_cast<int>(i)));
        const bool weed = (cell_rows[i][vision::c_fill] < 0.5f) != (i % 3 == 0);
        cell_labels.at<int>(static_cast<int>(i)) = to_value(weed ? PlantClass::Weed : PlantClass::Crop);
    }
    if (!model->train_cells(cell_samples, cell_labels, vision::kDefaultCellForest, vision::kDefaultCellMm, error))
        return std::nullopt;
    // The context forest (what stemd-train adds) on the same labels, its
    // context every entry the cell forest's probability: as deep, as costly.
    cv::Mat context_samples(cell_samples.rows, vision::kContextFeatureCount, CV_32FC1);
    for (int i = 0; i < cell_samples.rows; ++i) {
        float* row = context_samples.ptr<float>(i);
        std::copy(cell_samples.ptr<float>(i), cell_samples.ptr<float>(i) + vision::kCellFeatureCount, row);
        const float first = model->cell_weed_probability({row, static_cast<std::size_t>(vision::kCellFeatureCount)});
        std::fill(row + vision::kCellFeatureCount, row + vision::kContextFeatureCount, first);
    }
    if (!model->train_context(context_samples, cell_labels, vision::kDefaultCellForest, error))
        return std::nullopt;
    return model;
}

// A bus that takes every frame and keeps nothing.
class NullBus final : public drivers::CanBus {
public:
    std::string_view name() const override { return "null"; }
    using drivers::CanBus::send;
    drivers::SendResult send(const protocol::CanFrame&, std::int64_t, drivers::SendGate) override
    {
        ++sent;
        return drivers::SendResult::sent;
    }
    bool receive(protocol::CanFrame&, std::int64_t, std::int64_t&) override { return false; }
    drivers::CanBusCounters counters() const override { return {.sent = sent}; }
    std::uint64_t sent = 0;
};

struct ActuationSetup {
    std::vector<std::unique_ptr<runtime::FrameResult>> frames;   // one strip's detections
    double strip_odom_mm = 0;     // odometer advance of one pass (the strip repeats)
    std::int64_t period_ns = 0;
    std::unique_ptr<runtime::ActuationStage> stage;
    std::uint64_t i = 0;
};

ActuationSetup* g_actuation = nullptr;

void bench_actuation(benchmark::State& state)
{
    ActuationSetup& a = *g_actuation;
    for (auto _ : state) {
        const std::size_t n = a.frames.size();
        runtime::FrameResult& r = *a.frames[a.i % n];
        const auto pass = static_cast<double>(a.i / n);
        const double odom = r.odom_mm;
        r.odom_mm = odom + pass * a.strip_odom_mm;
        r.t_sample_ns = static_cast<std::int64_t>(a.i) * a.period_ns;
        r.seq = a.i;
        const auto t0 = std::chrono::steady_clock::now();
        a.stage->on_frame(r, r.t_sample_ns + 2'000'000);
        const auto t1 = std::chrono::steady_clock::now();
        r.odom_mm = odom;
        ++a.i;
        state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
    }
    state.counters["targets"] = static_cast<double>(a.stage->counters().targets.load());
}

double percentile(std::vector<double> v, double q)
{
    if (v.empty())
        return 0;
    std::sort(v.begin(), v.end());
    const auto i = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5);
    return v[std::min(i, v.size() - 1)];
}

std::int64_t stage_ns(const vision::StageTimes& t, int stage)
{
    switch (stage) {
    case 0: return t.index_ns;
    case 1: return t.threshold_ns;
    case 2: return t.closing_ns;
    case 3: return t.plants_ns;
    case 4: return t.leaves_ns;
    default: return t.total_ns;
    }
}

const char* const kStageNames[] = {"index", "threshold", "closing", "plants", "leaves", "frame"};

void bench_stage(benchmark::State& state, int stage)
{
    Setup& s = *g_setup;
    for (auto _ : state) {
        const synth::Frame& f = s.frames[s.next++ % s.frames.size()];
        vision::StageTimes times;
        vision::detect({.bgr = f.bgr, .nir = f.nir, .mask = f.mask}, s.params, *s.workspace, s.detections, &times);
        benchmark::DoNotOptimize(s.detections.plants.size());
        state.SetIterationTime(static_cast<double>(stage_ns(times, stage)) * 1e-9);
    }
    state.counters["plants"] = static_cast<double>(s.detections.plants.size());
}

void bench_cvtcolor(benchmark::State& state)
{
    Setup& s = *g_setup;
    cv::Mat gray;
    for (auto _ : state) {
        const synth::Frame& f = s.frames[s.next++ % s.frames.size()];
        const auto t0 = std::chrono::steady_clock::now();
        cv::cvtColor(f.bgr, gray, cv::COLOR_BGR2GRAY);
        const auto t1 = std::chrono::steady_clock::now();
        benchmark::DoNotOptimize(gray.data);
        state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
    }
}

// Keeps the median and p90 of every benchmark; prints them as one JSON line.
class JsonLineReporter : public benchmark::BenchmarkReporter {
public:
    bool ReportContext(const Context&) override { return true; }
    void ReportRuns(const std::vector<Run>& runs) override
    {
        for (const Run& run : runs) {
            if (run.aggregate_name == "median" || run.aggregate_name == "p90") {
                values_[run.run_name.function_name + "_ms_" + run.aggregate_name] = run.GetAdjustedRealTime();
                // The thread-CPU counters (cpu_ms, and the classifier's parts), and its cells.
                for (const auto& [name, counter] : run.counters)
                    if (name.ends_with("_ms") || name.starts_with("cells"))
                        values_[run.run_name.function_name + "_" + name + "_" + run.aggregate_name] = counter.value;
            }
        }
    }
    void Print(int frames, const std::string& preset, std::string_view segment, int radius,
               std::size_t workspace_bytes, double tiles_computed_pct) const
    {
        // A MiB to 0.01, a time to 0.1 us; dividing by the exact power of ten
        // gives the double nearest the decimal, which dumps as that decimal.
        auto rounded = [](double v, double per_unit) { return std::round(v * per_unit) / per_unit; };
        nlohmann::ordered_json json{
            {"frame_width_px", 1296},
            {"frame_height_px", 966},
            {"preset", preset},
            {"segment", segment},
            {"closing_radius_px", radius},
            {"frames", frames},
            {"workspace_mib", rounded(static_cast<double>(workspace_bytes) / (1024.0 * 1024.0), 100)},
            {"index_tiles_computed_pct", rounded(tiles_computed_pct, 10)}};
        for (const auto& [key, value] : values_)
            json[key] = rounded(value, 1e4);
        std::printf("%s\n", json.dump().c_str());
    }

private:
    std::map<std::string, double> values_;
};

}  // namespace

int main(int argc, char** argv)
{
    bool json = false;
    std::string preset_name = "late";
    int frame_count = 8, radius = vision::Params{}.closing_radius_px, repetitions = 200;
    int edge_radius = vision::Params{}.edge_radius_px;
    bool sparse_index = vision::Params{}.sparse_index;
    bool nir = false;
    std::string model_path;
    CLI::App app{"stemd-bench: per-stage and whole-pipeline timings on synthetic 1296x966 frames; other arguments "
                 "go to Google Benchmark (--benchmark_filter=REGEX, ...)"};
    app.add_flag("--json", json, "one line of JSON: medians and p90 of every stage");
    app.add_option("--preset", preset_name, "early, late, dense, seedling or canopy")
        ->check(CLI::Validator(
            [](std::string& name) {
                return synth::parse_preset(name) ? std::string() : "'" + name + "' is not early, late, dense, seedling or canopy";
            },
            "PRESET"));
    const auto positive = tools::value_check<int>("a positive integer", [](int n) { return n > 0; });
    app.add_option("--frames", frame_count, "frames to cycle through")->check(positive);
    app.add_option("--repetitions", repetitions, "repetitions of every benchmark (one frame each)")->check(positive);
    app.add_option("--radius", radius, "closing radius, px")
        ->check(tools::value_check<int>("a closing radius in [0, " + std::to_string(vision::kMaxClosingRadiusPx) + "]",
                                        [](int r) { return r >= 0 && r <= vision::kMaxClosingRadiusPx; }));
    app.add_option("--edge-radius", edge_radius, "mixed-edge radius, px (0: off)")
        ->check(tools::value_check<int>("an integer", [](int) { return true; }));
    app.add_option("--sparse-index", sparse_index, "the index in full only in tiles near vegetation (1, the "
                                                   "default) or on every pixel (0)");
    app.add_flag("--nir", nir, "the RGB+NIR camera's pipeline: the frames' NIR plane read, as segment.method auto "
                               "then does (exg_and_ndvi); without it the RGB camera's (chromatic_exg)");
    app.add_option("--model", model_path, "crop/weed model for the classify stage (default: a forest trained on the "
                                          "bench frames)");
    if (const auto exit_code = tools::parse(app, argc, argv, {.tool = "stemd-bench", .pass_unknown = true}))
        return *exit_code;
    std::vector<std::string> rest_args = app.remaining();
    std::vector<char*> rest{argv[0]};
    for (std::string& a : rest_args)
        rest.push_back(a.data());
    const auto preset = synth::parse_preset(preset_name);
    cv::setNumThreads(1);

    Setup setup;
    synth::Options options;
    options.preset = *preset;
    options.seed = 2024;
    for (int i = 0; i < frame_count; ++i)
        setup.frames.push_back(synth::generate_frame(options, i));
    // The bench frames carry NIR; without --nir it times the RGB camera's
    // pipeline (what segment.method auto runs without a NIR plane), as its
    // tables say.
    setup.params.segmentation = vision::resolve_segmentation(vision::Params{}.segmentation, nir);
    setup.params.closing_radius_px = radius;
    setup.params.edge_radius_px = std::max(edge_radius, 0);
    setup.params.sparse_index = sparse_index;
    setup.workspace = std::make_unique<vision::Workspace>(setup.frames.front().bgr.size(), setup.params);
    g_setup = &setup;
    // The share of the index's tiles computed in full, over the bench frames.
    double tiles = 0, computed = 0;
    for (const synth::Frame& f : setup.frames) {
        vision::detect({.bgr = f.bgr, .nir = f.nir, .mask = f.mask}, setup.params, *setup.workspace, setup.detections);
        tiles += setup.detections.stats.index_tiles;
        computed += setup.detections.stats.index_tiles_computed;
    }
    const double tiles_computed_pct = tiles > 0 ? 100.0 * computed / tiles : 100.0;

    ClassifySetup classify_setup;
    {
        const cv::Size size = setup.frames.front().bgr.size();
        classify_setup.workspace = std::make_unique<vision::ClassifyWorkspace>(size, setup.params);
        std::string error;
        if (model_path.empty()) {
            classify_setup.cells =
                std::make_unique<vision::CellWorkspace>(size, setup.params.gsd_mm_per_px, vision::kDefaultCellMm);
            classify_setup.model = bench_forest(setup, *classify_setup.workspace, *classify_setup.cells, error);
        } else {
            classify_setup.model = vision::PlantClassifier::load(model_path, error);
            // The model's own cells: as many per frame as on its camera.
            if (classify_setup.model)
                classify_setup.cells = std::make_unique<vision::CellWorkspace>(
                    size, classify_setup.model->info().gsd_mm_per_px, classify_setup.model->info().cell_mm);
        }
        if (!classify_setup.model) {
            std::fprintf(stderr, "stemd-bench: classify: %s\n", error.c_str());
            return 1;
        }
    }
    g_classify = &classify_setup;

    // The actuation: detections of a 1 m strip, then the stage driving over it.
    ActuationSetup actuation_setup;
    {
        synth::StripOptions strip_options;
        strip_options.preset = *preset;
        strip_options.seed = 2024;
        strip_options.length_mm = 1000;
        const synth::Strip strip = synth::generate_strip(strip_options);
        for (int k = 0; k < strip.frame_count; ++k) {
            const synth::StripFrame f = synth::render_strip_frame(strip, k);
            auto r = std::make_unique<runtime::FrameResult>();
            vision::detect({.bgr = f.bgr, .nir = f.nir}, setup.params, *setup.workspace, r->detections);
            r->odom_mm = f.odom_mm;
            actuation_setup.frames.push_back(std::move(r));
        }
        actuation_setup.strip_odom_mm = strip.odom_mm(strip.frame_count);
        actuation_setup.period_ns = strip.t_ns(1) - strip.t_ns(0);
        runtime::ActuationConfig config;
        config.tools = {{.id = 0, .offset_mm = 600, .y_min_mm = -220, .y_max_mm = 220, .lanes = 8}};
        config.policy = runtime::PolicyChoice::all;
        geometry::NadirParams nadir;
        nadir.principal_px = geometry::image_centre(setup.frames.front().bgr.size());
        runtime::ActuationStage::Parts parts;
        parts.bus = std::make_unique<NullBus>();
        std::string error;
        runtime::set_log_level("warn");
        actuation_setup.stage =
            runtime::ActuationStage::make(config, *geometry::CameraModel::nadir(nadir), setup.frames.front().bgr.size(),
                                          std::move(parts), runtime::make_logger("actuator"), error);
        if (!actuation_setup.stage) {
            std::fprintf(stderr, "stemd-bench: actuation: %s\n", error.c_str());
            return 1;
        }
    }
    g_actuation = &actuation_setup;

    auto p90 = [](const std::vector<double>& v) { return percentile(v, 0.9); };
    for (int stage = 0; stage < 6; ++stage)
        benchmark::RegisterBenchmark(kStageNames[stage], bench_stage, stage)
            ->UseManualTime()->Iterations(1)->Repetitions(repetitions)->ReportAggregatesOnly(true)
            ->ComputeStatistics("p90", p90)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("classify", bench_classify)
        ->UseManualTime()->Iterations(1)->Repetitions(repetitions)->ReportAggregatesOnly(true)
        ->ComputeStatistics("p90", p90)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("actuation", bench_actuation)
        ->UseManualTime()->Iterations(1)->Repetitions(repetitions)->ReportAggregatesOnly(true)
        ->ComputeStatistics("p90", p90)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("cvtcolor", bench_cvtcolor)
        ->UseManualTime()->Iterations(1)->Repetitions(repetitions)->ReportAggregatesOnly(true)
        ->ComputeStatistics("p90", p90)->Unit(benchmark::kMillisecond);

    int rest_argc = static_cast<int>(rest.size());
    benchmark::Initialize(&rest_argc, rest.data());
    if (benchmark::ReportUnrecognizedArguments(rest_argc, rest.data()))
        return 2;
    if (json) {
        JsonLineReporter reporter;
        benchmark::RunSpecifiedBenchmarks(&reporter);
        reporter.Print(frame_count, preset_name, vision::to_string(setup.params.segmentation), radius, setup.workspace->reserved_bytes(), tiles_computed_pct);
    } else {
        benchmark::RunSpecifiedBenchmarks();
        std::printf("workspace: %.2f MiB reserved for 1296x966 frames (allocated once; detect() allocates nothing)\n",
                    static_cast<double>(setup.workspace->reserved_bytes()) / (1024.0 * 1024.0));
        std::printf("index: %.1f %% of the 64 px tiles computed in full (%s)\n", tiles_computed_pct,
                    sparse_index ? "sparse index" : "every pixel");
    }
    benchmark::Shutdown();
    return 0;
}
