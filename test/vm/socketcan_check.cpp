// The project's SocketCAN driver (drivers/socketcan, stemd_drivers) on the
// real vcan driver in the VM: unlike can_probe.cpp this goes through
// SocketCanBus and the actuation encoder/decoder, so the check fails when the
// project's code is broken.
//
//   stemd-vm-socketcan-check frames
//       prints "target ID#DATA" and "odometry ID#DATA": the fixed messages
//       below, E2E-protected by the actuation encoder (guest.sh compares them
//       with its precomputed copies).
//   stemd-vm-socketcan-check send IFACE
//       sends the TARGET frame through SocketCanBus (guest.sh checks candump saw it).
//   stemd-vm-socketcan-check receive IFACE TIMEOUT_MS -- TRIGGER...
//       SocketCanBus with a receive filter on the ODOMETRY id; runs TRIGGER
//       (cansend), receives, and checks the E2E status and decoded values.
//   stemd-vm-socketcan-check gate IFACE -- TRIGGER...
//       runs "TRIGGER add" (a qdisc that takes a few frames, then refuses
//       them: ENOBUFS), sends until the transmit queue is full, then sends a
//       frame whose SendGate closes after its first write was refused: the
//       send must give it up (withdrawn) within milliseconds, long before
//       its deadline, and count it; then runs "TRIGGER del".
//   stemd-vm-socketcan-check confirm IFACE
//       on an interface whose driver echoes a frame when it leaves (vcan
//       loaded with echo=1) behind a token bucket that lets one frame out
//       every 400 ms: TARGETs sent with confirmed_tx_ids go one at a time.
//       A frame whose predecessor is still queued is never written: given
//       up at its deadline (deadline_passed) or when its gate closes
//       (withdrawn); a frame written in time but leaving after its deadline
//       is counted in tx_late; a second bus sees exactly the frames sent.
//   stemd-vm-socketcan-check downup IFACE -- TRIGGER...
//       sends, runs "TRIGGER down", checks sends fail with errors reported (no
//       crash, not sent), runs "TRIGGER up", checks sending resumes (the driver
//       reopens) and a second bus receives the frame sent after the resume.
#include <time.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include "probe_util.hpp"
#include "socketcan/socketcan_bus.hpp"
#include "stemd/protocol/e2e.hpp"
#include "stemd/protocol/messages.hpp"
#include "stemd/base/clock.hpp"

