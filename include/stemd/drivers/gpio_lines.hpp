// The GPIO lines interface: the machine's enable / e-stop input, an optional
// camera trigger output and optional encoder inputs. Backends: drivers/gpiod
// (libgpiod 1.6, the Linux GPIO character device).
//
// Where events are read: a backend owns one small GPIO thread that waits on
// the lines' event fds and updates atomics. Nothing else has to integrate fds:
//   - enabled() and encoder() are lock-free (std::atomic loads): the
//     actuator's per-frame path reads them directly;
//   - wait_change() blocks (mutex + condition variable, off the hot path) for
//     a thread that wants to react to the enable input as it changes;
//   - set_trigger() / pulse() run on the caller's thread (one ioctl each).
//
// Fail-safe: enabled() is false until the enable line has been read, and
// again as soon as the line is lost (chip gone, read error); only a
// debounced, stably active line enables (see EnableDebouncer).
//
// Time: CLOCK_MONOTONIC nanoseconds (base::monotonic_ns()).
//
// The pure logic (quadrature decoding, debouncing) is here, header-only, so
// it is tested without a chip (test/unit/drivers_gpiod_*.cpp).
#pragma once

#include <time.h>

#include <cstdint>
#include <string_view>
#include "stemd/base/clock.hpp"
#include "stemd/base/non_copyable.hpp"

namespace stemd::drivers {

// ---------------------------------------------------------------------------
// Quadrature decoding (x4: every edge of A or B is one tick).
// A state is (A << 1) | B. Forward (A leads B): 00 -> 10 -> 11 -> 01 -> 00.

enum class QuadStep : std::int8_t { none, forward, backward, invalid };

// The step from one sampled (A, B) state to the next: `none` if equal,
// `invalid` if both lines changed (an edge was missed: direction unknown).
constexpr QuadStep quad_step(std::uint8_t prev_ab, std::uint8_t next_ab)
{
    prev_ab &= 3U;
    next_ab &= 3U;
    if (prev_ab == next_ab)
        return QuadStep::none;
    if ((prev_ab ^ next_ab) == 3U)
        return QuadStep::invalid;
    // Position of each state along the forward cycle.
    constexpr std::uint8_t pos[4] = {0, 3, 1, 2};  // 00:0, 01:3, 10:1, 11:2
    return ((pos[prev_ab] + 1U) & 3U) == pos[next_ab] ? QuadStep::forward : QuadStep::backward;
}

// Accumulates samples of (A, B): ticks (+1 forward, -1 backward per edge) and
// invalid double steps (counted, not applied).
class QuadratureDecoder {
public:
    void reset(std::uint8_t ab) { ab_ = ab & 3U; }
    QuadStep sample(std::uint8_t ab)
    {
        const QuadStep s = quad_step(ab_, ab);
        switch (s) {
        case QuadStep::forward: ++ticks_; break;
        case QuadStep::backward: --ticks_; break;
        case QuadStep::invalid: ++invalid_; break;
        case QuadStep::none: break;
        }
        if (s != QuadStep::none)
            last_ = s;
        ab_ = ab & 3U;  // a double step still moves to the new state
        return s;
    }
    std::int64_t ticks() const { return ticks_; }
    std::uint64_t invalid() const { return invalid_; }
    std::uint8_t state() const { return ab_; }
    QuadStep last_direction() const { return last_; }  // forward, backward (or none/invalid)

private:
    std::uint8_t ab_ = 0;
    std::int64_t ticks_ = 0;
    std::uint64_t invalid_ = 0;
    QuadStep last_ = QuadStep::none;
};

// ---------------------------------------------------------------------------
// Enable debouncing, asymmetric because the input is an e-stop:
//   - active -> inactive disables at once (no debounce on the safe side);
//   - inactive -> active enables only once the line has stayed active for
//     debounce_ns; a bounce back to inactive restarts the wait (counted).
// Feed it the logical level (active-low already applied) on every edge,
// and call on_time() at or after next_deadline_ns().
class EnableDebouncer {
public:
    explicit EnableDebouncer(std::int64_t debounce_ns = 0) : debounce_ns_(debounce_ns) {}

    // The level when the line is (re)opened: active enables after debounce_ns.
    void reset(bool active, std::int64_t now_ns)
    {
        enabled_ = false;
        pending_since_ns_ = -1;
        sample(active, now_ns);
    }
    // Forces the safe state (the line was lost).
    void force_disabled()
    {
        enabled_ = false;
        pending_since_ns_ = -1;
    }
    void sample(bool active, std::int64_t now_ns)
    {
        if (!active) {
            if (pending_since_ns_ >= 0)
                ++bounces_;
            enabled_ = false;
            pending_since_ns_ = -1;
            return;
        }
        if (!enabled_ && pending_since_ns_ < 0)
            pending_since_ns_ = now_ns;
        on_time(now_ns);
    }
    void on_time(std::int64_t now_ns)
    {
        if (pending_since_ns_ >= 0 && now_ns - pending_since_ns_ >= debounce_ns_) {
            enabled_ = true;
            pending_since_ns_ = -1;
        }
    }
    // When on_time() must run to confirm a pending enable; -1 if none.
    std::int64_t next_deadline_ns() const { return pending_since_ns_ < 0 ? -1 : pending_since_ns_ + debounce_ns_; }
    bool enabled() const { return enabled_; }
    std::uint64_t bounces() const { return bounces_; }

private:
    std::int64_t debounce_ns_;
    std::int64_t pending_since_ns_ = -1;
    bool enabled_ = false;
    std::uint64_t bounces_ = 0;
};

// ---------------------------------------------------------------------------

enum class EncoderMode : std::uint8_t { none, quadrature, single };

struct EncoderReading {
    std::int64_t ticks = 0;   // quadrature: +-1 per edge; single: +1 per rising edge of A
    int direction = 0;        // +1 forward, -1 backward, 0 unknown (single channel, no motion yet)
    std::uint64_t invalid = 0;  // quadrature double steps (an edge was missed)
};

// Counters every backend keeps as atomics; read from any thread.
struct GpioCounters {
    std::uint64_t edges = 0;          // edge events read, all input lines
    std::uint64_t enable_bounces = 0; // enables withdrawn before debounce_ns
    std::uint64_t errors = 0;         // failed opens, reads, writes
    std::uint64_t reopens = 0;        // successful reopens after the lines were lost
    std::uint64_t trigger_pulses = 0; // pulse() calls that drove the line
    std::uint64_t trigger_busy = 0;   // pulse() calls skipped: the lines were being opened or dropped
};

class GpioLines : base::NonCopyable {
public:
    virtual ~GpioLines() = default;

    // "gpiod:gpiochip0"... for logs.
    virtual std::string_view name() const = 0;

    // Debounced enable state; lock-free, any thread.
    virtual bool enabled() const = 0;
    // Waits until enabled() != seen or timeout_ns passes; returns enabled() != seen.
    virtual bool wait_change(bool seen, std::int64_t timeout_ns) = 0;

    // Camera trigger output (false and counted when there is none or it fails).
    virtual bool has_trigger() const = 0;
    virtual bool set_trigger(bool active) = 0;
    // Drives the trigger active for width_us, then inactive; blocks that long.
    virtual bool pulse(std::uint32_t width_us) = 0;

    // Encoder; lock-free, any thread.
    virtual EncoderMode encoder_mode() const = 0;
    virtual EncoderReading encoder() const = 0;

    virtual GpioCounters counters() const = 0;
};

}  // namespace stemd::drivers
