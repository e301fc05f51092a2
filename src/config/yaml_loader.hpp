// Configuration text (YAML, read with yaml-cpp) into the values of schema()
// and list_schema(), each checked against its row as it is read. Private to
// src/config; no yaml-cpp type leaves yaml_loader.cpp.
#pragma once

#include <optional>
#include <string_view>
#include <vector>

#include "stemd/config/config.hpp"

namespace stemd::config::detail {

// The first error, naming `origin`, line and key. On an error `values` and
// `lists` may be half-written: the caller loads into copies.
std::optional<ConfigError> load_yaml(std::string_view text, std::string_view origin, std::vector<ConfigValue>& values,
                                     std::vector<ListValue>& lists);

}  // namespace stemd::config::detail
