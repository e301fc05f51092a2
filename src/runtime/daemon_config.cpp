#include "stemd/runtime/daemon_config.hpp"

#include "stemd/runtime/vision_config.hpp"

namespace stemd::runtime {

DaemonConfig daemon_config(const config::Config& config)
{
    DaemonConfig d;
    d.source_kind = config.get_text("source.kind");
    d.replay_dir = config.get_text("source.replay_dir");
    if (d.replay_dir == "none")
        d.replay_dir.clear();
    d.replay_fast = config.get_text("source.replay_pacing") == "fast";
    d.replay_loop = config.get_bool("source.replay_loop");
    d.replay_preload = config.get_bool("source.replay_preload");
    d.v4l2_device = config.get_text("source.v4l2_device");
    d.v4l2_pixel_format = config.get_text("source.v4l2_pixel_format");
    d.v4l2_buffers = static_cast<unsigned>(config.get_int("source.v4l2_buffers"));
    d.nir_device = config.get_text("source.nir_device");
    if (d.nir_device == "none")
        d.nir_device.clear();
    d.nir_tolerance_ms = config.get_real("source.nir_tolerance_ms");
    d.libcamera_camera = config.get_text("source.libcamera_camera");
    d.fps = config.get_real("source.fps");
    d.frame_size = {static_cast<int>(config.get_int("source.width_px")),
                    static_cast<int>(config.get_int("source.height_px"))};
    d.ring_capacity = static_cast<std::size_t>(config.get_int("ring.capacity"));
    d.overflow = config.get_text("ring.overflow") == "overwrite_oldest" ? OverflowPolicy::overwrite_oldest
                                                                        : OverflowPolicy::drop_newest;
    d.results_capacity = static_cast<std::size_t>(config.get_int("ring.results_capacity"));
    d.capture = {static_cast<int>(config.get_int("threads.capture_priority")),
                 static_cast<int>(config.get_int("threads.capture_cpu"))};
    d.processing = {static_cast<int>(config.get_int("threads.processing_priority")),
                    static_cast<int>(config.get_int("threads.processing_cpu"))};
    d.actuator = {static_cast<int>(config.get_int("threads.actuator_priority")),
                  static_cast<int>(config.get_int("threads.actuator_cpu"))};
    d.mlockall = config.get_bool("threads.mlockall");
    d.status_interval_s = config.get_real("status.interval_s");
    d.log_level = config.get_text("log.level");
    d.vision = config::vision_params(config);
    return d;
}

}  // namespace stemd::runtime
