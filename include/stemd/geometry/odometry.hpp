// Odometry: the distance the machine has travelled, as a function of time.
//
// Conventions: t_ns is CLOCK_MONOTONIC nanoseconds (the clock frames are
// stamped with); odom_mm is the distance travelled along machine x,
// millimetres, monotonic (never decreasing). A stem seen in a frame captured
// at t_ns lies at the along-track position odom_at(t_ns) + its forward
// offset from the camera's principal point (see field.hpp).
//
// OdometryRing keeps the newest `capacity` samples (allocated once, in the
// constructor); push() and odom_at() never allocate. Single-threaded: the
// actuator thread owns it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string_view>

namespace stemd::geometry {

struct OdomSample {
    std::int64_t t_ns = 0;
    double odom_mm = 0;
};

enum class OdomStatus : std::uint8_t {
    ok,              // interpolated between two samples (or exactly on one)
    extrapolated,    // past the newest sample, within max_extrapolation_ns, at the last speed
    stale,           // past the newest sample by more than max_extrapolation_ns: do not act on it
    before_history,  // older than the oldest sample kept
    empty,           // no sample yet
};
std::string_view to_string(OdomStatus v);

struct OdomQuery {
    OdomStatus status = OdomStatus::empty;
    // ok/extrapolated: the odometer at the time asked for. stale: the newest
    // sample's; before_history: the oldest sample's; empty: 0.
    double odom_mm = 0;
    // ok: how far apart the two samples it lies between are (0 at the
    // newest), so that a caller can refuse to bridge a silence.
    std::int64_t gap_ns = 0;
};

struct OdometryParams {
    std::size_t capacity = 256;                    // samples kept (at least 2)
    std::int64_t max_extrapolation_ns = 100'000'000;  // past the newest sample
};

class OdometryRing {
public:
    explicit OdometryRing(const OdometryParams& params = {});

    // Appends a sample. Rejected (and counted) unless its time is later than
    // the newest sample's and its odometer is not smaller (and both are
    // finite). When full, the oldest sample is overwritten.
    bool push(const OdomSample& sample) noexcept;

    // The odometer at t_ns: linear between the two samples around it;
    // past the newest, extrapolated at the last speed (between the two
    // newest samples; 0 with one sample) for at most max_extrapolation_ns.
    OdomQuery odom_at(std::int64_t t_ns) const noexcept;

    // Mean speed over the newest samples spanning at least window_ns (or all
    // samples if they span less), mm/s; 0 with fewer than two samples.
    double speed_mm_per_s(std::int64_t window_ns) const noexcept;
    // Speed between the two newest samples, mm/s (0 with fewer than two).
    double last_speed_mm_per_s() const noexcept;

    std::size_t size() const { return size_; }
    std::size_t capacity() const { return capacity_; }
    bool empty() const { return size_ == 0; }
    std::uint64_t rejected() const { return rejected_; }
    std::uint64_t overwritten() const { return overwritten_; }
    // i = 0 is the oldest sample kept, size() - 1 the newest.
    const OdomSample& at(std::size_t i) const { return samples_[(head_ + i) % capacity_]; }
    const OdomSample& newest() const { return at(size_ - 1); }
    const OdomSample& oldest() const { return at(0); }
    void clear() { size_ = 0; head_ = 0; }

private:
    std::size_t capacity_;
    std::int64_t max_extrapolation_ns_;
    std::unique_ptr<OdomSample[]> samples_;
    std::size_t head_ = 0;  // index of the oldest sample
    std::size_t size_ = 0;
    std::uint64_t rejected_ = 0;
    std::uint64_t overwritten_ = 0;
};

// A drive's 32-bit odometer (mm, wrapping at 2^32, as ODOMETRY carries it)
// as a running total: each reading adds its step from the last one, taken
// the shorter way round, so a wrap is not a jump of 4000 km and a machine
// reversing counts down. The first reading is taken as it is.
class OdometerUnwrap {
public:
    double add(std::uint32_t raw_mm) noexcept
    {
        total_mm_ = have_ ? total_mm_ + static_cast<double>(static_cast<std::int32_t>(raw_mm - last_raw_mm_))
                          : static_cast<double>(raw_mm);
        have_ = true;
        last_raw_mm_ = raw_mm;
        return total_mm_;
    }
    bool started() const { return have_; }

private:
    bool have_ = false;
    std::uint32_t last_raw_mm_ = 0;
    double total_mm_ = 0;
};

// An odometer moving at constant speed: for replays without odometry, the
// bench and tests. odom(t) = odom0_mm + speed * (t - t0_ns).
class ConstantSpeedOdometer {
public:
    ConstantSpeedOdometer(double speed_mm_per_s, std::int64_t t0_ns = 0, double odom0_mm = 0)
        : speed_mm_per_s_(speed_mm_per_s < 0 ? 0 : speed_mm_per_s), t0_ns_(t0_ns), odom0_mm_(odom0_mm)
    {
    }
    OdomSample sample(std::int64_t t_ns) const noexcept
    {
        return {t_ns, odom0_mm_ + speed_mm_per_s_ * static_cast<double>(t_ns - t0_ns_) * 1e-9};
    }
    double speed_mm_per_s() const { return speed_mm_per_s_; }

private:
    double speed_mm_per_s_;
    std::int64_t t0_ns_;
    double odom0_mm_;
};

}  // namespace stemd::geometry
