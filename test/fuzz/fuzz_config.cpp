// The configuration loader on arbitrary text: a YAML document, then the
// same bytes as a --set override. Any input must give a value or a
// ConfigError, never a crash, a hang or an unbounded allocation.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "stemd/config/config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    stemd::config::Config config;
    if (!config.load_text(text, "fuzz.yaml"))
        (void)config.settings();
    stemd::config::Config overridden;
    if (!overridden.set_override(text))
        (void)overridden.settings();
    return 0;
}
