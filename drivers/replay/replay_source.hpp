// Replay: a recording directory (frames.csv, see include/stemd/io/recording.hpp)
// as a frame source, paced by its t_ns or as fast as the pipeline takes
// frames, once or looping. The optional odom_mm column sets Frame::odom_mm
// (NaN when a frame has none); the optional class column (a per-pixel class
// PNG) fills Frame::plant_class when the slot has that plane, like the
// other planes (a corrupt or wrong-size one skips the frame), and sets
// has_class_map (false when the slot has no such plane or the frame no
// class PNG).
//
// Times: t_sample_ns = t_delivered_ns = when next() handed the frame over;
// t_recorded_ns is the recording's t_ns. Not the paced due time: a replay
// that falls behind would then hand the actuator frames (and their recorded
// odometer) older than it may extrapolate, and nothing would be treated.
// Recorded pacing: a frame the source comes to more than kLateToleranceNs
// late makes the recording's clock slip by that much, so the frames after
// it keep their recorded spacing from it (the machine waited) instead of
// coming in a burst. Each frame also carries the recording's odometer at
// the next frame's due time (t_next_ns, odom_next_mm): the encoder track
// the recording samples, so that the actuator interpolates the odometer
// between two frames instead of extrapolating it, and what it sends does
// not depend on how long a frame took to process (after the last frame of
// a recording played once: its last frame step again, the machine driving
// on). Fast pacing has no next sample.
// A looping replay drives the strip again: each pass adds the recording's
// distance plus one mean frame step to odom_mm, so the odometer never runs
// back (a real odometer does not; the actuator would refuse the samples).
//
// State machine: closed -> opened (frames.csv read) -> streaming -> ended
// (once, after the last frame) | failed. One thread drives it.
//
// Where it allocates: open() (frames.csv, and every decoded frame with
// preload) and, without preload, each next(): OpenCV's PNG decoder (its
// decoder object, libpng's state and the decoded image), and the file buffer
// grows to the largest file. The decoded image is then copied into the
// caller's slot (one memcpy; see decode_into for why not in place). With
// preload, next() is only that copy and allocates nothing, which the
// runtime's allocation test relies on.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>
#include <spdlog/logger.h>

#include "stemd/drivers/frame_source.hpp"

namespace stemd::drivers {

struct ReplayOptions {
    std::filesystem::path dir;
    enum class Pacing : std::uint8_t { recorded, fast } pacing = Pacing::recorded;
    bool loop = false;
    bool preload = false;   // decode every frame in open(); next() is then a copy
    // The frame slots' size. Each image's header is checked before it is
    // decoded: other sizes are counted (bad_size) and never decoded. Empty:
    // preload checks only io::kMaxImageSidePx (next() checks the slot's size).
    cv::Size frame_size{};
    // Polled before each frame the preload decodes; true: open() gives up
    // (a SIGTERM must not wait for a long recording). Empty: never.
    std::function<bool()> cancelled{};
};

class ReplaySource final : public FrameSource {
public:
    ReplaySource(ReplayOptions options, std::shared_ptr<spdlog::logger> log);
    ~ReplaySource() override;

    std::string_view name() const override { return name_; }
    bool open() override;
    bool start() override;
    NextStatus next(Frame& into, std::chrono::nanoseconds timeout) override;
    void stop() override;
    SourceCounters counters() const override;
    bool realtime() const override { return options_.pacing == ReplayOptions::Pacing::recorded; }

    std::size_t frame_count() const { return entries_.size(); }

private:
    enum class State : std::uint8_t { closed, opened, streaming, ended, failed };

    struct Entry {
        std::int64_t t_ns = 0;
        std::string name;                         // as written in frames.csv
        std::filesystem::path rgb, nir, mask, plant_class;   // resolved; empty when not recorded
        double odom_mm = 0;                       // NaN when not recorded
        cv::Mat bgr_data, nir_data, mask_data, class_data;   // preload only
        // Preload only: a plane could not be loaded; the frame is skipped
        // (and counted as this) every pass.
        enum class Fault : std::uint8_t { none, corrupt, bad_size } preload_fault = Fault::none;
    };

    bool read_frames_csv();
    bool preload_all();
    // Decodes `path` and copies it into `plane`. False (logged, counted) if
    // the file is unreadable, corrupt, or not the plane's size and type.
    bool decode_into(const std::filesystem::path& path, int imread_flags, cv::Mat& plane);
    bool read_file(const std::filesystem::path& path);
    // file_buffer_ (read from `path`) against `expected` before decoding;
    // false logged, and counted unless `count` is false.
    bool header_fits(const std::filesystem::path& path, cv::Size expected, bool count, Entry::Fault* fault);
    bool fill(const Entry& entry, Frame& into);
    // Recorded pacing: when the entry at index_ is due, CLOCK_MONOTONIC ns.
    std::int64_t due_ns(const Entry& entry) const;
    // Recorded pacing: the odometer at the next entry's due time (or the
    // next pass's first), into Frame::t_next_ns / odom_next_mm.
    void set_next_odometer(Frame& into) const;

    const ReplayOptions options_;
    const std::shared_ptr<spdlog::logger> log_;
    const std::string name_;
    State state_ = State::closed;
    std::vector<Entry> entries_;
    std::size_t index_ = 0;
    std::vector<unsigned char> file_buffer_;   // reused; grows to the largest file
    std::int64_t start_mono_ns_ = 0;           // recorded pacing: when the first frame was due
    std::int64_t loop_offset_ns_ = 0;          // recorded pacing: shift of the current pass
    std::int64_t loop_period_ns_ = 0;          // recorded pacing: one pass plus one frame interval
    double loop_odom_offset_mm_ = 0;           // added to odom_mm: the current pass's shift
    double loop_odom_period_mm_ = 0;           // one pass's distance plus one mean frame step

    SourceCounterCells counters_;
    std::atomic<std::uint64_t> loops_{0};
    std::atomic<std::uint64_t> late_{0};
    std::atomic<std::int64_t> worst_lateness_ns_{0};
};

}  // namespace stemd::drivers
