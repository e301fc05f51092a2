// VM check of the whole daemon: the real `stemd` binary on vivid (V4L2),
// vcan0 (SocketCAN) and gpio-sim (libgpiod); guest.sh runs the daemon and
// candump, this program feeds the frames and judges the bus.
//
//   stemd-vm-daemon-check feed CAPTURE OUTPUT -- CMD...
//       sets vivid up for HDMI output -> HDMI capture loopback (BGR24
//       640x480, vivid_loopback.hpp), streams bare soil and prints "ready";
//       on SIGUSR1 scrolls a field past the camera at kSpeedMmPerS (plants
//       move down the image, as under a camera with camera.forward up): the
//       phase-1 plants, then, with no plant in view, runs `CMD... down`
//       (guest.sh pulls the enable line inactive), then the phase-2 plants.
//       Prints "done" and streams bare soil until SIGTERM.
//   stemd-vm-daemon-check loop CAPTURE OUTPUT
//       as feed, without waiting or switching, at kLoopSpeedMmPerS: the field
//       scrolls past over and over until SIGTERM (guest.sh's fault checks
//       set odometry.speed_mm_per_s to that).
//   stemd-vm-daemon-check ticker STALLS_FILE
//       until SIGTERM, one SCHED_FIFO 99 thread per CPU wakes every 20 ms
//       and appends "cpu from_us to_us" (CLOCK_REALTIME, as candump's
//       timestamps) for every wake-up more than 50 ms late: the times the
//       host did not run that emulated CPU. No guest thread can hold one of
//       these off, so their lateness is the host's, not stemd's.
//   stemd-vm-daemon-check verify CANDUMP_LOG [PLANT_MAP [HEARTBEAT_ERRORS [STALLS_FILE]]]
//       judges `candump -L` of the daemon's bus and its plant map (see
//       verify() and verify_map()); HEARTBEAT_ERRORS: the heartbeats the
//       daemon's summary says it could not send; STALLS_FILE: the ticker's
//       record, whose stalls a heartbeat gap is not blamed for.
//   stemd-vm-daemon-check config
//       prints the daemon settings the field was drawn for (--set lines).
#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <csignal>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "plant_scene.hpp"
#include "probe_util.hpp"
#include "stemd/protocol/candump_format.hpp"
#include "stemd/protocol/messages.hpp"
#include "vivid_loopback.hpp"
#include "stemd/base/clock.hpp"

