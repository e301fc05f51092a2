// stemd-toolsim: a simulated tool controller on a SocketCAN interface (vcan
// for tests). It executes the TARGETs it receives with a known delay and
// reports each strike as TOOL_FIRED, so that stemd's tool timing (lag
// statistics, latency compensation) can be checked without a machine.
//
//   stemd-toolsim --interface vcan0 [--base-id 768] [--delay-ms 40]
//                 [--speed-mm-per-s V] [--ready-mask M] [--duration-s S]
//
// The odometer: with --speed-mm-per-s it is also the drive, sending
// ODOMETRY every 10 ms at that constant speed; without it, it follows the
// ODOMETRY frames on the bus (extrapolated between them at their speed).
// With --ready-mask it sends TOOL_STATUS every 100 ms with that
// tools_ready_mask (bit n: tool n ready), as a tool controller reports
// which tools can strike; without it, none (stemd then takes every tool
// as ready).
// Every strike is printed on standard output:
//   fired tool 0 target 17 lane 0 fired_odom_mm 5056
// It stops after --duration-s (0: at SIGINT or SIGTERM) and prints its counters;
// it exits 1 when a send failed (a send that missed its deadline is only counted).
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "socketcan/socketcan_bus.hpp"
#include "stemd/actuation/tool_simulator.hpp"
#include "stemd/base/clock.hpp"
#include "stemd/geometry/odometry.hpp"
#include "stemd/protocol/e2e.hpp"
#include "stemd/protocol/messages.hpp"
#include "stemd/runtime/logging.hpp"

using namespace stemd;

namespace {

volatile std::sig_atomic_t g_stop = 0;

void on_signal(int) { g_stop = 1; }

}  // namespace

