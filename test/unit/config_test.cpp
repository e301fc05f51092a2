// Configuration: schema, file loader, --set overrides, to_yaml, the typed settings.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "temp_dir_test.hpp"
#include "config_docs.hpp"
#include "config_test_util.hpp"

#include "stemd/config/config.hpp"
#include "stemd/config/schema.hpp"
#include "stemd/vision/types.hpp"

namespace stemd::config {
namespace {

namespace fs = std::filesystem;

const fs::path kDefaultConfig = fs::path(STEMD_SOURCE_DIR) / "config" / "stemd.yaml";

double to_double(std::string_view text)
{
    return std::strtod(std::string(text).c_str(), nullptr);
}

bool is_numeric(const KeySpec& spec)
{
    return spec.type == ValueType::integer || spec.type == ValueType::real;
}

// Every value of `a` equals the same key's value in `b`.
void expect_same_values(const Config& a, const Config& b)
{
    for (const KeySpec& spec : schema()) {
        SCOPED_TRACE(std::string(spec.key));
        switch (spec.type) {
        case ValueType::integer: EXPECT_EQ(test::int_of(a, spec.key), test::int_of(b, spec.key)); break;
        case ValueType::real: EXPECT_EQ(test::real_of(a, spec.key), test::real_of(b, spec.key)); break;
        case ValueType::boolean: EXPECT_EQ(test::bool_of(a, spec.key), test::bool_of(b, spec.key)); break;
        case ValueType::choice:
        case ValueType::text: EXPECT_EQ(test::text_of(a, spec.key), test::text_of(b, spec.key)); break;
        }
    }
}

void expect_schema_defaults(const Config& config)
{
    for (const KeySpec& spec : schema()) {
        SCOPED_TRACE(std::string(spec.key));
        switch (spec.type) {
        case ValueType::integer:
            EXPECT_EQ(test::int_of(config, spec.key), std::stol(std::string(spec.default_value)));
            break;
        case ValueType::real: EXPECT_EQ(test::real_of(config, spec.key), to_double(spec.default_value)); break;
        case ValueType::boolean: EXPECT_EQ(test::bool_of(config, spec.key), spec.default_value == "true"); break;
        case ValueType::choice:
        case ValueType::text: EXPECT_EQ(test::text_of(config, spec.key), spec.default_value); break;
        }
    }
}

// Temporary config files, removed after each test.
class ConfigFileTest : public stemd::test::TempDirTest {
protected:
    // Loading `text` fails at `line` on `key`; the message contains `fragment`
    // and the configuration keeps every previous value.
    void expect_error(const std::string& text, int line, const std::string& key, const std::string& fragment)
    {
        SCOPED_TRACE(text);
        const fs::path path = write(text);
        Config config;
        const auto error = config.load_file(path);
        ASSERT_TRUE(error.has_value());
        EXPECT_EQ(error->origin, path.string());
        EXPECT_EQ(error->line, line);
        EXPECT_EQ(error->key, key);
        const std::string prefix =
            path.string() + ":" + std::to_string(line) + ": " + (key.empty() ? "" : "key '" + key + "': ");
        EXPECT_EQ(error->to_string().substr(0, prefix.size()), prefix) << error->to_string();
        EXPECT_NE(error->to_string().find(fragment), std::string::npos) << error->to_string();
        EXPECT_EQ(error->to_string().find('\n'), std::string::npos) << "one line: " << error->to_string();
        expect_same_values(config, Config{});
        for (const KeySpec& spec : schema())
            EXPECT_EQ(config.origin_of(spec.key), "default") << spec.key;
    }
};

// --- schema ----------------------------------------------------------------

TEST(ConfigSchema, KeysAreUniqueSectionDotKeyWithValidDefaults)
{
    ASSERT_FALSE(schema().empty());
    std::vector<std::string> seen;
    for (const KeySpec& spec : schema()) {
        SCOPED_TRACE(std::string(spec.key));
        const std::size_t dot = spec.key.find('.');
        ASSERT_NE(dot, std::string_view::npos);
        EXPECT_GT(dot, 0u);
        EXPECT_LT(dot + 1, spec.key.size());
        EXPECT_EQ(spec.key.find('.', dot + 1), std::string_view::npos);
        EXPECT_EQ(std::count(seen.begin(), seen.end(), spec.key), 0);
        seen.emplace_back(spec.key);
        EXPECT_EQ(find_key(spec.key), &spec);
        EXPECT_FALSE(spec.help.empty());
        EXPECT_EQ(spec.help.find('|'), std::string_view::npos) << "breaks the Markdown table";
        if (is_numeric(spec)) {
            EXPECT_FALSE(spec.unit.empty());
            EXPECT_LE(spec.min, spec.max);
            EXPECT_GE(to_double(spec.default_value), spec.min);
            EXPECT_LE(to_double(spec.default_value), spec.max);
        }
        if (spec.type == ValueType::choice) {
            EXPECT_TRUE(is_choice(spec, spec.default_value));
        }
        // The loader accepts the default as written.
        Config config;
        const auto error = config.set_override(std::string(spec.key) + "=" + std::string(spec.default_value));
        EXPECT_FALSE(error) << error->to_string();
    }
    // Each section's keys are together, so to_yaml() writes each section once.
    std::vector<std::string> sections;
    for (const KeySpec& spec : schema()) {
        const std::string section(spec.key.substr(0, spec.key.find('.')));
        if (sections.empty() || sections.back() != section) {
            EXPECT_EQ(std::count(sections.begin(), sections.end(), section), 0) << section;
            sections.push_back(section);
        }
    }
    EXPECT_EQ(find_key("closing.radius"), nullptr);
    EXPECT_EQ(find_key("closing"), nullptr);
}

TEST(ConfigSchema, ProductKeysHaveTheirUnitsRangesAndChoices)
{
    const KeySpec* radius = find_key("closing.radius_px");
    ASSERT_NE(radius, nullptr);
    EXPECT_EQ(radius->type, ValueType::integer);
    EXPECT_EQ(radius->unit, "px");
    EXPECT_EQ(radius->min, 0);
    EXPECT_EQ(radius->max, vision::kMaxClosingRadiusPx);
    const KeySpec* method = find_key("segment.method");
    ASSERT_NE(method, nullptr);
    EXPECT_EQ(method->type, ValueType::choice);
    EXPECT_EQ(list_choices(*method), "auto, chromatic_exg, exg, ndvi, mask, exg_and_ndvi");
    EXPECT_TRUE(is_choice(*method, "mask"));
    EXPECT_FALSE(is_choice(*method, "ex"));
    EXPECT_FALSE(is_choice(*method, ""));
    const KeySpec* area = find_key("plants.min_area_mm2");
    ASSERT_NE(area, nullptr);
    EXPECT_EQ(area->unit, "mm2");
    EXPECT_EQ(area->max, 100000);
    // Every choice the schema allows is one the vision library can parse.
    for (const char* key : {"segment.method", "segment.threshold", "segment.mask_vegetation", "stem.method"}) {
        const KeySpec* spec = find_key(key);
        ASSERT_NE(spec, nullptr) << key;
        std::string choices(spec->choices);
        std::stringstream stream(choices);
        for (std::string choice; std::getline(stream, choice, '|');) {
            Config config;
            ASSERT_FALSE(config.set_override(std::string(key) + "=" + choice)) << key << "=" << choice;
            const vision::Params p = config.settings().daemon.vision;
            std::string_view mapped;
            if (spec->key == "segment.method") mapped = vision::to_string(p.segmentation);
            if (spec->key == "segment.threshold") mapped = vision::to_string(p.threshold);
            if (spec->key == "segment.mask_vegetation") mapped = vision::to_string(p.mask_vegetation);
            if (spec->key == "stem.method") mapped = vision::to_string(p.stem_estimator);
            EXPECT_EQ(mapped, choice) << key;
        }
    }
}

TEST(ConfigSchema, MarkdownTableHasOneRowPerKey)
{
    const std::string table = schema_markdown();
    std::vector<std::string> rows;
    std::stringstream stream(table);
    for (std::string row; std::getline(stream, row);)
        rows.push_back(row);
    // The keys of schema(), then the list item keys ("tools[].offset_mm").
    std::vector<const KeySpec*> keys;
    for (const KeySpec& spec : schema())
        keys.push_back(&spec);
    for (const KeySpec& spec : list_item_schema())
        keys.push_back(&spec);
    ASSERT_EQ(rows.size(), keys.size() + 2);
    EXPECT_EQ(rows[0], "| key | type | unit | default | range / choices | meaning |");
    EXPECT_EQ(rows[1], "|---|---|---|---|---|---|");
    for (std::size_t i = 0; i < keys.size(); ++i) {
        EXPECT_EQ(rows[i + 2].rfind("| `" + std::string(keys[i]->key) + "` | ", 0), 0u) << rows[i + 2];
        EXPECT_EQ(std::count(rows[i + 2].begin(), rows[i + 2].end(), '|'), 7) << rows[i + 2];
    }
    EXPECT_NE(table.find("| `tools[].offset_mm` | real | mm | `600` | [-5000, 5000] | forward distance"),
              std::string::npos);
    EXPECT_NE(table.find("| `closing.radius_px` | integer | px | `5` | [0, 50] | radius m of the elliptic"),
              std::string::npos);
    EXPECT_NE(table.find("| `segment.method` | choice |  | `auto` | `auto`, `chromatic_exg`, `exg`, `ndvi`, `mask`, `exg_and_ndvi` | "), std::string::npos);
    EXPECT_NE(table.find("| `plants.min_area_mm2` | real | mm2 | `10` | [0, 100000] | "), std::string::npos);
}

TEST(ConfigSchema, FormatNumberIsShortAndExact)
{
    EXPECT_EQ(format_number(0.33), "0.33");
    EXPECT_EQ(format_number(50), "50");
    EXPECT_EQ(format_number(100000), "100000");
    EXPECT_EQ(format_number(0.01), "0.01");
    EXPECT_EQ(format_number(-1), "-1");
}

// --- defaults ----------------------------------------------------------------

TEST(Config, DefaultsAreTheSchemaDefaults)
{
    const Config config;
    expect_schema_defaults(config);
    for (const KeySpec& spec : schema())
        EXPECT_EQ(config.origin_of(spec.key), "default") << spec.key;
}

TEST(Config, DefaultsAreTheVisionLibraryDefaults)
{
    const vision::Params p = Config{}.settings().daemon.vision;
    const vision::Params expected;
    EXPECT_EQ(p.segmentation, expected.segmentation);
    EXPECT_EQ(p.threshold, expected.threshold);
    EXPECT_EQ(p.mask_vegetation, expected.mask_vegetation);
    EXPECT_EQ(p.closing_radius_px, expected.closing_radius_px);
    EXPECT_EQ(p.gsd_mm_per_px, expected.gsd_mm_per_px);
    EXPECT_EQ(p.min_plant_area_mm2, expected.min_plant_area_mm2);
    EXPECT_EQ(p.defect_depth_mm, expected.defect_depth_mm);
    EXPECT_EQ(p.min_leaves, expected.min_leaves);
    EXPECT_EQ(p.min_intersection_angle_deg, expected.min_intersection_angle_deg);
    EXPECT_EQ(p.stem_estimator, expected.stem_estimator);
    EXPECT_EQ(p.defect_depth_rel, expected.defect_depth_rel);
    EXPECT_EQ(p.min_confidence, expected.min_confidence);
    EXPECT_EQ(p.grass_min_area_mm2, expected.grass_min_area_mm2);
    EXPECT_EQ(p.grass_max_width_mm, expected.grass_max_width_mm);
}

TEST(Config, DocumentedDefaultFileLoadsAndEqualsTheDefaults)
{
    Config config;
    const auto error = config.load_file(kDefaultConfig);
    ASSERT_FALSE(error) << error->to_string();
    expect_same_values(config, Config{});
    // Every key is written out in the file, not left to its default.
    for (const KeySpec& spec : schema())
        EXPECT_EQ(config.origin_of(spec.key).rfind(kDefaultConfig.string() + ":", 0), 0u)
            << spec.key << " from " << config.origin_of(spec.key);
    // Each list: the default list (one item), every item key written out.
    for (const ListSpec& list : list_schema()) {
        ASSERT_EQ(config.list_size(list.section), 1u) << list.section;
        for (const KeySpec& spec : item_keys(list.section)) {
            const std::string leaf(item_leaf_of(spec));
            SCOPED_TRACE(std::string(spec.key));
            EXPECT_EQ(config.item_origin_of(list.section, 0, leaf).rfind(kDefaultConfig.string() + ":", 0), 0u)
                << config.item_origin_of(list.section, 0, leaf);
            if (spec.type == ValueType::integer) {
                EXPECT_EQ(test::item_int_of(config, list.section, 0, leaf), std::stol(std::string(spec.default_value)));
            } else if (spec.type == ValueType::real) {
                EXPECT_EQ(test::item_real_of(config, list.section, 0, leaf), to_double(spec.default_value));
            }
        }
    }
}

TEST(Config, DocumentedDefaultFileStatesEachRangeAndChoiceList)
{
    std::ifstream in(kDefaultConfig);
    ASSERT_TRUE(in);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::vector<const KeySpec*> keys;
    for (const KeySpec& spec : schema())
        keys.push_back(&spec);
    for (const KeySpec& spec : list_item_schema())  // the list item keys too
        keys.push_back(&spec);
    for (const KeySpec* key : keys) {
        const KeySpec& spec = *key;
        SCOPED_TRACE(std::string(spec.key));
        if (is_numeric(spec)) {
            EXPECT_NE(text.find(std::string(spec.unit) + ", range [" + format_number(spec.min) + ", " +
                                format_number(spec.max) + "]"),
                      std::string::npos);
        }
        if (spec.type == ValueType::choice) {
            EXPECT_NE(text.find("Choice: " + list_choices(spec, " | ") + "."), std::string::npos);
        }
    }
}

// --- file format ---------------------------------------------------------------

TEST_F(ConfigFileTest, ReadsSectionsKeysCommentsAndBlankLines)
{
    const fs::path path = write(
        "# leading comment\n"
        "\n"
        "closing:   # trailing comment on a section\n"
        "  # comment inside a section\n"
        "\n"
        "  radius_px: 6 # trailing comment\n"
        "   # a comment may be indented any way\n"
        "segment:\n"
        "    method: \"ndvi\"   # quoted, four-space indentation\n"
        "    threshold: triangle\n"
        "camera:\n"
        "  gsd_mm_per_px: 1.5e-1\n"
        "stem:\n"
        "  min_leaves: +4\n"
        "  min_angle_deg: 0\n"
        "\n");
    Config config;
    const auto error = config.load_file(path);
    ASSERT_FALSE(error) << error->to_string();
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 6);
    EXPECT_EQ(config.origin_of("closing.radius_px"), path.string() + ":6");
    EXPECT_EQ(test::text_of(config, "segment.method"), "ndvi");
    EXPECT_EQ(config.origin_of("segment.method"), path.string() + ":9");
    EXPECT_EQ(test::text_of(config, "segment.threshold"), "triangle");
    EXPECT_EQ(test::real_of(config, "camera.gsd_mm_per_px"), 0.15);
    EXPECT_EQ(test::int_of(config, "stem.min_leaves"), 4);
    EXPECT_EQ(test::real_of(config, "stem.min_angle_deg"), 0.0);
    // Keys the file leaves out keep their values.
    EXPECT_EQ(test::text_of(config, "stem.method"), "robust");
    EXPECT_EQ(config.origin_of("stem.method"), "default");
}

TEST_F(ConfigFileTest, AcceptsCrlfLineEndingsAndAByteOrderMark)
{
    Config config;
    const auto error = config.load_file(write("\xEF\xBB\xBF" "closing:\r\n  radius_px: 7\r\n"));
    ASSERT_FALSE(error) << error->to_string();
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 7);
}

