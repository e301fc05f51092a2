// RGB + NIR from two V4L2 devices (an RGB camera and a mono NIR camera
// triggered together), paired by capture timestamp: the frame source for
// segment.method ndvi on a two-camera rig.
//
// It owns two V4l2Sources: the RGB one as configured (yuyv | bgr24 | grey)
// and the NIR one in GREY on another device node, same size. next() reads
// both (alternately, each for at most poll_slice: V4l2Source blocks on one
// device at a time) and pairs their frames with TimestampPairer
// (include/stemd/drivers/timestamp_pairing.hpp: the oldest RGB frame takes
// the nearest unused NIR frame within `tolerance`, else it is unpaired; NIR
// frames no RGB frame takes are unpaired). A delivered Frame has
//   bgr             the RGB device's frame (converted as V4l2Source does),
//   nir             the NIR device's frame (CV_8UC1, the GREY plane as is),
//   t_sample_ns     the RGB frame's buffer timestamp (t_recorded_ns too),
//   t_delivered_ns  when the pair was handed over;
//   source_seq      the RGB device's sequence number; name "paired:<rgb>+<nir>".
// A slot whose bgr is not CV_8UC3 or nir not CV_8UC1 of the configured size
// counts as bad_size (the pair is dropped, next() returns skipped).
//
// Each device reopens on its own with backoff (V4l2Source's state machine).
// While one is in backoff the other's frames become unpaired: at once (a
// device in backoff delivers nothing older than now, so the pairer's
// watermark for it advances to now) or, at the latest, when kPending frames
// wait on the other side (the oldest is then forced out).
//
// Where it allocates: open() (the pending slots: kPending + 1 frames per
// device, and V4l2Source's own buffers) and each device's reopen. next()
// allocates nothing. One thread drives it; counters are readable from any.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include <spdlog/logger.h>

#include "stemd/base/log_throttle.hpp"
#include "stemd/drivers/frame_source.hpp"
#include "stemd/drivers/timestamp_pairing.hpp"
#include "v4l2/v4l2_source.hpp"

namespace stemd::drivers {

struct PairedNirOptions {
    // The RGB device as configured (its size is the frame size).
    V4l2Options rgb;
    // The NIR device: its pixel_format is forced to grey and its size to
    // rgb.size; buffers, fps and backoff are its own.
    V4l2Options nir;
    // Largest |t_rgb - t_nir| of a pair. Keep it below half the frame
    // period (33 ms at 30 fps: < 16 ms); a few ms for hardware-triggered
    // cameras.
    std::chrono::nanoseconds tolerance = std::chrono::milliseconds(8);
    // How long next() waits on one device before looking at the other.
    std::chrono::nanoseconds poll_slice = std::chrono::milliseconds(2);
};

struct PairedNirCounters {
    std::uint64_t delivered = 0;     // pairs written into a caller's Frame
    std::uint64_t unpaired_rgb = 0;  // RGB frames dropped: no NIR frame within tolerance
    std::uint64_t unpaired_nir = 0;  // NIR frames dropped: no RGB frame took them
    std::uint64_t forced = 0;        // decisions made early because kPending frames waited on one side
    std::uint64_t out_of_order = 0;  // frames older than their device's previous one (counted as unpaired too)
    std::uint64_t bad_size = 0;      // pairs dropped: the caller's slot does not fit
    std::int64_t last_offset_ns = 0; // t_nir - t_rgb of the last delivered pair
    SourceCounters rgb;              // each device's own counters (its `timeouts` count poll slices)
    SourceCounters nir;
};

class PairedNirSource final : public FrameSource {
public:
    // Frames held per device while their partner may still come.
    static constexpr std::size_t kPending = 4;

    PairedNirSource(PairedNirOptions options, std::shared_ptr<spdlog::logger> log);
    ~PairedNirSource() override;

    std::string_view name() const override { return name_; }
    bool open() override;
    bool start() override;
    NextStatus next(Frame& into, std::chrono::nanoseconds timeout) override;
    void stop() override;
    // delivered, timeouts: pairs; corrupt, errors, reopens: both devices';
    // bad_size: both devices' and ours.
    SourceCounters counters() const override;
    bool realtime() const override { return true; }
    bool lost() const override { return rgb_.lost() || nir_.lost(); }

    PairedNirCounters paired_counters() const;
    const V4l2Source& rgb_source() const { return rgb_; }
    const V4l2Source& nir_source() const { return nir_; }

private:
    static constexpr std::size_t kSlots = kPending + 1;  // pending + the one being captured into
    struct Side {
        std::array<Frame, kSlots> slots;
        std::array<std::uint32_t, kSlots> free_ids{};
        std::size_t free_count = 0;
        std::uint32_t take() { return free_ids[--free_count]; }
        void give(std::uint32_t id) { free_ids[free_count++] = id; }
        void reset();
    };

    static PairedNirOptions normalised(PairedNirOptions options);
    std::int64_t now_ns() const;
    // Applies one pairer decision; true when it wrote a pair into `into`
    // (`status` says frame or skipped).
    bool handle(const PairDecision& d, Frame& into, NextStatus& status);
    void release_pending();

    const PairedNirOptions options_;
    const std::shared_ptr<spdlog::logger> log_;
    base::LogThrottle out_of_order_log_;   // one warning a second
    const std::string name_;
    V4l2Source rgb_;
    V4l2Source nir_;
    TimestampPairer<kPending> pairer_;
    Side rgb_side_;
    Side nir_side_;
    PairSide turn_ = PairSide::rgb;
    bool opened_ = false;

    SourceCounterCells counters_;   // the pairs' (devices' are their own)
    std::atomic<std::uint64_t> unpaired_rgb_{0};
    std::atomic<std::uint64_t> unpaired_nir_{0};
    std::atomic<std::uint64_t> forced_{0};
    std::atomic<std::uint64_t> out_of_order_{0};
    std::atomic<std::int64_t> last_offset_ns_{0};
};

}  // namespace stemd::drivers