int main(int argc, char** argv)
{
    CLI::App app{"stemd-toolsim: a simulated tool controller that fires stemd's TARGETs with a known delay"};
    std::string interface;
    unsigned base_id = protocol::kDefaultBaseId;
    double delay_ms = 40, speed_mm_per_s = 0, duration_s = 0;
    int ready_mask = -1;
    app.add_option("--interface", interface, "SocketCAN interface (e.g. vcan0)")->required();
    app.add_option("--base-id", base_id, "first CAN identifier of stemd's messages")
        ->check(CLI::Range(0u, static_cast<unsigned>(protocol::CanIds::kMaxBaseId)));
    app.add_option("--delay-ms", delay_ms, "time from the odometer reaching fire_odom_mm to the strike")
        ->check(CLI::Range(0.0, 1000.0));
    app.add_option("--speed-mm-per-s", speed_mm_per_s,
                   "also be the drive: send ODOMETRY at this constant speed (0: follow ODOMETRY on the bus)")
        ->check(CLI::Range(0.0, 32767.0));
    app.add_option("--ready-mask", ready_mask,
                   "send TOOL_STATUS every 100 ms with this tools_ready_mask (bit n: tool n ready; -1: none)")
        ->check(CLI::Range(-1, 0xFFFF));
    app.add_option("--duration-s", duration_s, "stop after this long (0: at SIGINT or SIGTERM)")
        ->check(CLI::Range(0.0, 86400.0));
    CLI11_PARSE(app, argc, argv);

    const protocol::CanIds ids = *protocol::CanIds::make(base_id);
    auto log = runtime::make_logger("toolsim");
    drivers::SocketCanOptions options;
    options.interface = interface;
    options.rx_ids = {ids.id(protocol::MessageKind::Target), ids.id(protocol::MessageKind::Odometry)};
    drivers::SocketCanBus bus(options, log);
    if (!bus.open())
        return 1;
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);

    actuation::ToolSimulator sim(delay_ms);
    const bool drive = speed_mm_per_s > 0;
    protocol::E2eChecker target_checker(ids.id(protocol::MessageKind::Target), 3);
    protocol::E2eChecker odometry_checker(ids.id(protocol::MessageKind::Odometry), 3);
    protocol::E2eCounter odometry_counter, fired_counter, status_counter;
    // A send whose deadline passed before the bus took it (the process was
    // not scheduled in time) is counted apart from a failed one: the next
    // ODOMETRY carries the odometer of its own moment anyway.
    std::uint64_t rejected = 0, send_errors = 0, sends_late = 0;
    const auto count_send = [&](drivers::SendResult r) {
        if (r == drivers::SendResult::deadline_passed)
            ++sends_late;
        else if (r != drivers::SendResult::sent)
            ++send_errors;
    };

    const std::int64_t t0 = base::monotonic_ns();
    const std::int64_t end_ns = duration_s > 0 ? t0 + static_cast<std::int64_t>(duration_s * 1e9) : 0;
    std::int64_t next_odometry_ns = t0, next_status_ns = t0;
    // For TOOL_STATUS: strikes made (wraps at 256), and the last one's target.
    std::uint64_t executed = 0;
    std::uint16_t last_target_id = 0;
    // Following the bus: the last ODOMETRY (unwrapped) and when it came.
    bool have_odometry = drive;
    double odom_at_rx = 0, speed = drive ? speed_mm_per_s : 0;
    std::int64_t t_odom_rx = t0;
    geometry::OdometerUnwrap unwrap;

    const auto odometer_at = [&](std::int64_t t_ns) {
        return odom_at_rx + speed * static_cast<double>(t_ns - t_odom_rx) / 1e9;
    };
    log->info("{} ms delay, {}", delay_ms,
              drive ? fmt::format("driving at {} mm/s", speed_mm_per_s) : std::string("following ODOMETRY"));
    while (!g_stop && (end_ns == 0 || base::monotonic_ns() < end_ns)) {
        protocol::CanFrame frame;
        std::int64_t t_rx = 0;
        const bool got = bus.receive(frame, 1'000'000, t_rx);
        const std::int64_t now = base::monotonic_ns();
        if (got) {
            const auto kind = ids.kind_of(frame);
            if (kind == protocol::MessageKind::Target) {
                protocol::TargetCommand t;
                if (!protocol::decode_checked(frame, target_checker, ids, t))
                    ++rejected;
                else if (have_odometry)
                    sim.command(t, odometer_at(t_rx));
            } else if (kind == protocol::MessageKind::Odometry && !drive) {
                protocol::Odometry o;
                if (!protocol::decode_checked(frame, odometry_checker, ids, o)) {
                    ++rejected;
                } else {
                    odom_at_rx = unwrap.add(o.odom_mm);
                    speed = o.speed_mm_per_s;
                    t_odom_rx = t_rx;
                    have_odometry = true;
                }
            }
        }
        if (drive && now >= next_odometry_ns) {
            protocol::Odometry o;
            o.odom_mm = static_cast<std::uint32_t>(static_cast<std::int64_t>(odometer_at(now)));
            o.speed_mm_per_s = static_cast<std::int16_t>(speed_mm_per_s);
            protocol::CanFrame out;
            if (!protocol::encode(o, odometry_counter.next(), ids, out))
                ++send_errors;
            else
                count_send(bus.send(out, now + 10'000'000));
            next_odometry_ns += 10'000'000;
        }
        if (ready_mask >= 0 && now >= next_status_ns) {
            protocol::ToolStatus status;
            status.tools_ready_mask = static_cast<std::uint16_t>(ready_mask);
            status.targets_executed = static_cast<std::uint8_t>(executed % 256);
            status.last_target_valid = executed > 0;
            status.last_target_id = last_target_id;
            protocol::CanFrame out;
            if (!protocol::encode(status, status_counter.next(), ids, out))
                ++send_errors;
            else
                count_send(bus.send(out, now + 100'000'000));
            next_status_ns += 100'000'000;
        }
        if (!have_odometry)
            continue;
        for (const protocol::ToolFired& f : sim.advance(now, odometer_at(now))) {
            ++executed;
            last_target_id = f.target_id;
            protocol::CanFrame out;
            if (!protocol::encode(f, fired_counter.next(), ids, out))
                ++send_errors;
            else
                count_send(bus.send(out, now + 50'000'000));
            std::printf("fired tool %u target %u lane %u fired_odom_mm %u\n", static_cast<unsigned>(f.tool_id),
                        static_cast<unsigned>(f.target_id), static_cast<unsigned>(f.lane),
                        static_cast<unsigned>(f.fired_odom_mm));
            std::fflush(stdout);
        }
    }
    const actuation::ToolSimCounters& c = sim.counters();
    std::printf("commands %llu, fired %llu, late %llu, full %llu, rejected %llu, send_errors %llu, sends_late %llu\n",
                static_cast<unsigned long long>(c.commands), static_cast<unsigned long long>(c.fired),
                static_cast<unsigned long long>(c.late), static_cast<unsigned long long>(c.full),
                static_cast<unsigned long long>(rejected), static_cast<unsigned long long>(send_errors),
                static_cast<unsigned long long>(sends_late));
    return send_errors == 0 ? 0 : 1;
}
