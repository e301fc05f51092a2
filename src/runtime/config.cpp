#include "stemd/runtime/config.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <span>
#include <stdexcept>
#include <system_error>

namespace stemd::config {

namespace {

using detail::ConfigValue;

constexpr std::string_view kWhitespace = " \t";

// Concatenation without "literal" + std::string&&, which GCC 12 at -O3
// misreports under -Wrestrict.
template <class... Parts>
std::string cat(const Parts&... parts)
{
    std::string out;
    (out.append(std::string_view(parts)), ...);
    return out;
}

std::string_view trim(std::string_view s)
{
    const std::size_t first = s.find_first_not_of(kWhitespace);
    if (first == std::string_view::npos)
        return {};
    const std::size_t last = s.find_last_not_of(kWhitespace);
    return s.substr(first, last - first + 1);
}

std::string quote(std::string_view s)
{
    return cat("'", s, "'");
}

std::string_view section_of(std::string_view key)
{
    return key.substr(0, key.find('.'));
}

std::string_view leaf_of(std::string_view key)
{
    const std::size_t dot = key.find('.');
    return dot == std::string_view::npos ? key : key.substr(dot + 1);
}

bool is_known_section(std::string_view name)
{
    return std::any_of(schema().begin(), schema().end(),
                       [&](const KeySpec& spec) { return section_of(spec.key) == name; });
}

std::string list_sections()
{
    std::string out;
    std::string_view previous;
    for (const KeySpec& spec : schema()) {
        const std::string_view section = section_of(spec.key);
        if (section == previous)
            continue;
        if (!out.empty())
            out += ", ";
        out += section;
        previous = section;
    }
    for (const ListSpec& list : list_schema()) {
        if (!out.empty())
            out += ", ";
        out += list.section;
    }
    return out;
}

std::size_t edit_distance(std::string_view a, std::string_view b)
{
    std::vector<std::size_t> row(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j)
        row[j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i) {
        std::size_t diagonal = row[0];
        row[0] = i;
        for (std::size_t j = 1; j <= b.size(); ++j) {
            const std::size_t above = row[j];
            row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
            diagonal = above;
        }
    }
    return row[b.size()];
}

// "unknown key; did you mean 'closing.radius_px'?" and the like.
std::string unknown_key_message(std::string_view key)
{
    const KeySpec* best = nullptr;
    std::size_t best_distance = 0;
    for (const KeySpec& spec : schema()) {
        const std::size_t d = edit_distance(key, spec.key);
        if (best == nullptr || d < best_distance) {
            best = &spec;
            best_distance = d;
        }
    }
    if (best != nullptr && best_distance <= 3)
        return cat("unknown key; did you mean ", quote(best->key), "?");
    // The same name in another section.
    for (const KeySpec& spec : schema())
        if (leaf_of(spec.key) == leaf_of(key))
            return cat("unknown key; did you mean ", quote(spec.key), "?");
    const std::string_view section = section_of(key);
    if (is_known_section(section)) {
        std::string keys;
        for (const KeySpec& spec : schema()) {
            if (section_of(spec.key) != section)
                continue;
            if (!keys.empty())
                keys += ", ";
            keys += leaf_of(spec.key);
        }
        return cat("unknown key; section ", quote(section), " has: ", keys);
    }
    return cat("unknown key; the sections are: ", list_sections());
}

std::string range_text(const KeySpec& spec)
{
    std::string out = cat("[", format_number(spec.min), ", ", format_number(spec.max), "]");
    if (!spec.unit.empty()) {
        out += ' ';
        out += spec.unit;
    }
    return out;
}

// --- list sections ---------------------------------------------------------

// "tools[1]" and "tools[1].offset_mm": how errors name an item and its keys.
std::string item_name(std::string_view section, std::size_t index)
{
    return cat(section, "[", std::to_string(index), "]");
}

std::string item_key_name(std::string_view section, std::size_t index, std::string_view leaf)
{
    return cat(item_name(section, index), ".", leaf);
}

std::size_t list_index(const ListSpec& list)
{
    return static_cast<std::size_t>(&list - list_schema().data());
}

std::size_t item_key_index(const ListSpec& list, const KeySpec& spec)
{
    return static_cast<std::size_t>(&spec - item_keys(list.section).data());
}

// "unknown key; did you mean 'tools[1].offset_mm'?" or the item's keys.
std::string unknown_item_key_message(const ListSpec& list, std::size_t index, std::string_view leaf)
{
    const KeySpec* best = nullptr;
    std::size_t best_distance = 0;
    std::string keys;
    for (const KeySpec& spec : item_keys(list.section)) {
        const std::size_t d = edit_distance(leaf, item_leaf_of(spec));
        if (best == nullptr || d < best_distance) {
            best = &spec;
            best_distance = d;
        }
        if (!keys.empty())
            keys += ", ";
        keys += item_leaf_of(spec);
    }
    if (best != nullptr && best_distance <= 3)
        return cat("unknown key; did you mean ", quote(item_key_name(list.section, index, item_leaf_of(*best))), "?");
    return cat("unknown key; a ", list.section, " item has: ", keys);
}

// A value as written: bare, or double-quoted with \" \\ \n \t escapes.
struct Scalar {
    std::string text;
    bool quoted = false;
    bool empty() const { return !quoted && text.empty(); }
};

// Parses the text after "key:" (file) or after "=" (--set). In a file a '#'
// after whitespace starts a comment; on the command line it is literal.
std::optional<std::string> parse_scalar(std::string_view raw, bool comments, Scalar& out)
{
    raw = trim(raw);
    out = Scalar{};
    if (raw.empty() || (comments && raw.front() == '#'))
        return std::nullopt;
    if (raw.front() == '"') {
        out.quoted = true;
        std::size_t i = 1;
        for (; i < raw.size() && raw[i] != '"'; ++i) {
            if (raw[i] != '\\') {
                out.text += raw[i];
                continue;
            }
            if (++i == raw.size())
                break;
            switch (raw[i]) {
            case '"': out.text += '"'; break;
            case '\\': out.text += '\\'; break;
            case 'n': out.text += '\n'; break;
            case 't': out.text += '\t'; break;
            default:
                return cat("unsupported escape '\\", std::string_view(&raw[i], 1),
                           "' in a double-quoted string (use \\\", \\\\, \\n or \\t)");
            }
        }
        if (i >= raw.size())
            return std::string("unterminated double-quoted string");
        const std::string_view after = trim(raw.substr(i + 1));
        if (!after.empty() && !(comments && after.front() == '#' &&
                                kWhitespace.find(raw[i + 1]) != std::string_view::npos))
            return cat("unexpected text after the closing quote: ", quote(after));
        return std::nullopt;
    }
    if (comments) {
        for (std::size_t i = 1; i < raw.size(); ++i) {
            if (raw[i] == '#' && kWhitespace.find(raw[i - 1]) != std::string_view::npos) {
                raw = trim(raw.substr(0, i));
                break;
            }
        }
    }
    // YAML syntax this subset does not support would otherwise be read as text.
    // On the command line a lone "-" is a plain value ("standard output").
    constexpr std::string_view kIndicators = "[]{}&*!|>'%@`,?";
    if (kIndicators.find(raw.front()) != std::string_view::npos || (raw == "-" && comments) ||
        raw.starts_with("- "))
        return cat("unsupported YAML syntax ", quote(raw), "; write a plain value or a double-quoted string");
    out.text = std::string(raw);
    return std::nullopt;
}

// Checks a scalar against the key's type, range and choices; stores it in
// `out` (origin untouched). Returns the message of the first problem.
std::optional<std::string> parse_value(const KeySpec& spec, const Scalar& scalar, ConfigValue& out)
{
    if (scalar.empty())
        return std::string("empty value");
    const std::string& text = scalar.text;
    switch (spec.type) {
    case ValueType::integer:
    case ValueType::real: {
        const bool is_int = spec.type == ValueType::integer;
        const std::string expected = is_int ? "expected an integer" : "expected a real number";
        if (scalar.quoted)
            return expected + ", got a quoted string";
        std::string_view digits = text;
        if (digits.size() > 1 && digits.front() == '+' && digits[1] != '-')
            digits.remove_prefix(1);
        const char* end = digits.data() + digits.size();
        long integer = 0;
        double real = 0.0;
        const std::from_chars_result result = is_int
            ? std::from_chars(digits.data(), end, integer)
            : std::from_chars(digits.data(), end, real);
        if (result.ec == std::errc::result_out_of_range && result.ptr == end)
            return cat(text, " is out of range ", range_text(spec));
        if (result.ec != std::errc() || result.ptr != end || (!is_int && !std::isfinite(real)))
            return cat(expected, ", got ", quote(text));
        const double value = is_int ? static_cast<double>(integer) : real;
        if (!(value >= spec.min && value <= spec.max))
            return cat(text, " is out of range ", range_text(spec));
        out.integer = integer;
        out.real = real;
        return std::nullopt;
    }
    case ValueType::boolean:
        if (!scalar.quoted && text == "true")
            out.boolean = true;
        else if (!scalar.quoted && text == "false")
            out.boolean = false;
        else
            return cat("expected true or false, got ", quote(text));
        return std::nullopt;
    case ValueType::choice:
        if (!is_choice(spec, text))
            return cat(quote(text), " is not one of ", list_choices(spec));
        out.text = text;
        return std::nullopt;
    case ValueType::text:
        out.text = text;
        return std::nullopt;
    }
    return std::string("unsupported value type");
}

std::size_t index_of(const KeySpec& spec)
{
    return static_cast<std::size_t>(&spec - schema().data());
}

// A value as a config file writes it (text quoted).
std::string value_text(const KeySpec& spec, const ConfigValue& value);

double number_of(const KeySpec& spec, const ConfigValue& value)
{
    return spec.type == ValueType::integer ? static_cast<double>(value.integer) : value.real;
}

// An item with every key at its default.
std::vector<ConfigValue> default_item(const ListSpec& list)
{
    std::vector<ConfigValue> item;
    for (const KeySpec& spec : item_keys(list.section)) {
        ConfigValue value;
        const Scalar scalar{std::string(spec.default_value), false};
        (void)parse_value(spec, scalar, value);
        value.origin = "default";
        item.push_back(std::move(value));
    }
    return item;
}

// What is wrong with item `index` of a list, given the other items: its
// upper key not above its lower key, or its unique key's value used by
// another item (only earlier ones if `only_earlier`).
struct ItemProblem {
    std::string_view leaf;   // the key at fault: the upper or the unique key
    std::string message;
    std::size_t other = 0;   // unique key: the other item
};

std::optional<ItemProblem> check_item(const ListSpec& list, const detail::ListValue& value, std::size_t index,
                                      bool only_earlier)
{
    const std::vector<ConfigValue>& item = value.items[index];
    const KeySpec* lower = find_item_key(list.section, list.lower_key);
    const KeySpec* upper = find_item_key(list.section, list.upper_key);
    if (lower != nullptr && upper != nullptr) {
        const ConfigValue& lo = item[item_key_index(list, *lower)];
        const ConfigValue& hi = item[item_key_index(list, *upper)];
        if (!(number_of(*upper, hi) > number_of(*lower, lo)))
            return ItemProblem{list.upper_key,
                               cat(list.upper_key, " ", value_text(*upper, hi), " must be greater than ",
                                   list.lower_key, " ", value_text(*lower, lo)),
                               0};
    }
    if (const KeySpec* unique = find_item_key(list.section, list.unique_key)) {
        const std::size_t k = item_key_index(list, *unique);
        const std::string mine = value_text(*unique, item[k]);
        const std::size_t end = only_earlier ? index : value.items.size();
        for (std::size_t other = 0; other < end; ++other)
            if (other != index && value_text(*unique, value.items[other][k]) == mine)
                return ItemProblem{list.unique_key,
                                   cat("duplicate ", list.unique_key, " ", mine, "; ",
                                       item_name(list.section, other), " has it already"),
                                   other};
    }
    return std::nullopt;
}

std::string_view without_cr(std::string_view line)
{
    if (!line.empty() && line.back() == '\r')
        line.remove_suffix(1);
    return line;
}

struct LineParts {
    std::size_t indent = 0;       // leading spaces and tabs
    bool tab = false;             // a tab among them
    bool content = false;         // neither blank nor a comment
    std::string_view name;        // before the ':' (trimmed); the whole text if no ':'
    bool colon = false;
    std::string_view after_colon; // untrimmed
};

LineParts split_line(std::string_view line)
{
    LineParts p;
    p.indent = std::min(line.find_first_not_of(kWhitespace), line.size());
    const std::string_view lead = line.substr(0, p.indent);
    p.tab = lead.find('\t') != std::string_view::npos;
    const std::string_view rest = line.substr(p.indent);
    p.content = !rest.empty() && rest.front() != '#';
    if (!p.content)
        return p;
    const std::size_t colon = rest.find(':');
    p.colon = colon != std::string_view::npos;
    p.name = trim(rest.substr(0, colon));
    if (p.colon)
        p.after_colon = rest.substr(colon + 1);
    return p;
}

bool is_valid_name(std::string_view name)
{
    return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
               c == '_' || c == '-' || c == '.';
    });
}