TEST_F(ConfigFileTest, HashInsideAValueIsNotAComment)
{
    // '#' starts a comment only after whitespace, and never inside quotes.
    expect_error("segment:\n  method: \"exg # x\"\n", 2, "segment.method", "'exg # x' is not one of auto, chromatic_exg, exg, ndvi, mask, exg_and_ndvi");
    expect_error("segment:\n  method: exg#x\n", 2, "segment.method", "'exg#x' is not one of");
}

TEST_F(ConfigFileTest, AnEmptyFileChangesNothing)
{
    Config config;
    ASSERT_FALSE(config.set_override("closing.radius_px=3"));
    const auto error = config.load_file(write("# only a comment\n\n"));
    ASSERT_FALSE(error) << error->to_string();
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 3);
}

// --- file errors: file, line and key ------------------------------------------

TEST_F(ConfigFileTest, OutOfRangeNamesFileLineKeyRangeAndUnit)
{
    const fs::path path = write("# radius\nclosing:\n  radius_px: 6000\n");
    Config config;
    const auto error = config.load_file(path);
    ASSERT_TRUE(error);
    EXPECT_EQ(error->to_string(),
              path.string() + ":3: key 'closing.radius_px': 6000 is out of range [0, 50] px");
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 5);
}

TEST_F(ConfigFileTest, TabIndentation)
{
    expect_error("closing:\n\tradius_px: 6\n", 2, "closing.radius_px", "tab in the indentation");
    expect_error("closing:\n  \tradius_px: 6\n", 2, "closing.radius_px", "indent with spaces");
    // yaml-cpp reads these; the format does not.
    expect_error("map:\n  file: \"a\n\tb\"\n", 3, "", "tab in the indentation");
    expect_error("closing: {\n\tradius_px: 6}\n", 2, "closing.radius_px", "tab in the indentation");
}

