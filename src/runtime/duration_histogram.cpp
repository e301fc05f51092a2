#include "stemd/runtime/duration_histogram.hpp"

#include <algorithm>

namespace stemd::runtime {

void DurationHistogram::add(Buckets& b, std::int64_t ns, std::size_t bucket)
{
    b.counts[bucket].fetch_add(1, std::memory_order_relaxed);
    b.sum_ns.fetch_add(ns, std::memory_order_relaxed);
    // One writer, so load-compare-store is enough for the maximum.
    if (ns > b.max_ns.load(std::memory_order_relaxed))
        b.max_ns.store(ns, std::memory_order_relaxed);
}

void DurationHistogram::record(std::int64_t duration_ns)
{
    const std::int64_t ns = std::max<std::int64_t>(duration_ns, 0);
    const std::size_t bucket = std::min(static_cast<std::size_t>(ns / kBucketNs), kBuckets);
    add(interval_, ns, bucket);
    add(total_, ns, bucket);
}

DurationHistogram::Summary DurationHistogram::summarise(const std::array<std::uint64_t, kBuckets + 1>& counts,
                                                        std::int64_t max_ns, std::int64_t sum_ns)
{
    Summary s;
    for (const std::uint64_t c : counts)
        s.count += c;
    if (s.count == 0)
        return s;
    // A percentile is the middle of its bucket (25 us off at most), capped
    // by the exact maximum.
    auto percentile = [&](double q) {
        const auto rank = static_cast<std::uint64_t>(q * static_cast<double>(s.count - 1)) + 1;
        std::uint64_t seen = 0;
        for (std::size_t i = 0; i < counts.size(); ++i) {
            seen += counts[i];
            if (seen >= rank)
                return std::min((static_cast<double>(i) + 0.5) * kBucketNs, static_cast<double>(max_ns)) / 1e6;
        }
        return max_ns / 1e6;
    };
    s.p50_ms = percentile(0.50);
    s.p99_ms = percentile(0.99);
    s.max_ms = max_ns / 1e6;
    s.mean_ms = static_cast<double>(sum_ns) / static_cast<double>(s.count) / 1e6;
    return s;
}

DurationHistogram::Summary DurationHistogram::take_interval()
{
    std::array<std::uint64_t, kBuckets + 1> counts{};
    for (std::size_t i = 0; i < counts.size(); ++i)
        counts[i] = interval_.counts[i].exchange(0, std::memory_order_relaxed);
    return summarise(counts, interval_.max_ns.exchange(0, std::memory_order_relaxed),
                     interval_.sum_ns.exchange(0, std::memory_order_relaxed));
}

DurationHistogram::Summary DurationHistogram::total() const
{
    std::array<std::uint64_t, kBuckets + 1> counts{};
    for (std::size_t i = 0; i < counts.size(); ++i)
        counts[i] = total_.counts[i].load(std::memory_order_relaxed);
    return summarise(counts, total_.max_ns.load(std::memory_order_relaxed),
                     total_.sum_ns.load(std::memory_order_relaxed));
}

DurationHistogram::Cumulative DurationHistogram::cumulative(std::span<const std::int64_t> upper_ns,
                                                            std::span<std::uint64_t> out) const
{
    Cumulative c;
    std::fill(out.begin(), out.end(), 0);
    for (std::size_t i = 0; i <= kBuckets; ++i) {
        const std::uint64_t n = total_.counts[i].load(std::memory_order_relaxed);
        c.count += n;
        if (i == kBuckets || n == 0)
            continue;   // the overflow bucket is below no finite bound
        const std::int64_t bucket_end_ns = static_cast<std::int64_t>(i + 1) * kBucketNs;
        for (std::size_t b = 0; b < upper_ns.size() && b < out.size(); ++b)
            if (bucket_end_ns <= upper_ns[b])
                out[b] += n;
    }
    c.sum_ns = total_.sum_ns.load(std::memory_order_relaxed);
    return c;
}

}  // namespace stemd::runtime