// The first line after `index` that is neither blank nor a comment, if it is
// indented deeper than `indent`: "key:" followed by it is a nested mapping.
std::optional<std::size_t> deeper_line(const std::vector<std::string_view>& lines, std::size_t index,
                                       std::size_t indent)
{
    for (std::size_t j = index + 1; j < lines.size(); ++j) {
        const LineParts next = split_line(lines[j]);
        if (!next.content)
            continue;
        if (next.indent > indent)
            return j;
        break;
    }
    return std::nullopt;
}

// Parses configuration text into `values` and `lists` (copies the caller commits).
class TextLoader {
public:
    TextLoader(std::string_view origin, std::vector<ConfigValue>& values, std::vector<detail::ListValue>& lists)
        : origin_(origin), values_(values), lists_(lists) {}

    std::optional<ConfigError> load(std::string_view text)
    {
        if (text.starts_with("\xEF\xBB\xBF"))  // UTF-8 byte order mark
            text.remove_prefix(3);
        std::vector<std::string_view> lines;
        while (!text.empty()) {
            const std::size_t nl = text.find('\n');
            lines.push_back(without_cr(text.substr(0, nl)));
            text = nl == std::string_view::npos ? std::string_view{} : text.substr(nl + 1);
        }
        for (std::size_t i = 0; i < lines.size(); ++i)
            if (auto error = line(lines, i))
                return error;
        return finish_list();
    }

private:
    ConfigError error(int line, std::string key, std::string message) const
    {
        return ConfigError{origin_, line, std::move(key), std::move(message)};
    }

