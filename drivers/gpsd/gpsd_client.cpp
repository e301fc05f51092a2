#include "gpsd/gpsd_client.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>

#include <gps.h>
#include <netdb.h>
#include <pthread.h>
#include <signal.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <memory>
#include <system_error>
#include <thread>

#include "stemd/base/clock.hpp"
#include "stemd/base/unique_fd.hpp"

#if GPSD_API_MAJOR_VERSION < 9
#error "drivers/gpsd needs gpsd API 9 or later (timespec fix times; Debian 12 has 11)"
#endif

namespace stemd::drivers {

namespace {

constexpr int kWaitUs = 100'000;   // longest wait for data: stop() latency
constexpr std::int64_t kPollNs = 50'000'000;
constexpr std::int64_t kConnectTimeoutNs = 2'000'000'000;   // one attempt; then the backoff

double or_unknown(double v)
{
    return std::isfinite(v) ? v : -1;
}

// The 95 % horizontal radius from a GST's 1-sigma latitude and longitude
// errors: a circular normal with their mean variance (radius factor
// sqrt(-2 ln 0.05)). -1 when either is missing.
double eph_from_gst(const gst_t& gst)
{
    const double lat = gst.lat_err_deviation, lon = gst.lon_err_deviation;
    if (!std::isfinite(lat) || !std::isfinite(lon) || lat < 0 || lon < 0)
        return -1;
    return 2.4477 * std::sqrt((lat * lat + lon * lon) / 2);
}

// ppoll until `deadline_ns` on the monotonic clock, resumed after a signal
// with the time then left; ppoll's result.
int poll_until(pollfd* fds, nfds_t count, std::int64_t deadline_ns)
{
    int r = 0;
    do {
        const std::int64_t left_ns = std::max<std::int64_t>(deadline_ns - base::monotonic_ns(), 0);
        const timespec ts{static_cast<time_t>(left_ns / 1'000'000'000), static_cast<long>(left_ns % 1'000'000'000)};
        r = ::ppoll(fds, count, &ts, nullptr);
    } while (r < 0 && errno == EINTR);
    return r;
}

// A host name's addresses, looked up on a thread of its own: getaddrinfo
// cannot be cut short, and a DNS server that does not answer holds it for
// the resolver's timeouts (seconds per try), which stop() must not wait
// for. The lookup thread and its waiter share the result; a waiter that
// gives up leaves it to the thread, and the next attempt waits for the same
// lookup instead of starting another.
class HostLookup {
public:
    struct Freer {
        void operator()(addrinfo* a) const noexcept { ::freeaddrinfo(a); }
    };
    using Addresses = std::unique_ptr<addrinfo, Freer>;

    // The addresses of host:port, or nullptr with the reason: EHOSTUNREACH
    // (the name does not resolve), ETIMEDOUT (not yet by `deadline_ns`),
    // ECANCELED (stop_fd readable), or why the thread did not start.
    Addresses resolve(const std::string& host, std::uint16_t port, int stop_fd, std::int64_t deadline_ns, int& err)
    {
        if (!in_flight_) {
            auto shared = std::make_shared<Shared>();
            shared->done.reset(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK));
            if (!shared->done.valid()) {
                err = errno;
                return nullptr;
            }
            try {
                std::thread([shared, host, port] {
                    addrinfo hints{};
                    hints.ai_family = AF_UNSPEC;
                    hints.ai_socktype = SOCK_STREAM;
                    addrinfo* found = nullptr;
                    if (::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found) == 0)
                        shared->found.reset(found);
                    shared->ready.store(true, std::memory_order_release);
                    const std::uint64_t one = 1;
                    [[maybe_unused]] const ssize_t n = ::write(shared->done.get(), &one, sizeof one);
                }).detach();
            } catch (const std::system_error& e) {
                err = e.code().value();
                return nullptr;
            }
            in_flight_ = std::move(shared);
        }
        pollfd fds[2] = {{in_flight_->done.get(), POLLIN, 0}, {stop_fd, POLLIN, 0}};
        if (poll_until(fds, 2, deadline_ns) < 0) {
            err = errno;
            return nullptr;
        }
        if (!in_flight_->ready.load(std::memory_order_acquire)) {
            err = (fds[1].revents & POLLIN) != 0 ? ECANCELED : ETIMEDOUT;
            return nullptr;
        }
        Addresses found = std::move(in_flight_->found);
        in_flight_.reset();
        err = found ? 0 : EHOSTUNREACH;
        return found;
    }

private:
    struct Shared {
        base::UniqueFd done;   // eventfd: wakes the waiter once `ready`
        Addresses found;
        std::atomic<bool> ready{false};   // `found` is final
    };
    std::shared_ptr<Shared> in_flight_;
};

