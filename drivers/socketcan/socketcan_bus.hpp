// SocketCAN: a raw CAN socket (PF_CAN, SOCK_RAW, CAN_RAW) bound to one
// interface by name, non-blocking.
//
// State machine (one thread drives it; counters() from any thread):
//
//   closed --open ok--> up <--> error_passive
//     ^                  |  \-> bus_off --(controller restarted / error active)--> up
//     |                  |
//     |   ENETDOWN/ENODEV on write or read, or the socket reports an error
//     |                  v
//     +--- reopen ---- down  (the fd is closed; reopened with exponential backoff,
//                             reopen_min..reopen_max (ReopenBackoff), once the
//                             interface exists and is UP)
//
// - open() may fail (no CAN support, no such interface): the bus is then
//   `down`, the error is logged naming the interface and errno, and send() /
//   receive() keep retrying the open on the backoff schedule. Nothing throws.
// - send() retries a full transmit queue (ENOBUFS, EAGAIN) by polling for
//   POLLOUT until the deadline, and never writes after it (deadline miss),
//   nor once the caller's SendGate has closed (withdrawn): it checks the
//   gate before each write and at least every millisecond while it waits.
//   While `down` (before the next reopen attempt is due) it fails at once.
// - Error frames are enabled (CAN_RAW_ERR_FILTER = CAN_ERR_MASK) and decoded
//   in receive(): CAN_ERR_BUSOFF and error-passive (CAN_ERR_CRTL) are counted
//   and logged; CAN_ERR_RESTARTED or "error active again" returns to `up`.
//   Sending is attempted in every state but `down` (the kernel decides), so it
//   resumes by itself when the controller comes back.
// - Frames whose identifier is in `confirmed_tx_ids` (the daemon's TARGET and
//   HEARTBEAT) go out one at a time: each is written only once the kernel
//   has reported the previous one on the wire (the controller's echo on a
//   second socket with CAN_RAW_RECV_OWN_MSGS, flagged MSG_CONFIRM). A frame
//   in the kernel cannot be called back, so a TARGET waits here instead,
//   where its deadline and SendGate are still checked, and at most one
//   such frame of stemd's is ever queued behind a stalled bus. Each echo's
//   stamp is compared with its frame's deadline (`tx_late`). An echo that
//   does not come (the driver dropped the frame at bus-off or a transmit
//   timeout, or gave no echo for 1 s while the controller is error-active)
//   is counted in `tx_unconfirmed` and the next frame may go; while the
//   controller is error-passive or bus-off (an unacknowledged bus), the
//   frame is waited for. The bound holds for drivers that echo on transmit
//   completion (IFF_ECHO: every controller driver, vcan with echo=1);
//   elsewhere the core echoes on enqueue and frames queue as before.
// - Transitions are logged once each (not once per failed frame).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <spdlog/logger.h>

#include "stemd/base/log_throttle.hpp"
#include "stemd/drivers/can_bus.hpp"
#include "stemd/drivers/reopen_backoff.hpp"
#include "stemd/base/unique_fd.hpp"

namespace stemd::drivers {

struct SocketCanOptions {
    std::string interface = "can0";
    // Receive filter: the 11-bit identifiers receive() delivers. Empty = every
    // data frame. (Error frames are always received and handled internally.)
    std::vector<std::uint32_t> rx_ids;
    // The 11-bit identifiers sent one at a time, each after the previous
    // one's echo (above). Empty: every frame is written at once, as the
    // kernel takes it. Keep them out of rx_ids (an empty rx_ids then also
    // receives them, from the sending socket's loopback).
    std::vector<std::uint32_t> confirmed_tx_ids;
    std::int64_t reopen_min_ns = 10'000'000;     // first retry after going down: 10 ms
    std::int64_t reopen_max_ns = 1'000'000'000;  // backoff doubles up to 1 s
};

enum class SocketCanState : std::uint8_t { closed, up, error_passive, bus_off, down };
std::string_view to_string(SocketCanState s);

// What one error frame says (CAN_ERR_FLAG set in can_id); exposed for tests.
struct CanErrorInfo {
    bool bus_off = false;        // CAN_ERR_BUSOFF
    bool error_passive = false;  // CAN_ERR_CRTL with RX or TX passive
    bool recovered = false;      // CAN_ERR_RESTARTED, or CAN_ERR_CRTL "active" again
    bool tx_timeout = false;     // CAN_ERR_TX_TIMEOUT
};
CanErrorInfo decode_error_frame(std::uint32_t can_id, const std::uint8_t (&data)[8]);

class SocketCanBus final : public CanBus {
public:
    SocketCanBus(SocketCanOptions options, std::shared_ptr<spdlog::logger> log);
    ~SocketCanBus() override;