TEST_F(ConfigFileTest, KeyOutsideASection)
{
    expect_error("# no section yet\n  radius_px: 6\n", 2, "radius_px", "key outside a section");
    expect_error("radius_px: 6\n", 1, "radius_px", "indent it under 'closing:'");
    expect_error("\nclosing.radius_px: 6\n", 2, "closing.radius_px", "write 'closing:' and indent 'radius_px: ...'");
}

TEST_F(ConfigFileTest, SectionWithAValue)
{
    expect_error("camera:\n  gsd_mm_per_px: 0.5\nclosing: 6\n", 3, "closing", "a section cannot have a value");
}

TEST_F(ConfigFileTest, NestingDeeperThanOneLevel)
{
    expect_error("closing:\n  radius_px:\n    value: 6\n", 3, "closing.radius_px.value",
                 "nesting deeper than one level");
    expect_error("closing:\n  radius_px:\n  # comment\n\n      value: 6\n", 5, "closing.radius_px.value",
                 "nesting deeper than one level");
}

TEST_F(ConfigFileTest, InconsistentIndentation)
{
    // YAML cannot read these: yaml-cpp's message, with a hint.
    expect_error("stem:\n  min_leaves: 4\n    method: com\n", 3, "stem.method",
                 "invalid YAML: illegal map value (inconsistent indentation? 4 spaces here, 2 on the line above)");
    expect_error("stem:\n    min_leaves: 4\n  method: com\n", 3, "stem.method",
                 "invalid YAML: end of map not found (inconsistent indentation? 2 spaces here, 4 on the line above)");
}

