#include "stemd/runtime/source_factory.hpp"

#include <algorithm>

// STEMD_HAVE_LIBCAMERA comes from stemd_drivers: libcamera is optional.
#include "stemd/drivers/source_factory.hpp"
#include "stemd/io/recording.hpp"
#include "stemd/runtime/logging.hpp"

namespace stemd::runtime {

std::optional<std::string> check_source_config(const DaemonConfig& d, const config::Config& config,
                                               bool replay_from_cli, bool check_only)
{
    if (d.source_kind == "replay" && !d.replay_dir.empty() && !io::is_recording_dir(d.replay_dir)) {
        const std::string where = replay_from_cli ? "--replay" : config.origin_of("source.replay_dir");
        return where + ": key 'source.replay_dir': " + d.replay_dir + " is not a recording directory (no frames.csv)";
    }
    if (d.source_kind == "replay" && d.replay_dir.empty() && !check_only)
        return std::string("no frame source: give --replay DIR or set source.replay_dir");
    // --- libcamera source
    if (d.source_kind == "libcamera" && !STEMD_HAVE_LIBCAMERA)
        return config.origin_of("source.kind") +
               ": key 'source.kind': libcamera: this stemd was built without libcamera (install libcamera-dev and rebuild)";
    // NIR: a second V4L2 camera, or none (then NDVI needs a recording with nir).
    const bool nir = vision::uses_nir(d.vision.segmentation);
    if (d.source_kind == "v4l2" && nir && d.nir_device.empty())
        return config.origin_of("segment.method") + ": key 'segment.method': " +
               std::string(vision::to_string(d.vision.segmentation)) +
               " with source.kind v4l2 needs a NIR camera (source.nir_device)";
    if (d.source_kind == "v4l2" && !d.nir_device.empty()) {
        if (d.nir_device == d.v4l2_device)
            return config.origin_of("source.nir_device") + ": key 'source.nir_device': " + d.nir_device +
                   " is also source.v4l2_device; the NIR camera must be a second device";
        if (d.nir_tolerance_ms >= 500.0 / d.fps)
            return config.origin_of("source.nir_tolerance_ms") + ": key 'source.nir_tolerance_ms': " +
                   config::format_number(d.nir_tolerance_ms) + " ms is not under half the frame period (" +
                   config::format_number(500.0 / d.fps) + " ms at source.fps " + config::format_number(d.fps) + ")";
    }
    if (d.source_kind != "v4l2" && !d.nir_device.empty())
        return config.origin_of("source.nir_device") +
               ": key 'source.nir_device': a NIR camera needs source.kind v4l2";
    return std::nullopt;
}

std::string resolve_auto_segmentation(DaemonConfig& d)
{
    if (d.vision.segmentation != vision::Segmentation::automatic)
        return {};
    std::string why;
    bool nir = false;
    if (d.source_kind == "v4l2") {
        nir = !d.nir_device.empty();
        why = nir ? "a NIR camera (source.nir_device " + d.nir_device + ")" : "no NIR camera (source.nir_device)";
    } else if (d.source_kind == "replay") {
        std::string error;
        const auto recording = d.replay_dir.empty() ? std::nullopt : io::read_recording(d.replay_dir, error);
        nir = recording && !recording->frames.empty() &&
              std::all_of(recording->frames.begin(), recording->frames.end(),
                          [](const io::RecordingFrame& f) { return !f.nir.empty(); });
        why = nir ? "every replayed frame has a nir image" : "not every replayed frame has a nir image";
    } else {
        why = "source.kind " + d.source_kind + " delivers no NIR plane";
    }
    d.vision.segmentation = vision::resolve_segmentation(d.vision.segmentation, nir);
    return "segment.method auto: " + std::string(vision::to_string(d.vision.segmentation)) + " (" + why + ")";
}

std::string resolve_auto_odometry(const DaemonConfig& d, ActuationConfig& actuation)
{
    if (actuation.odometry != OdometrySource::automatic)
        return {};
    std::string error;
    const auto recording = d.source_kind == "replay" && !d.replay_dir.empty()
                               ? io::read_recording(d.replay_dir, error)
                               : std::nullopt;
    const auto frames_with_odom =
        recording ? std::count_if(recording->frames.begin(), recording->frames.end(),
                                  [](const io::RecordingFrame& f) { return f.odom_mm.has_value(); })
                  : 0;
    if (frames_with_odom > 0) {
        actuation.odometry = OdometrySource::recording;
        return "odometry.source auto: recording (" + std::to_string(frames_with_odom) + " of " +
               std::to_string(recording->frames.size()) + " replayed frames carry odom_mm; the others are not actuated)";
    }
    actuation.odometry = OdometrySource::constant;
    return "odometry.source auto: constant at odometry.speed_mm_per_s (" +
           std::string(d.source_kind == "replay" ? "the replayed frames carry no odom_mm" : "a camera has no odometer") +
           ")";
}

std::unique_ptr<drivers::FrameSource> make_frame_source(const DaemonConfig& config, std::function<bool()> cancelled)
{
    drivers::SourceSpec spec;
    spec.kind = config.source_kind;
    spec.frame_size = config.frame_size;
    spec.fps = config.fps;
    spec.v4l2_device = config.v4l2_device;
    spec.v4l2_pixel_format = config.v4l2_pixel_format;
    spec.v4l2_buffers = config.v4l2_buffers;
    spec.reopen_backoff_max_ms = config.reopen_backoff_max_ms;
    spec.nir_device = config.nir_device;
    spec.nir_tolerance_ms = config.nir_tolerance_ms;
    spec.libcamera_camera = config.libcamera_camera;
    spec.replay_dir = config.replay_dir;
    spec.replay_fast = config.replay_fast;
    spec.replay_loop = config.replay_loop;
    spec.replay_preload = config.replay_preload;
    spec.cancelled = std::move(cancelled);
    return drivers::make_frame_source(spec, make_logger);
}

}  // namespace stemd::runtime
