#include "socketcan/socketcan_bus.hpp"

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include <spdlog/fmt/fmt.h>
#include "stemd/base/clock.hpp"

namespace stemd::drivers {

namespace {

// The kernel stamps received frames on CLOCK_REALTIME: its age, measured on
// that clock now, is taken back from the monotonic clock now. Without a
// stamp, the frame is as old as this read.
std::int64_t receive_time_ns(msghdr& msg)
{
    const std::int64_t now_ns = base::monotonic_ns();
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
        if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SCM_TIMESTAMPNS)
            continue;
        timespec stamp{};
        std::memcpy(&stamp, CMSG_DATA(c), sizeof stamp);
        timespec real{};
        ::clock_gettime(CLOCK_REALTIME, &real);
        const std::int64_t age_ns = (static_cast<std::int64_t>(real.tv_sec) - stamp.tv_sec) * 1'000'000'000 +
                                    (real.tv_nsec - stamp.tv_nsec);
        // A clock step between the stamp and now could make the age absurd.
        return age_ns >= 0 && age_ns < 10'000'000'000 ? now_ns - age_ns : now_ns;
    }
    return now_ns;
}

// One classic frame read with recvmsg(2), with room for its receive stamp.
struct ReceivedFrame {
    can_frame cf{};
    iovec iov{&cf, sizeof cf};
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec))];
    msghdr msg{};

    ReceivedFrame()
    {
        msg.msg_iov = &iov;
        msg.msg_iovlen = 1;
        msg.msg_control = control;
        msg.msg_controllen = sizeof control;
    }
    ReceivedFrame(const ReceivedFrame&) = delete;  // iov and msg point into it
    ReceivedFrame& operator=(const ReceivedFrame&) = delete;

    ssize_t read(int fd, int flags) { return ::recvmsg(fd, &msg, flags); }
};

timespec to_timespec(std::int64_t ns)
{
    if (ns < 0)
        ns = 0;
    return {static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
}

void sleep_for_ns(std::int64_t ns)
{
    if (ns <= 0)
        return;
    const timespec ts = to_timespec(ns);
    nanosleep(&ts, nullptr);
}

// Waits for `events` on fd for at most ns; the ppoll result.
int wait_fd(int fd, short events, std::int64_t ns)
{
    pollfd pfd{fd, events, 0};
    const timespec ts = to_timespec(ns);
    return ::ppoll(&pfd, 1, &ts, nullptr);
}

bool is_down_errno(int e) { return e == ENETDOWN || e == ENODEV || e == ENXIO; }

// ENOBUFS (the interface's tx queue is full) does not wake POLLOUT: the
// socket's own buffer is not the one that is full. Retry after this pause.
constexpr std::int64_t kEnobufsPauseNs = 100'000;

// While the transmit queue stays full, the caller's SendGate is checked
// at least this often.
constexpr std::int64_t kGateCheckNs = 1'000'000;

// An error-active controller moves a frame within milliseconds even on a
// busy bus at 125 kbit/s: an echo missing this long means the driver
// dropped the frame without one.
constexpr std::int64_t kEchoLostAfterNs = 1'000'000'000;

// A can_filter passing exactly one 11-bit data frame identifier.
can_filter exact_standard_id(std::uint32_t id)
{
    return {id & CAN_SFF_MASK, CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG};
}

}  // namespace

std::string_view to_string(SocketCanState s)
{
    switch (s) {
    case SocketCanState::closed: return "closed";
    case SocketCanState::up: return "up";
    case SocketCanState::error_passive: return "error_passive";
    case SocketCanState::bus_off: return "bus_off";
    case SocketCanState::down: return "down";
    }
    return "?";
}

CanErrorInfo decode_error_frame(std::uint32_t can_id, const std::uint8_t (&data)[8])
{
    CanErrorInfo info;
    if ((can_id & CAN_ERR_FLAG) == 0)
        return info;
    info.bus_off = (can_id & CAN_ERR_BUSOFF) != 0;
    const bool crtl = (can_id & CAN_ERR_CRTL) != 0;
    info.error_passive = crtl && (data[1] & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) != 0;
    info.recovered = (can_id & CAN_ERR_RESTARTED) != 0 || (crtl && (data[1] & CAN_ERR_CRTL_ACTIVE) != 0);
    info.tx_timeout = (can_id & CAN_ERR_TX_TIMEOUT) != 0;
    return info;
}