TEST_F(ConfigFileTest, DuplicateKeysAndSections)
{
    expect_error("closing:\n  radius_px: 6\n  radius_px: 7\n", 3, "closing.radius_px",
                 "duplicate key (first on line 2)");
    expect_error("closing:\n  radius_px: 6\nstem:\n  min_leaves: 4\nclosing:\n  radius_px: 7\n", 5, "closing",
                 "duplicate section (first on line 1)");
}

TEST_F(ConfigFileTest, UnknownKeysAndSections)
{
    expect_error("closing:\n  radius: 6\n", 2, "closing.radius", "unknown key; did you mean 'closing.radius_px'?");
    expect_error("segment:\n  radius_px: 6\n", 2, "segment.radius_px", "did you mean 'closing.radius_px'?");
    expect_error("stem:\n  colour: green\n", 2, "stem.colour", "section 'stem' has: method, min_leaves, min_angle_deg");
    expect_error("\n\ncapture:\n  fps: 30\n", 3, "capture",
                 "unknown section; the sections are: camera, segment, closing, plants, leaves, stem");
}

TEST_F(ConfigFileTest, WrongTypes)
{
    expect_error("closing:\n  radius_px: abc\n", 2, "closing.radius_px", "expected an integer, got 'abc'");
    expect_error("closing:\n  radius_px: 6.5\n", 2, "closing.radius_px", "expected an integer, got '6.5'");
    expect_error("closing:\n  radius_px: \"6\"\n", 2, "closing.radius_px", "expected an integer, got a quoted string");
    expect_error("closing:\n  radius_px: '6'\n", 2, "closing.radius_px", "expected an integer, got a quoted string");
    expect_error("camera:\n  gsd_mm_per_px: fast\n", 2, "camera.gsd_mm_per_px", "expected a real number, got 'fast'");
    expect_error("camera:\n  gsd_mm_per_px: nan\n", 2, "camera.gsd_mm_per_px", "expected a real number, got 'nan'");
    expect_error("camera:\n  gsd_mm_per_px: 0.3mm\n", 2, "camera.gsd_mm_per_px", "expected a real number");
}

TEST_F(ConfigFileTest, OutOfRange)
{
    expect_error("stem:\n  min_leaves: 1\n", 2, "stem.min_leaves", "1 is out of range [2, 16] count");
    expect_error("camera:\n  gsd_mm_per_px: 0\n", 2, "camera.gsd_mm_per_px", "0 is out of range [0.01, 10] mm/px");
    expect_error("plants:\n  min_area_mm2: -1\n", 2, "plants.min_area_mm2", "-1 is out of range [0, 100000] mm2");
    expect_error("closing:\n  radius_px: 99999999999999999999999\n", 2, "closing.radius_px",
                 "99999999999999999999999 is out of range [0, 50] px");
}

TEST_F(ConfigFileTest, ChoiceNotAllowedListsTheChoices)
{
    expect_error("segment:\n  method: rgb\n", 2, "segment.method", "'rgb' is not one of auto, chromatic_exg, exg, ndvi, mask, exg_and_ndvi");
    expect_error("stem:\n  method: Leaves\n", 2, "stem.method", "'Leaves' is not one of robust, paper, com");
}

