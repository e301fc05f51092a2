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

void add_generated_file_options(CLI::App& app, GeneratedFileArgs& args)
{
    app.add_option("--out", args.out)->excludes(app.add_option("--check", args.check));
}

int write_or_check_generated(std::string_view tool, const std::string& text, const GeneratedFileArgs& args,
                             std::string_view source, std::string_view regenerate)
{
    const bool check = !args.check.empty();
    const std::string& path = check ? args.check : args.out;
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
                  << regenerate << " --out " << path << '\n';
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
