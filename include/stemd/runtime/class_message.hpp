// The external class provider's messages (classify.provider: socket), one
// per SOCK_SEQPACKET packet, little-endian, every one starting with the
// same 8-byte header:
//
//   offset size  field
//   0      4     magic "STCM" (0x53 0x54 0x43 0x4d)
//   4      2     version (kClassMessageVersion)
//   6      2     type (ClassMessageType)
//
// frame (stemd -> peer, 40 bytes + name), one per captured frame:
//   8      8     t_capture_ns  int64, CLOCK_MONOTONIC of the exposure (the
//                              frame's sensor timestamp; a replay: when the
//                              frame was handed over)
//   16     8     seq           uint64, frames captured before this one
//   24     4     width         uint32, the frame's size in pixels
//   28     4     height        uint32
//   32     2     name_size     uint16, bytes of name below (<= 255)
//   34     6     reserved, zero
//   40     name  the frame's name (replay: its rgb path as in frames.csv;
//                a camera: empty), not terminated
//
// class map (peer -> stemd, 24 bytes + width * height):
//   8      8     t_capture_ns  int64, of the frame it classes (as sent)
//   16     4     width         uint32, the map's size: at most the frame's,
//   20     4     height        uint32  scaled to it on each axis
//   24     w*h   one byte per pixel, row-major: 0 soil, 1 crop, 2 weed
//                (anything else makes that pixel no class)
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

namespace stemd::runtime {

inline constexpr std::uint8_t kClassMessageMagic[4] = {'S', 'T', 'C', 'M'};
inline constexpr std::uint16_t kClassMessageVersion = 1;
inline constexpr std::size_t kFrameMessageHeaderBytes = 40;
inline constexpr std::size_t kFrameMessageMaxName = 255;
inline constexpr std::size_t kClassMapHeaderBytes = 24;

enum class ClassMessageType : std::uint16_t {
    frame = 1,
    class_map = 2,
};

enum class ClassMessageError : std::uint8_t {
    ok,
    too_short,      // shorter than its header
    bad_magic,
    bad_version,
    bad_type,       // not the type expected here
    bad_size,       // a zero dimension, or the length is not header + width * height
    too_large,      // larger than the frame
};
std::string_view to_string(ClassMessageError error);

struct FrameMessage {
    std::int64_t t_capture_ns = 0;
    std::uint64_t seq = 0;
    std::uint32_t width = 0, height = 0;
    std::string_view name;   // into the parsed buffer
};

struct ClassMapMessage {
    std::int64_t t_capture_ns = 0;
    std::uint32_t width = 0, height = 0;
    const std::uint8_t* classes = nullptr;   // into the parsed buffer, width * height bytes
};

// Writes a frame message into `out` (at least kFrameMessageHeaderBytes +
// kFrameMessageMaxName bytes; a longer name is cut); returns its length.
std::size_t encode_frame_message(const FrameMessage& message, std::span<std::uint8_t> out) noexcept;
// Writes a class map message's header into `out` (kClassMapHeaderBytes);
// the caller appends width * height class bytes.
void encode_class_map_header(std::int64_t t_capture_ns, std::uint32_t width, std::uint32_t height,
                             std::span<std::uint8_t, kClassMapHeaderBytes> out) noexcept;

// Parse one packet; nothing is copied (the views point into `packet`).
ClassMessageError parse_frame_message(std::span<const std::uint8_t> packet, FrameMessage& out) noexcept;
// A class map larger than max_width x max_height is refused (too_large).
ClassMessageError parse_class_map_message(std::span<const std::uint8_t> packet, std::uint32_t max_width,
                                          std::uint32_t max_height, ClassMapMessage& out) noexcept;

}  // namespace stemd::runtime
