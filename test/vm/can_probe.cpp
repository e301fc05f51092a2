// SocketCAN probe for the VM tests: raw CAN_RAW sockets on a (v)can interface.
//
//   stemd-vm-can-probe send IFACE ID#DATA
//       sends one frame (can-utils notation, e.g. 123#DEADBEEF; 8 hex digits of
//       id = extended frame) and checks the kernel took all of it.
//   stemd-vm-can-probe receive IFACE ID#DATA [TIMEOUT_MS] -- TRIGGER...
//       binds, then runs TRIGGER (e.g. cansend), then waits for a frame with
//       that id and checks its decoded id, length and payload.
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>

#include "probe_util.hpp"

namespace {

using stemd::vmprobe::fail;
using stemd::vmprobe::fail_errno;
using stemd::vmprobe::Fd;
using stemd::vmprobe::info;

std::uint32_t parse_hex(std::string_view text, const std::string& what) {
  if (text.empty()) fail("empty " + what);
  std::uint32_t value = 0;
  for (char c : text) {
    int digit = 0;
    if (c >= '0' && c <= '9') digit = c - '0';
    else if (c >= 'a' && c <= 'f') digit = c - 'a' + 10;
    else if (c >= 'A' && c <= 'F') digit = c - 'A' + 10;
    else fail("bad hex digit '" + std::string(1, c) + "' in " + what);
    value = value * 16 + static_cast<std::uint32_t>(digit);
  }
  return value;
}

can_frame parse_frame(std::string_view text) {
  const auto hash = text.find('#');
  if (hash == std::string_view::npos) fail("frame '" + std::string(text) + "' is not ID#DATA");
  const auto id_text = text.substr(0, hash);
  const auto data_text = text.substr(hash + 1);
  if (data_text.size() % 2 != 0 || data_text.size() > 2 * CAN_MAX_DLEN) {
    fail("frame data '" + std::string(data_text) + "' must be 0..8 whole bytes");
  }
  can_frame frame{};
  frame.can_id = parse_hex(id_text, "CAN id");
  if (id_text.size() == 8) frame.can_id |= CAN_EFF_FLAG;
  else if (id_text.size() != 3 || frame.can_id > CAN_SFF_MASK) fail("CAN id must be 3 or 8 hex digits");
  frame.len = static_cast<std::uint8_t>(data_text.size() / 2);
  for (std::size_t i = 0; i < frame.len; ++i) {
    frame.data[i] = static_cast<std::uint8_t>(parse_hex(data_text.substr(2 * i, 2), "CAN data"));
  }
  return frame;
}

std::string format_frame(const can_frame& frame) {
  const bool extended = (frame.can_id & CAN_EFF_FLAG) != 0;
  char buf[64];
  std::snprintf(buf, sizeof buf, extended ? "%08X#" : "%03X#",
                frame.can_id & (extended ? CAN_EFF_MASK : CAN_SFF_MASK));
  std::string text = buf;
  for (std::size_t i = 0; i < frame.len && i < CAN_MAX_DLEN; ++i) {
    std::snprintf(buf, sizeof buf, "%02X", frame.data[i]);
    text += buf;
  }
  return text;
}

Fd open_raw(const std::string& iface) {
  Fd sock(::socket(PF_CAN, SOCK_RAW, CAN_RAW));
  if (!sock.valid()) fail_errno(iface, "socket(PF_CAN, SOCK_RAW, CAN_RAW)");
  ifreq ifr{};
  if (iface.size() >= sizeof ifr.ifr_name) fail("interface name too long: " + iface);
  std::memcpy(ifr.ifr_name, iface.c_str(), iface.size() + 1);
  if (::ioctl(sock.get(), SIOCGIFINDEX, &ifr) < 0) fail_errno(iface, "SIOCGIFINDEX");
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifr.ifr_ifindex;
  if (::bind(sock.get(), reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) fail_errno(iface, "bind");
  return sock;
}

void send(const std::string& iface, const can_frame& frame) {
  Fd sock = open_raw(iface);
  const ssize_t n = ::write(sock.get(), &frame, sizeof frame);
  if (n < 0) fail_errno(iface, "write");
  if (n != static_cast<ssize_t>(sizeof frame)) fail("short write on " + iface + ": " + std::to_string(n) + " bytes");
  info("sent " + format_frame(frame) + " on " + iface);
}

void receive(const std::string& iface, const can_frame& want, int timeout_ms,
             const std::vector<std::string>& trigger) {
  Fd sock = open_raw(iface);
  // Only the frame we wait for: other traffic on the bus must not confuse the check.
  can_filter filter{};
  filter.can_id = want.can_id;
  filter.can_mask = CAN_EFF_FLAG | ((want.can_id & CAN_EFF_FLAG) ? CAN_EFF_MASK : CAN_SFF_MASK);
  if (::setsockopt(sock.get(), SOL_CAN_RAW, CAN_RAW_FILTER, &filter, sizeof filter) < 0) {
    fail_errno(iface, "setsockopt(CAN_RAW_FILTER)");
  }
  info("listening on " + iface + " for " + format_frame(want));
  if (!trigger.empty()) {
    const int status = stemd::vmprobe::run_command(trigger);
    if (status != 0) fail("trigger " + trigger[0] + " exited " + std::to_string(status));
  }
  pollfd pfd{sock.get(), POLLIN, 0};
  const int ready = ::poll(&pfd, 1, timeout_ms);
  if (ready < 0) fail_errno(iface, "poll");
  if (ready == 0) fail("no frame " + format_frame(want) + " on " + iface + " within " + std::to_string(timeout_ms) + " ms");
  can_frame got{};
  const ssize_t n = ::read(sock.get(), &got, sizeof got);
  if (n < 0) fail_errno(iface, "read");
  if (n != static_cast<ssize_t>(sizeof got)) fail("short read on " + iface + ": " + std::to_string(n) + " bytes");
  info("received " + format_frame(got) + " on " + iface);
  if (got.can_id != want.can_id) fail("id mismatch: got " + format_frame(got) + ", want " + format_frame(want));
  if (got.len != want.len || std::memcmp(got.data, want.data, want.len) != 0) {
    fail("payload mismatch: got " + format_frame(got) + ", want " + format_frame(want));
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (argc < 4 || (mode != "send" && mode != "receive")) {
    std::fprintf(stderr, "usage: %s send IFACE ID#DATA | receive IFACE ID#DATA [TIMEOUT_MS] -- TRIGGER...\n", argv[0]);
    return 2;
  }
  return stemd::vmprobe::run_probe("can-probe", [&] {
    const can_frame frame = parse_frame(argv[3]);
    if (mode == "send") {
      send(argv[2], frame);
    } else {
      const int timeout_ms = (argc > 4 && std::strcmp(argv[4], "--") != 0) ? std::atoi(argv[4]) : 3000;
      receive(argv[2], frame, timeout_ms, stemd::vmprobe::command_after_dashes(argc, argv));
    }
  });
}
