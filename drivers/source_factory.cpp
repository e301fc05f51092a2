#include "stemd/drivers/source_factory.hpp"

#include <chrono>
#include <cmath>
#include <utility>

#include "replay/replay_source.hpp"
#include "v4l2/paired_nir_source.hpp"
#include "v4l2/v4l2_source.hpp"
#if STEMD_HAVE_LIBCAMERA
#include "libcamera/libcamera_source.hpp"
#endif

namespace stemd::drivers {

std::unique_ptr<FrameSource> make_frame_source(const SourceSpec& spec, const MakeLogger& make_logger)
{
    if (spec.kind == "v4l2") {
        V4l2Options v4l2;
        v4l2.device = spec.v4l2_device;
        // The schema allows only the formats the source knows.
        v4l2.pixel_format = parse_v4l2_pixel_format(spec.v4l2_pixel_format).value_or(V4l2PixelFormat::yuyv);
        v4l2.buffers = spec.v4l2_buffers;
        v4l2.backoff_max = std::chrono::microseconds(std::llround(spec.reopen_backoff_max_ms * 1000));
        v4l2.size = spec.frame_size;
        v4l2.fps = spec.fps;
        if (!spec.nir_device.empty()) {
            // Paired by capture time; the NIR device's format and size are forced (GREY, same size).
            PairedNirOptions paired;
            paired.rgb = v4l2;
            paired.nir = v4l2;
            paired.nir.device = spec.nir_device;
            paired.tolerance = std::chrono::microseconds(std::llround(spec.nir_tolerance_ms * 1000));
            return std::make_unique<PairedNirSource>(std::move(paired), make_logger("v4l2"));
        }
        return std::make_unique<V4l2Source>(std::move(v4l2), make_logger("v4l2"));
    }
#if STEMD_HAVE_LIBCAMERA
    if (spec.kind == "libcamera") {
        LibcameraOptions libcamera;
        libcamera.camera = spec.libcamera_camera;
        libcamera.size = spec.frame_size;
        libcamera.fps = spec.fps;
        return std::make_unique<LibcameraSource>(std::move(libcamera), make_logger("libcamera"));
    }
#endif
    ReplayOptions replay;
    replay.dir = spec.replay_dir;
    replay.pacing = spec.replay_fast ? ReplayOptions::Pacing::fast : ReplayOptions::Pacing::recorded;
    replay.loop = spec.replay_loop;
    replay.preload = spec.replay_preload;
    replay.cancelled = spec.cancelled;
    replay.frame_size = spec.frame_size;
    return std::make_unique<ReplaySource>(replay, make_logger("replay"));
}

}  // namespace stemd::drivers
