// VM check of the project's own libcamera frame source (drivers/libcamera) on
// vimc.
//
//   stemd-vm-libcamera-source-check capture CAMERA [DUMP_DIR]
//       opens CAMERA (index, id or part of the id: "vimc") through
//       stemd::drivers::LibcameraSource at 636x480 (vimc: multiples of 6) and captures kFrames
//       frames into one preallocated BGR slot. Checks, frame by frame: the
//       slot keeps its size, type and buffer (never reallocated); capture
//       timestamps strictly increase and lie within 2 s before
//       CLOCK_MONOTONIC now; source_seq increases; the image is vimc's
//       sensor test pattern, 75% colour bars: eight vertical bars (rows
//       agree), in the order white, yellow, cyan, green, magenta, red, blue,
//       black, and not all frames identical (the OSD runs a timer). Yellow (R+G) against cyan (G+B) in the BGR slot pins the
//       byte order of libcamera's RGB888 (B, G, R in memory). Then the
//       counters: frames = delivered = frames captured, no errors, no
//       bad_size, no corrupt, every frame stamped by SensorTimestamp. Then
//       stop(), and open the same camera again by its full id (selection by
//       id, a clean teardown of the CameraManager) for one more frame.
//       DUMP_DIR gets the last image (PNG) on failure.
//
//   stemd-vm-libcamera-source-check unplug CAMERA DUMP_DIR -- COMMAND...
//       streams CAMERA, then runs COMMAND unplug (the guest unbinds vimc):
//       next() keeps returning timeouts (never `failed`), the source notices
//       the loss (stall timeout: without udev libcamera sees no hot-unplug),
//       releases the camera and goes to backoff (counters: lost 1). Then
//       COMMAND plug (vimc bound again): the source finds the camera again by
//       its id on its reopen schedule and frames resume into the same slot
//       (colour bars; counters: reopens 1, frames keep counting).
//       Exits 77 (SKIP) when the unplug caught requests inside the driver:
//       libcamera 0.0.3 cannot release that camera, the source goes to
//       `failed` without crashing (see drivers/libcamera/libcamera_source.hpp).
#include <time.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include "libcamera/libcamera_source.hpp"
#include "probe_util.hpp"
#include "stemd/base/clock.hpp"

