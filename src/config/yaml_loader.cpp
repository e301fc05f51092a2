#include "yaml_loader.hpp"

#include <algorithm>
#include <map>
#include <sstream>

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include "values.hpp"

namespace stemd::config::detail {

namespace {

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
        for (std::size_t at = 0; at < text_.size(); at = std::min(text_.find('\n', at), text_.size()) + 1) {
            const std::string_view line = std::string_view(text_).substr(at, text_.find('\n', at) - at);
            lines_.push_back(line.ends_with('\r') ? line.substr(0, line.size() - 1) : line);
        }
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
        for (int line = 1; line <= static_cast<int>(lines_.size()); ++line)
            if (tab_in_indentation(line_text(line)))
                return error(line, key_at(line), "tab in the indentation; indent with spaces");
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
        return mark.line >= 0 ? mark.line + 1 : static_cast<int>(lines_.size());
    }

    int line_of(const Node& node) const { return line_of(node.mark); }

    std::size_t offset_of(const Node& node) const
    {
        return node.mark.pos >= 0 ? std::min(static_cast<std::size_t>(node.mark.pos), text_.size()) : text_.size();
    }

    // Line `line` (1-based) of the text, without its line break.
    std::string_view line_text(int line) const
    {
        return line >= 1 && line <= static_cast<int>(lines_.size()) ? lines_[static_cast<std::size_t>(line - 1)]
                                                                    : std::string_view();
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
        // "listen: [::1]:8080": '[' or '{' opens a YAML list or map, so
        // yaml-cpp's message ("end of map not found") says nothing of the cause.
        const std::string_view text = line_text(line);
        if (const std::size_t colon = text.find(": "); !key.empty() && colon != std::string_view::npos) {
            const std::string_view rest = text.substr(colon + 2);
            const std::string_view value = trim(rest.substr(0, rest.find(" #")));
            if (value.starts_with('[') || value.starts_with('{'))
                return error(line, key, cat("invalid YAML: ", message, "; a value that starts with '", value.substr(0, 1),
                                            "' is a YAML list or map: double-quote it to mean text, e.g. \"",
                                            value, "\""));
        }
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
                ? 1 + static_cast<int>(std::count(text_.begin(), text_.begin() + static_cast<long>(dash), '\n'))
                : line_of(item);
            if (i >= list.max_items)
                return error(item_line, name, too_many_items(list));
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
    std::vector<std::string_view> lines_;  // each line of text_, without "\r\n" or "\n"
    TreeBuilder tree_;
    std::map<std::string, int, std::less<>> key_lines_;  // sections and keys ("tools[1].id"): their lines
};

}  // namespace

std::optional<ConfigError> load_yaml(std::string_view text, std::string_view origin, std::vector<ConfigValue>& values,
                                     std::vector<ListValue>& lists)
{
    return YamlLoader(origin, values, lists).load(text);
}

}  // namespace stemd::config::detail
