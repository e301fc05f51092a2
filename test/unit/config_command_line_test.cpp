// The command-line helpers stemd and its tools share.
#include <gtest/gtest.h>

#include "config_test_util.hpp"

#include <vector>

#include "stemd/config/command_line.hpp"

using namespace stemd::config;

namespace {

// argv for the helpers: a program name then `args`.
struct Argv {
    explicit Argv(std::vector<std::string> args) : storage(std::move(args))
    {
        storage.insert(storage.begin(), "prog");
        for (auto& s : storage)
            pointers.push_back(s.data());
    }
    int argc() { return static_cast<int>(pointers.size()); }
    char** argv() { return pointers.data(); }
    std::vector<std::string> storage;
    std::vector<char*> pointers;
};

}  // namespace

TEST(CommandLine, ConfigAndSetAreCollectedInOrder)
{
    Argv a({"--config", "x.yaml", "--set", "closing.radius_px=6", "--other", "--set", "stem.method=com"});
    ArgReader in(a.argc(), a.argv());
    ConfigArgs config;
    std::vector<std::string> rest;
    while (in.next())
        if (!in.config_option(config))
            rest.push_back(in.arg());
    EXPECT_FALSE(in.failed());
    EXPECT_EQ(config.file, "x.yaml");
    EXPECT_EQ(config.sets, (std::vector<std::string>{"closing.radius_px=6", "stem.method=com"}));
    EXPECT_EQ(rest, std::vector<std::string>{"--other"});
}

TEST(CommandLine, AMissingValueNamesTheOption)
{
    Argv a({"--set"});
    ArgReader in(a.argc(), a.argv());
    ConfigArgs config;
    ASSERT_TRUE(in.next());
    EXPECT_TRUE(in.config_option(config));
    EXPECT_TRUE(in.failed());
    EXPECT_EQ(in.error(), "--set needs a value");
    EXPECT_TRUE(config.sets.empty());
    EXPECT_FALSE(in.next());
}

TEST(CommandLine, AnEmptyConfigFileNameIsAnError)
{
    // It used to mean "no file": the defaults, without a word.
    Argv a({"--config", ""});
    ArgReader in(a.argc(), a.argv());
    ConfigArgs config;
    ASSERT_TRUE(in.next());
    EXPECT_TRUE(in.config_option(config));
    EXPECT_TRUE(in.failed());
    EXPECT_EQ(in.error(), "--config needs a file name, got ''");
}

TEST(CommandLine, ValueTakesTheNextArgument)
{
    Argv a({"--out", "dir", "input"});
    ArgReader in(a.argc(), a.argv());
    std::string out;
    ASSERT_TRUE(in.next());
    EXPECT_TRUE(in.value(out));
    EXPECT_EQ(out, "dir");
    ASSERT_TRUE(in.next());
    EXPECT_EQ(in.arg(), "input");
}

TEST(CommandLine, HelpAnywhere)
{
    Argv with({"--set", "a=b", "-h"});
    Argv without({"--set", "a=b"});
    EXPECT_TRUE(wants_help(with.argc(), with.argv()));
    EXPECT_FALSE(wants_help(without.argc(), without.argv()));
}

TEST(CommandLine, BuildConfigAppliesSetsAfterTheFileAndStopsAtTheFirstError)
{
    Config config;
    EXPECT_FALSE(build_config({"", {"closing.radius_px=7"}}, config));
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 7);
    const auto error = build_config({"", {"closing.radius_px=abc"}}, config);
    ASSERT_TRUE(error.has_value());
    EXPECT_NE(error->to_string().find("closing.radius_px"), std::string::npos);
    EXPECT_EQ(test::int_of(config, "closing.radius_px"), 7);
}
