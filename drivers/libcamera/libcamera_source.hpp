// libcamera: a camera behind libcamera's C++ API (Debian 12: libcamera 0.0.3)
// as a frame source. Built only when pkg-config finds libcamera
// (STEMD_HAVE_LIBCAMERA); without it, source.kind: libcamera is an error.
//
// State machine (one thread, the capture thread, drives it):
//   closed -> opened (open(): manager started, camera acquired and
//             configured, buffers allocated and mapped, requests built)
//          -> streaming (start(): camera started, every request queued)
//   streaming -> failed (the camera was unplugged or a requeue failed; logged
//             with the camera's id): next() returns `failed` from then on.
//   stop(): back to closed from any state, releasing everything in order
//   (camera stopped, requests, mappings, buffers, camera, manager).
// No reopen: a camera that vanishes is reported and the source ends.
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
// Times: t_capture_ns = t_recorded_ns = the request's SensorTimestamp
// metadata (CLOCK_MONOTONIC ns; capped at the dequeue time) when present,
// else CLOCK_MONOTONIC at dequeue (counted as `unstamped`). source_seq =
// the buffer's sequence number.
//
// Skipped frames: request status cancelled, frame status not success, or
// too few bytes -> corrupt; a slot of another size or type -> bad_size.
// Both are counted and the request is queued again.
//
// Where it allocates: open() (manager, configuration, buffers, requests) and
// start(). next() allocates nothing itself; Camera::queueRequest() is
// libcamera's and may.
#pragma once

#include <atomic>
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

struct LibcameraOptions {
    std::string camera = "0";     // index or id (rules above)
    cv::Size size{640, 480};      // the camera must take it exactly
    double fps = 30;              // FrameDurationLimits when the camera has it; 0: leave it
};

struct LibcameraCounters {
    std::uint64_t frames = 0;      // frames delivered
    std::uint64_t timeouts = 0;    // next() calls that saw no frame within their timeout
    std::uint64_t errors = 0;      // failures (manager, camera, configure, mmap, queue), each logged
    std::uint64_t corrupt = 0;     // cancelled or failed requests, short frames; skipped
    std::uint64_t bad_size = 0;    // slot of another size or type, skipped
    std::uint64_t unstamped = 0;   // delivered frames without SensorTimestamp (stamped at dequeue)
};

class LibcameraSource final : public FrameSource {
public:
    enum class State : std::uint8_t { closed, opened, streaming, failed };

    LibcameraSource(LibcameraOptions options, std::shared_ptr<spdlog::logger> log);
    ~LibcameraSource() override;
    LibcameraSource(const LibcameraSource&) = delete;
    LibcameraSource& operator=(const LibcameraSource&) = delete;

    // "libcamera:<option>" until open() has found the camera, then "libcamera:<id>".
    std::string_view name() const override { return name_; }
    bool open() override;
    bool start() override;
    NextStatus next(Frame& into, std::chrono::nanoseconds timeout) override;
    void stop() override;
    SourceCounters counters() const override;
    bool realtime() const override { return true; }

    LibcameraCounters libcamera_counters() const;
    State state() const { return state_; }
    // Valid once open() succeeded.
    const std::string& camera_id() const { return camera_id_; }
    LibcameraByteOrder byte_order() const { return order_; }
    std::size_t buffer_count() const;

private:
    struct Impl;  // libcamera objects; keeps libcamera's headers out of this one

    bool open_camera();
    void close_camera();
    NextStatus fail(const std::string& what);

    const LibcameraOptions options_;
    const std::shared_ptr<spdlog::logger> log_;
    std::string name_;
    std::string camera_id_;
    State state_ = State::closed;
    LibcameraByteOrder order_ = LibcameraByteOrder::bgr;
    std::unique_ptr<Impl> impl_;

    std::atomic<std::uint64_t> frames_{0};
    std::atomic<std::uint64_t> timeouts_{0};
    std::atomic<std::uint64_t> errors_{0};
    std::atomic<std::uint64_t> corrupt_{0};
    std::atomic<std::uint64_t> bad_size_{0};
    std::atomic<std::uint64_t> unstamped_{0};
};

}  // namespace stemd::drivers
