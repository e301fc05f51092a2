#include "stemd/geometry/odometry.hpp"

#include <algorithm>
#include <cmath>

namespace stemd::geometry {

namespace {
// Long enough to hold several samples of any source (frames at 10-30 fps,
// CAN odometry at 100-500 Hz), short against a machine's change of speed.
constexpr std::int64_t kExtrapolationSpeedWindowNs = 100'000'000;
}  // namespace

std::string_view to_string(OdomStatus v)
{
    switch (v) {
    case OdomStatus::ok: return "ok";
    case OdomStatus::extrapolated: return "extrapolated";
    case OdomStatus::stale: return "stale";
    case OdomStatus::before_history: return "before_history";
    case OdomStatus::empty: return "empty";
    }
    return "?";
}

OdometryRing::OdometryRing(const OdometryParams& params)
    : capacity_(std::max<std::size_t>(params.capacity, 2)),
      max_extrapolation_ns_(std::max<std::int64_t>(params.max_extrapolation_ns, 0)),
      samples_(std::make_unique<OdomSample[]>(capacity_))
{
}

bool OdometryRing::push(const OdomSample& sample) noexcept
{
    if (!std::isfinite(sample.odom_mm) ||
        (size_ > 0 && (sample.t_ns <= newest().t_ns || sample.odom_mm < newest().odom_mm))) {
        ++rejected_;
        return false;
    }
    if (size_ == capacity_) {
        samples_[head_] = sample;
        head_ = (head_ + 1) % capacity_;
        ++overwritten_;
    } else {
        samples_[(head_ + size_) % capacity_] = sample;
        ++size_;
    }
    return true;
}

double OdometryRing::last_speed_mm_per_s() const noexcept
{
    if (size_ < 2)
        return 0;
    const OdomSample& a = at(size_ - 2);
    const OdomSample& b = at(size_ - 1);
    return (b.odom_mm - a.odom_mm) / (static_cast<double>(b.t_ns - a.t_ns) * 1e-9);
}

double OdometryRing::speed_mm_per_s(std::int64_t window_ns) const noexcept
{
    if (size_ < 2)
        return 0;
    const OdomSample& b = newest();
    std::size_t i = size_ - 2;
    while (i > 0 && b.t_ns - at(i).t_ns < window_ns)
        --i;
    const OdomSample& a = at(i);
    return (b.odom_mm - a.odom_mm) / (static_cast<double>(b.t_ns - a.t_ns) * 1e-9);
}

OdomQuery OdometryRing::odom_at(std::int64_t t_ns) const noexcept
{
    if (size_ == 0)
        return {OdomStatus::empty, 0};
    const OdomSample& last = newest();
    if (t_ns >= last.t_ns) {
        const std::int64_t past = t_ns - last.t_ns;
        if (past == 0)
            return {OdomStatus::ok, last.odom_mm};
        if (past > max_extrapolation_ns_)
            return {OdomStatus::stale, last.odom_mm};
        // The speed over the newest samples spanning kExtrapolationSpeedWindowNs:
        // two samples a few ms apart (a frame delivered late, then the next
        // on time) give a speed that is mostly their timing noise, and
        // extrapolating it ran the odometer hundreds of mm ahead.
        return {OdomStatus::extrapolated,
                last.odom_mm + speed_mm_per_s(kExtrapolationSpeedWindowNs) * static_cast<double>(past) * 1e-9};
    }
    if (t_ns < oldest().t_ns)
        return {OdomStatus::before_history, oldest().odom_mm};
    // The last sample at or before t_ns: at(lo).t_ns <= t_ns < at(hi).t_ns.
    std::size_t lo = 0, hi = size_ - 1;
    while (hi - lo > 1) {
        const std::size_t mid = lo + (hi - lo) / 2;
        if (at(mid).t_ns <= t_ns)
            lo = mid;
        else
            hi = mid;
    }
    const OdomSample& a = at(lo);
    const OdomSample& b = at(hi);
    const double f = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
    return {OdomStatus::ok, a.odom_mm + f * (b.odom_mm - a.odom_mm), b.t_ns - a.t_ns};
}

}  // namespace stemd::geometry
