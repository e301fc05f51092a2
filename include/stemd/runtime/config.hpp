// The effective configuration: schema defaults, then a config file, then
// --set overrides, each value checked against the schema (type, range,
// choices) as it arrives.
//
// File format, a strict YAML subset (see config/stemd.yaml):
//
//   # a comment
//   closing:              # a section: a top-level name ending in ':'
//     radius_px: 10       # key: value, indented by spaces, one level only
//
// Values are integers, reals, bare words, true/false or double-quoted
// strings ("a \"b\" \\ c"). Keys are flattened to "section.key". Keys a file
// does not mention keep their previous value.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "stemd/runtime/config_schema.hpp"

namespace stemd::config {

namespace detail {
struct ConfigValue {
    long integer = 0;
    double real = 0.0;
    bool boolean = false;
    std::string text;               // text and choice values
    std::string origin = "default";
};
}  // namespace detail

struct ConfigError {
    std::string origin;   // file path, or "--set KEY=VALUE"
    int line = 0;         // 1-based; 0 when no line applies
    std::string key;      // "section.key" (or the section); empty when no key applies
    std::string message;

    // "config/x.yaml:12: key 'closing.radius_px': 6000 is out of range [0, 50] px"
    // "config/x.yaml:3: expected 'key: value'"                      (no key)
    // "config/x.yaml: cannot read file: No such file or directory"  (no line)
    // "--set closing.radius_px=abc: key 'closing.radius_px': expected an integer, got 'abc'"
    std::string to_string() const;
};

class Config {
public:
    Config();  // every key at its schema default

    // Reads a file on top of the current values. On an error nothing changes
    // and the first error is returned. Never throws.
    std::optional<ConfigError> load_file(const std::filesystem::path& path);

    // Loads configuration text as if it were a file called `origin`.
    std::optional<ConfigError> load_text(std::string_view text, std::string_view origin);

    // "section.key=value" from --set. On an error nothing changes. Never throws.
    std::optional<ConfigError> set_override(std::string_view key_equals_value);

    // Typed access. An unknown key or the wrong type is a programming error:
    // these throw std::logic_error.
    long get_int(std::string_view key) const;
    double get_real(std::string_view key) const;   // real keys only
    bool get_bool(std::string_view key) const;
    const std::string& get_text(std::string_view key) const;  // text and choice keys

    // Where the value came from: "default", "FILE:LINE" or "--set".
    // Throws std::logic_error on an unknown key.
    std::string origin_of(std::string_view key) const;

    // The effective configuration as a config file (every key, with its unit,
    // range and origin in a comment); load_text() of it gives the same values.
    std::string to_yaml() const;

private:
    const detail::ConfigValue& value_for(std::string_view key, std::string_view getter,
                                         ValueType type, ValueType or_type) const;

    std::vector<detail::ConfigValue> values_;  // parallel to schema()
};

}  // namespace stemd::config