TEST_F(ConfigFileTest, EmptyValues)
{
    expect_error("closing:\n  radius_px:\n", 2, "closing.radius_px", "empty value");
    expect_error("closing:\n  radius_px:   # nothing\nstem:\n  min_leaves: 3\n", 2, "closing.radius_px",
                 "empty value");
    expect_error("segment:\n  method: \"\"\n", 2, "segment.method", "'' is not one of auto, chromatic_exg, exg, ndvi, mask, exg_and_ndvi");
    // YAML's explicit nulls are no value either, with a word on quoting them.
    const std::string null_message = "empty value ('~' and 'null' are YAML for no value; quote them for the text)";
    expect_error("can:\n  log_file: ~\n", 2, "can.log_file", null_message);
    expect_error("can:\n  log_file: null\n", 2, "can.log_file", null_message);
}

TEST_F(ConfigFileTest, MalformedLines)
{
    expect_error("closing:\n  radius_px 6\n", 2, "", "expected 'section:' or 'key: value', got 'radius_px 6'");
    expect_error("closing:\n  radius_px:6\n", 2, "closing.radius_px", "expected a space after ':'");
    expect_error("segment:\n  method: \"exg\n", 2, "segment.method", "unterminated double-quoted string");
    expect_error("segment:\n  method: 'exg\n", 2, "segment.method", "unterminated single-quoted string");
    expect_error("segment:\n  method: \"exg\" ndvi\n", 2, "segment.method", "invalid YAML: end of map not found");
    // An IPv6 address unquoted: '[' opens a YAML list.
    expect_error("web:\n  listen: [::1]:8080\n", 2, "web.listen",
                 "invalid YAML: end of map not found; a value that starts with '[' is a YAML list or map: "
                 "double-quote it to mean text, e.g. \"[::1]:8080\"");
    expect_error("web:\n  listen: [::1]:8080  # the view\n", 2, "web.listen", "e.g. \"[::1]:8080\"");
    expect_error("segment:\n  method: [exg, ndvi]\n", 2, "segment.method",
                 "expected a value, got a list; a section holds only 'key: value' lines");
    expect_error("segment:\n  method: {a: 1}\n", 2, "segment.method.a", "nesting deeper than one level");
    expect_error("segment:\n  - exg\n", 2, "segment", "expected 'key: value' lines under 'segment:', got a list");
    expect_error("closing:\n  radius_px: 6\n  : 7\n", 3, "closing", "expected a key name");
}

TEST_F(ConfigFileTest, TheShapeIsAMapOfSectionsOfScalars)
{
    expect_error("- closing\n", 1, "", "expected 'section:' lines (a map of sections) at the top level, got a list");
    expect_error("\nclosing\n", 2, "", "expected 'section:' lines (a map of sections) at the top level, got 'closing'");
    expect_error("closing:\nstem:\n  min_leaves: 3\n", 1, "closing",
                 "empty section; put its keys ('key: value') on indented lines below it, or remove the line");
    expect_error("closing:\n  radius_px: 6\n---\nstem:\n  min_leaves: 3\n", 3, "",
                 "more than one YAML document ('---'); a config file holds one map of sections");
    expect_error("closing:\n  radius_px: ~\n", 2, "closing.radius_px", "empty value ('~' and 'null' are YAML");
    expect_error("map:\n  file: null\n", 2, "map.file", "empty value ('~' and 'null' are YAML");
    expect_error("closing:\n  radius_px: !!int 6\n", 2, "closing.radius_px", "YAML tags are not supported");
    // A key YAML would keep once is still a duplicate, however it is quoted.
    expect_error("closing:\n  radius_px: 6\n  \"radius_px\": 7\n", 3, "closing.radius_px",
                 "duplicate key (first on line 2)");
    expect_error("closing: {radius_px: 6, radius_px: 7}\n", 1, "closing.radius_px", "duplicate key (first on line 1)");
}

TEST_F(ConfigFileTest, AnyYamlLayoutOfTheSameShapeReads)
{
    const fs::path path = write(
        "---\n"
        "closing: {radius_px: 7}\n"
        "segment:\n"
        "  method: 'ndvi'\n"
        "map:\n"
        "  file: \"it's \\\"here\\\"\"\n"
        "can:\n"
        "  interface: 'can''0'\n"
        "  log_file: \"null\"\n"
        "...\n");
    Config config;
    const auto error = config.load_file(path);
    ASSERT_FALSE(error) << error->to_string();
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 7);
    EXPECT_EQ(config.origin_of("closing.radius_px"), path.string() + ":2");
    EXPECT_EQ(test::text_of(config, "segment.method"), "ndvi");
    EXPECT_EQ(test::text_of(config, "map.file"), "it's \"here\"");
    EXPECT_EQ(test::text_of(config, "can.interface"), "can'0");
    EXPECT_EQ(test::text_of(config, "can.log_file"), "null");
}

TEST_F(ConfigFileTest, AnErrorLeavesEarlierValuesUntouched)
{
    Config config;
    ASSERT_FALSE(config.set_override("stem.min_leaves=5"));
    const auto error = config.load_file(write("closing:\n  radius_px: 6\nstem:\n  min_leaves: 99\n"));
    ASSERT_TRUE(error);
    EXPECT_EQ(error->line, 4);
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 5);
    EXPECT_EQ(config.origin_of("closing.radius_px"), "default");
    EXPECT_EQ(test::int_of(config, "stem.min_leaves"), 5);
    EXPECT_EQ(config.origin_of("stem.min_leaves"), "--set");
}

TEST_F(ConfigFileTest, UnreadableFile)
{
    const fs::path missing = dir_ / "missing.yaml";
    Config config;
    auto error = config.load_file(missing);
    ASSERT_TRUE(error);
    EXPECT_EQ(error->line, 0);
    EXPECT_EQ(error->key, "");
    EXPECT_EQ(error->to_string(), missing.string() + ": cannot read file: No such file or directory");

    error = config.load_file(dir_);
    ASSERT_TRUE(error);
    EXPECT_EQ(error->to_string(), dir_.string() + ": cannot read file: it is a directory");
    expect_same_values(config, Config{});
}