    std::optional<ConfigError> line(const std::vector<std::string_view>& lines, std::size_t index)
    {
        const int number = static_cast<int>(index) + 1;
        const LineParts p = split_line(lines[index]);
        if (!p.content)
            return std::nullopt;
        if (list_ != nullptr) {
            // Inside a list section: items, until the next line at indent 0
            // that is not an item.
            if (lines[index][p.indent] == '-' || p.indent > 0)
                return list_line(lines, index, p);
            if (auto error = finish_list())
                return error;
        }
        const bool nested = p.indent > 0;
        const std::string full = nested && !section_.empty() && p.colon
            ? cat(section_, ".", p.name)
            : std::string(p.colon ? p.name : std::string_view{});
        if (p.tab)
            return error(number, full, "tab in the indentation; indent with spaces");
        if (!p.colon || !is_valid_name(p.name))
            return error(number, "", cat("expected 'section:' or 'key: value', got ", quote(trim(lines[index]))));
        if (!p.after_colon.empty() && kWhitespace.find(p.after_colon.front()) == std::string_view::npos)
            return error(number, full, "expected a space after ':'");
        Scalar scalar;
        if (auto message = parse_scalar(p.after_colon, true, scalar))
            return error(number, full, *message);
        return nested ? key_line(lines, index, p, full, scalar) : section_line(number, p.name, scalar);
    }

