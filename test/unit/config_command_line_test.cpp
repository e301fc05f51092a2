// --config and --set into a Config, as stemd and its tools load them (the
// options themselves: test/daemon/command_line.sh and the tools' tests).
#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "config_test_util.hpp"

#include "stemd/config/command_line.hpp"

using namespace stemd::config;

TEST(CommandLine, BuildConfigAppliesSetsAfterTheFileAndStopsAtTheFirstError)
{
    Config config;
    EXPECT_FALSE(build_config({{}, {"closing.radius_px=7"}}, config));
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 7);
    const auto error = build_config({{}, {"closing.radius_px=abc"}}, config);
    ASSERT_TRUE(error.has_value());
    EXPECT_NE(error->to_string().find("closing.radius_px"), std::string::npos);
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 7);
}

namespace {

namespace fs = std::filesystem;

// A file in a directory of its own, removed with it.
struct TempFiles {
    fs::path dir = fs::temp_directory_path() / ("stemd-command-line-test-" + std::to_string(::getpid()));
    TempFiles() { fs::create_directories(dir); }
    ~TempFiles()
    {
        std::error_code ec;
        fs::remove_all(dir, ec);
    }
    std::string write(const std::string& name, const std::string& text)
    {
        std::ofstream(dir / name) << text;
        return (dir / name).string();
    }
};

}  // namespace

TEST(CommandLine, LaterConfigFilesOverrideEarlierOnesKeyByKey)
{
    TempFiles files;
    // Both give a section of the same name (a calibration fragment's
    // "source:" beside the site file's): a layer, not a duplicate section.
    const std::string site = files.write("site.yaml",
                                         "source:\n  fps: 20\n  width_px: 640\nclosing:\n  radius_px: 6\n"
                                         "tools:\n  - id: 1\n  - id: 2\n");
    const std::string fragment = files.write("fragment.yaml", "# from stemd-calibrate\nsource:\n  width_px: 800\n");
    Config config;
    ASSERT_FALSE(build_config({{site, fragment}, {"closing.radius_px=7"}}, config));
    const Settings settings = config.settings();
    EXPECT_EQ(settings.daemon.frame_size.width, 800);
    EXPECT_EQ(config.origin_of("source.width_px"), fragment + ":3");
    EXPECT_EQ(settings.daemon.fps, 20);
    EXPECT_EQ(config.origin_of("source.fps"), site + ":2");
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 7);
    EXPECT_EQ(config.origin_of("closing.radius_px"), "--set");
    EXPECT_EQ(config.list_size("tools"), 2u);

    // A later file's list replaces the list.
    const std::string one_tool = files.write("one_tool.yaml", "tools:\n  - id: 5\n");
    Config replaced;
    ASSERT_FALSE(build_config({{site, one_tool}, {}}, replaced));
    ASSERT_EQ(replaced.list_size("tools"), 1u);
    EXPECT_EQ(test::item_int_of(replaced, "tools", 0, "id"), 5);

    // Each error names its own file and line.
    const std::string bad = files.write("bad.yaml", "source:\n  width_px: 800\n  fsp: 30\n");
    Config failed;
    const auto error = build_config({{site, bad}, {}}, failed);
    ASSERT_TRUE(error);
    EXPECT_EQ(error->origin, bad);
    EXPECT_EQ(error->line, 3);
    EXPECT_EQ(error->key, "source.fsp");
    const auto first = build_config({{bad, site}, {}}, failed);
    ASSERT_TRUE(first);
    EXPECT_EQ(first->origin, bad);
}