TEST_F(ConfigFileTest, EndlessAndFailingReadsAreErrorsNotAborts)
{
    Config config;
    // A device that never ends, and a FIFO no one writes: refused at once.
    auto error = config.load_file("/dev/zero");
    ASSERT_TRUE(error);
    EXPECT_EQ(error->to_string(), "/dev/zero: cannot read file: not a regular file (a FIFO or a device)");
    const fs::path fifo = dir_ / "fifo.yaml";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    error = config.load_file(fifo);
    ASSERT_TRUE(error);
    EXPECT_EQ(error->to_string(), fifo.string() + ": cannot read file: not a regular file (a FIFO or a device)");
    // A file too large to be a configuration.
    const fs::path big = write(std::string(1024 * 1024 + 1, '#'), "big.yaml");
    error = config.load_file(big);
    ASSERT_TRUE(error);
    EXPECT_EQ(error->to_string(), big.string() + ": cannot read file: larger than 1024 KiB; is it a configuration file?");
    // A read that fails with EIO (offset 0 of this process's memory is unmapped).
    error = config.load_file("/proc/self/mem");
    ASSERT_TRUE(error);
    EXPECT_EQ(error->to_string(), "/proc/self/mem: cannot read file: read error: Input/output error");
    error = config.load_file("");
    ASSERT_TRUE(error);
    EXPECT_NE(error->to_string().find("empty file name"), std::string::npos) << error->to_string();
    expect_same_values(config, Config{});
}

TEST_F(ConfigFileTest, AStrayCommaIsOneClearErrorNotAnEndlessLoad)
{
    // yaml-cpp 0.7 reads a ',' outside a flow collection as endless empty
    // documents; loading them all used to allocate until std::bad_alloc.
    const std::string message = "(a ',' outside [ ] or { } starts a document too)";
    expect_error(",", 1, "", message);
    expect_error(",\nclosing:\n  radius_px: 6\n", 1, "", message);
    expect_error("closing:\n  radius_px: 6\n---\n,\n", 3, "", message);
    expect_error("closing:\n  radius_px: 6\n...\n,\n", 4, "", message);
}

TEST_F(ConfigFileTest, AliasesOfAliasesAreOneErrorNotAnAbort)
{
    // Each line doubles the one above: 2^40 values if every alias were copied.
    std::string text = "camera: &a0 [1]\n";
    for (int i = 1; i <= 40; ++i) {
        const std::string n = std::to_string(i), above = std::to_string(i - 1);
        text.append("k").append(n).append(": &a").append(n).append(" [*a").append(above).append(", *a");
        text.append(above).append("]\n");
    }
    Config config;
    const auto error = config.load_text(text, "x");
    ASSERT_TRUE(error);
    EXPECT_NE(error->message.find("invalid YAML: more than 100000 values (aliases)"), std::string::npos)
        << error->to_string();
    expect_same_values(config, Config{});
    // One alias of a value reads as the value.
    ASSERT_FALSE(config.load_text("closing:\n  radius_px: &r 7\nstem:\n  min_leaves: *r\n", "x"));
    EXPECT_EQ(test::int_of(config, "stem.min_leaves"), 7);
}

// --- --set ---------------------------------------------------------------------

TEST(ConfigSet, GoodValuesOverride)
{
    Config config;
    EXPECT_FALSE(config.set_override("closing.radius_px=6"));
    EXPECT_FALSE(config.set_override("camera.gsd_mm_per_px=0.5"));
    EXPECT_FALSE(config.set_override("segment.method=mask"));
    EXPECT_FALSE(config.set_override("stem.method=\"com\""));
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 6);
    EXPECT_EQ(test::real_of(config, "camera.gsd_mm_per_px"), 0.5);
    EXPECT_EQ(test::text_of(config, "segment.method"), "mask");
    EXPECT_EQ(test::text_of(config, "stem.method"), "com");
    EXPECT_EQ(config.origin_of("closing.radius_px"), "--set");
    EXPECT_EQ(config.origin_of("stem.min_leaves"), "default");
    // The last --set of a key wins.
    EXPECT_FALSE(config.set_override("closing.radius_px=0"));
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 0);
}

TEST(ConfigSet, BadValuesGiveOneLineAndChangeNothing)
{
    struct Case {
        const char* set;
        const char* expected;
    };
    const Case cases[] = {
        {"closing.radius_px=abc", "--set closing.radius_px=abc: key 'closing.radius_px': expected an integer, got 'abc'"},
        {"closing.radius_px=51", "--set closing.radius_px=51: key 'closing.radius_px': 51 is out of range [0, 50] px"},
        {"closing.radius_px=", "--set closing.radius_px=: key 'closing.radius_px': empty value"},
        {"segment.method=rgb", "--set segment.method=rgb: key 'segment.method': 'rgb' is not one of auto, chromatic_exg, exg, ndvi, mask, exg_and_ndvi"},
        {"closing.radius=6", "--set closing.radius=6: key 'closing.radius': unknown key; did you mean 'closing.radius_px'?"},
        {"closing.radius_px", "--set closing.radius_px: expected KEY=VALUE, e.g. --set closing.radius_px=6"},
        {"=6", "--set =6: expected KEY=VALUE, e.g. --set closing.radius_px=6"},
        {"camera.gsd_mm_per_px=inf", "--set camera.gsd_mm_per_px=inf: key 'camera.gsd_mm_per_px': expected a real number, got 'inf'"},
        // --set values are not YAML: a double-quoted string takes only its four escapes, and YAML syntax is refused.
        {"can.log_file=\"a\\qb\"", "--set can.log_file=\"a\\qb\": key 'can.log_file': unsupported escape '\\q' in a double-quoted string (use \\\", \\\\, \\n or \\t)"},
        {"can.log_file=\"a\" b", "--set can.log_file=\"a\" b: key 'can.log_file': unexpected text after the closing quote: 'b'"},
        {"can.log_file=\"ab", "--set can.log_file=\"ab: key 'can.log_file': unterminated double-quoted string"},
        {"can.log_file=[a]", "--set can.log_file=[a]: key 'can.log_file': unsupported YAML syntax '[a]'; write a plain value or a double-quoted string"},
    };
    for (const Case& c : cases) {
        Config config;
        const auto error = config.set_override(c.set);
        ASSERT_TRUE(error) << c.set;
        EXPECT_EQ(error->to_string(), c.expected);
        expect_same_values(config, Config{});
        EXPECT_EQ(config.origin_of("closing.radius_px"), "default");
    }
}

