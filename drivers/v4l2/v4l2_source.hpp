// V4L2: a video capture device (/dev/videoN) as a frame source, with mmap
// streaming, a non-blocking fd and poll().
//
// State machine (one thread drives it):
//   closed -> opening -> streaming
//   streaming -> failed (an ioctl, poll or mmap error; logged with the device
//   and errno) -> backoff -> opening -> streaming | failed ...
// In backoff, next() waits (at most its timeout) until the reopen is due and
// returns `timeout`; reopen delays double from backoff_initial up to
// backoff_max and start over after a successful reopen (ReopenBackoff,
// include/stemd/drivers/reopen_backoff.hpp). The first open()
// does not retry: a device that cannot be opened or configured at start is a
// configuration error, reported once and returned as false.
//
// Pixel formats (the slot is always BGR, CV_8UC3, the configured size):
//   yuyv  -> cv::cvtColor(COLOR_YUV2BGR_YUYV) straight into the slot;
//   bgr24 -> copied into the slot;
//   grey  -> expanded into the slot with B = G = R (a monochrome camera; ExG
//            sees no vegetation in it). A GREY camera as the NIR plane of
//            an RGB+NIR pair: PairedNirSource (v4l2/paired_nir_source.hpp).
// Conversions write into the slot's own buffer and never reallocate it.
//
// Times: t_sample_ns = t_recorded_ns = the buffer's timestamp when the
// driver marks it V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC (capped at the dequeue
// time), else CLOCK_MONOTONIC at dequeue; t_delivered_ns = the dequeue time.
// source_seq = the driver's sequence number.
//
// Skipped frames: V4L2_BUF_FLAG_ERROR or bytesused != sizeimage -> corrupt;
// a slot of another size -> bad_size. Both are counted and the buffer is
// queued again.
//
// Where it allocates: open() and every reopen (the buffer table, names).
// next() allocates nothing.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
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
#include "stemd/base/unique_fd.hpp"
#include "stemd/base/mapped_memory.hpp"

struct v4l2_buffer;

namespace stemd::drivers {

enum class V4l2PixelFormat : std::uint8_t { yuyv, bgr24, grey };

// "yuyv", "bgr24", "grey" (the config's choices); nullopt otherwise.
std::optional<V4l2PixelFormat> parse_v4l2_pixel_format(std::string_view text);
std::string_view to_string(V4l2PixelFormat format);
std::uint32_t v4l2_fourcc_of(V4l2PixelFormat format);
// Bytes per pixel of the packed format (2, 3, 1).
int bytes_per_pixel(V4l2PixelFormat format);

enum class ConvertStatus : std::uint8_t { ok, bad_size, corrupt };

// Converts one frame of `format` (size `size`, rows `bytesperline` apart,
// `bytesused` bytes) into `bgr`, which must already be CV_8UC3 of `size`
// (else bad_size, untouched). Too few bytes for the image: corrupt. Writes
// into bgr's buffer; never reallocates it.
ConvertStatus convert_to_bgr(const std::uint8_t* data, std::size_t bytesused, std::size_t bytesperline,
                             cv::Size size, V4l2PixelFormat format, cv::Mat& bgr);

// The capture time of a dequeued buffer: its timestamp (ns) when the driver
// stamps with CLOCK_MONOTONIC (but never after `now_ns`: some drivers stamp
// a nominal frame time that can lie just after the dequeue), else `now_ns`.
std::int64_t v4l2_capture_time_ns(const v4l2_buffer& buf, std::int64_t now_ns);

struct V4l2Options {
    std::string device = "/dev/video0";
    V4l2PixelFormat pixel_format = V4l2PixelFormat::yuyv;
    unsigned buffers = 4;                 // asked of VIDIOC_REQBUFS; the driver may grant more or fewer (>= 2)
    cv::Size size{640, 480};              // asked of VIDIOC_S_FMT; the driver must take it exactly
    double fps = 30;                      // VIDIOC_S_PARM when the device supports it; 0: leave it
    std::chrono::nanoseconds backoff_initial = std::chrono::milliseconds(100);
    std::chrono::nanoseconds backoff_max = std::chrono::seconds(5);
    // CLOCK_MONOTONIC ns; empty: the real clock. Tests inject their own.
    std::function<std::int64_t()> clock;
};

class V4l2Source final : public FrameSource {
public:
    enum class State : std::uint8_t { closed, opening, streaming, failed, backoff };

    V4l2Source(V4l2Options options, std::shared_ptr<spdlog::logger> log);
    ~V4l2Source() override;

    std::string_view name() const override { return name_; }
    bool open() override;
    bool start() override;
    NextStatus next(Frame& into, std::chrono::nanoseconds timeout) override;
    void stop() override;
    SourceCounters counters() const override;
    bool realtime() const override { return true; }
    bool lost() const override { return state_ == State::backoff || state_ == State::failed; }

    State state() const { return state_; }
    // What the driver granted (valid while streaming).
    std::size_t buffer_count() const { return buffers_.size(); }
    double granted_fps() const { return granted_fps_; }

private:
    std::int64_t now_ns() const;
    // Opens and configures the device, maps its buffers (state opening).
    bool open_device();
    // Queues every buffer and starts streaming.
    bool start_streaming();
    // Unmaps, closes; back to `closed`.
    void close_device();
    // Logs "<device>: <what>: <strerror> (errno N)", counts an error.
    void log_errno(const char* what, int err);
    // A streaming error: close, schedule the reopen (failed -> backoff).
    NextStatus fail_and_backoff(const char* what, int err);
    bool requeue(unsigned index);
    bool ioctl_retry(unsigned long request, void* arg) const;

    const V4l2Options options_;
    const std::shared_ptr<spdlog::logger> log_;
    const std::string name_;
    State state_ = State::closed;
    base::UniqueFd fd_;
    std::vector<base::MappedMemory> buffers_;
    std::size_t bytesperline_ = 0;
    std::size_t sizeimage_ = 0;
    double granted_fps_ = 0;
    ReopenBackoff backoff_;
    SkippedFrameLog skipped_log_;   // corrupt and wrong-size frames

    SourceCounterCells counters_;
};

}  // namespace stemd::drivers
