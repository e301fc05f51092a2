// stemd-eval: scores stem detections, vegetation masks, crop/weed class maps and
// TARGET commands against ground truth.
//   stemd-eval GT.csv PRED.csv [--tol-mm MM] [--gsd-mm-per-px MM] [--json]
//   stemd-eval --iou PRED_MASK_DIR RECORDING_DIR [--gt-vegetation nonzero|zero] [--json]
//   stemd-eval --classes PRED_CLASS_DIR RECORDING_DIR [--json]
//   stemd-eval --sweep GT.csv RECORDING_DIR [--config FILE] [--set KEY=VALUE]... [--radii 1,6,10,20]
//              [--tol-mm MM] [--json]
//   stemd-eval --targets PLANTS.csv CAN_LOG [--config FILE] [--set KEY=VALUE]... [--tol-mm MM]
//              [--treat all|weeds] [--min-radius-mm MM] [--require-exact] [--json]
// Adding a mode: a Mode value, its row in kModes, its checks in check_mode()
// and a run_<mode>(const Args&) function that returns the exit code.
#include <algorithm>
#include <array>
#include <limits>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "stemd/eval/eval.hpp"
#include "stemd/eval/targets.hpp"
#include "stemd/runtime/actuation_config.hpp"
#include "stemd/io/recording.hpp"
#include "stemd/config/config.hpp"
#include "stemd/vision/detect.hpp"
#include "tool_cli.hpp"
#include "tool_frames.hpp"

namespace fs = std::filesystem;
using namespace stemd;

