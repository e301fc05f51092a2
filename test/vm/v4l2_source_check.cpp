// VM check of the project's own V4L2 frame source (drivers/v4l2) on vivid.
//
//   stemd-vm-v4l2-source-check loop CAPTURE OUTPUT FORMAT [DUMP_DIR]
//       sets vivid up for HDMI output -> HDMI input loopback (as
//       v4l2_probe.cpp's loopback does: HDMI 0 both sides, equal DV timings
//       640x480p60, loop_video = 1, osd_text_mode = 2, >= 2 output buffers),
//       keeps writing a synthetic plant frame (green rosettes on brown soil,
//       known stems) in FORMAT (yuyv | bgr24) to OUTPUT, captures through
//       stemd::drivers::V4l2Source from CAPTURE and checks, on kPassFrames
//       consecutive frames: the soil and leaf colours (catches swapped
//       channels), vision::detect finds a stem within 3 px of every drawn
//       stem, and the capture timestamps increase by at least 5 ms per frame
//       (nanoseconds, not microseconds) and lie within 2 s before
//       CLOCK_MONOTONIC now. DUMP_DIR gets the sent and the last captured
//       image (PNG) on failure.
//   stemd-vm-v4l2-source-check selftest FORMAT
//       the same scene through the format conversion and detection, without
//       a device (host sanity check of the check itself).
#include <algorithm>
#include <linux/videodev2.h>
#include <time.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include "plant_scene.hpp"
#include "probe_util.hpp"
#include "vivid_loopback.hpp"
#include "stemd/vision/detect.hpp"
#include "v4l2/v4l2_source.hpp"
#include "stemd/base/clock.hpp"

namespace {

using stemd::drivers::V4l2PixelFormat;
using namespace stemd::vmprobe;

constexpr int kPassFrames = 5;     // consecutive good frames needed
constexpr int kMaxFrames = 60;     // frames captured at most
constexpr double kMaxStemErrorPx = 3.0;
// Distinct frames at 59.94 fps are 16.7 ms apart; a timestamp in the wrong
// unit (e.g. tv_usec not scaled to ns) makes them microseconds apart (with a
// ~1 s jump at each second boundary, which a mean would hide). Checked on the
// median interval: a pair may come closer, because the source caps a (vivid)
// timestamp ahead of the dequeue time at the dequeue time, and a loaded
// machine dequeues in bursts.
constexpr std::int64_t kMinMedianFrameIntervalNs = 5'000'000;

const cv::Vec3b kSoil{45, 80, 125};   // BGR: brown
const cv::Vec3b kLeaf{40, 150, 60};   // BGR: green
const cv::Rect kSoilPatch{8, 8, 24, 24};

using stemd::vmprobe::Rosette;
const std::array kRosettes{Rosette{{180, 200}, 5, 70, 10}, Rosette{{450, 300}, 6, 60, 35}};

using stemd::base::monotonic_ns;

// Leaves are ellipses radiating from the stem, each from the stem outwards.
cv::Mat draw_scene() {
  cv::Mat bgr(kVividHeight, kVividWidth, CV_8UC3, cv::Scalar(kSoil[0], kSoil[1], kSoil[2]));
  cv::Mat noise(bgr.size(), CV_8UC3);
  cv::RNG rng(0x5eed);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 8);
  bgr += noise;
  for (const Rosette& r : kRosettes) stemd::vmprobe::draw_rosette(bgr, r, cv::Scalar(kLeaf[0], kLeaf[1], kLeaf[2]));
  return bgr;
}

std::uint8_t clamp_u8(double v) { return static_cast<std::uint8_t>(std::lround(std::min(255.0, std::max(0.0, v)))); }

// BGR -> packed bytes of `format` with rows `bytesperline` apart. YUYV uses
// BT.601 limited range, the inverse of OpenCV's COLOR_YUV2BGR_YUYV.
std::vector<std::uint8_t> encode(const cv::Mat& bgr, V4l2PixelFormat format, std::size_t bytesperline,
                                 std::size_t sizeimage) {
  std::vector<std::uint8_t> out(sizeimage, 0);
  for (int y = 0; y < bgr.rows; ++y) {
    std::uint8_t* q = out.data() + static_cast<std::size_t>(y) * bytesperline;
    const auto* row = bgr.ptr<cv::Vec3b>(y);
    if (format == V4l2PixelFormat::bgr24) {
      std::memcpy(q, row, static_cast<std::size_t>(bgr.cols) * 3);
      continue;
    }
    for (int x = 0; x < bgr.cols; x += 2) {
      double yy[2], u = 0, v = 0;
      for (int k = 0; k < 2; ++k) {
        const double b = row[x + k][0], g = row[x + k][1], r = row[x + k][2];
        yy[k] = 16 + 0.257 * r + 0.504 * g + 0.098 * b;
        u += (128 - 0.148 * r - 0.291 * g + 0.439 * b) / 2;
        v += (128 + 0.439 * r - 0.368 * g - 0.071 * b) / 2;
      }
      q[2 * x + 0] = clamp_u8(yy[0]);
      q[2 * x + 1] = clamp_u8(u);
      q[2 * x + 2] = clamp_u8(yy[1]);
      q[2 * x + 3] = clamp_u8(v);
    }
  }
  return out;
}