SocketCanBus::SocketCanBus(SocketCanOptions options, std::shared_ptr<spdlog::logger> log)
    : options_(std::move(options)),
      log_(std::move(log)),
      name_("socketcan:" + options_.interface),
      backoff_(options_.reopen_min_ns, options_.reopen_max_ns)
{
}

SocketCanBus::~SocketCanBus() = default;

void SocketCanBus::fail(const char* what, int err)
{
    std::string message = fmt::format("{} on {}: {} (errno {})", what, options_.interface, std::strerror(err), err);
    // Repeated reopen attempts fail the same way: log a failure once, until it changes.
    if (message != last_error_)
        log_->error("{}: {}", name_, message);
    last_error_ = std::move(message);
}

bool SocketCanBus::try_open()
{
    const std::string& ifname = options_.interface;
    if (ifname.empty() || ifname.size() >= IFNAMSIZ) {
        fail("interface name must be 1..15 characters", EINVAL);
        return false;
    }
    base::UniqueFd sock(::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW));
    if (!sock.valid()) {
        fail("socket(PF_CAN, SOCK_RAW, CAN_RAW)", errno);
        return false;
    }
    ifreq ifr{};
    std::memcpy(ifr.ifr_name, ifname.c_str(), ifname.size() + 1);
    if (::ioctl(sock.get(), SIOCGIFINDEX, &ifr) < 0) {
        fail("SIOCGIFINDEX (no such interface?)", errno);
        return false;
    }
    const int ifindex = ifr.ifr_ifindex;
    if (::ioctl(sock.get(), SIOCGIFFLAGS, &ifr) < 0) {
        fail("SIOCGIFFLAGS", errno);
        return false;
    }
    if ((ifr.ifr_flags & IFF_UP) == 0) {
        fail("interface is not up", ENETDOWN);
        return false;
    }
    const can_err_mask_t err_mask = CAN_ERR_MASK;
    if (::setsockopt(sock.get(), SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) < 0) {
        fail("setsockopt(CAN_RAW_ERR_FILTER)", errno);
        return false;
    }
    if (!set_up_socket(sock, ifindex, options_.rx_ids, SocketRole::receive))
        return false;
    if (!options_.confirmed_tx_ids.empty()) {
        // It hears only its own frames of these identifiers (MSG_CONFIRM); an
        // error frame is left to the receiving socket (its error mask stays 0).
        base::UniqueFd tx(::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW));
        if (!tx.valid()) {
            fail("socket(PF_CAN, SOCK_RAW, CAN_RAW) for sending", errno);
            return false;
        }
        const int on = 1;
        if (::setsockopt(tx.get(), SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &on, sizeof on) < 0) {
            fail("setsockopt(CAN_RAW_RECV_OWN_MSGS)", errno);
            return false;
        }
        if (!set_up_socket(tx, ifindex, options_.confirmed_tx_ids, SocketRole::send))
            return false;
        tx_fd_ = std::move(tx);
    }
    fd_ = std::move(sock);
    unconfirmed_ = {};  // an echo for a closed socket never comes
    return true;
}

bool SocketCanBus::set_up_socket(const base::UniqueFd& sock, int ifindex, const std::vector<std::uint32_t>& ids,
                                 SocketRole role)
{
    const char* const of = role == SocketRole::send ? " of the sending socket" : "";
    // The receiving socket takes every data frame when no identifier is
    // given; the sending one then hears nothing.
    if (!ids.empty() || role == SocketRole::send) {
        std::vector<can_filter> filters;
        filters.reserve(ids.size());
        for (const std::uint32_t id : ids)
            filters.push_back(exact_standard_id(id));
        if (::setsockopt(sock.get(), SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(),
                         static_cast<socklen_t>(filters.size() * sizeof(can_filter))) < 0) {
            fail(fmt::format("setsockopt(CAN_RAW_FILTER){}", of).c_str(), errno);
            return false;
        }
    }
    // Receive stamps are a nicety (the read time stands in): not an error.
    const int on = 1;
    if (::setsockopt(sock.get(), SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) < 0)
        log_->warn("{}: setsockopt(SO_TIMESTAMPNS){}: {} (errno {}); frames are stamped when read", name_, of,
                   std::strerror(errno), errno);
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifindex;
    if (::bind(sock.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) < 0) {
        fail(fmt::format("bind{}", of).c_str(), errno);
        return false;
    }
    return true;
}

