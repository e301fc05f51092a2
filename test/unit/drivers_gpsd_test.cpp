// drivers/gpsd against a stand-in gpsd on a loopback TCP socket: the JSON
// watch stream parsed into fixes (time, mode, status, position, error
// estimates), reports without a position counted, a repeated epoch dropped,
// and a lost connection reopened on the backoff schedule.
#include <gtest/gtest.h>

#ifdef STEMD_HAVE_LIBGPS

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <string>

#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>

#include "gpsd/gpsd_client.hpp"
#include "stemd/base/clock.hpp"

using namespace stemd;

namespace {

class FakeGpsd {
public:
    FakeGpsd()
    {
        listen_fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
        sockaddr_in a{};
        a.sin_family = AF_INET;
        a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        EXPECT_EQ(::bind(listen_fd_, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
        EXPECT_EQ(::listen(listen_fd_, 4), 0);
        socklen_t len = sizeof a;
        ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&a), &len);
        port_ = ntohs(a.sin_port);
    }
    ~FakeGpsd()
    {
        drop();
        ::close(listen_fd_);
    }
    std::uint16_t port() const { return port_; }
    // Waits (bounded) for the client to connect and ask for the watch
    // stream. The client first checks that the port answers with a
    // connection of its own, closed at once (as a real gpsd, which serves
    // many clients, sees it): such a connection is skipped.
    bool accept_client()
    {
        const std::int64_t deadline = base::monotonic_ns() + 20'000'000'000;
        while (base::monotonic_ns() < deadline) {
            pollfd p{listen_fd_, POLLIN, 0};
            if (::poll(&p, 1, 1'000) != 1)
                continue;
            const int fd = ::accept(listen_fd_, nullptr, nullptr);
            if (fd < 0)
                return false;
            pollfd c{fd, POLLIN, 0};
            char byte = 0;
            if (::poll(&c, 1, 20'000) == 1 && ::recv(fd, &byte, 1, MSG_PEEK) == 1) {
                client_fd_ = fd;
                return true;
            }
            ::close(fd);   // closed without a word: the reachability check
        }
        return false;
    }
    void send(const std::string& line)
    {
        const std::string l = line + "\n";
        ASSERT_EQ(::write(client_fd_, l.data(), l.size()), static_cast<ssize_t>(l.size()));
    }
    void drop()
    {
        if (client_fd_ >= 0)
            ::close(client_fd_);
        client_fd_ = -1;
    }

private:
    int listen_fd_ = -1;
    int client_fd_ = -1;
    std::uint16_t port_ = 0;
};

bool pop_within(drivers::GpsdClient& c, drivers::GnssFix& out)
{
    const std::int64_t deadline = base::monotonic_ns() + 20'000'000'000;
    while (base::monotonic_ns() < deadline) {
        if (c.try_pop(out))
            return true;
        base::sleep_for_ns(1'000'000);
    }
    return false;
}

std::int64_t utc_ns(int year, int mon, int day, int h, int m, int s, int ms)
{
    std::tm t{};
    t.tm_year = year - 1900;
    t.tm_mon = mon - 1;
    t.tm_mday = day;
    t.tm_hour = h;
    t.tm_min = m;
    t.tm_sec = s;
    return static_cast<std::int64_t>(timegm(&t)) * 1'000'000'000 + ms * 1'000'000LL;
}

// The client's log goes nowhere: the tests read its counters.
std::shared_ptr<spdlog::logger> null_logger()
{
    return std::make_shared<spdlog::logger>("gpsd", std::make_shared<spdlog::sinks::null_sink_mt>());
}

const char* const kVersion =
    R"({"class":"VERSION","release":"3.22","rev":"3.22","proto_major":3,"proto_minor":14})";

}  // namespace

TEST(DriversGpsd, ParsesFixesAndReconnectsAfterALostConnection)
{
    FakeGpsd gpsd;
    drivers::GpsdClient client({.host = "127.0.0.1", .port = gpsd.port()}, null_logger());
    EXPECT_EQ(client.name(), "gpsd 127.0.0.1:" + std::to_string(gpsd.port()));
    ASSERT_TRUE(client.start());
    ASSERT_TRUE(gpsd.accept_client());
    const std::int64_t before = base::monotonic_ns();
    gpsd.send(kVersion);
    gpsd.send(R"({"class":"TPV","device":"/dev/ttyUSB0","mode":1,"status":0})");
    gpsd.send(R"({"class":"SKY","device":"/dev/ttyUSB0","hdop":0.7})");
    const char* const tpv =
        R"({"class":"TPV","device":"/dev/ttyUSB0","status":3,"mode":3,"time":"2026-05-10T09:19:05.900Z",)"
        R"("lat":50.615633590,"lon":6.999126718,"altHAE":228.833,"epx":0.011,"epy":0.012,"eph":0.025})";
    gpsd.send(tpv);
    gpsd.send(tpv);   // the same epoch again
    drivers::GnssFix fix;
    ASSERT_TRUE(pop_within(client, fix));
    EXPECT_GE(fix.timestamp_sample_ns, before);
    EXPECT_LE(fix.timestamp_sample_ns, base::monotonic_ns());
    EXPECT_EQ(fix.gnss_time_ns, utc_ns(2026, 5, 10, 9, 19, 5, 900));
    EXPECT_EQ(fix.mode, 3);
    EXPECT_EQ(fix.quality, 3);   // RTK fixed
    EXPECT_DOUBLE_EQ(fix.lat_deg, 50.615633590);
    EXPECT_DOUBLE_EQ(fix.lon_deg, 6.999126718);
    EXPECT_NEAR(fix.height_m, 228.833, 1e-9);
    EXPECT_NEAR(fix.epx_m, 0.011, 1e-9);
    EXPECT_NEAR(fix.epy_m, 0.012, 1e-9);
    EXPECT_NEAR(fix.eph_m, 0.025, 1e-9);
    // A later epoch comes through; the repeat did not.
    gpsd.send(R"({"class":"TPV","status":1,"mode":2,"time":"2026-05-10T09:19:06.000Z","lat":50.6,"lon":7.0})");
    ASSERT_TRUE(pop_within(client, fix));
    EXPECT_EQ(fix.gnss_time_ns, utc_ns(2026, 5, 10, 9, 19, 6, 0));
    EXPECT_EQ(fix.mode, 2);
    EXPECT_EQ(fix.height_m, 0) << "a 2D fix has no height";
    EXPECT_FALSE(client.try_pop(fix));
    EXPECT_EQ(client.counters().fixes, 2u);
    EXPECT_EQ(client.counters().no_fix, 1u);

    // gpsd goes away: the client notices, and connects again by itself.
    gpsd.drop();
    ASSERT_TRUE(gpsd.accept_client());
    gpsd.send(kVersion);
    gpsd.send(R"({"class":"TPV","status":1,"mode":3,"time":"2026-05-10T09:19:07.000Z","lat":50.7,"lon":7.1,"altHAE":1})");
    ASSERT_TRUE(pop_within(client, fix));
    EXPECT_DOUBLE_EQ(fix.lat_deg, 50.7);
    const drivers::GnssCounters c = client.counters();
    EXPECT_EQ(c.connects, 2u);
    EXPECT_GE(c.failures, 1u);
    client.stop();
}

// gpsd's TPV eph comes from the DOP (metres even for RTK); a receiver's
// GST, which follows its epoch's TPV, gives the fix its eph instead.
TEST(DriversGpsd, AnEpochsGstGivesTheFixItsErrorEstimate)
{
    FakeGpsd gpsd;
    drivers::GpsdClient client({.host = "127.0.0.1", .port = gpsd.port()}, null_logger());
    ASSERT_TRUE(client.start());
    ASSERT_TRUE(gpsd.accept_client());
    gpsd.send(kVersion);
    const auto tpv = [](const char* time) {
        return std::string(R"({"class":"TPV","status":3,"mode":3,"time":")") + time +
               R"(","lat":50.6,"lon":7.0,"altHAE":200,"eph":13.3})";
    };
    const auto gst = [](const char* time) {
        return std::string(R"({"class":"GST","time":")") + time +
               R"(","rms":0.004,"major":0.004,"minor":0.003,"orient":0.0,"lat":0.004,"lon":0.003,"alt":0.008})";
    };
    // 95 % radius of a circular normal with the mean of the two variances.
    const double from_gst = 2.4477 * std::sqrt((0.004 * 0.004 + 0.003 * 0.003) / 2);
    gpsd.send(tpv("2026-05-10T09:19:05.000Z"));
    gpsd.send(gst("2026-05-10T09:19:05.000Z"));
    drivers::GnssFix fix;
    ASSERT_TRUE(pop_within(client, fix));
    EXPECT_EQ(fix.gnss_time_ns, utc_ns(2026, 5, 10, 9, 19, 5, 0));
    // Before the first GST the client could not know one would come: gpsd's.
    EXPECT_NEAR(fix.eph_m, 13.3, 1e-9);
    gpsd.send(tpv("2026-05-10T09:19:05.100Z"));
    gpsd.send(gst("2026-05-10T09:19:05.100Z"));
    ASSERT_TRUE(pop_within(client, fix));
    EXPECT_EQ(fix.gnss_time_ns, utc_ns(2026, 5, 10, 9, 19, 5, 100));
    EXPECT_NEAR(fix.eph_m, from_gst, 1e-9);
    // A GST of another epoch does not describe this fix.
    gpsd.send(tpv("2026-05-10T09:19:05.200Z"));
    gpsd.send(gst("2026-05-10T09:19:05.100Z"));
    ASSERT_TRUE(pop_within(client, fix));
    EXPECT_EQ(fix.gnss_time_ns, utc_ns(2026, 5, 10, 9, 19, 5, 200));
    EXPECT_NEAR(fix.eph_m, 13.3, 1e-9);
    // Its GST never comes: the fix is published anyway (the next report or
    // the client's wait), with gpsd's estimate.
    gpsd.send(tpv("2026-05-10T09:19:05.300Z"));
    ASSERT_TRUE(pop_within(client, fix));
    EXPECT_EQ(fix.gnss_time_ns, utc_ns(2026, 5, 10, 9, 19, 5, 300));
    EXPECT_NEAR(fix.eph_m, 13.3, 1e-9);
    EXPECT_EQ(client.counters().fixes, 4u);
    client.stop();
}

