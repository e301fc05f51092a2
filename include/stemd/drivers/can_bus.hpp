// The CAN bus interface: every CAN backend (drivers/socketcan, drivers/canlog)
// sends and receives protocol::CanFrame values. It knows nothing of the
// messages' meaning (include/stemd/protocol/messages.hpp) nor of the
// scheduler that calls it.
//
// Time: deadlines and timeouts are CLOCK_MONOTONIC nanoseconds
// (base::monotonic_ns()). A frame is never handed to the bus after its
// deadline: send() checks the clock before every attempt and, once the
// deadline has passed, gives up and counts a deadline miss. A caller's
// SendGate is checked before every attempt too: a TARGET kept waiting by a
// full transmit queue must not go out after the enable input dropped.
//
// Threading: one thread drives a bus (send() and receive() from the same
// thread, or from two threads only if the backend says so); counters() may be
// read from any thread.
#pragma once

#include <time.h>

#include <atomic>
#include <cstdint>
#include <string_view>

#include "stemd/protocol/can_frame.hpp"
#include "stemd/base/clock.hpp"
#include "stemd/base/non_copyable.hpp"

namespace stemd::drivers {

enum class SendResult : std::uint8_t {
    sent,             // the kernel (or the log) took the whole frame
    deadline_passed,  // not sent: the deadline passed before it could be (counted in deadline_misses)
    withdrawn,        // not sent: the caller's SendGate closed before it could be (counted in withdrawn)
    error,            // not sent: the bus is down, the frame is invalid, a write failed (counted in errors)
};

constexpr std::string_view to_string(SendResult r)
{
    switch (r) {
    case SendResult::sent: return "sent";
    case SendResult::deadline_passed: return "deadline_passed";
    case SendResult::withdrawn: return "withdrawn";
    case SendResult::error: return "error";
    }
    return "?";
}

// Counters every bus keeps as members; read from any thread.
struct CanBusCounters {
    std::uint64_t sent = 0;                   // frames the bus took
    std::uint64_t tx_queue_full_retries = 0;  // send attempts that found the transmit queue full and retried
    std::uint64_t deadline_misses = 0;        // frames given up at their deadline (never sent)
    std::uint64_t withdrawn = 0;              // frames given up when their SendGate closed (never sent)
    std::uint64_t errors = 0;                 // failed sends and receive errors (bus down, write errors...)
    std::uint64_t bus_off = 0;                // bus-off events reported by the controller
    std::uint64_t error_passive = 0;          // error-passive events reported by the controller
    std::uint64_t rx = 0;                     // data frames delivered by receive()
    // Backends that hear their own frames on the wire (SocketCAN's
    // confirmed_tx_ids):
    std::uint64_t tx_confirm_waits = 0;  // sends that waited for the previous frame to reach the wire
    std::uint64_t tx_late = 0;           // frames that reached the wire after their deadline
    std::uint64_t tx_unconfirmed = 0;    // frames written whose arrival on the wire was never reported
};

// The counters as atomics, one set for every backend (a backend leaves the
// ones it has no use for at 0): the thread driving the bus adds, any thread
// loads. Relaxed: each only grows, and no reader needs two of them to agree.
struct CanBusCounterCells {
    std::atomic<std::uint64_t> sent{0};
    std::atomic<std::uint64_t> tx_queue_full_retries{0};
    std::atomic<std::uint64_t> deadline_misses{0};
    std::atomic<std::uint64_t> withdrawn{0};
    std::atomic<std::uint64_t> errors{0};
    std::atomic<std::uint64_t> bus_off{0};
    std::atomic<std::uint64_t> error_passive{0};
    std::atomic<std::uint64_t> rx{0};
    std::atomic<std::uint64_t> tx_confirm_waits{0};
    std::atomic<std::uint64_t> tx_late{0};
    std::atomic<std::uint64_t> tx_unconfirmed{0};

    static void bump(std::atomic<std::uint64_t>& cell) { cell.fetch_add(1, std::memory_order_relaxed); }

    CanBusCounters load() const
    {
        const auto get = [](const std::atomic<std::uint64_t>& c) { return c.load(std::memory_order_relaxed); };
        return {.sent = get(sent),
                .tx_queue_full_retries = get(tx_queue_full_retries),
                .deadline_misses = get(deadline_misses),
                .withdrawn = get(withdrawn),
                .errors = get(errors),
                .bus_off = get(bus_off),
                .error_passive = get(error_passive),
                .rx = get(rx),
                .tx_confirm_waits = get(tx_confirm_waits),
                .tx_late = get(tx_late),
                .tx_unconfirmed = get(tx_unconfirmed)};
    }
};

// What must still hold when a frame is written: checked by send() before
// every attempt, the first included. A function and its context, so that
// passing one allocates nothing; the default is always open.
struct SendGate {
    bool (*is_open)(const void* context) = nullptr;
    const void* context = nullptr;
    bool open() const { return is_open == nullptr || is_open(context); }
};

class CanBus : base::NonCopyable {
public:
    virtual ~CanBus() = default;

    // "socketcan:can0", "canlog:/var/log/stemd/can.log"... for logs.
    virtual std::string_view name() const = 0;

    // Sends one frame unless deadline_ns (CLOCK_MONOTONIC) passes, or
    // `gate` closes, first. Never blocks past the deadline, and checks the
    // gate at least every millisecond while it waits.
    virtual SendResult send(const protocol::CanFrame& frame, std::int64_t deadline_ns, SendGate gate) = 0;
    SendResult send(const protocol::CanFrame& frame, std::int64_t deadline_ns)
    {
        return send(frame, deadline_ns, SendGate{});
    }

    // Waits at most timeout_ns for the next data frame that passes the bus's
    // receive filter and writes it into `out`, and into t_rx_ns when it
    // arrived (CLOCK_MONOTONIC): the kernel's receive stamp where the backend
    // has one, else when it was read. A frame read late (a poll after a busy
    // frame) still carries its own time. False on timeout (or when the bus
    // cannot receive), leaving both as they were.
    virtual bool receive(protocol::CanFrame& out, std::int64_t timeout_ns, std::int64_t& t_rx_ns) = 0;
    // The same, for callers that do not need the time.
    bool receive(protocol::CanFrame& out, std::int64_t timeout_ns)
    {
        std::int64_t t_rx_ns = 0;
        return receive(out, timeout_ns, t_rx_ns);
    }

    virtual CanBusCounters counters() const = 0;

    // True when the bus is a record (a log file) that lost frames: unlike a
    // bus that was down for a while, the run's output is then incomplete.
    virtual bool output_lost() const { return false; }
};

}  // namespace stemd::drivers
