// The daemon's configuration: the source.*, ring.*, threads.*, status.*
// and log.* keys (and the pipeline's keys), filled by config::Config.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include <opencv2/core/types.hpp>

#include "stemd/base/enum_names.hpp"
#include "stemd/geometry/camera_model.hpp"
#include "stemd/runtime/frame_pool.hpp"
#include "stemd/runtime/web_config.hpp"
#include "stemd/vision/cells.hpp"
#include "stemd/vision/types.hpp"

namespace stemd::runtime {

enum class OverflowPolicy : std::uint8_t {
    drop_newest,       // a full frame ring drops the frame just captured
    overwrite_oldest,  // a full frame ring gives up its oldest frame for the new one
};
inline constexpr base::EnumName<OverflowPolicy> kOverflowPolicyNames[]{
    {OverflowPolicy::drop_newest, "drop_newest"}, {OverflowPolicy::overwrite_oldest, "overwrite_oldest"}};

// Real-time settings of one thread; priority 0 and cpu -1 leave it alone.
struct ThreadSettings {
    int fifo_priority = 0;   // SCHED_FIFO 1..99
    int cpu = -1;
};

// classify.provider: where plants' classes come from (class_provider.hpp).
enum class ClassProviderChoice : std::uint8_t {
    automatic,   // model when classify.model is set, else recording
    model,       // classify.model (required)
    recording,   // a replayed recording's class column
    socket,      // another process, over classify.socket
};
inline constexpr base::EnumName<ClassProviderChoice> kClassProviderNames[]{
    {ClassProviderChoice::automatic, "auto"}, {ClassProviderChoice::model, "model"},
    {ClassProviderChoice::recording, "recording"}, {ClassProviderChoice::socket, "socket"}};

// classify.*: the crop/weed model of vision/classify, or another provider.
struct ClassifyConfig {
    ClassProviderChoice provider = ClassProviderChoice::automatic;
    std::string socket;                 // empty: none
    double provider_timeout_ms = 100;   // socket: a frame's classes after this are unknown
    std::string model;             // empty: none
    double min_confidence = 0.6;   // probability
    double weed_confidence = 0.85;   // probability
    bool weed_parts = true;               // weed cells of crop/unknown plants become targets (vision::add_weed_parts)
    double weed_part_clearance_mm = 3;    // no crop or unknown vegetation this near a weed part's target
    double weed_cover_radius_mm = 0;      // a wider weed gets further targets; 0: one per weed
    unsigned max_targets_per_weed = 16;   // with weed_cover_radius_mm, the first included
    std::size_t max_cells = 4096;         // vegetated cells classified per frame, those nearest the entry edge first
};

// The image edge plants enter the view by: the one the direction of travel
// points to (camera.forward up: they come in at the top).
inline vision::ImageEdge entry_edge(geometry::Forward forward)
{
    switch (forward) {
    case geometry::Forward::up: return vision::ImageEdge::top;
    case geometry::Forward::down: return vision::ImageEdge::bottom;
    case geometry::Forward::left: return vision::ImageEdge::left;
    case geometry::Forward::right: return vision::ImageEdge::right;
    }
    return vision::ImageEdge::top;
}

// vision::classify_frame()'s settings from classify.* and camera.forward.
inline vision::ModelClassParams model_class_params(const ClassifyConfig& config, geometry::Forward forward)
{
    return {.decision = {.min_confidence = config.min_confidence,
                         .weed_confidence = config.weed_confidence,
                         .clearance_mm = config.weed_part_clearance_mm,
                         .cover_radius_mm = config.weed_cover_radius_mm,
                         .max_targets_per_weed = config.max_targets_per_weed},
            .weed_parts = config.weed_parts,
            .budget = {.max_cells = config.max_cells, .first_edge = entry_edge(forward)}};
}

struct DaemonConfig {
    // source.*
    std::string source_kind = "replay";
    std::string replay_dir;          // empty: not set (none)
    bool replay_fast = false;        // source.replay_pacing: fast (true) or recorded
    bool replay_loop = true;
    bool replay_preload = false;
    std::string v4l2_device = "/dev/video0";
    std::string v4l2_pixel_format = "yuyv";   // yuyv | bgr24 | grey
    unsigned v4l2_buffers = 4;
    double reopen_backoff_max_ms = 250;       // v4l2: longest wait between reopen attempts
    double lost_after_ms = 1000;              // no frame this long: the HEARTBEAT says CAMERA_LOST
    std::string nir_device;                   // empty: no NIR camera (none)
    double nir_tolerance_ms = 8;
    std::string libcamera_camera = "0";       // libcamera: index, id, or unique part of the id
    double fps = 30;
    cv::Size frame_size{1296, 966};
    // ring.*
    std::size_t ring_capacity = 4;
    OverflowPolicy overflow = OverflowPolicy::drop_newest;
    std::size_t results_capacity = 4;
    // threads.*
    ThreadSettings capture, processing, actuator;
    bool mlockall = false;
    // status.*, log.*
    double status_interval_s = 5.0;
    std::string log_level = "info";
    // debug.*: after this many frames the processing thread stops making
    // progress (0: never), to test the systemd watchdog contract.
    std::size_t stall_processing_after_frames = 0;
    // Allocate a class-map plane per frame slot (replay of recordings with a
    // class column, for the actuation's policy).
    bool class_maps = false;
    // The frame slots' shape (FramePool): the daemon's and the live feed's.
    FrameShape frame_shape() const { return {frame_size, vision.segmentation, class_maps}; }
    ClassifyConfig classify;
    // web.*
    WebConfig web;
    // The pipeline's keys (camera.*, segment.*, closing.*, ...).
    vision::Params vision;
};

}  // namespace stemd::runtime