    std::optional<ConfigError> section_line(int number, std::string_view name, const Scalar& scalar)
    {
        const std::string section(name);
        const ListSpec* list = find_list(section);
        if (!scalar.empty()) {
            if (list != nullptr)
                return error(number, section, cat("a list section cannot have a value; put its items ('- ",
                                                      item_leaf_of(item_keys(section).front()),
                                                      ": ...') on indented lines below it"));
            if (is_known_section(section))
                return error(number, section, "a section cannot have a value; put its keys on indented lines below it");
            if (find_key(section) != nullptr)
                return error(number, section, cat("key outside a section; write '", section_of(section), ":' and indent '",
                                                      leaf_of(section), ": ...' below it"));
            for (const KeySpec& spec : schema())
                if (leaf_of(spec.key) == name)
                    return error(number, section, cat("key outside a section; indent it under '", section_of(spec.key), ":'"));
            return error(number, section, cat("key outside a section; indent it under its section (", list_sections(), ")"));
        }
        if (!is_known_section(section) && list == nullptr)
            return error(number, section, cat("unknown section; the sections are: ", list_sections()));
        const auto [it, inserted] = section_lines_.emplace(section, number);
        if (!inserted)
            return error(number, section, cat("duplicate section (first on line ", std::to_string(it->second), ")"));
        section_ = section;
        section_indent_ = 0;
        if (list != nullptr) {
            // The file's list replaces the whole list.
            list_ = list;
            list_value_ = &lists_[list_index(*list)];
            list_value_->items.clear();
            list_line_ = number;
            dash_indent_ = std::string_view::npos;
            item_open_ = false;
            unique_lines_.clear();
        }
        return std::nullopt;
    }

    std::optional<ConfigError> key_line(const std::vector<std::string_view>& lines, std::size_t index,
                                        const LineParts& p, const std::string& full, const Scalar& scalar)
    {
        const int number = static_cast<int>(index) + 1;
        if (section_.empty())
            return error(number, std::string(p.name), "key outside a section; no 'section:' line above it");
        if (section_indent_ == 0)
            section_indent_ = p.indent;
        if (p.indent != section_indent_)
            return error(number, full, cat("inconsistent indentation: ", std::to_string(p.indent),
                                               " spaces, the keys of section '", section_, "' have ",
                                               std::to_string(section_indent_)));
        if (scalar.empty()) {
            if (const auto j = deeper_line(lines, index, p.indent))
                return error(static_cast<int>(*j) + 1, cat(full, ".", split_line(lines[*j]).name),
                             "nesting deeper than one level; a section holds only 'key: value' lines");
        }
        const KeySpec* spec = find_key(full);
        if (spec == nullptr)
            return error(number, full, unknown_key_message(full));
        const auto [it, inserted] = key_lines_.emplace(full, number);
        if (!inserted)
            return error(number, full, cat("duplicate key (first on line ", std::to_string(it->second), ")"));
        ConfigValue& value = values_[index_of(*spec)];
        if (auto message = parse_value(*spec, scalar, value))
            return error(number, full, *message);
        value.origin = cat(origin_, ":", std::to_string(number));
        return std::nullopt;
    }

