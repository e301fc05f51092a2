#include "values.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <system_error>

namespace stemd::config::detail {

namespace {

// "a, b, c": the names `name_of` gives, each once, in order.
template <class Range, class NameOf>
std::string joined(const Range& range, NameOf name_of)
{
    std::string out;
    std::string_view previous;
    for (const auto& element : range) {
        const std::string_view name = name_of(element);
        if (name.empty() || name == previous)
            continue;
        out += cat(out.empty() ? "" : ", ", name);
        previous = name;
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

// The key of `keys` nearest `name` (a full key, or an item key's leaf), if
// it is at most three edits away.
const KeySpec* nearest(std::string_view name, std::span<const KeySpec> keys)
{
    const KeySpec* best = nullptr;
    std::size_t best_distance = 4;
    for (const KeySpec& spec : keys) {
        // Lengths further apart than that are further apart in edits too: a
        // long line mistaken for a key costs nothing.
        const std::string_view candidate = item_leaf_of(spec);
        const std::size_t longer = std::max(name.size(), candidate.size());
        if (longer - std::min(name.size(), candidate.size()) >= best_distance)
            continue;
        if (const std::size_t d = edit_distance(name, candidate); d < best_distance) {
            best = &spec;
            best_distance = d;
        }
    }
    return best;
}

// The escapes of a double-quoted string that --set reads and to_yaml()
// writes: \" \\ \n \t (to_yaml() writes other control bytes as YAML's \xXX).
struct Escape {
    char letter;
    char value;
};
constexpr Escape kEscapes[] = {{'"', '"'}, {'\\', '\\'}, {'n', '\n'}, {'t', '\t'}};

// Parses the text after "=" of --set KEY=VALUE (not YAML: '#' is literal and
// a lone "-" is a plain value, "standard output").
std::optional<std::string> parse_scalar(std::string_view raw, Scalar& out)
{
    raw = trim(raw);
    out = Scalar{};
    if (raw.empty())
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
            const auto escape = std::find_if(std::begin(kEscapes), std::end(kEscapes),
                                             [&](const Escape& e) { return e.letter == raw[i]; });
            if (escape == std::end(kEscapes))
                return cat("unsupported escape '\\", std::string_view(&raw[i], 1),
                           "' in a double-quoted string (use \\\", \\\\, \\n or \\t)");
            out.text += escape->value;
        }
        if (i >= raw.size())
            return std::string("unterminated double-quoted string");
        const std::string_view after = trim(raw.substr(i + 1));
        if (!after.empty())
            return cat("unexpected text after the closing quote: ", quote(after));
        return std::nullopt;
    }
    // YAML syntax a value given this way does not support would otherwise be
    // read as text.
    constexpr std::string_view kIndicators = "[]{}&*!|>'%@`,?";
    if (kIndicators.find(raw.front()) != std::string_view::npos || raw.starts_with("- "))
        return cat("unsupported YAML syntax ", quote(raw), "; write a plain value or a double-quoted string");
    out.text = std::string(raw);
    return std::nullopt;
}

std::string yaml_quoted(std::string_view s)
{
    std::string out = "\"";
    for (const char c : s) {
        const auto escape = std::find_if(std::begin(kEscapes), std::end(kEscapes),
                                         [&](const Escape& e) { return e.value == c; });
        const auto byte = static_cast<unsigned char>(c);
        constexpr std::string_view kHex = "0123456789abcdef";
        if (escape != std::end(kEscapes))
            out += cat("\\", std::string_view(&escape->letter, 1));
        else if (byte < 0x20 || byte == 0x7f)
            out += cat("\\x", kHex.substr(byte >> 4, 1), kHex.substr(byte & 15, 1));
        else
            out += c;
    }
    return out + "\"";
}

std::string range_text(const KeySpec& spec)
{
    return cat(bounds_text(spec), spec.unit.empty() ? "" : " ", spec.unit);
}

double number_of(const KeySpec& spec, const ConfigValue& value)
{
    return spec.type == ValueType::integer ? static_cast<double>(value.integer) : value.real;
}

}  // namespace

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

bool is_valid_name(std::string_view name)
{
    return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
               c == '_' || c == '-' || c == '.';
    });
}

std::string list_sections()
{
    return cat(joined(schema(), [](const KeySpec& spec) { return section_of(spec.key); }), ", ",
               joined(list_schema(), [](const ListSpec& list) { return list.section; }));
}

std::string unknown_key_message(std::string_view key)
{
    if (const KeySpec* best = nearest(key, schema()))
        return cat("unknown key; did you mean ", quote(best->key), "?");
    // The same name in another section.
    for (const KeySpec& spec : schema())
        if (leaf_of(spec.key) == leaf_of(key))
            return cat("unknown key; did you mean ", quote(spec.key), "?");
    const std::string_view section = section_of(key);
    if (is_known_section(section))
        return cat("unknown key; section ", quote(section), " has: ", joined(schema(), [&](const KeySpec& spec) {
                       return section_of(spec.key) == section ? leaf_of(spec.key) : std::string_view{};
                   }));
    return cat("unknown key; the sections are: ", list_sections());
}

std::string too_many_items(const ListSpec& list)
{
    const std::string most = std::to_string(list.max_items);
    return cat("more than ", most, " items; '", list.section, "' holds at most ", most);
}

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
    if (const KeySpec* best = nearest(leaf, item_keys(list.section)))
        return cat("unknown key; did you mean ", quote(item_key_name(list.section, index, item_leaf_of(*best))), "?");
    return cat("unknown key; a ", list.section, " item has: ", joined(item_keys(list.section), item_leaf_of));
}
const ListSpec* list_of_key(std::string_view key)
{
    return find_list(key.substr(0, key.find_first_of(".[")));
}

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

// The schema's defaults are valid (the tests check); a bad one would leave
// the zero value rather than throw.
ConfigValue default_value(const KeySpec& spec)
{
    ConfigValue value;
    (void)parse_value(spec, Scalar{std::string(spec.default_value), false}, value);
    return value;
}

std::vector<ConfigValue> default_item(const ListSpec& list)
{
    std::vector<ConfigValue> item;
    for (const KeySpec& spec : item_keys(list.section))
        item.push_back(default_value(spec));
    return item;
}

std::optional<std::string> set_value(const KeySpec& spec, std::string_view raw, std::string_view source,
                                     ConfigValue& value)
{
    Scalar scalar;
    if (auto message = parse_scalar(raw, scalar))
        return message;
    if (auto message = parse_value(spec, scalar, value))
        return message;
    value.origin = std::string(source);
    return std::nullopt;
}

std::optional<ItemProblem> check_item(const ListSpec& list, const ListValue& value, std::size_t index,
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

std::string printable(std::string_view s)
{
    std::string out(s);
    for (char& c : out)
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
            c = '?';
    return out;
}

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

}  // namespace stemd::config::detail