namespace {

using namespace stemd;
using drivers::SendResult;
using drivers::SocketCanBus;
using drivers::SocketCanOptions;
using stemd::vmprobe::fail;
using stemd::vmprobe::info;

constexpr std::int64_t kMs = 1'000'000;

const protocol::CanIds kIds;  // base 0x300
const protocol::TargetCommand kTarget{.target_id = 1234, .tool_id = 2, .lane = 5, .fire_odom_mm = 200000,
                                       .lateral_mm = -321, .plant_class = protocol::PlantClass::Weed};
constexpr std::uint8_t kTargetCounter = 3;
const protocol::Odometry kOdometry{.odom_mm = 987654, .speed_mm_per_s = -1500};
constexpr std::uint8_t kOdometryCounter = 7;

std::string text(const protocol::CanFrame& f)
{
    char buf[8];
    std::string s;
    std::snprintf(buf, sizeof buf, "%03X#", f.id);
    s = buf;
    for (std::size_t i = 0; i < f.dlc; ++i) {
        std::snprintf(buf, sizeof buf, "%02X", f.data[i]);
        s += buf;
    }
    return s;
}

protocol::CanFrame target_frame(std::uint8_t counter, const protocol::TargetCommand& msg = kTarget)
{
    protocol::CanFrame f;
    const auto r = protocol::encode(msg, counter, kIds, f);
    if (!r)
        fail("encode TARGET: " + std::string(protocol::to_string(r.error)));
    return f;
}

protocol::CanFrame odometry_frame()
{
    protocol::CanFrame f;
    const auto r = protocol::encode(kOdometry, kOdometryCounter, kIds, f);
    if (!r)
        fail("encode ODOMETRY: " + std::string(protocol::to_string(r.error)));
    return f;
}

std::shared_ptr<spdlog::logger> logger()
{
    auto log = std::make_shared<spdlog::logger>("socketcan", std::make_shared<spdlog::sinks::stdout_sink_st>());
    log->set_pattern("  [%l] %v");
    return log;
}

SocketCanOptions options(const std::string& iface, std::vector<std::uint32_t> rx_ids = {},
                         std::vector<std::uint32_t> confirmed_tx_ids = {})
{
    SocketCanOptions o;
    o.interface = iface;
    o.rx_ids = std::move(rx_ids);
    o.confirmed_tx_ids = std::move(confirmed_tx_ids);
    o.reopen_min_ns = 10 * kMs;
    o.reopen_max_ns = 100 * kMs;
    return o;
}

void open_or_fail(SocketCanBus& bus)
{
    if (!bus.open())
        fail("cannot open " + std::string(bus.name()) + ": " + bus.last_error());
}

void counters(const SocketCanBus& bus)
{
    const auto c = bus.counters();
    std::printf("%.*s: state %.*s, sent %llu, retries %llu, deadline misses %llu, withdrawn %llu, errors %llu, rx %llu, "
                "reopens %llu, echo waits %llu, late %llu, unconfirmed %llu\n",
                static_cast<int>(bus.name().size()), bus.name().data(),
                static_cast<int>(to_string(bus.state()).size()), to_string(bus.state()).data(),
                static_cast<unsigned long long>(c.sent), static_cast<unsigned long long>(c.tx_queue_full_retries),
                static_cast<unsigned long long>(c.deadline_misses), static_cast<unsigned long long>(c.withdrawn),
                static_cast<unsigned long long>(c.errors),
                static_cast<unsigned long long>(c.rx), static_cast<unsigned long long>(bus.reopens()),
                static_cast<unsigned long long>(c.tx_confirm_waits), static_cast<unsigned long long>(c.tx_late),
                static_cast<unsigned long long>(c.tx_unconfirmed));
    std::fflush(stdout);
}

void sleep_ms(int ms)
{
    const timespec ts{0, ms * kMs};
    nanosleep(&ts, nullptr);
}

void send(const std::string& iface)
{
    SocketCanBus bus(options(iface), logger());
    open_or_fail(bus);
    const auto frame = target_frame(kTargetCounter);
    const auto r = bus.send(frame, stemd::base::monotonic_ns() + 1000 * kMs);
    if (r != SendResult::sent)
        fail("send " + text(frame) + " on " + iface + ": " + std::string(to_string(r)) + " " + bus.last_error());
    info("sent TARGET " + text(frame) + " on " + iface);
    counters(bus);
    if (bus.counters().sent != 1)
        fail("sent counter is not 1");
}

void receive(const std::string& iface, int timeout_ms, const std::vector<std::string>& trigger)
{
    const std::uint16_t id = kIds.id(protocol::MessageKind::Odometry);
    SocketCanBus bus(options(iface, {id}), logger());
    open_or_fail(bus);
    info("listening on " + iface + " for ODOMETRY (id " + std::to_string(id) + ")");
    if (!trigger.empty()) {
        const int status = stemd::vmprobe::run_command(trigger);
        if (status != 0)
            fail("trigger " + trigger[0] + " exited " + std::to_string(status));
    }
    protocol::CanFrame frame;
    if (!bus.receive(frame, timeout_ms * kMs))
        fail("no ODOMETRY frame on " + iface + " within " + std::to_string(timeout_ms) + " ms");
    info("received " + text(frame));
    if (frame.id != id)
        fail("the receive filter let through " + text(frame));
    protocol::E2eChecker checker(id);
    const auto status = checker.check(std::span<const std::uint8_t, 8>(frame.data));
    info("E2E: " + std::string(protocol::to_string(status)));
    if (!protocol::e2e_accepted(status))
        fail("E2E check rejected " + text(frame));
    protocol::Odometry odo;
    const auto r = protocol::decode(frame, kIds, odo);
    if (!r)
        fail("decode ODOMETRY: " + std::string(protocol::to_string(r.error)));
    info("ODOMETRY odom_mm " + std::to_string(odo.odom_mm) + ", speed_mm_per_s " + std::to_string(odo.speed_mm_per_s));
    if (!(odo == kOdometry))
        fail("decoded values differ from the ones sent");
    if (protocol::e2e_counter_of(std::span<const std::uint8_t, 8>(frame.data)) != kOdometryCounter)
        fail("alive counter differs");
    counters(bus);
}

void run_trigger(std::vector<std::string> trigger, const char* arg)
{
    trigger.emplace_back(arg);
    const int status = stemd::vmprobe::run_command(trigger);
    if (status != 0)
        fail("trigger '" + trigger[0] + " ... " + arg + "' exited " + std::to_string(status));
}

// A SendGate open for its first check only: the enable input dropping
// while the frame waits for the transmit queue.
struct OpenOnce {
    mutable int checks = 0;
    static bool open(const void* self) { return ++static_cast<const OpenOnce*>(self)->checks == 1; }
};

void gate(const std::string& iface, const std::vector<std::string>& trigger)
{
    if (trigger.empty())
        fail("gate needs a TRIGGER (it appends add / del)");
    SocketCanBus bus(options(iface), logger());
    open_or_fail(bus);
    run_trigger(trigger, "add");
    std::uint8_t counter = 0;
    bool full = false;
    for (int i = 0; i < 16 && !full; ++i) {
        const auto r = bus.send(target_frame(counter++), stemd::base::monotonic_ns() + 20 * kMs);
        if (r == SendResult::error)
            fail("filling the queue: send error: " + bus.last_error());
        full = r == SendResult::deadline_passed;
    }
    counters(bus);
    if (!full || bus.counters().tx_queue_full_retries == 0)
        fail("the transmit queue never filled: no send was refused until its deadline");
    info("== the transmit queue is full; a frame whose gate closes while it waits");
    const std::uint64_t retries_before = bus.counters().tx_queue_full_retries;
    const OpenOnce once;
    const drivers::SendGate closing{.is_open = &OpenOnce::open, .context = &once};
    const std::int64_t t0 = stemd::base::monotonic_ns();
    const auto r = bus.send(target_frame(counter), t0 + 5000 * kMs, closing);
    const std::int64_t waited_ns = stemd::base::monotonic_ns() - t0;
    run_trigger(trigger, "del");
    counters(bus);
    info("gated send: " + std::string(to_string(r)) + " after " + std::to_string(waited_ns / 1000) + " us, " +
         std::to_string(once.checks) + " gate checks");
    if (r != SendResult::withdrawn)
        fail("the gated send returned " + std::string(to_string(r)) + ", not withdrawn");
    if (bus.counters().tx_queue_full_retries <= retries_before)
        fail("the gated frame never met the full queue: its first write was not refused");
    if (once.checks < 2)
        fail("the gate was not checked again after the refused write");
    if (bus.counters().withdrawn != 1)
        fail("withdrawn counter is not 1");
    if (waited_ns > 1000 * kMs)
        fail("the send waited " + std::to_string(waited_ns / kMs) + " ms for a closed gate");
}

void confirm(const std::string& iface)
{
    const std::uint16_t target_id = kIds.id(protocol::MessageKind::Target);
    SocketCanBus watcher(options(iface, {target_id}), logger());
    open_or_fail(watcher);
    SocketCanBus bus(options(iface, {kIds.id(protocol::MessageKind::Odometry)},
                             {target_id, kIds.id(protocol::MessageKind::Heartbeat)}),
                     logger());
    open_or_fail(bus);
    const auto now = [] { return stemd::base::monotonic_ns(); };
    const auto expect = [&](SendResult got, SendResult want, const std::string& what) {
        if (got != want)
            fail(what + ": " + std::string(to_string(got)) + ", expected " + std::string(to_string(want)));
        info(what + ": " + std::string(to_string(got)));
    };
    std::vector<protocol::CanFrame> on_the_wire;
    protocol::TargetCommand msg = kTarget;
    const auto frame = [&](std::uint16_t id) {
        msg.target_id = id;
        return target_frame(static_cast<std::uint8_t>(id % 15), msg);
    };
    // The bucket holds two frames: the first two leave at once, the third
    // 400 ms after it is written.
    for (std::uint16_t id = 1; id <= 2; ++id) {
        const auto f = frame(id);
        expect(bus.send(f, now() + 5000 * kMs), SendResult::sent, "frame " + std::to_string(id) + " (bucket full)");
        on_the_wire.push_back(f);
    }
    const auto late = frame(3);
    expect(bus.send(late, now() + 100 * kMs), SendResult::sent, "frame 3, due in 100 ms (the bucket is empty)");
    on_the_wire.push_back(late);
    const std::int64_t t_missed = now();
    expect(bus.send(frame(4), t_missed + 50 * kMs), SendResult::deadline_passed,
           "frame 4, due in 50 ms while frame 3 is queued");
    const std::int64_t missed_after_ns = now() - t_missed;
    if (missed_after_ns < 50 * kMs)
        fail("frame 4 was given up " + std::to_string(missed_after_ns / 1000) + " us after the send, before its deadline");
    const OpenOnce once;
    const std::int64_t t_gated = now();
    expect(bus.send(frame(5), t_gated + 5000 * kMs, {.is_open = &OpenOnce::open, .context = &once}),
           SendResult::withdrawn, "frame 5, its gate closing while frame 3 is queued");
    if (now() - t_gated > 1000 * kMs)
        fail("the gated frame waited " + std::to_string((now() - t_gated) / kMs) + " ms for a closed gate");
    const auto last = frame(6);
    expect(bus.send(last, now() + 5000 * kMs), SendResult::sent, "frame 6, once frame 3 has left");
    on_the_wire.push_back(last);
    counters(bus);
    const auto c = bus.counters();
    if (c.sent != 4 || c.deadline_misses != 1 || c.withdrawn != 1)
        fail("sent / deadline misses / withdrawn are not 4 / 1 / 1");
    if (c.tx_confirm_waits < 3)
        fail("fewer than 3 sends (frames 4, 5, 6) waited for an echo");
    if (c.tx_late != 1)
        fail("frame 3's late arrival on the bus was not counted once in tx_late");
    if (c.tx_unconfirmed != 0)
        fail("an echo was presumed lost");
    for (const auto& want : on_the_wire) {
        protocol::CanFrame got;
        if (!watcher.receive(got, 2000 * kMs))
            fail("the second bus did not receive " + text(want));
        info("second bus received " + text(got));
        if (!(got == want))
            fail("received " + text(got) + ", expected " + text(want) + " (a withdrawn or missed frame went out?)");
    }
    protocol::CanFrame extra;
    if (watcher.receive(extra, 1000 * kMs))
        fail("a frame that was never sent reached the bus: " + text(extra));
}

void downup(const std::string& iface, const std::vector<std::string>& trigger)
{
    if (trigger.empty())
        fail("downup needs a TRIGGER (it appends down / up)");
    SocketCanBus bus(options(iface), logger());
    open_or_fail(bus);
    std::uint8_t counter = 0;
    for (int i = 0; i < 3; ++i) {
        const auto r = bus.send(target_frame(counter++), stemd::base::monotonic_ns() + 100 * kMs);
        if (r != SendResult::sent)
            fail("before down: send " + std::string(to_string(r)));
    }
    info("== 3 frames sent; taking " + iface + " down");
    run_trigger(trigger, "down");
    int errors = 0;
    for (int i = 0; i < 20; ++i) {
        const auto r = bus.send(target_frame(counter), stemd::base::monotonic_ns() + 50 * kMs);
        if (r == SendResult::sent)
            fail("a frame was sent while " + iface + " is down");
        errors += r == SendResult::error;
        sleep_ms(5);
    }
    counters(bus);
    info("while down: " + std::to_string(errors) + " of 20 sends reported an error; last error: " + bus.last_error());
    if (errors == 0 || bus.counters().errors == 0)
        fail("no error reported while " + iface + " was down");
    if (bus.state() != drivers::SocketCanState::down)
        fail("state is " + std::string(to_string(bus.state())) + ", not down");
    if (bus.last_error().find(iface) == std::string::npos)
        fail("the error does not name " + iface);

    info("== bringing " + iface + " up");
    run_trigger(trigger, "up");
    const std::uint16_t target_id = kIds.id(protocol::MessageKind::Target);
    SocketCanBus rx(options(iface, {target_id}), logger());
    open_or_fail(rx);
    protocol::TargetCommand resumed_msg = kTarget;
    resumed_msg.target_id = 4000;
    const auto resumed = target_frame(counter, resumed_msg);
    const std::int64_t t0 = stemd::base::monotonic_ns();
    SendResult r = SendResult::error;
    while (stemd::base::monotonic_ns() - t0 < 3000 * kMs) {
        r = bus.send(resumed, stemd::base::monotonic_ns() + 50 * kMs);
        if (r == SendResult::sent)
            break;
        sleep_ms(5);
    }
    if (r != SendResult::sent)
        fail("sending did not resume within 3 s after " + iface + " came up: " + bus.last_error());
    info("sending resumed " + std::to_string((stemd::base::monotonic_ns() - t0) / kMs) + " ms after up: " +
         text(resumed));
    counters(bus);
    if (bus.reopens() < 1)
        fail("the driver did not reopen its socket");
    if (bus.state() != drivers::SocketCanState::up)
        fail("state is " + std::string(to_string(bus.state())) + " after resuming");
    protocol::CanFrame got;
    if (!rx.receive(got, 1000 * kMs))
        fail("a second bus on " + iface + " did not receive the frame sent after the resume");
    info("second bus received " + text(got));
    if (!(got == resumed))
        fail("received " + text(got) + ", sent " + text(resumed));
}

}  // namespace

