// V4L2 probe for the VM tests, against the vivid test driver.
//
//   stemd-vm-v4l2-probe capture DEVICE [FRAMES]
//       mmap-streams FRAMES (default 10) YUYV 640x480 frames from the webcam
//       input and checks sizes, increasing sequence numbers and that the
//       frames carry a picture (not one constant byte).
//   stemd-vm-v4l2-probe loopback CAPTURE OUTPUT [DUMP_DIR]
//       writes a known YUYV image to vivid's video output node and checks it
//       comes back on the capture node byte for byte (vivid loops its HDMI
//       output to its HDMI input). DUMP_DIR gets both images on mismatch.
#include <fcntl.h>
#include <linux/v4l2-dv-timings.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "probe_util.hpp"

namespace {

using stemd::vmprobe::fail;
using stemd::vmprobe::fail_errno;
using stemd::vmprobe::Fd;
using stemd::vmprobe::info;

// vivid's private controls (drivers/media/test-drivers/vivid/vivid-ctrls.c).
constexpr std::uint32_t kVividCidBase = 0x00f00000 | 0xf000;
constexpr std::uint32_t kVividOsdTextMode = kVividCidBase + 1;  // 2 = no text over the picture
constexpr std::uint32_t kVividLoopVideo = kVividCidBase + 37;   // 1 = output loops to capture

constexpr unsigned kWidth = 640;
constexpr unsigned kHeight = 480;

// ioctl that retries on EINTR and fails naming the device, request and errno.
void xioctl(int fd, unsigned long request, void* arg, const std::string& device, const char* name) {
  int r = 0;
  do r = ::ioctl(fd, request, arg);
  while (r < 0 && errno == EINTR);
  if (r < 0) fail_errno(device, name);
}
#define XIOCTL(fd, req, arg, dev) xioctl(fd, req, arg, dev, #req)

// One mmap'ed V4L2 buffer, unmapped on destruction.
class Mapping {
 public:
  Mapping(int fd, std::size_t length, off_t offset, const std::string& device) : length_(length) {
    data_ = ::mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, offset);
    if (data_ == MAP_FAILED) fail_errno(device, "mmap");
  }
  Mapping(const Mapping&) = delete;
  Mapping& operator=(const Mapping&) = delete;
  Mapping(Mapping&& other) noexcept : data_(other.data_), length_(other.length_) { other.data_ = MAP_FAILED; }
  Mapping& operator=(Mapping&&) = delete;
  ~Mapping() {
    if (data_ != MAP_FAILED) ::munmap(data_, length_);
  }
  [[nodiscard]] std::uint8_t* bytes() const { return static_cast<std::uint8_t*>(data_); }
  [[nodiscard]] std::size_t size() const { return length_; }

 private:
  void* data_ = MAP_FAILED;
  std::size_t length_;
};

Fd open_device(const std::string& device, int extra_flags = 0) {
  Fd fd(::open(device.c_str(), O_RDWR | O_CLOEXEC | extra_flags));
  if (!fd.valid()) fail_errno(device, "open");
  return fd;
}

void require_caps(int fd, const std::string& device, std::uint32_t caps, const char* what) {
  v4l2_capability cap{};
  XIOCTL(fd, VIDIOC_QUERYCAP, &cap, device);
  info(device + ": driver=" + reinterpret_cast<const char*>(cap.driver) +
       " card=" + reinterpret_cast<const char*>(cap.card));
  if ((cap.device_caps & caps) != caps) fail(device + " is not a " + what + " device with streaming");
}

v4l2_pix_format set_yuyv(int fd, const std::string& device, v4l2_buf_type type) {
  v4l2_format fmt{};
  fmt.type = type;
  fmt.fmt.pix.width = kWidth;
  fmt.fmt.pix.height = kHeight;
  fmt.fmt.pix.pixelformat = V4L2_PIX_FMT_YUYV;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  XIOCTL(fd, VIDIOC_S_FMT, &fmt, device);
  const auto& pix = fmt.fmt.pix;
  if (pix.width != kWidth || pix.height != kHeight || pix.pixelformat != V4L2_PIX_FMT_YUYV) {
    fail(device + ": driver changed the format to " + std::to_string(pix.width) + "x" + std::to_string(pix.height));
  }
  if (pix.sizeimage < pix.bytesperline * pix.height) fail(device + ": sizeimage smaller than the image");
  return pix;
}

