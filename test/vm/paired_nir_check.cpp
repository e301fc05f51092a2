// VM check of the paired RGB + NIR source (drivers/v4l2/paired_nir_source) on
// two vivid instances, each with its own HDMI output -> HDMI capture loopback.
//
//   stemd-vm-paired-nir-check loop RGB_CAP RGB_OUT NIR_CAP NIR_OUT [DUMP_DIR]
//       keeps writing a plant scene (green discs on brown soil, BGR24) to
//       RGB_OUT and its NIR counterpart (GREY: bright leaves, dark soil) to
//       NIR_OUT, captures pairs through stemd::drivers::PairedNirSource and
//       checks:
//       1. kPassPairs pairs (twice: at the start, then steady): bgr holds the RGB scene's colours, nir the NIR
//          scene's levels (so each plane came from its own device), |t_nir -
//          t_rgb| within the tolerance, timestamps increasing, the caller's
//          planes never reallocated;
//       2. vivid drops 50% of the NIR device's buffers ("Percentage of
//          Dropped Buffers"): unpaired_rgb grows, pairs stay right;
//       3. the same on the RGB device: unpaired_nir grows.
//       DUMP_DIR gets the last pair (PNG) on failure.
#include <linux/videodev2.h>
#include <time.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include "probe_util.hpp"
#include "vivid_loopback.hpp"
#include "v4l2/paired_nir_source.hpp"

namespace {

using namespace stemd::vmprobe;

constexpr int kPassPairs = 20;   // phase 1: good pairs needed
constexpr int kDropPairs = 30;   // phases 2, 3: pairs read while one side drops
constexpr int kMaxCalls = 600;   // next() calls per phase at most
// vivid runs 640x480p60 at 59.94 fps: frames 16.7 ms apart. The two
// instances' streams start independently, so their phases differ by up to a
// period; a tolerance just over half of it pairs every RGB frame with its
// nearest NIR frame.
constexpr std::int64_t kToleranceNs = 9'000'000;

const cv::Vec3b kSoil{45, 80, 125};  // BGR: brown
const cv::Vec3b kLeaf{40, 150, 60};  // BGR: green
constexpr int kNirSoil = 70;         // NIR: soil reflects little,
constexpr int kNirLeaf = 230;        // leaves a lot
const std::array<cv::Point, 2> kPlants{cv::Point{180, 200}, cv::Point{450, 300}};
constexpr int kPlantRadius = 40;
const cv::Rect kSoilPatch{8, 8, 24, 24};

cv::Mat draw_rgb() {
  cv::Mat bgr(kVividHeight, kVividWidth, CV_8UC3, cv::Scalar(kSoil[0], kSoil[1], kSoil[2]));
  for (const cv::Point& p : kPlants) cv::circle(bgr, p, kPlantRadius, cv::Scalar(kLeaf[0], kLeaf[1], kLeaf[2]), cv::FILLED);
  return bgr;
}

cv::Mat draw_nir() {
  cv::Mat grey(kVividHeight, kVividWidth, CV_8UC1, cv::Scalar(kNirSoil));
  for (const cv::Point& p : kPlants) cv::circle(grey, p, kPlantRadius, cv::Scalar(kNirLeaf), cv::FILLED);
  return grey;
}

cv::Rect around(cv::Point p) { return {p.x - 5, p.y - 5, 10, 10}; }

std::string bgr_text(const cv::Scalar& s) {
  return fmt::format("({},{},{})", std::lround(s[0]), std::lround(s[1]), std::lround(s[2]));
}

// Empty: both planes show their own device's scene; else why not.
std::string judge(const stemd::drivers::Frame& f) {
  const cv::Scalar soil = cv::mean(f.bgr(kSoilPatch));
  const cv::Scalar leaf = cv::mean(f.bgr(around(kPlants[0])));
  for (int c = 0; c < 3; ++c) {
    if (std::abs(soil[c] - kSoil[c]) > 12) return "bgr soil " + bgr_text(soil) + ", sent " + bgr_text(cv::Scalar(kSoil));
    if (std::abs(leaf[c] - kLeaf[c]) > 12) return "bgr leaf " + bgr_text(leaf) + ", sent " + bgr_text(cv::Scalar(kLeaf));
  }
  const double nir_soil = cv::mean(f.nir(kSoilPatch))[0];
  const double nir_leaf = cv::mean(f.nir(around(kPlants[1])))[0];
  if (std::abs(nir_soil - kNirSoil) > 12 || std::abs(nir_leaf - kNirLeaf) > 12)
    return "nir soil " + std::to_string(std::lround(nir_soil)) + " leaf " + std::to_string(std::lround(nir_leaf)) +
           ", sent " + std::to_string(kNirSoil) + " / " + std::to_string(kNirLeaf);
  return {};
}

// One vivid instance looping `image` (packed `fourcc`) from its HDMI output to
// its HDMI capture, with vivid's "Percentage of Dropped Buffers" at hand.
class Loopback {
 public:
  Loopback(const std::string& cap_dev, const std::string& out_dev, std::uint32_t fourcc, const cv::Mat& image)
      : cap_dev_(cap_dev), loop_(cap_dev, out_dev) {
    drop_ctrl_ = control_named(loop_.cap_fd(), cap_dev, "Percentage of Dropped Buffers");
    drop_percent(0);
    const v4l2_pix_format pix = loop_.set_output_format(fourcc, kVividWidth, kVividHeight);
    const std::size_t row = static_cast<std::size_t>(image.cols) * image.elemSize();
    if (pix.bytesperline < row || pix.sizeimage < pix.bytesperline * kVividHeight) fail(out_dev + ": unexpected stride");
    std::vector<std::uint8_t> bytes(pix.sizeimage, 0);
    for (int y = 0; y < kVividHeight; ++y)
      std::memcpy(bytes.data() + static_cast<std::size_t>(y) * pix.bytesperline, image.ptr(y), row);
    loop_.start(std::move(bytes), 6);  // vivid holds one while it shows it; several so a slow loop does not starve it
  }