TEST_F(ConfigFileTest, LaterSetOverridesTheFile)
{
    const fs::path path = write("closing:\n  radius_px: 6\nstem:\n  min_leaves: 4\n");
    Config config;
    ASSERT_FALSE(config.load_file(path));
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 6);
    ASSERT_FALSE(config.set_override("closing.radius_px=8"));
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 8);
    EXPECT_EQ(config.origin_of("closing.radius_px"), "--set");
    EXPECT_EQ(test::int_of(config, "stem.min_leaves"), 4);
    EXPECT_EQ(config.origin_of("stem.min_leaves"), path.string() + ":4");
}

// --- ranges --------------------------------------------------------------------

TEST(ConfigRange, MinAndMaxAcceptedJustOutsideRejected)
{
    for (const KeySpec& spec : schema()) {
        if (!is_numeric(spec))
            continue;
        SCOPED_TRACE(std::string(spec.key));
        const std::string key(spec.key);
        const bool integer = spec.type == ValueType::integer;
        const auto value_of = [&](const Config& c) {
            return integer ? static_cast<double>(test::int_of(c, key)) : test::real_of(c, key);
        };
        const double below = integer ? spec.min - 1 : std::nextafter(spec.min, -1e300);
        const double above = integer ? spec.max + 1 : std::nextafter(spec.max, 1e300);
        Config config;
        for (const double inside : {spec.min, spec.max}) {
            ASSERT_FALSE(config.set_override(key + "=" + format_number(inside)));
            EXPECT_EQ(value_of(config), inside);
        }
        for (const double outside : {below, above}) {
            const auto error = config.set_override(key + "=" + format_number(outside));
            ASSERT_TRUE(error) << format_number(outside);
            EXPECT_NE(error->message.find("is out of range [" + format_number(spec.min) + ", " +
                                          format_number(spec.max) + "] " + std::string(spec.unit)),
                      std::string::npos)
                << error->to_string();
            EXPECT_EQ(value_of(config), spec.max);  // unchanged
        }
    }
}

TEST_F(ConfigFileTest, RangeBoundariesInAFile)
{
    Config config;
    ASSERT_FALSE(config.load_file(write("closing:\n  radius_px: 0\nleaves:\n  defect_depth_mm: 100\n")));
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 0);
    EXPECT_EQ(test::real_of(config, "leaves.defect_depth_mm"), 100.0);
    ASSERT_FALSE(config.load_file(write("closing:\n  radius_px: 50\nleaves:\n  defect_depth_mm: 0.1\n")));
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 50);
    EXPECT_EQ(test::real_of(config, "leaves.defect_depth_mm"), 0.1);
    expect_error("closing:\n  radius_px: -1\n", 2, "closing.radius_px", "-1 is out of range [0, 50] px");
    expect_error("closing:\n  radius_px: 51\n", 2, "closing.radius_px", "51 is out of range [0, 50] px");
    expect_error("leaves:\n  defect_depth_mm: 0.09999\n", 2, "leaves.defect_depth_mm",
                 "0.09999 is out of range [0.1, 100] mm");
    expect_error("leaves:\n  defect_depth_mm: 100.00001\n", 2, "leaves.defect_depth_mm",
                 "100.00001 is out of range [0.1, 100] mm");
}

// --- to_yaml -------------------------------------------------------------------

TEST_F(ConfigFileTest, ToYamlRoundTrips)
{
    Config config;
    ASSERT_FALSE(config.load_file(write("closing:\n  radius_px: 7\n")));
    for (const char* set : {"camera.gsd_mm_per_px=0.30000000000000004", "segment.method=ndvi",
                            "segment.threshold=triangle", "segment.mask_vegetation=zero",
                            "plants.min_area_mm2=12345.678", "leaves.defect_depth_mm=0.1",
                            "stem.method=com", "stem.min_leaves=16", "stem.min_angle_deg=1e-7",
                            // Text YAML must quote and escape: quotes, '#', a tab, a newline, a control byte.
                            "map.file=\"a \\\"b\\\" # c\\td\\n: - e\\\\\"", "can.interface=x\x01y"})
        ASSERT_FALSE(config.set_override(set)) << set;
    EXPECT_EQ(test::text_of(config, "map.file"), "a \"b\" # c\td\n: - e\\");
    const std::string yaml = config.to_yaml();
    EXPECT_NE(yaml.find("closing:\n  radius_px: 7  # [0, 50] px; " + (dir_ / "test.yaml").string() + ":2\n"),
              std::string::npos)
        << yaml;
    EXPECT_NE(yaml.find("  method: ndvi  # auto|chromatic_exg|exg|ndvi|mask|exg_and_ndvi; --set\n"), std::string::npos) << yaml;

    const fs::path dumped = write(yaml, "dumped.yaml");
    Config reloaded;
    const auto error = reloaded.load_file(dumped);
    ASSERT_FALSE(error) << error->to_string() << "\n" << yaml;
    expect_same_values(reloaded, config);
    for (const KeySpec& spec : schema())
        EXPECT_EQ(reloaded.origin_of(spec.key).rfind(dumped.string() + ":", 0), 0u) << spec.key;

    // The defaults round-trip too, and load_text reads the same text.
    Config defaults;
    ASSERT_FALSE(defaults.load_text(Config{}.to_yaml(), "defaults"));
    expect_schema_defaults(defaults);
    EXPECT_EQ(defaults.origin_of("closing.radius_px").rfind("defaults:", 0), 0u);
}

