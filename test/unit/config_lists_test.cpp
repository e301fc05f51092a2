// Configuration list sections (tools), the actuation keys, and the typed
// actuation view (actuation_config).
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

#include "temp_dir_test.hpp"
#include "config_test_util.hpp"

#include "stemd/runtime/actuation_config.hpp"
#include "stemd/config/config.hpp"
#include "stemd/config/schema.hpp"

namespace stemd::config {
namespace {

namespace fs = std::filesystem;

double to_double(std::string_view text)
{
    return std::strtod(std::string(text).c_str(), nullptr);
}

struct Tool {
    long id;
    double offset_mm;
    double y_min_mm;
    double y_max_mm;
    long lanes;
    bool operator==(const Tool&) const = default;
};

std::ostream& operator<<(std::ostream& out, const Tool& t)
{
    return out << "{id " << t.id << ", offset " << t.offset_mm << ", y [" << t.y_min_mm << ", " << t.y_max_mm
               << "], lanes " << t.lanes << "}";
}

std::vector<Tool> tools_of(const Config& config)
{
    std::vector<Tool> out;
    for (std::size_t i = 0; i < config.list_size("tools"); ++i)
        out.push_back({test::item_int_of(config, "tools", i, "id"), test::item_real_of(config, "tools", i, "offset_mm"),
                       test::item_real_of(config, "tools", i, "y_min_mm"), test::item_real_of(config, "tools", i, "y_max_mm"),
                       test::item_int_of(config, "tools", i, "lanes")});
    return out;
}

const Tool kDefaultTool{0, 600, -220, 220, 1};

class ConfigListTest : public stemd::test::TempDirTest {
protected:
    // Loading `text` fails with exactly "FILE:LINE: key 'KEY': MESSAGE" (no
    // key part when `key` is empty), and the list is left as it was.
    void expect_error(const std::string& text, int line, const std::string& key, const std::string& message)
    {
        SCOPED_TRACE(text);
        const fs::path path = write(text);
        Config config;
        ASSERT_FALSE(config.set_override("tools.0.offset_mm=700"));
        const auto error = config.load_file(path);
        ASSERT_TRUE(error.has_value());
        EXPECT_EQ(error->line, line);
        EXPECT_EQ(error->key, key);
        EXPECT_EQ(error->to_string(), path.string() + ":" + std::to_string(line) + ": " +
                                          (key.empty() ? "" : "key '" + key + "': ") + message);
        EXPECT_EQ(tools_of(config), (std::vector<Tool>{{0, 700, -220, 220, 1}}));
        EXPECT_EQ(config.item_origin_of("tools", 0, "offset_mm"), "--set");
    }
};

// --- schema ----------------------------------------------------------------------

TEST(ConfigListSchema, ItemKeysAreTypedTemplatesWithValidDefaults)
{
    ASSERT_EQ(list_schema().size(), 1u);
    const ListSpec* tools = find_list("tools");
    ASSERT_NE(tools, nullptr);
    EXPECT_EQ(tools->max_items, 16u);
    EXPECT_EQ(find_list("tracker"), nullptr);
    EXPECT_EQ(find_key("tools[].offset_mm"), nullptr) << "item keys are not scalar keys";
    std::size_t total = 0;
    for (const ListSpec& list : list_schema()) {
        ASSERT_FALSE(item_keys(list.section).empty()) << list.section;
        total += item_keys(list.section).size();
        for (const KeySpec& spec : item_keys(list.section)) {
            SCOPED_TRACE(std::string(spec.key));
            EXPECT_EQ(spec.key, std::string(list.section) + "[]." + std::string(item_leaf_of(spec)));
            EXPECT_EQ(item_list_of(spec), list.section);
            EXPECT_EQ(find_item_key(list.section, item_leaf_of(spec)), &spec);
            EXPECT_FALSE(spec.help.empty());
            EXPECT_EQ(spec.help.find('|'), std::string_view::npos);
            if (spec.type == ValueType::integer || spec.type == ValueType::real) {
                EXPECT_FALSE(spec.unit.empty());
                EXPECT_GE(to_double(spec.default_value), spec.min);
                EXPECT_LE(to_double(spec.default_value), spec.max);
            }
        }
        for (const std::string_view leaf : {list.unique_key, list.lower_key, list.upper_key})
            EXPECT_NE(find_item_key(list.section, leaf), nullptr) << leaf;
    }
    EXPECT_EQ(total, list_item_schema().size());
    EXPECT_EQ(find_item_key("tools", "offset"), nullptr);

    struct Expected {
        const char* key;
        ValueType type;
        const char* unit;
        double min, max;
        const char* def;
    };
    for (const Expected& e : std::initializer_list<Expected>{
             {"id", ValueType::integer, "id", 0, 15, "0"},
             {"offset_mm", ValueType::real, "mm", -5000, 5000, "600"},
             {"y_min_mm", ValueType::real, "mm", -2047, 2047, "-220"},
             {"y_max_mm", ValueType::real, "mm", -2047, 2047, "220"},
             {"lanes", ValueType::integer, "count", 1, 16, "1"}}) {
        const KeySpec* spec = find_item_key("tools", e.key);
        ASSERT_NE(spec, nullptr) << e.key;
        EXPECT_EQ(spec->type, e.type) << e.key;
        EXPECT_EQ(spec->unit, e.unit) << e.key;
        EXPECT_EQ(spec->min, e.min) << e.key;
        EXPECT_EQ(spec->max, e.max) << e.key;
        EXPECT_EQ(spec->default_value, e.def) << e.key;
    }
}

TEST(ConfigListSchema, ActuationScalarKeys)
{
    struct Expected {
        const char* key;
        ValueType type;
        const char* unit;
        double min, max;
        const char* def;
        const char* choices;
    };
    for (const Expected& e : std::initializer_list<Expected>{
             {"tracker.association_radius_mm", ValueType::real, "mm", 0.5, 500, "10", ""},
             {"tracker.confirm_frames", ValueType::integer, "count", 1, 100, "3", ""},
             {"tracker.exit_margin_mm", ValueType::real, "mm", 0, 1000, "60", ""},
             {"tracker.max_missed_frames", ValueType::integer, "count", 1, 100, "3", ""},
             {"tracker.capacity", ValueType::integer, "tracks", 1, 4096, "256", ""},
             {"scheduler.policy", ValueType::choice, "", 0, 0, "auto", "auto|weeds_only|all"},
             {"scheduler.lead_ms", ValueType::real, "ms", 0, 1000, "20", ""},
             {"scheduler.send_budget_ms", ValueType::real, "ms", 0, 100, "2", ""},
             {"scheduler.standing_speed_mm_per_s", ValueType::real, "mm/s", 0, 1000, "1", ""},
             {"odometry.source", ValueType::choice, "", 0, 0, "auto", "auto|recording|constant|can|encoder"},
             {"odometry.speed_mm_per_s", ValueType::real, "mm/s", 0, 10000, "1388.9", ""},
             {"odometry.encoder_mm_per_tick", ValueType::real, "mm", 0.0001, 1000, "0.1", ""},
             {"odometry.max_extrapolation_ms", ValueType::real, "ms", 1, 10000, "100", ""},
             {"odometry.timeout_ms", ValueType::real, "ms", 10, 60000, "500", ""},
             {"can.interface", ValueType::text, "", 0, 0, "none", ""},
             {"can.base_id", ValueType::integer, "id", 0, 2043, "768", ""},
             {"can.log_file", ValueType::text, "", 0, 0, "-", ""},
             {"can.log_clock", ValueType::choice, "", 0, 0, "realtime", "realtime|monotonic"},
             {"can.heartbeat_ms", ValueType::real, "ms", 10, 10000, "100", ""},
             {"gpio.chip", ValueType::text, "", 0, 0, "none", ""},
             {"gpio.enable_line", ValueType::integer, "line", -1, 1023, "-1", ""},
             {"gpio.enable_active", ValueType::choice, "", 0, 0, "high", "high|low"},
             {"gpio.enable_debounce_ms", ValueType::real, "ms", 0, 1000, "20", ""},
             {"gpio.trigger_line", ValueType::integer, "line", -1, 1023, "-1", ""},
             {"gpio.trigger_active", ValueType::choice, "", 0, 0, "high", "high|low"},
             {"gpio.trigger_pulse_us", ValueType::integer, "us", 1, 100000, "100", ""},
             {"gpio.encoder", ValueType::choice, "", 0, 0, "none", "none|quadrature|single"},
             {"gpio.encoder_a_line", ValueType::integer, "line", -1, 1023, "-1", ""},
             {"gpio.encoder_b_line", ValueType::integer, "line", -1, 1023, "-1", ""},
             {"map.file", ValueType::text, "", 0, 0, "none", ""}}) {
        const KeySpec* spec = find_key(e.key);
        ASSERT_NE(spec, nullptr) << e.key;
        EXPECT_EQ(spec->type, e.type) << e.key;
        EXPECT_EQ(spec->unit, e.unit) << e.key;
        EXPECT_EQ(spec->min, e.min) << e.key;
        EXPECT_EQ(spec->max, e.max) << e.key;
        EXPECT_EQ(spec->default_value, e.def) << e.key;
        EXPECT_EQ(spec->choices, e.choices) << e.key;
    }
    // "-" is a plain value on the command line; a file quotes it (a bare '-'
    // is YAML for a list item).
    Config config;
    ASSERT_FALSE(config.set_override("can.log_file=out.log"));
    ASSERT_FALSE(config.set_override("can.log_file=-"));
    EXPECT_EQ(test::text_of(config, "can.log_file"), "-");
    EXPECT_EQ(config.load_text("can:\n  log_file: -\n", "x")->to_string(),
              "x:2: key 'can.log_file': invalid YAML: a bare '-' starts a list item, not a value; "
              "write \"-\" (double-quoted) for a dash");
    ASSERT_FALSE(config.set_override("can.log_file=out.log"));
    const auto quoted = config.load_text("can:\n  log_file: \"-\"  # standard output\n", "x");
    ASSERT_FALSE(quoted) << quoted->to_string();
    EXPECT_EQ(test::text_of(config, "can.log_file"), "-");
    ASSERT_FALSE(config.load_text("can:\n  log_file: '-'\n", "x"));
    EXPECT_EQ(test::text_of(config, "can.log_file"), "-");
}

// --- defaults and parsing ---------------------------------------------------------

TEST(ConfigList, DefaultIsOneToolAtTheItemDefaults)
{
    const Config config;
    EXPECT_EQ(tools_of(config), std::vector<Tool>{kDefaultTool});
    for (const KeySpec& spec : item_keys("tools"))
        EXPECT_EQ(config.item_origin_of("tools", 0, item_leaf_of(spec)), "default");
}

TEST_F(ConfigListTest, ReadsItemsOmittedKeysTakeTheDefaults)
{
    const fs::path path = write(
        "closing:\n"
        "  radius_px: 6\n"
        "tools:   # two stamps\n"
        "  # the left one\n"
        "  - id: 3\n"
        "    offset_mm: 900   # comment\n"
        "\n"
        "    y_min_mm: 0\n"
        "  - offset_mm: -50.5\n"
        "    id: 4\n"
        "    y_max_mm: 0\n"
        "    lanes: 16\n"
        "stem:\n"
        "  min_leaves: 4\n");
    Config config;
    const auto error = config.load_file(path);
    ASSERT_FALSE(error) << error->to_string();
    EXPECT_EQ(tools_of(config), (std::vector<Tool>{{3, 900, 0, 220, 1}, {4, -50.5, -220, 0, 16}}));
    EXPECT_EQ(config.item_origin_of("tools", 0, "id"), path.string() + ":5");
    EXPECT_EQ(config.item_origin_of("tools", 0, "y_max_mm"), "default");
    EXPECT_EQ(config.item_origin_of("tools", 1, "offset_mm"), path.string() + ":9");
    EXPECT_EQ(config.item_origin_of("tools", 1, "lanes"), path.string() + ":12");
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 6);
    EXPECT_EQ(test::int_of(config, "stem.min_leaves"), 4);
}

TEST_F(ConfigListTest, ItemsMayStartAtTheSectionsIndentAndKeysAlignWithTheFirst)
{
    Config config;
    const auto error = config.load_file(write("tools:\n- id: 1\n  lanes: 2\n-   id: 2\n    lanes: 3\nlog:\n  level: warn\n"));
    ASSERT_FALSE(error) << error->to_string();
    EXPECT_EQ(tools_of(config), (std::vector<Tool>{{1, 600, -220, 220, 2}, {2, 600, -220, 220, 3}}));
    EXPECT_EQ(test::text_of(config, "log.level"), "warn");
}

TEST_F(ConfigListTest, AFileListReplacesTheWholeList)
{
    Config config;
    ASSERT_FALSE(config.set_override("tools.1.offset_mm=900"));
    ASSERT_EQ(config.list_size("tools"), 2u);
    ASSERT_FALSE(config.load_file(write("tools:\n  - id: 7\n")));
    EXPECT_EQ(tools_of(config), (std::vector<Tool>{{7, 600, -220, 220, 1}}));
    // A file without a tools section keeps the list.
    ASSERT_FALSE(config.load_file(write("closing:\n  radius_px: 2\n")));
    EXPECT_EQ(tools_of(config), (std::vector<Tool>{{7, 600, -220, 220, 1}}));
}

TEST_F(ConfigListTest, SixteenItemsAreAllowed)
{
    std::string text = "tools:\n";
    for (int i = 0; i < 16; ++i)
        text += "  - id: " + std::to_string(i) + "\n";
    Config config;
    const auto error = config.load_file(write(text));
    ASSERT_FALSE(error) << error->to_string();
    EXPECT_EQ(config.list_size("tools"), 16u);
    EXPECT_EQ(test::item_int_of(config, "tools", 15, "id"), 15);
}

// --- file errors: file, line and key ----------------------------------------------

TEST_F(ConfigListTest, OutOfRangeAndWrongTypeNameTheItem)
{
    expect_error("tools:\n  - id: 0\n  - id: 1\n    offset_mm: 6000\n", 4, "tools[1].offset_mm",
                 "6000 is out of range [-5000, 5000] mm");
    expect_error("tools:\n  - id: 16\n", 2, "tools[0].id", "16 is out of range [0, 15] id");
    expect_error("tools:\n  - id: 0\n    lanes: 0\n", 3, "tools[0].lanes", "0 is out of range [1, 16] count");
    expect_error("tools:\n  - id: 0\n    lanes: 1.5\n", 3, "tools[0].lanes", "expected an integer, got '1.5'");
    expect_error("tools:\n  - id: 0\n    offset_mm:\n", 3, "tools[0].offset_mm", "empty value");
}

TEST_F(ConfigListTest, UnknownAndDuplicateItemKeys)
{
    expect_error("tools:\n  - id: 0\n  - id: 1\n    offset: 900\n", 4, "tools[1].offset",
                 "unknown key; did you mean 'tools[1].offset_mm'?");
    expect_error("tools:\n  - colour: red\n", 2, "tools[0].colour",
                 "unknown key; a tools item has: id, offset_mm, y_min_mm, y_max_mm, lanes, "
                 "latency_ms, learn_latency, latency_min_ms, latency_max_ms");
    expect_error("tools:\n  - id: 0\n    lanes: 2\n    lanes: 3\n", 4, "tools[0].lanes",
                 "duplicate key (first on line 3)");
}

TEST_F(ConfigListTest, DuplicateIdNamesTheSecondItemsIdLine)
{
    expect_error("tools:\n  - id: 2\n  - id: 1\n  - offset_mm: 700\n    id: 2\n", 5, "tools[2].id",
                 "duplicate id 2; tools[0] has it already (line 2)");
    // An omitted id is the default 0: the item's first line.
    expect_error("tools:\n  - offset_mm: 1\n  - offset_mm: 2\n", 3, "tools[1].id",
                 "duplicate id 0; tools[0] has it already (line 2)");
}

TEST_F(ConfigListTest, SpanMustNotBeEmpty)
{
    expect_error("tools:\n  - id: 0\n    y_max_mm: -300\n    lanes: 2\n", 3, "tools[0].y_max_mm",
                 "y_max_mm -300 must be greater than y_min_mm -220");
    expect_error("tools:\n  - id: 0\n    y_min_mm: 10\n    y_max_mm: 10\n", 4, "tools[0].y_max_mm",
                 "y_max_mm 10 must be greater than y_min_mm 10");
    // Only y_min_mm given: it is the line at fault.
    expect_error("tools:\n  - id: 0\n  - id: 1\n    y_min_mm: 500\n", 4, "tools[1].y_min_mm",
                 "y_max_mm 220 must be greater than y_min_mm 500");
}

TEST_F(ConfigListTest, NotAListEmptyTooLongOrWithAValue)
{
    expect_error("tools:\n  offset_mm: 600\n", 2, "tools",
                 "expected a list of items ('- key: value' lines) under 'tools:'");
    expect_error("tools:\n# nothing\nclosing:\n  radius_px: 5\n", 1, "tools",
                 "empty list; give at least one item ('- id: ...') on indented lines below it");
    expect_error("tools:\n", 1, "tools", "empty list; give at least one item ('- id: ...') on indented lines below it");
    expect_error("tools: 3\n", 1, "tools",
                 "a list section cannot have a value; put its items ('- id: ...') on indented lines below it");
    std::string text = "tools:\n";
    for (int i = 0; i < 17; ++i)
        text += "  - id: " + std::to_string(i % 16) + "\n";
    expect_error(text, 18, "tools[16]", "more than 16 items; 'tools' holds at most 16");
    expect_error("tools:\n  - id: 0\ntools:\n  - id: 1\n", 3, "tools", "duplicate section (first on line 1)");
}

TEST_F(ConfigListTest, MalformedItems)
{
    expect_error("tools:\n  -id: 0\n", 2, "tools", "expected a list of items ('- key: value' lines) under 'tools:'");
    expect_error("tools:\n  - 5\n", 2, "tools[0]", "expected '- key: value' (an item is 'key: value' lines), got '5'");
    expect_error("tools:\n  - [1, 2]\n", 2, "tools[0]", "expected '- key: value' (an item is 'key: value' lines), got a list");
    expect_error("tools:\n  -\n  - id: 1\n", 2, "tools[0]",
                 "empty item; an item starts with '- ' and its first key ('- id: ...')");
    expect_error("tools:\n  - id: 0\n  - # nothing\n", 3, "tools[1]",
                 "empty item; an item starts with '- ' and its first key ('- id: ...')");
    expect_error("tools:\n  - id:0\n", 2, "tools[0].id", "expected a space after ':'");
    expect_error("tools:\n  - id: 0\n\tlanes: 2\n", 3, "tools[0].lanes", "tab in the indentation; indent with spaces");
    expect_error("tools:\n  -\tid: 0\n", 2, "tools[0].id", "tab in the indentation; indent with spaces");
    // Indentation YAML cannot read: yaml-cpp's message, the key the line holds.
    expect_error("tools:\n  - id: 0\n   lanes: 2\n", 3, "tools[0].lanes",
                 "invalid YAML: end of sequence not found (inconsistent indentation? 3 spaces here, 4 on the line above)");
    expect_error("tools:\n  - id: 0\n - id: 1\n", 3, "tools[1].id",
                 "invalid YAML: end of map not found (inconsistent indentation? 1 spaces here, 4 on the line above)");
    expect_error("tools:\n  - id: 0\n    lanes:\n      - 1\n", 4, "tools[0].lanes",
                 "expected a value, got a list; a list item holds only 'key: value' lines");
    expect_error("tools:\n  - id: 0\n    lanes:\n      x: 1\n", 4, "tools[0].lanes.x",
                 "nesting deeper than one level; a list item holds only 'key: value' lines");
    expect_error("tools:\n  - id: 0\n    lanes: 2\n      x: 1\n", 4, "tools[0].x",
                 "invalid YAML: illegal map value (inconsistent indentation? 6 spaces here, 4 on the line above)");
    // A list outside a list section.
    expect_error("segment:\n  - method: exg\n", 2, "segment",
                 "expected 'key: value' lines under 'segment:', got a list ('- ' items); only 'tools' holds a list");
}

TEST_F(ConfigListTest, AnyYamlLayoutOfTheSameShapeReads)
{
    // An item's first key on the line after its '-', and YAML flow style.
    Config config;
    auto error = config.load_file(write("tools:\n  -\n    id: 0\n    lanes: 2\n  - {id: 1, offset_mm: 700}\n"));
    ASSERT_FALSE(error) << error->to_string();
    EXPECT_EQ(tools_of(config), (std::vector<Tool>{{0, 600, -220, 220, 2}, {1, 700, -220, 220, 1}}));
    EXPECT_EQ(config.item_origin_of("tools", 0, "id"), (dir_ / "test.yaml").string() + ":3");
    error = config.load_file(write("tools: [{id: 5}]\n"));
    ASSERT_FALSE(error) << error->to_string();
    EXPECT_EQ(tools_of(config), (std::vector<Tool>{{5, 600, -220, 220, 1}}));
    expect_error("tools: []\n", 1, "tools", "empty list; give at least one item ('- id: ...') on indented lines below it");
    // Duplicate keys are found in flow style too.
    expect_error("tools: [{id: 1, id: 2}]\n", 1, "tools[0].id", "duplicate key (first on line 1)");
}

TEST_F(ConfigListTest, AnErrorAfterTheListKeepsTheOldList)
{
    expect_error("tools:\n  - id: 5\nclosing:\n  radius_px: 99\n", 4, "closing.radius_px",
                 "99 is out of range [0, 50] px");
}

TEST_F(ConfigListTest, UnknownSectionListsTheListSectionsToo)
{
    Config config;
    const auto error = config.load_file(write("capture:\n  fps: 30\n"));
    ASSERT_TRUE(error);
    EXPECT_NE(error->message.find("the sections are: camera, "), std::string::npos) << error->message;
    EXPECT_NE(error->message.find(", tracker, scheduler, odometry, can, gpio, map, gnss, tools"), std::string::npos)
        << error->message;
}

TEST_F(ConfigListTest, BlameNamesAnItemKeyWithItsLine)
{
    // What the daemon refuses after loading (check_actuation_config) names
    // an item's key as "tools[1].latency_max_ms": its file and line, not
    // "(unknown)".
    const fs::path path = write("tools:\n  - id: 0\n  - id: 1\n    latency_max_ms: 5\n");
    Config config;
    ASSERT_FALSE(config.load_file(path));
    EXPECT_EQ(config.origin_of("tools[1].latency_max_ms"), path.string() + ":4");
    EXPECT_EQ(config.blame("tools[1].latency_max_ms", "below latency_min_ms"),
              path.string() + ":4: key 'tools[1].latency_max_ms': below latency_min_ms");
    EXPECT_EQ(config.blame("tools[1].latency_min_ms", "m"), "key 'tools[1].latency_min_ms' (default): m");
    ASSERT_FALSE(config.set_override("tools.0.offset_mm=650"));
    EXPECT_EQ(config.blame("tools[0].offset_mm", "m"), "key 'tools[0].offset_mm' (--set): m");
    // An item or a key the list does not have is still unknown.
    EXPECT_EQ(config.origin_of("tools[2].offset_mm"), "");
    EXPECT_EQ(config.origin_of("tools[0].colour"), "");
    EXPECT_EQ(config.blame("tools[2].offset_mm", "m"), "key 'tools[2].offset_mm' (unknown): m");
}

// --- --set -------------------------------------------------------------------------

TEST(ConfigListSet, OverridesAndAppends)
{
    Config config;
    ASSERT_FALSE(config.set_override("tools.0.offset_mm=650"));
    EXPECT_EQ(tools_of(config), (std::vector<Tool>{{0, 650, -220, 220, 1}}));
    EXPECT_EQ(config.item_origin_of("tools", 0, "offset_mm"), "--set");
    EXPECT_EQ(config.item_origin_of("tools", 0, "id"), "default");
    // Index == size appends an item at the defaults, with the lowest free id.
    ASSERT_FALSE(config.set_override("tools.1.offset_mm=900"));
    ASSERT_FALSE(config.set_override("tools[2].lanes=4"));
    EXPECT_EQ(tools_of(config),
              (std::vector<Tool>{{0, 650, -220, 220, 1}, {1, 900, -220, 220, 1}, {2, 600, -220, 220, 4}}));
    ASSERT_FALSE(config.set_override("tools.0.id=15"));
    ASSERT_FALSE(config.set_override("tools.3.y_min_mm=0"));
    EXPECT_EQ(test::item_int_of(config, "tools", 3, "id"), 0);
    EXPECT_EQ(test::item_real_of(config, "tools", 3, "y_min_mm"), 0.0);
}

TEST(ConfigListSet, ErrorsNameTheItemKeyAndChangeNothing)
{
    struct Case {
        const char* set;
        const char* expected;
    };
    const Case cases[] = {
        {"tools.2.offset_mm=650", "--set tools.2.offset_mm=650: key 'tools[2].offset_mm': no item 2; 'tools' has 1 item (tools.0 .. tools.0), tools.1 appends one"},
        {"tools.0.offset_mm=5001", "--set tools.0.offset_mm=5001: key 'tools[0].offset_mm': 5001 is out of range [-5000, 5000] mm"},
        {"tools.0.offset=1", "--set tools.0.offset=1: key 'tools[0].offset': unknown key; did you mean 'tools[0].offset_mm'?"},
        {"tools.0.y_min_mm=220", "--set tools.0.y_min_mm=220: key 'tools[0].y_min_mm': y_max_mm 220 must be greater than y_min_mm 220"},
        {"tools.0.y_max_mm=-300", "--set tools.0.y_max_mm=-300: key 'tools[0].y_max_mm': y_max_mm -300 must be greater than y_min_mm -220"},
        {"tools.offset_mm=650", "--set tools.offset_mm=650: key 'tools.offset_mm': expected tools.INDEX.KEY, e.g. --set tools.0.offset_mm=..."},
        {"tools=1", "--set tools=1: key 'tools': expected tools.INDEX.KEY, e.g. --set tools.0.offset_mm=..."},
        {"tools.x.id=1", "--set tools.x.id=1: key 'tools.x.id': expected tools.INDEX.KEY, e.g. --set tools.0.offset_mm=..."},
        {"tools.0.lanes=", "--set tools.0.lanes=: key 'tools[0].lanes': empty value"},
    };
    for (const Case& c : cases) {
        Config config;
        const auto error = config.set_override(c.set);
        ASSERT_TRUE(error) << c.set;
        EXPECT_EQ(error->to_string(), c.expected);
        EXPECT_EQ(tools_of(config), std::vector<Tool>{kDefaultTool});
    }
    // A duplicate id, and more than 16 items.
    Config config;
    ASSERT_FALSE(config.set_override("tools.1.id=1"));
    auto error = config.set_override("tools.1.id=0");
    ASSERT_TRUE(error);
    EXPECT_EQ(error->to_string(), "--set tools.1.id=0: key 'tools[1].id': duplicate id 0; tools[0] has it already");
    for (int i = 2; i < 16; ++i)
        ASSERT_FALSE(config.set_override("tools." + std::to_string(i) + ".lanes=2")) << i;
    EXPECT_EQ(test::item_int_of(config, "tools", 15, "id"), 15);
    error = config.set_override("tools.16.lanes=2");
    ASSERT_TRUE(error);
    EXPECT_EQ(error->to_string(), "--set tools.16.lanes=2: key 'tools[16].lanes': more than 16 items; 'tools' holds at most 16");
    EXPECT_EQ(config.list_size("tools"), 16u);
}

// --- to_yaml -------------------------------------------------------------------------

TEST_F(ConfigListTest, ToYamlWritesTheListAndRoundTrips)
{
    Config config;
    ASSERT_FALSE(config.load_file(write("tools:\n  - id: 3\n    offset_mm: 900.25\n  - id: 1\n    lanes: 8\n")));
    ASSERT_FALSE(config.set_override("tools.2.y_min_mm=-2047"));
    ASSERT_FALSE(config.set_override("tracker.capacity=17"));
    const std::string yaml = config.to_yaml();
    EXPECT_NE(yaml.find("\ntools:\n  - id: 3  # [0, 15] id; " + (dir_ / "test.yaml").string() + ":2\n"
                        "    offset_mm: 900.25  # [-5000, 5000] mm; " + (dir_ / "test.yaml").string() + ":3\n"
                        "    y_min_mm: -220  # [-2047, 2047] mm; default\n"),
              std::string::npos)
        << yaml;
    EXPECT_NE(yaml.find("  - id: 0  # [0, 15] id; default\n    offset_mm: 600"), std::string::npos) << yaml;
    EXPECT_NE(yaml.find("  log_file: \"-\"  # text; default\n"), std::string::npos) << yaml;

    Config reloaded;
    const auto error = reloaded.load_text(yaml, "dumped");
    ASSERT_FALSE(error) << error->to_string() << "\n" << yaml;
    EXPECT_EQ(tools_of(reloaded), tools_of(config));
    EXPECT_EQ(tools_of(reloaded),
              (std::vector<Tool>{{3, 900.25, -220, 220, 1}, {1, 600, -220, 220, 8}, {0, 600, -2047, 220, 1}}));
    EXPECT_EQ(test::int_of(reloaded, "tracker.capacity"), 17);
    EXPECT_EQ(reloaded.item_origin_of("tools", 2, "lanes").rfind("dumped:", 0), 0u);
    const std::string again = reloaded.to_yaml();
    EXPECT_EQ(std::count(again.begin(), again.end(), '\n'), std::count(yaml.begin(), yaml.end(), '\n'));

    // The defaults round-trip too.
    Config defaults;
    ASSERT_FALSE(defaults.load_text(Config{}.to_yaml(), "defaults"));
    EXPECT_EQ(tools_of(defaults), std::vector<Tool>{kDefaultTool});
}

}  // namespace
}  // namespace stemd::config

