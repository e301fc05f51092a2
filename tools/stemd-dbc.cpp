// stemd-dbc: writes the DBC of stemd's CAN messages (config/stemd.dbc) from
// the message table, or checks that a file holds exactly that text.
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>
#include <string>
#include <string_view>

#include "stemd/protocol/dbc_writer.hpp"

namespace {

constexpr int kUsageError = 2;
constexpr int kFailed = 1;

const char* const kUsage =
    "usage: stemd-dbc [--out FILE | --check FILE]\n"
    "  (no option)   write the DBC to standard output\n"
    "  --out FILE    write it to FILE\n"
    "  --check FILE  exit 0 if FILE is exactly the DBC this build writes, 1 if not\n";

// 1-based number of the first line where the two texts differ.
std::size_t first_different_line(std::string_view a, std::string_view b)
{
    std::size_t line = 1;
    for (std::size_t i = 0; i < a.size() && i < b.size() && a[i] == b[i]; ++i)
        line += a[i] == '\n' ? 1 : 0;
    return line;
}

int check(const std::string& path, const std::string& expected, const char* self)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        std::cerr << "stemd-dbc: cannot read " << path << '\n';
        return kFailed;
    }
    const std::string actual{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    if (actual == expected)
        return 0;
    std::cerr << "stemd-dbc: " << path << " differs from the message table (src/protocol/messages.cpp) from line "
              << first_different_line(actual, expected) << ".\nRegenerate it, and commit it with the table:\n  "
              << self << " --out " << path << '\n';
    return kFailed;
}

}  // namespace

int main(int argc, char** argv)
{
    const std::string_view option = argc >= 2 ? argv[1] : "";
    if (argc == 2 && (option == "-h" || option == "--help")) {
        std::cout << kUsage;
        return 0;
    }
    if (!(argc == 1 || (argc == 3 && (option == "--out" || option == "--check")))) {
        std::cerr << kUsage;
        return kUsageError;
    }
    std::ostringstream text;
    stemd::protocol::write_dbc(text);
    if (argc == 1) {
        std::cout << text.str();
        return std::cout.flush() ? 0 : kFailed;
    }
    const std::string path = argv[2];
    if (option == "--check")
        return check(path, text.str(), argv[0]);
    std::ofstream out(path, std::ios::binary);
    out << text.str();
    if (!out.flush()) {
        std::cerr << "stemd-dbc: cannot write " << path << '\n';
        return kFailed;
    }
    return 0;
}