    // Opens the socket now; false (logged) leaves the bus `down`, retried later.
    bool open();

    std::string_view name() const override { return name_; }
    using CanBus::send;
    SendResult send(const protocol::CanFrame& frame, std::int64_t deadline_ns, SendGate gate) override;
    using CanBus::receive;
    // t_rx_ns: the kernel's receive stamp (SO_TIMESTAMPNS), moved onto
    // CLOCK_MONOTONIC; the read time if the socket gave none.
    bool receive(protocol::CanFrame& out, std::int64_t timeout_ns, std::int64_t& t_rx_ns) override;
    CanBusCounters counters() const override;

    SocketCanState state() const { return state_.load(std::memory_order_relaxed); }
    std::uint64_t reopens() const { return reopens_.load(std::memory_order_relaxed); }
    // The last open/IO failure, "<what> on <interface>: <strerror> (errno N)"; "" if none.
    const std::string& last_error() const { return last_error_; }

private:

    // The frame written last among confirmed_tx_ids whose echo has not come.
    struct Unconfirmed {
        bool pending = false;
        std::uint32_t id = 0;
        std::int64_t written_ns = 0;
        std::int64_t deadline_ns = 0;
    };

    enum class SocketRole : std::uint8_t { receive, send };

    bool try_open();
    // Filters `sock` to `ids`, stamps what it receives and binds it to the
    // interface; false (logged) on failure.
    bool set_up_socket(const base::UniqueFd& sock, int ifindex, const std::vector<std::uint32_t>& ids,
                       SocketRole role);
    bool is_confirmed(const protocol::CanFrame& frame) const;
    // Reads the echoes queued on the send socket without waiting; false if
    // the socket failed (the bus went down).
    bool take_echoes();
    // Gives up on the pending echo (counted in tx_unconfirmed), naming why.
    void forget_unconfirmed(const char* why);
    // Opens when down and the next attempt is due; true if there is a socket.
    bool ensure_open(std::int64_t now_ns);
    void go_down(const char* what, int err);
    void fail(const char* what, int err);  // sets last_error_ and logs it
    void handle_error_frame(std::uint32_t can_id, const std::uint8_t (&data)[8]);
    void set_state(SocketCanState s) { state_.store(s, std::memory_order_relaxed); }

    const SocketCanOptions options_;
    const std::shared_ptr<spdlog::logger> log_;
    const std::string name_;
    base::UniqueFd fd_;     // receives (and sends, without confirmed_tx_ids)
    base::UniqueFd tx_fd_;  // sends, and receives its own echoes, with confirmed_tx_ids
    Unconfirmed unconfirmed_;
    std::atomic<SocketCanState> state_{SocketCanState::closed};
    ReopenBackoff backoff_;  // when the next open is due (reopen_min..reopen_max)
    bool was_up_ = false;  // for the "up again" log line
    std::string last_error_;

    CanBusCounterCells counters_;
    // Error frames can come with every frame on the bus: one warning a second each.
    base::LogThrottle bus_off_log_, error_passive_log_, tx_timeout_log_, tx_late_log_;
    std::atomic<std::uint64_t> reopens_{0};
};

}  // namespace stemd::drivers