TEST(DriversGpsd, RetriesWhileNothingListens)
{
    std::uint16_t port = 0;
    {
        FakeGpsd probe;   // a port that was free, closed again
        port = probe.port();
    }
    drivers::GpsdClient client({.host = "127.0.0.1", .port = port}, null_logger());
    ASSERT_TRUE(client.start());
    const std::int64_t deadline = base::monotonic_ns() + 20'000'000'000;
    while (client.counters().failures < 2 && base::monotonic_ns() < deadline)
        base::sleep_for_ns(5'000'000);
    EXPECT_GE(client.counters().failures, 2u) << "it retries on the backoff schedule";
    EXPECT_EQ(client.counters().connects, 0u);
    client.stop();   // returns although nothing ever answered
}

// A host name: looked up off the client's thread, the addresses tried in
// turn ("localhost" may give ::1 first, where nothing listens), and libgps
// given the numeric address that answered.
TEST(DriversGpsd, AHostNameIsLookedUpAndConnected)
{
    addrinfo hints{};
    hints.ai_family = AF_INET;
    hints.ai_socktype = SOCK_STREAM;
    addrinfo* found = nullptr;
    if (::getaddrinfo("localhost", nullptr, &hints, &found) != 0)
        GTEST_SKIP() << "this machine does not resolve 'localhost'";
    ::freeaddrinfo(found);
    FakeGpsd gpsd;
    drivers::GpsdClient client({.host = "localhost", .port = gpsd.port()}, null_logger());
    ASSERT_TRUE(client.start());
    ASSERT_TRUE(gpsd.accept_client());
    gpsd.send(kVersion);
    gpsd.send(R"({"class":"TPV","status":1,"mode":2,"time":"2026-05-10T09:19:06.000Z","lat":50.6,"lon":7.0})");
    drivers::GnssFix fix;
    ASSERT_TRUE(pop_within(client, fix));
    EXPECT_DOUBLE_EQ(fix.lat_deg, 50.6);
    EXPECT_EQ(client.counters().connects, 1u);
    client.stop();
}

// A name that does not resolve (or whose lookup does not end within an
// attempt) is a failed attempt like a refused connection: counted and
// retried, and stop() does not wait for a lookup still running.
TEST(DriversGpsd, ANameThatDoesNotResolveIsRetried)
{
    drivers::GpsdClient client({.host = "gpsd.stemd-test.invalid", .port = 2947}, null_logger());
    ASSERT_TRUE(client.start());
    const std::int64_t deadline = base::monotonic_ns() + 20'000'000'000;
    while (client.counters().failures < 1 && base::monotonic_ns() < deadline)
        base::sleep_for_ns(5'000'000);
    EXPECT_GE(client.counters().failures, 1u);
    EXPECT_EQ(client.counters().connects, 0u);
    client.stop();
}

#endif  // STEMD_HAVE_LIBGPS