std::vector<Mapping> request_buffers(int fd, const std::string& device, v4l2_buf_type type, unsigned count) {
  v4l2_requestbuffers req{};
  req.count = count;
  req.type = type;
  req.memory = V4L2_MEMORY_MMAP;
  XIOCTL(fd, VIDIOC_REQBUFS, &req, device);
  if (req.count < 2) fail(device + ": driver granted only " + std::to_string(req.count) + " buffers");
  std::vector<Mapping> maps;
  for (unsigned i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.type = type;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    XIOCTL(fd, VIDIOC_QUERYBUF, &buf, device);
    maps.emplace_back(fd, buf.length, buf.m.offset, device);
  }
  return maps;
}

void queue(int fd, const std::string& device, v4l2_buf_type type, unsigned index, std::uint32_t bytesused = 0) {
  v4l2_buffer buf{};
  buf.type = type;
  buf.memory = V4L2_MEMORY_MMAP;
  buf.index = index;
  buf.bytesused = bytesused;
  XIOCTL(fd, VIDIOC_QBUF, &buf, device);
}

// Waits up to timeout_ms for a filled capture buffer and dequeues it.
v4l2_buffer dequeue_capture(int fd, const std::string& device, int timeout_ms) {
  pollfd pfd{fd, POLLIN, 0};
  const int ready = ::poll(&pfd, 1, timeout_ms);
  if (ready < 0) fail_errno(device, "poll");
  if (ready == 0) fail(device + ": no frame within " + std::to_string(timeout_ms) + " ms");
  v4l2_buffer buf{};
  buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buf.memory = V4L2_MEMORY_MMAP;
  XIOCTL(fd, VIDIOC_DQBUF, &buf, device);
  return buf;
}

void stream(int fd, const std::string& device, v4l2_buf_type type, bool on) {
  int t = type;
  if (on) XIOCTL(fd, VIDIOC_STREAMON, &t, device);
  else XIOCTL(fd, VIDIOC_STREAMOFF, &t, device);
}

void capture(const std::string& device, int frames) {
  Fd fd = open_device(device);
  require_caps(fd.get(), device, V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING, "capture");
  int input = 0;  // vivid's input 0 is its webcam: a moving test pattern
  XIOCTL(fd.get(), VIDIOC_S_INPUT, &input, device);
  const auto pix = set_yuyv(fd.get(), device, V4L2_BUF_TYPE_VIDEO_CAPTURE);
  auto maps = request_buffers(fd.get(), device, V4L2_BUF_TYPE_VIDEO_CAPTURE, 4);
  for (unsigned i = 0; i < maps.size(); ++i) queue(fd.get(), device, V4L2_BUF_TYPE_VIDEO_CAPTURE, i);
  stream(fd.get(), device, V4L2_BUF_TYPE_VIDEO_CAPTURE, true);
  long last_sequence = -1;
  for (int n = 0; n < frames; ++n) {
    const v4l2_buffer buf = dequeue_capture(fd.get(), device, 5000);
    if (buf.index >= maps.size()) fail(device + ": dequeued unknown buffer " + std::to_string(buf.index));
    if (buf.bytesused != pix.sizeimage) {
      fail(device + ": frame of " + std::to_string(buf.bytesused) + " bytes, want " + std::to_string(pix.sizeimage));
    }
    if (static_cast<long>(buf.sequence) <= last_sequence) fail(device + ": sequence did not increase");
    last_sequence = buf.sequence;
    const std::uint8_t* p = maps[buf.index].bytes();
    std::size_t differing = 0;
    for (std::size_t i = 1; i < buf.bytesused; ++i) differing += p[i] != p[0];
    if (differing == 0) fail(device + ": frame " + std::to_string(n) + " is one constant byte");
    info("frame " + std::to_string(n) + " seq=" + std::to_string(buf.sequence) + " bytes=" + std::to_string(buf.bytesused));
    queue(fd.get(), device, V4L2_BUF_TYPE_VIDEO_CAPTURE, buf.index);
  }
  stream(fd.get(), device, V4L2_BUF_TYPE_VIDEO_CAPTURE, false);
  info("captured " + std::to_string(frames) + " frames " + std::to_string(pix.width) + "x" +
       std::to_string(pix.height) + " YUYV from " + device);
}

