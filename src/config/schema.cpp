#include "stemd/config/schema.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <system_error>
#include <type_traits>
#include <vector>

#include "stemd/base/enum_names.hpp"
#include "stemd/config/config.hpp"
#include "stemd/config/settings.hpp"
#include "values.hpp"

namespace stemd::config {

namespace {

using base::cat;

using enum ValueType;

// --- binding a row to its Settings member ------------------------------------
// STEMD_KEY(daemon.fps) names a member of Settings, STEMD_ITEM(actuation.tools,
// lanes) a member of a list's items: a captureless lambda the row's store and
// load functions are generated from.
#define STEMD_KEY(path) [](auto& s, std::size_t) -> auto& { return s.path; }
#define STEMD_ITEM(list, member) [](auto& s, std::size_t item) -> auto& { return s.list[item].member; }

constexpr std::int64_t kNsPerMs = 1'000'000;

// Choices kept as a bool: false is the first word.
constexpr base::EnumName<bool> kReplayPacingNames[]{{false, "recorded"}, {true, "fast"}};
constexpr base::EnumName<bool> kLogClockNames[]{{false, "realtime"}, {true, "monotonic"}};
constexpr base::EnumName<bool> kActiveLowNames[]{{false, "high"}, {true, "low"}};

// The row of `rows` whose name (`name_of` the row) is `name`, or nullptr.
template <class Row, class NameOf>
const Row* find_named(std::span<const Row> rows, std::string_view name, NameOf name_of)
{
    const auto it = std::ranges::find(rows, name, name_of);
    return it == rows.end() ? nullptr : &*it;
}

// A text key whose default is "none" keeps "none" (not set) as "".
bool means_unset(const KeySpec& spec, std::string_view value)
{
    return spec.type == ValueType::text && spec.default_value == "none" && value == "none";
}

// spec.choices ("a|b|c"), one by one.
std::vector<std::string_view> choices_of(const KeySpec& spec)
{
    std::vector<std::string_view> out;
    for (std::string_view rest = spec.choices; !rest.empty();) {
        const std::size_t bar = std::min(rest.find('|'), rest.size());
        out.push_back(rest.substr(0, bar));
        rest.remove_prefix(std::min(bar + 1, rest.size()));
    }
    return out;
}

// A row bound to a bool, text, integer or real member. A real key bound to
// an integer member is scaled (ms -> ns with Scale = kNsPerMs). Scale is an
// integer: clang 14 (the fuzz build) takes no floating-point template argument.
template <auto Field, std::int64_t Scale = 1>
constexpr KeySpec bind(KeySpec spec)
{
    spec.store = [](const KeySpec& k, Settings& s, std::size_t item, const detail::ConfigValue& v) {
        auto& field = Field(s, item);
        using T = std::remove_cvref_t<decltype(field)>;
        if constexpr (std::is_same_v<T, bool>)
            field = v.boolean;
        else if constexpr (std::is_same_v<T, std::string>)
            field = means_unset(k, v.text) ? std::string() : v.text;
        else if constexpr (std::is_floating_point_v<T>)
            field = k.type == integer ? static_cast<T>(v.integer) : static_cast<T>(v.real * Scale);
        else
            field = k.type == real ? static_cast<T>(std::llround(v.real * Scale)) : static_cast<T>(v.integer);
    };
    spec.load = [](const KeySpec& k, const Settings& s, std::size_t item, detail::ConfigValue& v) {
        const auto& field = Field(s, item);
        using T = std::remove_cvref_t<decltype(field)>;
        if constexpr (std::is_same_v<T, bool>)
            v.boolean = field;
        else if constexpr (std::is_same_v<T, std::string>)
            v.text = field.empty() && means_unset(k, "none") ? std::string("none") : field;
        else if (k.type == real)
            v.real = static_cast<double>(field) / Scale;
        else
            v.integer = static_cast<long>(field);
    };
    return spec;
}

// A choice row bound to a member of any type: Table holds the member's
// values and their words (the enum's own word table).
template <auto Field, auto& Table>
constexpr KeySpec bind_choice(KeySpec spec)
{
    spec.store = [](const KeySpec&, Settings& s, std::size_t item, const detail::ConfigValue& v) {
        if (const auto value = base::value_of(Table, v.text))  // the loader has checked it is a choice
            Field(s, item) = *value;
    };
    spec.load = [](const KeySpec&, const Settings& s, std::size_t item, detail::ConfigValue& v) {
        v.text = base::name_of(Table, Field(s, item));
    };
    return spec;
}

// A word table's words as one "a|b|c" text, joined at compile time.
template <auto& Table>
struct JoinedWords {
    static constexpr std::size_t size = [] {
        std::size_t n = 0;
        for (const auto& entry : Table)
            n += entry.name.size() + 1;
        return n - 1;
    }();
    static constexpr std::array<char, size> chars = [] {
        std::array<char, size> out{};
        std::size_t at = 0;
        for (const auto& entry : Table) {
            if (at != 0)
                out[at++] = '|';
            for (const char c : entry.name)
                out[at++] = c;
        }
        return out;
    }();
    static constexpr std::string_view text{chars.data(), size};
};

// The rows' makers, one per kind of key: a row names only what its kind has.
template <auto Field, std::int64_t Scale = 1>
constexpr KeySpec real_key(std::string_view key, std::string_view unit, double min, double max,
                           std::string_view default_value, std::string_view help)
{
    return bind<Field, Scale>({key, real, unit, min, max, default_value, "", help});
}
template <auto Field>
constexpr KeySpec int_key(std::string_view key, std::string_view unit, double min, double max,
                          std::string_view default_value, std::string_view help)
{
    return bind<Field>({key, integer, unit, min, max, default_value, "", help});
}
template <auto Field>
constexpr KeySpec bool_key(std::string_view key, std::string_view default_value, std::string_view help)
{
    return bind<Field>({key, boolean, "", 0, 0, default_value, "", help});
}
template <auto Field>
constexpr KeySpec text_key(std::string_view key, std::string_view default_value, std::string_view help)
{
    return bind<Field>({key, text, "", 0, 0, default_value, "", help});
}
// A choice kept as its text (a std::string member).
template <auto Field>
constexpr KeySpec choice_key(std::string_view key, std::string_view default_value, std::string_view choices,
                             std::string_view help)
{
    return bind<Field>({key, choice, "", 0, 0, default_value, choices, help});
}
// A choice kept as a value of Table (an enum's word table): the choices are its words.
template <auto Field, auto& Table>
constexpr KeySpec enum_key(std::string_view key, std::string_view default_value, std::string_view help)
{
    return bind_choice<Field, Table>({key, choice, "", 0, 0, default_value, JoinedWords<Table>::text, help});
}

// One row per key; keep each section's rows together (the README table and
// config/stemd.yaml follow this order).
constexpr std::array kSchema{
    real_key<STEMD_KEY(daemon.vision.gsd_mm_per_px)>("camera.gsd_mm_per_px", "mm/px", 0.01, 10, "0.33",
        "ground sampling distance: millimetres of ground per image pixel"),
    // Camera geometry: machine frame x forward, y left, mm.
    enum_key<STEMD_KEY(camera.model), geometry::kModelKindNames>("camera.model", "nadir",
        "nadir: straight down at camera.gsd_mm_per_px; calibrated: OpenCV calibration file plus the pose below"),
    enum_key<STEMD_KEY(camera.mount.forward), geometry::kForwardNames>("camera.forward", "up",
        "which image direction points in the direction of travel (up: plants move down the image)"),
    text_key<STEMD_KEY(camera.calibration_file)>("camera.calibration_file", "none",
        "calibrated: OpenCV calibration YAML (camera_matrix, distortion_coefficients, image_width, image_height; stemd-calibrate writes one) or ROS camera_info YAML; none: not set"),
    real_key<STEMD_KEY(camera.pose.height_mm)>("camera.height_mm", "mm", 10, 5000, "500",
        "calibrated: height of the optical centre above the ground"),
    real_key<STEMD_KEY(camera.pose.roll_deg)>("camera.roll_deg", "deg", -45, 45, "0",
        "calibrated: tilt about machine x; > 0 tilts the optical axis to the left"),
    real_key<STEMD_KEY(camera.pose.pitch_deg)>("camera.pitch_deg", "deg", -45, 45, "0",
        "calibrated: tilt about machine y; > 0 tilts the optical axis forward"),
    real_key<STEMD_KEY(camera.pose.yaw_deg)>("camera.yaw_deg", "deg", -180, 180, "0",
        "calibrated: turn about the vertical; > 0 counter-clockwise seen from above"),
    real_key<STEMD_KEY(camera.mount.x_mm)>("camera.x_mm", "mm", -5000, 5000, "0",
        "machine-frame x (forward) of the principal point's ground position (where the optical axis meets the ground)"),
    real_key<STEMD_KEY(camera.mount.y_mm)>("camera.y_mm", "mm", -5000, 5000, "0",
        "machine-frame y (left) of the principal point's ground position"),

    enum_key<STEMD_KEY(daemon.vision.segmentation), vision::kSegmentationNames>("segment.method", "auto",
        "vegetation index: auto (exg_and_ndvi when the frames carry a NIR plane: a NIR camera (source.nir_device) or a recording with a nir column; chromatic_exg otherwise), chromatic Excess Green (RGB, exposure-invariant), Excess Green, NDVI (RGB+NIR), an external mask, or exg_and_ndvi (RGB+NIR: both chromatic Excess Green and NDVI above the soil)"),
    bool_key<STEMD_KEY(daemon.vision.leaf_colour)>("segment.leaf_colour", "true",
        "exg, chromatic_exg: a plant needs a core of pixels whose green-to-red ratio is at least 1.25 times the soil's in the same frame, as chlorophyll makes a leaf; yellowish clods are not. Relative to the soil, so a colour cast of the light or the white balance does not move it. A piece is also dropped as a colour fringe when, with the green plane slid one pixel some way, none of its pixels passes that test (its green was a bright edge's, misregistered)"),
    bool_key<STEMD_KEY(daemon.vision.smooth_index)>("segment.smooth", "true",
        "smooth the index with a 3x3 binomial kernel before the threshold"),
    bool_key<STEMD_KEY(daemon.vision.sparse_index)>("segment.sparse_index", "true",
        "exg, chromatic_exg (smoothed): compute the index in full only in 64 px tiles near vegetation found on every 8th row, the rest as soil (a piece at most about 5 rows tall between sampled rows, away from any plant, is missed); the threshold's histogram counts soil tiles from those rows, and every tile when vegetation fills a third of a camera-sized frame. false: every pixel"),
    enum_key<STEMD_KEY(daemon.vision.threshold), vision::kThresholdMethodNames>("segment.threshold", "above_soil",
        "automatic threshold on the vegetation index; above_soil: Otsu, but never within segment.soil_sigmas of the soil mode"),
    real_key<STEMD_KEY(daemon.vision.soil_sigmas)>("segment.soil_sigmas", "sigma", 1, 20, "5",
        "above_soil: the threshold lies at least this many soil standard deviations above the soil mode"),
    int_key<STEMD_KEY(daemon.vision.opening_radius_px)>("segment.opening_radius_px", "px", 0, 50, "1",
        "radius of the elliptic opening before the closing: removes specks and colour fringes; 0 disables"),
    int_key<STEMD_KEY(daemon.vision.edge_radius_px)>("segment.edge_radius_px", "px", 0, 50, "5",
        "exg, chromatic_exg: mixed pixels at a plant's edge: within this radius of the thresholded plant, a pixel is vegetation when its index lies above the halfway point between the soil mode and the mean of the plant pixels around it (at least half leaf) and beyond the soil's noise; 0 disables"),
    real_key<STEMD_KEY(daemon.vision.min_class_separation)>("segment.min_class_separation", "index", 0, 255, "12",
        "automatic thresholds: if the two classes' mean 8-bit index differs by less (ExG: 1 = 4 of 2G-R-B), the frame has no vegetation; 0 disables"),
    enum_key<STEMD_KEY(daemon.vision.mask_vegetation), vision::kMaskVegetationNames>(
        "segment.mask_vegetation", "nonzero",
        "which pixel value of an external mask is vegetation"),

    int_key<STEMD_KEY(daemon.vision.closing_radius_px)>("closing.radius_px", "px", 0, 50, "5",
        "radius m of the elliptic closing kernel (size 2m+1); 0 disables closing"),

    real_key<STEMD_KEY(daemon.vision.min_plant_area_mm2)>("plants.min_area_mm2", "mm2", 0, 100000, "10",
        "plants with a smaller area are dropped as noise"),
    real_key<STEMD_KEY(daemon.vision.group_gap_mm)>("plants.group_gap_mm", "mm", 0, 50, "6",
        "pieces of vegetation less than this far apart are grouped: a leaf whose petiole fell below the threshold joins the plant it points at, and pieces with leaves of their own stay plants; 0: every piece is a plant"),

    real_key<STEMD_KEY(daemon.vision.defect_depth_mm)>("leaves.defect_depth_mm", "mm", 0.1, 100, "1",
        "convexity defects deeper than this cut the contour into leaves (the paper: 3.3)"),
    real_key<STEMD_KEY(daemon.vision.defect_depth_rel)>("leaves.defect_depth_rel", "fraction", 0, 1, "0.15",
        "defects must also be deeper than this fraction of the plant's equivalent radius sqrt(area/pi)"),

    enum_key<STEMD_KEY(daemon.vision.stem_estimator), vision::kStemEstimatorNames>("stem.method", "robust",
        "stem estimator: robust (least-squares point of the leaf lines), paper (mean of their intersections) or com (centre of mass)"),
    int_key<STEMD_KEY(daemon.vision.min_leaves)>("stem.min_leaves", "count", 2, 16, "3",
        "paper estimator: the paper's N, plants with fewer leaves use the centre of mass"),
    real_key<STEMD_KEY(daemon.vision.min_intersection_angle_deg)>("stem.min_angle_deg", "deg", 0, 45, "0",
        "paper estimator: pairs of leaf lines meeting at a smaller angle are skipped (0: only exactly parallel ones, as in the paper)"),
    real_key<STEMD_KEY(daemon.vision.min_confidence)>("stem.min_confidence", "fraction", 0, 1, "0.05",
        "plants whose stem confidence is lower are reported without a stem"),
    real_key<STEMD_KEY(daemon.vision.grass_min_area_mm2)>("stem.grass_min_area_mm2", "mm2", 0, 100000, "100",
        "robust estimator: plants at least this large and thinner than stem.grass_max_width_mm are grass, without a stem"),
    real_key<STEMD_KEY(daemon.vision.grass_max_width_mm)>("stem.grass_max_width_mm", "mm", 0, 100, "3",
        "robust estimator: mean width (2 area / perimeter) below which a large plant is grass; 0 disables"),
    real_key<STEMD_KEY(daemon.vision.grass_max_hull_fill)>("stem.grass_max_hull_fill", "fraction", 0, 2, "0.4",
        "robust estimator: grass also covers less than this fraction of its convex hull; 1 or more: width alone"),
    enum_key<STEMD_KEY(daemon.classify.provider), runtime::kClassProviderNames>("classify.provider", "auto",
        "where plants' classes come from: model (classify.model), recording (a replayed recording's class column), socket (another process over classify.socket), or auto (model when classify.model is set, else recording)"),
    text_key<STEMD_KEY(daemon.classify.socket)>("classify.socket", "none",
        "provider socket: the Unix socket stemd listens on for a class provider's class maps; none: not set"),
    real_key<STEMD_KEY(daemon.classify.provider_timeout_ms)>("classify.provider_timeout_ms", "ms", 1, 10000, "100",
        "provider socket: a frame whose class map has not come this long after capture has its plants unknown (never treated under weeds_only), counted as class_timeouts"),
    text_key<STEMD_KEY(daemon.classify.model)>("classify.model", "none",
        "crop/weed model written by stemd-train (trained for this camera, GSD and crop); none: no classifier, plants are unknown"),
    real_key<STEMD_KEY(daemon.classify.min_confidence)>("classify.min_confidence", "probability", 0.5, 1, "0.6",
        "a plant is weed when the model's weed probability is at least this, crop when its crop probability is; else unknown (never treated under weeds_only)"),
    real_key<STEMD_KEY(daemon.classify.weed_confidence)>("classify.weed_confidence", "probability", 0.5, 1, "0.85",
        "crop safety: a plant is weed only when its weed probability is also at least this (crop plants called weed are stamped, weeds called crop only stay)"),
    bool_key<STEMD_KEY(daemon.classify.weed_parts)>("classify.weed_parts", "true",
        "with a model: each group of a crop or unknown plant's cells at weed_confidence or above (a weed grown into it), and of a stemless weed's (grass), becomes a weed target of its own, at the group's centre or, when crop lies within the clearance of it, at the nearest of its cells that is clear"),
    real_key<STEMD_KEY(daemon.classify.weed_part_clearance_mm)>("classify.weed_part_clearance_mm", "mm", 0, 100, "3",
        "no crop or unknown vegetation may lie this near a weed part's target (its centre, else its nearest clear cell; none, no target); at least the tool's strike radius"),
    real_key<STEMD_KEY(daemon.classify.weed_cover_radius_mm)>("classify.weed_cover_radius_mm", "mm", 0, 500, "0",
        "with a model and classify.weed_parts: a plant classed weed wider than this gets further targets, each at its clear weed cell farthest from the targets so far, until every clear weed cell lies within this of one (touching weeds are one plant with one stem; weed parts of other plants get none); the reach of a strike, such as a spray's footprint radius; 0: one target per weed"),
    int_key<STEMD_KEY(daemon.classify.max_targets_per_weed)>("classify.max_targets_per_weed", "count", 1, 64, "16",
        "classify.weed_cover_radius_mm: at most this many targets on one weed plant (on each group of a stemless one), its first included"),
    int_key<STEMD_KEY(daemon.classify.max_cells)>("classify.max_cells", "cells", 1, 10000000, "4096",
        "with a model: at most this many vegetated cells are classified in a frame, bounding the classifier's time (it grows with the vegetation, to every cell under a closed canopy); beyond it the cells nearest the image edge plants enter by (camera.forward) go first, as the tracker fixes a plant's class on its first sightings; the others stay unclassified, and a plant with any of them is unknown (counted in the status line)"),

    // The daemon (stemd): frame source, rings, threads, status, logging.
    choice_key<STEMD_KEY(daemon.source_kind)>("source.kind", "replay", "replay|v4l2|libcamera",
        "where frames come from: a recording, a V4L2 camera, or a libcamera camera; --replay DIR picks replay"),
    text_key<STEMD_KEY(daemon.replay_dir)>("source.replay_dir", "none",
        "recording directory (frames.csv) to replay; none: not set (--replay DIR sets it)"),
    enum_key<STEMD_KEY(daemon.replay_fast), kReplayPacingNames>("source.replay_pacing", "recorded",
        "recorded: deliver frames at their t_ns; fast: as fast as the pipeline takes them, dropping none"),
    bool_key<STEMD_KEY(daemon.replay_loop)>("source.replay_loop", "true",
        "start the recording over at its end (--once: play it once, then exit)"),
    bool_key<STEMD_KEY(daemon.replay_preload)>("source.replay_preload", "false",
        "decode every frame at start (needs frames x frame size of memory); capture then only copies"),
    int_key<STEMD_KEY(daemon.frame_size.width)>("source.width_px", "px", 16, 8192, "1296",
        "frame width; the frame slots are allocated for it, other sizes are skipped and counted"),
    int_key<STEMD_KEY(daemon.frame_size.height)>("source.height_px", "px", 16, 8192, "966",
        "frame height; the frame slots are allocated for it, other sizes are skipped and counted"),
    text_key<STEMD_KEY(daemon.v4l2_device)>("source.v4l2_device", "/dev/video0",
        "v4l2: the video capture device node (mmap streaming, source.width_px x source.height_px)"),
    choice_key<STEMD_KEY(daemon.v4l2_pixel_format)>("source.v4l2_pixel_format", "yuyv", "yuyv|bgr24|grey",
        "v4l2: pixel format asked of the camera, converted to BGR (grey: B = G = R)"),
    int_key<STEMD_KEY(daemon.v4l2_buffers)>("source.v4l2_buffers", "count", 2, 32, "4",
        "v4l2: mmap buffers asked of the driver"),
    real_key<STEMD_KEY(daemon.reopen_backoff_max_ms)>("source.reopen_backoff_max_ms", "ms", 100, 60000, "250",
        "v4l2: a lost camera is reopened after 100 ms, then at doubling intervals up to this; it bounds how long frames take to resume once the camera is back"),
    real_key<STEMD_KEY(daemon.lost_after_ms)>("source.lost_after_ms", "ms", 50, 60000, "1000",
        "after the first frame: no frame from the source for this long (time waiting for the pipeline aside) and the HEARTBEAT state is CAMERA_LOST until frames come again; a camera being reopened is reported at once"),
    text_key<STEMD_KEY(daemon.nir_device)>("source.nir_device", "none",
        "v4l2: a second, monochrome camera for NIR (segment.method auto then runs exg_and_ndvi; ndvi and exg_and_ndvi need it), paired to each RGB frame by capture time; none: no NIR camera"),
    real_key<STEMD_KEY(daemon.nir_tolerance_ms)>("source.nir_tolerance_ms", "ms", 0.1, 100, "8",
        "v4l2 with source.nir_device: largest capture-time difference of an RGB/NIR pair; unpaired frames are dropped and counted (keep it under half the frame period)"),
    real_key<STEMD_KEY(daemon.fps)>("source.fps", "fps", 1, 240, "30",
        "v4l2: frame rate asked of the camera (VIDIOC_S_PARM); a camera that cannot set one keeps its own"),
    // --- libcamera source (drivers/libcamera) ---
    text_key<STEMD_KEY(daemon.libcamera_camera)>("source.libcamera_camera", "0",
        "libcamera: the camera, by index in libcamera's list, by id, or by a part of the id matching one camera"),

    int_key<STEMD_KEY(daemon.ring_capacity)>("ring.capacity", "frames", 1, 64, "4",
        "captured frames waiting for the processing thread (slots: capacity + 2)"),
    enum_key<STEMD_KEY(daemon.overflow), runtime::kOverflowPolicyNames>("ring.overflow", "drop_newest",
        "when the frame ring is full: drop the new frame, or replace the oldest waiting one (both counted)"),
    int_key<STEMD_KEY(daemon.results_capacity)>("ring.results_capacity", "frames", 1, 64, "4",
        "detection results waiting for the actuator thread; a full ring drops the result (counted)"),

    int_key<STEMD_KEY(daemon.capture.fifo_priority)>("threads.capture_priority", "priority", 0, 99, "0",
        "SCHED_FIFO priority of the capture thread; 0 keeps the normal scheduler"),
    int_key<STEMD_KEY(daemon.processing.fifo_priority)>("threads.processing_priority", "priority", 0, 99, "0",
        "SCHED_FIFO priority of the processing thread; 0 keeps the normal scheduler"),
    int_key<STEMD_KEY(daemon.actuator.fifo_priority)>("threads.actuator_priority", "priority", 0, 99, "0",
        "SCHED_FIFO priority of the actuator thread; 0 keeps the normal scheduler"),
    int_key<STEMD_KEY(daemon.capture.cpu)>("threads.capture_cpu", "cpu", -1, 1023, "-1",
        "CPU the capture thread is pinned to; -1: any"),
    int_key<STEMD_KEY(daemon.processing.cpu)>("threads.processing_cpu", "cpu", -1, 1023, "-1",
        "CPU the processing thread is pinned to; -1: any"),
    int_key<STEMD_KEY(daemon.actuator.cpu)>("threads.actuator_cpu", "cpu", -1, 1023, "-1",
        "CPU the actuator thread is pinned to; -1: any"),
    bool_key<STEMD_KEY(daemon.mlockall)>("threads.mlockall", "false",
        "lock all current and future memory (mlockall) so that page faults cannot stall the threads"),

    int_key<STEMD_KEY(daemon.stall_processing_after_frames)>(
        "debug.stall_processing_after_frames", "frames", 0, 1000000000, "0",
        "for tests only: after this many frames the processing thread stops making progress (a stuck thread: the systemd watchdog is no longer fed); 0: never"),

    real_key<STEMD_KEY(daemon.status_interval_s)>("status.interval_s", "s", 0.1, 3600, "5",
        "seconds between status lines (fps, drops, latency, pipeline time)"),

    choice_key<STEMD_KEY(daemon.log_level)>("log.level", "info", "trace|debug|info|warn|error",
        "log level of every logger (debug: one line per frame's detections)"),

    text_key<STEMD_KEY(daemon.web.listen)>("web.listen", "none",
        "address and port of the live view (HTTP), e.g. 127.0.0.1:8080 or \"[::1]:8080\" (quoted); none: no server"),
    int_key<STEMD_KEY(daemon.web.fps)>("web.fps", "fps", 1, 30, "5",
        "most frames a second the live view is sent (each one is copied once off the processing path)"),
    int_key<STEMD_KEY(daemon.web.max_width_px)>("web.max_width_px", "px", 64, 4096, "640",
        "frames wider than this are scaled down before JPEG encoding (on the web thread)"),
    int_key<STEMD_KEY(daemon.web.plants)>("web.plants", "count", 1, 10000, "200",
        "the last N plants of the plant map kept for the view's field strip and /api/plants"),
    text_key<STEMD_KEY(daemon.web.token_file)>("web.token_file", "none",
        "file holding the live view's control token (16+ characters, mode 0600 or stricter); none: no control endpoints"),

    // --- actuation: one target per plant, deadline scheduling, odometry, CAN, GPIO ---
    real_key<STEMD_KEY(actuation.tracker.association_radius_mm)>("tracker.association_radius_mm", "mm", 0.5, 500, "10",
        "detections of one plant in overlapping frames closer than this (in the field) are the same plant"),
    int_key<STEMD_KEY(actuation.tracker.confirm_frames)>("tracker.confirm_frames", "count", 1, 100, "3",
        "a plant seen in this many frames becomes a target (one command), fewer sightings only when it leaves the view"),
    real_key<STEMD_KEY(actuation.tracker.exit_margin_mm)>("tracker.exit_margin_mm", "mm", 0, 1000, "60",
        "a plant this close to the view's trailing edge is sent now; at least the travel between two frames (46 mm at 5 km/h, 30 fps)"),
    int_key<STEMD_KEY(actuation.tracker.max_missed_frames)>("tracker.max_missed_frames", "count", 1, 100, "3",
        "a plant in view but not detected in this many frames in a row is forgotten"),
    int_key<STEMD_KEY(actuation.tracker.capacity)>("tracker.capacity", "tracks", 1, 4096, "256",
        "plants tracked at once; beyond this new detections are dropped (counted)"),

    enum_key<STEMD_KEY(actuation.policy), runtime::kPolicyChoiceNames>("scheduler.policy", "auto",
        "which plants are treated: weeds_only, all, or auto (weeds_only when a class provider gives the frame classes: classify.model, a socket provider, or the recording's class map; all without); unknown plants are never treated under weeds_only"),
    real_key<STEMD_KEY(actuation.scheduler.lead_ms)>("scheduler.lead_ms", "ms", 0, 1000, "20",
        "a command must reach the tool controller at least this long before the plant is under the tool"),
    real_key<STEMD_KEY(actuation.scheduler.send_budget_ms)>("scheduler.send_budget_ms", "ms", 0, 100, "2",
        "worst-case time to put a command on the bus; plants arriving sooner than lead + budget are missed (counted)"),
    real_key<STEMD_KEY(actuation.scheduler.standing_speed_mm_per_s)>(
        "scheduler.standing_speed_mm_per_s", "mm/s", 0, 1000, "1",
        "at or below this speed the machine is standing: commands have no deadline pressure"),

    enum_key<STEMD_KEY(actuation.odometry), runtime::kOdometrySourceNames>("odometry.source", "auto",
        "distance travelled from: the recording's odom_mm, a constant speed, CAN ODOMETRY frames, a wheel encoder; auto: recording if any replayed frame carries it (a frame without it is then not actuated), else constant"),
    real_key<STEMD_KEY(actuation.speed_mm_per_s)>("odometry.speed_mm_per_s", "mm/s", 0, 10000, "1388.9",
        "constant: the machine's speed (1388.9 mm/s = 5 km/h)"),
    real_key<STEMD_KEY(actuation.encoder_mm_per_tick)>("odometry.encoder_mm_per_tick", "mm", 0.0001, 1000, "0.1",
        "encoder: ground travel per encoder count (wheel circumference / counts per turn)"),
    real_key<STEMD_KEY(actuation.max_extrapolation_ns), kNsPerMs>(
        "odometry.max_extrapolation_ms", "ms", 1, 10000, "100",
        "the odometer is extrapolated at the last speed for at most this long after its last sample"),
    real_key<STEMD_KEY(actuation.odometry_timeout_ns), kNsPerMs>("odometry.timeout_ms", "ms", 10, 60000, "500",
        "can, encoder: no fresh sample for this long means no odometry (nothing is actuated)"),

    text_key<STEMD_KEY(actuation.can_interface)>("can.interface", "none",
        "SocketCAN interface of the tool controllers (e.g. can0); none: no bus, commands are written to can.log_file"),
    int_key<STEMD_KEY(actuation.can_base_id)>("can.base_id", "id", 0, 2043, "768",
        "first of the five 11-bit CAN ids (base .. base+4) of the stemd messages; 768 = 0x300"),
    text_key<STEMD_KEY(actuation.can_log_file)>("can.log_file", "-",
        "candump -L log of the commands when can.interface is none (and for --can-log FILE); -: standard output"),
    enum_key<STEMD_KEY(actuation.can_log_monotonic), kLogClockNames>("can.log_clock", "realtime",
        "timestamps of the log lines: wall clock (realtime, as candump) or CLOCK_MONOTONIC"),
    real_key<STEMD_KEY(actuation.heartbeat_interval_ns), kNsPerMs>("can.heartbeat_ms", "ms", 10, 10000, "100",
        "period of the HEARTBEAT message the tool controllers watch"),
    real_key<STEMD_KEY(actuation.tool_status_timeout_ns), kNsPerMs>("can.tool_status_timeout_ms", "ms", 0, 60000,
        "1000",
        "a tool whose bit in the tool controller's last TOOL_STATUS (tools_ready_mask) is clear gets no TARGET; "
        "until the first TOOL_STATUS every tool counts as ready, once the last is older than this none does; "
        "0: it holds until the next"),

    text_key<STEMD_KEY(actuation.gpio_chip)>("gpio.chip", "none",
        "GPIO chip of the lines below (e.g. gpiochip0 or /dev/gpiochip0); none: no GPIO, the enable input counts as active (warned)"),
    int_key<STEMD_KEY(actuation.enable_line)>("gpio.enable_line", "line", -1, 1023, "-1",
        "line offset of the enable input (operator switch: treat only while active); -1: none, always enabled"),
    enum_key<STEMD_KEY(actuation.enable_active_low), kActiveLowNames>("gpio.enable_active", "high",
        "level at which the enable input is active"),
    real_key<STEMD_KEY(actuation.enable_debounce_ns), kNsPerMs>("gpio.enable_debounce_ms", "ms", 0, 1000, "20",
        "the enable input must hold a new level this long before it counts"),
    int_key<STEMD_KEY(actuation.trigger_line)>("gpio.trigger_line", "line", -1, 1023, "-1",
        "line offset of the camera trigger output, pulsed once per frame; -1: none"),
    enum_key<STEMD_KEY(actuation.trigger_active_low), kActiveLowNames>("gpio.trigger_active", "high",
        "level of the trigger pulse"),
    int_key<STEMD_KEY(actuation.trigger_pulse_us)>("gpio.trigger_pulse_us", "us", 1, 100000, "100",
        "length of the trigger pulse"),
    choice_key<STEMD_KEY(actuation.encoder_mode)>("gpio.encoder", "none", "none|quadrature|single",
        "wheel encoder on gpio.encoder_a_line/b_line: quadrature (A and B, direction-aware), single (A only, forward), none"),
    int_key<STEMD_KEY(actuation.encoder_a_line)>("gpio.encoder_a_line", "line", -1, 1023, "-1",
        "line offset of the encoder's A channel; -1: none"),
    int_key<STEMD_KEY(actuation.encoder_b_line)>("gpio.encoder_b_line", "line", -1, 1023, "-1",
        "line offset of the encoder's B channel (quadrature only); -1: none"),

    text_key<STEMD_KEY(actuation.map_file)>("map.file", "none",
        "plant map written as JSON lines, one per target; none: no map (--map FILE sets it)"),

    enum_key<STEMD_KEY(actuation.gnss.source), runtime::kGnssSourceNames>("gnss.source", "none",
        "GNSS receiver for the plant map's latitude and longitude: gpsd (libgps), or none"),
    text_key<STEMD_KEY(actuation.gnss.host)>("gnss.host", "localhost",
        "host gpsd listens on"),
    int_key<STEMD_KEY(actuation.gnss.port)>("gnss.port", "port", 1, 65535, "2947",
        "TCP port gpsd listens on"),
    real_key<STEMD_KEY(actuation.gnss.antenna_x_mm)>("gnss.antenna_x_mm", "mm", -20000, 20000, "0",
        "the antenna's position in the machine frame, forward (measured to the antenna's phase centre)"),
    real_key<STEMD_KEY(actuation.gnss.antenna_y_mm)>("gnss.antenna_y_mm", "mm", -20000, 20000, "0",
        "the antenna's position in the machine frame, left"),
    real_key<STEMD_KEY(actuation.gnss.max_age_ns), kNsPerMs>("gnss.max_age_ms", "ms", 10, 600000, "1000",
        "a fix older than this is not used to extrapolate; a plant past the newest fix is then stale"),
    enum_key<STEMD_KEY(actuation.gnss.time), runtime::kGnssTimeNames>("gnss.time", "receive",
        "the time that finds a fix's odometer reading: when stemd received it, or the fix's own UTC time through the system clock (needs the clock synchronised to GNSS)"),
    real_key<STEMD_KEY(actuation.gnss.heading_baseline_mm)>("gnss.heading_baseline_mm", "mm", 100, 100000, "2000",
        "the heading is the direction of the track over this much travel (longer: less GNSS noise, slower to follow curves)"),
    real_key<STEMD_KEY(actuation.gnss.max_extrapolation_mm)>("gnss.max_extrapolation_mm", "mm", 0, 10000, "500",
        "a plant at most this far past the newest fix is placed along the heading (georef extrapolated)"),
    real_key<STEMD_KEY(actuation.gnss.max_eph_mm)>("gnss.max_eph_mm", "mm", 1, 1000000, "100",
        "a plant placed from fixes whose horizontal error estimate (gpsd's eph, 95 %) is above this is georef degraded: placed, not trusted as a fix"),
};

constexpr std::array kSections{
    SectionSpec{"camera", "",
                "The camera: its ground sampling distance, and its geometry (where a pixel lies on the ground). "
                "Machine frame: x forward (direction of travel), y to the left, millimetres; the ground is z = 0."},
    SectionSpec{"segment", "", "Vegetation segmentation: the index, its smoothing, threshold and opening."},
    SectionSpec{"closing", "", "The morphological closing that joins a plant's leaves."},
    SectionSpec{"plants", "", "Plants: the blobs of the closed mask, grouped across small gaps."},
    SectionSpec{"leaves", "", "Leaves: the plant's contour cut at its deep convexity defects."},
    SectionSpec{"stem", "", "The stem: from the leaf directions, or the centre of mass as the fallback."},
    SectionSpec{"classify", "", "Crop or weed per plant: a model trained by stemd-train, a recording's class column, or another process over a socket (README, \"Crop or weed\")."},
    SectionSpec{"source", "The daemon (stemd): frames, rings, threads, status, logging",
                "Where frames come from. Real-time settings (threads.*) are off by default; on the robot, e.g. "
                "capture_priority: 40, actuator_priority: 45, processing_priority: 30, processing_cpu: 1, "
                "mlockall: true. Without the privileges (CAP_SYS_NICE, CAP_IPC_LOCK or RLIMIT_MEMLOCK) stemd "
                "warns once and runs without them."},
    SectionSpec{"ring", "", "The lock-free rings between the capture, processing and actuator threads."},
    SectionSpec{"threads", "", "Real-time scheduling, CPU pinning and memory locking of the three real-time threads (capture, processing, actuator)."},
    SectionSpec{"status", "", "The status line."},
    SectionSpec{"log", "", "Logging (standard error, the journal under systemd)."},
    SectionSpec{"web", "", "The live view: an HTTP server on a low-priority thread (README, \"Live view\"). Off by default; "
                "bind it to loopback unless the robot's network is trusted."},
    SectionSpec{"tracker", "Actuation: one target per plant, deadlines, odometry, CAN, GPIO",
                "One target per plant across overlapping frames. Coordinates: machine frame, x forward, y to the "
                "left, millimetres; a plant's s_mm is the odometer reading when its stem is under the camera's "
                "principal point (README, \"Machine frame and field coordinates\")."},
    SectionSpec{"scheduler", "", "Which plants are treated, and the deadline of each command."},
    SectionSpec{"odometry", "", "The distance travelled, which turns positions into firing times."},
    SectionSpec{"can", "", "The CAN bus of the tool controllers (SocketCAN), or a candump log instead."},
    SectionSpec{"gpio", "", "GPIO lines (libgpiod): the operator's enable input, a camera trigger, a wheel encoder."},
    SectionSpec{"map", "", "The plant map: one JSON line per plant, with what became of it."},
    SectionSpec{"gnss", "", "GNSS through gpsd: every plant in the map gets its latitude and longitude (README, \"Georeferenced plant map\")."},
    SectionSpec{"tools", "", ""},
};

// List sections and their item keys ("section[].key"), each list's keys
// together, in the order config files list them.
constexpr std::array kLists{
    ListSpec{"tools", 16, "id", "y_min_mm", "y_max_mm",
             "the tools behind the camera (stamps, sprayers, lasers), one item each; a file's list replaces the default one",
             [](const Settings& s) { return s.actuation.tools.size(); },
             [](Settings& s, std::size_t items) { s.actuation.tools.resize(items); }},
};

constexpr std::array kItemSchema{
    int_key<STEMD_ITEM(actuation.tools, id)>("tools[].id", "id", 0, 15, "0",
        "TARGET tool_id the tool controller answers to; unique in the list"),
    real_key<STEMD_ITEM(actuation.tools, offset_mm)>("tools[].offset_mm", "mm", -5000, 5000, "600",
        "forward distance behind the camera's principal point: a plant at s_mm is under the tool at odom_mm = s_mm + offset_mm"),
    real_key<STEMD_ITEM(actuation.tools, y_min_mm)>("tools[].y_min_mm", "mm", -2047, 2047, "-220",
        "right edge of the tool's lateral span, machine y (left > 0)"),
    real_key<STEMD_ITEM(actuation.tools, y_max_mm)>("tools[].y_max_mm", "mm", -2047, 2047, "220",
        "left edge of the tool's lateral span, machine y (left > 0); greater than y_min_mm"),
    int_key<STEMD_ITEM(actuation.tools, lanes)>("tools[].lanes", "count", 1, 16, "1",
        "nozzles side by side across the span, each a lane of equal width; 1 for a stamp"),
    real_key<STEMD_ITEM(actuation.tools, latency_ms)>("tools[].latency_ms", "ms", 0, 1000, "0",
        "time from the odometer reaching the fire point to the strike taking effect (valve, stamp); commands go out earlier by speed x latency_ms"),
    bool_key<STEMD_ITEM(actuation.tools, learn_latency)>("tools[].learn_latency", "false",
        "learn latency_ms from the tool's TOOL_FIRED reports (median of the last 15 lags in ms), starting from latency_ms"),
    real_key<STEMD_ITEM(actuation.tools, latency_min_ms)>("tools[].latency_min_ms", "ms", 0, 1000, "0",
        "learn_latency: the learned latency never goes below this"),
    real_key<STEMD_ITEM(actuation.tools, latency_max_ms)>("tools[].latency_max_ms", "ms", 0, 1000, "200",
        "learn_latency: the learned latency never goes above this (at least latency_min_ms)"),
};

}  // namespace

std::string_view to_string(ValueType type)
{
    constexpr base::EnumName<ValueType> kNames[] = {
        {integer, "integer"}, {real, "real"}, {choice, "choice"}, {boolean, "boolean"}, {text, "text"}};
    return base::name_of(kNames, type);
}

std::span<const SectionSpec> section_schema()
{
    return kSections;
}

std::span<const KeySpec> schema()
{
    return kSchema;
}

const KeySpec* find_key(std::string_view key)
{
    return find_named(std::span<const KeySpec>(kSchema), key, &KeySpec::key);
}

std::span<const ListSpec> list_schema()
{
    return kLists;
}

const ListSpec* find_list(std::string_view section)
{
    return find_named(std::span<const ListSpec>(kLists), section, &ListSpec::section);
}

std::span<const KeySpec> list_item_schema()
{
    return kItemSchema;
}

std::string_view item_list_of(const KeySpec& spec)
{
    const std::size_t bracket = spec.key.find("[].");
    return bracket == std::string_view::npos ? std::string_view{} : spec.key.substr(0, bracket);
}

std::string_view item_leaf_of(const KeySpec& spec)
{
    const std::size_t bracket = spec.key.find("[].");
    return bracket == std::string_view::npos ? spec.key : spec.key.substr(bracket + 3);
}

std::span<const KeySpec> item_keys(std::string_view section)
{
    const std::span<const KeySpec> all = kItemSchema;
    std::size_t first = 0;
    while (first < all.size() && item_list_of(all[first]) != section)
        ++first;
    std::size_t last = first;
    while (last < all.size() && item_list_of(all[last]) == section)
        ++last;
    return all.subspan(first, last - first);
}

const KeySpec* find_item_key(std::string_view section, std::string_view item_key)
{
    return find_named(item_keys(section), item_key, item_leaf_of);
}

bool is_choice(const KeySpec& spec, std::string_view value)
{
    const std::vector<std::string_view> choices = choices_of(spec);
    return std::find(choices.begin(), choices.end(), value) != choices.end();
}

std::string list_choices(const KeySpec& spec, std::string_view separator)
{
    std::string out;
    for (const std::string_view choice : choices_of(spec))
        out += cat(out.empty() ? "" : separator, choice);
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

std::string bounds_text(const KeySpec& spec)
{
    return cat("[", format_number(spec.min), ", ", format_number(spec.max), "]");
}

}  // namespace stemd::config