// Checks one captured BGR image; empty string = good, else why not.
std::string judge(const cv::Mat& bgr, stemd::vision::Workspace& ws, stemd::vision::Detections& det) {
  const cv::Scalar soil = cv::mean(bgr(kSoilPatch));
  for (int c = 0; c < 3; ++c) {
    if (std::abs(soil[c] - (kSoil[c] + 3.5)) > 12) {
      return "soil colour BGR (" + std::to_string(std::lround(soil[0])) + "," + std::to_string(std::lround(soil[1])) +
             "," + std::to_string(std::lround(soil[2])) + "), drawn (" + std::to_string(kSoil[0]) + "," +
             std::to_string(kSoil[1]) + "," + std::to_string(kSoil[2]) + ")";
    }
  }
  const Rosette& r0 = kRosettes[0];
  const float a = r0.rotation_deg * static_cast<float>(CV_PI) / 180.0f;
  const cv::Point leaf_px = r0.stem + 0.5f * r0.leaf_length * cv::Point2f(std::cos(a), std::sin(a));
  const cv::Scalar leaf = cv::mean(bgr(cv::Rect(leaf_px.x - 3, leaf_px.y - 3, 6, 6)));
  for (int c = 0; c < 3; ++c) {
    if (std::abs(leaf[c] - kLeaf[c]) > 12) {
      return "leaf colour BGR (" + std::to_string(std::lround(leaf[0])) + "," + std::to_string(std::lround(leaf[1])) +
             "," + std::to_string(std::lround(leaf[2])) + "), drawn (" + std::to_string(kLeaf[0]) + "," +
             std::to_string(kLeaf[1]) + "," + std::to_string(kLeaf[2]) + ")";
    }
  }
  stemd::vision::detect(stemd::vision::FrameView{bgr, {}, {}}, stemd::vision::Params{}, ws, det);
  if (det.status != stemd::vision::DetectStatus::ok)
    return "detect status " + std::string(stemd::vision::to_string(det.status));
  std::string found;
  for (const auto& p : det.plants) {
    if (p.has_stem)
      found += " (" + std::to_string(p.stem.x) + "," + std::to_string(p.stem.y) + ")";
  }
  for (const Rosette& r : kRosettes) {
    double best = 1e9;
    for (const auto& p : det.plants) {
      if (p.has_stem) best = std::min(best, static_cast<double>(cv::norm(p.stem - r.stem)));
    }
    if (best > kMaxStemErrorPx) {
      return "no stem within " + std::to_string(static_cast<int>(kMaxStemErrorPx)) + " px of (" + std::to_string(r.stem.x) + "," +
             std::to_string(r.stem.y) + "); nearest " + std::to_string(best) + " px; stems found:" + found;
    }
  }
  return {};
}

void selftest(V4l2PixelFormat format) {
  const cv::Mat scene = draw_scene();
  const std::size_t bpl = static_cast<std::size_t>(kVividWidth) * static_cast<std::size_t>(stemd::drivers::bytes_per_pixel(format));
  const auto bytes = encode(scene, format, bpl, bpl * kVividHeight);
  cv::Mat slot(kVividHeight, kVividWidth, CV_8UC3, cv::Scalar::all(0));
  if (stemd::drivers::convert_to_bgr(bytes.data(), bytes.size(), bpl, slot.size(), format, slot) !=
      stemd::drivers::ConvertStatus::ok)
    fail("convert_to_bgr failed");
  stemd::vision::Workspace ws(slot.size(), stemd::vision::Params{});
  stemd::vision::Detections det;
  if (const std::string why = judge(slot, ws, det); !why.empty()) fail("selftest: " + why);
  info("selftest " + std::string(stemd::drivers::to_string(format)) + ": scene converts and detects");
}

