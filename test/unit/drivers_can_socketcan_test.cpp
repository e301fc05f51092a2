// The SocketCAN bus where the host has no CAN (build and CI machines): opening
// a nonexistent interface fails with a clear error naming it, sending and
// receiving then fail cleanly (no crash, counted); deadlines are checked
// first; error frames are decoded. The real thing runs on vcan in the VM
// (test/vm/socketcan_check.cpp, ctest vm.socketcan).
#include <gtest/gtest.h>

#include <linux/can.h>
#include <linux/can/error.h>

#include <algorithm>
#include <sstream>

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include "socketcan/socketcan_bus.hpp"
#include "captured_log.hpp"
#include "stemd/base/clock.hpp"

using namespace stemd;
using namespace stemd::drivers;

namespace {

constexpr std::int64_t kSecond = 1'000'000'000;

using stemd::test::CapturedLog;

SocketCanOptions on(const char* interface, std::int64_t reopen_min_ns = 10'000'000,
                    std::int64_t reopen_max_ns = 1'000'000'000)
{
    SocketCanOptions o;
    o.interface = interface;
    o.reopen_min_ns = reopen_min_ns;
    o.reopen_max_ns = reopen_max_ns;
    return o;
}

const protocol::CanFrame kFrame{.id = 0x301, .extended = false, .dlc = 8, .data = {1, 2, 3, 4, 5, 6, 7, 8}};

}  // namespace

TEST(SocketCan, NonexistentInterfaceIsAClearErrorNamingIt)
{
    CapturedLog log;
    SocketCanBus bus(on("stemdnocan9"), log.logger);
    EXPECT_EQ(bus.name(), "socketcan:stemdnocan9");
    EXPECT_FALSE(bus.open());
    EXPECT_EQ(bus.state(), SocketCanState::down);
    // This host has no CAN: socket() fails (EAFNOSUPPORT) or, with CAN, the
    // interface lookup (ENODEV). Either way the message names the interface and errno.
    EXPECT_NE(bus.last_error().find("stemdnocan9"), std::string::npos) << bus.last_error();
    EXPECT_NE(bus.last_error().find("errno"), std::string::npos) << bus.last_error();
    EXPECT_NE(log.text().find("stemdnocan9"), std::string::npos) << log.text();

    EXPECT_EQ(bus.send(kFrame, stemd::base::monotonic_ns() + kSecond), SendResult::error);
    protocol::CanFrame got;
    EXPECT_FALSE(bus.receive(got, 5'000'000));
    const auto c = bus.counters();
    EXPECT_EQ(c.sent, 0U);
    EXPECT_GE(c.errors, 1U);
    EXPECT_EQ(c.rx, 0U);
    EXPECT_EQ(bus.reopens(), 0U);
}

TEST(SocketCan, RepeatedReopenFailuresAreLoggedOnce)
{
    CapturedLog log;
    SocketCanBus bus(on("stemdnocan9", 1'000'000, 2'000'000),
                     log.logger);
    EXPECT_FALSE(bus.open());
    protocol::CanFrame got;
    EXPECT_FALSE(bus.receive(got, 30'000'000));  // several reopen attempts on the backoff schedule
    for (int i = 0; i < 20; ++i)
        EXPECT_EQ(bus.send(kFrame, stemd::base::monotonic_ns() + kSecond), SendResult::error);
    const std::string text = log.text();
    EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1) << text;
}

TEST(SocketCan, DeadlineAlreadyPassedIsNotSentAndCounted)
{
    CapturedLog log;
    SocketCanBus bus(on("stemdnocan9"), log.logger);
    EXPECT_EQ(bus.send(kFrame, stemd::base::monotonic_ns() - 1), SendResult::deadline_passed);
    EXPECT_EQ(bus.send(kFrame, 0), SendResult::deadline_passed);
    const auto c = bus.counters();
    EXPECT_EQ(c.deadline_misses, 2U);
    EXPECT_EQ(c.sent, 0U);
    EXPECT_EQ(c.errors, 0U);  // the deadline is checked before the socket
}

TEST(SocketCan, InvalidFramesAndNamesAreErrors)
{
    CapturedLog log;
    SocketCanBus bus(on("stemdnocan9"), log.logger);
    EXPECT_EQ(bus.send({.id = 0x800, .extended = false, .dlc = 8, .data = {}}, stemd::base::monotonic_ns() + kSecond),
              SendResult::error);
    EXPECT_EQ(bus.send({.id = 0x100, .extended = false, .dlc = 9, .data = {}}, stemd::base::monotonic_ns() + kSecond),
              SendResult::error);
    EXPECT_EQ(bus.counters().errors, 2U);

    SocketCanBus long_name(on("a-name-longer-than-15"), log.logger);
    EXPECT_FALSE(long_name.open());
    EXPECT_NE(long_name.last_error().find("a-name-longer-than-15"), std::string::npos) << long_name.last_error();
}

TEST(SocketCan, ErrorFramesDecode)
{
    const std::uint8_t none[8]{};
    EXPECT_FALSE(decode_error_frame(0x123, none).bus_off);  // not an error frame

    const auto busoff = decode_error_frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, none);
    EXPECT_TRUE(busoff.bus_off);
    EXPECT_FALSE(busoff.error_passive);
    EXPECT_FALSE(busoff.recovered);

    const std::uint8_t tx_passive[8]{0, CAN_ERR_CRTL_TX_PASSIVE};
    const std::uint8_t rx_passive[8]{0, CAN_ERR_CRTL_RX_PASSIVE};
    EXPECT_TRUE(decode_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, tx_passive).error_passive);
    EXPECT_TRUE(decode_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, rx_passive).error_passive);
    // The same data byte without CAN_ERR_CRTL in the id means nothing.
    EXPECT_FALSE(decode_error_frame(CAN_ERR_FLAG | CAN_ERR_PROT, tx_passive).error_passive);

    const std::uint8_t warning[8]{0, CAN_ERR_CRTL_TX_WARNING};
    EXPECT_FALSE(decode_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, warning).error_passive);

    EXPECT_TRUE(decode_error_frame(CAN_ERR_FLAG | CAN_ERR_RESTARTED, none).recovered);
    const std::uint8_t active[8]{0, CAN_ERR_CRTL_ACTIVE};
    EXPECT_TRUE(decode_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, active).recovered);
    EXPECT_TRUE(decode_error_frame(CAN_ERR_FLAG | CAN_ERR_TX_TIMEOUT, none).tx_timeout);
}

TEST(SocketCan, SendResultNames)
{
    EXPECT_EQ(to_string(SendResult::sent), "sent");
    EXPECT_EQ(to_string(SendResult::deadline_passed), "deadline_passed");
    EXPECT_EQ(to_string(SendResult::error), "error");
    EXPECT_EQ(to_string(SocketCanState::bus_off), "bus_off");
}
