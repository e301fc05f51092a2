// The effective configuration: schema defaults, then config files (each on
// top of the ones before it), then --set overrides, each value checked
// against the schema (type, range, choices) as it arrives.
//
// A config file is YAML (read with yaml-cpp) in one shape: a map of
// sections, each a map of scalars, "section.key" once flattened; a list
// section ("tools", ListSpec) holds a list of such maps and a file's list
// replaces the whole list. The format and its errors: README,
// "Configuration", and the header of config/stemd.yaml. Every error names
// file, line and key ("key 'tools[1].offset_mm'").
//
// --set values are not YAML: "--set can.log_file=-" is the text "-", and a
// value may be double-quoted ("a \"b\"").
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "stemd/config/schema.hpp"
#include "stemd/config/settings.hpp"

namespace stemd::config {

namespace detail {
struct ConfigValue {
    long integer = 0;
    double real = 0.0;
    bool boolean = false;
    std::string text;               // text and choice values
    std::string origin = "default";
};

// One list section's items; each item's values are parallel to item_keys().
struct ListValue {
    std::vector<std::vector<ConfigValue>> items;
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
    // List items: "tools.0.offset_mm=650" (or "tools[0].offset_mm=650") sets
    // item 0's key; index == list_size() appends an item at the item
    // defaults, its unique key (id) the lowest value no other item has.
    // `source` becomes the value's origin: "--set", or "web" for a change
    // the live view's control makes at run time.
    std::optional<ConfigError> set_override(std::string_view key_equals_value, std::string_view source = "--set");

    // The values, typed: every key stored into the Settings member its
    // schema row is bound to.
    Settings settings() const;

    // Where a key's value came from: "default", "FILE:LINE" or "--set"
    // ("" for a key the schema does not have). A list item's key is named
    // as errors name it: "tools[1].offset_mm".
    std::string origin_of(std::string_view key) const;

    // A key's value as a config file writes it ("5", "0.33", "true",
    // "robust"); "" for a key the schema does not have. A list item's key
    // is named as in origin_of().
    std::string value_of(std::string_view key) const;

    // A problem with a key's value as errors name it: "FILE:LINE: key 'k':
    // message" for a key from a file, "key 'k' (default): message" else.
    std::string blame(std::string_view key, std::string_view message) const;

    // Items in a list section ("tools"); 0 for an unknown section.
    std::size_t list_size(std::string_view section) const;
    // Where item `index`'s key came from ("" for an unknown key or item).
    std::string item_origin_of(std::string_view section, std::size_t index, std::string_view key) const;

    // The effective configuration as a config file (every key, with its unit,
    // range and origin in a comment); load_text() of it gives the same values.
    std::string to_yaml() const;

private:
    // The value `key` names (as origin_of() takes it) and its row; nullptr if none.
    const detail::ConfigValue* find_value(std::string_view key, const KeySpec*& spec) const;
    std::optional<ConfigError> set_item_override(const ListSpec& list, std::string_view key,
                                                 std::string_view raw_value, const std::string& origin,
                                                 std::string_view source);

    std::vector<detail::ConfigValue> values_;  // parallel to schema()
    std::vector<detail::ListValue> lists_;     // parallel to list_schema()
};

}  // namespace stemd::config
