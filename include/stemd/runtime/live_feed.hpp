// What the daemon shows the live view, handed over without touching the
// real-time path. The processing thread publishes the latest frame into a
// triple buffer (at most web.fps times a second, only while a viewer asked
// for frames recently, and after the frame's result is on its way to the
// actuator). The image is not copied: the frame slot itself is lent to the
// feed, which gives back in exchange a slot the viewer can no longer see
// (the feed holds three slots of the daemon's shape, allocated here). Only
// the frame's plants and closed mask are copied (~0.2 MB at 1296x966,
// against 3.8 MB for the image). The actuator thread pushes each plant
// whose track ended into a lock-free ring, and each target it decided into
// another. The web thread reads them all; drawing and JPEG encoding happen
// there.
#pragma once

#include <atomic>
#include <cstdint>

#include <opencv2/core/mat.hpp>

#include "stemd/base/plant_class.hpp"
#include "stemd/base/spsc_ring.hpp"
#include "stemd/base/triple_buffer.hpp"
#include "stemd/drivers/frame_source.hpp"
#include "stemd/runtime/frame_pool.hpp"
#include "stemd/runtime/plant_map.hpp"
#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/types.hpp"

namespace stemd::runtime {

// One frame as the processing thread saw it.
struct LiveFrame {
    // The frame slot lent to the feed: its image is the view's (has_image:
    // a 3-channel image of the feed's size). Never written while it is here.
    drivers::Frame* frame = nullptr;
    bool has_image = false;
    std::uint64_t seq = 0;
    std::int64_t t_sample_ns = 0;
    std::int64_t t_published_ns = 0;
    double odom_mm = 0;                // NaN if unknown
    drivers::FrameName name;
    vision::BitMask closed;            // the closed mask the plants came from
    vision::Detections detections;
    bool has_class = false;
    std::array<PlantClass, vision::kMaxPlants> plant_class{};
};

// One plant of the plant map (as --map writes it).
struct LivePlant {
    std::int32_t id = -1;              // TARGET target_id, -1 never confirmed
    double s_mm = 0, y_mm = 0;
    PlantClass plant_class = PlantClass::Unknown;
    std::uint8_t leaves = 0;
    std::uint32_t sightings = 0;
    std::uint64_t first_frame = 0, last_frame = 0;
    MapEntry entry;                    // reason, tool, lane, fire_odom_mm
};

// One target as the actuator decided it (field coordinates).
struct LiveTarget {
    std::uint16_t target_id = 0;
    double s_mm = 0, y_mm = 0;
    MapReason reason = MapReason::pending;   // sent, or why not (spared: policy, no_tool, disabled; missed)
    // The actuator's odometer at the deciding frame's capture, and its speed:
    // where frames without their own odometer reading were taken.
    std::int64_t t_sample_ns = 0;
    double odom_at_capture_mm = 0;
    double speed_mm_per_s = 0;
};

class LiveFeed {
public:
    // Allocates the three frame slots it lends in exchange, of the daemon's
    // `shape` (DaemonConfig::frame_shape()), three masks and the plant and
    // target rings.
    LiveFeed(const FrameShape& shape, int fps, std::size_t plant_capacity);

    // --- processing thread ------------------------------------------------------
    // True if a viewer asked for frames within the last 2 s and 1/fps has
    // passed since the last publication.
    bool frame_due(std::int64_t now_ns) const
    {
        return now_ns < wanted_until_ns_.load(std::memory_order_relaxed) &&
               now_ns - last_published_ns_ >= min_interval_ns_;
    }
    // Takes `frame` (a slot of the shape given to the constructor) for the
    // viewer with a copy of its plants and closed mask, publishes it, and
    // returns a slot the viewer can no longer see, which takes the frame's
    // place in the caller's pool. No allocation; the image is not copied
    // (frames of another size or type are published without their image).
    drivers::Frame* publish(drivers::Frame* frame, const vision::Detections& detections,
                            const vision::BitMask& closed, const PlantClass* plant_class, bool has_class,
                            std::int64_t now_ns);

    // --- actuator thread --------------------------------------------------------
    // False (counted) if the ring is full: the web thread is behind.
    bool push_plant(const LivePlant& plant) { return plants_.try_push(plant); }
    bool push_target(const LiveTarget& target) { return targets_.try_push(target); }

    // --- web thread -------------------------------------------------------------
    void want_frames(std::int64_t now_ns) { wanted_until_ns_.store(now_ns + kWantNs, std::memory_order_relaxed); }
    bool take_frame() { return frames_.take(); }
    const LiveFrame& frame() const { return frames_.read_slot(); }
    bool pop_plant(LivePlant& out) { return plants_.try_pop(out); }
    bool pop_target(LiveTarget& out) { return targets_.try_pop(out); }

    // Any thread.
    std::uint64_t frames_published() const { return frames_.published(); }
    std::uint64_t plants_dropped() const { return plants_.dropped(); }
    cv::Size frame_size() const { return frame_size_; }
    const FrameShape& shape() const { return spare_slots_.shape(); }

private:
    static constexpr std::int64_t kWantNs = 2'000'000'000;
    const cv::Size frame_size_;
    const std::int64_t min_interval_ns_;
    std::int64_t last_published_ns_ = -(std::int64_t{1} << 62);   // the processing thread's
    std::atomic<std::int64_t> wanted_until_ns_{0};
    FramePool spare_slots_;   // lent in exchange for the first frames; then they circulate
    base::TripleBuffer<LiveFrame> frames_;
    base::SpscRing<LivePlant> plants_;
    base::SpscRing<LiveTarget> targets_;
};

}  // namespace stemd::runtime