int main(int argc, char** argv)
{
    const std::string mode = argc > 1 ? argv[1] : "";
    const bool ok = mode == "frames" ||
                    (argc >= 3 && (mode == "send" || mode == "downup" || mode == "gate" || mode == "confirm")) ||
                    (argc >= 4 && mode == "receive");
    if (!ok) {
        std::fprintf(stderr,
                     "usage: %s frames | send IFACE | receive IFACE TIMEOUT_MS -- TRIGGER... | downup IFACE -- "
                     "TRIGGER... | gate IFACE -- TRIGGER... | confirm IFACE\n",
                     argv[0]);
        return 2;
    }
    return stemd::vmprobe::run_probe("socketcan-check", [&] {
        if (mode == "frames") {
            info("target " + text(target_frame(kTargetCounter)));
            info("odometry " + text(odometry_frame()));
        } else if (mode == "send") {
            send(argv[2]);
        } else if (mode == "receive") {
            receive(argv[2], std::atoi(argv[3]), stemd::vmprobe::command_after_dashes(argc, argv));
        } else if (mode == "gate") {
            gate(argv[2], stemd::vmprobe::command_after_dashes(argc, argv));
        } else if (mode == "confirm") {
            confirm(argv[2]);
        } else {
            downup(argv[2], stemd::vmprobe::command_after_dashes(argc, argv));
        }
    });
}