namespace {

using namespace stemd::drivers;
using namespace stemd::vmprobe;

// libcamera 0.0.3's vimc pipeline assumes the old x3 scaler and takes only
// multiples of 6 (640x480 is adjusted to 636x480).
constexpr int kWidth = 636;
constexpr int kHeight = 480;
constexpr int kFrames = 6;
// vimc under TCG emulation is slow to start: the first frame may take seconds.
constexpr auto kFirstFrameWait = std::chrono::seconds(20);

// 75% colour bars, left to right: which of B, G, R are on.
struct Bar {
    const char* name;
    bool b, g, r;
};
constexpr std::array<Bar, 8> kBars{Bar{"white", true, true, true},   Bar{"yellow", false, true, true},
                                   Bar{"cyan", true, true, false},   Bar{"green", false, true, false},
                                   Bar{"magenta", true, false, true}, Bar{"red", false, false, true},
                                   Bar{"blue", true, false, false},  Bar{"black", false, false, false}};

using stemd::base::monotonic_ns;

std::string bgr_text(const cv::Scalar& s) {
  return "BGR(" + std::to_string(std::lround(s[0])) + "," + std::to_string(std::lround(s[1])) + "," +
         std::to_string(std::lround(s[2])) + ")";
}

// Empty = the frame is the colour-bar pattern; else why not.
std::string judge_pattern(const cv::Mat& bgr) {
  cv::Scalar mean, stddev;
  cv::meanStdDev(bgr, mean, stddev);
  if (stddev[0] + stddev[1] + stddev[2] < 10) return "frame is (nearly) constant: " + bgr_text(mean);
  const int bar_w = bgr.cols / static_cast<int>(kBars.size());
  std::string seen;
  for (std::size_t i = 0; i < kBars.size(); ++i) {
    const int x0 = static_cast<int>(i) * bar_w + bar_w / 4;
    // The same bar at three heights in the lower half (vimc's OSD text
    // covers the upper half): vertical bars.
    std::array<cv::Scalar, 3> at{};
    for (int k = 0; k < 3; ++k) {
      const int y0 = bgr.rows * (55 + 15 * k) / 100;
      at[static_cast<std::size_t>(k)] = cv::mean(bgr(cv::Rect(x0, y0, bar_w / 2, bgr.rows / 12)));
    }
    const cv::Scalar& c = at[1];
    seen += std::string(" ") + kBars[i].name + "=" + bgr_text(c);
    for (int k = 0; k < 3; k += 2) {
      for (int ch = 0; ch < 3; ++ch) {
        if (std::abs(at[static_cast<std::size_t>(k)][ch] - c[ch]) > 24)
          return std::string("bar ") + kBars[i].name + " differs between rows: " + bgr_text(at[0]) + " " +
                 bgr_text(at[1]) + " " + bgr_text(at[2]);
      }
    }
    const std::array<bool, 3> want{kBars[i].b, kBars[i].g, kBars[i].r};
    for (int ch = 0; ch < 3; ++ch) {
      const bool on = c[ch] > 128, off = c[ch] < 64;
      if (want[static_cast<std::size_t>(ch)] ? !on : !off)
        return std::string("bar ") + std::to_string(i) + " should be " + kBars[i].name + ", is " + bgr_text(c) +
               "; bars:" + seen;
    }
  }
  info("colour bars:" + seen);
  return {};
}

// Captures one frame (waiting up to `wait`), or fails.
void capture_one(LibcameraSource& source, Frame& frame, std::chrono::nanoseconds wait, const std::string& what) {
  const std::int64_t give_up = monotonic_ns() + wait.count();
  for (;;) {
    const NextStatus s = source.next(frame, std::chrono::milliseconds(500));
    if (s == NextStatus::frame) return;
    if (s == NextStatus::failed || s == NextStatus::end_of_stream) fail(what + ": the source failed");
    if (monotonic_ns() > give_up) fail(what + ": no frame within " + std::to_string(wait.count() / 1'000'000) + " ms");
  }
}

void dump(const cv::Mat& bgr, const std::string& dir) {
  if (dir.empty()) return;
  const std::string path = dir + "/libcamera_source_last.png";
  if (cv::imwrite(path, bgr)) info("wrote " + path);
}

void capture(const std::string& camera, const std::string& dump_dir) {
  auto log = spdlog::stdout_logger_mt("libcamera");
  LibcameraOptions options;
  options.camera = camera;
  options.size = {kWidth, kHeight};
  Frame frame;
  frame.bgr = cv::Mat(kHeight, kWidth, CV_8UC3, cv::Scalar::all(0));
  const std::uint8_t* const slot_data = frame.bgr.data;
  std::string id;
  {
    LibcameraSource source(options, log);
    if (!source.open()) fail("open " + camera + " (see the log above)");
    id = source.camera_id();
    info("camera id '" + id + "', " + std::to_string(source.buffer_count()) + " buffers, byte order " +
         (source.byte_order() == stemd::drivers::LibcameraByteOrder::bgr ? "B,G,R (RGB888)" : "R,G,B (BGR888)"));
    // Every frame is captured after this and delivered before its "now": in
    // CLOCK_MONOTONIC's domain, however slowly a loaded emulated guest runs.
    const std::int64_t t_before_start = monotonic_ns();
    if (!source.start()) fail("start " + id);

    std::int64_t last_t = 0;
    std::uint64_t last_seq = 0;
    cv::Mat previous(kHeight, kWidth, CV_8UC3);
    int changed = 0;  // frames that differ from the one before (vimc's OSD runs a timer)
    for (int n = 0; n < kFrames; ++n) {
      capture_one(source, frame, n == 0 ? std::chrono::nanoseconds(kFirstFrameWait) : std::chrono::seconds(5),
                  "frame " + std::to_string(n));
      const std::int64_t now = monotonic_ns();
      const std::string tag = "frame " + std::to_string(n) + " (seq " + std::to_string(frame.source_seq) + ")";
      info(tag + ": t_sample " + std::to_string(frame.t_sample_ns) + " ns, " +
           std::to_string((now - frame.t_sample_ns) / 1'000'000) + " ms before now");
      if (frame.bgr.data != slot_data || frame.bgr.size() != cv::Size(kWidth, kHeight) || frame.bgr.type() != CV_8UC3)
        fail(tag + ": the slot was reallocated or resized");
      if (frame.t_sample_ns < t_before_start || frame.t_sample_ns > now)
        fail(tag + ": t_sample_ns " + std::to_string(frame.t_sample_ns) + " is not between the start " +
             std::to_string(t_before_start) + " and now " + std::to_string(now));
      if (frame.t_recorded_ns != frame.t_sample_ns) fail(tag + ": t_recorded_ns differs from t_sample_ns");
      if (n > 0 && frame.t_sample_ns <= last_t)
        fail(tag + ": timestamp " + std::to_string(frame.t_sample_ns) + " not after the previous " +
             std::to_string(last_t));
      if (n > 0 && frame.source_seq <= last_seq) fail(tag + ": source_seq did not increase");
      if (frame.name.view() != source.name()) fail(tag + ": frame name is not the source's");
      if (const std::string why = judge_pattern(frame.bgr); !why.empty()) {
        dump(frame.bgr, dump_dir);
        fail(tag + ": " + why);
      }
      if (n > 0 && cv::norm(frame.bgr, previous, cv::NORM_L1) > 0) ++changed;
      frame.bgr.copyTo(previous);
      last_t = frame.t_sample_ns;
      last_seq = frame.source_seq;
    }
    if (changed == 0) fail("all " + std::to_string(kFrames) + " frames are identical (a stale buffer?)");
    const auto c = source.libcamera_counters();
    const auto common = source.counters();
    info("counters: frames " + std::to_string(c.delivered) + ", timeouts " + std::to_string(c.timeouts) + ", errors " +
         std::to_string(c.errors) + ", corrupt " + std::to_string(c.corrupt) + ", bad_size " +
         std::to_string(c.bad_size) + ", unstamped " + std::to_string(c.unstamped));
    if (c.delivered != static_cast<std::uint64_t>(kFrames) || common.delivered != c.delivered)
      fail("counters: frames " + std::to_string(c.delivered) + ", delivered " + std::to_string(common.delivered) +
           ", captured " + std::to_string(kFrames));
    if (c.errors != 0 || c.bad_size != 0 || c.corrupt != 0 || common.corrupt != c.corrupt ||
        common.bad_size != c.bad_size)
      fail("counters: errors, bad_size or corrupt on a healthy camera");
    if (c.unstamped != 0) fail("counters: " + std::to_string(c.unstamped) + " frames without SensorTimestamp");
    source.stop();
    if (source.state() != LibcameraSource::State::closed) fail("stop() did not close the source");
    if (source.next(frame, std::chrono::milliseconds(1)) != NextStatus::failed) fail("next() after stop() did not fail");
  }

  info("== reopen by full id '" + id + "'");
  options.camera = id;
  LibcameraSource again(options, log);
  if (!again.open() || !again.start()) fail("reopening by id '" + id + "'");
  if (again.camera_id() != id) fail("opened '" + again.camera_id() + "', not '" + id + "'");
  capture_one(again, frame, kFirstFrameWait, "frame after reopen");
  if (frame.bgr.data != slot_data) fail("frame after reopen: slot reallocated");
  if (const std::string why = judge_pattern(frame.bgr); !why.empty()) {
    dump(frame.bgr, dump_dir);
    fail("frame after reopen: " + why);
  }
  again.stop();
}


std::string counters_text(const LibcameraSource& source) {
  const auto c = source.libcamera_counters();
  return "frames " + std::to_string(c.delivered) + ", timeouts " + std::to_string(c.timeouts) + ", errors " +
         std::to_string(c.errors) + ", corrupt " + std::to_string(c.corrupt) + ", lost " + std::to_string(c.lost) +
         ", reopens " + std::to_string(c.reopens) + ", state " + std::string(to_string(source.state()));
}

void run_ctl(const std::vector<std::string>& ctl, const std::string& step) {
  std::vector<std::string> argv = ctl;
  argv.push_back(step);
  info("-- " + step);
  if (const int rc = stemd::vmprobe::run_command(argv); rc != 0) fail(step + ": the command exited " + std::to_string(rc));
}

void unplug(const std::string& camera, const std::string& dump_dir, const std::vector<std::string>& ctl) {
  if (ctl.empty()) fail("unplug needs -- COMMAND (called with unplug, then plug)");
  auto log = spdlog::stdout_logger_mt("libcamera");
  LibcameraOptions options;
  options.camera = camera;
  options.size = {kWidth, kHeight};
  options.first_frame_timeout = kFirstFrameWait;  // TCG may start slowly
  options.stall_timeout = std::chrono::seconds(1);
  options.reopen_min = std::chrono::milliseconds(50);
  options.reopen_max = std::chrono::milliseconds(400);
  Frame frame;
  frame.bgr = cv::Mat(kHeight, kWidth, CV_8UC3, cv::Scalar::all(0));
  const std::uint8_t* const slot_data = frame.bgr.data;
  LibcameraSource source(options, log);
  if (!source.open() || !source.start()) fail("open and start " + camera + " (see the log above)");
  const std::string id = source.camera_id();
  for (int n = 0; n < 3; ++n)
    capture_one(source, frame, n == 0 ? std::chrono::nanoseconds(kFirstFrameWait) : std::chrono::seconds(5),
                "frame " + std::to_string(n) + " before the unplug");
  info("streaming '" + id + "': " + counters_text(source));

  run_ctl(ctl, "unplug");
  // The daemon's loop: next() with a short timeout, which must never fail.
  const std::int64_t unplugged = monotonic_ns();
  while (source.state() != LibcameraSource::State::backoff) {
    const NextStatus s = source.next(frame, std::chrono::milliseconds(100));
    if (s == NextStatus::failed && source.state() == LibcameraSource::State::failed &&
        source.libcamera_counters().lost == 1) {
      // The documented limit (drivers/libcamera/libcamera_source.hpp): the
      // unplug caught requests inside the driver and libcamera 0.0.3 can
      // neither stop nor destroy that camera. A race of the unbind against
      // vb2's queue release; reported as a skip, not a pass.
      std::printf("SKIP: the unplug left requests stuck in the driver; libcamera 0.0.3 cannot release the camera "
                  "(the source stopped cleanly instead of aborting): %s\n", counters_text(source).c_str());
      std::fflush(stdout);
      std::_Exit(77);
    }
    if (s == NextStatus::failed || s == NextStatus::end_of_stream) fail("next() failed after the unplug");
    if (monotonic_ns() - unplugged > 10'000'000'000) fail("no loss noticed 10 s after the unplug: " + counters_text(source));
  }
  info("loss noticed after " + std::to_string((monotonic_ns() - unplugged) / 1'000'000) + " ms: " +
       counters_text(source));
  // Still away: a few reopen attempts, each a timeout.
  const std::int64_t away_until = monotonic_ns() + 1'000'000'000;
  while (monotonic_ns() < away_until) {
    const NextStatus s = source.next(frame, std::chrono::milliseconds(100));
    if (s != NextStatus::timeout) fail("next() while the camera is away: status " + std::to_string(static_cast<int>(s)));
  }
  if (source.state() != LibcameraSource::State::backoff) fail("not in backoff while the camera is away: " + counters_text(source));
  if (source.libcamera_counters().lost != 1 || source.libcamera_counters().reopens != 0)
    fail("counters while away: " + counters_text(source));
  info("camera away: " + counters_text(source));

  run_ctl(ctl, "plug");
  const std::uint64_t frames_before = source.libcamera_counters().delivered;
  capture_one(source, frame, std::chrono::seconds(30), "first frame after the plug");
  info("frames resume: " + counters_text(source));
  for (int n = 0; n < 3; ++n) capture_one(source, frame, std::chrono::seconds(5), "frame after the plug");
  const auto c = source.libcamera_counters();
  if (c.reopens != 1 || c.lost != 1) fail("counters after the plug: " + counters_text(source));
  if (c.delivered != frames_before + 4) fail("frames did not keep counting: " + counters_text(source));
  if (source.camera_id() != id) fail("reopened '" + source.camera_id() + "', not '" + id + "'");
  if (frame.bgr.data != slot_data) fail("frame after the plug: slot reallocated");
  if (const std::string why = judge_pattern(frame.bgr); !why.empty()) {
    dump(frame.bgr, dump_dir);
    fail("frame after the plug: " + why);
  }
  source.stop();
  info("after stop: " + counters_text(source));
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if ((mode != "capture" && mode != "unplug") || argc < 3) {
    std::fprintf(stderr, "usage: %s capture CAMERA [DUMP_DIR]\n       %s unplug CAMERA DUMP_DIR -- COMMAND...\n",
                 argv[0], argv[0]);
    return 2;
  }
  const std::string camera = argv[2];
  const std::string dump_dir = argc > 3 && std::string(argv[3]) != "--" ? argv[3] : "";
  const auto ctl = stemd::vmprobe::command_after_dashes(argc, argv);
  return stemd::vmprobe::run_probe("libcamera-source-check", [&] {
    if (mode == "capture")
      capture(camera, dump_dir);
    else
      unplug(camera, dump_dir, ctl);
  });
}
