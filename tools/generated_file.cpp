#include "generated_file.hpp"

#include <fstream>
#include <iostream>
#include <iterator>

namespace stemd::tools {

namespace {

// 1-based number of the first line where the two texts differ.
std::size_t first_different_line(std::string_view a, std::string_view b)
{
    std::size_t line = 1;
    for (std::size_t i = 0; i < a.size() && i < b.size() && a[i] == b[i]; ++i)
        line += a[i] == '\n' ? 1 : 0;
    return line;
}

}  // namespace

int write_or_check_generated(std::string_view tool, const std::string& text, const std::string& path, bool check,
                             std::string_view source, std::string_view regenerate)
{
    if (path.empty()) {
        std::cout << text;
        return std::cout.flush() ? 0 : 1;
    }
    if (check) {
        std::ifstream in(path, std::ios::binary);
        if (!in) {
            std::cerr << tool << ": cannot read " << path << '\n';
            return 1;
        }
        const std::string actual{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
        if (actual == text)
            return 0;
        std::cerr << tool << ": " << path << " differs from " << source << " from line "
                  << first_different_line(actual, text) << ".\nRegenerate it, and commit it with the table:\n  "
                  << regenerate << '\n';
        return 1;
    }
    std::ofstream out(path, std::ios::binary);
    out << text;
    if (!out.flush()) {
        std::cerr << tool << ": cannot write " << path << '\n';
        return 1;
    }
    return 0;
}

}  // namespace stemd::tools
