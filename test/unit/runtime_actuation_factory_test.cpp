// The actuation factories refuse a configuration that does not hold
// together, naming the key, before opening anything.
#include <gtest/gtest.h>

#include "stemd/runtime/actuation_factory.hpp"

using namespace stemd::runtime;

TEST(ActuationFactory, TheOdometerTapRefusesWhatTheActuationRefusesNamingTheKey)
{
    std::string error;
    ActuationConfig config;
    config.odometry = OdometrySource::can;   // no can.interface: commands go to a log
    EXPECT_EQ(make_odometer_tap(config, error), nullptr);
    EXPECT_EQ(error.rfind("odometry.source: can, but can.interface is none", 0), 0u) << error;

    config.odometry = OdometrySource::encoder;   // no gpio.chip, no gpio.encoder
    error.clear();
    EXPECT_EQ(make_odometer_tap(config, error), nullptr);
    EXPECT_EQ(error.rfind("odometry.source: encoder, but gpio.encoder is none", 0), 0u) << error;

    config.odometry = OdometrySource::constant;
    error.clear();
    EXPECT_EQ(make_odometer_tap(config, error), nullptr);
    EXPECT_EQ(error.rfind("odometry.source: neither can nor encoder", 0), 0u) << error;

    config.odometry = OdometrySource::can;
    config.can_interface = "can0";
    config.can_base_id = 0x7FF;   // the next four identifiers do not fit in 11 bits
    error.clear();
    EXPECT_EQ(make_odometer_tap(config, error), nullptr);
    EXPECT_EQ(error, "can.base_id 2047 is too large");
}
