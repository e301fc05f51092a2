#include "stemd/config/schema.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <system_error>
#include <type_traits>
#include <vector>

#include "stemd/config/config.hpp"
#include "stemd/config/settings.hpp"
#include "values.hpp"

namespace stemd::config {

namespace {

using detail::cat;

using enum ValueType;
using geometry::Forward;
using geometry::ModelKind;
using runtime::GnssSourceKind;
using runtime::GnssTime;
using runtime::OdometrySource;
using runtime::OverflowPolicy;
using runtime::PolicyChoice;
using vision::MaskVegetation;
using vision::Segmentation;
using vision::StemEstimator;
using vision::ThresholdMethod;

// --- binding a row to its Settings member ------------------------------------
// STEMD_KEY(daemon.fps) names a member of Settings, STEMD_ITEM(actuation.tools,
// lanes) a member of a list's items: a captureless lambda the row's store and
// load functions are generated from.
#define STEMD_KEY(path) [](auto& s, std::size_t) -> auto& { return s.path; }
#define STEMD_ITEM(list, member) [](auto& s, std::size_t item) -> auto& { return s.list[item].member; }

constexpr std::int64_t kNsPerMs = 1'000'000;

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

// The position of `text` among the choices (the loader has checked that it
// is one; else the last).
std::size_t choice_index(const KeySpec& spec, std::string_view text)
{
    const std::vector<std::string_view> choices = choices_of(spec);
    return static_cast<std::size_t>(std::find(choices.begin(), choices.end() - 1, text) - choices.begin());
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

// A choice row bound to a member of any type: Values holds the member's
// value for each of spec.choices, in order.
template <auto Field, auto Values>
constexpr KeySpec bind_choice(KeySpec spec)
{
    spec.store = [](const KeySpec& k, Settings& s, std::size_t item, const detail::ConfigValue& v) {
        Field(s, item) = Values[choice_index(k, v.text)];
    };
    spec.load = [](const KeySpec& k, const Settings& s, std::size_t item, detail::ConfigValue& v) {
        for (std::size_t i = 0; i < Values.size(); ++i)
            if (Values[i] == Field(s, item))
                v.text = choices_of(k).at(i);
    };
    return spec;
}

// One row per key; keep each section's rows together (the README table and
// config/stemd.yaml follow this order).
constexpr std::array kSchema{
    bind<STEMD_KEY(daemon.vision.gsd_mm_per_px)>(
        {"camera.gsd_mm_per_px", real, "mm/px", 0.01, 10, "0.33", "",
            "ground sampling distance: millimetres of ground per image pixel"}),
    // Camera geometry: machine frame x forward, y left, mm.
    bind_choice<STEMD_KEY(camera.model), std::array{ModelKind::nadir, ModelKind::calibrated}>(
        {"camera.model", choice, "", 0, 0, "nadir", "nadir|calibrated",
            "nadir: straight down at camera.gsd_mm_per_px; calibrated: OpenCV calibration file plus the pose below"}),
    bind_choice<STEMD_KEY(camera.mount.forward), std::array{Forward::up, Forward::down, Forward::left, Forward::right}>(
        {"camera.forward", choice, "", 0, 0, "up", "up|down|left|right",
            "which image direction points in the direction of travel (up: plants move down the image)"}),
    bind<STEMD_KEY(camera.calibration_file)>(
        {"camera.calibration_file", text, "", 0, 0, "none", "",
            "calibrated: OpenCV calibration YAML (camera_matrix, distortion_coefficients, image_width, image_height; stemd-calibrate writes one) or ROS camera_info YAML; none: not set"}),
    bind<STEMD_KEY(camera.pose.height_mm)>(
        {"camera.height_mm", real, "mm", 10, 5000, "500", "",
            "calibrated: height of the optical centre above the ground"}),
    bind<STEMD_KEY(camera.pose.roll_deg)>(
        {"camera.roll_deg", real, "deg", -45, 45, "0", "",
            "calibrated: tilt about machine x; > 0 tilts the optical axis to the left"}),
    bind<STEMD_KEY(camera.pose.pitch_deg)>(
        {"camera.pitch_deg", real, "deg", -45, 45, "0", "",
            "calibrated: tilt about machine y; > 0 tilts the optical axis forward"}),
    bind<STEMD_KEY(camera.pose.yaw_deg)>(
        {"camera.yaw_deg", real, "deg", -180, 180, "0", "",
            "calibrated: turn about the vertical; > 0 counter-clockwise seen from above"}),
    bind<STEMD_KEY(camera.mount.x_mm)>(
        {"camera.x_mm", real, "mm", -5000, 5000, "0", "",
            "machine-frame x (forward) of the principal point's ground position (where the optical axis meets the ground)"}),
    bind<STEMD_KEY(camera.mount.y_mm)>(
        {"camera.y_mm", real, "mm", -5000, 5000, "0", "",
            "machine-frame y (left) of the principal point's ground position"}),

    bind_choice<STEMD_KEY(daemon.vision.segmentation), std::array{Segmentation::chromatic_exg, Segmentation::exg, Segmentation::ndvi, Segmentation::mask,
                                                             Segmentation::exg_and_ndvi}>(
        {"segment.method", choice, "", 0, 0, "chromatic_exg", "chromatic_exg|exg|ndvi|mask|exg_and_ndvi",
            "vegetation index: chromatic Excess Green (RGB, exposure-invariant), Excess Green, NDVI (RGB+NIR), an external mask, or exg_and_ndvi (RGB+NIR: both chromatic Excess Green and NDVI above the soil; the choice with a NIR camera)"}),
    bind<STEMD_KEY(daemon.vision.leaf_colour)>(
        {"segment.leaf_colour", boolean, "", 0, 0, "true", "",
            "exg, chromatic_exg: a plant needs a core of pixels more green than red (by 2 % of their brightness), as chlorophyll makes a leaf; yellowish clods and colour fringes are not. Off only for a camera without white balance"}),
    bind<STEMD_KEY(daemon.vision.smooth_index)>(
        {"segment.smooth", boolean, "", 0, 0, "true", "",
            "smooth the index with a 3x3 binomial kernel before the threshold"}),
    bind<STEMD_KEY(daemon.vision.sparse_index)>(
        {"segment.sparse_index", boolean, "", 0, 0, "true", "",
            "exg, chromatic_exg (smoothed): compute the index in full only in 64 px tiles near vegetation found on every 8th row, the rest as soil (a piece at most about 5 rows tall between sampled rows, away from any plant, is missed); the threshold's histogram counts soil tiles from those rows. false: every pixel"}),
    bind_choice<STEMD_KEY(daemon.vision.threshold), std::array{ThresholdMethod::above_soil, ThresholdMethod::otsu, ThresholdMethod::triangle, ThresholdMethod::min_error}>(
        {"segment.threshold", choice, "", 0, 0, "above_soil", "above_soil|otsu|triangle|min_error",
            "automatic threshold on the vegetation index; above_soil: Otsu, but never within segment.soil_sigmas of the soil mode"}),
    bind<STEMD_KEY(daemon.vision.soil_sigmas)>(
        {"segment.soil_sigmas", real, "sigma", 1, 20, "5", "",
            "above_soil: the threshold lies at least this many soil standard deviations above the soil mode"}),
    bind<STEMD_KEY(daemon.vision.opening_radius_px)>(
        {"segment.opening_radius_px", integer, "px", 0, 50, "1", "",
            "radius of the elliptic opening before the closing: removes specks and colour fringes; 0 disables"}),
    bind<STEMD_KEY(daemon.vision.edge_radius_px)>(
        {"segment.edge_radius_px", integer, "px", 0, 50, "5", "",
            "exg, chromatic_exg: mixed pixels at a plant's edge: within this radius of the thresholded plant, a pixel is vegetation when its index lies above the halfway point between the soil mode and the mean of the plant pixels around it (at least half leaf) and beyond the soil's noise; 0 disables"}),
    bind<STEMD_KEY(daemon.vision.min_class_separation)>(
        {"segment.min_class_separation", real, "index", 0, 255, "12", "",
            "automatic thresholds: if the two classes' mean 8-bit index differs by less (ExG: 1 = 4 of 2G-R-B), the frame has no vegetation; 0 disables"}),
    bind_choice<STEMD_KEY(daemon.vision.mask_vegetation), std::array{MaskVegetation::nonzero, MaskVegetation::zero}>(
        {"segment.mask_vegetation", choice, "", 0, 0, "nonzero", "nonzero|zero",
            "which pixel value of an external mask is vegetation"}),

    bind<STEMD_KEY(daemon.vision.closing_radius_px)>(
        {"closing.radius_px", integer, "px", 0, 50, "5", "",
            "radius m of the elliptic closing kernel (size 2m+1); 0 disables closing"}),

    bind<STEMD_KEY(daemon.vision.min_plant_area_mm2)>(
        {"plants.min_area_mm2", real, "mm2", 0, 100000, "10", "",
            "plants with a smaller area are dropped as noise"}),
    bind<STEMD_KEY(daemon.vision.group_gap_mm)>(
        {"plants.group_gap_mm", real, "mm", 0, 50, "6", "",
            "pieces of vegetation less than this far apart are one plant (leaves whose petioles fell below the threshold); 0: every piece is a plant"}),

    bind<STEMD_KEY(daemon.vision.defect_depth_mm)>(
        {"leaves.defect_depth_mm", real, "mm", 0.1, 100, "1", "",
            "convexity defects deeper than this cut the contour into leaves (the paper: 3.3)"}),
    bind<STEMD_KEY(daemon.vision.defect_depth_rel)>(
        {"leaves.defect_depth_rel", real, "fraction", 0, 1, "0.15", "",
            "defects must also be deeper than this fraction of the plant's equivalent radius sqrt(area/pi)"}),

    bind_choice<STEMD_KEY(daemon.vision.stem_estimator), std::array{StemEstimator::robust, StemEstimator::paper, StemEstimator::com}>(
        {"stem.method", choice, "", 0, 0, "robust", "robust|paper|com",
            "stem estimator: robust (least-squares point of the leaf lines), paper (mean of their intersections) or com (centre of mass)"}),
    bind<STEMD_KEY(daemon.vision.min_leaves)>(
        {"stem.min_leaves", integer, "count", 2, 16, "3", "",
            "paper estimator: the paper's N, plants with fewer leaves use the centre of mass"}),
    bind<STEMD_KEY(daemon.vision.min_intersection_angle_deg)>(
        {"stem.min_angle_deg", real, "deg", 0, 45, "0", "",
            "paper estimator: pairs of leaf lines meeting at a smaller angle are skipped (0: only exactly parallel ones, as in the paper)"}),
    bind<STEMD_KEY(daemon.vision.min_confidence)>(
        {"stem.min_confidence", real, "fraction", 0, 1, "0.05", "",
            "plants whose stem confidence is lower are reported without a stem"}),
    bind<STEMD_KEY(daemon.vision.grass_min_area_mm2)>(
        {"stem.grass_min_area_mm2", real, "mm2", 0, 100000, "100", "",
            "robust estimator: plants at least this large and thinner than stem.grass_max_width_mm are grass, without a stem"}),
    bind<STEMD_KEY(daemon.vision.grass_max_width_mm)>(
        {"stem.grass_max_width_mm", real, "mm", 0, 100, "3", "",
            "robust estimator: mean width (2 area / perimeter) below which a large plant is grass; 0 disables"}),
    bind<STEMD_KEY(daemon.vision.grass_max_hull_fill)>(
        {"stem.grass_max_hull_fill", real, "fraction", 0, 2, "0.4", "",
            "robust estimator: grass also covers less than this fraction of its convex hull; 1 or more: width alone"}),
    bind_choice<STEMD_KEY(daemon.classify.provider),
                std::array{runtime::ClassProviderChoice::automatic, runtime::ClassProviderChoice::model,
                           runtime::ClassProviderChoice::recording, runtime::ClassProviderChoice::socket}>(
        {"classify.provider", choice, "", 0, 0, "auto", "auto|model|recording|socket",
            "where plants' classes come from: model (classify.model), recording (a replayed recording's class column), socket (another process over classify.socket), or auto (model when classify.model is set, else recording)"}),
    bind<STEMD_KEY(daemon.classify.socket)>(
        {"classify.socket", text, "", 0, 0, "none", "",
            "provider socket: the Unix socket stemd listens on for a class provider's class maps; none: not set"}),
    bind<STEMD_KEY(daemon.classify.provider_timeout_ms)>(
        {"classify.provider_timeout_ms", real, "ms", 1, 10000, "100", "",
            "provider socket: a frame whose class map has not come this long after capture has its plants unknown (never treated under weeds_only), counted as class_timeouts"}),
    bind<STEMD_KEY(daemon.classify.model)>(
        {"classify.model", text, "", 0, 0, "none", "",
            "crop/weed model written by stemd-train (trained for this camera, GSD and crop); none: no classifier, plants are unknown"}),
    bind<STEMD_KEY(daemon.classify.min_confidence)>(
        {"classify.min_confidence", real, "probability", 0.5, 1, "0.6", "",
            "a plant is weed when the model's weed probability is at least this, crop when its crop probability is; else unknown (never treated under weeds_only)"}),
    bind<STEMD_KEY(daemon.classify.weed_confidence)>(
        {"classify.weed_confidence", real, "probability", 0.5, 1, "0.85", "",
            "crop safety: a plant is weed only when its weed probability is also at least this (crop plants called weed are stamped, weeds called crop only stay)"}),

    // The daemon (stemd): frame source, rings, threads, status, logging.
    bind<STEMD_KEY(daemon.source_kind)>(
        {"source.kind", choice, "", 0, 0, "replay", "replay|v4l2|libcamera",
            "where frames come from: a recording, a V4L2 camera, or a libcamera camera; --replay DIR picks replay"}),
    bind<STEMD_KEY(daemon.replay_dir)>(
        {"source.replay_dir", text, "", 0, 0, "none", "",
            "recording directory (frames.csv) to replay; none: not set (--replay DIR sets it)"}),
    bind_choice<STEMD_KEY(daemon.replay_fast), std::array{false, true}>(
        {"source.replay_pacing", choice, "", 0, 0, "recorded", "recorded|fast",
            "recorded: deliver frames at their t_ns; fast: as fast as the pipeline takes them, dropping none"}),
    bind<STEMD_KEY(daemon.replay_loop)>(
        {"source.replay_loop", boolean, "", 0, 0, "true", "",
            "start the recording over at its end (--once: play it once, then exit)"}),
    bind<STEMD_KEY(daemon.replay_preload)>(
        {"source.replay_preload", boolean, "", 0, 0, "false", "",
            "decode every frame at start (needs frames x frame size of memory); capture then only copies"}),
    bind<STEMD_KEY(daemon.frame_size.width)>(
        {"source.width_px", integer, "px", 16, 8192, "1296", "",
            "frame width; the frame slots are allocated for it, other sizes are skipped and counted"}),
    bind<STEMD_KEY(daemon.frame_size.height)>(
        {"source.height_px", integer, "px", 16, 8192, "966", "",
            "frame height; the frame slots are allocated for it, other sizes are skipped and counted"}),
    bind<STEMD_KEY(daemon.v4l2_device)>(
        {"source.v4l2_device", text, "", 0, 0, "/dev/video0", "",
            "v4l2: the video capture device node (mmap streaming, source.width_px x source.height_px)"}),
    bind<STEMD_KEY(daemon.v4l2_pixel_format)>(
        {"source.v4l2_pixel_format", choice, "", 0, 0, "yuyv", "yuyv|bgr24|grey",
            "v4l2: pixel format asked of the camera, converted to BGR (grey: B = G = R)"}),
    bind<STEMD_KEY(daemon.v4l2_buffers)>(
        {"source.v4l2_buffers", integer, "count", 2, 32, "4", "",
            "v4l2: mmap buffers asked of the driver"}),
    bind<STEMD_KEY(daemon.reopen_backoff_max_ms)>(
        {"source.reopen_backoff_max_ms", real, "ms", 100, 60000, "250", "",
            "v4l2: a lost camera is reopened after 100 ms, then at doubling intervals up to this; it bounds how long frames take to resume once the camera is back"}),
    bind<STEMD_KEY(daemon.lost_after_ms)>(
        {"source.lost_after_ms", real, "ms", 50, 60000, "1000", "",
            "after the first frame: no frame from the source for this long (time waiting for the pipeline aside) and the HEARTBEAT state is CAMERA_LOST until frames come again; a camera being reopened is reported at once"}),
    bind<STEMD_KEY(daemon.nir_device)>(
        {"source.nir_device", text, "", 0, 0, "none", "",
            "v4l2: a second, monochrome camera for NIR (segment.method ndvi), paired to each RGB frame by capture time; none: no NIR camera"}),
    bind<STEMD_KEY(daemon.nir_tolerance_ms)>(
        {"source.nir_tolerance_ms", real, "ms", 0.1, 100, "8", "",
            "v4l2 with source.nir_device: largest capture-time difference of an RGB/NIR pair; unpaired frames are dropped and counted (keep it under half the frame period)"}),
    bind<STEMD_KEY(daemon.fps)>(
        {"source.fps", real, "fps", 1, 240, "30", "",
            "v4l2: frame rate asked of the camera (VIDIOC_S_PARM); a camera that cannot set one keeps its own"}),
    // --- libcamera source (drivers/libcamera) ---
    bind<STEMD_KEY(daemon.libcamera_camera)>(
        {"source.libcamera_camera", text, "", 0, 0, "0", "",
            "libcamera: the camera, by index in libcamera's list, by id, or by a part of the id matching one camera"}),

    bind<STEMD_KEY(daemon.ring_capacity)>(
        {"ring.capacity", integer, "frames", 1, 64, "4", "",
            "captured frames waiting for the processing thread (slots: capacity + 2)"}),
    bind_choice<STEMD_KEY(daemon.overflow), std::array{OverflowPolicy::drop_newest, OverflowPolicy::overwrite_oldest}>(
        {"ring.overflow", choice, "", 0, 0, "drop_newest", "drop_newest|overwrite_oldest",
            "when the frame ring is full: drop the new frame, or replace the oldest waiting one (both counted)"}),
    bind<STEMD_KEY(daemon.results_capacity)>(
        {"ring.results_capacity", integer, "frames", 1, 64, "4", "",
            "detection results waiting for the actuator thread; a full ring drops the result (counted)"}),

    bind<STEMD_KEY(daemon.capture.fifo_priority)>(
        {"threads.capture_priority", integer, "priority", 0, 99, "0", "",
            "SCHED_FIFO priority of the capture thread; 0 keeps the normal scheduler"}),
    bind<STEMD_KEY(daemon.processing.fifo_priority)>(
        {"threads.processing_priority", integer, "priority", 0, 99, "0", "",
            "SCHED_FIFO priority of the processing thread; 0 keeps the normal scheduler"}),
    bind<STEMD_KEY(daemon.actuator.fifo_priority)>(
        {"threads.actuator_priority", integer, "priority", 0, 99, "0", "",
            "SCHED_FIFO priority of the actuator thread; 0 keeps the normal scheduler"}),
    bind<STEMD_KEY(daemon.capture.cpu)>(
        {"threads.capture_cpu", integer, "cpu", -1, 1023, "-1", "",
            "CPU the capture thread is pinned to; -1: any"}),
    bind<STEMD_KEY(daemon.processing.cpu)>(
        {"threads.processing_cpu", integer, "cpu", -1, 1023, "-1", "",
            "CPU the processing thread is pinned to; -1: any"}),
    bind<STEMD_KEY(daemon.actuator.cpu)>(
        {"threads.actuator_cpu", integer, "cpu", -1, 1023, "-1", "",
            "CPU the actuator thread is pinned to; -1: any"}),
    bind<STEMD_KEY(daemon.mlockall)>(
        {"threads.mlockall", boolean, "", 0, 0, "false", "",
            "lock all current and future memory (mlockall) so that page faults cannot stall the threads"}),

    bind<STEMD_KEY(daemon.stall_processing_after_frames)>(
        {"debug.stall_processing_after_frames", integer, "frames", 0, 1000000000, "0", "",
            "for tests only: after this many frames the processing thread stops making progress (a stuck thread: the systemd watchdog is no longer fed); 0: never"}),

    bind<STEMD_KEY(daemon.status_interval_s)>(
        {"status.interval_s", real, "s", 0.1, 3600, "5", "",
            "seconds between status lines (fps, drops, latency, pipeline time)"}),

    bind<STEMD_KEY(daemon.log_level)>(
        {"log.level", choice, "", 0, 0, "info", "trace|debug|info|warn|error",
            "log level of every logger (debug: one line per frame's detections)"}),

    bind<STEMD_KEY(daemon.web.listen)>(
        {"web.listen", text, "", 0, 0, "none", "",
            "address and port of the live view (HTTP), e.g. 127.0.0.1:8080 or \"[::1]:8080\" (quoted); none: no server"}),
    bind<STEMD_KEY(daemon.web.fps)>(
        {"web.fps", integer, "fps", 1, 30, "5", "",
            "most frames a second the live view is sent (each one is copied once off the processing path)"}),
    bind<STEMD_KEY(daemon.web.max_width_px)>(
        {"web.max_width_px", integer, "px", 64, 4096, "640", "",
            "frames wider than this are scaled down before JPEG encoding (on the web thread)"}),
    bind<STEMD_KEY(daemon.web.plants)>(
        {"web.plants", integer, "count", 1, 10000, "200", "",
            "the last N plants of the plant map kept for the view's field strip and /api/plants"}),
    bind<STEMD_KEY(daemon.web.token_file)>(
        {"web.token_file", text, "", 0, 0, "none", "",
            "file holding the live view's control token (16+ characters, mode 0600 or stricter); none: no control endpoints"}),

    // --- actuation: one target per plant, deadline scheduling, odometry, CAN, GPIO ---
    bind<STEMD_KEY(actuation.tracker.association_radius_mm)>(
        {"tracker.association_radius_mm", real, "mm", 0.5, 500, "10", "",
            "detections of one plant in overlapping frames closer than this (in the field) are the same plant"}),
    bind<STEMD_KEY(actuation.tracker.confirm_frames)>(
        {"tracker.confirm_frames", integer, "count", 1, 100, "3", "",
            "a plant seen in this many frames becomes a target (one command), fewer sightings only when it leaves the view"}),
    bind<STEMD_KEY(actuation.tracker.exit_margin_mm)>(
        {"tracker.exit_margin_mm", real, "mm", 0, 1000, "60", "",
            "a plant this close to the view's trailing edge is sent now; at least the travel between two frames (46 mm at 5 km/h, 30 fps)"}),
    bind<STEMD_KEY(actuation.tracker.max_missed_frames)>(
        {"tracker.max_missed_frames", integer, "count", 1, 100, "3", "",
            "a plant in view but not detected in this many frames in a row is forgotten"}),
    bind<STEMD_KEY(actuation.tracker.capacity)>(
        {"tracker.capacity", integer, "tracks", 1, 4096, "256", "",
            "plants tracked at once; beyond this new detections are dropped (counted)"}),

    bind_choice<STEMD_KEY(actuation.policy), std::array{PolicyChoice::automatic, PolicyChoice::weeds_only, PolicyChoice::all}>(
        {"scheduler.policy", choice, "", 0, 0, "auto", "auto|weeds_only|all",
            "which plants are treated: weeds_only, all, or auto (weeds_only when a class provider gives the frame classes: classify.model, a socket provider, or the recording's class map; all without); unknown plants are never treated under weeds_only"}),
    bind<STEMD_KEY(actuation.scheduler.lead_ms)>(
        {"scheduler.lead_ms", real, "ms", 0, 1000, "20", "",
            "a command must reach the tool controller at least this long before the plant is under the tool"}),
    bind<STEMD_KEY(actuation.scheduler.send_budget_ms)>(
        {"scheduler.send_budget_ms", real, "ms", 0, 100, "2", "",
            "worst-case time to put a command on the bus; plants arriving sooner than lead + budget are missed (counted)"}),
    bind<STEMD_KEY(actuation.scheduler.standing_speed_mm_per_s)>(
        {"scheduler.standing_speed_mm_per_s", real, "mm/s", 0, 1000, "1", "",
            "at or below this speed the machine is standing: commands have no deadline pressure"}),

    bind_choice<STEMD_KEY(actuation.odometry), std::array{OdometrySource::automatic, OdometrySource::recording, OdometrySource::constant, OdometrySource::can, OdometrySource::encoder}>(
        {"odometry.source", choice, "", 0, 0, "auto", "auto|recording|constant|can|encoder",
            "distance travelled from: the recording's odom_mm, a constant speed, CAN ODOMETRY frames, a wheel encoder; auto: recording if the frames carry it, else constant"}),
    bind<STEMD_KEY(actuation.speed_mm_per_s)>(
        {"odometry.speed_mm_per_s", real, "mm/s", 0, 10000, "1388.9", "",
            "constant: the machine's speed (1388.9 mm/s = 5 km/h)"}),
    bind<STEMD_KEY(actuation.encoder_mm_per_tick)>(
        {"odometry.encoder_mm_per_tick", real, "mm", 0.0001, 1000, "0.1", "",
            "encoder: ground travel per encoder count (wheel circumference / counts per turn)"}),
    bind<STEMD_KEY(actuation.max_extrapolation_ns), kNsPerMs>(
        {"odometry.max_extrapolation_ms", real, "ms", 1, 10000, "100", "",
            "the odometer is extrapolated at the last speed for at most this long after its last sample"}),
    bind<STEMD_KEY(actuation.odometry_timeout_ns), kNsPerMs>(
        {"odometry.timeout_ms", real, "ms", 10, 60000, "500", "",
            "can, encoder: no fresh sample for this long means no odometry (nothing is actuated)"}),

    bind<STEMD_KEY(actuation.can_interface)>(
        {"can.interface", text, "", 0, 0, "none", "",
            "SocketCAN interface of the tool controllers (e.g. can0); none: no bus, commands are written to can.log_file"}),
    bind<STEMD_KEY(actuation.can_base_id)>(
        {"can.base_id", integer, "id", 0, 2043, "768", "",
            "first of the five 11-bit CAN ids (base .. base+4) of the stemd messages; 768 = 0x300"}),
    bind<STEMD_KEY(actuation.can_log_file)>(
        {"can.log_file", text, "", 0, 0, "-", "",
            "candump -L log of the commands when can.interface is none (and for --can-log FILE); -: standard output"}),
    bind_choice<STEMD_KEY(actuation.can_log_monotonic), std::array{false, true}>(
        {"can.log_clock", choice, "", 0, 0, "realtime", "realtime|monotonic",
            "timestamps of the log lines: wall clock (realtime, as candump) or CLOCK_MONOTONIC"}),
    bind<STEMD_KEY(actuation.heartbeat_interval_ns), kNsPerMs>(
        {"can.heartbeat_ms", real, "ms", 10, 10000, "100", "",
            "period of the HEARTBEAT message the tool controllers watch"}),

    bind<STEMD_KEY(actuation.gpio_chip)>(
        {"gpio.chip", text, "", 0, 0, "none", "",
            "GPIO chip of the lines below (e.g. gpiochip0 or /dev/gpiochip0); none: no GPIO, the enable input counts as active (warned)"}),
    bind<STEMD_KEY(actuation.enable_line)>(
        {"gpio.enable_line", integer, "line", -1, 1023, "-1", "",
            "line offset of the enable input (operator switch: treat only while active); -1: none, always enabled"}),
    bind_choice<STEMD_KEY(actuation.enable_active_low), std::array{false, true}>(
        {"gpio.enable_active", choice, "", 0, 0, "high", "high|low",
            "level at which the enable input is active"}),
    bind<STEMD_KEY(actuation.enable_debounce_ns), kNsPerMs>(
        {"gpio.enable_debounce_ms", real, "ms", 0, 1000, "20", "",
            "the enable input must hold a new level this long before it counts"}),
    bind<STEMD_KEY(actuation.trigger_line)>(
        {"gpio.trigger_line", integer, "line", -1, 1023, "-1", "",
            "line offset of the camera trigger output, pulsed once per frame; -1: none"}),
    bind_choice<STEMD_KEY(actuation.trigger_active_low), std::array{false, true}>(
        {"gpio.trigger_active", choice, "", 0, 0, "high", "high|low",
            "level of the trigger pulse"}),
    bind<STEMD_KEY(actuation.trigger_pulse_us)>(
        {"gpio.trigger_pulse_us", integer, "us", 1, 100000, "100", "",
            "length of the trigger pulse"}),
    bind<STEMD_KEY(actuation.encoder_mode)>(
        {"gpio.encoder", choice, "", 0, 0, "none", "none|quadrature|single",
            "wheel encoder on gpio.encoder_a_line/b_line: quadrature (A and B, direction-aware), single (A only, forward), none"}),
    bind<STEMD_KEY(actuation.encoder_a_line)>(
        {"gpio.encoder_a_line", integer, "line", -1, 1023, "-1", "",
            "line offset of the encoder's A channel; -1: none"}),
    bind<STEMD_KEY(actuation.encoder_b_line)>(
        {"gpio.encoder_b_line", integer, "line", -1, 1023, "-1", "",
            "line offset of the encoder's B channel (quadrature only); -1: none"}),

    bind<STEMD_KEY(actuation.map_file)>(
        {"map.file", text, "", 0, 0, "none", "",
            "plant map written as JSON lines, one per target; none: no map (--map FILE sets it)"}),

    bind_choice<STEMD_KEY(actuation.gnss.source), std::array{GnssSourceKind::none, GnssSourceKind::gpsd}>(
        {"gnss.source", choice, "", 0, 0, "none", "none|gpsd",
            "GNSS receiver for the plant map's latitude and longitude: gpsd (libgps), or none"}),
    bind<STEMD_KEY(actuation.gnss.host)>(
        {"gnss.host", text, "", 0, 0, "localhost", "",
            "host gpsd listens on"}),
    bind<STEMD_KEY(actuation.gnss.port)>(
        {"gnss.port", integer, "port", 1, 65535, "2947", "",
            "TCP port gpsd listens on"}),
    bind<STEMD_KEY(actuation.gnss.antenna_x_mm)>(
        {"gnss.antenna_x_mm", real, "mm", -20000, 20000, "0", "",
            "the antenna's position in the machine frame, forward (measured to the antenna's phase centre)"}),
    bind<STEMD_KEY(actuation.gnss.antenna_y_mm)>(
        {"gnss.antenna_y_mm", real, "mm", -20000, 20000, "0", "",
            "the antenna's position in the machine frame, left"}),
    bind<STEMD_KEY(actuation.gnss.max_age_ns), kNsPerMs>(
        {"gnss.max_age_ms", real, "ms", 10, 600000, "1000", "",
            "a fix older than this is not used to extrapolate; a plant past the newest fix is then stale"}),
    bind_choice<STEMD_KEY(actuation.gnss.time), std::array{GnssTime::receive, GnssTime::gnss}>(
        {"gnss.time", choice, "", 0, 0, "receive", "receive|gnss",
            "the time that finds a fix's odometer reading: when stemd received it, or the fix's own UTC time through the system clock (needs the clock synchronised to GNSS)"}),
    bind<STEMD_KEY(actuation.gnss.heading_baseline_mm)>(
        {"gnss.heading_baseline_mm", real, "mm", 100, 100000, "2000", "",
            "the heading is the direction of the track over this much travel (longer: less GNSS noise, slower to follow curves)"}),
    bind<STEMD_KEY(actuation.gnss.max_extrapolation_mm)>(
        {"gnss.max_extrapolation_mm", real, "mm", 0, 10000, "500", "",
            "a plant at most this far past the newest fix is placed along the heading (georef extrapolated)"}),
    bind<STEMD_KEY(actuation.gnss.max_eph_mm)>(
        {"gnss.max_eph_mm", real, "mm", 1, 1000000, "100", "",
            "a plant placed from fixes whose horizontal error estimate (gpsd's eph, 95 %) is above this is georef degraded: placed, not trusted as a fix"}),
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
    SectionSpec{"threads", "", "Real-time scheduling, CPU pinning and memory locking of the three threads."},
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
    bind<STEMD_ITEM(actuation.tools, id)>(
        {"tools[].id", integer, "id", 0, 15, "0", "",
            "TARGET tool_id the tool controller answers to; unique in the list"}),
    bind<STEMD_ITEM(actuation.tools, offset_mm)>(
        {"tools[].offset_mm", real, "mm", -5000, 5000, "600", "",
            "forward distance behind the camera's principal point: a plant at s_mm is under the tool at odom_mm = s_mm + offset_mm"}),
    bind<STEMD_ITEM(actuation.tools, y_min_mm)>(
        {"tools[].y_min_mm", real, "mm", -2047, 2047, "-220", "",
            "right edge of the tool's lateral span, machine y (left > 0)"}),
    bind<STEMD_ITEM(actuation.tools, y_max_mm)>(
        {"tools[].y_max_mm", real, "mm", -2047, 2047, "220", "",
            "left edge of the tool's lateral span, machine y (left > 0); greater than y_min_mm"}),
    bind<STEMD_ITEM(actuation.tools, lanes)>(
        {"tools[].lanes", integer, "count", 1, 16, "1", "",
            "nozzles side by side across the span, each a lane of equal width; 1 for a stamp"}),
    bind<STEMD_ITEM(actuation.tools, latency_ms)>(
        {"tools[].latency_ms", real, "ms", 0, 1000, "0", "",
            "time from the odometer reaching the fire point to the strike taking effect (valve, stamp); commands go out earlier by speed x latency_ms"}),
    bind<STEMD_ITEM(actuation.tools, learn_latency)>(
        {"tools[].learn_latency", boolean, "", 0, 0, "false", "",
            "learn latency_ms from the tool's TOOL_FIRED reports (median of the last 15 lags in ms), starting from latency_ms"}),
    bind<STEMD_ITEM(actuation.tools, latency_min_ms)>(
        {"tools[].latency_min_ms", real, "ms", 0, 1000, "0", "",
            "learn_latency: the learned latency never goes below this"}),
    bind<STEMD_ITEM(actuation.tools, latency_max_ms)>(
        {"tools[].latency_max_ms", real, "ms", 0, 1000, "200", "",
            "learn_latency: the learned latency never goes above this (at least latency_min_ms)"}),
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
    for (const KeySpec& spec : kSchema)
        if (spec.key == key)
            return &spec;
    return nullptr;
}

std::span<const ListSpec> list_schema()
{
    return kLists;
}

const ListSpec* find_list(std::string_view section)
{
    for (const ListSpec& list : kLists)
        if (list.section == section)
            return &list;
    return nullptr;
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
    for (const KeySpec& spec : item_keys(section))
        if (item_leaf_of(spec) == item_key)
            return &spec;
    return nullptr;
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

std::string schema_markdown()
{
    std::string out =
        "| key | type | unit | default | range / choices | meaning |\n"
        "|---|---|---|---|---|---|\n";
    const auto row = [&out](const KeySpec& spec) {
        std::string range;
        if (spec.type == integer || spec.type == real)
            range = detail::bounds_text(spec);
        else if (spec.type == choice)
            range = cat("`", list_choices(spec, "`, `"), "`");
        else if (spec.type == boolean)
            range = "`true`, `false`";
        out += cat("| `", spec.key, "` | ", to_string(spec.type), " | ", spec.unit, " | `", spec.default_value,
                   "` | ", range, " | ", spec.help, " |\n");
    };
    for (const KeySpec& spec : kSchema)
        row(spec);
    for (const KeySpec& spec : kItemSchema)
        row(spec);
    return out;
}

}  // namespace stemd::config
