// What stemd and its tools share on the command line: --config FILE and
// --set KEY=VALUE into a Config (the options themselves: tools/tool_cli).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "stemd/config/config.hpp"

namespace stemd::config {

struct ConfigArgs {
    std::vector<std::string> files;  // none: defaults only
    std::vector<std::string> sets;   // KEY=VALUE, applied in order after the files
};

// Loads the files in order, each on top of the ones before it (a key a later
// file gives wins; a list section it gives replaces the list), then the
// overrides. The first error is returned, naming its own file and line.
std::optional<ConfigError> build_config(const ConfigArgs& args, Config& out);

}  // namespace stemd::config
