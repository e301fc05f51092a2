// The project's GPIO lines (drivers/gpiod, GpiodLines, stemd_drivers) on the
// real gpio-sim driver in the VM: unlike gpio_probe.cpp this goes through
// GpiodLines (its thread, debouncing, active-low handling, quadrature
// decoding), so the check fails when the project's code is broken.
//
//   stemd-vm-gpiod-check enable chip=C enable=L active_low=0|1 -- PULL...
//       runs "PULL up" / "PULL down" (gpio-sim sysfs pulls) one edge at a
//       time and checks that enabled() follows each within 100 ms (active-low:
//       inverted), that the debounced initial state is right, and that no
//       change comes without a pull.
//   stemd-vm-gpiod-check trigger chip=C enable=L trigger=T active_low=0|1 -- CHECK...
//       set_trigger(true/false) and pulse(); after each runs "CHECK V" with
//       the physical level V the simulator must show (active-low: inverted).
//   stemd-vm-gpiod-check encoder chip=C enable=L a=A b=B n=N m=M -- TOGGLE...
//       drives the quadrature sequence N edges forward then M back by running
//       "TOGGLE a|b up|down", waiting for each edge to be decoded before the
//       next; the count must be N-M, the direction backward, no invalid steps.
//   stemd-vm-gpiod-check lost chip=C enable=L -- CTL...
//       "CTL up" (enabled), "CTL unplug" (gpio-sim goes away: enabled() must
//       drop within 500 ms, state down, errors counted), "CTL plug" (the
//       chip is back: the driver reopens), "CTL up" (enabled again).
#include <time.h>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include "gpiod/gpiod_lines.hpp"
#include "probe_util.hpp"
#include "stemd/base/clock.hpp"

