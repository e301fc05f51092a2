// vivid's video output -> video capture loopback, shared by the VM checks
// (v4l2_probe.cpp, v4l2_source_check.cpp, paired_nir_check.cpp, the daemon's
// frame feeder). Failures throw vmprobe::ProbeError naming the device, the
// request and errno (probe_util.hpp).
//
// vivid loops output to capture only HDMI to HDMI (or S-Video), with equal DV
// timings, format and field on both sides, loop_video = 1, osd_text_mode = 2
// (no text over the picture) and at least two output buffers (vivid holds one
// while it shows it).
//
//   VividLoopback loop(cap_dev, out_dev);      // opens both, routes, controls
//   auto pix = loop.set_output_format(fourcc, 640, 480);
//   loop.start(image, 3);                      // fills and queues, STREAMON
//   for (;;) { loop.show(next_image); loop.pump(); ... }   // show() optional
#pragma once

#include <fcntl.h>
#include <linux/v4l2-dv-timings.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "probe_util.hpp"

namespace stemd::vmprobe {

// vivid's private controls (drivers/media/test-drivers/vivid/vivid-ctrls.c).
inline constexpr std::uint32_t kVividCidBase = 0x00f00000 | 0xf000;
inline constexpr std::uint32_t kVividOsdTextMode = kVividCidBase + 1;  // 2 = no text over the picture
inline constexpr std::uint32_t kVividLoopVideo = kVividCidBase + 37;   // 1 = output loops to capture

// ioctl that retries on EINTR and fails naming the device, request and errno.
inline void xioctl(int fd, unsigned long request, void* arg, const std::string& device, const char* name) {
  int r = 0;
  do r = ::ioctl(fd, request, arg);
  while (r < 0 && errno == EINTR);
  if (r < 0) fail_errno(device, name);
}
#define XIOCTL(fd, req, arg, dev) ::stemd::vmprobe::xioctl(fd, req, arg, dev, #req)

// Opens a V4L2 node read-write (close-on-exec, plus extra_flags).
inline Fd open_device(const std::string& device, int extra_flags = 0) {
  Fd fd(::open(device.c_str(), O_RDWR | O_CLOEXEC | extra_flags));
  if (!fd.valid()) fail_errno(device, "open");
  return fd;
}

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

// The index of the input (or output) called `name`.
inline int find_named(int fd, const std::string& device, bool output, const std::string& name) {
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

inline void set_control(int fd, const std::string& device, std::uint32_t id, int value, const char* name) {
  v4l2_control ctrl{};
  ctrl.id = id;
  ctrl.value = value;
  xioctl(fd, VIDIOC_S_CTRL, &ctrl, device, name);
}

// A control's id by its name (vivid's test controls have no uapi ids).
inline std::uint32_t control_named(int fd, const std::string& device, const std::string& name) {
  v4l2_queryctrl q{};
  q.id = V4L2_CTRL_FLAG_NEXT_CTRL;
  while (::ioctl(fd, VIDIOC_QUERYCTRL, &q) == 0) {
    if (name == reinterpret_cast<const char*>(q.name)) return q.id;
    q.id |= V4L2_CTRL_FLAG_NEXT_CTRL;
  }
  fail(device + ": no control named '" + name + "'");
}

// Sets a packed single-plane format, progressive; fails unless the driver
// takes it as asked.
inline v4l2_pix_format set_format(int fd, const std::string& device, v4l2_buf_type type, std::uint32_t fourcc,
                                  unsigned width, unsigned height) {
  v4l2_format fmt{};
  fmt.type = type;
  fmt.fmt.pix.width = width;
  fmt.fmt.pix.height = height;
  fmt.fmt.pix.pixelformat = fourcc;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  XIOCTL(fd, VIDIOC_S_FMT, &fmt, device);
  const v4l2_pix_format pix = fmt.fmt.pix;
  if (pix.width != width || pix.height != height || pix.pixelformat != fourcc) {
    fail(device + ": the driver does not take this format at " + std::to_string(width) + "x" + std::to_string(height) +
         " (it set " + std::to_string(pix.width) + "x" + std::to_string(pix.height) + ")");
  }
  if (pix.sizeimage < pix.bytesperline * pix.height) fail(device + ": sizeimage smaller than the image");
  return pix;
}

// The frame size of the loopback's timings (V4L2_DV_BT_DMT_640X480P60).
constexpr int kVividWidth = 640;
constexpr int kVividHeight = 480;

// One vivid instance set up to loop its HDMI output to its HDMI capture at
// 640x480p60; owns both fds and the output buffers, stops the output stream
// on destruction. The capture side is only routed: whoever captures (a probe,
// V4l2Source, the daemon) opens, formats and streams it.
class VividLoopback {
 public:
  VividLoopback(std::string cap_dev, std::string out_dev)
      : cap_dev_(std::move(cap_dev)), out_dev_(std::move(out_dev)) {
    cap_ = open_device(cap_dev_);
    out_ = open_device(out_dev_, O_NONBLOCK);  // output buffers are reclaimed without waiting
    int input = find_named(cap_.get(), cap_dev_, false, "HDMI 0");
    int output = find_named(out_.get(), out_dev_, true, "HDMI 0");
    XIOCTL(cap_.get(), VIDIOC_S_INPUT, &input, cap_dev_);
    XIOCTL(out_.get(), VIDIOC_S_OUTPUT, &output, out_dev_);
    v4l2_dv_timings timings = V4L2_DV_BT_DMT_640X480P60;
    XIOCTL(cap_.get(), VIDIOC_S_DV_TIMINGS, &timings, cap_dev_);
    timings = V4L2_DV_BT_DMT_640X480P60;
    XIOCTL(out_.get(), VIDIOC_S_DV_TIMINGS, &timings, out_dev_);
    set_control(cap_.get(), cap_dev_, kVividLoopVideo, 1, "VIDIOC_S_CTRL(loop_video=1)");
    set_control(cap_.get(), cap_dev_, kVividOsdTextMode, 2, "VIDIOC_S_CTRL(osd_text_mode=2)");
  }
  VividLoopback(const VividLoopback&) = delete;
  VividLoopback& operator=(const VividLoopback&) = delete;
  ~VividLoopback() {
    if (streaming_) {
      int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      ::ioctl(out_.get(), VIDIOC_STREAMOFF, &type);
    }
  }

  // Sets the output format; fails unless the driver takes it as asked.
  v4l2_pix_format set_output_format(std::uint32_t fourcc, unsigned width, unsigned height) {
    pix_ = set_format(out_.get(), out_dev_, V4L2_BUF_TYPE_VIDEO_OUTPUT, fourcc, width, height);
    return pix_;
  }

  // Asks for `buffers` mmap output buffers (at least 2 granted), writes
  // `image` (laid out as set_output_format's pix) into each, queues them all
  // and starts the output stream.
  void start(std::vector<std::uint8_t> image, unsigned buffers) {
    image_ = std::move(image);
    v4l2_requestbuffers req{};
    req.count = buffers;
    req.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    req.memory = V4L2_MEMORY_MMAP;
    XIOCTL(out_.get(), VIDIOC_REQBUFS, &req, out_dev_);
    if (req.count < 2) fail(out_dev_ + ": driver granted only " + std::to_string(req.count) + " output buffers");
    for (unsigned i = 0; i < req.count; ++i) {
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      buf.memory = V4L2_MEMORY_MMAP;
      buf.index = i;
      XIOCTL(out_.get(), VIDIOC_QUERYBUF, &buf, out_dev_);
      maps_.emplace_back(out_.get(), buf.length, buf.m.offset, out_dev_);
      shown_.push_back(0);
      if (maps_.back().size() < image_.size()) fail(out_dev_ + ": output buffer smaller than the image");
      queue(i);
    }
    int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    XIOCTL(out_.get(), VIDIOC_STREAMON, &type, out_dev_);
    streaming_ = true;
  }

  // The image for the buffers queued from now on (same size as start's).
  void show(std::vector<std::uint8_t> image) {
    if (image.size() != image_.size()) fail(out_dev_ + ": show() with an image of another size");
    image_ = std::move(image);
    ++generation_;
  }

  // Gives back every output buffer vivid has finished with; returns how many.
  unsigned pump() {
    unsigned n = 0;
    for (;;) {
      v4l2_buffer done{};
      done.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      done.memory = V4L2_MEMORY_MMAP;
      if (::ioctl(out_.get(), VIDIOC_DQBUF, &done) < 0) {
        if (errno == EAGAIN) return n;
        if (errno == EINTR) continue;
        fail_errno(out_dev_, "VIDIOC_DQBUF");
      }
      queue(done.index);
      ++n;
    }
  }

  // Stops the output stream (failing on error, unlike the destructor).
  void stop() {
    int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    XIOCTL(out_.get(), VIDIOC_STREAMOFF, &type, out_dev_);
    streaming_ = false;
  }

  [[nodiscard]] int cap_fd() const { return cap_.get(); }
  [[nodiscard]] int out_fd() const { return out_.get(); }
  [[nodiscard]] const v4l2_pix_format& output_pix() const { return pix_; }

 private:
  void queue(unsigned index) {
    if (shown_[index] != generation_ + 1) {  // copy only when the image changed
      std::memcpy(maps_[index].bytes(), image_.data(), image_.size());
      shown_[index] = generation_ + 1;
    }
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = index;
    buf.bytesused = static_cast<std::uint32_t>(image_.size());
    XIOCTL(out_.get(), VIDIOC_QBUF, &buf, out_dev_);
  }

  std::string cap_dev_, out_dev_;
  Fd cap_, out_;
  v4l2_pix_format pix_{};
  std::vector<std::uint8_t> image_;
  std::vector<Mapping> maps_;
  std::vector<std::uint64_t> shown_;  // generation + 1 of the image in each buffer (0: none)
  std::uint64_t generation_ = 0;
  bool streaming_ = false;
};

}  // namespace stemd::vmprobe