// gps_open() connects with a blocking connect(): to a host that drops the
// SYN (a full backlog, a firewall) it blocks for minutes, and stop() with it.
// So each attempt first connects here, non-blocking and polled together
// with the stop eventfd, until `deadline_ns`; libgps is only asked once the
// port answers, and then with the numeric address that answered
// (`numeric_host`), so that it does not look the name up again. It also
// finds the system's errno (ECONNREFUSED, EHOSTUNREACH...) that libgps's own
// codes hide. 0 when it connects, ECANCELED when stopped.
int try_connect(const addrinfo* found, int stop_fd, std::int64_t deadline_ns, std::string& numeric_host)
{
    int err = ETIMEDOUT;
    for (const addrinfo* a = found; a != nullptr; a = a->ai_next) {
        const base::UniqueFd fd(::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, a->ai_protocol));
        if (!fd.valid()) {
            err = errno;
            continue;
        }
        if (::connect(fd.get(), a->ai_addr, a->ai_addrlen) == 0) {
            err = 0;
        } else {
            err = errno;
            if (err != EINPROGRESS)
                continue;
            pollfd fds[2] = {{fd.get(), POLLOUT, 0}, {stop_fd, POLLIN, 0}};
            const int r = poll_until(fds, 2, deadline_ns);
            if (r > 0 && (fds[1].revents & POLLIN) != 0)
                return ECANCELED;
            if (r == 0)
                return ETIMEDOUT;
            socklen_t len = sizeof err;
            if (r < 0 || ::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &err, &len) != 0)
                err = errno;
        }
        if (err == 0) {
            char text[NI_MAXHOST];
            if (::getnameinfo(a->ai_addr, a->ai_addrlen, text, sizeof text, nullptr, 0, NI_NUMERICHOST) != 0)
                return EADDRNOTAVAIL;
            numeric_host = text;
            return 0;
        }
    }
    return err;
}

}  // namespace

struct GpsdClient::Session {
    gps_data_t data{};
};

struct GpsdClient::Lookup : HostLookup {};

GpsdClient::GpsdClient(GnssSpec spec, std::shared_ptr<spdlog::logger> log, std::size_t ring_capacity)
    : spec_(std::move(spec)),
      name_("gpsd " + spec_.host + ":" + std::to_string(spec_.port)),
      log_(std::move(log)),
      ring_(ring_capacity),
      lookup_(std::make_unique<Lookup>())
{
}

GpsdClient::~GpsdClient()
{
    stop();
}

bool GpsdClient::start()
{
    if (thread_.joinable())
        return true;
    stop_.store(false);
    stop_fd_.reset(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK));
    if (!stop_fd_.valid()) {
        log_->error("gpsd {}:{}: eventfd: {} (errno {})", spec_.host, spec_.port, std::strerror(errno), errno);
        return false;
    }
    thread_ = std::thread([this] { run(); });
    return true;
}

