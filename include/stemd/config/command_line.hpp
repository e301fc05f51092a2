// What stemd and its tools share on the command line: --config FILE and
// --set KEY=VALUE into a Config (the options themselves: tools/tool_cli).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "stemd/config/config.hpp"

namespace stemd::config {

struct ConfigArgs {
    std::string file;                // empty: defaults only
    std::vector<std::string> sets;   // KEY=VALUE, applied in order after the file
};

// Loads the file then the overrides; the first error is returned.
std::optional<ConfigError> build_config(const ConfigArgs& args, Config& out);

}  // namespace stemd::config
