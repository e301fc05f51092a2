// An enum's words as one table that both directions read: to_string looks a
// value up, parse looks a word up, so the two cannot drift apart.
#pragma once

#include <cstddef>
#include <optional>
#include <string_view>

namespace stemd::base {

template <typename E>
struct EnumName {
    E value;
    std::string_view name;
};

// The word of `v`; `fallback` for a value the table lacks (a cast from a
// bad integer).
template <typename E, std::size_t N>
constexpr std::string_view name_of(const EnumName<E> (&table)[N], E v, std::string_view fallback = "?")
{
    for (const EnumName<E>& e : table)
        if (e.value == v)
            return e.name;
    return fallback;
}

// The value whose word is exactly `name`.
template <typename E, std::size_t N>
constexpr std::optional<E> value_of(const EnumName<E> (&table)[N], std::string_view name)
{
    for (const EnumName<E>& e : table)
        if (e.name == name)
            return e.value;
    return std::nullopt;
}

}  // namespace stemd::base
