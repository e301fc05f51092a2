// GPIO probe for the VM tests, through libgpiod 1.6 (Debian 12), against gpio-sim.
//
//   stemd-vm-gpio-probe events CHIP LINE [TIMEOUT_MS] -- TRIGGER...
//       requests both-edge events on LINE, runs "TRIGGER... up" (which must
//       pull the line high, e.g. through gpio-sim's sysfs) and checks that a
//       rising edge arrives, then "TRIGGER... down" for a falling edge, then
//       that no further edge comes. One edge at a time: the v1 uAPI that
//       libgpiod 1.6 uses reads the level when its IRQ thread runs, so two
//       quick pulls could both be reported as falling.
//   stemd-vm-gpio-probe output CHIP LINE VALUE -- CHECK...
//       drives LINE as an output to VALUE, reads it back through libgpiod, and
//       while still holding it runs CHECK (which reads the simulator's side);
//       fails if CHECK does.
// CHIP: a name (gpiochip1), path or number, as gpiod_chip_open_lookup takes.
#include <gpiod.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>

#include "probe_util.hpp"

namespace {

using stemd::vmprobe::fail;
using stemd::vmprobe::fail_errno;
using stemd::vmprobe::info;

constexpr const char* kConsumer = "stemd-vm-probe";

struct ChipCloser {
  void operator()(gpiod_chip* chip) const { gpiod_chip_close(chip); }
};
using Chip = std::unique_ptr<gpiod_chip, ChipCloser>;

// A requested line; releasing it hands it back to the kernel.
struct LineReleaser {
  void operator()(gpiod_line* line) const { gpiod_line_release(line); }
};
using RequestedLine = std::unique_ptr<gpiod_line, LineReleaser>;

Chip open_chip(const std::string& name) {
  Chip chip(gpiod_chip_open_lookup(name.c_str()));
  if (!chip) fail_errno(name, "gpiod_chip_open_lookup");
  info(std::string("chip ") + gpiod_chip_name(chip.get()) + " label=" + gpiod_chip_label(chip.get()) +
       " lines=" + std::to_string(gpiod_chip_num_lines(chip.get())));
  return chip;
}

gpiod_line* get_line(gpiod_chip* chip, unsigned offset, const std::string& where) {
  gpiod_line* line = gpiod_chip_get_line(chip, offset);
  if (line == nullptr) fail_errno(where, "gpiod_chip_get_line");
  return line;
}

void run_trigger(const std::vector<std::string>& cmd, const char* what) {
  if (cmd.empty()) fail(std::string("no ") + what + " command after --");
  const int status = stemd::vmprobe::run_command(cmd);
  if (status != 0) fail(std::string(what) + " command " + cmd[0] + " exited " + std::to_string(status));
}

void events(const std::string& chip_name, unsigned offset, int timeout_ms, const std::vector<std::string>& trigger) {
  Chip chip = open_chip(chip_name);
  const std::string where = chip_name + " line " + std::to_string(offset);
  gpiod_line* raw = get_line(chip.get(), offset, where);
  if (gpiod_line_request_both_edges_events(raw, kConsumer) < 0) fail_errno(where, "gpiod_line_request_both_edges_events");
  RequestedLine line(raw);
  const int initial = gpiod_line_get_value(line.get());
  if (initial < 0) fail_errno(where, "gpiod_line_get_value");
  if (initial != 0) fail(where + " is " + std::to_string(initial) + " before the trigger, want 0");
  info("watching " + where + " for edges");

  const int want[] = {GPIOD_LINE_EVENT_RISING_EDGE, GPIOD_LINE_EVENT_FALLING_EDGE};
  for (int expected : want) {
    const bool rising = expected == GPIOD_LINE_EVENT_RISING_EDGE;
    const char* name = rising ? "rising" : "falling";
    auto cmd = trigger;
    if (!cmd.empty()) cmd.emplace_back(rising ? "up" : "down");
    run_trigger(cmd, "trigger");
    const timespec timeout{timeout_ms / 1000, (timeout_ms % 1000) * 1000000L};
    const int r = gpiod_line_event_wait(line.get(), &timeout);
    if (r < 0) fail_errno(where, "gpiod_line_event_wait");
    if (r == 0) fail(where + ": no " + name + " edge within " + std::to_string(timeout_ms) + " ms");
    gpiod_line_event event{};
    if (gpiod_line_event_read(line.get(), &event) < 0) fail_errno(where, "gpiod_line_event_read");
    if (event.event_type != expected) fail(where + ": got the opposite edge, want " + name);
    info(std::string(name) + " edge on " + where + " at " + std::to_string(event.ts.tv_sec) + "." +
         std::to_string(event.ts.tv_nsec / 1000000) + " s");
  }
  const timespec settle{0, 200 * 1000000L};
  const int extra = gpiod_line_event_wait(line.get(), &settle);
  if (extra < 0) fail_errno(where, "gpiod_line_event_wait");
  if (extra > 0) fail(where + ": more edges than the trigger made");
}

void output(const std::string& chip_name, unsigned offset, int value, const std::vector<std::string>& check) {
  Chip chip = open_chip(chip_name);
  const std::string where = chip_name + " line " + std::to_string(offset);
  gpiod_line* raw = get_line(chip.get(), offset, where);
  if (gpiod_line_request_output(raw, kConsumer, value) < 0) fail_errno(where, "gpiod_line_request_output");
  RequestedLine line(raw);
  // Drive the other level first, so the check cannot pass on a stale value.
  if (gpiod_line_set_value(line.get(), !value) < 0 || gpiod_line_set_value(line.get(), value) < 0) {
    fail_errno(where, "gpiod_line_set_value");
  }
  const int got = gpiod_line_get_value(line.get());
  if (got < 0) fail_errno(where, "gpiod_line_get_value");
  if (got != value) fail(where + " reads " + std::to_string(got) + " after setting " + std::to_string(value));
  info("drove " + where + " to " + std::to_string(value));
  run_trigger(check, "check");
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (!((mode == "events" && argc >= 4) || (mode == "output" && argc >= 5))) {
    std::fprintf(stderr, "usage: %s events CHIP LINE [TIMEOUT_MS] -- TRIGGER... | output CHIP LINE VALUE -- CHECK...\n",
                 argv[0]);
    return 2;
  }
  return stemd::vmprobe::run_probe("gpio-probe", [&] {
    const auto cmd = stemd::vmprobe::command_after_dashes(argc, argv);
    const auto offset = static_cast<unsigned>(std::atoi(argv[3]));
    if (mode == "events") {
      const int timeout_ms = (argc > 4 && std::strcmp(argv[4], "--") != 0) ? std::atoi(argv[4]) : 3000;
      events(argv[2], offset, timeout_ms, cmd);
    } else {
      output(argv[2], offset, std::atoi(argv[4]) != 0 ? 1 : 0, cmd);
    }
  });
}
