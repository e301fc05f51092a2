// --config and --set into a Config, as stemd and its tools load them (the
// options themselves: test/daemon/command_line.sh and the tools' tests).
#include <gtest/gtest.h>

#include "config_test_util.hpp"

#include "stemd/config/command_line.hpp"

using namespace stemd::config;

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
