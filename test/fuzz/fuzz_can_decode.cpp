// Received CAN frames (ODOMETRY, TOOL_STATUS, TOOL_FIRED from the bus; the rest for
// completeness): any identifier, DLC and payload decodes or is rejected.
#include <cstddef>
#include <cstdint>
#include <algorithm>
#include <cstring>

#include "stemd/protocol/e2e.hpp"
#include "stemd/protocol/messages.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    namespace p = stemd::protocol;
    if (size < 3)
        return 0;
    p::CanFrame frame;
    // The identifier picks one of the five messages or something else.
    frame.id = p::CanIds{}.id(p::MessageKind::Target) + (data[0] % 7) - 1;
    frame.dlc = data[1];   // out-of-range DLCs must be refused, not read past
    std::memcpy(frame.data.data(), data + 2, std::min<std::size_t>(size - 2, frame.data.size()));
    const p::CanIds ids;
    p::Odometry odometry;
    p::TargetCommand target;
    p::ToolStatus tool_status;
    p::Heartbeat heartbeat;
    p::ToolFired tool_fired;
    (void)p::decode(frame, ids, odometry);
    (void)p::decode(frame, ids, target);
    (void)p::decode(frame, ids, tool_status);
    (void)p::decode(frame, ids, heartbeat);
    (void)p::decode(frame, ids, tool_fired);
    (void)p::e2e_crc_ok(ids.id(p::MessageKind::Odometry), frame.data);
    return 0;
}