bool SocketCanBus::is_confirmed(const protocol::CanFrame& frame) const
{
    if (!tx_fd_.valid() || frame.extended)
        return false;
    return std::find(options_.confirmed_tx_ids.begin(), options_.confirmed_tx_ids.end(), frame.id) !=
           options_.confirmed_tx_ids.end();
}

bool SocketCanBus::take_echoes()
{
    for (;;) {
        ReceivedFrame echo;
        const ssize_t n = echo.read(tx_fd_.get(), MSG_DONTWAIT);
        if (n < 0) {
            const int e = errno;
            if (e == EINTR)
                continue;
            if (e == EAGAIN || e == EWOULDBLOCK)
                return true;
            CanBusCounterCells::bump(counters_.errors);
            if (is_down_errno(e))
                go_down("read of the send socket's echoes", e);
            else
                fail("read of the send socket's echoes", e);
            return false;
        }
        // Another node's frame with one of our identifiers is not an echo.
        if ((echo.msg.msg_flags & MSG_CONFIRM) == 0 || !unconfirmed_.pending ||
            (echo.cf.can_id & CAN_SFF_MASK) != unconfirmed_.id || (echo.cf.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG)) != 0)
            continue;
        const std::int64_t on_wire_ns = receive_time_ns(echo.msg);
        if (on_wire_ns > unconfirmed_.deadline_ns) {
            CanBusCounterCells::bump(counters_.tx_late);
            std::uint64_t left_out = 0;
            if (tx_late_log_.allow(on_wire_ns, left_out))
                log_->warn("{}: frame 0x{:03X} reached the bus {:.1f} ms after its deadline ({:.1f} ms after it was "
                           "written; {} more not logged since the last)",
                           name_, unconfirmed_.id, static_cast<double>(on_wire_ns - unconfirmed_.deadline_ns) / 1e6,
                           static_cast<double>(on_wire_ns - unconfirmed_.written_ns) / 1e6, left_out);
        }
        unconfirmed_.pending = false;
    }
}

void SocketCanBus::forget_unconfirmed(const char* why)
{
    if (!unconfirmed_.pending)
        return;
    unconfirmed_.pending = false;
    CanBusCounterCells::bump(counters_.tx_unconfirmed);
    log_->warn("{}: frame 0x{:03X} written {:.0f} ms ago was never reported on the bus ({}); the next frame may go",
               name_, unconfirmed_.id, static_cast<double>(base::monotonic_ns() - unconfirmed_.written_ns) / 1e6,
               why);
}

bool SocketCanBus::open()
{
    if (fd_.valid())
        return true;
    backoff_.retry_now();
    return ensure_open(base::monotonic_ns());
}

bool SocketCanBus::ensure_open(std::int64_t now_ns)
{
    if (fd_.valid())
        return true;
    if (!backoff_.due(now_ns))
        return false;
    if (try_open()) {
        if (was_up_) {
            reopens_.fetch_add(1, std::memory_order_relaxed);
            log_->info("{}: interface is up again; sending resumes", name_);
        } else {
            log_->info("{}: open{}", name_,
                       options_.rx_ids.empty() ? std::string(", receiving every frame")
                                               : fmt::format(", receiving {} identifiers", options_.rx_ids.size()));
        }
        was_up_ = true;
        backoff_.on_success();
        last_error_.clear();
        set_state(SocketCanState::up);
        return true;
    }
    backoff_.on_failure(now_ns);
    set_state(SocketCanState::down);
    return false;
}

