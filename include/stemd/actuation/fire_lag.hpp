// Tool timing: how late a tool's strike lands, per tool, and the latency by
// which commands go out earlier to make up for it.
//
// A TOOL_FIRED reports the odometer reading fired_odom_mm at which the strike
// took effect; its TARGET asked for fire_odom_mm (the commanded point). Then
//   lag_mm    = fired_odom_mm - fire_odom_mm   (wrap-safe, fire_distance_mm)
//   lag_ms    = lag_mm / speed × 1000           (speed from the odometry)
//   strike_mm = fired_odom_mm - aim_odom_mm     (aim = s_mm + offset_mm: the stem)
// A valve's delay is a time: lag_mm grows with speed, lag_ms does not. With
// compensation the command's point is aim - compensation_mm(), so lag_ms
// still measures the tool's whole latency while strike_mm (how far past the
// stem the strike landed) goes to zero.
//
// Everything here is fixed-size: no allocation, nothing throws.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace stemd::actuation {

// The distance by which a command for a tool of latency_ms goes out earlier
// at speed_mm_per_s: speed × latency, and 0 at or below standing speed
// (standing, creeping or reversing: nothing arrives, nothing to lead).
double compensation_mm(double speed_mm_per_s, double latency_ms, double standing_speed_mm_per_s);

// Speeds below this give no lag in ms: a few mm of odometer noise at walking
// pace would read as hundreds of ms.
inline constexpr double kMinLagSpeedMmPerS = 100.0;

// lag_mm / speed in ms; NaN when speed < kMinLagSpeedMmPerS (or not finite).
double lag_ms_of(double lag_mm, double speed_mm_per_s);

struct LagSummary {
    std::uint64_t count = 0;        // strikes recorded
    double mean_mm = 0, p95_mm = 0;  // lag_mm
    std::uint64_t count_ms = 0;     // of which with a lag in ms (moving)
    double mean_ms = 0, p95_ms = 0;  // lag_ms
    double strike_mean_mm = 0;      // strike_mm, signed
    double strike_p95_mm = 0;       // |strike_mm|
};

// Running statistics of one tool's strikes: counts and sums for the means,
// fixed-bucket histograms for the 95th percentiles (the upper edge of the
// bucket holding it: never optimistic by more than nothing, pessimistic by
// at most a bucket). Values beyond a histogram's range count in its end
// buckets (their p95 then reads as the range's end).
class LagStats {
public:
    static constexpr double kMmBucket = 0.5;      // lag_mm: [-512, 512) mm
    static constexpr std::size_t kMmBuckets = 2048;
    static constexpr double kMsBucket = 0.25;     // lag_ms: [-256, 256) ms
    static constexpr std::size_t kMsBuckets = 2048;
    static constexpr double kStrikeBucket = 0.25; // |strike_mm|: [0, 256) mm
    static constexpr std::size_t kStrikeBuckets = 1024;

    // lag_ms NaN: not known (standing); non-finite lag_mm or strike_mm: ignored.
    void record(double lag_mm, double lag_ms, double strike_mm) noexcept;
    LagSummary summary() const noexcept;

private:
    std::uint64_t count_ = 0, count_ms_ = 0;
    double sum_mm_ = 0, sum_ms_ = 0, sum_strike_ = 0;
    std::array<std::uint32_t, kMmBuckets> mm_{};
    std::array<std::uint32_t, kMsBuckets> ms_{};
    std::array<std::uint32_t, kStrikeBuckets> strike_{};
};

// Learns a tool's latency from its measured lag_ms: the median of the last
// kWindow samples (one bad report cannot move it), clamped to [min_ms,
// max_ms], once kMinSamples have come. It changes only by at least
// kMinChangeMs, so that the commands do not dither.
class LatencyLearner {
public:
    static constexpr std::size_t kWindow = 15;
    static constexpr std::size_t kMinSamples = 5;
    static constexpr double kMinChangeMs = 0.25;

    LatencyLearner() noexcept = default;   // 0 ms, bounds [0, 0]
    // initial_ms: the configured latency, used until enough samples came.
    LatencyLearner(double initial_ms, double min_ms, double max_ms) noexcept;

    // True when latency_ms() changed. Non-finite samples are ignored.
    bool add(double lag_ms) noexcept;
    double latency_ms() const noexcept { return latency_ms_; }
    std::uint64_t samples() const noexcept { return samples_; }

private:
    double min_ms_ = 0, max_ms_ = 0;
    double latency_ms_ = 0;
    std::array<double, kWindow> window_{};
    std::size_t next_ = 0;
    std::uint64_t samples_ = 0;
};

}  // namespace stemd::actuation
