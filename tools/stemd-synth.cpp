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
#include <charconv>
#include <iterator>
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

namespace fs = std::filesystem;
using namespace stemd;

namespace {

constexpr int kUsageError = 2;
constexpr int kWriteError = 1;
constexpr int kMaxFrames = 1000000;   // file names have six digits

const char* const kUsage =
    "usage: stemd-synth --out DIR [--preset early|late|dense|seedling] [--frames N] [--seed S]\n"
    "                   [--fragment F] [--width W] [--height H] [--gsd-mm-per-px G] [--fps FPS]\n"
    "       stemd-synth --strip --out DIR [--length-mm L] [--speed-kmh V] [--fps FPS]\n"
    "                   [--preset P] [--seed S] [--fragment F] [--width W] [--height H] [--gsd-mm-per-px G]\n"
    "  --out             recording directory to write (created if missing)\n"
    "  --preset          early (small crops, tiny weeds), late (default: medium crops),\n"
    "                    dense (many crops, weeds, grass, fragmented masks),\n"
    "                    seedling (~1 % vegetation on dark cloddy soil, a real camera's\n"
    "                    exposure, colour cast, vignetting, gain noise and colour fringes)\n"
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

// Every option but --strip takes a value.
constexpr std::string_view kOptions[] = {"--out",   "--preset", "--frames",         "--seed", "--fragment",
                                         "--width", "--height", "--gsd-mm-per-px", "--fps",  "--gsd",
                                         "--length-mm", "--speed-kmh"};

struct Args {
    fs::path out;
    synth::Options options;
    int frames = 10;
    double fps = 10;
    bool strip = false;
    bool frames_set = false;
    bool fps_set = false;
    bool strip_only_set = false;   // --length-mm or --speed-kmh given
    double length_mm = 3000;
    double speed_kmh = 5;
};

template <typename T>
bool parse_number(std::string_view text, T& out)
{
    const char* end = text.data() + text.size();
    const auto [ptr, ec] = std::from_chars(text.data(), end, out);
    return ec == std::errc() && ptr == end;
}

// Each option's value check; false + error on a bad value.
bool apply_option(Args& args, const std::string& name, const std::string& value, std::string& error)
{
    auto bad = [&](const char* what) {
        error = name + " " + value + ": " + what;
        return false;
    };
    synth::Options& o = args.options;
    if (name == "--out") {
        if (value.empty()) return bad("must not be empty");
        args.out = value;
    } else if (name == "--preset") {
        const auto preset = synth::parse_preset(value);
        if (!preset) return bad("expected early, late or dense");
        o.preset = *preset;
    } else if (name == "--frames") {
        if (!parse_number(value, args.frames) || args.frames < 1 || args.frames > kMaxFrames)
            return bad("expected an integer 1..1000000");
        args.frames_set = true;
    } else if (name == "--seed") {
        if (!parse_number(value, o.seed)) return bad("expected an unsigned 64-bit integer");
    } else if (name == "--fragment") {
        if (!parse_number(value, o.fragmentation) || !(o.fragmentation >= 0 && o.fragmentation <= 1))
            return bad("expected a number 0..1");
    } else if (name == "--width" || name == "--height") {
        int& px = name == "--width" ? o.width_px : o.height_px;
        if (!parse_number(value, px) || px < 16 || px > 32768) return bad("expected an integer 16..32768");
    } else if (name == "--gsd-mm-per-px" || name == "--gsd") {
        if (!parse_number(value, o.gsd_mm_per_px) || !(o.gsd_mm_per_px > 0 && o.gsd_mm_per_px <= 100))
            return bad("expected a number in (0, 100]");
    } else if (name == "--fps") {
        if (!parse_number(value, args.fps) || !(args.fps > 0 && args.fps <= 1e6))
            return bad("expected a number in (0, 1000000]");
        args.fps_set = true;
    } else if (name == "--length-mm") {
        if (!parse_number(value, args.length_mm) || !(args.length_mm > 0 && args.length_mm <= 1e6))
            return bad("expected a number in (0, 1000000]");
        args.strip_only_set = true;
    } else if (name == "--speed-kmh") {
        if (!parse_number(value, args.speed_kmh) || !(args.speed_kmh > 0 && args.speed_kmh <= 1000))
            return bad("expected a number in (0, 1000]");
        args.strip_only_set = true;
    } else {
        error = "unknown option " + name;
        return false;
    }
    return true;
}

std::optional<Args> parse_args(int argc, char** argv, std::string& error)
{
    Args args;
    for (int i = 1; i < argc; ++i) {
        const std::string name = argv[i];
        if (name == "--strip") {
            args.strip = true;
            continue;
        }
        if (name.rfind("--", 0) != 0) {
            error = "unexpected argument " + name;
            return std::nullopt;
        }
        if (std::find(std::begin(kOptions), std::end(kOptions), name) == std::end(kOptions)) {
            error = "unknown option " + name;
            return std::nullopt;
        }
        if (i + 1 >= argc) {
            error = name + " needs a value";
            return std::nullopt;
        }
        if (!apply_option(args, name, argv[++i], error))
            return std::nullopt;
    }
    if (args.out.empty()) {
        error = "--out DIR is required";
        return std::nullopt;
    }
    if (args.strip && args.frames_set) {
        error = "--frames does not go with --strip (the strip's length and speed set the frames)";
        return std::nullopt;
    }
    if (!args.strip && args.strip_only_set) {
        error = "--length-mm and --speed-kmh need --strip";
        return std::nullopt;
    }
    if (args.strip && !args.fps_set)
        args.fps = 30;
    if (args.strip && args.fps > 10000) {
        error = "--fps " + std::to_string(args.fps) + ": --strip takes at most 10000";
        return std::nullopt;
    }
    return args;
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

std::string fixed(double value, int decimals)
{
    char text[64];
    std::snprintf(text, sizeof text, "%.*f", decimals, value);
    return text;
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
    for (int i = 1; i < argc; ++i) {
        const std::string_view a = argv[i];
        if (a == "--help" || a == "-h") {
            std::cout << kUsage;
            return 0;
        }
    }
    std::string error;
    const auto args = parse_args(argc, argv, error);
    if (!args) {
        std::cerr << "stemd-synth: " << error << " (see --help)\n";
        return kUsageError;
    }
    return args->strip ? run_strip(*args) : run(*args);
}