// --- actuation_config ---------------------------------------------------------------------

namespace stemd::runtime {
namespace {

TEST(ActuationConfig, DefaultsMatchTheStructsDefaults)
{
    const ActuationConfig a = config::Config{}.settings().actuation;
    const ActuationConfig d;
    ASSERT_EQ(a.tools.size(), 1u);
    EXPECT_EQ(a.tools[0].id, 0);
    EXPECT_EQ(a.tools[0].offset_mm, 600.0);
    EXPECT_EQ(a.tools[0].y_min_mm, -220.0);
    EXPECT_EQ(a.tools[0].y_max_mm, 220.0);
    EXPECT_EQ(a.tools[0].lanes, 1);
    const actuation::TrackerParams tracker;
    EXPECT_EQ(a.tracker.association_radius_mm, tracker.association_radius_mm);
    EXPECT_EQ(a.tracker.confirm_frames, tracker.confirm_frames);
    EXPECT_EQ(a.tracker.exit_margin_mm, 60.0);  // the config's default: 46 mm per frame at 5 km/h, 30 fps
    EXPECT_EQ(a.tracker.max_missed_frames, tracker.max_missed_frames);
    EXPECT_EQ(a.tracker.capacity, tracker.capacity);
    EXPECT_EQ(a.tracker.max_detections, tracker.max_detections);
    const actuation::SchedulerParams scheduler;
    EXPECT_EQ(a.scheduler.lead_ms, scheduler.lead_ms);
    EXPECT_EQ(a.scheduler.send_budget_ms, scheduler.send_budget_ms);
    EXPECT_EQ(a.scheduler.standing_speed_mm_per_s, scheduler.standing_speed_mm_per_s);
    EXPECT_EQ(a.scheduler.standing_deadline_ms, scheduler.standing_deadline_ms);
    EXPECT_EQ(a.policy, PolicyChoice::automatic);
    EXPECT_EQ(a.odometry, d.odometry);
    EXPECT_EQ(a.speed_mm_per_s, d.speed_mm_per_s);
    EXPECT_EQ(a.encoder_mm_per_tick, d.encoder_mm_per_tick);
    EXPECT_EQ(a.max_extrapolation_ns, d.max_extrapolation_ns);
    EXPECT_EQ(a.odometry_timeout_ns, d.odometry_timeout_ns);
    EXPECT_EQ(a.can_interface, "");
    EXPECT_EQ(a.can_base_id, 0x300u);
    EXPECT_EQ(a.can_log_file, "-");
    EXPECT_FALSE(a.can_log_monotonic);
    EXPECT_EQ(a.heartbeat_interval_ns, d.heartbeat_interval_ns);
    EXPECT_EQ(a.gpio_chip, "");
    EXPECT_EQ(a.enable_line, -1);
    EXPECT_FALSE(a.enable_active_low);
    EXPECT_EQ(a.enable_debounce_ns, d.enable_debounce_ns);
    EXPECT_EQ(a.trigger_line, -1);
    EXPECT_FALSE(a.trigger_active_low);
    EXPECT_EQ(a.trigger_pulse_us, d.trigger_pulse_us);
    EXPECT_EQ(a.encoder_mode, "none");
    EXPECT_EQ(a.encoder_a_line, -1);
    EXPECT_EQ(a.encoder_b_line, -1);
    EXPECT_EQ(a.map_file, "");
    // The default tool table is one the scheduler accepts.
    std::string_view error;
    EXPECT_TRUE(actuation::Scheduler::make(a.tools, a.scheduler, &error).has_value()) << error;
}

TEST(ActuationConfig, EveryKeyMapsToItsField)
{
    config::Config config;
    for (const char* set :
         {"tools.0.id=4", "tools.0.offset_mm=650.5", "tools.0.y_min_mm=-100", "tools.0.y_max_mm=300",
          "tools.0.lanes=8", "tools.1.id=9", "tools.1.offset_mm=-20",
          "tracker.association_radius_mm=12.5", "tracker.confirm_frames=5", "tracker.exit_margin_mm=47",
          "tracker.max_missed_frames=7", "tracker.capacity=1024",
          "scheduler.policy=all", "scheduler.lead_ms=15.5", "scheduler.send_budget_ms=1.25",
          "scheduler.standing_speed_mm_per_s=3",
          "odometry.source=encoder", "odometry.speed_mm_per_s=700", "odometry.encoder_mm_per_tick=0.25",
          "odometry.max_extrapolation_ms=50.5", "odometry.timeout_ms=250",
          "can.interface=can0", "can.base_id=1024", "can.log_file=/tmp/x.log", "can.log_clock=monotonic",
          "can.heartbeat_ms=50",
          "gpio.chip=gpiochip0", "gpio.enable_line=17", "gpio.enable_active=low", "gpio.enable_debounce_ms=5",
          "gpio.trigger_line=27", "gpio.trigger_active=low", "gpio.trigger_pulse_us=250",
          "gpio.encoder=quadrature", "gpio.encoder_a_line=5", "gpio.encoder_b_line=6",
          "map.file=plants.jsonl"})
        ASSERT_FALSE(config.set_override(set)) << set;
    const ActuationConfig a = config.settings().actuation;
    ASSERT_EQ(a.tools.size(), 2u);
    EXPECT_EQ(a.tools[0].id, 4);
    EXPECT_EQ(a.tools[0].offset_mm, 650.5);
    EXPECT_EQ(a.tools[0].y_min_mm, -100.0);
    EXPECT_EQ(a.tools[0].y_max_mm, 300.0);
    EXPECT_EQ(a.tools[0].lanes, 8);
    EXPECT_EQ(a.tools[1].id, 9);
    EXPECT_EQ(a.tools[1].offset_mm, -20.0);
    EXPECT_EQ(a.tools[1].lanes, 1);
    EXPECT_EQ(a.tracker.association_radius_mm, 12.5);
    EXPECT_EQ(a.tracker.confirm_frames, 5u);
    EXPECT_EQ(a.tracker.exit_margin_mm, 47.0);
    EXPECT_EQ(a.tracker.max_missed_frames, 7u);
    EXPECT_EQ(a.tracker.capacity, 1024u);
    EXPECT_EQ(a.policy, PolicyChoice::all);
    EXPECT_EQ(a.scheduler.lead_ms, 15.5);
    EXPECT_EQ(a.scheduler.send_budget_ms, 1.25);
    EXPECT_EQ(a.scheduler.standing_speed_mm_per_s, 3.0);
    EXPECT_EQ(a.odometry, OdometrySource::encoder);
    EXPECT_EQ(a.speed_mm_per_s, 700.0);
    EXPECT_EQ(a.encoder_mm_per_tick, 0.25);
    EXPECT_EQ(a.max_extrapolation_ns, 50'500'000);
    EXPECT_EQ(a.odometry_timeout_ns, 250'000'000);
    EXPECT_EQ(a.can_interface, "can0");
    EXPECT_EQ(a.can_base_id, 1024u);
    EXPECT_EQ(a.can_log_file, "/tmp/x.log");
    EXPECT_TRUE(a.can_log_monotonic);
    EXPECT_EQ(a.heartbeat_interval_ns, 50'000'000);
    EXPECT_EQ(a.gpio_chip, "gpiochip0");
    EXPECT_EQ(a.enable_line, 17);
    EXPECT_TRUE(a.enable_active_low);
    EXPECT_EQ(a.enable_debounce_ns, 5'000'000);
    EXPECT_EQ(a.trigger_line, 27);
    EXPECT_TRUE(a.trigger_active_low);
    EXPECT_EQ(a.trigger_pulse_us, 250u);
    EXPECT_EQ(a.encoder_mode, "quadrature");
    EXPECT_EQ(a.encoder_a_line, 5);
    EXPECT_EQ(a.encoder_b_line, 6);
    EXPECT_EQ(a.map_file, "plants.jsonl");
    std::string_view error;
    EXPECT_TRUE(actuation::Scheduler::make(a.tools, a.scheduler, &error).has_value()) << error;
}

TEST(ActuationConfig, ChoicesMap)
{
    const auto with = [](const std::string& set) {
        config::Config config;
        EXPECT_FALSE(config.set_override(set)) << set;
        return config.settings().actuation;
    };
    EXPECT_EQ(with("scheduler.policy=weeds_only").policy, PolicyChoice::weeds_only);
    EXPECT_EQ(with("scheduler.policy=auto").policy, PolicyChoice::automatic);
    EXPECT_EQ(with("odometry.source=auto").odometry, OdometrySource::automatic);
    EXPECT_EQ(with("odometry.source=recording").odometry, OdometrySource::recording);
    EXPECT_EQ(with("odometry.source=constant").odometry, OdometrySource::constant);
    EXPECT_EQ(with("odometry.source=can").odometry, OdometrySource::can);
    EXPECT_EQ(with("can.log_clock=realtime").can_log_monotonic, false);
    EXPECT_EQ(with("gpio.encoder=single").encoder_mode, "single");
    EXPECT_EQ(with("gpio.enable_active=high").enable_active_low, false);
    // "none" is "not set" for the text keys that have it; "-" stays.
    EXPECT_EQ(with("can.interface=none").can_interface, "");
    EXPECT_EQ(with("can.log_file=-").can_log_file, "-");
}

}  // namespace
}  // namespace stemd::runtime