int find_named(int fd, const std::string& device, bool output, const std::string& name) {
  for (unsigned i = 0; i < 64; ++i) {
    if (output) {
      v4l2_output o{};
      o.index = i;
      if (::ioctl(fd, VIDIOC_ENUMOUTPUT, &o) < 0) break;
      if (name == reinterpret_cast<const char*>(o.name)) return static_cast<int>(i);
    } else {
      v4l2_input in{};
      in.index = i;
      if (::ioctl(fd, VIDIOC_ENUMINPUT, &in) < 0) break;
      if (name == reinterpret_cast<const char*>(in.name)) return static_cast<int>(i);
    }
  }
  fail(device + ": no " + (output ? "output" : "input") + " named '" + name + "'");
}

void set_control(int fd, const std::string& device, std::uint32_t id, int value, const char* name) {
  v4l2_control ctrl{};
  ctrl.id = id;
  ctrl.value = value;
  xioctl(fd, VIDIOC_S_CTRL, &ctrl, device, name);
}

// The known image: a soil-and-stem scene with deterministic noise, every byte
// inside the video range (Y 16..235, Cb/Cr 16..240) so that no range clamping
// anywhere could pass unnoticed or be blamed.
std::vector<std::uint8_t> known_image(const v4l2_pix_format& pix) {
  std::vector<std::uint8_t> img(pix.sizeimage, 0);
  std::uint32_t state = 0x5eed1234;
  auto noise = [&state] {
    state = state * 1664525u + 1013904223u;
    return static_cast<int>((state >> 24) % 16);
  };
  for (unsigned y = 0; y < pix.height; ++y) {
    for (unsigned x = 0; x < pix.width; x += 2) {
      std::uint8_t* q = img.data() + y * pix.bytesperline + x * 2;
      const bool stem = x > pix.width / 2 - 10 && x < pix.width / 2 + 10 && y > pix.height / 4;
      q[0] = static_cast<std::uint8_t>((stem ? 130 : 60) + noise() + (x * 40) / pix.width);
      q[1] = static_cast<std::uint8_t>((stem ? 70 : 110) + noise());
      q[2] = static_cast<std::uint8_t>((stem ? 130 : 60) + noise() + (y * 40) / pix.height);
      q[3] = static_cast<std::uint8_t>((stem ? 80 : 150) + noise());
    }
  }
  return img;
}

void dump(const std::string& dir, const std::string& name, const std::uint8_t* data, std::size_t size) {
  if (dir.empty()) return;
  std::ofstream(dir + "/" + name, std::ios::binary).write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  info("wrote " + dir + "/" + name);
}