void SocketCanBus::go_down(const char* what, int err)
{
    fd_.reset();
    tx_fd_.reset();
    fail(what, err);
    log_->warn("{}: interface down; reopening with backoff ({} ms .. {} ms)", name_, options_.reopen_min_ns / 1'000'000,
               options_.reopen_max_ns / 1'000'000);
    backoff_.on_failure(base::monotonic_ns());  // it was up: the delay is back at reopen_min
    set_state(SocketCanState::down);
}

SendResult SocketCanBus::send(const protocol::CanFrame& frame, std::int64_t deadline_ns, SendGate gate)
{
    const std::uint32_t max_id = frame.extended ? protocol::kMaxExtendedId : protocol::kMaxStandardId;
    if (frame.dlc > CAN_MAX_DLEN || frame.id > max_id) {
        CanBusCounterCells::bump(counters_.errors);
        log_->error("{}: invalid frame (id 0x{:X}, dlc {}) not sent", name_, frame.id, frame.dlc);
        return SendResult::error;
    }
    can_frame cf{};
    cf.can_id = frame.id | (frame.extended ? CAN_EFF_FLAG : 0U);
    cf.len = frame.dlc;
    std::memcpy(cf.data, frame.data.data(), frame.dlc);

    bool waited_for_echo = false;
    for (;;) {
        const std::int64_t now = base::monotonic_ns();
        if (now >= deadline_ns) {
            CanBusCounterCells::bump(counters_.deadline_misses);
            log_->debug("{}: deadline passed, frame 0x{:03X} not sent", name_, frame.id);
            return SendResult::deadline_passed;
        }
        if (!gate.open()) {
            CanBusCounterCells::bump(counters_.withdrawn);
            log_->debug("{}: gate closed, frame 0x{:03X} not sent", name_, frame.id);
            return SendResult::withdrawn;
        }
        if (!ensure_open(now)) {
            CanBusCounterCells::bump(counters_.errors);
            return SendResult::error;
        }
        if (unconfirmed_.pending) {
            if (!take_echoes()) {
                CanBusCounterCells::bump(counters_.errors);
                return SendResult::error;
            }
            if (unconfirmed_.pending && state() == SocketCanState::up && now - unconfirmed_.written_ns > kEchoLostAfterNs)
                forget_unconfirmed("no echo for 1 s from an error-active controller");
            if (unconfirmed_.pending) {
                if (!waited_for_echo)
                    CanBusCounterCells::bump(counters_.tx_confirm_waits);
                waited_for_echo = true;
                const std::int64_t left = std::min(deadline_ns - now, kGateCheckNs);
                if (wait_fd(tx_fd_.get(), POLLIN, left) < 0 && errno != EINTR) {
                    CanBusCounterCells::bump(counters_.errors);
                    fail("poll(POLLIN) for the echo", errno);
                    return SendResult::error;
                }
                continue;  // the deadline and the gate are checked before the next look
            }
        }
        const int out_fd = tx_fd_.valid() ? tx_fd_.get() : fd_.get();
        const ssize_t n = ::write(out_fd, &cf, sizeof cf);
        if (n == static_cast<ssize_t>(sizeof cf)) {
            CanBusCounterCells::bump(counters_.sent);
            if (is_confirmed(frame))
                unconfirmed_ = {.pending = true, .id = frame.id, .written_ns = now, .deadline_ns = deadline_ns};
            return SendResult::sent;
        }
        if (n >= 0) {
            CanBusCounterCells::bump(counters_.errors);
            fail("short write", EIO);
            return SendResult::error;
        }
        const int e = errno;
        if (e == EINTR)
            continue;
        if (e == ENOBUFS || e == EAGAIN) {
            CanBusCounterCells::bump(counters_.tx_queue_full_retries);
            // Waits in slices, so that the gate is checked again while the
            // queue stays full.
            const std::int64_t left = std::min(deadline_ns - base::monotonic_ns(), kGateCheckNs);
            if (e == ENOBUFS)
                sleep_for_ns(std::min(left, kEnobufsPauseNs));
            else if (left > 0 && wait_fd(out_fd, POLLOUT, left) < 0 && errno != EINTR) {
                CanBusCounterCells::bump(counters_.errors);
                fail("poll(POLLOUT)", errno);
                return SendResult::error;
            }
            continue;  // the deadline is checked before the next write
        }
        CanBusCounterCells::bump(counters_.errors);
        if (is_down_errno(e))
            go_down("write", e);
        else
            fail("write", e);
        return SendResult::error;
    }
}

