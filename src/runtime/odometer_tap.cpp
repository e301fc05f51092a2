#include "stemd/runtime/odometer_tap.hpp"

#include <algorithm>
#include <chrono>
#include <utility>

#include "stemd/base/clock.hpp"

namespace stemd::runtime {

namespace {

// The odometer's stream tolerates lost frames as the actuator's does.
constexpr std::uint8_t kMaxCounterStep = 3;
// How long the thread waits for a frame before looking at stop().
constexpr std::int64_t kReceiveSliceNs = 50'000'000;
constexpr int kMaxFramesPerReceive = 64;
// The encoder is read as often as a drive sends ODOMETRY: interpolation
// between readings 10 ms apart is exact at any steady speed.
constexpr std::int64_t kEncoderPeriodNs = 10'000'000;

}  // namespace

OdometerTap::OdometerTap(std::unique_ptr<drivers::CanBus> bus, std::unique_ptr<drivers::GpioLines> lines,
                         protocol::CanIds ids, double encoder_mm_per_tick, const OdometerTapParams& params)
    : bus_(std::move(bus)),
      lines_(std::move(lines)),
      ids_(ids),
      encoder_mm_per_tick_(encoder_mm_per_tick),
      params_(params),
      checker_(ids.id(protocol::MessageKind::Odometry), kMaxCounterStep),
      samples_(params.capacity),
      ring_({.capacity = params.capacity, .max_extrapolation_ns = params.max_extrapolation_ns})
{
}

OdometerTap::OdometerTap(std::unique_ptr<drivers::CanBus> bus, protocol::CanIds ids, const OdometerTapParams& params)
    : OdometerTap(std::move(bus), nullptr, ids, 0, params)
{
}

OdometerTap::OdometerTap(std::unique_ptr<drivers::GpioLines> lines, double encoder_mm_per_tick,
                         const OdometerTapParams& params)
    : OdometerTap(nullptr, std::move(lines), protocol::CanIds(), encoder_mm_per_tick, params)
{
}

OdometerTap::~OdometerTap() { stop(); }

void OdometerTap::start()
{
    if (thread_.joinable())
        return;
    stop_.store(false, std::memory_order_relaxed);
    thread_ = std::thread([this] {
        while (!stop_.load(std::memory_order_relaxed)) {
            if (bus_) {
                receive(kReceiveSliceNs);
            } else {
                read_encoder(base::monotonic_ns());
                std::this_thread::sleep_for(std::chrono::nanoseconds(kEncoderPeriodNs));
            }
        }
    });
}

void OdometerTap::stop()
{
    stop_.store(true, std::memory_order_relaxed);
    if (thread_.joinable())
        thread_.join();
}

void OdometerTap::receive(std::int64_t timeout_ns) noexcept
{
    protocol::CanFrame frame;
    std::int64_t t_rx_ns = 0;
    // Bounded, so that a flooded bus still lets the thread see stop().
    for (int n = 0; n < kMaxFramesPerReceive && bus_->receive(frame, n == 0 ? timeout_ns : 0, t_rx_ns); ++n) {
        if (ids_.kind_of(frame) != protocol::MessageKind::Odometry)
            continue;   // the socket's filter normally keeps others out
        protocol::Odometry m;
        if (!protocol::decode_checked(frame, checker_, ids_, m)) {
            rejected_.fetch_add(1, std::memory_order_relaxed);
            continue;
        }
        taken_.fetch_add(1, std::memory_order_relaxed);
        samples_.try_push({t_rx_ns, unwrap_.add(m.odom_mm)});   // a full ring counts the drop
    }
}

void OdometerTap::read_encoder(std::int64_t now_ns) noexcept
{
    taken_.fetch_add(1, std::memory_order_relaxed);
    samples_.try_push({now_ns, static_cast<double>(lines_->encoder().ticks) * encoder_mm_per_tick_});
}

void OdometerTap::take_samples() noexcept
{
    geometry::OdomSample s;
    while (samples_.try_pop(s)) {
        newest_rx_ns_ = std::max(newest_rx_ns_, s.t_ns);
        if (!ring_.empty() && s.odom_mm < ring_.newest().odom_mm) {
            backwards_.fetch_add(1, std::memory_order_relaxed);
            if (!reversing_)
                reversal_from_ns_ = ring_.newest().t_ns;
            reversing_ = true;
            continue;
        }
        if (ring_.push(s) && reversing_) {
            reversals_[n_reversals_++ % kReversals] = {reversal_from_ns_, s.t_ns};
            reversing_ = false;
        }
    }
}

bool OdometerTap::across_reversal(std::int64_t t_ns) const noexcept
{
    const std::size_t kept = std::min(n_reversals_, kReversals);
    for (std::size_t i = 0; i < kept; ++i)
        if (t_ns > reversals_[i].from_ns && t_ns < reversals_[i].to_ns)
            return true;
    return false;
}

OdometerTap::Reading OdometerTap::odometer_at(std::int64_t t_ns, std::int64_t now_ns, double& odom_mm) noexcept
{
    take_samples();
    if (!ring_.empty() && ring_.newest().t_ns >= t_ns) {
        const geometry::OdomQuery q = ring_.odom_at(t_ns);
        if (q.status != geometry::OdomStatus::ok || q.gap_ns > params_.timeout_ns || across_reversal(t_ns))
            return Reading::unknown;
        odom_mm = q.odom_mm;
        return Reading::known;
    }
    if (newest_rx_ns_ >= t_ns)
        return Reading::unknown;   // the readings after it went backwards
    const bool bus_speaks = newest_rx_ns_ >= 0 && now_ns - newest_rx_ns_ <= params_.max_extrapolation_ns;
    if (bus_speaks && now_ns - t_ns <= params_.timeout_ns)
        return Reading::wait;
    const geometry::OdomQuery q = ring_.odom_at(t_ns);
    if (q.status != geometry::OdomStatus::extrapolated)
        return Reading::unknown;
    odom_mm = q.odom_mm;
    return Reading::known;
}

OdometerTapCounters OdometerTap::counters() const
{
    return {.samples = taken_.load(std::memory_order_relaxed),
            .rejected = rejected_.load(std::memory_order_relaxed),
            .dropped = samples_.dropped(),
            .backwards = backwards_.load(std::memory_order_relaxed)};
}

}  // namespace stemd::runtime
