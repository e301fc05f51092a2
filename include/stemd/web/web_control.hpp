// The live view's control endpoints, as pure functions: the token file, the
// bearer check, and which parameters may change and how (through the
// configuration schema's own type and range checks).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "stemd/config/config.hpp"

namespace stemd::web {

// Shorter tokens are refused: guessable over a field network.
inline constexpr std::size_t kMinTokenChars = 16;

// The token in `path`: the file's first line, without surrounding
// whitespace. nullopt and `error` (one line) if the file cannot be read,
// is readable or writable by group or others, or holds an empty or short
// token.
std::optional<std::string> read_token_file(const std::string& path, std::string& error);

// True if `authorization` is "Bearer <token>" with exactly this token. The
// comparison takes the same time wherever the first difference is.
bool bearer_matches(std::string_view authorization, std::string_view token);

// The keys the view may change: segment.* and stem.* except those that size
// buffers at start (segment.method: the frame slots' channels;
// segment.opening_radius_px, segment.edge_radius_px: kernels set up once).
bool is_controllable(std::string_view key);
std::vector<std::string> controllable_keys();

struct ParamChange {
    bool ok = false;
    std::string error;       // why not (names the range for a number out of it)
    std::string old_value;   // as a config file writes it
    std::string new_value;
};

// Sets `key` to `value` (text as --set takes it) in `config`, checked by the
// schema. On an error `config` is unchanged.
ParamChange change_param(config::Config& config, std::string_view key, std::string_view value);

}  // namespace stemd::web