void GpsdClient::stop()
{
    stop_.store(true);
    if (thread_.joinable()) {
        // Wakes a connect attempt at once (the other waits are short).
        const std::uint64_t one = 1;
        if (::write(stop_fd_.get(), &one, sizeof one) < 0)
            log_->warn("gpsd {}:{}: eventfd write: {}", spec_.host, spec_.port, std::strerror(errno));
        thread_.join();
    }
    stop_fd_.reset();
}

GnssCounters GpsdClient::counters() const
{
    GnssCounters c;
    c.fixes = fixes_.load(std::memory_order_relaxed);
    c.no_fix = no_fix_.load(std::memory_order_relaxed);
    c.dropped = ring_.dropped();
    c.connects = connects_.load(std::memory_order_relaxed);
    c.failures = failures_.load(std::memory_order_relaxed);
    return c;
}

void GpsdClient::run()
{
    // libgps writes with write(2): to a gpsd that has gone away that would
    // raise SIGPIPE and end the process. Blocked in this thread, the write
    // fails with EPIPE instead.
    sigset_t pipe;
    sigemptyset(&pipe);
    sigaddset(&pipe, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe, nullptr);
    while (!stop_.load(std::memory_order_relaxed)) {
        if (state_ == State::closed) {
            const std::int64_t now = base::monotonic_ns();
            if (!backoff_.due(now)) {
                base::sleep_for_ns(std::min(backoff_.wait_ns(now), kPollNs));
                continue;
            }
            if (!connect())
                backoff_.on_failure(base::monotonic_ns());
            continue;
        }
        read_once();
    }
    if (state_ == State::streaming) {
        publish_pending();
        gps_stream(&session_->data, WATCH_DISABLE, nullptr);
        disconnect();
    }
}

bool GpsdClient::connect()
{
    const std::int64_t deadline_ns = base::monotonic_ns() + kConnectTimeoutNs;
    int reach = 0;
    const HostLookup::Addresses addresses = lookup_->resolve(spec_.host, spec_.port, stop_fd_.get(), deadline_ns, reach);
    const char* failed = reach == ETIMEDOUT ? "no answer to the name lookup" : "the name does not resolve";
    std::string numeric_host;
    if (addresses) {
        reach = try_connect(addresses.get(), stop_fd_.get(), deadline_ns, numeric_host);
        failed = "no connection";
    }
    if (reach == ECANCELED)
        return false;
    auto session = std::make_unique<Session>();
    const std::string port = std::to_string(spec_.port);
    errno = 0;
    if (reach != 0 || gps_open(numeric_host.c_str(), port.c_str(), &session->data) != 0) {
        const int code = errno;
        failures_.fetch_add(1, std::memory_order_relaxed);
        if (!failure_logged_) {
            std::string unused;
            const int err = reach != 0 ? reach
                                       : try_connect(addresses.get(), stop_fd_.get(),
                                                     base::monotonic_ns() + kConnectTimeoutNs, unused);
            log_->warn("gpsd {}:{}: cannot connect: {} ({}, errno {}); retrying every {:.1f} s at most", spec_.host,
                       spec_.port, reach != 0 ? failed : gps_errstr(code), std::strerror(err), err,
                       static_cast<double>(backoff_.max_ns()) / 1e9);
        }
        failure_logged_ = true;
        return false;
    }
    if (gps_stream(&session->data, WATCH_ENABLE | WATCH_JSON, nullptr) != 0) {
        const int err = errno;
        failures_.fetch_add(1, std::memory_order_relaxed);
        if (!failure_logged_)
            log_->warn("gpsd {}:{}: cannot start the watch stream: {} (errno {})", spec_.host, spec_.port,
                       std::strerror(err), err);
        failure_logged_ = true;
        gps_close(&session->data);
        return false;
    }
    session_ = std::move(session);
    state_ = State::streaming;
    failure_logged_ = false;
    backoff_.on_success();
    connects_.fetch_add(1, std::memory_order_relaxed);
    log_->info("gpsd {}:{}: connected, watching", spec_.host, spec_.port);
    return true;
}