namespace {

using stemd::vmprobe::fail;
using stemd::vmprobe::info;
using stemd::vmprobe::Rosette;
namespace proto = stemd::protocol;

constexpr int kWidth = 640;
constexpr int kHeight = 480;
constexpr double kGsdMmPerPx = 0.33;    // camera.gsd_mm_per_px (the default)
// odometry.speed_mm_per_s. A frame reaches the daemon some time after the
// feeder showed it, and on a loaded host (the guest's CPU is emulated) that
// time varies by a few hundred ms; at 30 mm/s that is under the 12 mm the
// plant spacing may be off, at 60 mm/s it was not.
constexpr double kSpeedMmPerS = 30.0;
// The fault checks' loop (no positions judged): plants come twice as often.
constexpr double kLoopSpeedMmPerS = 60.0;
constexpr double kCx = (kWidth - 1) / 2.0, kCy = (kHeight - 1) / 2.0;  // principal point
constexpr double kHalfViewMm = kCy * kGsdMmPerPx;  // 79 mm: view from s - 79 to s + 79
constexpr float kLeafPx = 50;                      // plants ~100 px = 33 mm across
constexpr double kPlantMarginMm = kLeafPx * kGsdMmPerPx + 5;
constexpr int kToolOffsetMm = 600;  // tools.0.offset_mm (the default)

const cv::Vec3b kSoil{45, 80, 125};  // BGR: brown
const cv::Vec3b kLeaf{40, 150, 60};  // BGR: green

// A plant in field coordinates: s along the track (the odometer reading when
// its stem is under the principal point), y across (left > 0).
struct Plant {
  double s_mm;
  double y_mm;
  int leaves;
  float rotation_deg;
};
// Phase 1 (enable active): TARGETs for each (at least one; see verify()).
// Phase 2 (enable inactive): none, each counted as dropped in
// HEARTBEAT.targets_dropped. 60 mm apart along the track: beyond
// tracker.association_radius_mm plus the detection error; lateral positions
// 30 mm apart, which tells which plant a TARGET is for.
const std::array kPhase1{Plant{100, -35, 5, 10}, Plant{160, 25, 6, 35}, Plant{220, -5, 5, 60}};
const std::array kPhase2{Plant{460, 55, 6, 0}, Plant{520, -65, 5, 20}};
// The odometer (from the start of the feed) at which the enable line goes
// inactive: the last phase-1 plant has left the view, no phase-2 plant is in it.
constexpr double kDisableAtMm = 220 + kHalfViewMm + kPlantMarginMm + 10;
static_assert(kDisableAtMm + 20 < 460 - kHalfViewMm - kPlantMarginMm, "phase-2 plants in view at the switch");
constexpr double kEndAtMm = 520 + kHalfViewMm + kPlantMarginMm + 10;

// Settings the field is drawn for; guest.sh passes them to stemd (with its
// device, interface and chip).
const char* const kDaemonSettings[] = {
    "source.kind=v4l2",
    "source.v4l2_pixel_format=bgr24",
    "source.width_px=640",
    "source.height_px=480",
    "source.fps=60",
    "camera.gsd_mm_per_px=0.33",
    "camera.model=nadir",
    "camera.forward=up",
    "odometry.source=constant",
    "odometry.speed_mm_per_s=30",
    "scheduler.policy=all",
    "tracker.association_radius_mm=20",
    "gpio.enable_active=high",
    "can.heartbeat_ms=100",
    "status.interval_s=2",
    // The phases are judged by the first frame and the enable line; a guest
    // the loaded host stops for a second must not read as a lost camera.
    "source.lost_after_ms=10000",
    // The VM emulates the CPU (QEMU TCG): the default chromatic index's
    // float division takes ~150 ms a frame there, and the daemon would see
    // 5 of 60 frames. This check is about the drivers and the daemon's
    // wiring, so it runs the integer Excess Green path at full rate.
    "segment.method=exg",
    "segment.threshold=otsu",
    "segment.smooth=false",
    "segment.opening_radius_px=0",
};

volatile std::sig_atomic_t g_go = 0;
volatile std::sig_atomic_t g_stop = 0;
extern "C" void on_signal(int sig) {
  if (sig == SIGUSR1) g_go = 1;
  else g_stop = 1;
}

double monotonic_s() { return static_cast<double>(stemd::base::monotonic_ns()) * 1e-9; }

// The field as one tall BGR strip; row k shows s = kStripTopMm - k * gsd.
constexpr double kStripTopMm = kEndAtMm + kHalfViewMm + 1;
constexpr double kStripBottomMm = -kHalfViewMm - 1;
cv::Mat draw_field() {
  const int rows = static_cast<int>(std::ceil((kStripTopMm - kStripBottomMm) / kGsdMmPerPx)) + 1;
  cv::Mat bgr(rows, kWidth, CV_8UC3, cv::Scalar(kSoil[0], kSoil[1], kSoil[2]));
  cv::Mat noise(bgr.size(), CV_8UC3);
  cv::RNG rng(0x5eed);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 8);
  bgr += noise;
  auto draw = [&](const Plant& p) {
    const cv::Point2f stem(static_cast<float>(kCx - p.y_mm / kGsdMmPerPx),
                           static_cast<float>((kStripTopMm - p.s_mm) / kGsdMmPerPx));
    stemd::vmprobe::draw_rosette(bgr, Rosette{stem, p.leaves, kLeafPx, p.rotation_deg},
                                 cv::Scalar(kLeaf[0], kLeaf[1], kLeaf[2]));
  };
  for (const Plant& p : kPhase1) draw(p);
  for (const Plant& p : kPhase2) draw(p);
  return bgr;
}

// The frame at odometer `odom_mm`: image row y shows s = odom + (cy - y) * gsd.
std::vector<std::uint8_t> frame_at(const cv::Mat& field, double odom_mm, const v4l2_pix_format& pix) {
  const double top_s = odom_mm + kCy * kGsdMmPerPx;
  const int k0 = std::clamp(static_cast<int>(std::lround((kStripTopMm - top_s) / kGsdMmPerPx)), 0, field.rows - kHeight);
  std::vector<std::uint8_t> out(pix.sizeimage, 0);
  for (int y = 0; y < kHeight; ++y)
    std::memcpy(out.data() + static_cast<std::size_t>(y) * pix.bytesperline, field.ptr(k0 + y),
                static_cast<std::size_t>(kWidth) * 3);
  return out;
}

