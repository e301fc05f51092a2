// Small string helpers the configuration, the live view's control and the
// evaluation share.
#pragma once

#include <string>
#include <string_view>

namespace stemd::base {

// Concatenation by append: GCC 12 at -O3 misreports "literal" + std::string&&
// under -Wrestrict.
template <class... Parts>
std::string cat(const Parts&... parts)
{
    std::string out;
    (out.append(std::string_view(parts)), ...);
    return out;
}

// `s` without the leading and trailing characters of `space`.
constexpr std::string_view trim(std::string_view s, std::string_view space = " \t")
{
    const std::size_t first = s.find_first_not_of(space);
    if (first == std::string_view::npos)
        return {};
    return s.substr(first, s.find_last_not_of(space) - first + 1);
}

}  // namespace stemd::base
