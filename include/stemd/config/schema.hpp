// The configuration schema: every key the daemon and the tools read, with
// its type, unit, range, default, meaning and the Settings member it sets.
// One table, so the loader, the typed settings, the documented
// config/stemd.yaml and the README's table cannot drift apart.
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <string_view>

namespace stemd::config {

enum class ValueType { integer, real, choice, boolean, text };

struct Settings;
namespace detail {
struct ConfigValue;
}

std::string_view to_string(ValueType type);

struct KeySpec {
    std::string_view key;            // "section.key"
    ValueType type;
    std::string_view unit;           // "" when the value has none
    double min;                      // integer and real only
    double max;                      // integer and real only
    std::string_view default_value;  // as written in a config file
    std::string_view choices;        // choice only: "exg|ndvi|mask"
    std::string_view help;           // one line: what the value means

    // The member of Settings the key sets (for list item keys, of item
    // `item`): store a checked value into it, load it back.
    void (*store)(const KeySpec& spec, Settings& settings, std::size_t item, const detail::ConfigValue& value) = nullptr;
    void (*load)(const KeySpec& spec, const Settings& settings, std::size_t item, detail::ConfigValue& value) = nullptr;
};

// Every key, grouped by section; sections in the order config files list them.
std::span<const KeySpec> schema();

// The key's spec, or nullptr if the schema has no such key.
const KeySpec* find_key(std::string_view key);

// A section of a config file and what it holds: the comment above it in
// config/stemd.yaml. `group`, if any, is a heading written above the
// section (the first section of the daemon's keys, of the actuation's).
struct SectionSpec {
    std::string_view name;
    std::string_view group;
    std::string_view help;
};

// Every section of schema() and of list_schema(), in the order files list them.
std::span<const SectionSpec> section_schema();

// --- List sections --------------------------------------------------------
// A list section is a top-level section holding a list of maps:
//
//   tools:
//     - id: 0
//       offset_mm: 600
//     - id: 1
//       offset_mm: 900
//
// Its item keys are KeySpecs named "section[].key" ("tools[].offset_mm"),
// typed and ranged like any key; an item's omitted keys take their defaults.
// Item keys are not in schema() and not found by find_key().
struct ListSpec {
    std::string_view section;     // "tools"
    std::size_t max_items;        // at least 1 item, at most this many
    std::string_view unique_key;  // item key whose values must differ across items ("" = none)
    std::string_view lower_key;   // if both set: the upper key's value must be > the lower key's
    std::string_view upper_key;
    std::string_view help;
    // The Settings member holding the list.
    std::size_t (*size)(const Settings& settings);
    void (*resize)(Settings& settings, std::size_t items);
};

// Every list section, in the order config files list them (after the
// sections of schema()).
std::span<const ListSpec> list_schema();

// The list section's spec, or nullptr if `section` is not a list section.
const ListSpec* find_list(std::string_view section);

// Every list's item keys, each list's keys together.
std::span<const KeySpec> list_item_schema();

// The item keys of one list section (empty if there is no such list).
std::span<const KeySpec> item_keys(std::string_view section);

// The item key "key" of list section `section` ("tools", "offset_mm"), or nullptr.
const KeySpec* find_item_key(std::string_view section, std::string_view item_key);

// "tools[].offset_mm" -> "tools" and "offset_mm" (item keys only).
std::string_view item_list_of(const KeySpec& spec);
std::string_view item_leaf_of(const KeySpec& spec);

// True if value is one of spec.choices (choice keys only).
bool is_choice(const KeySpec& spec, std::string_view value);

// spec.choices with `separator` between the choices: "exg, ndvi, mask".
std::string list_choices(const KeySpec& spec, std::string_view separator = ", ");

// A number as the schema and the error messages write it: the shortest text
// that reads back as the same double ("0.33", "10", "100000").
std::string format_number(double value);

// A numeric key's range as errors, config files and the README write it: "[0, 50]".
std::string bounds_text(const KeySpec& spec);

}  // namespace stemd::config