// SIGTERM and SIGINT end a feeder's loop.
void stop_on_signals() {
  std::signal(SIGTERM, on_signal);
  std::signal(SIGINT, on_signal);
}

// The loopback's output as BGR24 at the vivid size; its format as set.
v4l2_pix_format bgr_output(stemd::vmprobe::VividLoopback& loop, const std::string& out_dev) {
  const v4l2_pix_format pix = loop.set_output_format(V4L2_PIX_FMT_BGR24, kWidth, kHeight);
  if (pix.bytesperline < kWidth * 3) fail(out_dev + ": bytesperline " + std::to_string(pix.bytesperline));
  return pix;
}

void feed(const std::string& cap_dev, const std::string& out_dev, std::vector<std::string> cmd) {
  std::signal(SIGUSR1, on_signal);
  stop_on_signals();
  const cv::Mat field = draw_field();
  stemd::vmprobe::VividLoopback loop(cap_dev, out_dev);
  const v4l2_pix_format pix = bgr_output(loop, out_dev);
  const auto soil = frame_at(field, kStripBottomMm - 2 * kHalfViewMm, pix);  // bottom of the strip: no plant
  // Two output buffers, vivid's least: an image is shown after those queued
  // before it, and on a loaded host vivid takes them at a few per second, so
  // each queued buffer adds a varying delay between the odometer an image
  // was drawn for and its capture time.
  loop.start(soil, 2);
  info("ready: " + out_dev + " -> " + cap_dev + " BGR24 640x480, field " + std::to_string(field.rows) + " rows");

  auto wait_frame = [&] {
    pollfd pfd{loop.out_fd(), POLLOUT, 0};
    ::poll(&pfd, 1, 20);
    loop.pump();
  };
  const double ready_at = monotonic_s();
  while (!g_go && !g_stop) {
    if (monotonic_s() - ready_at > 300) fail("no SIGUSR1 within 300 s");
    wait_frame();
  }
  const double t0 = monotonic_s();
  info("go: " + std::to_string(kSpeedMmPerS) + " mm/s, phase 1 plants at s = 100, 160, 220 mm; enable off at " +
       std::to_string(static_cast<int>(kDisableAtMm)) + " mm; phase 2 at 460, 520 mm; end at " +
       std::to_string(static_cast<int>(kEndAtMm)) + " mm");
  bool disabled = false;
  long shown = 0;
  int last_k = -1;
  while (!g_stop) {
    // The next image is drawn only when vivid hands a buffer back, for the
    // odometer of that moment: no image waits in the queue while the field
    // moves on, and far less copying (the emulated CPU is short of time)
    // than drawing every 0.33 mm step.
    pollfd pfd{loop.out_fd(), POLLOUT, 0};
    ::poll(&pfd, 1, 20);
    const double odom = kSpeedMmPerS * (monotonic_s() - t0);
    if (!disabled && odom >= kDisableAtMm) {
      std::vector<std::string> c = cmd;
      c.emplace_back("down");
      info("odometer " + std::to_string(odom) + " mm: enable line inactive");
      if (stemd::vmprobe::run_command(c) != 0) fail("the enable command failed");
      disabled = true;
    }
    if (odom >= kEndAtMm) break;
    const int k = static_cast<int>(std::lround(odom / kGsdMmPerPx));
    if ((pfd.revents & POLLOUT) != 0 && k != last_k) {
      loop.show(frame_at(field, odom, pix));
      last_k = k;
      ++shown;
    }
    loop.pump();
  }
  // "disabled plants N": guest.sh waits for a HEARTBEAT counting them all.
  info("done: " + std::to_string(shown) + " distinct frames in " + std::to_string(monotonic_s() - t0) +
       " s; disabled plants " + std::to_string(kPhase2.size()));
  loop.show(soil);
  while (!g_stop) wait_frame();
  loop.stop();
}

