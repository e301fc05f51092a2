#include "stemd/actuation/fire_lag.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace stemd::actuation {

namespace {

// The bucket of v in a histogram of `n` buckets of `width` starting at `lo`,
// clamped to the end buckets.
std::size_t bucket_of(double v, double lo, double width, std::size_t n)
{
    const double i = std::floor((v - lo) / width);
    if (!(i >= 0))
        return 0;
    return i >= static_cast<double>(n - 1) ? n - 1 : static_cast<std::size_t>(i);
}

// Upper edge of the bucket holding the 95th percentile of `count` values.
template <std::size_t N>
double p95(const std::array<std::uint32_t, N>& h, std::uint64_t count, double lo, double width)
{
    if (count == 0)
        return 0;
    // The smallest rank r with r >= 0.95 count (nearest-rank definition).
    const auto rank = static_cast<std::uint64_t>(std::ceil(0.95 * static_cast<double>(count)));
    std::uint64_t seen = 0;
    for (std::size_t i = 0; i < N; ++i) {
        seen += h[i];
        if (seen >= rank)
            return lo + width * static_cast<double>(i + 1);
    }
    return lo + width * static_cast<double>(N);
}

}  // namespace

double compensation_mm(double speed_mm_per_s, double latency_ms, double standing_speed_mm_per_s)
{
    if (!std::isfinite(speed_mm_per_s) || !std::isfinite(latency_ms) || speed_mm_per_s <= standing_speed_mm_per_s ||
        latency_ms <= 0)
        return 0;
    return speed_mm_per_s * latency_ms / 1000.0;
}

double lag_ms_of(double lag_mm, double speed_mm_per_s)
{
    if (!std::isfinite(lag_mm) || !std::isfinite(speed_mm_per_s) || speed_mm_per_s < kMinLagSpeedMmPerS)
        return std::numeric_limits<double>::quiet_NaN();
    return lag_mm / speed_mm_per_s * 1000.0;
}

void LagStats::record(double lag_mm, double lag_ms, double strike_mm) noexcept
{
    if (!std::isfinite(lag_mm) || !std::isfinite(strike_mm))
        return;
    ++count_;
    sum_mm_ += lag_mm;
    sum_strike_ += strike_mm;
    ++mm_[bucket_of(lag_mm, -512.0, kMmBucket, kMmBuckets)];
    ++strike_[bucket_of(std::abs(strike_mm), 0.0, kStrikeBucket, kStrikeBuckets)];
    if (std::isfinite(lag_ms)) {
        ++count_ms_;
        sum_ms_ += lag_ms;
        ++ms_[bucket_of(lag_ms, -256.0, kMsBucket, kMsBuckets)];
    }
}

LagSummary LagStats::summary() const noexcept
{
    LagSummary s;
    s.count = count_;
    s.count_ms = count_ms_;
    if (count_ > 0) {
        s.mean_mm = sum_mm_ / static_cast<double>(count_);
        s.strike_mean_mm = sum_strike_ / static_cast<double>(count_);
        s.p95_mm = p95(mm_, count_, -512.0, kMmBucket);
        s.strike_p95_mm = p95(strike_, count_, 0.0, kStrikeBucket);
    }
    if (count_ms_ > 0) {
        s.mean_ms = sum_ms_ / static_cast<double>(count_ms_);
        s.p95_ms = p95(ms_, count_ms_, -256.0, kMsBucket);
    }
    return s;
}

LatencyLearner::LatencyLearner(double initial_ms, double min_ms, double max_ms) noexcept
    : min_ms_(min_ms), max_ms_(std::max(min_ms, max_ms)), latency_ms_(initial_ms)
{
}

bool LatencyLearner::add(double lag_ms) noexcept
{
    if (!std::isfinite(lag_ms))
        return false;
    window_[next_] = lag_ms;
    next_ = (next_ + 1) % kWindow;
    ++samples_;
    if (samples_ < kMinSamples)
        return false;
    const std::size_t n = std::min<std::uint64_t>(samples_, kWindow);
    std::array<double, kWindow> sorted = window_;
    std::sort(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(n));
    const double median = n % 2 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
    const double learned = std::clamp(median, min_ms_, max_ms_);
    if (std::abs(learned - latency_ms_) < kMinChangeMs)
        return false;
    latency_ms_ = learned;
    return true;
}

}  // namespace stemd::actuation
