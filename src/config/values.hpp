// A value against its schema row, shared by the file loader, --set and the
// YAML writer: reading and checking a scalar, writing it back, and how
// errors name keys and items. Private to src/config.
#pragma once

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "stemd/base/strings.hpp"
#include "stemd/config/config.hpp"
#include "stemd/config/schema.hpp"

namespace stemd::config::detail {

using base::cat;
using base::trim;

constexpr std::string_view kWhitespace = " \t";

std::string quote(std::string_view s);  // 'text'
// Control characters become '?': an error message stays one line.
std::string printable(std::string_view s);

// "closing.radius_px" -> "closing", "radius_px".
std::string_view section_of(std::string_view key);
std::string_view leaf_of(std::string_view key);
bool is_known_section(std::string_view name);  // a section of schema()
bool is_valid_name(std::string_view name);     // letters, digits, _ - .
std::string list_sections();                   // "camera, segment, ..., tools"

// "unknown key; did you mean 'closing.radius_px'?" and the like.
std::string unknown_key_message(std::string_view key);
std::string unknown_item_key_message(const ListSpec& list, std::size_t index, std::string_view leaf);

// "more than 16 items; 'tools' holds at most 16".
std::string too_many_items(const ListSpec& list);

// "tools[1]" and "tools[1].offset_mm": how errors name an item and its keys.
std::string item_name(std::string_view section, std::size_t index);
std::string item_key_name(std::string_view section, std::size_t index, std::string_view leaf);
// The list section whose item a key names ("tools.1.offset_mm" or
// "tools[1].offset_mm": "tools"), or nullptr.
const ListSpec* list_of_key(std::string_view key);
// "tools.1.offset_mm" or "tools[1].offset_mm" -> 1, "offset_mm".
bool parse_item_key(std::string_view key, std::string_view section, std::size_t& index, std::string_view& leaf);

// Positions in schema(), list_schema() and a list's item_keys().
std::size_t index_of(const KeySpec& spec);
std::size_t list_index(const ListSpec& list);
std::size_t item_key_index(const ListSpec& list, const KeySpec& spec);

// A value as written: bare, or quoted (a YAML quoted scalar in a file, a
// double-quoted string with \" \\ \n \t escapes after --set KEY=).
struct Scalar {
    std::string text;
    bool quoted = false;
    bool empty() const { return !quoted && text.empty(); }
};

// Checks a scalar against the key's type, range and choices; stores it in
// `out` (origin untouched). Returns the message of the first problem.
std::optional<std::string> parse_value(const KeySpec& spec, const Scalar& scalar, ConfigValue& out);
// The text after "=" of --set KEY=VALUE into `value`, its origin `source`.
std::optional<std::string> set_value(const KeySpec& spec, std::string_view raw, std::string_view source,
                                     ConfigValue& value);

ConfigValue default_value(const KeySpec& spec);
std::vector<ConfigValue> default_item(const ListSpec& list);  // every key at its default

// A value as a config file writes it ("6", "0.33", "\"a b\"").
std::string value_text(const KeySpec& spec, const ConfigValue& value);
// What a key accepts: "[0, 50] px", "true or false", "a|b", "text".
std::string about_text(const KeySpec& spec);

// What is wrong with item `index` of a list, given the other items: its
// upper key not above its lower key, or its unique key's value used by
// another item (only earlier ones if `only_earlier`).
struct ItemProblem {
    std::string_view leaf;   // the key at fault: the upper or the unique key
    std::string message;
    std::size_t other = 0;   // unique key: the other item
};
std::optional<ItemProblem> check_item(const ListSpec& list, const ListValue& value, std::size_t index,
                                      bool only_earlier);

}  // namespace stemd::config::detail
