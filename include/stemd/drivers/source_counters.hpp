// The counters every frame source keeps: a snapshot to read, and the atomics
// the capture thread adds to. A backend with more to count keeps its extras
// beside these (LibcameraCounters, PairedNirCounters) rather than its own copy
// of the common ones.
#pragma once

#include <atomic>
#include <cstdint>

namespace stemd::drivers {

// A snapshot; fields a backend has no use for stay 0.
struct SourceCounters {
    std::uint64_t delivered = 0;   // frames written into a caller's Frame
    std::uint64_t timeouts = 0;    // next() calls that saw no frame within their timeout
    std::uint64_t errors = 0;      // failures (open, ioctl, poll, mmap, queue...), each logged
    std::uint64_t reopens = 0;     // successful reopens after a failure
    std::uint64_t corrupt = 0;     // unreadable or undecodable frames, skipped
    std::uint64_t bad_size = 0;    // frames whose size or format does not fit the slot, skipped
    std::uint64_t loops = 0;       // replay: times the recording started over
    // Replay paced by t_ns: frames whose due time had passed by more than
    // kLateToleranceNs when the source came to them (it fell behind: slow
    // decoding, a loaded CPU), and the most any frame was behind.
    std::uint64_t late = 0;
    double worst_lateness_ms = 0;
    static constexpr std::int64_t kLateToleranceNs = 2'000'000;
};

// The common counters as atomics: one thread (the one driving the source)
// adds, any thread loads. Relaxed: each counter only grows, and no reader
// needs two of them to agree.
struct SourceCounterCells {
    std::atomic<std::uint64_t> delivered{0};
    std::atomic<std::uint64_t> timeouts{0};
    std::atomic<std::uint64_t> errors{0};
    std::atomic<std::uint64_t> reopens{0};
    std::atomic<std::uint64_t> corrupt{0};
    std::atomic<std::uint64_t> bad_size{0};

    // Adds one; returns the count before (replay numbers its frames with it).
    static std::uint64_t bump(std::atomic<std::uint64_t>& cell)
    {
        return cell.fetch_add(1, std::memory_order_relaxed);
    }

    SourceCounters load() const
    {
        const auto get = [](const std::atomic<std::uint64_t>& c) { return c.load(std::memory_order_relaxed); };
        return {.delivered = get(delivered),
                .timeouts = get(timeouts),
                .errors = get(errors),
                .reopens = get(reopens),
                .corrupt = get(corrupt),
                .bad_size = get(bad_size)};
    }
};

}  // namespace stemd::drivers
