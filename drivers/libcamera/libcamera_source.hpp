// libcamera: a camera behind libcamera's C++ API (Debian 12: libcamera 0.0.3)
// as a frame source. Built only when pkg-config finds libcamera
// (STEMD_HAVE_LIBCAMERA); without it, source.kind: libcamera is an error.
//
// State machine (one thread, the capture thread, drives it):
//   closed -> opened (open(): manager started, camera acquired and
//             configured, buffers allocated and mapped, requests built)
//          -> streaming (start(): camera started, every request queued)
//   streaming -> backoff (the camera is lost: Camera::disconnected or
//             CameraManager::cameraRemoved for it, max_failed_requests
//             requests in a row completing with an error, no frame within
//             first_frame_timeout of a (re)start or within stall_timeout of
//             the last one, or a requeue/poll failure; logged once with the
//             camera's id and the reason): everything is released in order
//             (as stop()), and next() retries finding the camera by its id
//             (the configured selector before the first open) with a fresh
//             CameraManager on the ReopenBackoff schedule (reopen_min doubling
//             up to reopen_max, include/stemd/drivers/reopen_backoff.hpp).
//             While down next() waits at most its timeout and returns
//             `timeout`, so the daemon keeps running; a failed attempt is
//             logged when its reason changes; a successful one is logged and
//             counted (reopens).
//   One case does not recover: libcamera 0.0.3 can neither stop nor destroy
//   a running camera whose device nodes vanished while a request was still
//   queued in the driver (it aborts); the source then logs it, leaves the
//   camera alone and goes to `failed` (next() returns `failed`).
//   open() or start() failing at start is a configuration error: `failed`,
//   reported once, no retry (next() returns `failed`).
//   stop(): back to closed from any state, releasing everything in order
//   (camera stopped, requests, mappings, buffers, camera, manager).
// Without udev (a bare container, the test VM) libcamera sees no hot-unplug
// and emits neither signal: the stall timeouts are what notice the loss.
//
// Camera selection (source.libcamera_camera): all digits -> the index in
// CameraManager::cameras() (sorted by libcamera); otherwise the camera
// whose id is exactly that text; otherwise the one camera whose id contains
// it (several -> an error listing them). No match is an error listing the
// cameras present.
//
// Stream: one Viewfinder stream of the configured size, pixel format
// formats::RGB888. libcamera's formats follow DRM fourccs, which name the
// components of a little-endian word from the most significant end:
// RGB888 is stored B, G, R in memory (V4L2's BGR24) = OpenCV's BGR, so it is
// copied as is; BGR888 (stored R, G, B) is accepted too and swapped. The VM
// check (test/vm/libcamera_source_check.cpp) confirms the order on vimc's
// colour bars. Size adjusted by the camera, or another format -> error.
//
// Threads: libcamera completes requests on its own thread; requestCompleted
// only pushes the request's index (its cookie) into a lock-free SPSC ring and
// writes an eventfd. next() pops an index (waiting on the eventfd with
// poll() up to its timeout), copies the mmapped plane into the caller's slot
// and requeues the request. No locks on the per-frame path.
//
// Times: t_sample_ns = t_recorded_ns = the request's SensorTimestamp
// metadata (CLOCK_MONOTONIC ns; capped at the dequeue time) when present,
// else CLOCK_MONOTONIC at dequeue (counted as `unstamped`); t_delivered_ns
// = the dequeue time. source_seq = the buffer's sequence number.
//
// Skipped frames: request status cancelled, frame status not success, or
// too few bytes -> corrupt; a slot of another size or type -> bad_size.
// Both are counted and the request is queued again.
//
// Where it allocates: open() (manager, configuration, buffers, requests),
// start() and every reopen. next() allocates nothing itself; Camera::queueRequest() is
// libcamera's and may.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core/mat.hpp>
#include <spdlog/logger.h>

#include "stemd/drivers/frame_source.hpp"
#include "stemd/drivers/reopen_backoff.hpp"
#include "stemd/drivers/skipped_frame_log.hpp"

