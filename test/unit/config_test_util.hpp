// A key's value read back from Config::settings() through the key's schema
// binding: what the typed settings hold, in the schema's units and words.
#pragma once

#include <string>
#include <string_view>

#include <gtest/gtest.h>

#include "stemd/config/config.hpp"

namespace stemd::config::test {

inline detail::ConfigValue bound(const Config& config, const KeySpec* spec, std::size_t item = 0)
{
    detail::ConfigValue value;
    EXPECT_NE(spec, nullptr);
    if (spec != nullptr)
        spec->load(*spec, config.settings(), item, value);
    return value;
}

inline long int_of(const Config& c, std::string_view key) { return bound(c, find_key(key)).integer; }
inline double real_of(const Config& c, std::string_view key) { return bound(c, find_key(key)).real; }
inline bool bool_of(const Config& c, std::string_view key) { return bound(c, find_key(key)).boolean; }
inline std::string text_of(const Config& c, std::string_view key) { return bound(c, find_key(key)).text; }

inline long item_int_of(const Config& c, std::string_view list, std::size_t i, std::string_view key)
{
    return bound(c, find_item_key(list, key), i).integer;
}
inline double item_real_of(const Config& c, std::string_view list, std::size_t i, std::string_view key)
{
    return bound(c, find_item_key(list, key), i).real;
}

}  // namespace stemd::config::test