// The field over and over, from the start, until SIGTERM (the fault checks:
// plants keep coming, so TARGETs can be expected whenever the daemon is
// enabled and has frames). A lost device (the camera unplugged) ends it
// with an error, as a feeder whose output node is gone.
void loop_feed(const std::string& cap_dev, const std::string& out_dev) {
  stop_on_signals();
  const cv::Mat field = draw_field();
  stemd::vmprobe::VividLoopback loop(cap_dev, out_dev);
  const v4l2_pix_format pix = bgr_output(loop, out_dev);
  const auto soil = frame_at(field, kStripBottomMm - 2 * kHalfViewMm, pix);
  loop.start(soil, 2);  // as feed()
  info("ready: " + out_dev + " -> " + cap_dev + " BGR24 640x480, the field over and over");
  const double t0 = monotonic_s();
  int last_k = -1;
  while (!g_stop) {
    // As feed(): an image only when vivid hands a buffer back.
    pollfd pfd{loop.out_fd(), POLLOUT, 0};
    ::poll(&pfd, 1, 20);
    const double odom = std::fmod(kLoopSpeedMmPerS * (monotonic_s() - t0), kEndAtMm);
    const int k = static_cast<int>(std::lround(odom / kGsdMmPerPx));
    if ((pfd.revents & POLLOUT) != 0 && k != last_k) {
      loop.show(frame_at(field, odom, pix));
      last_k = k;
    }
    loop.pump();
  }
  loop.stop();
}

// --- verify ---------------------------------------------------------------------

// The plant map (stemd --map): the fused position of each plant's longest
// track (most sightings) must be where the plant is, relative to the first:
// the whole chain (capture, detection, geometry, odometry, fusion) to a few mm.
double json_number(const std::string& line, const std::string& key) {
  const auto at = line.find("\"" + key + "\":");
  if (at == std::string::npos) fail("plant map line without " + key + ": " + line);
  return std::strtod(line.c_str() + at + key.size() + 3, nullptr);
}

std::vector<double> verify_map(const std::string& path) {
  std::ifstream in(path);
  if (!in) fail("cannot read " + path);
  struct Entry {
    double s, y, sightings;
  };
  std::vector<Entry> entries;
  std::string line;
  while (std::getline(in, line))
    if (!line.empty()) entries.push_back({json_number(line, "s_mm"), json_number(line, "y_mm"), json_number(line, "sightings")});
  std::vector<Plant> plants(kPhase1.begin(), kPhase1.end());
  plants.insert(plants.end(), kPhase2.begin(), kPhase2.end());
  std::vector<Entry> main(plants.size(), Entry{0, 0, 0});
  for (const Entry& e : entries) {
    std::size_t best = 0;
    for (std::size_t i = 1; i < plants.size(); ++i)
      if (std::abs(e.y - plants[i].y_mm) < std::abs(e.y - plants[best].y_mm)) best = i;
    // The plants lie in lateral bands 30 mm apart.
    if (e.sightings > main[best].sightings) main[best] = e;
  }
  for (std::size_t i = 0; i < plants.size(); ++i) {
    if (main[i].sightings < 10) fail("plant map: no track with 10 sightings for plant " + std::to_string(i));
    const double ds = (main[i].s - main[0].s) - (plants[i].s_mm - plants[0].s_mm);
    const double dy = main[i].y - plants[i].y_mm;
    info("plant map: plant " + std::to_string(i) + " s " + std::to_string(main[i].s) + " y " + std::to_string(main[i].y) +
         " mm (" + std::to_string(static_cast<int>(main[i].sightings)) + " sightings): along-track error " +
         std::to_string(ds) + " mm relative to plant 0, lateral error " + std::to_string(dy) + " mm");
    if (std::abs(ds) > 4 || std::abs(dy) > 3) fail("plant map: plant " + std::to_string(i) + " is not where it was drawn");
  }
  std::vector<double> s;
  for (const Entry& e : main) s.push_back(e.s);
  return s;
}

std::uint64_t realtime_us() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000000u + static_cast<std::uint64_t>(ts.tv_nsec) / 1000u;
}

constexpr std::uint64_t kTickUs = 20000;
constexpr std::uint64_t kStallUs = 50000;