namespace {

using namespace stemd::drivers;
using stemd::vmprobe::fail;
using stemd::vmprobe::info;

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kFollowNs = 100 * kMs;  // enabled() must follow a pull within this

std::map<std::string, std::string> parse_args(int argc, char** argv)
{
    std::map<std::string, std::string> kv;
    for (int i = 2; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--")
            break;
        const auto eq = a.find('=');
        if (eq == std::string::npos)
            fail("argument " + a + " is not KEY=VALUE");
        kv[a.substr(0, eq)] = a.substr(eq + 1);
    }
    return kv;
}

int need_int(const std::map<std::string, std::string>& kv, const std::string& key)
{
    const auto it = kv.find(key);
    if (it == kv.end())
        fail("missing " + key + "=");
    return std::atoi(it->second.c_str());
}

void run_with(std::vector<std::string> cmd, std::initializer_list<std::string> extra, const char* what)
{
    if (cmd.empty())
        fail(std::string("no ") + what + " command after --");
    cmd.insert(cmd.end(), extra);
    const int status = stemd::vmprobe::run_command(cmd);
    if (status != 0)
        fail(std::string(what) + " command exited " + std::to_string(status));
}

std::shared_ptr<spdlog::logger> make_log()
{
    auto log = std::make_shared<spdlog::logger>("gpiod", std::make_shared<spdlog::sinks::stdout_sink_mt>());
    log->set_level(spdlog::level::debug);
    return log;
}

GpiodOptions base_options(const std::map<std::string, std::string>& kv)
{
    GpiodOptions o;
    const auto it = kv.find("chip");
    if (it == kv.end())
        fail("missing chip=");
    o.chip = it->second;
    o.enable_line = static_cast<unsigned>(need_int(kv, "enable"));
    return o;
}

void open_or_fail(GpiodLines& lines)
{
    if (!lines.open())
        fail("GpiodLines::open: " + lines.last_error());
    lines.start();
}

// Waits up to ns for enabled() == want; the time it took, or -1.
std::int64_t wait_enabled(GpiodLines& lines, bool want, std::int64_t ns)
{
    const std::int64_t t0 = stemd::base::monotonic_ns();
    if (lines.enabled() != want)
        lines.wait_change(!want, ns);
    if (lines.enabled() != want)
        return -1;
    return stemd::base::monotonic_ns() - t0;
}

void enable_check(const std::map<std::string, std::string>& kv, const std::vector<std::string>& pull)
{
    GpiodOptions o = base_options(kv);
    o.enable_active_low = need_int(kv, "active_low") != 0;
    o.enable_debounce_ns = 20 * kMs;
    GpiodLines lines(o, make_log());
    open_or_fail(lines);
    const std::string where = o.chip + " line " + std::to_string(o.enable_line);

    // The guest leaves the line pulled down: active-high is disabled, active-low enabled (after the debounce).
    const bool initial = o.enable_active_low;
    if (wait_enabled(lines, initial, kFollowNs) < 0)
        fail(where + ": initial enabled() is " + std::to_string(lines.enabled()) + ", want " + std::to_string(initial));
    info(where + ": initial enabled() = " + std::to_string(initial));

    int pulls = 0;
    for (const char* level : {"up", "down", "up", "down", "up", "down"}) {
        const bool high = std::string(level) == "up";
        const bool want = high != o.enable_active_low;
        run_with(pull, {level}, "pull");
        ++pulls;
        const std::int64_t took = wait_enabled(lines, want, kFollowNs);
        if (took < 0)
            fail(where + ": enabled() still " + std::to_string(lines.enabled()) + " 100 ms after pull-" + level +
                 ", want " + std::to_string(want));
        info(where + ": pull-" + level + " -> enabled() = " + std::to_string(want) + " after " +
             std::to_string(took / 1000) + " us");
    }
    // No change without a pull.
    const bool last = lines.enabled();
    if (lines.wait_change(last, 200 * kMs))
        fail(where + ": enabled() changed without a pull");
    const GpioCounters c = lines.counters();
    info("edges " + std::to_string(c.edges) + ", bounces " + std::to_string(c.enable_bounces) + ", errors " +
         std::to_string(c.errors) + ", reopens " + std::to_string(c.reopens));
    if (c.edges < static_cast<std::uint64_t>(pulls))
        fail(where + ": " + std::to_string(c.edges) + " edges counted for " + std::to_string(pulls) + " pulls");
    if (c.errors != 0)
        fail(where + ": errors counted: " + lines.last_error());
}

void trigger_check(const std::map<std::string, std::string>& kv, const std::vector<std::string>& check)
{
    GpiodOptions o = base_options(kv);
    o.trigger_line = need_int(kv, "trigger");
    o.trigger_active_low = need_int(kv, "active_low") != 0;
    GpiodLines lines(o, make_log());
    open_or_fail(lines);
    const std::string where = o.chip + " line " + std::to_string(o.trigger_line);
    auto physical = [&](bool active) { return std::string((active != o.trigger_active_low) ? "1" : "0"); };

    run_with(check, {physical(false)}, "check");  // requested inactive
    for (const bool active : {true, false, true, false}) {
        if (!lines.set_trigger(active))
            fail(where + ": set_trigger(" + std::to_string(active) + "): " + lines.last_error());
        info(where + ": set_trigger(" + std::to_string(active) + "), simulator must read " + physical(active));
        run_with(check, {physical(active)}, "check");
    }
    if (!lines.pulse(500))
        fail(where + ": pulse: " + lines.last_error());
    run_with(check, {physical(false)}, "check");
    const GpioCounters c = lines.counters();
    if (c.trigger_pulses != 1 || c.errors != 0)
        fail(where + ": pulses " + std::to_string(c.trigger_pulses) + ", errors " + std::to_string(c.errors));
    info(where + ": pulse(500 us) done, line back to inactive");
}

void encoder_check(const std::map<std::string, std::string>& kv, const std::vector<std::string>& toggle)
{
    GpiodOptions o = base_options(kv);
    o.encoder = EncoderMode::quadrature;
    o.encoder_a_line = need_int(kv, "a");
    o.encoder_b_line = need_int(kv, "b");
    const int n = need_int(kv, "n");
    const int m = need_int(kv, "m");
    GpiodLines lines(o, make_log());
    open_or_fail(lines);

    // Forward (A leads B) from 00: A up, B up, A down, B down; backward is the reverse.
    int a = 0, b = 0;
    std::int64_t want = 0;
    auto step = [&](bool forward) {
        // Forward from (a,b): 00->10 (A up), 10->11 (B up), 11->01 (A down), 01->00 (B down).
        // Backward from (a,b): 00->01 (B up), 01->11 (A up), 11->10 (B down), 10->00 (A down).
        const bool toggle_a = forward ? (a == b) : (a != b);
        int& line = toggle_a ? a : b;
        line ^= 1;
        want += forward ? 1 : -1;
        run_with(toggle, {toggle_a ? "a" : "b", line != 0 ? "up" : "down"}, "toggle");
        const std::int64_t t0 = stemd::base::monotonic_ns();
        while (lines.encoder().ticks != want) {
            if (stemd::base::monotonic_ns() - t0 > 1000 * kMs)
                fail("encoder: ticks " + std::to_string(lines.encoder().ticks) + " 1 s after edge, want " +
                     std::to_string(want) + " (invalid " + std::to_string(lines.encoder().invalid) + ")");
            const timespec ts{0, 1'000'000};
            nanosleep(&ts, nullptr);
        }
    };
    for (int i = 0; i < n; ++i)
        step(true);
    info("encoder: " + std::to_string(n) + " edges forward -> ticks " + std::to_string(lines.encoder().ticks));
    for (int i = 0; i < m; ++i)
        step(false);
    const EncoderReading r = lines.encoder();
    info("encoder: " + std::to_string(m) + " edges back -> ticks " + std::to_string(r.ticks) + ", direction " +
         std::to_string(r.direction) + ", invalid " + std::to_string(r.invalid) + ", edges " +
         std::to_string(lines.counters().edges));
    if (r.ticks != n - m)
        fail("encoder: ticks " + std::to_string(r.ticks) + ", want " + std::to_string(n - m));
    if (m > 0 && r.direction != -1)
        fail("encoder: direction " + std::to_string(r.direction) + " after moving back, want -1");
    if (r.invalid != 0)
        fail("encoder: " + std::to_string(r.invalid) + " invalid steps");
}

bool wait_state(GpiodLines& lines, GpiodState want, std::int64_t ns)
{
    const std::int64_t t0 = stemd::base::monotonic_ns();
    while (lines.state() != want) {
        if (stemd::base::monotonic_ns() - t0 > ns)
            return false;
        const timespec ts{0, 2'000'000};
        nanosleep(&ts, nullptr);
    }
    return true;
}

void lost_check(const std::map<std::string, std::string>& kv, const std::vector<std::string>& ctl)
{
    GpiodOptions o = base_options(kv);
    o.reopen_min_ns = 10 * kMs;
    o.reopen_max_ns = 100 * kMs;
    GpiodLines lines(o, make_log());
    open_or_fail(lines);
    const std::string where = o.chip + " line " + std::to_string(o.enable_line);

    run_with(ctl, {"up"}, "ctl");
    if (wait_enabled(lines, true, kFollowNs) < 0)
        fail(where + ": not enabled after pull-up");
    run_with(ctl, {"unplug"}, "ctl");
    const std::int64_t took = wait_enabled(lines, false, 500 * kMs);
    if (took < 0)
        fail(where + ": still enabled 500 ms after the chip went away");
    if (!wait_state(lines, GpiodState::down, 500 * kMs))
        fail(where + ": state " + std::string(to_string(lines.state())) + " after the chip went away, want down");
    info(where + ": chip gone -> enabled() = 0 after " + std::to_string(took / 1000) + " us, state down, error: " +
         lines.last_error());
    if (lines.counters().errors == 0)
        fail(where + ": no error counted for the lost chip");
    run_with(ctl, {"plug"}, "ctl");
    if (!wait_state(lines, GpiodState::up, 2000 * kMs))
        fail(where + ": not reopened 2 s after the chip came back: " + lines.last_error());
    if (lines.counters().reopens != 1)
        fail(where + ": reopens " + std::to_string(lines.counters().reopens) + ", want 1");
    info(where + ": chip back -> reopened");
    run_with(ctl, {"up"}, "ctl");
    if (wait_enabled(lines, true, kFollowNs) < 0)
        fail(where + ": not enabled after pull-up on the reopened chip");
    info(where + ": enabled again after pull-up");
}

}  // namespace

int main(int argc, char** argv)
{
    const std::string mode = argc > 1 ? argv[1] : "";
    if (mode != "enable" && mode != "trigger" && mode != "encoder" && mode != "lost") {
        std::fprintf(stderr,
                     "usage: %s enable|trigger|encoder|lost KEY=VALUE... -- COMMAND...\n"
                     "  (see the header of test/vm/gpiod_check.cpp)\n",
                     argv[0]);
        return 2;
    }
    return stemd::vmprobe::run_probe("gpiod-check", [&] {
        const auto kv = parse_args(argc, argv);
        const auto cmd = stemd::vmprobe::command_after_dashes(argc, argv);
        if (mode == "enable")
            enable_check(kv, cmd);
        else if (mode == "trigger")
            trigger_check(kv, cmd);
        else if (mode == "encoder")
            encoder_check(kv, cmd);
        else
            lost_check(kv, cmd);
    });
}
