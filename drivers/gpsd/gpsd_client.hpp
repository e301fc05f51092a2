// gpsd client (libgps, Debian's libgps-dev; gpsd API 11 = gpsd 3.22): a
// thread of its own connects to gpsd at host:port, asks for the JSON watch
// stream, and publishes each position report (TPV with mode 2D or 3D) into a
// lock-free SPSC ring (base::SpscRing) that the actuator thread drains with
// try_pop(): the processing and actuator threads never wait on gpsd.
//
// eph: gpsd's TPV estimate comes from the DOP times a fixed range error
// (13.3 m for an RTK fixed HDOP 0.7), so when the receiver sends GST
// reports (NMEA GST: its own 1-sigma latitude/longitude errors) a fix waits
// for its epoch's GST, which follows it, and takes its eph from that (the
// 95 % radius); without a GST it keeps gpsd's.
//
// State machine (the client's thread; counters() from any thread):
//
//   closed --gps_open + gps_stream ok--> streaming --read error / EOF--> closed
//     ^  |                                                                |
//     |  +--fail: retry at ReopenBackoff's schedule (0.2 s doubling to 5 s)
//     +-------------------------------------------------------------------+
//
// Each transition is logged once, naming host:port and errno (a refused
// connection while gpsd is down is logged on the first failure only, then
// once when it comes back). The thread waits at most 100 ms at a time
// (gps_waiting) and a connect attempt ends at once on stop() (an eventfd),
// so stop() returns within about 100 ms. A host name is looked up on a
// thread of its own (getaddrinfo cannot be cut short, and a DNS server that
// does not answer holds it for seconds): a stop stops waiting for it, and
// libgps is given the numeric address that answered.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include <spdlog/logger.h>

#include "stemd/base/spsc_ring.hpp"
#include "stemd/base/unique_fd.hpp"
#include "stemd/drivers/gnss_factory.hpp"
#include "stemd/drivers/gnss_source.hpp"
#include "stemd/drivers/reopen_backoff.hpp"

namespace stemd::drivers {

class GpsdClient final : public GnssSource {
public:
    GpsdClient(GnssSpec spec, std::shared_ptr<spdlog::logger> log, std::size_t ring_capacity = 256);
    ~GpsdClient() override;

    std::string_view name() const override { return name_; }
    bool start() override;
    void stop() override;
    bool try_pop(GnssFix& out) noexcept override { return ring_.try_pop(out); }
    GnssCounters counters() const override;

private:
    enum class State : std::uint8_t { closed, streaming };

    void run();
    bool connect();       // closed -> streaming, or a logged failure
    void disconnect();    // streaming -> closed
    void read_once();     // one report, published if it is a position
    void publish_pending();   // the fix waiting for its GST, as it is

    const GnssSpec spec_;
    const std::string name_;
    const std::shared_ptr<spdlog::logger> log_;
    base::SpscRing<GnssFix> ring_;
    ReopenBackoff backoff_{200'000'000, 5'000'000'000};
    State state_ = State::closed;
    bool failure_logged_ = false;
    struct Session;              // gps_data_t, kept out of this header
    std::unique_ptr<Session> session_;
    struct Lookup;               // the host name's lookup, off this thread
    std::unique_ptr<Lookup> lookup_;
    std::int64_t last_fix_time_ns_ = -1;
    // With a receiver that sends GST (error statistics) after each
    // position: the newest position, until its GST gives its eph.
    bool gst_seen_ = false;
    bool pending_ = false;
    GnssFix pending_fix_;
    std::atomic<bool> stop_{false};
    base::UniqueFd stop_fd_;   // eventfd: written by stop(), wakes a connect attempt
    std::thread thread_;
    std::atomic<std::uint64_t> fixes_{0}, no_fix_{0}, connects_{0}, failures_{0};
};

}  // namespace stemd::drivers
