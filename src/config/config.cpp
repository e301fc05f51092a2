#include "stemd/config/config.hpp"

#include <cstring>
#include <span>

#include "stemd/base/whole_file.hpp"
#include "values.hpp"
#include "yaml_loader.hpp"

namespace stemd::config {

using namespace detail;

namespace {

constexpr std::size_t kMaxConfigBytes = 1024 * 1024;

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
        lists_.push_back(ListValue{{default_item(list)}});
}

std::optional<ConfigError> Config::load_text(std::string_view text, std::string_view origin)
{
    std::vector<ConfigValue> staged = values_;
    std::vector<ListValue> staged_lists = lists_;
    if (auto error = load_yaml(text, origin, staged, staged_lists))
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
    // A FIFO must not hang the start (SIGTERM is only taken later), and
    // /dev/zero must not fill the memory: a config is a regular file of a
    // few kB.
    const auto unreadable = [&](std::string_view why) {
        return ConfigError{origin, 0, "", cat("cannot read file: ", why)};
    };
    std::string text;
    const base::WholeFileResult read = base::read_whole_file(origin.c_str(), kMaxConfigBytes, text);
    switch (read.status) {
    case base::WholeFileStatus::ok: break;
    case base::WholeFileStatus::cannot_open:
    case base::WholeFileStatus::cannot_stat: return unreadable(std::strerror(read.error_number));
    case base::WholeFileStatus::directory: return unreadable("it is a directory");
    case base::WholeFileStatus::not_regular: return unreadable("not a regular file (a FIFO or a device)");
    case base::WholeFileStatus::too_large:
        return unreadable(
            cat("larger than ", std::to_string(kMaxConfigBytes / 1024), " KiB; is it a configuration file?"));
    case base::WholeFileStatus::read_error: return unreadable(cat("read error: ", std::strerror(read.error_number)));
    case base::WholeFileStatus::truncated:
        return unreadable(cat("it ended after ", std::to_string(read.read_bytes), " of its ",
                              std::to_string(read.size_bytes), " bytes"));
    }
    return load_text(text, origin);
}

std::optional<ConfigError> Config::set_override(std::string_view key_equals_value, std::string_view source)
{
    const std::string origin = cat(source, " ", key_equals_value);
    const std::size_t eq = key_equals_value.find('=');
    const std::string key(trim(key_equals_value.substr(0, eq)));
    if (eq == std::string_view::npos || key.empty())
        return ConfigError{origin, 0, "", "expected KEY=VALUE, e.g. --set closing.radius_px=6"};
    if (const ListSpec* list = list_of_key(key))
        return set_item_override(*list, key, key_equals_value.substr(eq + 1), origin, source);
    const KeySpec* spec = find_key(key);
    if (spec == nullptr)
        return ConfigError{origin, 0, key, unknown_key_message(key)};
    ConfigValue value = values_[index_of(*spec)];
    if (auto message = set_value(*spec, key_equals_value.substr(eq + 1), source, value))
        return ConfigError{origin, 0, key, *message};
    values_[index_of(*spec)] = std::move(value);
    return std::nullopt;
}

std::optional<ConfigError> Config::set_item_override(const ListSpec& list, std::string_view key,
                                                     std::string_view raw_value, const std::string& origin,
                                                     std::string_view source)
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
    ListValue staged = lists_[list_index(list)];
    const std::size_t size = staged.items.size();
    if (index > size)
        return ConfigError{origin, 0, full,
                           cat("no item ", std::to_string(index), "; '", section, "' has ", std::to_string(size),
                               size == 1 ? " item" : " items", " (", section, ".0 .. ", section, ".",
                               std::to_string(size - 1), "), ", section, ".", std::to_string(size),
                               " appends one")};
    if (index == size) {
        if (size >= list.max_items)
            return ConfigError{origin, 0, full, too_many_items(list)};
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
    if (auto message = set_value(*spec, raw_value, source, staged.items[index][item_key_index(list, *spec)]))
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
        const ListValue& value = lists_[list_index(list)];
        list.resize(settings, value.items.size());
        const std::span<const KeySpec> keys = item_keys(list.section);
        for (std::size_t i = 0; i < value.items.size(); ++i)
            for (std::size_t k = 0; k < keys.size(); ++k)
                keys[k].store(keys[k], settings, i, value.items[i][k]);
    }
    return settings;
}

const ConfigValue* Config::find_value(std::string_view key, const KeySpec*& spec) const
{
    spec = find_key(key);
    if (spec != nullptr)
        return &values_[index_of(*spec)];
    // A list item's key, as errors name it: "tools[1].offset_mm".
    const ListSpec* list = list_of_key(key);
    std::size_t index = 0;
    std::string_view leaf;
    if (list == nullptr || !parse_item_key(key, list->section, index, leaf) ||
        (spec = find_item_key(list->section, leaf)) == nullptr || index >= lists_[list_index(*list)].items.size())
        return nullptr;
    return &lists_[list_index(*list)].items[index][item_key_index(*list, *spec)];
}

std::string Config::origin_of(std::string_view key) const
{
    const KeySpec* spec = nullptr;
    const ConfigValue* value = find_value(key, spec);
    return value == nullptr ? std::string() : value->origin;
}

std::string Config::value_of(std::string_view key) const
{
    const KeySpec* spec = nullptr;
    const ConfigValue* value = find_value(key, spec);
    return value == nullptr ? std::string() : value_text(*spec, *value);
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
    return origin_of(item_key_name(section, index, key));
}

std::string Config::to_yaml() const
{
    std::string out = "# stemd effective configuration: value  # unit, range or choices; origin\n";
    const auto key_line = [&](std::string_view first, std::string_view name, const KeySpec& spec,
                              const ConfigValue& value) {
        out += cat(first, name, ": ", value_text(spec, value), "  # ", about_text(spec), "; ", printable(value.origin),
                   "\n");
    };
    std::string_view section;
    for (const KeySpec& spec : schema()) {
        if (section_of(spec.key) != section) {
            section = section_of(spec.key);
            out += cat(section, ":\n");
        }
        key_line("  ", leaf_of(spec.key), spec, values_[index_of(spec)]);
    }
    // List sections: "- " before each item's first key.
    for (const ListSpec& list : list_schema()) {
        out += cat(list.section, ":\n");
        const std::span<const KeySpec> keys = item_keys(list.section);
        for (const std::vector<ConfigValue>& item : lists_[list_index(list)].items)
            for (std::size_t k = 0; k < keys.size(); ++k)
                key_line(k == 0 ? "  - " : "    ", item_leaf_of(keys[k]), keys[k], item[k]);
    }
    return out;
}

}  // namespace stemd::config
