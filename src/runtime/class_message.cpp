#include "stemd/runtime/class_message.hpp"

#include <algorithm>
#include <cstring>

namespace stemd::runtime {

namespace {

// Explicit little-endian, whatever the host's order.
void put(std::uint8_t* p, std::uint64_t v, int bytes)
{
    for (int i = 0; i < bytes; ++i)
        p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

std::uint64_t get(const std::uint8_t* p, int bytes)
{
    std::uint64_t v = 0;
    for (int i = 0; i < bytes; ++i)
        v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
    return v;
}

void put_header(std::uint8_t* p, ClassMessageType type)
{
    std::memcpy(p, kClassMessageMagic, 4);
    put(p + 4, kClassMessageVersion, 2);
    put(p + 6, static_cast<std::uint16_t>(type), 2);
}

ClassMessageError check_header(std::span<const std::uint8_t> packet, std::size_t header_bytes, ClassMessageType type)
{
    if (packet.size() < header_bytes)
        return ClassMessageError::too_short;
    if (std::memcmp(packet.data(), kClassMessageMagic, 4) != 0)
        return ClassMessageError::bad_magic;
    if (get(packet.data() + 4, 2) != kClassMessageVersion)
        return ClassMessageError::bad_version;
    if (get(packet.data() + 6, 2) != static_cast<std::uint16_t>(type))
        return ClassMessageError::bad_type;
    return ClassMessageError::ok;
}

}  // namespace

std::string_view to_string(ClassMessageError error)
{
    switch (error) {
    case ClassMessageError::ok: return "ok";
    case ClassMessageError::too_short: return "shorter than its header";
    case ClassMessageError::bad_magic: return "bad magic";
    case ClassMessageError::bad_version: return "unknown version";
    case ClassMessageError::bad_type: return "unexpected type";
    case ClassMessageError::bad_size: return "length does not match its size";
    case ClassMessageError::too_large: return "larger than the frame";
    }
    return "?";
}

std::size_t encode_frame_message(const FrameMessage& message, std::span<std::uint8_t> out) noexcept
{
    const std::size_t name_size =
        std::min({message.name.size(), kFrameMessageMaxName, out.size() - kFrameMessageHeaderBytes});
    std::uint8_t* p = out.data();
    std::memset(p, 0, kFrameMessageHeaderBytes);
    put_header(p, ClassMessageType::frame);
    put(p + 8, static_cast<std::uint64_t>(message.t_capture_ns), 8);
    put(p + 16, message.seq, 8);
    put(p + 24, message.width, 4);
    put(p + 28, message.height, 4);
    put(p + 32, name_size, 2);
    std::memcpy(p + kFrameMessageHeaderBytes, message.name.data(), name_size);
    return kFrameMessageHeaderBytes + name_size;
}

void encode_class_map_header(std::int64_t t_capture_ns, std::uint32_t width, std::uint32_t height,
                             std::span<std::uint8_t, kClassMapHeaderBytes> out) noexcept
{
    std::uint8_t* p = out.data();
    put_header(p, ClassMessageType::class_map);
    put(p + 8, static_cast<std::uint64_t>(t_capture_ns), 8);
    put(p + 16, width, 4);
    put(p + 20, height, 4);
}

ClassMessageError parse_frame_message(std::span<const std::uint8_t> packet, FrameMessage& out) noexcept
{
    if (const auto e = check_header(packet, kFrameMessageHeaderBytes, ClassMessageType::frame);
        e != ClassMessageError::ok)
        return e;
    const std::uint8_t* p = packet.data();
    const std::size_t name_size = get(p + 32, 2);
    if (name_size > kFrameMessageMaxName || packet.size() != kFrameMessageHeaderBytes + name_size)
        return ClassMessageError::bad_size;
    out.t_capture_ns = static_cast<std::int64_t>(get(p + 8, 8));
    out.seq = get(p + 16, 8);
    out.width = static_cast<std::uint32_t>(get(p + 24, 4));
    out.height = static_cast<std::uint32_t>(get(p + 28, 4));
    out.name = {reinterpret_cast<const char*>(p + kFrameMessageHeaderBytes), name_size};
    return ClassMessageError::ok;
}

ClassMessageError parse_class_map_message(std::span<const std::uint8_t> packet, std::uint32_t max_width,
                                          std::uint32_t max_height, ClassMapMessage& out) noexcept
{
    if (const auto e = check_header(packet, kClassMapHeaderBytes, ClassMessageType::class_map);
        e != ClassMessageError::ok)
        return e;
    const std::uint8_t* p = packet.data();
    const auto width = static_cast<std::uint32_t>(get(p + 16, 4));
    const auto height = static_cast<std::uint32_t>(get(p + 20, 4));
    if (width == 0 || height == 0)
        return ClassMessageError::bad_size;
    if (width > max_width || height > max_height)
        return ClassMessageError::too_large;
    if (packet.size() - kClassMapHeaderBytes != static_cast<std::size_t>(width) * height)
        return ClassMessageError::bad_size;
    out.t_capture_ns = static_cast<std::int64_t>(get(p + 8, 8));
    out.width = width;
    out.height = height;
    out.classes = p + kClassMapHeaderBytes;
    return ClassMessageError::ok;
}

}  // namespace stemd::runtime
