// The frame source a configuration names (v4l2, with a paired NIR camera or
// not; libcamera; replay), built from plain settings. The runtime maps its
// configuration onto SourceSpec, so the backends' own headers stay private
// to drivers/.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include <opencv2/core/types.hpp>
#include <spdlog/logger.h>

#include "stemd/drivers/frame_source.hpp"

namespace stemd::drivers {

// Makes the logger a backend logs to, given the backend's name ("v4l2").
using MakeLogger = std::function<std::shared_ptr<spdlog::logger>(const std::string& name)>;

struct SourceSpec {
    std::string kind = "replay";           // v4l2 | libcamera | replay; anything else builds replay
    cv::Size frame_size{};
    double fps = 30;
    std::string v4l2_device;
    std::string v4l2_pixel_format = "yuyv";  // yuyv | bgr24 | grey; unknown: yuyv
    unsigned v4l2_buffers = 4;
    double reopen_backoff_max_ms = 5000;   // v4l2: cap of the reopen backoff
    std::string nir_device;                // v4l2 only; empty: no NIR camera
    double nir_tolerance_ms = 8;
    std::string libcamera_camera;
    std::string replay_dir;
    bool replay_fast = false;              // as fast as taken, else paced by the recording's t_ns
    bool replay_loop = false;
    bool replay_preload = false;
    // Polled between the slow steps of open() (each frame a replay
    // preloads); true makes open() give up and fail. Empty: never.
    std::function<bool()> cancelled{};
};

// The source, not yet opened; loggers are named after the backend ("v4l2",
// "libcamera", "replay"). libcamera in a build without it builds replay:
// the caller checks STEMD_HAVE_LIBCAMERA first.
std::unique_ptr<FrameSource> make_frame_source(const SourceSpec& spec, const MakeLogger& make_logger);

}  // namespace stemd::drivers
