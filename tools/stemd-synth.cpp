// stemd-synth: writes a recording directory of synthetic field frames with
// ground truth, for stemd-detect, stemd-eval and the daemon's replay.
//   DIR/frames.csv   t_ns,rgb,nir,mask   (see stemd/io/recording.hpp)
//   DIR/stems.csv    image,x,y,kind,leaves   (image = the rgb path in frames.csv)
//   DIR/rgb/NNNNNN.png, DIR/nir/NNNNNN.png, DIR/mask/NNNNNN.png
// With --strip, a moving field strip (see synth::generate_strip):
//   DIR/frames.csv   t_ns,rgb,nir,mask,odom_mm,class
//   DIR/stems.csv    as above: per-frame truth
//   DIR/plants.csv   id,s_mm,y_mm,kind,leaves,radius_mm   (field coordinates)
//   DIR/strip.txt    the parameters (gsd, speed, fps, camera pose)
//   DIR/class/NNNNNN.png   0 soil, 1 crop, 2 weed (grass too)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <opencv2/core.hpp>

#include "stemd/io/csv.hpp"
#include "stemd/io/recording_writer.hpp"
#include "stemd/synth/synth.hpp"
#include "tool_cli.hpp"

namespace fs = std::filesystem;
using namespace stemd;

namespace {

using tools::fixed;
using tools::kUsageError;
constexpr int kWriteError = 1;
constexpr int kMaxFrames = 1000000;   // file names have six digits

const char* const kUsage =
    "usage: stemd-synth --out DIR [--preset early|late|dense|seedling|canopy] [--frames N] [--seed S]\n"
    "                   [--fragment F] [--width W] [--height H] [--gsd-mm-per-px G] [--fps FPS]\n"
    "       stemd-synth --strip --out DIR [--length-mm L] [--speed-kmh V] [--fps FPS]\n"
    "                   [--preset P] [--seed S] [--fragment F] [--width W] [--height H] [--gsd-mm-per-px G]\n"
    "  --out             recording directory to write (created if missing)\n"
    "  --preset          early (small crops, tiny weeds), late (default: medium crops),\n"
    "                    dense (many crops, weeds, grass, fragmented masks),\n"
    "                    seedling (~1 % vegetation on dark cloddy soil, a real camera's\n"
    "                    exposure, colour cast, vignetting, gain noise and colour fringes),\n"
    "                    canopy (large plants overlapping, leaves over most of the soil,\n"
    "                    the same real camera)\n"
    "  --frames          number of frames, 1..1000000 (default 10)\n"
    "  --seed            unsigned 64-bit seed (default 1); same seed, same bytes\n"
    "  --fragment        mask fragmentation 0..1 (default: the preset's)\n"
    "  --width/--height  image size in px, 16..32768 (default 1296 x 966)\n"
    "  --gsd-mm-per-px   ground sampling distance, mm per px (default 0.33)\n"
    "  --fps             frame rate for the t_ns column (default 10; --strip: 30)\n"
    "  --gsd             the same as --gsd-mm-per-px\n"
    "  --strip           a moving field strip instead of independent frames: a nadir camera\n"
    "                    (forward = image up, at machine x = 0, y = 0) driving along one strip;\n"
    "                    frames.csv gets odom_mm and class (class/NNNNNN.png: 0 soil, 1 crop,\n"
    "                    2 weed) columns, plants.csv (id,s_mm,y_mm,kind,leaves,radius_mm) the\n"
    "                    plants in field coordinates, strip.txt the parameters\n"
    "  --length-mm       --strip: length of the planted strip, mm (default 3000)\n"
    "  --speed-kmh       --strip: driving speed, km/h (default 5)\n";

struct Args {
    fs::path out;
    synth::Options options;
    int frames = 10;
    double fps = 10;
    bool strip = false;
    double length_mm = 3000;
    double speed_kmh = 5;
};

const tools::CommandLine kCommandLine{.tool = "stemd-synth", .usage = kUsage, .after = " (see --help)"};

// A number in (0, max].
CLI::Validator up_to(double max, const std::string& what)
{
    return tools::value_check<double>(what, [max](double v) { return v > 0 && v <= max; });
}

// The arguments into `args`; the exit code after --help or a usage error.
std::optional<int> parse_args(int argc, char** argv, Args& args)
{
    synth::Options& o = args.options;
    CLI::App app{"stemd-synth"};
    std::string out;
    app.add_option("--out", out)->check(CLI::Validator(
        [](std::string& dir) { return dir.empty() ? std::string("must not be empty") : std::string(); }, "DIR"));
    app.add_option_function<std::string>("--preset", [&](const std::string& name) { o.preset = *synth::parse_preset(name); })
        ->check(CLI::Validator(
            [](std::string& name) {
                return synth::parse_preset(name) ? std::string() : "'" + name + "' is not early, late, dense, seedling or canopy";
            },
            "PRESET"));
    CLI::Option* const frames = app.add_option("--frames", args.frames)
        ->check(tools::value_check<int>("an integer 1..1000000", [](int n) { return n >= 1 && n <= kMaxFrames; }));
    app.add_option("--seed", o.seed)
        ->check(tools::value_check<std::uint64_t>("an unsigned 64-bit integer", [](std::uint64_t) { return true; }));
    app.add_option("--fragment", o.fragmentation)
        ->check(tools::value_check<double>("a number 0..1", [](double f) { return f >= 0 && f <= 1; }));
    const auto size_px = tools::value_check<int>("an integer 16..32768", [](int px) { return px >= 16 && px <= 32768; });
    app.add_option("--width", o.width_px)->check(size_px);
    app.add_option("--height", o.height_px)->check(size_px);
    app.add_option("--gsd-mm-per-px,--gsd", o.gsd_mm_per_px)->check(up_to(100, "a number in (0, 100]"));
    CLI::Option* const fps = app.add_option("--fps", args.fps)->check(up_to(1e6, "a number in (0, 1000000]"));
    CLI::Option* const length = app.add_option("--length-mm", args.length_mm)->check(up_to(1e6, "a number in (0, 1000000]"));
    CLI::Option* const speed = app.add_option("--speed-kmh", args.speed_kmh)->check(up_to(1000, "a number in (0, 1000]"));
    app.add_flag("--strip", args.strip);
    if (const auto exit_code = tools::parse(app, argc, argv, kCommandLine))
        return *exit_code;
    args.out = out;
    if (args.out.empty())
        return tools::usage_error(kCommandLine, "--out DIR is required");
    if (args.strip && frames->count() > 0)
        return tools::usage_error(kCommandLine,
                                  "--frames does not go with --strip (the strip's length and speed set the frames)");
    if (!args.strip && (length->count() > 0 || speed->count() > 0))
        return tools::usage_error(kCommandLine, "--length-mm and --speed-kmh need --strip");
    if (args.strip && fps->count() == 0)
        args.fps = 30;
    if (args.strip && args.fps > 10000)
        return tools::usage_error(kCommandLine, "--fps " + std::to_string(args.fps) + ": --strip takes at most 10000");
    return std::nullopt;
}

bool write_text(const fs::path& path, const std::string& text, std::string& error)
{
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << text;
    out.close();
    if (!out) {
        error = path.string() + ": cannot write";
        return false;
    }
    return true;
}

std::string stem_row(const std::string& image, const synth::GroundTruthStem& stem)
{
    char xy[64];
    std::snprintf(xy, sizeof xy, "%.2f,%.2f", stem.x_px, stem.y_px);
    return io::csv_field(image) + "," + xy + "," + io::csv_field(to_string(stem.kind)) + "," + std::to_string(stem.leaves) + "\n";
}

struct Totals {
    int crops = 0;
    int weeds = 0;
};

int run(const Args& args)
{
    std::string error;
    io::RecordingWriter writer;
    if (!writer.open(args.out, {.columns = {.nir = true, .mask = true}}, error)) {
        std::cerr << "stemd-synth: " << error << "\n";
        return kWriteError;
    }
    std::string stems_csv = "image,x,y,kind,leaves\n";
    Totals totals;
    for (int i = 0; i < args.frames; ++i) {
        const synth::Frame frame = synth::generate_frame(args.options, i);
        const auto t_ns = std::llround(static_cast<double>(i) * 1e9 / args.fps);
        if (!writer.append({.t_ns = t_ns, .bgr = frame.bgr, .nir = frame.nir, .mask = frame.mask}, error)) {
            std::cerr << "stemd-synth: " << error << "\n";
            return kWriteError;
        }
        for (const synth::GroundTruthStem& stem : frame.stems) {
            stems_csv += stem_row(writer.last_written().rgb, stem);
            (stem.kind == PlantClass::Crop ? totals.crops : totals.weeds) += 1;
        }
    }
    if (!write_text(args.out / "stems.csv", stems_csv, error)) {
        std::cerr << "stemd-synth: " << error << "\n";
        return kWriteError;
    }
    std::cout << "stemd-synth: wrote " << args.frames << " frames (" << synth::to_string(args.options.preset)
              << ", seed " << args.options.seed << "): " << totals.crops << " crops, " << totals.weeds
              << " weeds in " << args.out.string() << "\n";
    return 0;
}

// Shortest text that reads back as the same double.
std::string exact(double value)
{
    char text[64];
    const auto [end, ec] = std::to_chars(text, text + sizeof text, value);
    return ec == std::errc() ? std::string(text, end) : std::string("nan");
}

int run_strip(const Args& args)
{
    const auto t_start = std::chrono::steady_clock::now();
    std::string error;
    auto fail = [&] {
        std::cerr << "stemd-synth: " << error << "\n";
        return kWriteError;
    };
    const synth::Options& o = args.options;
    const synth::StripOptions options{.preset = o.preset,
                                      .seed = o.seed,
                                      .length_mm = args.length_mm,
                                      .width_px = o.width_px,
                                      .height_px = o.height_px,
                                      .gsd_mm_per_px = o.gsd_mm_per_px,
                                      .speed_kmh = args.speed_kmh,
                                      .fps = args.fps,
                                      .fragmentation = o.fragmentation};
    synth::Strip strip;
    try {
        strip = synth::generate_strip(options);
    } catch (const std::invalid_argument& e) {
        std::cerr << "stemd-synth: " << e.what() << "\n";
        return kUsageError;
    }
    io::RecordingWriter writer;
    // Low PNG compression: the frames are large and many.
    const io::RecordingWriterOptions recording{
        .columns = {.nir = true, .mask = true, .odom_mm = true, .plant_class = true}, .png_compression_level = 1};
    if (!writer.open(args.out, recording, error))
        return fail();
    std::string stems_csv = "image,x,y,kind,leaves\n";
    for (int k = 0; k < strip.frame_count; ++k) {
        const synth::StripFrame frame = synth::render_strip_frame(strip, k);
        if (!writer.append({.t_ns = frame.t_ns,
                            .bgr = frame.bgr,
                            .nir = frame.nir,
                            .mask = frame.mask,
                            .odom_mm = frame.odom_mm,
                            .plant_class = frame.plant_class},
                           error))
            return fail();
        for (const synth::GroundTruthStem& stem : frame.stems)
            stems_csv += stem_row(writer.last_written().rgb, stem);
    }
    std::string plants_csv = "id,s_mm,y_mm,kind,leaves,radius_mm\n";
    Totals totals;
    for (const synth::StripPlant& p : strip.plants) {
        plants_csv += std::to_string(p.id) + "," + exact(p.s_mm) + "," + exact(p.y_mm) + "," + std::string(to_string(p.kind)) + "," +
                      std::to_string(p.leaves) + "," + fixed(p.radius_mm, 2) + "\n";
        (p.kind == PlantClass::Crop ? totals.crops : totals.weeds) += 1;
    }
    const double last_odom_mm = strip.odom_mm(strip.frame_count - 1);
    std::string strip_txt =
        "# stemd-synth --strip: a nadir camera driving along a field strip.\n"
        "# A plant at field (s_mm, y_mm) (plants.csv; y left > 0) is in the frame with odometer o\n"
        "# (frames.csv odom_mm) at u = cx - y_mm / gsd, v = cy - (s_mm - o) / gsd,\n"
        "# c = ((width - 1) / 2, (height - 1) / 2).\n";
    strip_txt += "preset: " + std::string(synth::to_string(options.preset)) + "\n";
    strip_txt += "seed: " + std::to_string(options.seed) + "\n";
    strip_txt += "length_mm: " + exact(options.length_mm) + "\n";
    strip_txt += "width_mm: " + exact(strip.width_mm) + "\n";
    strip_txt += "lead_mm: " + exact(strip.lead_mm) + "\n";
    strip_txt += "speed_kmh: " + exact(options.speed_kmh) + "\n";
    strip_txt += "fps: " + exact(options.fps) + "\n";
    strip_txt += "frames: " + std::to_string(strip.frame_count) + "\n";
    strip_txt += "width_px: " + std::to_string(options.width_px) + "\n";
    strip_txt += "height_px: " + std::to_string(options.height_px) + "\n";
    strip_txt += "gsd_mm_per_px: " + exact(options.gsd_mm_per_px) + "\n";
    strip_txt += "camera.model: nadir\ncamera.forward: up\ncamera.x_mm: 0\ncamera.y_mm: 0\n";
    strip_txt += "plants: " + std::to_string(strip.plants.size()) + "\n";
    strip_txt += "grass_tufts: " + std::to_string(strip.grass_tufts) + "\n";
    if (!write_text(args.out / "stems.csv", stems_csv, error) ||
        !write_text(args.out / "plants.csv", plants_csv, error) ||
        !write_text(args.out / "strip.txt", strip_txt, error))
        return fail();
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    std::cout << "stemd-synth: wrote a " << fixed(options.length_mm / 1000, 2) << " m strip ("
              << synth::to_string(options.preset) << ", seed " << options.seed << "): " << strip.frame_count
              << " frames at " << exact(options.speed_kmh) << " km/h, " << exact(options.fps) << " fps (odometer 0.."
              << fixed(last_odom_mm, 1) << " mm), " << strip.plants.size() << " plants (" << totals.crops
              << " crops, " << totals.weeds << " weeds) in " << args.out.string() << " (" << fixed(seconds, 1)
              << " s)\n";
    return 0;
}

}  // namespace

int main(int argc, char** argv)
{
    Args args;
    if (const auto exit_code = parse_args(argc, argv, args))
        return *exit_code;
    return args.strip ? run_strip(args) : run(args);
}
