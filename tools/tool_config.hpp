// What the tools share: --config FILE and --set KEY=VALUE into a Config.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "stemd/runtime/config.hpp"

namespace stemd::tools {

struct ConfigArgs {
    std::string file;                // empty: defaults only
    std::vector<std::string> sets;   // KEY=VALUE, applied in order after the file
};

// Loads the file then the overrides; the first error is returned.
std::optional<config::ConfigError> build_config(const ConfigArgs& args, config::Config& out);

// Parses a finite double or an integer; false if the text is not one.
bool parse_number(const std::string& text, double& out);
bool parse_int(const std::string& text, long& out);

}  // namespace stemd::tools