bool SocketCanBus::receive(protocol::CanFrame& out, std::int64_t timeout_ns, std::int64_t& t_rx_ns)
{
    const std::int64_t end = base::monotonic_ns() + std::max<std::int64_t>(timeout_ns, 0);
    for (;;) {
        const std::int64_t now = base::monotonic_ns();
        if (!ensure_open(now)) {
            if (now >= end)
                return false;
            sleep_for_ns(std::min(end - now, backoff_.wait_ns(now)));
            continue;
        }
        const int ready = wait_fd(fd_.get(), POLLIN, end - now);
        if (ready < 0) {
            if (errno == EINTR)
                continue;
            CanBusCounterCells::bump(counters_.errors);
            fail("poll(POLLIN)", errno);
            return false;
        }
        if (ready == 0)
            return false;
        ReceivedFrame received;
        const ssize_t n = received.read(fd_.get(), 0);
        const can_frame& cf = received.cf;
        if (n < 0) {
            const int e = errno;
            if (e == EINTR || e == EAGAIN)
                continue;
            CanBusCounterCells::bump(counters_.errors);
            if (!is_down_errno(e)) {
                fail("read", e);
                return false;
            }
            go_down("read", e);
            continue;
        }
        if (n != static_cast<ssize_t>(sizeof cf))
            continue;  // not a classic CAN frame (CAN FD is not enabled)
        if ((cf.can_id & CAN_ERR_FLAG) != 0) {
            std::uint8_t data[8]{};
            std::memcpy(data, cf.data, sizeof data);
            handle_error_frame(cf.can_id, data);
            continue;
        }
        if ((cf.can_id & CAN_RTR_FLAG) != 0 || cf.len > CAN_MAX_DLEN)
            continue;
        out.extended = (cf.can_id & CAN_EFF_FLAG) != 0;
        out.id = cf.can_id & (out.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
        out.dlc = cf.len;
        out.data.fill(0);
        std::memcpy(out.data.data(), cf.data, cf.len);
        t_rx_ns = receive_time_ns(received.msg);
        CanBusCounterCells::bump(counters_.rx);
        return true;
    }
}

void SocketCanBus::handle_error_frame(std::uint32_t can_id, const std::uint8_t (&data)[8])
{
    const CanErrorInfo info = decode_error_frame(can_id, data);
    const std::int64_t now = base::monotonic_ns();
    std::uint64_t left_out = 0;
    if (info.bus_off) {
        CanBusCounterCells::bump(counters_.bus_off);
        if (bus_off_log_.allow(now, left_out))
            log_->error("{}: controller is bus-off (error frame 0x{:X}; {} more not logged since the last)", name_,
                        can_id, left_out);
        set_state(SocketCanState::bus_off);
        forget_unconfirmed("the controller went bus-off, which drops its frames");
    }
    if (info.error_passive) {
        CanBusCounterCells::bump(counters_.error_passive);
        if (error_passive_log_.allow(now, left_out))
            log_->warn("{}: controller is error-passive (ctrl 0x{:02X}; {} more not logged since the last)", name_,
                       data[1], left_out);
        if (state() != SocketCanState::bus_off)
            set_state(SocketCanState::error_passive);
    }
    if (info.recovered && !info.bus_off) {
        if (state() != SocketCanState::up)
            log_->info("{}: controller is error-active again; sending resumes", name_);
        set_state(SocketCanState::up);
    }
    if (info.tx_timeout) {
        if (tx_timeout_log_.allow(now, left_out))
            log_->warn("{}: transmit timeout reported by the controller ({} more not logged since the last)", name_,
                       left_out);
        forget_unconfirmed("the controller reported a transmit timeout");
    }
}

CanBusCounters SocketCanBus::counters() const
{
    return counters_.load();
}

}  // namespace stemd::drivers