void ticker(const std::string& path) {
  stop_on_signals();
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) fail("cannot create " + path + ": " + std::strerror(errno));
  const unsigned cpus = std::max(1u, std::thread::hardware_concurrency());
  std::vector<std::thread> threads;
  for (unsigned cpu = 0; cpu < cpus; ++cpu)
    threads.emplace_back([fd, cpu] {
      cpu_set_t set;
      CPU_ZERO(&set);
      CPU_SET(cpu, &set);
      const sched_param param{99};
      // Without both, a late wake-up could be the guest's own load: then
      // record nothing, so that no heartbeat gap is excused.
      if (pthread_setaffinity_np(pthread_self(), sizeof set, &set) != 0 ||
          pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) != 0) {
        std::fprintf(stderr, "ticker: cpu %u: no SCHED_FIFO 99 pinned thread, no stalls recorded\n", cpu);
        return;
      }
      while (!g_stop) {
        const std::uint64_t before = realtime_us();
        const timespec nap{0, static_cast<long>(kTickUs * 1000)};
        clock_nanosleep(CLOCK_MONOTONIC, 0, &nap, nullptr);
        const std::uint64_t after = realtime_us();
        if (after > before + kTickUs + kStallUs) {
          char line[96];
          const int n = std::snprintf(line, sizeof line, "%u %llu %llu\n", cpu,
                                      static_cast<unsigned long long>(before + kTickUs),
                                      static_cast<unsigned long long>(after));
          if (::write(fd, line, static_cast<std::size_t>(n)) != n) return;
        }
      }
    });
  std::printf("ready: %u ticker threads\n", cpus);
  std::fflush(stdout);
  for (std::thread& t : threads) t.join();
  ::close(fd);
}

// The ticker's stalls as sorted, merged intervals [from_us, to_us).
std::vector<std::pair<std::uint64_t, std::uint64_t>> read_stalls(const std::string& path) {
  std::vector<std::pair<std::uint64_t, std::uint64_t>> stalls, merged;
  if (path.empty()) return merged;
  std::ifstream in(path);
  if (!in) fail("cannot read " + path);
  unsigned cpu = 0;
  unsigned long long from = 0, to = 0;
  while (in >> cpu >> from >> to)
    if (to > from) stalls.emplace_back(from, to);
  std::sort(stalls.begin(), stalls.end());
  for (const auto& s : stalls) {
    if (!merged.empty() && s.first <= merged.back().second) merged.back().second = std::max(merged.back().second, s.second);
    else merged.push_back(s);
  }
  return merged;
}

// Microseconds of [from, to) inside any of the stalls.
std::uint64_t stalled_us(const std::vector<std::pair<std::uint64_t, std::uint64_t>>& stalls, std::uint64_t from,
                         std::uint64_t to) {
  std::uint64_t sum = 0;
  for (const auto& [a, b] : stalls) {
    const std::uint64_t lo = std::max(a, from), hi = std::min(b, to);
    if (hi > lo) sum += hi - lo;
  }
  return sum;
}

struct Rec {
  std::uint64_t t_us;
  proto::CanFrame frame;
};

