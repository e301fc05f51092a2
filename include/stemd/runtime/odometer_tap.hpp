// The machine's odometer for a program that records frames without
// actuating (stemd-record), so that a field recording carries the distance
// travelled and replays with it. Two sources, as the actuator has:
//   - the drive's ODOMETRY frames on the CAN bus, checked and unwrapped as
//     the actuator does, each at its receive time (the kernel's stamp, so a
//     late read does not move it);
//   - a wheel encoder on GPIO lines: its count times mm per tick, read
//     every 10 ms (ODOMETRY's own rate) at the time of reading.
//
// A thread of its own takes the samples and hands each to one reader
// through a lock-free ring; the reader keeps them in an OdometryRing and asks
// for the odometer at a frame's capture time. It waits for the first sample
// after that time rather than extrapolate, since a recorder can afford to:
//   - a sample at or after the time: interpolated (known), unless the two
//     samples around it are further apart than timeout_ns (a silence is not
//     bridged: unknown);
//   - none yet, and the source spoke within max_extrapolation_ns: wait (ask
//     again), up to timeout_ns after the capture;
//   - the source quiet: extrapolated at the last speed for up to
//     max_extrapolation_ns past the newest sample, as the daemon would
//     (known), else unknown;
//   - samples after the time that go backwards (the machine reversing: the
//     odometer a recording carries never decreases) are not used: unknown
//     until it passes its highest reading again, the stretch the daemon
//     does not actuate either.
// An unknown reading is an empty odom_mm cell: the replay does not actuate
// that frame, as the daemon would not have.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <thread>

#include "stemd/base/non_copyable.hpp"
#include "stemd/base/spsc_ring.hpp"
#include "stemd/drivers/can_bus.hpp"
#include "stemd/drivers/gpio_lines.hpp"
#include "stemd/geometry/odometry.hpp"
#include "stemd/protocol/e2e.hpp"
#include "stemd/protocol/messages.hpp"

namespace stemd::runtime {

struct OdometerTapParams {
    std::int64_t timeout_ns = 500'000'000;            // odometry.timeout_ms
    std::int64_t max_extrapolation_ns = 100'000'000;  // odometry.max_extrapolation_ms
    std::size_t capacity = 4096;                      // samples kept: 41 s of ODOMETRY at 100 Hz
};

struct OdometerTapCounters {
    std::uint64_t samples = 0;    // ODOMETRY frames or encoder readings taken
    std::uint64_t rejected = 0;   // ODOMETRY frames refused: bad CRC, counter jump, length or value
    std::uint64_t dropped = 0;    // samples the reader was too far behind to take
    std::uint64_t backwards = 0;  // samples below the highest reading (reversing), not used
};

class OdometerTap : base::NonCopyable {
public:
    enum class Reading : std::uint8_t { known, wait, unknown };

    // ODOMETRY frames. The bus is the tap's: its thread is the only one to
    // drive it.
    OdometerTap(std::unique_ptr<drivers::CanBus> bus, protocol::CanIds ids, const OdometerTapParams& params);
    // A wheel encoder of `encoder_mm_per_tick` on these lines.
    OdometerTap(std::unique_ptr<drivers::GpioLines> lines, double encoder_mm_per_tick,
                const OdometerTapParams& params);
    ~OdometerTap();

    // The sampling thread, until stop() (or destruction).
    void start();
    void stop();
    // What the thread does; called directly only while it is not running
    // (tests). ODOMETRY: takes the frames that come within timeout_ns (at
    // most 64 a call).
    void receive(std::int64_t timeout_ns) noexcept;
    // The encoder: its count now, at now_ns.
    void read_encoder(std::int64_t now_ns) noexcept;

    // --- the one reader's thread ------------------------------------------------
    // The odometer at `t_ns` (CLOCK_MONOTONIC) into odom_mm when known;
    // `now_ns` decides how long a missing later sample is waited for.
    Reading odometer_at(std::int64_t t_ns, std::int64_t now_ns, double& odom_mm) noexcept;

    // Any thread.
    OdometerTapCounters counters() const;
    // The bus's or the lines' name, for the log.
    std::string_view source_name() const { return bus_ ? bus_->name() : lines_->name(); }

private:
    void take_samples() noexcept;
    bool across_reversal(std::int64_t t_ns) const noexcept;

    OdometerTap(std::unique_ptr<drivers::CanBus> bus, std::unique_ptr<drivers::GpioLines> lines,
                protocol::CanIds ids, double encoder_mm_per_tick, const OdometerTapParams& params);

    // One of the two.
    std::unique_ptr<drivers::CanBus> bus_;
    std::unique_ptr<drivers::GpioLines> lines_;
    const protocol::CanIds ids_;
    const double encoder_mm_per_tick_;
    const OdometerTapParams params_;
    // The sampling side's.
    protocol::E2eChecker checker_;
    geometry::OdometerUnwrap unwrap_;
    base::SpscRing<geometry::OdomSample> samples_;
    std::atomic<std::uint64_t> taken_{0}, rejected_{0};
    // The reader's.
    geometry::OdometryRing ring_;
    std::int64_t newest_rx_ns_ = -1;   // the newest sample taken, used or not
    // Where samples went backwards: between the last sample kept before
    // and the first kept after, the kept ones must not be interpolated.
    struct Span {
        std::int64_t from_ns = 0, to_ns = 0;
    };
    static constexpr std::size_t kReversals = 64;   // the newest ones
    std::array<Span, kReversals> reversals_{};
    std::size_t n_reversals_ = 0;                    // ever
    bool reversing_ = false;
    std::int64_t reversal_from_ns_ = 0;
    std::atomic<std::uint64_t> backwards_{0};

    std::atomic<bool> stop_{false};
    std::thread thread_;
};

}  // namespace stemd::runtime
