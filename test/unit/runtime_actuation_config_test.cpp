// The actuation settings the schema cannot check key by key.
#include <gtest/gtest.h>

#include "stemd/runtime/actuation_config.hpp"

namespace stemd::runtime {
namespace {

// The key check_actuation_config blames, or "" when it accepts `c`.
std::string blamed(const ActuationConfig& c)
{
    const auto problem = check_actuation_config(c);
    return problem ? problem->key : "";
}

TEST(ActuationConfigCheck, DefaultsAreAccepted)
{
    EXPECT_EQ(blamed(ActuationConfig{}), "");
}

TEST(ActuationConfigCheck, GpioLinesNeedAChipAndAChipNeedsTheEnableInput)
{
    ActuationConfig c;
    c.enable_line = 3;
    EXPECT_EQ(blamed(c), "gpio.enable_line");
    c = {};
    c.trigger_line = 4;
    EXPECT_EQ(blamed(c), "gpio.trigger_line");
    c = {};
    c.encoder_mode = "single";
    c.encoder_a_line = 5;
    EXPECT_EQ(blamed(c), "gpio.encoder");
    c = {};
    c.gpio_chip = "gpiochip0";
    EXPECT_EQ(blamed(c), "gpio.enable_line");
    c.enable_line = 0;
    EXPECT_EQ(blamed(c), "");
}

TEST(ActuationConfigCheck, EncoderNeedsItsLines)
{
    ActuationConfig c;
    c.gpio_chip = "gpiochip0";
    c.enable_line = 0;
    c.encoder_mode = "quadrature";
    EXPECT_EQ(blamed(c), "gpio.encoder_a_line");
    c.encoder_a_line = 1;
    EXPECT_EQ(blamed(c), "gpio.encoder_b_line");
    c.encoder_b_line = 2;
    EXPECT_EQ(blamed(c), "");
    c.encoder_mode = "single";
    c.encoder_b_line = -1;
    EXPECT_EQ(blamed(c), "");
}

TEST(ActuationConfigCheck, OdometryNeedsItsSource)
{
    ActuationConfig c;
    c.odometry = OdometrySource::encoder;
    EXPECT_EQ(blamed(c), "odometry.source");
    c.gpio_chip = "gpiochip0";
    c.enable_line = 0;
    c.encoder_mode = "single";
    c.encoder_a_line = 1;
    EXPECT_EQ(blamed(c), "");

    c = {};
    c.odometry = OdometrySource::can;
    EXPECT_EQ(blamed(c), "odometry.source");
    c.can_interface = "can0";
    EXPECT_EQ(blamed(c), "");
}

}  // namespace
}  // namespace stemd::runtime