namespace stemd::drivers {

// Byte order of a packed 24-bit RGB plane in memory.
enum class LibcameraByteOrder : std::uint8_t {
    bgr,  // libcamera formats::RGB888 (DRM_FORMAT_RGB888)
    rgb,  // libcamera formats::BGR888 (DRM_FORMAT_BGR888)
};

enum class PlaneStatus : std::uint8_t { ok, bad_size, corrupt };

// Copies (bgr) or swaps (rgb) one packed 24-bit plane of `size`, rows
// `stride` bytes apart and `bytesused` bytes long, into `bgr`, which must
// already be CV_8UC3 of `size` (else bad_size, untouched). Too few bytes:
// corrupt. Writes into bgr's buffer; never reallocates it.
PlaneStatus copy_plane_to_bgr(const std::uint8_t* data, std::size_t bytesused, std::size_t stride, cv::Size size,
                              LibcameraByteOrder order, cv::Mat& bgr);

// Which of `ids` `wanted` selects (rules above); nullopt and `why` set if none.
std::optional<std::size_t> select_camera(const std::vector<std::string>& ids, std::string_view wanted,
                                         std::string& why);

// The capture time of a completed request: the sensor's timestamp (ns,
// CLOCK_MONOTONIC) capped at `now_ns`, else `now_ns`.
std::int64_t libcamera_capture_time_ns(std::optional<std::int64_t> sensor_timestamp_ns, std::int64_t now_ns);

// Why a streaming camera counts as lost (none: it is healthy).
enum class StreamLoss : std::uint8_t { none, no_first_frame, stalled, failed_requests };
std::string_view to_string(StreamLoss loss);

// Decides from request completions and the time when a streaming camera
// counts as lost. Pure: times are CLOCK_MONOTONIC ns passed in. A limit of 0
// is off.
class StreamWatchdog {
public:
    StreamWatchdog(std::int64_t first_frame_ns, std::int64_t stall_ns, std::uint32_t max_failed_requests)
        : first_frame_ns_(first_frame_ns), stall_ns_(stall_ns), max_failed_(max_failed_requests)
    {
    }
    // Streaming (re)started at now_ns: waiting for the first frame.
    void started(std::int64_t now_ns)
    {
        since_ns_ = now_ns;
        got_frame_ = false;
        failed_in_row_ = 0;
    }
    // A request completed with a good frame.
    void frame(std::int64_t now_ns)
    {
        since_ns_ = now_ns;
        got_frame_ = true;
        failed_in_row_ = 0;
    }
    // A request completed cancelled or with a frame error.
    void failed_request() { ++failed_in_row_; }
    StreamLoss check(std::int64_t now_ns) const
    {
        if (max_failed_ > 0 && failed_in_row_ >= max_failed_)
            return StreamLoss::failed_requests;
        const std::int64_t limit = got_frame_ ? stall_ns_ : first_frame_ns_;
        if (limit > 0 && now_ns - since_ns_ >= limit)
            return got_frame_ ? StreamLoss::stalled : StreamLoss::no_first_frame;
        return StreamLoss::none;
    }
    // The limit check() applies now (ns since the last frame or the start).
    std::int64_t limit_ns() const { return got_frame_ ? stall_ns_ : first_frame_ns_; }
    std::uint32_t failed_in_row() const { return failed_in_row_; }

private:
    std::int64_t first_frame_ns_;
    std::int64_t stall_ns_;
    std::uint32_t max_failed_;
    std::int64_t since_ns_ = 0;
    bool got_frame_ = false;
    std::uint32_t failed_in_row_ = 0;
};

struct LibcameraOptions {
    std::string camera = "0";     // index or id (rules above)
    cv::Size size{640, 480};      // the camera must take it exactly
    double fps = 30;              // FrameDurationLimits when the camera has it; 0: leave it
    // Loss detection while streaming (0: off) and the reopen schedule.
    std::chrono::nanoseconds first_frame_timeout = std::chrono::seconds(5);
    std::chrono::nanoseconds stall_timeout = std::chrono::seconds(2);
    std::uint32_t max_failed_requests = 8;  // completed with an error in a row
    std::chrono::nanoseconds reopen_min = std::chrono::milliseconds(100);
    std::chrono::nanoseconds reopen_max = std::chrono::seconds(5);
};

// The common counters (corrupt: cancelled or failed requests, short frames;
// reopens: after a loss) and libcamera's own.
struct LibcameraCounters : SourceCounters {
    std::uint64_t unstamped = 0;   // delivered frames without SensorTimestamp (stamped at dequeue)
    std::uint64_t lost = 0;        // times the streaming camera was lost (released, then retried)
};

class LibcameraSource final : public FrameSource {
public:
    enum class State : std::uint8_t { closed, opened, streaming, failed, backoff };

    LibcameraSource(LibcameraOptions options, std::shared_ptr<spdlog::logger> log);
    ~LibcameraSource() override;

    // "libcamera:<option>" until open() has found the camera, then "libcamera:<id>".
    std::string_view name() const override { return name_; }
    bool open() override;
    bool start() override;
    NextStatus next(Frame& into, std::chrono::nanoseconds timeout) override;
    void stop() override;
    SourceCounters counters() const override;
    bool realtime() const override { return true; }
    bool lost() const override { return state_ == State::backoff || state_ == State::failed; }

    LibcameraCounters libcamera_counters() const;
    State state() const { return state_; }
    // Valid once open() succeeded.
    const std::string& camera_id() const { return camera_id_; }
    LibcameraByteOrder byte_order() const { return order_; }
    std::size_t buffer_count() const;

private:
    struct Impl;  // libcamera objects; keeps libcamera's headers out of this one

    // Finds, acquires and configures the camera `selector` names (state opened).
    bool open_camera(const std::string& selector);
    // Starts the camera and queues every request (state streaming).
    bool start_camera();
    void close_camera();
    // Counts and logs an error: at error level, or (while reopening) as the
    // reason of the failed attempt, logged when it changes.
    bool error(const std::string& what);
    // The streaming camera is lost: log, release, schedule the reopen.
    NextStatus lose(const std::string& why);
    // In backoff: waits for the reopen to be due, tries it.
    NextStatus try_reopen(std::chrono::nanoseconds timeout);

    const LibcameraOptions options_;
    const std::shared_ptr<spdlog::logger> log_;
    std::string name_;
    std::string camera_id_;
    State state_ = State::closed;
    LibcameraByteOrder order_ = LibcameraByteOrder::bgr;
    std::unique_ptr<Impl> impl_;
    ReopenBackoff backoff_;
    StreamWatchdog watchdog_;
    SkippedFrameLog skipped_log_;   // failed, corrupt and wrong-size frames
    bool reopening_ = false;        // open_camera() runs as a reopen attempt
    bool wedged_ = false;           // a vanished camera libcamera cannot release (left as is)
    std::string attempt_error_;     // why the current reopen attempt failed
    std::string logged_attempt_error_;  // the last one logged

    SourceCounterCells counters_;
    std::atomic<std::uint64_t> unstamped_{0};
    std::atomic<std::uint64_t> lost_{0};
};

std::string_view to_string(LibcameraSource::State s);

}  // namespace stemd::drivers
