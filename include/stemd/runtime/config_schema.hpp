// The configuration schema: every key the daemon and the tools read, with
// its type, unit, range, default and meaning. One table, so the loader, the
// documented config/stemd.yaml and the README's table cannot drift apart.
#pragma once

#include <span>
#include <string>
#include <string_view>

namespace stemd::config {

enum class ValueType { integer, real, choice, boolean, text };

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
};

// Every key, grouped by section; sections in the order config files list them.
std::span<const KeySpec> schema();

// The key's spec, or nullptr if the schema has no such key.
const KeySpec* find_key(std::string_view key);

// True if value is one of spec.choices (choice keys only).
bool is_choice(const KeySpec& spec, std::string_view value);

// spec.choices with `separator` between the choices: "exg, ndvi, mask".
std::string list_choices(const KeySpec& spec, std::string_view separator = ", ");

// A number as the schema and the error messages write it: the shortest text
// that reads back as the same double ("0.33", "10", "100000").
std::string format_number(double value);

// The schema as a Markdown table for the README:
// key | type | unit | default | range / choices | meaning.
std::string schema_markdown();

}  // namespace stemd::config