// --- the pipeline's settings -------------------------------------------------------------

TEST(VisionConfig, EveryKeyMapsToItsParamsField)
{
    Config config;
    for (const char* set : {"camera.gsd_mm_per_px=0.5", "segment.method=ndvi", "segment.threshold=triangle",
                            "segment.mask_vegetation=zero", "closing.radius_px=4", "plants.min_area_mm2=25",
                            "leaves.defect_depth_mm=2.5", "stem.method=com", "stem.min_leaves=5",
                            "stem.min_angle_deg=20"})
        ASSERT_FALSE(config.set_override(set)) << set;
    const vision::Params p = config.settings().daemon.vision;
    EXPECT_EQ(p.gsd_mm_per_px, 0.5);
    EXPECT_EQ(p.segmentation, vision::Segmentation::ndvi);
    EXPECT_EQ(p.threshold, vision::ThresholdMethod::triangle);
    EXPECT_EQ(p.mask_vegetation, vision::MaskVegetation::zero);
    EXPECT_EQ(p.closing_radius_px, 4);
    EXPECT_EQ(p.min_plant_area_mm2, 25.0);
    EXPECT_EQ(p.defect_depth_mm, 2.5);
    EXPECT_EQ(p.stem_estimator, vision::StemEstimator::com);
    EXPECT_EQ(p.min_leaves, 5);
    EXPECT_EQ(p.min_intersection_angle_deg, 20.0);

    ASSERT_FALSE(config.set_override("segment.method=mask"));
    EXPECT_EQ(config.settings().daemon.vision.segmentation, vision::Segmentation::mask);
}

}  // namespace
}  // namespace stemd::config

TEST(ConfigSchema, ReadmeTableIsTheSchemas)
{
    // The README's configuration table is schema_markdown() verbatim: a key
    // added, removed or changed in the schema must show there too.
    std::ifstream readme(std::string(STEMD_SOURCE_DIR) + "/README.md");
    ASSERT_TRUE(readme) << "README.md";
    const std::string text((std::istreambuf_iterator<char>(readme)), std::istreambuf_iterator<char>());
    const std::string table = stemd::config::schema_markdown();
    EXPECT_NE(text.find(table), std::string::npos) << "README.md's table differs from the schema; it should read:\n"
                                                   << table;
}

namespace stemd::config {
namespace {

// The value a row's default means, as its binding loads it.
bool equals_default(const KeySpec& spec, const detail::ConfigValue& v)
{
    const std::string d(spec.default_value);
    switch (spec.type) {
    case ValueType::integer: return v.integer == std::stol(d);
    case ValueType::real: return v.real == std::strtod(d.c_str(), nullptr);
    case ValueType::boolean: return v.boolean == (d == "true");
    case ValueType::choice:
    case ValueType::text: return v.text == d;
    }
    return false;
}

// The struct defaults (Settings{}) are the schema's defaults, key by key:
// neither can change without the other.
TEST(ConfigSettings, StructDefaultsAreTheSchemaDefaults)
{
    const Settings defaults{};
    for (const KeySpec& spec : schema()) {
        detail::ConfigValue v;
        spec.load(spec, defaults, 0, v);
        EXPECT_TRUE(equals_default(spec, v)) << spec.key << " = " << v.integer << " / " << v.real << " / "
                                             << v.boolean << " / '" << v.text << "'";
    }
    for (const ListSpec& list : list_schema()) {
        ASSERT_EQ(list.size(defaults), 1u) << list.section;
        for (const KeySpec& spec : item_keys(list.section)) {
            detail::ConfigValue v;
            spec.load(spec, defaults, 0, v);
            EXPECT_TRUE(equals_default(spec, v)) << spec.key;
        }
    }
}

// A value other than the default for `spec`, as --set writes it.
std::string other_value(const KeySpec& spec)
{
    switch (spec.type) {
    case ValueType::integer:
    case ValueType::real:
        return format_number(std::strtod(std::string(spec.default_value).c_str(), nullptr) == spec.max ? spec.min
                                                                                                        : spec.max);
    case ValueType::boolean: return spec.default_value == "true" ? "false" : "true";
    case ValueType::choice: {
        const std::string all = list_choices(spec, "|");
        const std::string first = all.substr(0, all.find('|'));
        return first == spec.default_value ? all.substr(all.find('|') + 1, all.find('|', all.find('|') + 1) - all.find('|') - 1)
                                           : first;
    }
    case ValueType::text: return "x";
    }
    return "";
}

// Each key sets its own member: changing one key changes what that key
// loads back and nothing else (two rows bound to one member would show).
TEST(ConfigSettings, EveryKeySetsItsOwnMember)
{
    for (const KeySpec& changed : schema()) {
        Config config;
        const std::string value = other_value(changed);
        ASSERT_FALSE(config.set_override(std::string(changed.key) + "=" + value)) << changed.key << "=" << value;
        const Settings settings = config.settings();
        for (const KeySpec& spec : schema()) {
            detail::ConfigValue v;
            spec.load(spec, settings, 0, v);
            if (&spec == &changed)
                EXPECT_FALSE(equals_default(spec, v)) << spec.key << " did not change with --set " << value;
            else
                EXPECT_TRUE(equals_default(spec, v)) << spec.key << " changed with --set " << changed.key << "=" << value;
        }
    }
}

}  // namespace
}  // namespace stemd::config