void verify(const std::string& path, const std::string& map_path, int heartbeats_not_sent, const std::string& stalls_path) {
  std::ifstream in(path);
  if (!in) fail("cannot read " + path);
  const proto::CanIds ids;
  std::vector<Rec> recs;
  std::string line, error;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.empty()) continue;
    proto::CandumpRecord r;
    if (!proto::parse_candump_line(line, r, error)) fail(path + ":" + std::to_string(lineno) + ": " + error);
    recs.push_back({r.time_us, r.frame});
  }
  info(std::to_string(recs.size()) + " frames in " + path);

  struct Hb {
    std::uint64_t t_us;
    proto::Heartbeat m;
  };
  struct Tg {
    std::uint64_t t_us;
    proto::TargetCommand m;
    std::size_t heartbeats_before;
  };
  std::vector<Hb> hbs;
  std::vector<Tg> tgs;
  int last_hb_counter = -1, last_tg_counter = -1;
  // A counter may skip only as many values as the daemon says it could not
  // send (HEARTBEATs: its heartbeat_errors, e.g. a send past its deadline
  // when the emulated CPU was held up); the skips must add up to exactly that.
  int hb_skipped = 0;
  auto check_counter = [](int& last, const proto::CanFrame& f, const char* what, int* skipped, int allowed) {
    const int c = f.data[1] & 0x0F;
    if (last >= 0 && c != (last + 1) % 15) {
      const int skip = ((c - last - 1) % 15 + 15) % 15;
      if (skipped == nullptr || *skipped + skip > allowed)
        fail(std::string(what) + " alive counter " + std::to_string(c) + " after " + std::to_string(last) +
             " (frames lost or repeated)");
      *skipped += skip;
    }
    last = c;
  };
  for (const Rec& r : recs) {
    const auto kind = ids.kind_of(r.frame);
    if (!kind) fail("a frame that is not stemd's: id " + std::to_string(r.frame.id));
    if (*kind == proto::MessageKind::Heartbeat) {
      proto::Heartbeat m;
      if (const auto res = proto::decode(r.frame, ids, m); !res)
        fail("HEARTBEAT does not decode: " + std::string(proto::to_string(res.error)));
      check_counter(last_hb_counter, r.frame, "HEARTBEAT", &hb_skipped, heartbeats_not_sent);
      hbs.push_back({r.t_us, m});
    } else if (*kind == proto::MessageKind::Target) {
      proto::TargetCommand m;
      if (const auto res = proto::decode(r.frame, ids, m); !res)
        fail("TARGET does not decode (E2E CRC or range): " + std::string(proto::to_string(res.error)));
      check_counter(last_tg_counter, r.frame, "TARGET", nullptr, 0);
      tgs.push_back({r.t_us, m, hbs.size()});
      info("TARGET id " + std::to_string(m.target_id) + " tool " + std::to_string(m.tool_id) + " lane " +
           std::to_string(m.lane) + " fire_odom " + std::to_string(m.fire_odom_mm) + " mm lateral " +
           std::to_string(m.lateral_mm) + " mm class " + std::to_string(static_cast<int>(m.plant_class)) +
           " (after heartbeat " + std::to_string(hbs.size()) + ")");
    } else {
      fail("stemd sent a " + std::string(proto::to_string(*kind)) + " frame");
    }
  }

  if (hb_skipped != heartbeats_not_sent)
    fail("HEARTBEAT counters skip " + std::to_string(hb_skipped) + " values, the daemon did not send " +
         std::to_string(heartbeats_not_sent));
  if (heartbeats_not_sent > 0)
    info("HEARTBEAT counters skip the " + std::to_string(heartbeats_not_sent) + " the daemon counted as not sent");
  // Heartbeats: ~100 ms apart, all those sent (the alive counter above).
  if (hbs.size() < 30) fail("only " + std::to_string(hbs.size()) + " heartbeats");
  std::vector<std::uint64_t> gaps;
  for (std::size_t i = 1; i < hbs.size(); ++i) gaps.push_back(hbs[i].t_us - hbs[i - 1].t_us);
  std::vector<std::uint64_t> sorted = gaps;
  std::sort(sorted.begin(), sorted.end());
  const double median_ms = static_cast<double>(sorted[sorted.size() / 2]) / 1000.0;
  const double max_ms = static_cast<double>(sorted.back()) / 1000.0;
  const double mean_ms = static_cast<double>(hbs.back().t_us - hbs.front().t_us) / 1000.0 / static_cast<double>(gaps.size());
  info("heartbeats: " + std::to_string(hbs.size()) + ", interval median " + std::to_string(median_ms) + " ms, mean " +
       std::to_string(mean_ms) + " ms, max " + std::to_string(max_ms) + " ms");
  if (median_ms < 90 || median_ms > 115 || mean_ms < 90 || mean_ms > 120)
    fail("heartbeat interval not ~100 ms");
  // A gap counts against stemd only for the time the host ran the guest:
  // under TCG a loaded host can stop an emulated CPU for longer than that.
  const auto stalls = read_stalls(stalls_path);
  std::uint64_t longest_stall_us = 0;
  for (const auto& [a, b] : stalls) longest_stall_us = std::max(longest_stall_us, b - a);
  if (!stalls_path.empty())
    info("guest stalls (the host did not run a CPU for > 50 ms): " + std::to_string(stalls.size()) + ", longest " +
         std::to_string(static_cast<double>(longest_stall_us) / 1000.0) + " ms");
  for (std::size_t i = 1; i < hbs.size(); ++i) {
    const std::uint64_t gap_us = hbs[i].t_us - hbs[i - 1].t_us;
    if (gap_us <= 400000) continue;
    const std::uint64_t stalled = stalled_us(stalls, hbs[i - 1].t_us, hbs[i].t_us);
    const double gap = static_cast<double>(gap_us) / 1000.0, own = static_cast<double>(gap_us - stalled) / 1000.0;
    if (gap_us - stalled > 400000)
      fail("a heartbeat gap of " + std::to_string(gap) + " ms, " + std::to_string(own) + " ms of it while the host ran the guest");
    info("a heartbeat gap of " + std::to_string(gap) + " ms, only " + std::to_string(own) +
         " ms of it while the host ran the guest");
  }

  // Phases by the heartbeat state: Starting until the first frame, then
  // Active (or Degraded), then Idle once the enable line is inactive.
  auto state = [&](std::size_t i) { return hbs[i].m.state; };
  std::size_t first_active = hbs.size();
  for (std::size_t i = 0; i < hbs.size(); ++i)
    if (state(i) == proto::DaemonState::Active || state(i) == proto::DaemonState::Degraded) {
      first_active = i;
      break;
    }
  if (first_active == hbs.size()) fail("no heartbeat with state active");
  for (std::size_t i = 0; i < first_active; ++i)
    if (state(i) != proto::DaemonState::Starting) fail("heartbeat " + std::to_string(i) + " before active is not starting");
  std::size_t first_idle = hbs.size();
  for (std::size_t i = first_active; i < hbs.size(); ++i)
    if (state(i) == proto::DaemonState::Idle) {
      first_idle = i;
      break;
    }
  if (first_idle == hbs.size()) fail("no heartbeat with state idle after the enable line went inactive");
  for (std::size_t i = first_active; i < first_idle; ++i)
    if (state(i) != proto::DaemonState::Active) fail("heartbeat " + std::to_string(i) + " in phase 1 is not active (state " + std::to_string(static_cast<int>(state(i))) + ")");
  for (std::size_t i = first_idle; i < hbs.size(); ++i)
    if (state(i) != proto::DaemonState::Idle) fail("heartbeat " + std::to_string(i) + " after the switch is not idle");
  const std::size_t idle_count = hbs.size() - first_idle;
  info("heartbeats: " + std::to_string(first_active) + " starting, " + std::to_string(first_idle - first_active) +
       " active, " + std::to_string(idle_count) + " idle");
  if (idle_count < 30) fail("only " + std::to_string(idle_count) + " heartbeats in phase 2 (idle)");

  // Phase 1: TARGETs only before the switch, at least one per plant, where
  // the plants are. A TARGET belongs to the plant with the nearest lateral
  // position (the plants' differ by >= 30 mm), within 14 mm (a plant only
  // partly in view has its stem estimated off the true one).
  for (const Tg& t : tgs)
    if (t.heartbeats_before > first_idle) fail("a TARGET after the enable line went inactive (state idle)");
  std::array<std::vector<proto::TargetCommand>, kPhase1.size()> per_plant;
  std::vector<std::uint16_t> ids_seen;
  for (const Tg& t : tgs) {  // in emission order
    const proto::TargetCommand& m = t.m;
    if (m.tool_id != 0 || m.lane != 0) fail("TARGET for tool " + std::to_string(m.tool_id) + " lane " + std::to_string(m.lane));
    if (m.plant_class != proto::PlantClass::Unknown) fail("TARGET with a plant class (no class map here)");
    std::size_t best = 0;
    for (std::size_t i = 1; i < kPhase1.size(); ++i)
      if (std::abs(m.lateral_mm - kPhase1[i].y_mm) < std::abs(m.lateral_mm - kPhase1[best].y_mm)) best = i;
    if (std::abs(m.lateral_mm - kPhase1[best].y_mm) > 14)
      fail("TARGET id " + std::to_string(m.target_id) + " lateral " + std::to_string(m.lateral_mm) + " mm: no plant there");
    per_plant[best].push_back(m);
    ids_seen.push_back(m.target_id);
  }
  std::sort(ids_seen.begin(), ids_seen.end());
  if (std::adjacent_find(ids_seen.begin(), ids_seen.end()) != ids_seen.end()) fail("repeated target_id");
  std::size_t extra = 0;
  for (std::size_t i = 0; i < kPhase1.size(); ++i) {
    const Plant& p = kPhase1[i];
    if (per_plant[i].empty()) fail("no TARGET for plant " + std::to_string(i) + " (y " + std::to_string(p.y_mm) + " mm)");
    const proto::TargetCommand& first = per_plant[i].front();
    std::string dups;
    for (std::size_t k = 1; k < per_plant[i].size(); ++k)
      dups += " " + std::to_string(proto::fire_distance_mm(per_plant[i][k].fire_odom_mm, first.fire_odom_mm)) + "/" +
              std::to_string(per_plant[i][k].lateral_mm - first.lateral_mm);
    extra += per_plant[i].size() - 1;
    info("plant " + std::to_string(i) + " (s " + std::to_string(static_cast<int>(p.s_mm)) + ", y " +
         std::to_string(static_cast<int>(p.y_mm)) + " mm): " + std::to_string(per_plant[i].size()) +
         " TARGET(s); first: fire_odom " + std::to_string(first.fire_odom_mm) + " lateral " +
         std::to_string(first.lateral_mm) + (dups.empty() ? "" : "; more at +fire/+lateral mm:" + dups));
    if (i > 0) {
      const int d = proto::fire_distance_mm(first.fire_odom_mm, per_plant[i - 1].front().fire_odom_mm);
      const double want = p.s_mm - kPhase1[i - 1].s_mm;
      if (std::abs(d - want) > 12)
        fail("first TARGETs of plants " + std::to_string(i - 1) + " and " + std::to_string(i) + " " +
             std::to_string(d) + " mm apart, the plants " + std::to_string(want) + " mm");
    }
  }
  // One plant, one TARGET: the daemon leaves out plants cut by the leading
  // or trailing image border, so neither a plant entering the view nor its
  // leaves still in view after its stem has left start a track of their own.
  if (extra > 0) fail(std::to_string(extra) + " TARGET(s) more than plants: a plant was commanded twice");

  // Heartbeat counters: targets_sent = the TARGET frames on the bus; in
  // phase 2 every plant is dropped (disabled), none sent.
  const proto::Heartbeat& last = hbs.back().m;
  const proto::Heartbeat& at_switch = hbs[first_idle].m;
  info("last heartbeat: targets_sent " + std::to_string(last.targets_sent) + " targets_dropped " +
       std::to_string(last.targets_dropped) + " deadline_misses " + std::to_string(last.deadline_misses) +
       " rx_rejected " + std::to_string(last.rx_rejected) + "; at the switch targets_dropped " +
       std::to_string(at_switch.targets_dropped));
  if (last.targets_sent != tgs.size())
    fail("heartbeat targets_sent is not the " + std::to_string(tgs.size()) + " TARGETs on the bus");
  if (at_switch.targets_dropped != 0) fail("targets dropped in phase 1");
  if (last.targets_dropped < kPhase2.size())
    fail("heartbeat targets_dropped " + std::to_string(last.targets_dropped) + ", want >= " +
         std::to_string(kPhase2.size()) + " (the phase-2 plants, disabled)");
  if (last.deadline_misses != 0 || last.rx_rejected != 0) fail("deadline misses or rejected frames");
  if (!map_path.empty()) {
    // Where each plant's TARGET fires, against the plant's fused position
    // at the end (the map's s + the tool's offset): it is sent after
    // confirm_frames sightings of the whole plant, so within a few mm.
    const std::vector<double> fused = verify_map(map_path);
    for (std::size_t i = 0; i < kPhase1.size(); ++i) {
      const double want = fused[i] + kToolOffsetMm;
      const double bias = proto::fire_distance_mm(per_plant[i].front().fire_odom_mm,
                                                static_cast<std::uint32_t>(std::lround(want)));
      info("plant " + std::to_string(i) + ": first TARGET fires " + std::to_string(bias) +
           " mm from the plant's fused position + tool offset");
      if (std::abs(bias) > 5) fail("the TARGET fires more than 5 mm from the plant");
    }
  }
  info("the daemon: TARGETs while enabled (E2E CRC, consecutive counters) for every plant, at its lateral position "
       "and spacing; none while disabled (counted dropped); heartbeats every ~100 ms, starting -> active -> idle");
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  const auto cmd = stemd::vmprobe::command_after_dashes(argc, argv);
  if (mode == "config") {
    for (const char* s : kDaemonSettings) std::printf("%s\n", s);
    return 0;
  }
  if (!((mode == "feed" && argc >= 4 && !cmd.empty()) || (mode == "loop" && argc >= 4) ||
        (mode == "verify" && argc >= 3) || (mode == "ticker" && argc >= 3))) {
    std::fprintf(stderr, "usage: %s feed CAPTURE OUTPUT -- CMD... | loop CAPTURE OUTPUT | ticker STALLS_FILE | verify CANDUMP_LOG [PLANT_MAP [HEARTBEAT_ERRORS [STALLS_FILE]]] | config\n",
                 argv[0]);
    return 2;
  }
  return stemd::vmprobe::run_probe("daemon-check", [&] {
    if (mode == "feed") feed(argv[2], argv[3], cmd);
    else if (mode == "loop") loop_feed(argv[2], argv[3]);
    else if (mode == "ticker") ticker(argv[2]);
    else verify(argv[2], argc > 3 ? argv[3] : "", argc > 4 ? std::atoi(argv[4]) : 0, argc > 5 ? argv[5] : "");
  });
}