void loop(const std::string& cap_dev, const std::string& out_dev, V4l2PixelFormat format, const std::string& dump_dir) {
  // Routing and controls on the capture side; V4l2Source opens the node again.
  VividLoopback out(cap_dev, out_dev);
  const v4l2_pix_format pix =
      out.set_output_format(stemd::drivers::v4l2_fourcc_of(format), kVividWidth, kVividHeight);

  const cv::Mat scene = draw_scene();
  const auto image = encode(scene, format, pix.bytesperline, pix.sizeimage);
  out.start(image, 3);  // vivid holds one while it shows it

  // The project's source, as the daemon would build it.
  // Everything the loop needs exists before streaming starts, so that the
  // first frames do not wait in the queue while it is made.
  stemd::drivers::Frame slot;
  slot.bgr = cv::Mat(kVividHeight, kVividWidth, CV_8UC3, cv::Scalar::all(0));
  const std::uint8_t* const slot_data = slot.bgr.data;
  stemd::vision::Workspace ws(slot.bgr.size(), stemd::vision::Params{});
  stemd::vision::Detections det;
  auto log = spdlog::stdout_logger_mt("v4l2");
  stemd::drivers::V4l2Options options;
  options.device = cap_dev;
  options.pixel_format = format;
  options.size = {kVividWidth, kVividHeight};
  options.buffers = 4;
  options.fps = 60;
  stemd::drivers::V4l2Source source(options, log);
  // Every frame is captured after this and dequeued before its "now": in
  // CLOCK_MONOTONIC's domain, however slowly a loaded emulated guest runs.
  const std::int64_t t_before_start = monotonic_ns();
  if (!source.open() || !source.start()) fail("V4l2Source on " + cap_dev + " did not start");
  info(std::string(source.name()) + ": streaming with " + std::to_string(source.buffer_count()) + " buffers");

  int good_in_a_row = 0, frames = 0;
  std::int64_t last_t = 0;
  std::vector<std::int64_t> intervals_ns;
  std::string last_why;
  while (frames < kMaxFrames && good_in_a_row < kPassFrames) {
    out.pump();  // give back every output buffer vivid has finished with
    const auto status = source.next(slot, std::chrono::milliseconds(2000));
    if (status == stemd::drivers::NextStatus::timeout) fail(cap_dev + ": no frame within 2 s through V4l2Source");
    if (status != stemd::drivers::NextStatus::frame) fail(cap_dev + ": V4l2Source::next did not deliver a frame");
    const std::int64_t now = monotonic_ns();
    ++frames;
    if (slot.bgr.data != slot_data) fail("V4l2Source reallocated the caller's slot");
    if (slot.t_sample_ns <= last_t)
      fail("capture timestamps not increasing: " + std::to_string(slot.t_sample_ns) + " after " + std::to_string(last_t));
    if (last_t != 0) intervals_ns.push_back(slot.t_sample_ns - last_t);
    last_t = slot.t_sample_ns;
    const std::int64_t age = now - slot.t_sample_ns;
    if (slot.t_sample_ns < t_before_start || slot.t_sample_ns > now)
      fail("capture timestamp " + std::to_string(slot.t_sample_ns) + " is not between the start " +
           std::to_string(t_before_start) + " and CLOCK_MONOTONIC now " + std::to_string(now));
    last_why = judge(slot.bgr, ws, det);
    info("frame " + std::to_string(frames) + " seq=" + std::to_string(slot.source_seq) + " age=" +
         std::to_string(age / 1000) + " us: " + (last_why.empty() ? "good" : last_why));
    // The first frames may predate the first output frame; once the scene
    // has arrived, every frame must be good.
    if (last_why.empty()) ++good_in_a_row;
    else if (good_in_a_row > 0) break;
  }
  if (!intervals_ns.empty()) {
    std::nth_element(intervals_ns.begin(), intervals_ns.begin() + intervals_ns.size() / 2, intervals_ns.end());
    const std::int64_t median = intervals_ns[intervals_ns.size() / 2];
    if (median < kMinMedianFrameIntervalNs)
      fail("capture timestamps only " + std::to_string(median) + " ns apart (median over " +
           std::to_string(frames) + " frames; want >= " + std::to_string(kMinMedianFrameIntervalNs) +
           " ns: the unit is wrong)");
  }
  const auto c = source.counters();
  info("counters: frames=" + std::to_string(c.delivered) + " timeouts=" + std::to_string(c.timeouts) +
       " errors=" + std::to_string(c.errors) + " corrupt=" + std::to_string(c.corrupt) +
       " bad_size=" + std::to_string(c.bad_size));
  source.stop();
  out.stop();
  if (good_in_a_row < kPassFrames) {
    if (!dump_dir.empty()) {
      cv::imwrite(dump_dir + "/v4l2_source-sent.png", scene);
      cv::imwrite(dump_dir + "/v4l2_source-captured.png", slot.bgr);
      info("wrote " + dump_dir + "/v4l2_source-{sent,captured}.png");
    }
    fail("no " + std::to_string(kPassFrames) + " consecutive good frames in " + std::to_string(frames) +
         " (last: " + last_why + ")");
  }
  info(std::to_string(kPassFrames) + " consecutive " + std::string(stemd::drivers::to_string(format)) +
       " frames through V4l2Source: colours right, every stem within " + std::to_string(static_cast<int>(kMaxStemErrorPx)) +
       " px, timestamps monotonic, frame-spaced and fresh");
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  const bool ok_args = (mode == "loop" && argc >= 5) || (mode == "selftest" && argc >= 3);
  const auto format = ok_args ? stemd::drivers::parse_v4l2_pixel_format(argv[mode == "loop" ? 4 : 2]) : std::nullopt;
  if (!ok_args || !format || *format == V4l2PixelFormat::grey) {
    std::fprintf(stderr, "usage: %s loop CAPTURE OUTPUT yuyv|bgr24 [DUMP_DIR] | selftest yuyv|bgr24\n", argv[0]);
    return 2;
  }
  return stemd::vmprobe::run_probe("v4l2-source-check", [&] {
    if (mode == "selftest") selftest(*format);
    else loop(argv[2], argv[3], *format, argc > 5 ? argv[5] : "");
  });
}