    // A line inside a list section: "- key: value" starts an item, "key: value"
    // (aligned with the item's first key) continues it.
    std::optional<ConfigError> list_line(const std::vector<std::string_view>& lines, std::size_t index,
                                         const LineParts& p)
    {
        const int number = static_cast<int>(index) + 1;
        const std::string_view section = list_->section;
        std::string_view rest = lines[index].substr(p.indent);
        const bool dash = rest.front() == '-';
        const std::size_t item = list_value_->items.size() - (dash || list_value_->items.empty() ? 0 : 1);
        if (!dash && !item_open_)
            return error(number, std::string(section),
                         cat("expected a list of items ('- key: value' lines) under '", section, ":'"));
        std::size_t key_column = p.indent;
        bool tab = p.tab;
        if (dash) {
            const std::size_t key_start = rest.find_first_not_of(kWhitespace, 1);
            if (rest.size() < 2 || kWhitespace.find(rest[1]) == std::string_view::npos ||
                key_start == std::string_view::npos || rest[key_start] == '#')
                return error(number, item_name(section, item),
                             cat("expected '- key: value' (an item starts with '- ' and its first key), got ",
                                 quote(trim(rest))));
            tab = tab || rest.substr(1, key_start - 1).find('\t') != std::string_view::npos;
            key_column = p.indent + key_start;
            rest = rest.substr(key_start);
        }
        const LineParts k = split_line(rest);
        const std::string full = k.colon ? item_key_name(section, item, k.name) : item_name(section, item);
        if (tab)
            return error(number, full, "tab in the indentation; indent with spaces");
        if (item_open_ && p.indent > item_indent_)
            return error(number, full, "nesting deeper than one level; a list item holds only 'key: value' lines");
        if (dash) {
            if (dash_indent_ == std::string_view::npos)
                dash_indent_ = p.indent;
            if (p.indent != dash_indent_)
                return error(number, full, cat("inconsistent indentation: ", std::to_string(p.indent),
                                                   " spaces, the items of '", section, "' start at ",
                                                   std::to_string(dash_indent_)));
            if (auto error = finish_item())
                return error;
            if (list_value_->items.size() >= list_->max_items)
                return error(number, item_name(section, item),
                             cat("more than ", std::to_string(list_->max_items), " items; '", section,
                                 "' holds at most ", std::to_string(list_->max_items)));
            list_value_->items.push_back(default_item(*list_));
            item_open_ = true;
            item_line_ = number;
            item_indent_ = key_column;
            item_key_lines_.clear();
        } else if (p.indent != item_indent_) {
            return error(number, full, cat("inconsistent indentation: ", std::to_string(p.indent),
                                               " spaces, the keys of item ", item_name(section, item), " are at ",
                                               std::to_string(item_indent_)));
        }
        if (!k.colon || !is_valid_name(k.name))
            return error(number, "", cat("expected '- key: value' or 'key: value' in a list item, got ",
                                         quote(trim(lines[index]))));
        if (!k.after_colon.empty() && kWhitespace.find(k.after_colon.front()) == std::string_view::npos)
            return error(number, full, "expected a space after ':'");
        Scalar scalar;
        if (auto message = parse_scalar(k.after_colon, true, scalar))
            return error(number, full, *message);
        if (scalar.empty()) {
            if (const auto j = deeper_line(lines, index, key_column))
                return error(static_cast<int>(*j) + 1, cat(full, ".", split_line(lines[*j]).name),
                             "nesting deeper than one level; a list item holds only 'key: value' lines");
        }
        const KeySpec* spec = find_item_key(section, k.name);
        if (spec == nullptr)
            return error(number, full, unknown_item_key_message(*list_, item, k.name));
        const auto [it, inserted] = item_key_lines_.emplace(std::string(k.name), number);
        if (!inserted)
            return error(number, full, cat("duplicate key (first on line ", std::to_string(it->second), ")"));
        ConfigValue& value = list_value_->items[item][item_key_index(*list_, *spec)];
        if (auto message = parse_value(*spec, scalar, value))
            return error(number, full, *message);
        value.origin = cat(origin_, ":", std::to_string(number));
        return std::nullopt;
    }

    // The line of `leaf` in the current item, or 0.
    int item_key_line(std::string_view leaf) const
    {
        const auto it = item_key_lines_.find(leaf);
        return it == item_key_lines_.end() ? 0 : it->second;
    }

    // Checks the item just read against the earlier ones.
    std::optional<ConfigError> finish_item()
    {
        if (!item_open_)
            return std::nullopt;
        item_open_ = false;
        const std::size_t item = list_value_->items.size() - 1;
        const int unique_line = item_key_line(list_->unique_key);
        unique_lines_.push_back(unique_line != 0 ? unique_line : item_line_);
        auto problem = check_item(*list_, *list_value_, item, true);
        if (!problem)
            return std::nullopt;
        std::string_view leaf = problem->leaf;
        int line = item_key_line(leaf);
        if (leaf == list_->unique_key) {
            problem->message += cat(" (line ", std::to_string(unique_lines_[problem->other]), ")");
        } else if (line == 0 && item_key_line(list_->lower_key) != 0) {
            // The upper key is at its default: the lower key set is at fault.
            leaf = list_->lower_key;
            line = item_key_line(leaf);
        }
        return error(line != 0 ? line : item_line_, item_key_name(list_->section, item, leaf), problem->message);
    }

