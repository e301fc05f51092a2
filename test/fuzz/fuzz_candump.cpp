// candump -L lines (what stemd writes and the tests read back): any line
// parses or is refused with a reason; a parsed frame formats back.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "stemd/protocol/candump_format.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string_view line(reinterpret_cast<const char*>(data), size);
    stemd::protocol::CandumpRecord record;
    std::string error;
    if (stemd::protocol::parse_candump_line(line, record, error))
        (void)stemd::protocol::format_candump_line(record.time_us, record.interface, record.frame);
    return 0;
}