  // Gives back every output buffer vivid has finished with.
  void pump() { loop_.pump(); }
  void drop_percent(int percent) {
    set_control(loop_.cap_fd(), cap_dev_, drop_ctrl_, percent, "VIDIOC_S_CTRL(Percentage of Dropped Buffers)");
  }

 private:
  std::string cap_dev_;
  VividLoopback loop_;
  std::uint32_t drop_ctrl_ = 0;
};

std::string counters_text(const stemd::drivers::PairedNirCounters& c) {
  return "delivered=" + std::to_string(c.delivered) + " unpaired_rgb=" + std::to_string(c.unpaired_rgb) +
         " unpaired_nir=" + std::to_string(c.unpaired_nir) + " forced=" + std::to_string(c.forced) +
         " out_of_order=" + std::to_string(c.out_of_order) + " bad_size=" + std::to_string(c.bad_size) +
         " rgb.delivered=" + std::to_string(c.rgb.delivered) + " nir.delivered=" + std::to_string(c.nir.delivered) +
         " rgb.corrupt=" + std::to_string(c.rgb.corrupt) + " nir.corrupt=" + std::to_string(c.nir.corrupt) +
         " last_offset=" + std::to_string(c.last_offset_ns / 1000) + " us";
}

void loop(const std::string& rgb_cap, const std::string& rgb_out, const std::string& nir_cap, const std::string& nir_out,
          const std::string& dump_dir) {
  const cv::Mat rgb_scene = draw_rgb();
  const cv::Mat nir_scene = draw_nir();
  Loopback rgb_loop(rgb_cap, rgb_out, V4L2_PIX_FMT_BGR24, rgb_scene);
  Loopback nir_loop(nir_cap, nir_out, V4L2_PIX_FMT_GREY, nir_scene);

  stemd::drivers::Frame slot;
  slot.bgr = cv::Mat(kVividHeight, kVividWidth, CV_8UC3, cv::Scalar::all(0));
  slot.nir = cv::Mat(kVividHeight, kVividWidth, CV_8UC1, cv::Scalar::all(0));
  const std::uint8_t* const bgr_data = slot.bgr.data;
  const std::uint8_t* const nir_data = slot.nir.data;
  auto log = spdlog::stdout_logger_mt("paired");
  stemd::drivers::PairedNirOptions options;
  options.rgb.device = rgb_cap;
  options.rgb.pixel_format = stemd::drivers::V4l2PixelFormat::bgr24;
  options.rgb.size = {kVividWidth, kVividHeight};
  options.rgb.fps = 60;
  options.nir.device = nir_cap;
  options.nir.fps = 60;
  options.tolerance = std::chrono::nanoseconds(kToleranceNs);
  stemd::drivers::PairedNirSource source(options, log);
  if (!source.open() || !source.start()) fail(std::string(source.name()) + " did not start");
  info(std::string(source.name()) + ": streaming, tolerance " + std::to_string(kToleranceNs / 1000) + " us");

  std::int64_t last_t = 0;
  std::int64_t min_offset = 0, max_offset = 0;  // t_nir - t_rgb of the pairs of a phase
  std::string last_why;
  auto fail_dump = [&](const std::string& why) {
    if (!dump_dir.empty()) {
      cv::imwrite(dump_dir + "/paired_nir-bgr.png", slot.bgr);
      cv::imwrite(dump_dir + "/paired_nir-nir.png", slot.nir);
      info("wrote " + dump_dir + "/paired_nir-{bgr,nir}.png");
    }
    fail(why + " [" + counters_text(source.paired_counters()) + "]");
  };
  // Reads pairs until `want` good ones (after the scene has arrived, every
  // pair must be good).
  auto read_pairs = [&](const char* phase, int want) {
    int good = 0, calls = 0;
    while (good < want) {
      if (++calls > kMaxCalls) fail_dump(std::string(phase) + ": only " + std::to_string(good) + " good pairs in " +
                                         std::to_string(kMaxCalls) + " calls (last: " + last_why + ")");
      rgb_loop.pump();
      nir_loop.pump();
      const auto status = source.next(slot, std::chrono::milliseconds(50));
      if (status == stemd::drivers::NextStatus::timeout || status == stemd::drivers::NextStatus::skipped) continue;
      if (status != stemd::drivers::NextStatus::frame) fail_dump(std::string(phase) + ": next() failed");
      if (slot.bgr.data != bgr_data || slot.nir.data != nir_data) fail_dump("the source reallocated the caller's planes");
      if (slot.t_sample_ns <= last_t) fail_dump("pair timestamps not increasing");
      last_t = slot.t_sample_ns;
      const auto c = source.paired_counters();
      if (std::llabs(c.last_offset_ns) > kToleranceNs)
        fail_dump("pair offset " + std::to_string(c.last_offset_ns) + " ns over the tolerance");
      min_offset = std::min(min_offset, c.last_offset_ns);
      max_offset = std::max(max_offset, c.last_offset_ns);
      last_why = judge(slot);
      if (!last_why.empty()) {
        if (good > 0 || std::string(phase) != "synchronous") fail_dump(std::string(phase) + ": bad pair: " + last_why);
        continue;  // the first frames may predate the first output frame
      }
      ++good;
    }
  };

  read_pairs("synchronous", kPassPairs);
  auto c0 = source.paired_counters();
  info("synchronous: " + std::to_string(kPassPairs) + " good pairs; " + counters_text(c0));
  // Streaming steadily (the start is behind): how well they pair here.
  min_offset = kToleranceNs, max_offset = -kToleranceNs;
  read_pairs("steady", kPassPairs);
  const auto cs = source.paired_counters();
  info(fmt::format("steady: {} pairs of {} RGB and {} NIR frames, offsets {:.2f}..{:.2f} ms; {}",
                   cs.delivered - c0.delivered, cs.rgb.delivered - c0.rgb.delivered, cs.nir.delivered - c0.nir.delivered,
                   static_cast<double>(min_offset) / 1e6, static_cast<double>(max_offset) / 1e6, counters_text(cs)));
  c0 = cs;

  // vivid drops half of one device's buffers while pairs are read.
  const auto dropping = [&](const std::string& side, Loopback& loop) {
    info("== vivid drops 50% of the " + side + " device's buffers");
    loop.drop_percent(50);
    read_pairs((side + " drops").c_str(), kDropPairs);
    loop.drop_percent(0);
    const auto c = source.paired_counters();
    info(side + " drops: " + counters_text(c));
    return c;
  };
  const auto c1 = dropping("NIR", nir_loop);
  if (c1.unpaired_rgb <= c0.unpaired_rgb) fail("NIR frames dropped, but unpaired_rgb did not grow");
  const auto c2 = dropping("RGB", rgb_loop);
  if (c2.unpaired_nir <= c1.unpaired_nir) fail("RGB frames dropped, but unpaired_nir did not grow");

  if (c2.bad_size != 0 || c2.rgb.errors != 0 || c2.nir.errors != 0) fail("errors: " + counters_text(c2));
  source.stop();
  info("pairs: bgr from " + rgb_cap + ", nir from " + nir_cap + ", within " + std::to_string(kToleranceNs / 1000) +
       " us; drops on either side counted as unpaired on the other");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 6 || std::string(argv[1]) != "loop") {
    std::fprintf(stderr, "usage: %s loop RGB_CAPTURE RGB_OUTPUT NIR_CAPTURE NIR_OUTPUT [DUMP_DIR]\n", argv[0]);
    return 2;
  }
  return stemd::vmprobe::run_probe("paired-nir-check",
                                   [&] { loop(argv[2], argv[3], argv[4], argv[5], argc > 6 ? argv[6] : ""); });
}
