#include "stemd/runtime/config_schema.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <system_error>

namespace stemd::config {

namespace {

// Concatenation without "literal" + std::string&&, which GCC 12 at -O3
// misreports under -Wrestrict.
template <class... Parts>
std::string cat(const Parts&... parts)
{
    std::string out;
    (out.append(std::string_view(parts)), ...);
    return out;
}

using enum ValueType;

// Later issues add capture/CAN/actuator sections: append rows, keep each
// section's rows together.
constexpr std::array kSchema{
    KeySpec{"camera.gsd_mm_per_px", real, "mm/px", 0.01, 10, "0.33", "",
            "ground sampling distance: millimetres of ground per image pixel"},
    // --- camera geometry (issue 5): machine frame x forward, y left, mm ---
    KeySpec{"camera.model", choice, "", 0, 0, "nadir", "nadir|calibrated",
            "nadir: straight down at camera.gsd_mm_per_px; calibrated: OpenCV calibration file plus the pose below"},
    KeySpec{"camera.forward", choice, "", 0, 0, "up", "up|down|left|right",
            "which image direction points in the direction of travel (up: plants move down the image)"},
    KeySpec{"camera.calibration_file", text, "", 0, 0, "none", "",
            "calibrated: OpenCV calibration YAML (camera_matrix, distortion_coefficients, image_width, image_height); none: not set"},
    KeySpec{"camera.height_mm", real, "mm", 10, 5000, "500", "",
            "calibrated: height of the optical centre above the ground"},
    KeySpec{"camera.roll_deg", real, "deg", -45, 45, "0", "",
            "calibrated: tilt about machine x; > 0 tilts the optical axis to the left"},
    KeySpec{"camera.pitch_deg", real, "deg", -45, 45, "0", "",
            "calibrated: tilt about machine y; > 0 tilts the optical axis forward"},
    KeySpec{"camera.yaw_deg", real, "deg", -180, 180, "0", "",
            "calibrated: turn about the vertical; > 0 counter-clockwise seen from above"},
    KeySpec{"camera.x_mm", real, "mm", -5000, 5000, "0", "",
            "machine-frame x (forward) of the principal point's ground position (where the optical axis meets the ground)"},
    KeySpec{"camera.y_mm", real, "mm", -5000, 5000, "0", "",
            "machine-frame y (left) of the principal point's ground position"},
    // --- end camera geometry ---

    KeySpec{"segment.method", choice, "", 0, 0, "exg", "exg|ndvi|mask",
            "vegetation index: Excess Green (RGB), NDVI (RGB+NIR) or an external mask"},
    KeySpec{"segment.threshold", choice, "", 0, 0, "otsu", "otsu|triangle|min_error",
            "automatic threshold on the vegetation index"},
    KeySpec{"segment.mask_vegetation", choice, "", 0, 0, "nonzero", "nonzero|zero",
            "which pixel value of an external mask is vegetation"},

    KeySpec{"closing.radius_px", integer, "px", 0, 50, "5", "",
            "radius m of the elliptic closing kernel (size 2m+1); 0 disables closing"},

    KeySpec{"plants.min_area_mm2", real, "mm2", 0, 100000, "10", "",
            "plants with a smaller area are dropped as noise"},

    KeySpec{"leaves.defect_depth_mm", real, "mm", 0.1, 100, "1", "",
            "convexity defects deeper than this cut the contour into leaves (the paper: 3.3)"},
    KeySpec{"leaves.defect_depth_rel", real, "fraction", 0, 1, "0.15", "",
            "defects must also be deeper than this fraction of the plant's equivalent radius sqrt(area/pi)"},

    KeySpec{"stem.method", choice, "", 0, 0, "robust", "robust|paper|com",
            "stem estimator: robust (least-squares point of the leaf lines), paper (mean of their intersections) or com (centre of mass)"},
    KeySpec{"stem.min_leaves", integer, "count", 2, 16, "3", "",
            "paper estimator: the paper's N, plants with fewer leaves use the centre of mass"},
    KeySpec{"stem.min_angle_deg", real, "deg", 0, 45, "0", "",
            "paper estimator: pairs of leaf lines meeting at a smaller angle are skipped (0: only exactly parallel ones, as in the paper)"},
    KeySpec{"stem.min_confidence", real, "fraction", 0, 1, "0.05", "",
            "plants whose stem confidence is lower are reported without a stem"},
    KeySpec{"stem.grass_min_area_mm2", real, "mm2", 0, 100000, "100", "",
            "robust estimator: plants at least this large and thinner than stem.grass_max_width_mm are grass, without a stem"},
    KeySpec{"stem.grass_max_width_mm", real, "mm", 0, 100, "3", "",
            "robust estimator: mean width (2 area / perimeter) below which a large plant is grass; 0 disables"},

    // The daemon (stemd): frame source, rings, threads, status, logging.
    KeySpec{"source.kind", choice, "", 0, 0, "replay", "replay|v4l2|libcamera",
            "where frames come from: a recording, a V4L2 camera, or a libcamera camera; --replay DIR picks replay"},
    KeySpec{"source.replay_dir", text, "", 0, 0, "none", "",
            "recording directory (frames.csv) to replay; none: not set (--replay DIR sets it)"},
    KeySpec{"source.replay_pacing", choice, "", 0, 0, "recorded", "recorded|fast",
            "recorded: deliver frames at their t_ns; fast: as fast as the pipeline takes them, dropping none"},
    KeySpec{"source.replay_loop", boolean, "", 0, 0, "true", "",
            "start the recording over at its end (--once: play it once, then exit)"},
    KeySpec{"source.replay_preload", boolean, "", 0, 0, "false", "",
            "decode every frame at start (needs frames x frame size of memory); capture then only copies"},
    KeySpec{"source.width_px", integer, "px", 16, 8192, "1296", "",
            "frame width; the frame slots are allocated for it, other sizes are skipped and counted"},
    KeySpec{"source.height_px", integer, "px", 16, 8192, "966", "",
            "frame height; the frame slots are allocated for it, other sizes are skipped and counted"},
    KeySpec{"source.v4l2_device", text, "", 0, 0, "/dev/video0", "",
            "v4l2: the video capture device node (mmap streaming, source.width_px x source.height_px)"},
    KeySpec{"source.v4l2_pixel_format", choice, "", 0, 0, "yuyv", "yuyv|bgr24|grey",
            "v4l2: pixel format asked of the camera, converted to BGR (grey: B = G = R)"},
    KeySpec{"source.v4l2_buffers", integer, "count", 2, 32, "4", "",
            "v4l2: mmap buffers asked of the driver"},
    KeySpec{"source.fps", real, "fps", 1, 240, "30", "",
            "v4l2: frame rate asked of the camera (VIDIOC_S_PARM); a camera that cannot set one keeps its own"},
    // --- libcamera source (drivers/libcamera) ---
    KeySpec{"source.libcamera_camera", text, "", 0, 0, "0", "",
            "libcamera: the camera, by index in libcamera's list, by id, or by a part of the id matching one camera"},
    // --- end libcamera source

    KeySpec{"ring.capacity", integer, "frames", 1, 64, "4", "",
            "captured frames waiting for the processing thread (slots: capacity + 2)"},
    KeySpec{"ring.overflow", choice, "", 0, 0, "drop_newest", "drop_newest|overwrite_oldest",
            "when the frame ring is full: drop the new frame, or replace the oldest waiting one (both counted)"},
    KeySpec{"ring.results_capacity", integer, "frames", 1, 64, "4", "",
            "detection results waiting for the actuator thread; a full ring drops the result (counted)"},

    KeySpec{"threads.capture_priority", integer, "priority", 0, 99, "0", "",
            "SCHED_FIFO priority of the capture thread; 0 keeps the normal scheduler"},
    KeySpec{"threads.processing_priority", integer, "priority", 0, 99, "0", "",
            "SCHED_FIFO priority of the processing thread; 0 keeps the normal scheduler"},
    KeySpec{"threads.actuator_priority", integer, "priority", 0, 99, "0", "",
            "SCHED_FIFO priority of the actuator thread; 0 keeps the normal scheduler"},
    KeySpec{"threads.capture_cpu", integer, "cpu", -1, 1023, "-1", "",
            "CPU the capture thread is pinned to; -1: any"},
    KeySpec{"threads.processing_cpu", integer, "cpu", -1, 1023, "-1", "",
            "CPU the processing thread is pinned to; -1: any"},
    KeySpec{"threads.actuator_cpu", integer, "cpu", -1, 1023, "-1", "",
            "CPU the actuator thread is pinned to; -1: any"},
    KeySpec{"threads.mlockall", boolean, "", 0, 0, "false", "",
            "lock all current and future memory (mlockall) so that page faults cannot stall the threads"},

    KeySpec{"status.interval_s", real, "s", 0.1, 3600, "5", "",
            "seconds between status lines (fps, drops, latency, pipeline time)"},

    KeySpec{"log.level", choice, "", 0, 0, "info", "trace|debug|info|warn|error",
            "log level of every logger (debug: one line per frame's detections)"},
};

}  // namespace

std::string_view to_string(ValueType type)
{
    switch (type) {
    case integer: return "integer";
    case real: return "real";
    case choice: return "choice";
    case boolean: return "boolean";
    case text: return "text";
    }
    return "?";
}

std::span<const KeySpec> schema()
{
    return kSchema;
}

const KeySpec* find_key(std::string_view key)
{
    for (const KeySpec& spec : kSchema)
        if (spec.key == key)
            return &spec;
    return nullptr;
}

bool is_choice(const KeySpec& spec, std::string_view value)
{
    std::string_view rest = spec.choices;
    while (!rest.empty()) {
        const std::size_t bar = rest.find('|');
        if (rest.substr(0, bar) == value)
            return true;
        if (bar == std::string_view::npos)
            break;
        rest.remove_prefix(bar + 1);
    }
    return false;
}

std::string list_choices(const KeySpec& spec, std::string_view separator)
{
    std::string out;
    for (const char c : spec.choices) {
        if (c == '|')
            out += separator;
        else
            out += c;
    }
    return out;
}

std::string format_number(double value)
{
    // Plain shortest to_chars prefers "1e+05" to "100000"; fixed notation
    // (still the shortest that reads back exactly) where it stays readable.
    std::array<char, 400> buffer{};
    const double magnitude = std::fabs(value);
    const bool fixed = magnitude == 0.0 || (magnitude >= 1e-6 && magnitude < 1e15);
    const auto [end, ec] = fixed
        ? std::to_chars(buffer.data(), buffer.data() + buffer.size(), value, std::chars_format::fixed)
        : std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
    if (ec != std::errc())
        return "?";
    return std::string(buffer.data(), end);
}

std::string schema_markdown()
{
    std::string out =
        "| key | type | unit | default | range / choices | meaning |\n"
        "|---|---|---|---|---|---|\n";
    for (const KeySpec& spec : kSchema) {
        std::string range;
        if (spec.type == integer || spec.type == real)
            range = cat("[", format_number(spec.min), ", ", format_number(spec.max), "]");
        else if (spec.type == choice)
            range = cat("`", list_choices(spec, "`, `"), "`");
        else if (spec.type == boolean)
            range = "`true`, `false`";
        out += "| `";
        out += spec.key;
        out += "` | ";
        out += to_string(spec.type);
        out += " | ";
        out += spec.unit;
        out += " | `";
        out += spec.default_value;
        out += "` | ";
        out += range;
        out += " | ";
        out += spec.help;
        out += " |\n";
    }
    return out;
}

}  // namespace stemd::config