void loopback(const std::string& cap_dev, const std::string& out_dev, const std::string& dump_dir) {
  Fd cap = open_device(cap_dev);
  Fd out = open_device(out_dev, O_NONBLOCK);  // output buffers are reclaimed without waiting
  require_caps(cap.get(), cap_dev, V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING, "capture");
  require_caps(out.get(), out_dev, V4L2_CAP_VIDEO_OUTPUT | V4L2_CAP_STREAMING, "output");

  // vivid loops output to capture only HDMI to HDMI (or S-Video), with equal
  // DV timings, format and field on both sides.
  int input = find_named(cap.get(), cap_dev, false, "HDMI 0");
  int output = find_named(out.get(), out_dev, true, "HDMI 0");
  XIOCTL(cap.get(), VIDIOC_S_INPUT, &input, cap_dev);
  XIOCTL(out.get(), VIDIOC_S_OUTPUT, &output, out_dev);
  v4l2_dv_timings timings = V4L2_DV_BT_DMT_640X480P60;
  XIOCTL(cap.get(), VIDIOC_S_DV_TIMINGS, &timings, cap_dev);
  timings = V4L2_DV_BT_DMT_640X480P60;
  XIOCTL(out.get(), VIDIOC_S_DV_TIMINGS, &timings, out_dev);
  set_control(cap.get(), cap_dev, kVividLoopVideo, 1, "VIDIOC_S_CTRL(loop_video=1)");
  set_control(cap.get(), cap_dev, kVividOsdTextMode, 2, "VIDIOC_S_CTRL(osd_text_mode=2)");

  const auto cap_pix = set_yuyv(cap.get(), cap_dev, V4L2_BUF_TYPE_VIDEO_CAPTURE);
  const auto out_pix = set_yuyv(out.get(), out_dev, V4L2_BUF_TYPE_VIDEO_OUTPUT);
  if (cap_pix.bytesperline != out_pix.bytesperline || cap_pix.sizeimage != out_pix.sizeimage) {
    fail("capture and output layouts differ (bytesperline " + std::to_string(cap_pix.bytesperline) + " vs " +
         std::to_string(out_pix.bytesperline) + ")");
  }
  const auto image = known_image(out_pix);

  // At least two output buffers: vivid holds one while it shows it.
  auto out_maps = request_buffers(out.get(), out_dev, V4L2_BUF_TYPE_VIDEO_OUTPUT, 3);
  for (unsigned i = 0; i < out_maps.size(); ++i) {
    if (out_maps[i].size() < image.size()) fail(out_dev + ": output buffer smaller than the image");
    std::memcpy(out_maps[i].bytes(), image.data(), image.size());
    queue(out.get(), out_dev, V4L2_BUF_TYPE_VIDEO_OUTPUT, i, static_cast<std::uint32_t>(image.size()));
  }
  stream(out.get(), out_dev, V4L2_BUF_TYPE_VIDEO_OUTPUT, true);

  auto cap_maps = request_buffers(cap.get(), cap_dev, V4L2_BUF_TYPE_VIDEO_CAPTURE, 4);
  for (unsigned i = 0; i < cap_maps.size(); ++i) queue(cap.get(), cap_dev, V4L2_BUF_TYPE_VIDEO_CAPTURE, i);
  stream(cap.get(), cap_dev, V4L2_BUF_TYPE_VIDEO_CAPTURE, true);

  // The first captured frames may predate the first output frame; keep
  // feeding the output and take the first frame that arrives after it.
  constexpr int kMaxFrames = 30;
  std::size_t best_differing = image.size();
  std::vector<std::uint8_t> best_frame;
  for (int n = 0; n < kMaxFrames; ++n) {
    for (;;) {  // re-queue every output buffer vivid has finished with
      v4l2_buffer done{};
      done.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      done.memory = V4L2_MEMORY_MMAP;
      if (::ioctl(out.get(), VIDIOC_DQBUF, &done) < 0) {
        if (errno == EAGAIN) break;
        fail_errno(out_dev, "VIDIOC_DQBUF");
      }
      queue(out.get(), out_dev, V4L2_BUF_TYPE_VIDEO_OUTPUT, done.index, static_cast<std::uint32_t>(image.size()));
    }
    const v4l2_buffer buf = dequeue_capture(cap.get(), cap_dev, 5000);
    if (buf.index >= cap_maps.size()) fail(cap_dev + ": dequeued unknown buffer " + std::to_string(buf.index));
    const std::uint8_t* p = cap_maps[buf.index].bytes();
    std::size_t differing = 0;
    if (buf.bytesused != image.size()) differing = image.size();
    else
      for (std::size_t i = 0; i < image.size(); ++i) differing += p[i] != image[i];
    info("frame " + std::to_string(n) + " seq=" + std::to_string(buf.sequence) + " bytes=" +
         std::to_string(buf.bytesused) + " differing=" + std::to_string(differing));
    if (differing < best_differing) {
      best_differing = differing;
      best_frame.assign(p, p + buf.bytesused);
    }
    queue(cap.get(), cap_dev, V4L2_BUF_TYPE_VIDEO_CAPTURE, buf.index);
    if (differing == 0) break;
  }
  stream(cap.get(), cap_dev, V4L2_BUF_TYPE_VIDEO_CAPTURE, false);
  stream(out.get(), out_dev, V4L2_BUF_TYPE_VIDEO_OUTPUT, false);
  if (best_differing != 0) {
    dump(dump_dir, "loopback-sent.yuyv", image.data(), image.size());
    dump(dump_dir, "loopback-best.yuyv", best_frame.data(), best_frame.size());
    fail("no frame in " + std::to_string(kMaxFrames) + " came back byte for byte from " + out_dev + " on " + cap_dev +
         " (best: " + std::to_string(best_differing) + " of " + std::to_string(image.size()) + " bytes differ)");
  }
  info("known " + std::to_string(image.size()) + "-byte image came back byte for byte: " + out_dev + " -> " + cap_dev);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (!((mode == "capture" && argc >= 3) || (mode == "loopback" && argc >= 4))) {
    std::fprintf(stderr, "usage: %s capture DEVICE [FRAMES] | loopback CAPTURE OUTPUT [DUMP_DIR]\n", argv[0]);
    return 2;
  }
  return stemd::vmprobe::run_probe("v4l2-probe", [&] {
    if (mode == "capture") capture(argv[2], argc > 3 ? std::atoi(argv[3]) : 10);
    else loopback(argv[2], argv[3], argc > 4 ? argv[4] : "");
  });
}