namespace {

using tools::fixed;

constexpr int kOk = 0;
constexpr int kError = 2;  // bad arguments, unreadable or malformed input

const char* const kUsage =
    "usage: stemd-eval GT.csv PRED.csv [--tol-mm MM] [--gsd-mm-per-px MM] [--json]\n"
    "       stemd-eval --iou PRED_MASK_DIR RECORDING_DIR [--gt-vegetation nonzero|zero] [--json]\n"
    "       stemd-eval --classes PRED_CLASS_DIR RECORDING_DIR [--json]\n"
    "       stemd-eval --sweep GT.csv RECORDING_DIR [--config FILE] [--set K=V]... [--radii LIST]\n"
    "                  [--tol-mm MM] [--json]\n"
    "       stemd-eval --targets PLANTS.csv CAN_LOG [--config FILE] [--set K=V]... [--treat all|weeds]\n"
    "                  [--min-radius-mm R] [--tol-mm MM] [--require-exact] [--json]\n"
    "Stems (default mode): matches detected stems to ground truth one-to-one per image,\n"
    "closest pairs first; a detection within --tol-mm of a true stem is correct.\n"
    "  GT.csv           ground truth, columns image,x,y (stems.csv: image,x,y,kind,leaves)\n"
    "  PRED.csv         detections, columns image,x,y (stemd-detect --csv output)\n"
    "                   x, y in pixels; images are matched by equal 'image' strings\n"
    "  --tol-mm         match tolerance in mm (default 5, the paper's 0.5 cm)\n"
    "  --gsd-mm-per-px  ground sampling distance in mm per pixel (default 0.33)\n"
    "  prints counts, precision = TP/predictions, recall = TP/ground truth, F1, mean\n"
    "  error of the matches in mm (each 0 when its denominator is 0)\n"
    "Masks (--iou): intersection over union of the vegetation, for every frame of\n"
    "RECORDING_DIR (frames.csv) that has a mask path.\n"
    "  PRED_MASK_DIR    predicted masks named as stemd-detect --mask-out writes them: the\n"
    "                   frame's rgb file name (mask file name if it has no rgb) with .png;\n"
    "                   nonzero = vegetation\n"
    "  --gt-vegetation  ground-truth vegetation pixels: nonzero (default) or zero (CWFID\n"
    "                   masks, which mark soil 255)\n"
    "  prints each frame's IoU and the mean\n"
    "Class maps (--classes): per pixel of the annotated vegetation, for every frame of\n"
    "RECORDING_DIR that has a class path (0 soil, 1 crop, 2 weed; other values are not\n"
    "scored): crop recall, weed recall and their mean, the balanced accuracy, over all\n"
    "the frames' pixels together (as stemd-train reports it) and per frame. A pixel the\n"
    "map calls soil (not segmented, or left unclassified) is right for neither class.\n"
    "  PRED_CLASS_DIR   class maps as stemd-detect --class-out writes them (0 soil, 1 crop,\n"
    "                   2 weed), named like --iou's masks\n"
    "Sweep (--sweep): runs the detector over RECORDING_DIR for each closing radius m with\n"
    "the centre of mass and the paper's method (its 10 px cut, exactly parallel pairs\n"
    "skipped), plus the configured robust estimator at its own radius, and prints recall,\n"
    "precision and F1 like the paper's tables 1-3. The ground sampling distance is the\n"
    "config's camera.gsd_mm_per_px.\n"
    "  --config, --set  configuration as for stemd-detect\n"
    "  --radii          comma-separated radii in px (default 1,6,10,20)\n"
    "Targets (--targets): scores the TARGET commands of a candump -L log (stemd --can-log)\n"
    "against the field truth of a moving recording (stemd-synth --strip writes plants.csv:\n"
    "id,s_mm,y_mm,kind). A command is for the plant whose fire position it matches: its\n"
    "strike point = s_mm + the tool's offset_mm (modulo 2^18), lateral_mm = y_mm; the strike\n"
    "point is the log's TOOL_FIRED odometer for it, else fire_odom_mm + speed x the tool's\n"
    "latency_ms (the log's ODOMETRY speed, else odometry.speed_mm_per_s); matched\n"
    "one-to-one, closest first, within --tol-mm. Prints commands per plant, misses,\n"
    "duplicates, extra commands and the position error p50/p95/max.\n"
    "  --config, --set  the configuration stemd ran with (tools, can.base_id, odometry)\n"
    "  --treat          which plants should have a command: all (default) or weeds\n"
    "  --min-radius-mm  leave out plants smaller than this (plants.csv radius_mm): below the\n"
    "                   detector's working size, commands for them count neither way\n"
    "  --require-exact  exit 1 unless every plant has exactly one command and there are no\n"
    "                   extra commands\n"
    "All: --json prints one line of JSON instead of the text summary.\n"
    "Exit status: 0 done, 1 --require-exact failed, 2 bad arguments or unreadable/malformed input.\n";

enum class Mode { stems, iou, classes, sweep, targets };
enum class Vegetation { nonzero, zero };

struct Args {
    Mode mode = Mode::stems;
    std::vector<std::string> positional;
    std::set<std::string> options;  // options given, to reject those the mode does not use
    double tol_mm = 5.0;
    double gsd_mm_per_px = 0.33;
    Vegetation gt_vegetation = Vegetation::nonzero;
    bool json = false;
    config::ConfigArgs config;
    std::vector<int> radii{1, 6, 10, 20};
    bool treat_weeds_only = false;
    bool require_exact = false;
    double min_radius_mm = 0;
};

struct ModeSpec {
    Mode mode;
    const char* flag;  // nullptr: the default mode
    const char* operands;
    std::vector<std::string_view> options;
};

const ModeSpec kModes[] = {
    {Mode::stems, nullptr, "GT.csv PRED.csv", {"--tol-mm", "--gsd-mm-per-px", "--json"}},
    {Mode::iou, "--iou", "PRED_MASK_DIR RECORDING_DIR", {"--gt-vegetation", "--json"}},
    {Mode::classes, "--classes", "PRED_CLASS_DIR RECORDING_DIR", {"--json"}},
    {Mode::sweep, "--sweep", "GT.csv RECORDING_DIR", {"--tol-mm", "--json", "--config", "--set", "--radii"}},
    {Mode::targets, "--targets", "PLANTS.csv CAN_LOG",
     {"--tol-mm", "--json", "--config", "--set", "--treat", "--min-radius-mm", "--require-exact"}},
};

const ModeSpec& spec(Mode mode)
{
    for (const auto& s : kModes)
        if (s.mode == mode)
            return s;
    return kModes[0];
}

// Shortest text that reads back as the same double ("0.4", "5", "0.3333333333333333").
std::string number(double v)
{
    char buf[64];
    const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
    return ec == std::errc() ? std::string(buf, end) : std::string("0");
}

// The --json line's fields in the order written.
using Json = nlohmann::ordered_json;

// A whole number as an integer ("5", as the text summary writes it, not
// "5.0"); any other as the shortest text that reads back as the same double.
Json json_number(double v)
{
    if (std::isfinite(v) && v == std::trunc(v) && std::fabs(v) < 9.0e15)
        return static_cast<std::int64_t>(v);
    return v;
}

void print_json(const Json& json)
{
    std::cout << json.dump() << "\n";
}

const tools::CommandLine kCommandLine{.tool = "stemd-eval", .usage = kUsage, .after = " (see stemd-eval --help)"};

// A comma-separated list of closing radii.
std::vector<int> parse_radii(std::string_view text)
{
    std::vector<int> radii;
    while (!text.empty()) {
        const auto comma = text.find(',');
        const std::string item(text.substr(0, comma));
        long r = -1;
        if (!tools::parse_int(item, r) || r < 0 || r > vision::kMaxClosingRadiusPx)
            throw CLI::ValidationError("--radii", "'" + item + "' is not a radius in [0, " +
                                                      std::to_string(vision::kMaxClosingRadiusPx) + "] px");
        radii.push_back(static_cast<int>(r));
        text = comma == std::string_view::npos ? std::string_view{} : text.substr(comma + 1);
    }
    if (radii.empty())
        throw CLI::ValidationError("--radii", "no radius given");
    return radii;
}

// One of two words: the text is `yes` or `no`, else "'<text>' is neither <yes> nor <no>".
CLI::Validator either(const std::string& yes, const std::string& no)
{
    return CLI::Validator(
        [yes, no](std::string& text) {
            return text == yes || text == no ? std::string() : "'" + text + "' is neither " + yes + " nor " + no;
        },
        yes + "|" + no);
}

// The arguments into `args`; the exit code after --help or a usage error.
std::optional<int> parse_args(int argc, char** argv, Args& args)
{
    CLI::App app{"stemd-eval"};
    std::string treat = "all", gt_vegetation = "nonzero";
    const auto positive = tools::value_check<double>("a number > 0", [](double v) { return v > 0; });
    CLI::Option* const mode_flags[] = {app.add_flag("--iou"), app.add_flag("--classes"), app.add_flag("--sweep"),
                                       app.add_flag("--targets")};
    app.add_option("--tol-mm", args.tol_mm)->check(positive);
    app.add_option("--gsd-mm-per-px", args.gsd_mm_per_px)->check(positive);
    app.add_option("--min-radius-mm", args.min_radius_mm)->check(positive);
    app.add_option("--gt-vegetation", gt_vegetation)->check(either("nonzero", "zero"));
    app.add_option("--treat", treat)->check(either("all", "weeds"));
    app.add_option_function<std::string>("--radii", [&](const std::string& text) { args.radii = parse_radii(text); });
    app.add_flag("--require-exact", args.require_exact);
    app.add_flag("--json", args.json);
    tools::add_config_options(app, args.config);
    app.add_option("operands", args.positional);
    if (const auto exit_code = tools::parse(app, argc, argv, kCommandLine))
        return *exit_code;
    args.treat_weeds_only = treat == "weeds";
    args.gt_vegetation = gt_vegetation == "zero" ? Vegetation::zero : Vegetation::nonzero;
    // The last mode flag given chooses the mode; check_mode refuses the others.
    const Mode modes[] = {Mode::iou, Mode::classes, Mode::sweep, Mode::targets};
    for (const CLI::Option* option : app.parse_order())
        for (std::size_t m = 0; m < std::size(modes); ++m)
            if (option == mode_flags[m])
                args.mode = modes[m];
    for (const CLI::Option* option : app.get_options())
        if (option->nonpositional() && option->count() > 0)
            args.options.insert(option->get_name());
    return std::nullopt;
}

// Options and operands that fit the chosen mode.
bool check_mode(const Args& args, std::string& error)
{
    const ModeSpec& s = spec(args.mode);
    const std::string mode_name = s.flag ? s.flag : "stem matching";
    for (const std::string& option : args.options) {
        if (s.flag && option == s.flag)
            continue;
        if (std::find(s.options.begin(), s.options.end(), option) == s.options.end()) {
            error = option + " does not apply to " + mode_name;
            return false;
        }
    }
    if (args.positional.size() != 2) {
        error = mode_name + " takes 2 operands (" + s.operands + "), got " + std::to_string(args.positional.size());
        return false;
    }
    return true;
}

int fail(const std::string& message)
{
    std::cerr << "stemd-eval: " << message << "\n";
    return kError;
}

// --- stems -------------------------------------------------------------------

// Warns when both files have points but not one image name in common: the
// names are compared as strings, so "rgb/000.png" and "000.png" differ
// (stemd-detect writes the frames.csv path for recordings, the file name for
// images given one by one).
void warn_disjoint_images(std::span<const eval::StemPoint> gt, std::span<const eval::StemPoint> pred,
                          const std::string& gt_path, const std::string& pred_path)
{
    if (gt.empty() || pred.empty())
        return;
    std::set<std::string_view> gt_images;
    for (const auto& p : gt)
        gt_images.insert(p.image);
    for (const auto& p : pred)
        if (gt_images.count(p.image))
            return;
    std::cerr << "stemd-eval: warning: no image name occurs in both " << gt_path << " and " << pred_path << " (e.g. '"
              << gt.front().image << "' and '" << pred.front().image << "'), so nothing can match\n";
}

int run_stems(const Args& args)
{
    const std::string& gt_path = args.positional[0];
    const std::string& pred_path = args.positional[1];
    std::string error;
    const auto gt = eval::read_stem_points(gt_path, error);
    if (!gt)
        return fail(error);
    const auto pred = eval::read_stem_points(pred_path, error);
    if (!pred)
        return fail(error);
    warn_disjoint_images(*gt, *pred, gt_path, pred_path);

    const eval::MatchResult r = eval::match_stems(*gt, *pred, args.tol_mm, args.gsd_mm_per_px);
    if (args.json) {
        print_json({{"ground_truth", r.ground_truth},
                    {"predictions", r.predictions},
                    {"true_positives", r.true_positives},
                    {"precision", json_number(r.precision)},
                    {"recall", json_number(r.recall)},
                    {"f1", json_number(r.f1)},
                    {"mean_error_mm", json_number(r.mean_error_mm)},
                    {"tol_mm", json_number(args.tol_mm)},
                    {"gsd_mm_per_px", json_number(args.gsd_mm_per_px)}});
        return kOk;
    }
    std::cout << "ground truth    " << r.ground_truth << " stems\n"
              << "predictions     " << r.predictions << " stems\n"
              << "true positives  " << r.true_positives << "\n"
              << "precision       " << fixed(100 * r.precision, 1) << " %\n"
              << "recall          " << fixed(100 * r.recall, 1) << " %\n"
              << "F1              " << fixed(100 * r.f1, 1) << " %\n"
              << "mean error      " << fixed(r.mean_error_mm, 2) << " mm over " << r.true_positives << " matches\n"
              << "tolerance       " << number(args.tol_mm) << " mm = " << fixed(args.tol_mm / args.gsd_mm_per_px, 1)
              << " px at " << number(args.gsd_mm_per_px) << " mm/px\n";
    return kOk;
}

// --- iou and classes ---------------------------------------------------------

// stemd-detect names a frame by its rgb path (its mask path without rgb) and
// writes its mask and class map as <that file name>.png.
std::string frame_name(const io::RecordingFrame& f)
{
    return !f.rgb.empty() ? f.rgb : f.mask;
}

fs::path prediction_path(const fs::path& dir, const io::RecordingFrame& f)
{
    return dir / fs::path(frame_name(f)).filename().replace_extension(".png");
}

// The recording of --iou and --classes, once their prediction folder is
// found to be one; nullopt with `error` otherwise.
std::optional<io::Recording> read_scored_recording(const Args& args, std::string& error)
{
    std::error_code ec;
    if (!fs::is_directory(args.positional[0], ec)) {
        error = args.positional[0] + ": not a directory";
        return std::nullopt;
    }
    return io::read_recording(args.positional[1], error);
}

// Frame f's prediction and its ground truth (`truth`, a path of the
// recording) as 8-bit grey images; false with `error`.
bool load_scored_pair(const fs::path& pred_dir, const io::Recording& rec, const io::RecordingFrame& f,
                      const std::string& truth, cv::Mat& pred, cv::Mat& gt, std::string& error)
{
    if (!io::load_image(prediction_path(pred_dir, f), cv::IMREAD_GRAYSCALE, pred, error)) {
        error = "prediction " + error;
        return false;
    }
    if (!io::load_image(rec.resolve(truth), cv::IMREAD_GRAYSCALE, gt, error)) {
        error = "ground truth " + error;
        return false;
    }
    return true;
}

int run_iou(const Args& args)
{
    const fs::path pred_dir = args.positional[0];
    std::string error;
    const auto rec = read_scored_recording(args, error);
    if (!rec)
        return fail(error);

    // Everything is computed before anything is printed: an error leaves stdout empty.
    struct FrameIou {
        std::string name;
        eval::IouResult iou;
    };
    std::vector<FrameIou> results;
    cv::Mat pred, gt, gt_vegetation;
    for (const io::RecordingFrame& f : rec->frames) {
        if (f.mask.empty())
            continue;
        if (!load_scored_pair(pred_dir, *rec, f, f.mask, pred, gt, error))
            return fail(error);
        if (args.gt_vegetation == Vegetation::zero)
            cv::compare(gt, 0, gt_vegetation, cv::CMP_EQ);
        else
            gt_vegetation = gt;
        const auto r = eval::mask_iou(pred, gt_vegetation, error);
        if (!r)
            return fail(prediction_path(pred_dir, f).string() + " vs " + rec->resolve(f.mask).string() + ": " + error);
        results.push_back({frame_name(f), *r});
    }
    if (results.empty())
        return fail((rec->dir / "frames.csv").string() + ": no frame has a mask path, nothing to evaluate");

    double sum = 0;
    const FrameIou* worst = &results.front();
    for (const FrameIou& r : results) {
        sum += r.iou.iou;
        if (r.iou.iou < worst->iou.iou)
            worst = &r;
    }
    const double mean = sum / static_cast<double>(results.size());
    if (args.json) {
        print_json({{"frames", results.size()},
                    {"mean_iou", json_number(mean)},
                    {"min_iou", json_number(worst->iou.iou)}});
        return kOk;
    }
    for (const FrameIou& r : results)
        std::cout << r.name << "  IoU " << fixed(r.iou.iou, 4) << "  (intersection " << r.iou.intersection_px
                  << " px, union " << r.iou.union_px << " px)\n";
    std::cout << "mean IoU " << fixed(mean, 4) << " over " << results.size() << " frames (min "
              << fixed(worst->iou.iou, 4) << ": " << worst->name << ")\n";
    return kOk;
}

int run_classes(const Args& args)
{
    const fs::path pred_dir = args.positional[0];
    std::string error;
    const auto rec = read_scored_recording(args, error);
    if (!rec)
        return fail(error);

    // Everything is computed before anything is printed: an error leaves stdout empty.
    struct FrameScore {
        std::string name;
        eval::ClassScore score;
    };
    std::vector<FrameScore> results;
    eval::ClassScore all;
    cv::Mat pred, truth;
    for (const io::RecordingFrame& f : rec->frames) {
        if (f.plant_class.empty())
            continue;
        if (!load_scored_pair(pred_dir, *rec, f, f.plant_class, pred, truth, error))
            return fail(error);
        const auto r = eval::class_map_score(pred, truth, error);
        if (!r)
            return fail(prediction_path(pred_dir, f).string() + " vs " + rec->resolve(f.plant_class).string() + ": " +
                        error);
        results.push_back({frame_name(f), *r});
        all += *r;
    }
    if (results.empty())
        return fail((rec->dir / "frames.csv").string() + ": no frame has a class path, nothing to evaluate");

    const FrameScore* worst = &results.front();
    for (const FrameScore& r : results)
        if (r.score.balanced_accuracy() < worst->score.balanced_accuracy())
            worst = &r;
    const auto share = [](long part, long whole) {
        return whole > 0 ? static_cast<double>(part) / static_cast<double>(whole) : 0.0;
    };
    if (args.json) {
        print_json({{"frames", results.size()},
                    {"crop_px", all.crop_px},
                    {"weed_px", all.weed_px},
                    {"crop_recall", json_number(all.crop_recall())},
                    {"weed_recall", json_number(all.weed_recall())},
                    {"balanced_accuracy", json_number(all.balanced_accuracy())},
                    {"crop_as_weed", json_number(share(all.crop_as_weed, all.crop_px))},
                    {"weed_as_crop", json_number(share(all.weed_as_crop, all.weed_px))},
                    {"not_segmented", json_number(share(all.crop_as_soil() + all.weed_as_soil(),
                                                        all.crop_px + all.weed_px))},
                    {"min_frame_balanced_accuracy", json_number(worst->score.balanced_accuracy())}});
        return kOk;
    }
    for (const FrameScore& r : results)
        std::cout << r.name << "  balanced accuracy " << fixed(r.score.balanced_accuracy(), 4) << "  (crop "
                  << r.score.crop_right << " of " << r.score.crop_px << " px, weed " << r.score.weed_right << " of "
                  << r.score.weed_px << " px)\n";
    std::cout << "crop recall " << fixed(all.crop_recall(), 4) << " (" << fixed(100 * share(all.crop_as_weed, all.crop_px), 1)
              << " % called weed, " << fixed(100 * share(all.crop_as_soil(), all.crop_px), 1) << " % soil)\n"
              << "weed recall " << fixed(all.weed_recall(), 4) << " (" << fixed(100 * share(all.weed_as_crop, all.weed_px), 1)
              << " % called crop, " << fixed(100 * share(all.weed_as_soil(), all.weed_px), 1) << " % soil)\n"
              << "balanced accuracy " << fixed(all.balanced_accuracy(), 4) << " over " << results.size()
              << " frames, every pixel together (min frame " << fixed(worst->score.balanced_accuracy(), 4) << ": "
              << worst->name << ")\n";
    return kOk;
}


// --- sweep -------------------------------------------------------------------

struct SweepRow {
    std::string approach;
    int radius_px = 0;
    vision::StemEstimator estimator = vision::StemEstimator::robust;
    eval::MatchResult result;
};

int run_sweep(const Args& args)
{
    config::Config config;
    if (const auto config_error = config::build_config(args.config, config))
        return fail(config_error->to_string());
    vision::Params base = config.settings().daemon.vision;
    std::string error;
    const auto gt = eval::read_stem_points(args.positional[0], error);
    if (!gt)
        return fail(error);
    std::vector<tools::FrameJob> jobs;
    if (!io::is_recording_dir(args.positional[1]))
        return fail(args.positional[1] + ": not a recording directory (no frames.csv)");
    if (!tools::collect_frames({args.positional[1]}, base.segmentation, jobs, error))
        return fail(error);
    base.segmentation = tools::frames_segmentation(base.segmentation, jobs);
    // Frames are decoded once and kept: the sweep runs over them many times.
    std::vector<tools::LoadedFrame> frames(jobs.size());
    for (std::size_t i = 0; i < jobs.size(); ++i)
        if (!tools::load_frame(jobs[i], base.segmentation, false, frames[i], error))
            return fail(error);

    // The paper's method with the paper's own cut (10 px) at every radius,
    // the centre of mass at every radius, and the configured estimator as
    // configured (its own radius) when it is neither.
    struct Run {
        vision::StemEstimator estimator;
        int radius_px;
    };
    std::vector<Run> runs;
    for (const auto estimator : {vision::StemEstimator::com, vision::StemEstimator::paper})
        for (const int radius : args.radii)
            runs.push_back({estimator, radius});
    if (base.stem_estimator == vision::StemEstimator::robust)
        runs.push_back({vision::StemEstimator::robust, base.closing_radius_px});

    std::vector<SweepRow> rows;
    for (const Run& run : runs) {
        vision::Params params = base;
        params.closing_radius_px = run.radius_px;
        params.stem_estimator = run.estimator;
        if (run.estimator == vision::StemEstimator::paper) {
            params.defect_depth_mm = 10 * base.gsd_mm_per_px;
            params.defect_depth_rel = 0;
            params.min_intersection_angle_deg = 0;
        }
        std::vector<eval::StemPoint> predictions;
        auto detections = std::make_unique<vision::Detections>();
        std::unique_ptr<vision::Workspace> workspace;
        for (std::size_t i = 0; i < frames.size(); ++i) {
            const auto& f = frames[i];
            const cv::Size size = base.segmentation == vision::Segmentation::mask ? f.mask.size() : f.bgr.size();
            if (!workspace || workspace->frame_size() != size)
                workspace = std::make_unique<vision::Workspace>(size, params);
            vision::detect({.bgr = f.bgr, .nir = f.nir, .mask = f.mask}, params, *workspace, *detections);
            if (detections->status != vision::DetectStatus::ok)
                return fail(jobs[i].image + ": " + std::string(vision::to_string(detections->status)));
            for (const auto& p : detections->plants)
                if (p.has_stem)
                    predictions.push_back({jobs[i].image, p.stem.x, p.stem.y});
        }
        SweepRow row;
        const char* name = run.estimator == vision::StemEstimator::com     ? "centre of mass"
                           : run.estimator == vision::StemEstimator::paper ? "paper"
                                                                           : "robust";
        row.approach = std::string(name) + ", m=" + std::to_string(run.radius_px);
        row.radius_px = run.radius_px;
        row.estimator = run.estimator;
        row.result = eval::match_stems(*gt, predictions, args.tol_mm, base.gsd_mm_per_px);
        rows.push_back(row);
    }
    if (args.json) {
        Json json_rows = Json::array();
        for (const auto& r : rows)
            json_rows.push_back({{"method", std::string(vision::to_string(r.estimator))},
                                 {"closing_radius_px", r.radius_px},
                                 {"recall", json_number(r.result.recall)},
                                 {"precision", json_number(r.result.precision)},
                                 {"f1", json_number(r.result.f1)},
                                 {"mean_error_mm", json_number(r.result.mean_error_mm)}});
        print_json({{"tol_mm", json_number(args.tol_mm)},
                    {"gsd_mm_per_px", json_number(base.gsd_mm_per_px)},
                    {"frames", frames.size()},
                    {"ground_truth", gt->size()},
                    {"rows", std::move(json_rows)}});
        return kOk;
    }
    std::printf("%zu frames, %zu ground-truth stems, tolerance %s mm at %s mm/px\n", frames.size(), gt->size(),
                number(args.tol_mm).c_str(), number(base.gsd_mm_per_px).c_str());
    std::printf("%-22s %8s %10s %8s %11s\n", "approach", "recall", "precision", "F1", "error (mm)");
    for (const auto& r : rows)
        std::printf("%-22s %7.1f%% %9.1f%% %7.1f%% %11.2f\n", r.approach.c_str(), 100 * r.result.recall,
                    100 * r.result.precision, 100 * r.result.f1, r.result.mean_error_mm);
    return kOk;
}

// --- targets -----------------------------------------------------------------

int run_targets(const Args& args)
{
    config::Config config;
    if (const auto config_error = config::build_config(args.config, config))
        return fail(config_error->to_string());
    const runtime::ActuationConfig actuation = config.settings().actuation;
    std::array<double, 16> offsets;
    offsets.fill(std::numeric_limits<double>::quiet_NaN());
    std::array<double, 16> latencies{};
    for (const auto& tool : actuation.tools) {
        offsets[tool.id & 15U] = tool.offset_mm;
        latencies[tool.id & 15U] = tool.latency_ms;
    }
    const auto ids = stemd::protocol::CanIds::make(actuation.can_base_id);
    if (!ids)
        return fail("can.base_id " + std::to_string(actuation.can_base_id) + " is too large");
    std::string error;
    auto plants = eval::read_truth_plants(args.positional[0], error);
    if (!plants)
        return fail(error);
    // Plants too small for the detector take no part: neither their commands
    // nor their absence count. A crop under --treat weeds does take part: a
    // command for it is an extra (a crop must never be struck).
    std::vector<eval::TruthPlant> too_small;
    for (const auto& p : *plants)
        if (p.radius_mm < args.min_radius_mm)
            too_small.push_back(p);
    std::erase_if(*plants, [&](const eval::TruthPlant& p) {
        return (args.treat_weeds_only && p.kind != PlantClass::Weed) || p.radius_mm < args.min_radius_mm;
    });
    const auto log = eval::read_target_log(args.positional[1], *ids, error);
    if (!log)
        return fail(error);
    // Scored where each command strikes: a tool with a latency was commanded
    // earlier by speed x latency (or the log's TOOL_FIRED says where it fired).
    const std::vector<double> all_leads = eval::target_leads_mm(*log, latencies, actuation.speed_mm_per_s);
    std::vector<stemd::protocol::TargetCommand> commands;
    std::vector<double> leads;
    for (std::size_t i = 0; i < log->targets.size(); ++i) {
        const std::array<stemd::protocol::TargetCommand, 1> one{log->targets[i]};
        const std::array<double, 1> lead{all_leads[i]};
        if (eval::score_targets(too_small, one, offsets, args.tol_mm, lead).matched == 0) {
            commands.push_back(log->targets[i]);
            leads.push_back(all_leads[i]);
        }
    }
    const eval::TargetScore s = eval::score_targets(*plants, commands, offsets, args.tol_mm, leads);
    const double per_plant = s.plants > 0 ? static_cast<double>(s.matched + s.duplicates) / static_cast<double>(s.plants) : 0;
    if (args.json) {
        print_json({{"plants", s.plants},
                    {"commands", s.commands},
                    {"matched", s.matched},
                    {"missed", s.missed},
                    {"duplicates", s.duplicates},
                    {"extra", s.extra},
                    {"bad_targets", log->bad_targets},
                    {"commands_per_plant", json_number(per_plant)},
                    {"error_p50_mm", json_number(s.error_p50_mm)},
                    {"error_p95_mm", json_number(s.error_p95_mm)},
                    {"error_max_mm", json_number(s.error_max_mm)},
                    {"along_p50_mm", json_number(s.along_p50_mm)},
                    {"lateral_p50_mm", json_number(s.lateral_p50_mm)},
                    {"tol_mm", json_number(args.tol_mm)},
                    {"exact", s.exact()}});
    } else {
        std::cout << "plants to treat  " << s.plants << (args.treat_weeds_only ? " (weeds)" : "") << "\n"
                  << "TARGET commands  " << s.commands << " counted of " << log->targets.size() << " in the log ("
                  << log->targets.size() - s.commands << " for plants under --min-radius-mm, " << log->bad_targets
                  << " undecodable, " << log->other_frames << " other frames)\n"
                  << "matched          " << s.matched << " plants within " << number(args.tol_mm) << " mm\n"
                  << "missed           " << s.missed << " plants without a command\n"
                  << "duplicates       " << s.duplicates << " second commands for a plant\n"
                  << "extra            " << s.extra << " commands near no plant"
                  << (s.unknown_tool ? " (" + std::to_string(s.unknown_tool) + " for unknown tools)" : "") << "\n"
                  << "commands/plant   " << fixed(per_plant, 3) << "\n"
                  << "position error   p50 " << fixed(s.error_p50_mm, 2) << " p95 " << fixed(s.error_p95_mm, 2)
                  << " max " << fixed(s.error_max_mm, 2) << " mm (along p50 " << fixed(s.along_p50_mm, 2)
                  << ", lateral p50 " << fixed(s.lateral_p50_mm, 2) << ")\n";
    }
    if (args.require_exact && !s.exact()) {
        std::cerr << "stemd-eval: not exactly one command per plant (missed " << s.missed << ", duplicates "
                  << s.duplicates << ", extra " << s.extra << ")\n";
        return 1;
    }
    return kOk;
}

int run(const Args& args)
{
    switch (args.mode) {
    case Mode::stems:
        return run_stems(args);
    case Mode::iou:
        return run_iou(args);
    case Mode::classes:
        return run_classes(args);
    case Mode::sweep:
        return run_sweep(args);
    case Mode::targets:
        return run_targets(args);
    }
    return fail("internal error: unknown mode");
}

}  // namespace

int main(int argc, char** argv)
{
    Args args;
    if (const auto exit_code = parse_args(argc, argv, args))
        return *exit_code;
    std::string error;
    if (!check_mode(args, error))
        return tools::usage_error(kCommandLine, error);
    try {
        return run(args);
    } catch (const std::exception& e) {  // e.g. cv::Exception, std::bad_alloc
        return fail(e.what());
    }
}
