#include "config_docs.hpp"

#include <string_view>

#include "stemd/base/strings.hpp"
#include "stemd/config/config.hpp"
#include "stemd/config/schema.hpp"

namespace stemd::config {

namespace {

using base::cat;

constexpr std::string_view kHeader =
    "# stemd configuration: every key at its default.\n"
    "#\n"
    "# Format: YAML (read with yaml-cpp) in one shape: top-level \"section:\" lines,\n"
    "# then \"key: value\" lines indented by spaces (never tabs), one level deep;\n"
    "# the list section \"tools\" holds \"- key: value\" items instead. Values are\n"
    "# integers, reals, bare words, true/false or quoted strings (\"-\" for a dash:\n"
    "# a bare - starts a YAML list item); '#' starts a comment on its own line or\n"
    "# after a value (preceded by a space). Unknown or duplicate keys, deeper\n"
    "# nesting and out-of-range values are errors. A file need not list every\n"
    "# key: keys it leaves out keep their defaults. stemd and the tools take\n"
    "# --config FILE, repeated to layer files (a later file wins key by key), and\n"
    "# --set section.key=value (e.g. --set closing.radius_px=6), which wins over\n"
    "# the files.\n"
    "#\n"
    "# Generated from the schema (src/config/schema.cpp), like the README's table:\n"
    "#   stemd-config yaml --out config/stemd.yaml\n";

// `text` as "# " comment lines of at most 79 columns after `indent`.
std::string wrapped_comment(std::string_view indent, std::string_view text)
{
    constexpr std::size_t kWidth = 79;
    std::string out;
    std::string line = cat(indent, "#");
    for (std::size_t at = 0; at < text.size();) {
        const std::size_t end = std::min(text.find(' ', at), text.size());
        const std::string_view word = text.substr(at, end - at);
        at = end + 1;
        if (word.empty())
            continue;
        if (line.size() + 1 + word.size() > kWidth && line.size() > indent.size() + 1) {
            out += cat(line, "\n");
            line = cat(indent, "#");
        }
        line += cat(" ", word);
    }
    return out + line + "\n";
}

// "Integer, px, range [0, 50].", "Boolean.", "Choice: a | b.", "Text."
std::string about(const KeySpec& spec)
{
    switch (spec.type) {
    case ValueType::integer:
    case ValueType::real:
        return cat(spec.type == ValueType::integer ? "Integer, " : "Real, ", spec.unit, spec.unit.empty() ? "" : ", ",
                   "range ", bounds_text(spec), ".");
    case ValueType::boolean: return "Boolean.";
    case ValueType::choice: return cat("Choice: ", list_choices(spec, " | "), ".");
    case ValueType::text: return "Text.";
    }
    return "?";
}

// A section's line, the group heading and the section's help above it
// (`fallback` for a section without help: a list's).
std::string section_lines(std::string_view name, std::string_view fallback)
{
    std::string out;
    for (const SectionSpec& section : section_schema())
        if (section.name == name && !section.group.empty())
            out += cat("\n# --- ", section.group, " ---\n");
    out += "\n";
    for (const SectionSpec& section : section_schema())
        if (section.name == name)
            out += wrapped_comment("", section.help.empty() ? cat(fallback, ".") : std::string(section.help));
    return cat(out, name, ":\n");
}

// One key: its help and what it accepts above it, then "name: value".
std::string key_lines(std::string_view indent, std::string_view first, std::string_view name, const KeySpec& spec,
                      const std::string& value)
{
    return cat(wrapped_comment(indent, cat(spec.help, ".")), indent, "# ", about(spec), "\n", first, name, ": ", value,
               "\n");
}

}  // namespace

std::string documented_yaml()
{
    const Config defaults;
    std::string out(kHeader);
    std::string_view section;
    for (const KeySpec& spec : schema()) {
        const std::size_t dot = spec.key.find('.');
        if (spec.key.substr(0, dot) != section) {
            section = spec.key.substr(0, dot);
            out += section_lines(section, "");
        }
        out += key_lines("  ", "  ", spec.key.substr(dot + 1), spec, defaults.value_of(spec.key));
    }
    // List sections: "- " before each item's first key.
    for (const ListSpec& list : list_schema()) {
        out += section_lines(list.section, list.help);
        const std::span<const KeySpec> keys = item_keys(list.section);
        for (std::size_t i = 0; i < defaults.list_size(list.section); ++i)
            for (std::size_t k = 0; k < keys.size(); ++k) {
                const std::string_view leaf = item_leaf_of(keys[k]);
                const std::string key = cat(list.section, "[", std::to_string(i), "].", leaf);
                out += key_lines("    ", k == 0 ? "  - " : "    ", leaf, keys[k], defaults.value_of(key));
            }
    }
    return out;
}

std::string schema_markdown()
{
    std::string out =
        "| key | type | unit | default | range / choices | meaning |\n"
        "|---|---|---|---|---|---|\n";
    const auto row = [&out](const KeySpec& spec) {
        std::string range;
        if (spec.type == ValueType::integer || spec.type == ValueType::real)
            range = bounds_text(spec);
        else if (spec.type == ValueType::choice)
            range = cat("`", list_choices(spec, "`, `"), "`");
        else if (spec.type == ValueType::boolean)
            range = "`true`, `false`";
        out += cat("| `", spec.key, "` | ", to_string(spec.type), " | ", spec.unit, " | `", spec.default_value, "` | ",
                   range, " | ", spec.help, " |\n");
    };
    for (const KeySpec& spec : schema())
        row(spec);
    for (const KeySpec& spec : list_item_schema())
        row(spec);
    return out;
}

}  // namespace stemd::config
