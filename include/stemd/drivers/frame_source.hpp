// The frame-source interface: every camera backend (drivers/v4l2,
// drivers/libcamera, drivers/replay) fills caller-owned, preallocated frames.
// It knows nothing of the runtime that calls it.
//
// Life cycle, driven by one thread (the capture thread):
//   open() -> start() -> next()... -> stop()
// next() writes pixels into the Frame it is given and never reallocates its
// planes: a frame that does not fit them is counted and skipped.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string_view>

#include <opencv2/core/mat.hpp>

#include "stemd/drivers/source_counters.hpp"
#include "stemd/base/non_copyable.hpp"

namespace stemd::drivers {

// A frame's name for logs and CSVs (replay: the rgb path as written in
// frames.csv), inline so that naming a frame never touches the heap.
class FrameName {
public:
    static constexpr std::size_t kCapacity = 255;
    // Longer names are truncated; truncated() says so.
    void assign(std::string_view name)
    {
        size_ = name.size() < kCapacity ? name.size() : kCapacity;
        truncated_ = name.size() > kCapacity;
        name.copy(chars_.data(), size_);
    }
    std::string_view view() const { return {chars_.data(), size_}; }
    bool truncated() const { return truncated_; }

private:
    std::array<char, kCapacity> chars_{};
    std::size_t size_ = 0;
    bool truncated_ = false;
};

// One frame slot. The owner (the runtime's frame pool) allocates the planes
// the segmentation needs once; an empty plane is one the source must not fill.
struct Frame {
    cv::Mat bgr;   // CV_8UC3
    cv::Mat nir;   // CV_8UC1, same size (NDVI only)
    cv::Mat mask;  // CV_8UC1, same size (external mask only)
    // CV_8UC1, same size, optional (the runtime allocates it only when a
    // class map is configured): per-pixel plant class, 0 soil, 1 crop,
    // 2 weed (values as PlantClass). A source without class maps
    // leaves has_class_map false.
    cv::Mat plant_class;
    bool has_class_map = false;
    // CLOCK_MONOTONIC of the exposure: the sensor's timestamp (V4L2 buffer,
    // libcamera SensorTimestamp), or when a replayed frame was handed over
    // (stamping it when it was due would count its decode as latency).
    // Latency and odometry are measured from it, as the scene is what it
    // was then.
    std::int64_t t_sample_ns = 0;
    // CLOCK_MONOTONIC when the source handed the frame over; later than
    // t_sample_ns by the driver's queueing.
    std::int64_t t_delivered_ns = 0;
    std::int64_t t_recorded_ns = 0;  // the frame's own time: the camera's timestamp, or a recording's t_ns
    // The odometer at capture (mm, monotonic) when the source knows it (a
    // recording's odom_mm column); NaN otherwise.
    double odom_mm = std::numeric_limits<double>::quiet_NaN();
    // A source that knows the odometer ahead of the next frame (a paced
    // replay of a recording with odom_mm: the track it samples): that
    // odometer and when it is reached; NaN (and 0) otherwise.
    std::int64_t t_next_ns = 0;
    double odom_next_mm = std::numeric_limits<double>::quiet_NaN();
    std::uint64_t source_seq = 0;    // the source's frame counter (gaps = frames the source lost)
    std::uint64_t seq = 0;           // set by the runtime: frames captured before this one
    FrameName name;
};

enum class NextStatus : std::uint8_t {
    frame,          // `into` holds a new frame
    timeout,        // nothing within the timeout; call again
    skipped,        // a corrupt or unfitting frame was counted and skipped; call again
    end_of_stream,  // a finite source (replay once) has no more frames
    failed,         // the source failed (already logged); stop using it
};

class FrameSource : base::NonCopyable {
public:
    virtual ~FrameSource() = default;

    // "replay:/path/to/recording", "v4l2:/dev/video0"... for logs.
    virtual std::string_view name() const = 0;

    // Opens the device or recording. Errors are logged where they occur,
    // naming the device or file (and errno); false means the source is unusable.
    virtual bool open() = 0;
    virtual bool start() = 0;

    // Waits at most `timeout` for the next frame and writes it into `into`
    // (including t_sample_ns and t_delivered_ns).
    virtual NextStatus next(Frame& into, std::chrono::nanoseconds timeout) = 0;

    virtual void stop() = 0;

    virtual SourceCounters counters() const = 0;

    // True while the source has lost its device and is reopening it (no
    // frames until it is back). Called by the thread that calls next().
    virtual bool lost() const { return false; }

    // True: frames come on their own clock (a camera, paced replay) and a
    // full ring must drop one. False: the source can wait (fast replay), so
    // the capture thread applies back-pressure and drops nothing.
    virtual bool realtime() const = 0;
};

}  // namespace stemd::drivers