    std::optional<ConfigError> finish_list()
    {
        if (list_ == nullptr)
            return std::nullopt;
        if (auto error = finish_item())
            return error;
        const ListSpec* list = list_;
        list_ = nullptr;
        section_.clear();
        if (list_value_->items.empty())
            return error(list_line_, std::string(list->section),
                         cat("empty list; give at least one item ('- ", item_leaf_of(item_keys(list->section).front()),
                             ": ...') on indented lines below it"));
        return std::nullopt;
    }

    std::string origin_;
    std::vector<ConfigValue>& values_;
    std::vector<detail::ListValue>& lists_;
    std::string section_;
    std::size_t section_indent_ = 0;  // 0: not known yet
    std::map<std::string, int, std::less<>> section_lines_;
    std::map<std::string, int, std::less<>> key_lines_;

    // The list section being read (nullptr: none).
    const ListSpec* list_ = nullptr;
    detail::ListValue* list_value_ = nullptr;
    int list_line_ = 0;                              // its "section:" line
    std::size_t dash_indent_ = std::string_view::npos;  // column of its items' '-'
    bool item_open_ = false;
    int item_line_ = 0;                              // the current item's '-' line
    std::size_t item_indent_ = 0;                    // column of the current item's keys
    std::map<std::string, int, std::less<>> item_key_lines_;
    std::vector<int> unique_lines_;                  // per item: line of its unique key (or its '-' line)
};

// Control characters would break the comment to_yaml() writes an origin in.
std::string printable(std::string_view s)
{
    std::string out(s);
    for (char& c : out)
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
            c = '?';
    return out;
}

std::string yaml_quoted(std::string_view s)
{
    std::string out = "\"";
    for (const char c : s) {
        switch (c) {
        case '"': out += "\\\""; break;
        case '\\': out += "\\\\"; break;
        case '\n': out += "\\n"; break;
        case '\t': out += "\\t"; break;
        default: out += c;
        }
    }
    return out + "\"";
}

std::string value_text(const KeySpec& spec, const ConfigValue& value)
{
    switch (spec.type) {
    case ValueType::integer: return std::to_string(value.integer);
    case ValueType::real: return format_number(value.real);
    case ValueType::boolean: return value.boolean ? "true" : "false";
    case ValueType::choice: return value.text;
    case ValueType::text: return yaml_quoted(value.text);
    }
    return "?";
}

// The comment to_yaml() writes after a value: unit, range or choices.
std::string about_text(const KeySpec& spec)
{
    switch (spec.type) {
    case ValueType::integer:
    case ValueType::real: return range_text(spec);
    case ValueType::boolean: return "true or false";
    case ValueType::choice: return list_choices(spec, "|");
    case ValueType::text: return "text";
    }
    return "?";
}

// "tools.1.offset_mm" or "tools[1].offset_mm" -> 1, "offset_mm".
bool parse_item_key(std::string_view key, std::string_view section, std::size_t& index, std::string_view& leaf)
{
    std::string_view rest = key.substr(section.size());
    const bool bracket = rest.starts_with("[");
    if (!bracket && !rest.starts_with("."))
        return false;
    rest.remove_prefix(1);
    const std::size_t end = rest.find(bracket ? ']' : '.');
    if (end == 0 || end == std::string_view::npos)
        return false;
    const std::string_view digits = rest.substr(0, end);
    const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), index);
    if (ec != std::errc() || ptr != digits.data() + digits.size())
        return false;
    rest.remove_prefix(end + 1);
    if (bracket) {
        if (!rest.starts_with("."))
            return false;
        rest.remove_prefix(1);
    }
    leaf = rest;
    return is_valid_name(leaf) && leaf.find('.') == std::string_view::npos;
}

}  // namespace

std::string ConfigError::to_string() const
{
    std::string out = origin;
    if (line > 0)
        out += cat(":", std::to_string(line));
    if (!out.empty())
        out += ": ";
    if (!key.empty())
        out += cat("key ", quote(key), ": ");
    return out + message;
}

Config::Config()
{
    values_.resize(schema().size());
    for (const KeySpec& spec : schema()) {
        ConfigValue& value = values_[index_of(spec)];
        // The schema's defaults are valid (the tests check); a bad one would
        // leave the zero value rather than throw.
        const Scalar scalar{std::string(spec.default_value), false};
        (void)parse_value(spec, scalar, value);
        value.origin = "default";
    }
    // Each list: one item at the item defaults.
    for (const ListSpec& list : list_schema())
        lists_.push_back(detail::ListValue{{default_item(list)}});
}

