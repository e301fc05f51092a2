#include "stemd/runtime/source_factory.hpp"

#include <chrono>
#include <cmath>
#include <utility>

#include "replay/replay_source.hpp"
#include "v4l2/paired_nir_source.hpp"
#include "v4l2/v4l2_source.hpp"
// --- libcamera source (built only with libcamera; STEMD_HAVE_LIBCAMERA from stemd_drivers)
#if STEMD_HAVE_LIBCAMERA
#include "libcamera/libcamera_source.hpp"
#endif
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

std::unique_ptr<drivers::FrameSource> make_frame_source(const DaemonConfig& config)
{
    if (config.source_kind == "v4l2") {
        drivers::V4l2Options v4l2;
        v4l2.device = config.v4l2_device;
        // The schema allows only the formats the source knows.
        v4l2.pixel_format =
            drivers::parse_v4l2_pixel_format(config.v4l2_pixel_format).value_or(drivers::V4l2PixelFormat::yuyv);
        v4l2.buffers = config.v4l2_buffers;
        v4l2.size = config.frame_size;
        v4l2.fps = config.fps;
        if (!config.nir_device.empty()) {
            // Paired by capture time; the NIR device's format and size are forced (GREY, same size).
            drivers::PairedNirOptions paired;
            paired.rgb = v4l2;
            paired.nir = v4l2;
            paired.nir.device = config.nir_device;
            paired.tolerance = std::chrono::microseconds(std::llround(config.nir_tolerance_ms * 1000));
            return std::make_unique<drivers::PairedNirSource>(std::move(paired), make_logger("v4l2"));
        }
        return std::make_unique<drivers::V4l2Source>(std::move(v4l2), make_logger("v4l2"));
    }
#if STEMD_HAVE_LIBCAMERA
    if (config.source_kind == "libcamera") {  // --- libcamera source
        drivers::LibcameraOptions libcamera;
        libcamera.camera = config.libcamera_camera;
        libcamera.size = config.frame_size;
        libcamera.fps = config.fps;
        return std::make_unique<drivers::LibcameraSource>(std::move(libcamera), make_logger("libcamera"));
    }
#endif
    drivers::ReplayOptions replay;
    replay.dir = config.replay_dir;
    replay.pacing = config.replay_fast ? drivers::ReplayOptions::Pacing::fast : drivers::ReplayOptions::Pacing::recorded;
    replay.loop = config.replay_loop;
    replay.preload = config.replay_preload;
    replay.frame_size = config.frame_size;
    return std::make_unique<drivers::ReplaySource>(replay, make_logger("replay"));
}

}  // namespace stemd::runtime
