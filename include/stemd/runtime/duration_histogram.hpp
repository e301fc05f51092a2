// Latency histograms the status line summarises: recording is lock-free and
// allocation-free, so any real-time thread may record.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>

namespace stemd::runtime {

// Durations in fixed 50 us buckets up to 200 ms (and one overflow bucket),
// so that recording one is a relaxed increment: no allocation, no lock.
// One writer thread; any thread may read. Two sets of buckets: the interval
// since the last take_interval() (the status line) and the whole run.
class DurationHistogram {
public:
    static constexpr std::int64_t kBucketNs = 50'000;
    static constexpr std::size_t kBuckets = 4000;   // 0 .. 200 ms

    struct Summary {
        std::uint64_t count = 0;
        double p50_ms = 0;
        double p99_ms = 0;
        double max_ms = 0;
        double mean_ms = 0;
    };

    void record(std::int64_t duration_ns);
    // Reads and clears the interval buckets (the status thread only).
    Summary take_interval();
    Summary total() const;

    // The whole run as a cumulative histogram (Prometheus' le buckets):
    // out[i] = durations below upper_ns[i] (ascending; an upper bound off
    // the 50 us grid counts only the whole buckets under it). count and
    // sum_ns of every duration, the overflow bucket included.
    struct Cumulative {
        std::uint64_t count = 0;
        std::int64_t sum_ns = 0;
    };
    Cumulative cumulative(std::span<const std::int64_t> upper_ns, std::span<std::uint64_t> out) const;

private:
    struct Buckets {
        std::array<std::atomic<std::uint64_t>, kBuckets + 1> counts{};
        std::atomic<std::int64_t> max_ns{0};
        std::atomic<std::int64_t> sum_ns{0};
    };
    static void add(Buckets& b, std::int64_t ns, std::size_t bucket);
    static Summary summarise(const std::array<std::uint64_t, kBuckets + 1>& counts, std::int64_t max_ns,
                             std::int64_t sum_ns);

    Buckets interval_;
    Buckets total_;
};

}  // namespace stemd::runtime