std::optional<ConfigError> Config::load_text(std::string_view text, std::string_view origin)
{
    std::vector<ConfigValue> staged = values_;
    std::vector<detail::ListValue> staged_lists = lists_;
    TextLoader loader(origin, staged, staged_lists);
    if (auto error = loader.load(text))
        return error;
    values_ = std::move(staged);
    lists_ = std::move(staged_lists);
    return std::nullopt;
}

std::optional<ConfigError> Config::load_file(const std::filesystem::path& path)
{
    const std::string origin = path.string();
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec))
        return ConfigError{origin, 0, "", "cannot read file: it is a directory"};
    errno = 0;
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        const int saved = errno;
        return ConfigError{origin, 0, "",
                           cat("cannot read file: ", saved != 0 ? std::strerror(saved) : "open failed")};
    }
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad())
        return ConfigError{origin, 0, "", "cannot read file: read error"};
    return load_text(text, origin);
}

std::optional<ConfigError> Config::set_override(std::string_view key_equals_value)
{
    const std::string origin = cat("--set ", key_equals_value);
    const std::size_t eq = key_equals_value.find('=');
    const std::string key(trim(key_equals_value.substr(0, eq)));
    if (eq == std::string_view::npos || key.empty())
        return ConfigError{origin, 0, "", "expected KEY=VALUE, e.g. --set closing.radius_px=6"};
    if (const ListSpec* list = find_list(key.substr(0, key.find_first_of(".["))))
        return set_item_override(*list, key, key_equals_value.substr(eq + 1), origin);
    const KeySpec* spec = find_key(key);
    if (spec == nullptr)
        return ConfigError{origin, 0, key, unknown_key_message(key)};
    Scalar scalar;
    if (auto message = parse_scalar(key_equals_value.substr(eq + 1), false, scalar))
        return ConfigError{origin, 0, key, *message};
    ConfigValue value = values_[index_of(*spec)];
    if (auto message = parse_value(*spec, scalar, value))
        return ConfigError{origin, 0, key, *message};
    value.origin = "--set";
    values_[index_of(*spec)] = std::move(value);
    return std::nullopt;
}

std::optional<ConfigError> Config::set_item_override(const ListSpec& list, std::string_view key,
                                                     std::string_view raw_value, const std::string& origin)
{
    const std::string_view section = list.section;
    std::size_t index = 0;
    std::string_view leaf;
    if (!parse_item_key(key, section, index, leaf)) {
        const std::string example(item_leaf_of(item_keys(section)[std::min<std::size_t>(1, item_keys(section).size() - 1)]));
        return ConfigError{origin, 0, std::string(key),
                           cat("expected ", section, ".INDEX.KEY, e.g. --set ", section, ".0.", example, "=...")};
    }
    const std::string full = item_key_name(section, index, leaf);
    const KeySpec* spec = find_item_key(section, leaf);
    if (spec == nullptr)
        return ConfigError{origin, 0, full, unknown_item_key_message(list, index, leaf)};
    detail::ListValue staged = lists_[list_index(list)];
    const std::size_t size = staged.items.size();
    if (index > size)
        return ConfigError{origin, 0, full,
                           cat("no item ", std::to_string(index), "; '", section, "' has ", std::to_string(size),
                               size == 1 ? " item" : " items", " (", section, ".0 .. ", section, ".",
                               std::to_string(size - 1), "), ", section, ".", std::to_string(size),
                               " appends one")};
    if (index == size) {
        if (size >= list.max_items)
            return ConfigError{origin, 0, full,
                               cat("more than ", std::to_string(list.max_items), " items; '", section,
                                   "' holds at most ", std::to_string(list.max_items))};
        std::vector<ConfigValue> item = default_item(list);
        // The appended item's unique key: the lowest value no other item has.
        if (const KeySpec* unique = find_item_key(section, list.unique_key);
            unique != nullptr && unique->type == ValueType::integer) {
            const std::size_t k = item_key_index(list, *unique);
            for (long v = static_cast<long>(unique->min); v <= static_cast<long>(unique->max); ++v) {
                if (std::none_of(staged.items.begin(), staged.items.end(),
                                 [&](const std::vector<ConfigValue>& other) { return other[k].integer == v; })) {
                    item[k].integer = v;
                    break;
                }
            }
        }
        staged.items.push_back(std::move(item));
    }
    Scalar scalar;
    if (auto message = parse_scalar(raw_value, false, scalar))
        return ConfigError{origin, 0, full, *message};
    ConfigValue& value = staged.items[index][item_key_index(list, *spec)];
    if (auto message = parse_value(*spec, scalar, value))
        return ConfigError{origin, 0, full, *message};
    value.origin = "--set";
    if (const auto problem = check_item(list, staged, index, false))
        return ConfigError{origin, 0, full, problem->message};
    lists_[list_index(list)] = std::move(staged);
    return std::nullopt;
}

