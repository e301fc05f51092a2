// OpenCV's and yaml-cpp's messages span lines; the geometry library's
// errors are one line each.
#pragma once

#include <string>
#include <string_view>

namespace stemd::geometry::detail {

inline std::string one_line(std::string_view text)
{
    std::string out;
    for (const char c : text) {
        const bool space = c == '\n' || c == '\r' || c == '\t';
        if (space && (out.empty() || out.back() == ' '))
            continue;
        out += space ? ' ' : c;
    }
    while (!out.empty() && out.back() == ' ')
        out.pop_back();
    return out;
}

}  // namespace stemd::geometry::detail
