#include "stemd/runtime/config.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
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
    constexpr std::string_view kIndicators = "[]{}&*!|>'%@`,?";
    if (kIndicators.find(raw.front()) != std::string_view::npos || raw == "-" ||
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

// Parses configuration text into `values` (a copy the caller commits).
class TextLoader {
public:
    TextLoader(std::string_view origin, std::vector<ConfigValue>& values)
        : origin_(origin), values_(values) {}

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
        return std::nullopt;
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
        if (!scalar.empty()) {
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
        if (!is_known_section(section))
            return error(number, section, cat("unknown section; the sections are: ", list_sections()));
        const auto [it, inserted] = section_lines_.emplace(section, number);
        if (!inserted)
            return error(number, section, cat("duplicate section (first on line ", std::to_string(it->second), ")"));
        section_ = section;
        section_indent_ = 0;
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
            // "key:" followed by deeper lines is a nested mapping.
            for (std::size_t j = index + 1; j < lines.size(); ++j) {
                const LineParts next = split_line(lines[j]);
                if (!next.content)
                    continue;
                if (next.indent > p.indent)
                    return error(static_cast<int>(j) + 1, cat(full, ".", next.name),
                                 "nesting deeper than one level; a section holds only 'key: value' lines");
                break;
            }
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

    std::string origin_;
    std::vector<ConfigValue>& values_;
    std::string section_;
    std::size_t section_indent_ = 0;  // 0: not known yet
    std::map<std::string, int, std::less<>> section_lines_;
    std::map<std::string, int, std::less<>> key_lines_;
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
}

std::optional<ConfigError> Config::load_text(std::string_view text, std::string_view origin)
{
    std::vector<ConfigValue> staged = values_;
    TextLoader loader(origin, staged);
    if (auto error = loader.load(text))
        return error;
    values_ = std::move(staged);
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
        std::string text;
        std::string about;
        switch (spec.type) {
        case ValueType::integer:
            text = std::to_string(value.integer);
            about = range_text(spec);
            break;
        case ValueType::real:
            text = format_number(value.real);
            about = range_text(spec);
            break;
        case ValueType::boolean:
            text = value.boolean ? "true" : "false";
            about = "true or false";
            break;
        case ValueType::choice:
            text = value.text;
            about = list_choices(spec, "|");
            break;
        case ValueType::text:
            text = yaml_quoted(value.text);
            about = "text";
            break;
        }
        out += cat("  ", leaf_of(spec.key), ": ", text, "  # ", about, "; ", printable(value.origin), "\n");
    }
    return out;
}

}  // namespace stemd::config
