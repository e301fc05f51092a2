#include "stemd/runtime/odometry_input.hpp"

#include <cmath>

#include "stemd/runtime/status.hpp"

namespace stemd::runtime {

namespace {

// Speed over this window: smooths encoder ticks and frame-rate odometry.
constexpr std::int64_t kSpeedWindowNs = 200'000'000;

// A sample per ~2 ms is plenty for interpolation and speed.
constexpr std::int64_t kEncoderSampleNs = 2'000'000;

}  // namespace

OdometryInput::OdometryInput(const ActuationConfig& config, ActuationCounters& counters)
    : source_(config.odometry),
      speed_mm_per_s_(config.speed_mm_per_s),
      encoder_mm_per_tick_(config.encoder_mm_per_tick),
      counters_(counters),
      ring_({.capacity = 1024, .max_extrapolation_ns = config.max_extrapolation_ns})
{
}

void OdometryInput::add_frame(std::int64_t t_sample_ns, double odom_mm) noexcept
{
    const bool frame_has_odom = std::isfinite(odom_mm);
    geometry::OdomSample sample{t_sample_ns, 0};
    constant_now_ = false;
    switch (source_) {
    case OdometrySource::recording:
        if (!frame_has_odom)
            return;
        sample.odom_mm = odom_mm;
        break;
    case OdometrySource::automatic:
        frames_carry_odom_ = frames_carry_odom_ || frame_has_odom;
        if (frame_has_odom) {
            sample.odom_mm = odom_mm;
            break;
        }
        if (frames_carry_odom_)
            return;
        [[fallthrough]];
    case OdometrySource::constant:
        if (constant_t0_ns_ < 0)
            constant_t0_ns_ = t_sample_ns;
        constant_now_ = true;
        sample = geometry::ConstantSpeedOdometer(speed_mm_per_s_, constant_t0_ns_).sample(t_sample_ns);
        break;
    case OdometrySource::encoder:
    case OdometrySource::can:
        // Sampled with the time they were read or received; a reading taken
        // now is not the odometer at this frame's capture.
        return;
    }
    if (!ring_.empty() && ring_.newest().t_ns >= sample.t_ns)
        return;   // the same instant again (no new information)
    push(sample);
}

void OdometryInput::add_encoder(std::int64_t now_ns, std::int64_t ticks) noexcept
{
    if (source_ != OdometrySource::encoder)
        return;
    if (ring_.empty() || now_ns - ring_.newest().t_ns >= kEncoderSampleNs)
        push({now_ns, static_cast<double>(ticks) * encoder_mm_per_tick_});
}

void OdometryInput::add_can(std::int64_t t_rx_ns, std::uint32_t odom_raw_mm) noexcept
{
    if (source_ != OdometrySource::can)
        return;
    push({t_rx_ns, can_odom_.add(odom_raw_mm)});
}

bool OdometryInput::odometer_at(std::int64_t t_ns, double& odom_mm) const noexcept
{
    if (constant_now_) {
        // A constant speed is known at every instant: it never goes stale.
        odom_mm = geometry::ConstantSpeedOdometer(speed_mm_per_s_, constant_t0_ns_).sample(t_ns).odom_mm;
        return true;
    }
    if (going_back_since_ns_ >= 0 && t_ns >= going_back_since_ns_)
        return false;
    const geometry::OdomQuery q = ring_.odom_at(t_ns);
    if (q.status != geometry::OdomStatus::ok && q.status != geometry::OdomStatus::extrapolated)
        return false;
    odom_mm = q.odom_mm;
    return true;
}

bool OdometryInput::frame_odometer(std::int64_t t_sample_ns, double frame_odom_mm, double& odom_mm) const noexcept
{
    const bool column_is_source =
        source_ == OdometrySource::recording || (source_ == OdometrySource::automatic && frames_carry_odom_);
    if (column_is_source && !std::isfinite(frame_odom_mm))
        return false;
    return odometer_at(t_sample_ns, odom_mm);
}

bool OdometryInput::covers(std::int64_t t_ns) const noexcept
{
    return constant_now_ || (!ring_.empty() && t_ns <= ring_.newest().t_ns);
}

double OdometryInput::speed_mm_per_s() const noexcept
{
    return constant_now_ ? speed_mm_per_s_ : ring_.speed_mm_per_s(kSpeedWindowNs);
}

void OdometryInput::push(const geometry::OdomSample& sample) noexcept
{
    const bool going_back = !ring_.empty() && sample.odom_mm < ring_.newest().odom_mm;
    if (ring_.push(sample)) {
        going_back_since_ns_ = -1;
    } else if (going_back) {
        bump(counters_.odometry_going_back);
        if (going_back_since_ns_ < 0)
            going_back_since_ns_ = sample.t_ns;
    }
}

}  // namespace stemd::runtime