void GpsdClient::disconnect()
{
    if (session_) {
        gps_close(&session_->data);
        session_.reset();
    }
    state_ = State::closed;
}

void GpsdClient::publish_pending()
{
    if (!pending_)
        return;
    pending_ = false;
    if (ring_.try_push(pending_fix_))
        fixes_.fetch_add(1, std::memory_order_relaxed);
}

void GpsdClient::read_once()
{
    gps_data_t& d = session_->data;
    if (!gps_waiting(&d, kWaitUs)) {
        publish_pending();   // its GST did not come
        return;   // nothing within the wait (a closed socket is readable: gps_read reports it)
    }
    d.set = 0;
    errno = 0;
    const int n = gps_read(&d, nullptr, 0);
    const std::int64_t received_ns = base::monotonic_ns();
    if (n <= 0) {
        const int err = errno;
        failures_.fetch_add(1, std::memory_order_relaxed);
        log_->warn("gpsd {}:{}: connection lost: {} (errno {}); reconnecting", spec_.host, spec_.port,
                   err != 0 ? std::strerror(err) : "end of stream", err);
        publish_pending();
        disconnect();
        backoff_.on_failure(received_ns);
        return;
    }
    if ((d.set & GST_SET) != 0 && (d.set & MODE_SET) == 0) {
        // The receiver's error statistics for an epoch: gpsd's own eph
        // comes from the DOP and a fixed range error (metres even for RTK),
        // the GST's from the receiver's solution.
        gst_seen_ = true;
        const std::int64_t gst_ns =
            static_cast<std::int64_t>(d.gst.utctime.tv_sec) * 1'000'000'000 + d.gst.utctime.tv_nsec;
        const double eph = eph_from_gst(d.gst);
        if (pending_ && gst_ns == pending_fix_.gnss_time_ns && eph >= 0)
            pending_fix_.eph_m = eph;
        publish_pending();
        return;
    }
    if ((d.set & MODE_SET) == 0)
        return;   // not a position report (SKY, VERSION, DEVICES...)
    if (d.fix.mode < MODE_2D || (d.set & LATLON_SET) == 0 || !std::isfinite(d.fix.latitude) ||
        !std::isfinite(d.fix.longitude)) {
        no_fix_.fetch_add(1, std::memory_order_relaxed);
        return;
    }
    GnssFix fix;
    fix.timestamp_sample_ns = received_ns;
    if ((d.set & TIME_SET) != 0)
        fix.gnss_time_ns = static_cast<std::int64_t>(d.fix.time.tv_sec) * 1'000'000'000 + d.fix.time.tv_nsec;
    if (fix.gnss_time_ns != 0 && fix.gnss_time_ns == last_fix_time_ns_)
        return;   // the same epoch reported again
    last_fix_time_ns_ = fix.gnss_time_ns;
    fix.mode = static_cast<std::uint8_t>(d.fix.mode);
    fix.quality = static_cast<std::uint8_t>(d.fix.status);
    fix.lat_deg = d.fix.latitude;
    fix.lon_deg = d.fix.longitude;
    fix.height_m = d.fix.mode >= MODE_3D && std::isfinite(d.fix.altHAE) ? d.fix.altHAE : 0;
    fix.eph_m = or_unknown(d.fix.eph);
    fix.epx_m = or_unknown(d.fix.epx);
    fix.epy_m = or_unknown(d.fix.epy);
    // A receiver that sends GST sends it after the epoch's position: the
    // fix waits for it (at most until the next report or kWaitUs).
    publish_pending();
    pending_fix_ = fix;
    pending_ = true;
    if (!gst_seen_)
        publish_pending();
}

std::unique_ptr<GnssSource> make_gpsd_source(const GnssSpec& spec, std::shared_ptr<spdlog::logger> log,
                                             std::string&)
{
    return std::make_unique<GpsdClient>(spec, std::move(log));
}

}  // namespace stemd::drivers
