// stemd-dbc: writes the DBC of stemd's CAN messages (config/stemd.dbc) from
// the message table, or checks that a file holds exactly that text.
#include <iostream>
#include <sstream>
#include <string>
#include <string_view>

#include "generated_file.hpp"
#include "stemd/protocol/dbc_writer.hpp"

namespace {

constexpr int kUsageError = 2;

const char* const kUsage =
    "usage: stemd-dbc [--out FILE | --check FILE]\n"
    "  (no option)   write the DBC to standard output\n"
    "  --out FILE    write it to FILE\n"
    "  --check FILE  exit 0 if FILE is exactly the DBC this build writes, 1 if not\n";

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
    const std::string path = argc == 3 ? argv[2] : "";
    return stemd::tools::write_or_check_generated("stemd-dbc", text.str(), path, option == "--check",
                                                  "the message table (src/protocol/messages.cpp)",
                                                  std::string(argv[0]) + " --out " + path);
}
