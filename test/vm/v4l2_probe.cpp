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
#include "vivid_loopback.hpp"

namespace {

using namespace stemd::vmprobe;

void require_caps(int fd, const std::string& device, std::uint32_t caps, const char* what) {
  v4l2_capability cap{};
  XIOCTL(fd, VIDIOC_QUERYCAP, &cap, device);
  info(device + ": driver=" + reinterpret_cast<const char*>(cap.driver) +
       " card=" + reinterpret_cast<const char*>(cap.card));
  if ((cap.device_caps & caps) != caps) fail(device + " is not a " + what + " device with streaming");
}

v4l2_pix_format set_yuyv(int fd, const std::string& device, v4l2_buf_type type) {
  return set_format(fd, device, type, V4L2_PIX_FMT_YUYV, kVividWidth, kVividHeight);
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
  VividLoopback loop(cap_dev, out_dev);
  const int cap = loop.cap_fd();
  require_caps(cap, cap_dev, V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING, "capture");
  require_caps(loop.out_fd(), out_dev, V4L2_CAP_VIDEO_OUTPUT | V4L2_CAP_STREAMING, "output");

  const auto cap_pix = set_yuyv(cap, cap_dev, V4L2_BUF_TYPE_VIDEO_CAPTURE);
  const auto out_pix = loop.set_output_format(V4L2_PIX_FMT_YUYV, kVividWidth, kVividHeight);
  if (cap_pix.bytesperline != out_pix.bytesperline || cap_pix.sizeimage != out_pix.sizeimage) {
    fail("capture and output layouts differ (bytesperline " + std::to_string(cap_pix.bytesperline) + " vs " +
         std::to_string(out_pix.bytesperline) + ")");
  }
  const auto image = known_image(out_pix);

  loop.start(image, 3);  // at least two output buffers: vivid holds one while it shows it

  auto cap_maps = request_buffers(cap, cap_dev, V4L2_BUF_TYPE_VIDEO_CAPTURE, 4);
  for (unsigned i = 0; i < cap_maps.size(); ++i) queue(cap, cap_dev, V4L2_BUF_TYPE_VIDEO_CAPTURE, i);
  stream(cap, cap_dev, V4L2_BUF_TYPE_VIDEO_CAPTURE, true);

  // The first captured frames may predate the first output frame; keep
  // feeding the output and take the first frame that arrives after it.
  constexpr int kMaxFrames = 30;
  std::size_t best_differing = image.size();
  std::vector<std::uint8_t> best_frame;
  for (int n = 0; n < kMaxFrames; ++n) {
    loop.pump();  // re-queue every output buffer vivid has finished with
    const v4l2_buffer buf = dequeue_capture(cap, cap_dev, 5000);
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
    queue(cap, cap_dev, V4L2_BUF_TYPE_VIDEO_CAPTURE, buf.index);
    if (differing == 0) break;
  }
  stream(cap, cap_dev, V4L2_BUF_TYPE_VIDEO_CAPTURE, false);
  loop.stop();
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