const ConfigValue& Config::value_for(std::string_view key, std::string_view getter, ValueType type,
                                     ValueType or_type) const
{
    const KeySpec* spec = find_key(key);
    if (spec == nullptr)
        throw std::logic_error(cat("Config::", getter, ": unknown key ", quote(key)));
    if (spec->type != type && spec->type != or_type)
        throw std::logic_error(cat("Config::", getter, ": key ", quote(key), " is ", to_string(spec->type)));
    return values_[index_of(*spec)];
}

long Config::get_int(std::string_view key) const
{
    return value_for(key, "get_int", ValueType::integer, ValueType::integer).integer;
}

double Config::get_real(std::string_view key) const
{
    return value_for(key, "get_real", ValueType::real, ValueType::real).real;
}

bool Config::get_bool(std::string_view key) const
{
    return value_for(key, "get_bool", ValueType::boolean, ValueType::boolean).boolean;
}

const std::string& Config::get_text(std::string_view key) const
{
    return value_for(key, "get_text", ValueType::text, ValueType::choice).text;
}

std::string Config::origin_of(std::string_view key) const
{
    const KeySpec* spec = find_key(key);
    if (spec == nullptr)
        throw std::logic_error(cat("Config::origin_of: unknown key ", quote(key)));
    return values_[index_of(*spec)].origin;
}

const ConfigValue& Config::item_value_for(std::string_view section, std::size_t index, std::string_view key,
                                          std::string_view getter, ValueType type, ValueType or_type) const
{
    const ListSpec* list = find_list(section);
    if (list == nullptr)
        throw std::logic_error(cat("Config::", getter, ": unknown list section ", quote(section)));
    const KeySpec* spec = find_item_key(section, key);
    if (spec == nullptr)
        throw std::logic_error(cat("Config::", getter, ": unknown key ", quote(cat(section, "[].", key))));
    if (spec->type != type && spec->type != or_type)
        throw std::logic_error(cat("Config::", getter, ": key ", quote(spec->key), " is ", to_string(spec->type)));
    const detail::ListValue& value = lists_[list_index(*list)];
    if (index >= value.items.size())
        throw std::logic_error(cat("Config::", getter, ": no item ", quote(item_key_name(section, index, key)),
                                   "; the list has ", std::to_string(value.items.size())));
    return value.items[index][item_key_index(*list, *spec)];
}

std::size_t Config::list_size(std::string_view section) const
{
    const ListSpec* list = find_list(section);
    if (list == nullptr)
        throw std::logic_error(cat("Config::list_size: unknown list section ", quote(section)));
    return lists_[list_index(*list)].items.size();
}

long Config::get_item_int(std::string_view section, std::size_t index, std::string_view key) const
{
    return item_value_for(section, index, key, "get_item_int", ValueType::integer, ValueType::integer).integer;
}

double Config::get_item_real(std::string_view section, std::size_t index, std::string_view key) const
{
    return item_value_for(section, index, key, "get_item_real", ValueType::real, ValueType::real).real;
}

bool Config::get_item_bool(std::string_view section, std::size_t index, std::string_view key) const
{
    return item_value_for(section, index, key, "get_item_bool", ValueType::boolean, ValueType::boolean).boolean;
}

const std::string& Config::get_item_text(std::string_view section, std::size_t index, std::string_view key) const
{
    return item_value_for(section, index, key, "get_item_text", ValueType::text, ValueType::choice).text;
}

std::string Config::item_origin_of(std::string_view section, std::size_t index, std::string_view key) const
{
    const ListSpec* list = find_list(section);
    const KeySpec* spec = find_item_key(section, key);
    if (list == nullptr || spec == nullptr)
        throw std::logic_error(cat("Config::item_origin_of: unknown key ", quote(cat(section, "[].", key))));
    return item_value_for(section, index, key, "item_origin_of", spec->type, spec->type).origin;
}

std::string Config::to_yaml() const
{
    std::string out = "# stemd effective configuration: value  # unit, range or choices; origin\n";
    std::string_view section;
    for (const KeySpec& spec : schema()) {
        const ConfigValue& value = values_[index_of(spec)];
        if (section_of(spec.key) != section) {
            section = section_of(spec.key);
            out += cat(section, ":\n");
        }
        out += cat("  ", leaf_of(spec.key), ": ", value_text(spec, value), "  # ", about_text(spec), "; ",
                   printable(value.origin), "\n");
    }
    // List sections: "- " before each item's first key.
    for (const ListSpec& list : list_schema()) {
        out += cat(list.section, ":\n");
        for (const std::vector<ConfigValue>& item : lists_[list_index(list)].items) {
            const std::span<const KeySpec> keys = item_keys(list.section);
            for (std::size_t k = 0; k < keys.size(); ++k)
                out += cat(k == 0 ? "  - " : "    ", item_leaf_of(keys[k]), ": ", value_text(keys[k], item[k]),
                           "  # ", about_text(keys[k]), "; ", printable(item[k].origin), "\n");
        }
    }
    return out;
}

}  // namespace stemd::config
