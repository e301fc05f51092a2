#include "stemd/config/config.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <map>
#include <span>
#include <sstream>
#include <system_error>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include "stemd/base/unique_fd.hpp"

namespace stemd::config {

namespace {

using detail::ConfigValue;
using detail::ListValue;

constexpr std::size_t kMaxConfigBytes = 1024 * 1024;

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

bool is_valid_name(std::string_view name)
{
    return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
               c == '_' || c == '-' || c == '.';
    });
}

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

std::string list_sections()
{
    return cat(joined(schema(), [](const KeySpec& spec) { return section_of(spec.key); }), ", ",
               joined(list_schema(), [](const ListSpec& list) { return list.section; }));
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

// "unknown key; did you mean 'closing.radius_px'?" and the like.
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

std::string range_text(const KeySpec& spec)
{
    return cat("[", format_number(spec.min), ", ", format_number(spec.max), "]", spec.unit.empty() ? "" : " ",
               spec.unit);
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
    if (const KeySpec* best = nearest(leaf, item_keys(list.section)))
        return cat("unknown key; did you mean ", quote(item_key_name(list.section, index, item_leaf_of(*best))), "?");
    return cat("unknown key; a ", list.section, " item has: ", joined(item_keys(list.section), item_leaf_of));
}
// A value as written: bare, or quoted (a YAML quoted scalar in a file, a
// double-quoted string with \" \\ \n \t escapes after --set KEY=).
struct Scalar {
    std::string text;
    bool quoted = false;
    bool empty() const { return !quoted && text.empty(); }
};

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

std::string yaml_quoted(std::string_view s)
{
    std::string out = "\"";
    for (const char c : s) {
        switch (c) {
        case '"': out += "\\\""; break;
        case '\\': out += "\\\\"; break;
        case '\n': out += "\\n"; break;
        case '\t': out += "\\t"; break;
        default:
            if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {  // YAML's \xXX escape
                constexpr std::string_view kHex = "0123456789abcdef";
                const auto byte = static_cast<unsigned char>(c);
                out += cat("\\x", std::string_view(&kHex[byte >> 4], 1), std::string_view(&kHex[byte & 15], 1));
            } else {
                out += c;
            }
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
double number_of(const KeySpec& spec, const ConfigValue& value)
{
    return spec.type == ValueType::integer ? static_cast<double>(value.integer) : value.real;
}

// The schema's defaults are valid (the tests check); a bad one would leave
// the zero value rather than throw.
ConfigValue default_value(const KeySpec& spec)
{
    ConfigValue value;
    (void)parse_value(spec, Scalar{std::string(spec.default_value), false}, value);
    return value;
}

// An item with every key at its default.
std::vector<ConfigValue> default_item(const ListSpec& list)
{
    std::vector<ConfigValue> item;
    for (const KeySpec& spec : item_keys(list.section))
        item.push_back(default_value(spec));
    return item;
}

// The value of --set KEY=VALUE into `value`; the message of the first problem.
std::optional<std::string> set_value(const KeySpec& spec, std::string_view raw, ConfigValue& value)
{
    Scalar scalar;
    if (auto message = parse_scalar(raw, scalar))
        return message;
    if (auto message = parse_value(spec, scalar, value))
        return message;
    value.origin = "--set";
    return std::nullopt;
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

// Control characters would break a one-line error message, or the comment
// to_yaml() writes an origin in.
std::string printable(std::string_view s)
{
    std::string out(s);
    for (char& c : out)
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
            c = '?';
    return out;
}

// --- the YAML tree -------------------------------------------------------------

// A YAML node with the marks (0-based line, column, offset) yaml-cpp's
// parser gives its events.
struct Node {
    enum class Kind { null, scalar, sequence, map } kind = Kind::null;
    YAML::Mark mark;
    std::string tag;
    std::string text;         // a scalar's value
    std::vector<Node> items;  // a sequence's items; a map's keys and values, alternating (duplicates too)
};

using Kind = Node::Kind;

// Builds the tree of one YAML document from the parser's events, instead of
// YAML::Load: the part built before a syntax error tells where in the file
// the error is. YAML::LoadAll cannot count the documents: yaml-cpp 0.7 reads
// a stray ',' as an endless run of empty documents, and LoadAll allocates
// until it aborts; the loader asks for two documents at the most.
class TreeBuilder : public YAML::EventHandler {
public:
    Node root;
    std::vector<YAML::Mark> documents;  // where each document starts

    void OnDocumentStart(const YAML::Mark& mark) override { documents.push_back(mark); }
    void OnDocumentEnd() override {}
    void OnNull(const YAML::Mark& mark, YAML::anchor_t anchor) override { add({Kind::null, mark, "", "", {}}, anchor); }
    void OnAlias(const YAML::Mark& mark, YAML::anchor_t anchor) override
    {
        // A copy, where YAML::Load would share the node: count what the
        // copies add up to, or aliases of aliases fill the memory.
        nodes_ += anchors_[anchor].second;
        if (nodes_ > kMaxNodes)
            throw YAML::ParserException(mark, cat("more than ", std::to_string(kMaxNodes), " values (aliases)"));
        add(anchors_[anchor].first, 0);
    }
    void OnScalar(const YAML::Mark& mark, const std::string& tag, YAML::anchor_t anchor,
                  const std::string& value) override
    {
        add({Kind::scalar, mark, tag, value, {}}, anchor);
    }
    void OnSequenceStart(const YAML::Mark& mark, const std::string& tag, YAML::anchor_t anchor,
                         YAML::EmitterStyle::value) override
    {
        open({Kind::sequence, mark, tag, "", {}}, anchor);
    }
    void OnSequenceEnd() override { close(); }
    void OnMapStart(const YAML::Mark& mark, const std::string& tag, YAML::anchor_t anchor,
                    YAML::EmitterStyle::value) override
    {
        open({Kind::map, mark, tag, "", {}}, anchor);
    }
    void OnMapEnd() override { close(); }

private:
    static constexpr std::size_t kMaxNodes = 100000;

    Node& add(Node node, YAML::anchor_t anchor)
    {
        ++nodes_;
        Node& added = open_.empty() ? (root = std::move(node)) : open_.back().node->items.emplace_back(std::move(node));
        if (anchor != 0)
            anchors_[anchor] = {added, 1};
        return added;
    }
    void open(Node node, YAML::anchor_t anchor) { open_.push_back({&add(std::move(node), 0), anchor, nodes_}); }
    void close()
    {
        const Open& done = open_.back();
        if (done.anchor != 0)  // an anchored collection: complete only now
            anchors_[done.anchor] = {*done.node, nodes_ - done.nodes + 1};
        open_.pop_back();
    }

    struct Open {
        Node* node;
        YAML::anchor_t anchor;
        std::size_t nodes;  // nodes_ when it started
    };
    std::vector<Open> open_;  // the collections not yet ended
    std::map<YAML::anchor_t, std::pair<Node, std::size_t>> anchors_;  // and how many nodes each holds
    std::size_t nodes_ = 0;
};

// A tab before a line's content, in its indentation or after an item's '-'.
bool tab_in_indentation(std::string_view line)
{
    const std::size_t end = std::min(line.find_first_not_of(" \t-"), line.size());
    const std::string_view lead = line.substr(0, end);
    const bool content = end < line.size() ? line[end] != '#' : lead.find('-') != std::string_view::npos;
    return content && lead.find('\t') != std::string_view::npos;
}

// The tree of a configuration file, checked against the schema, into
// `values` and `lists` (copies the caller commits).
class YamlLoader {
public:
    YamlLoader(std::string_view origin, std::vector<ConfigValue>& values, std::vector<ListValue>& lists)
        : origin_(origin), values_(values), lists_(lists) {}

    std::optional<ConfigError> load(std::string_view text)
    {
        if (text.starts_with("\xEF\xBB\xBF"))  // UTF-8 byte order mark
            text.remove_prefix(3);
        text_ = std::string(text);
        TreeBuilder second;
        std::optional<std::pair<YAML::Mark, std::string>> failure;
        try {
            std::istringstream in(text_);
            YAML::Parser parser(in);
            if (parser.HandleNextDocument(tree_))
                parser.HandleNextDocument(second);
        } catch (const YAML::Exception& e) {
            failure.emplace(e.mark, e.msg);
        }
        // A tab in the indentation: yaml-cpp calls it an "illegal map value"
        // or an "illegal tab", and takes one inside a quoted or a [ ] { }
        // value; one clear error for all of them.
        int line = 1;
        for (std::size_t at = 0; at < text_.size(); ++line) {
            const std::size_t end = std::min(text_.find('\n', at), text_.size());
            if (tab_in_indentation(line_text(at, end)))
                return error(line, key_at(line), "tab in the indentation; indent with spaces");
            at = end + 1;
        }
        if (failure)
            return syntax_error(failure->first, failure->second);
        if (!second.documents.empty())
            return error(line_of(second.documents.front()), "",
                         "more than one YAML document ('---'); a config file holds one map of sections (a ',' "
                         "outside [ ] or { } starts a document too)");
        const Node& root = tree_.root;
        if (root.kind == Kind::null)
            return std::nullopt;
        if (root.kind != Kind::map)
            return error(line_of(root), "",
                         cat("expected 'section:' lines (a map of sections) at the top level, got ", what(root)));
        for (std::size_t i = 0; i + 1 < root.items.size(); i += 2)
            if (auto error = section(root.items[i], root.items[i + 1]))
                return error;
        return std::nullopt;
    }

private:
    ConfigError error(int line, std::string_view key, std::string_view message) const
    {
        return ConfigError{origin_, line, printable(key), printable(message)};
    }

    // 1-based; a mark without a position (the end of the input): the last line.
    int line_of(const YAML::Mark& mark) const
    {
        if (mark.line >= 0)
            return mark.line + 1;
        return static_cast<int>(std::count(text_.begin(), text_.end(), '\n')) +
               (text_.empty() || text_.back() == '\n' ? 0 : 1);
    }

    int line_of(const Node& node) const { return line_of(node.mark); }

    std::size_t offset_of(const Node& node) const
    {
        return node.mark.pos >= 0 ? std::min(static_cast<std::size_t>(node.mark.pos), text_.size()) : text_.size();
    }

    std::string_view line_text(std::size_t begin, std::size_t end) const
    {
        std::string_view line = std::string_view(text_).substr(begin, end - begin);
        return line.ends_with('\r') ? line.substr(0, line.size() - 1) : line;
    }

    // Line `line` (1-based) of the text.
    std::string_view line_text(int line) const
    {
        std::size_t begin = 0;
        for (int l = 1; l < line && begin < text_.size(); ++l)
            begin = std::min(text_.find('\n', begin), text_.size() - 1) + 1;
        return line_text(begin, std::min(text_.find('\n', begin), text_.size()));
    }

    // The key a line holds, as errors name it ("closing.radius_px",
    // "tools[1].offset_mm", a section), or "" if the line does not say: the
    // section and the item from the tree above the line, the name from the
    // line itself (yaml-cpp stops before the key of a line it cannot read).
    std::string key_at(int line) const
    {
        std::string_view text = line_text(line);
        const std::size_t indent = std::min(text.find_first_not_of(kWhitespace), text.size());
        std::size_t dashes = 0;
        const auto dash = [&] {
            return text.starts_with('-') && (text.size() == 1 || kWhitespace.find(text[1]) != std::string_view::npos);
        };
        for (text.remove_prefix(indent); dash(); ++dashes)
            text = trim(text.substr(1));
        const std::string name(trim(text.substr(0, text.find(':'))));
        if (text.find(':') == std::string_view::npos || !is_valid_name(name))
            return "";
        if (indent == 0 && dashes == 0)
            return name;
        const Node& root = tree_.root;
        const Node* section = nullptr;  // the last section above the line, and its value
        const Node* value = nullptr;
        for (std::size_t i = 0; root.kind == Kind::map && i < root.items.size(); i += 2)
            if (root.items[i].mark.line + 1 < line) {
                section = &root.items[i];
                value = i + 1 < root.items.size() ? &root.items[i + 1] : nullptr;
            }
        if (section == nullptr)
            return "";
        const ListSpec* list = find_list(section->text);
        if (list == nullptr)
            return cat(section->text, ".", name);
        std::size_t items = dashes > 0 ? 1 : 0;  // the items started above the line, and this one
        if (value != nullptr && value->kind == Kind::sequence)
            for (const Node& item : value->items)
                items += item.mark.line + 1 < line ? 1 : 0;
        return items == 0 ? std::string(list->section) : item_key_name(list->section, items - 1, name);
    }

    ConfigError syntax_error(const YAML::Mark& mark, const std::string& message) const
    {
        const int line = line_of(mark);
        const std::string key = key_at(line);
        // "key: -": the dash starts a YAML list item, not the text "-".
        if (message == YAML::ErrorMsg::BLOCK_ENTRY && !key.empty())
            return error(line, key, "invalid YAML: a bare '-' starts a list item, not a value; write \"-\" "
                                    "(double-quoted) for a dash");
        return error(line, key, cat("invalid YAML: ", message, indentation_hint(line)));
    }

    // " (inconsistent indentation? ...)" when a line starts in a column no
    // key above it starts in, after a key with a value (so that it cannot
    // open a deeper level); "" otherwise.
    std::string indentation_hint(int line) const
    {
        const std::string_view text = line_text(line);
        const std::size_t indent = text.find_first_not_of(' ');
        if (indent == std::string_view::npos || text[indent] == '#')
            return "";
        std::vector<std::size_t> columns;
        const Node* last_key = nullptr;
        const Node* last_value = nullptr;
        const auto above = [&](const Node& node) { return node.mark.line >= 0 && node.mark.line + 1 < line; };
        const auto visit = [&](const auto& self, const Node& node) -> void {
            if (!above(node))
                return;
            if (node.kind != Kind::scalar)
                columns.push_back(static_cast<std::size_t>(node.mark.column));
            for (std::size_t i = 0; i < node.items.size(); ++i) {
                if (node.kind == Kind::map && i % 2 == 0 && above(node.items[i])) {
                    last_key = &node.items[i];
                    last_value = i + 1 < node.items.size() ? &node.items[i + 1] : nullptr;
                    columns.push_back(static_cast<std::size_t>(last_key->mark.column));
                }
                self(self, node.items[i]);
            }
        };
        visit(visit, tree_.root);
        if (last_value == nullptr || last_value->kind != Kind::scalar ||
            std::find(columns.begin(), columns.end(), indent) != columns.end())
            return "";
        return cat(" (inconsistent indentation? ", std::to_string(indent), " spaces here, ",
                   std::to_string(last_key->mark.column), " on the line above)");
    }

    // "a list", "a map", "'text'": a node where something else belongs.
    static std::string what(const Node& node)
    {
        switch (node.kind) {
        case Kind::sequence: return "a list";
        case Kind::map: return "a map";
        case Kind::null: return "nothing";
        case Kind::scalar: break;
        }
        return quote(node.text);
    }

    // The name of a map key, or the error for a key that is not one.
    std::optional<ConfigError> not_a_name(const Node& key, std::string_view where) const
    {
        if (key.kind == Kind::scalar && !key.text.empty())
            return std::nullopt;
        return error(line_of(key), where, cat("expected a key name, got ", what(key)));
    }

    // "key: ~" and "key: null": YAML for no value, like "key:" (whose null's
    // mark is where the next token starts).
    bool explicit_null(const Node& value) const
    {
        const std::string_view at = std::string_view(text_).substr(offset_of(value));
        return value.kind == Kind::null &&
               (at.starts_with("~") || at.starts_with("null") || at.starts_with("Null") || at.starts_with("NULL"));
    }

    // yaml-cpp 0.7 reads a quoted string the input ends in as if closed.
    bool unterminated(std::size_t pos) const
    {
        const char q = text_[pos];
        for (std::size_t i = pos + 1; i < text_.size(); ++i) {
            if (q == '"' && text_[i] == '\\')
                ++i;
            else if (text_[i] == q && !(q == '\'' && i + 1 < text_.size() && text_[i + 1] == '\''))
                return false;
            else if (text_[i] == q)
                ++i;  // '' in a single-quoted string
        }
        return true;
    }

    // A scalar (or null) value as the schema checks read it.
    std::optional<std::string> scalar_of(const Node& value, int key_line, Scalar& out) const
    {
        out = Scalar{};
        if (value.kind == Kind::null) {
            if (line_of(value) == key_line && explicit_null(value))
                return std::string("empty value ('~' and 'null' are YAML for no value; quote them for the text)");
            return std::nullopt;
        }
        if (value.tag != "?" && value.tag != "!")
            return cat("YAML tags are not supported (", quote(value.tag),
                       "); write a plain value or a double-quoted string");
        out.text = value.text;
        out.quoted = value.tag == "!";
        const std::size_t pos = offset_of(value);
        if (out.quoted && pos < text_.size() && (text_[pos] == '"' || text_[pos] == '\'') && unterminated(pos))
            return std::string(text_[pos] == '"' ? "unterminated double-quoted string"
                                                  : "unterminated single-quoted string");
        return std::nullopt;
    }

    // A scalar on a line of its own where "key: value" belongs: "radius_px 6",
    // or "radius_px:6" (YAML needs the space).
    ConfigError not_key_value(const Node& value, std::string_view key_prefix, std::string_view expected) const
    {
        const std::size_t colon = value.text.find(':');
        if (colon != std::string::npos && is_valid_name(value.text.substr(0, colon)))
            return error(line_of(value), cat(key_prefix, value.text.substr(0, colon)), "expected a space after ':'");
        return error(line_of(value), "", cat("expected ", expected, ", got ", quote(value.text)));
    }

    std::optional<ConfigError> section(const Node& key, const Node& value)
    {
        if (auto failure = not_a_name(key, ""))
            return failure;
        const int line = line_of(key);
        const std::string& section = key.text;
        const ListSpec* list = find_list(section);
        if (value.kind == Kind::scalar) {
            if (line_of(value) > line)  // the section's line, then a line without "key: "
                return list != nullptr
                    ? error(line_of(value), section,
                            cat("expected a list of items ('- key: value' lines) under '", section, ":'"))
                    : not_key_value(value, cat(section, "."), "'section:' or 'key: value'");
            if (list != nullptr)
                return error(line, section, cat("a list section cannot have a value; put its items ('- ",
                                                item_leaf_of(item_keys(section).front()),
                                                ": ...') on indented lines below it"));
            if (is_known_section(section))
                return error(line, section, "a section cannot have a value; put its keys on indented lines below it");
            if (find_key(section) != nullptr)
                return error(line, section, cat("key outside a section; write '", section_of(section),
                                                ":' and indent '", leaf_of(section), ": ...' below it"));
            for (const KeySpec& spec : schema())
                if (leaf_of(spec.key) == section)
                    return error(line, section, cat("key outside a section; indent it under '",
                                                    section_of(spec.key), ":'"));
            return error(line, section,
                         cat("key outside a section; indent it under its section (", list_sections(), ")"));
        }
        if (!is_known_section(section) && list == nullptr)
            return error(line, section, cat("unknown section; the sections are: ", list_sections()));
        const auto [it, inserted] = key_lines_.emplace(section, line);
        if (!inserted)
            return error(line, section, cat("duplicate section (first on line ", std::to_string(it->second), ")"));
        if (list != nullptr)
            return list_section(*list, line, value);
        if (value.kind == Kind::null)
            return error(line, section, "empty section; put its keys ('key: value') on indented lines below it, "
                                        "or remove the line");
        if (value.kind == Kind::sequence) {
            std::string lists;
            for (const ListSpec& other : list_schema())
                lists += cat(lists.empty() ? "" : ", ", quote(other.section));
            return error(line_of(value), section, cat("expected 'key: value' lines under '", section,
                                                      ":', got a list ('- ' items); only ", lists, " holds a list"));
        }
        for (std::size_t i = 0; i + 1 < value.items.size(); i += 2) {
            const Node& leaf = value.items[i];
            if (auto failure = not_a_name(leaf, section))
                return failure;
            const std::string full = cat(section, ".", leaf.text);
            const KeySpec* spec = find_key(full);
            if (auto error = key_value(full, spec, spec ? "" : unknown_key_message(full), leaf, value.items[i + 1],
                                       "a section", spec ? &values_[index_of(*spec)] : nullptr))
                return error;
        }
        return std::nullopt;
    }

    // One "key: value" of a section or a list item, named `full`: `spec` its
    // row (nullptr: an unknown key, `unknown` says so), `stored` its value.
    std::optional<ConfigError> key_value(const std::string& full, const KeySpec* spec, const std::string& unknown,
                                         const Node& key, const Node& value, std::string_view holder,
                                         ConfigValue* stored)
    {
        const int line = line_of(key);
        const std::string rule = cat("; ", holder, " holds only 'key: value' lines");
        if (value.kind == Kind::map && !value.items.empty()) {
            const Node& first = value.items.front();
            return error(line_of(first), cat(full, ".", first.kind == Kind::scalar ? first.text : "?"),
                         cat("nesting deeper than one level", rule));
        }
        if (value.kind == Kind::map || value.kind == Kind::sequence)
            return error(line_of(value), full, cat("expected a value, got ", what(value), rule));
        if (spec == nullptr)
            return error(line, full, unknown);
        const auto [it, inserted] = key_lines_.emplace(full, line);
        if (!inserted)
            return error(line, full, cat("duplicate key (first on line ", std::to_string(it->second), ")"));
        Scalar scalar;
        if (auto message = scalar_of(value, line, scalar))
            return error(line, full, *message);
        if (auto message = parse_value(*spec, scalar, *stored))
            return error(line, full, *message);
        stored->origin = cat(origin_, ":", std::to_string(line));
        return std::nullopt;
    }

    std::optional<ConfigError> list_section(const ListSpec& list, int line, const Node& value)
    {
        const std::string section(list.section);
        const std::string first_key(item_leaf_of(item_keys(section).front()));
        if (value.kind == Kind::map)
            return error(line_of(value), section,
                         cat("expected a list of items ('- key: value' lines) under '", section, ":'"));
        if (value.items.empty())
            return error(line, section, cat("empty list; give at least one item ('- ", first_key,
                                            ": ...') on indented lines below it"));
        // The file's list replaces the whole list.
        ListValue& items = lists_[list_index(list)];
        items.items.clear();
        std::vector<int> item_lines;
        for (std::size_t i = 0; i < value.items.size(); ++i) {
            const Node& item = value.items[i];
            const std::string name = item_name(section, i);
            // A null item's mark is where the next token starts: its line is
            // that of the '-' before it.
            const std::size_t dash = offset_of(item) == 0 ? std::string::npos : text_.rfind('-', offset_of(item) - 1);
            const int item_line = item.kind == Kind::null && dash != std::string::npos && dash >= offset_of(value)
                ? static_cast<int>(std::count(text_.begin(), text_.begin() + static_cast<long>(dash), '\n')) + 1
                : line_of(item);
            if (i >= list.max_items)
                return error(item_line, name, cat("more than ", std::to_string(list.max_items), " items; '",
                                                  section, "' holds at most ", std::to_string(list.max_items)));
            if (item.kind == Kind::null)
                return error(item_line, name, cat("empty item; an item starts with '- ' and its first key ('- ",
                                                  first_key, ": ...')"));
            if (item.kind == Kind::scalar) {
                if (item.tag == "?" && item.text.find(':') != std::string::npos &&
                    is_valid_name(item.text.substr(0, item.text.find(':'))))
                    return not_key_value(item, cat(name, "."), "'- key: value'");
                return error(item_line, name, cat("expected '- key: value' (an item is 'key: value' lines), got ",
                                                  quote(item.text)));
            }
            if (item.kind == Kind::sequence)
                return error(item_line, name, "expected '- key: value' (an item is 'key: value' lines), got a list");
            items.items.push_back(default_item(list));
            for (std::size_t k = 0; k + 1 < item.items.size(); k += 2) {
                const Node& leaf = item.items[k];
                if (auto failure = not_a_name(leaf, name))
                    return failure;
                const KeySpec* spec = find_item_key(section, leaf.text);
                if (auto error = key_value(item_key_name(section, i, leaf.text), spec,
                                           spec ? "" : unknown_item_key_message(list, i, leaf.text), leaf,
                                           item.items[k + 1], "a list item",
                                           spec ? &items.items[i][item_key_index(list, *spec)] : nullptr))
                    return error;
            }
            // The item against the earlier ones; a key's line, or the item's
            // if the file leaves the key out.
            item_lines.push_back(item_line);
            const auto line_of_key = [&](std::size_t index, std::string_view leaf) {
                const auto it = key_lines_.find(item_key_name(section, index, leaf));
                return it == key_lines_.end() ? item_lines[index] : it->second;
            };
            auto problem = check_item(list, items, i, true);
            if (!problem)
                continue;
            std::string_view leaf = problem->leaf;
            if (leaf == list.unique_key)
                problem->message += cat(" (line ", std::to_string(line_of_key(problem->other, leaf)), ")");
            else if (!key_lines_.contains(item_key_name(section, i, leaf)) &&
                     key_lines_.contains(item_key_name(section, i, list.lower_key)))
                leaf = list.lower_key;  // the upper key at its default: the lower key set is at fault
            return error(line_of_key(i, leaf), item_key_name(section, i, leaf), problem->message);
        }
        return std::nullopt;
    }

    std::string origin_;
    std::vector<ConfigValue>& values_;
    std::vector<ListValue>& lists_;
    std::string text_;
    TreeBuilder tree_;
    std::map<std::string, int, std::less<>> key_lines_;  // sections and keys ("tools[1].id"): their lines
};

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

// "Real, mm, range [0, 50]." and the like: what a documented key accepts.
std::string type_text(const KeySpec& spec)
{
    switch (spec.type) {
    case ValueType::integer:
    case ValueType::real:
        return cat(spec.type == ValueType::integer ? "Integer, " : "Real, ", spec.unit, spec.unit.empty() ? "" : ", ",
                   "range [", format_number(spec.min), ", ", format_number(spec.max), "].");
    case ValueType::boolean: return "Boolean.";
    case ValueType::choice: return cat("Choice: ", list_choices(spec, " | "), ".");
    case ValueType::text: return "Text.";
    }
    return "";
}

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

constexpr std::string_view kDocumentedHeader =
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
    "# --config FILE and --set section.key=value (e.g. --set closing.radius_px=6);\n"
    "# a --set given later wins over the file.\n"
    "#\n"
    "# Generated from the schema (src/config/schema.cpp), like the README's table:\n"
    "#   stemd-config yaml --out config/stemd.yaml\n";

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
    for (const KeySpec& spec : schema())
        values_.push_back(default_value(spec));
    // Each list: one item at the item defaults.
    for (const ListSpec& list : list_schema())
        lists_.push_back(detail::ListValue{{default_item(list)}});
}

std::optional<ConfigError> Config::load_text(std::string_view text, std::string_view origin)
{
    std::vector<ConfigValue> staged = values_;
    std::vector<detail::ListValue> staged_lists = lists_;
    YamlLoader loader(origin, staged, staged_lists);
    if (auto error = loader.load(text))
        return error;
    values_ = std::move(staged);
    lists_ = std::move(staged_lists);
    return std::nullopt;
}

std::optional<ConfigError> Config::load_file(const std::filesystem::path& path)
{
    const std::string origin = path.string();
    if (origin.empty())
        return ConfigError{"--config", 0, "", "empty file name"};
    // O_NONBLOCK: opening a FIFO must not hang the start (SIGTERM is only
    // taken later); a FIFO or a device is refused, a config is a file.
    const auto unreadable = [&](std::string_view why) {
        return ConfigError{origin, 0, "", cat("cannot read file: ", why)};
    };
    base::UniqueFd fd(::open(origin.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK));
    struct stat st {};
    if (!fd.valid() || ::fstat(fd.get(), &st) != 0)
        return unreadable(std::strerror(errno));
    if (S_ISDIR(st.st_mode))
        return unreadable("it is a directory");
    if (!S_ISREG(st.st_mode))
        return unreadable("not a regular file (a FIFO or a device)");
    // Read with a cap: a config is a few kB, and /dev/zero or a FIFO that
    // never ends must not fill the memory.
    std::string text;
    std::array<char, 4096> chunk;
    for (;;) {
        const ssize_t n = ::read(fd.get(), chunk.data(), chunk.size());
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0)
            return unreadable(cat("read error: ", std::strerror(errno)));
        if (n == 0)
            break;
        if (text.size() + static_cast<std::size_t>(n) > kMaxConfigBytes)
            return unreadable(
                cat("larger than ", std::to_string(kMaxConfigBytes / 1024), " KiB; is it a configuration file?"));
        text.append(chunk.data(), static_cast<std::size_t>(n));
    }
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
    ConfigValue value = values_[index_of(*spec)];
    if (auto message = set_value(*spec, key_equals_value.substr(eq + 1), value))
        return ConfigError{origin, 0, key, *message};
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
    if (auto message = set_value(*spec, raw_value, staged.items[index][item_key_index(list, *spec)]))
        return ConfigError{origin, 0, full, *message};
    if (const auto problem = check_item(list, staged, index, false))
        return ConfigError{origin, 0, full, problem->message};
    lists_[list_index(list)] = std::move(staged);
    return std::nullopt;
}

Settings Config::settings() const
{
    Settings settings;
    for (const KeySpec& spec : schema())
        spec.store(spec, settings, 0, values_[index_of(spec)]);
    for (const ListSpec& list : list_schema()) {
        const detail::ListValue& value = lists_[list_index(list)];
        list.resize(settings, value.items.size());
        const std::span<const KeySpec> keys = item_keys(list.section);
        for (std::size_t i = 0; i < value.items.size(); ++i)
            for (std::size_t k = 0; k < keys.size(); ++k)
                keys[k].store(keys[k], settings, i, value.items[i][k]);
    }
    return settings;
}

std::string Config::origin_of(std::string_view key) const
{
    const KeySpec* spec = find_key(key);
    if (spec != nullptr)
        return values_[index_of(*spec)].origin;
    // A list item's key, as errors name it: "tools[1].offset_mm".
    const ListSpec* list = find_list(key.substr(0, key.find_first_of(".[")));
    std::size_t index = 0;
    std::string_view leaf;
    if (list == nullptr || !parse_item_key(key, list->section, index, leaf))
        return "";
    return item_origin_of(list->section, index, leaf);
}

std::string Config::blame(std::string_view key, std::string_view message) const
{
    const std::string origin = origin_of(key);
    if (origin != "default" && origin != "--set" && !origin.empty())
        return cat(origin, ": key ", quote(key), ": ", message);
    return cat("key ", quote(key), " (", origin.empty() ? "unknown" : origin, "): ", message);
}

std::size_t Config::list_size(std::string_view section) const
{
    const ListSpec* list = find_list(section);
    return list == nullptr ? 0 : lists_[list_index(*list)].items.size();
}

std::string Config::item_origin_of(std::string_view section, std::size_t index, std::string_view key) const
{
    const ListSpec* list = find_list(section);
    const KeySpec* spec = find_item_key(section, key);
    if (list == nullptr || spec == nullptr || index >= lists_[list_index(*list)].items.size())
        return "";
    return lists_[list_index(*list)].items[index][item_key_index(*list, *spec)].origin;
}

std::string Config::to_yaml(YamlComments comments) const
{
    const bool documented = comments == YamlComments::documentation;
    std::string out = documented ? std::string(kDocumentedHeader)
                                 : "# stemd effective configuration: value  # unit, range or choices; origin\n";
    const auto section_heading = [&](std::string_view name, std::string_view list_help) {
        if (!documented) {
            out += cat(name, ":\n");
            return;
        }
        for (const SectionSpec& section : section_schema())
            if (section.name == name && !section.group.empty())
                out += cat("\n# --- ", section.group, " ---\n");
        out += "\n";
        for (const SectionSpec& section : section_schema())
            if (section.name == name)
                out += wrapped_comment("", section.help.empty() ? cat(list_help, ".") : std::string(section.help));
        out += cat(name, ":\n");
    };
    // One key: its documentation above it, or its range and origin after it.
    const auto key_line = [&](std::string_view indent, std::string_view first, const KeySpec& spec,
                              const ConfigValue& value) {
        if (documented)
            out += cat(wrapped_comment(indent, cat(spec.help, ".")), indent, "# ", type_text(spec), "\n");
        out += cat(first, item_list_of(spec).empty() ? leaf_of(spec.key) : item_leaf_of(spec), ": ",
                   config::value_text(spec, value));
        out += documented ? "\n" : cat("  # ", about_text(spec), "; ", printable(value.origin), "\n");
    };
    std::string_view section;
    for (const KeySpec& spec : schema()) {
        if (section_of(spec.key) != section) {
            section = section_of(spec.key);
            section_heading(section, "");
        }
        key_line("  ", "  ", spec, values_[index_of(spec)]);
    }
    // List sections: "- " before each item's first key.
    for (const ListSpec& list : list_schema()) {
        section_heading(list.section, list.help);
        for (const std::vector<ConfigValue>& item : lists_[list_index(list)].items) {
            const std::span<const KeySpec> keys = item_keys(list.section);
            for (std::size_t k = 0; k < keys.size(); ++k)
                key_line("    ", k == 0 ? "  - " : "    ", keys[k], item[k]);
        }
    }
    return out;
}

}  // namespace stemd::config
