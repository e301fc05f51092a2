// stemd-dbc: writes the DBC of stemd's CAN messages (config/stemd.dbc) from
// the message table, or checks that a file holds exactly that text.
#include <iostream>
#include <sstream>
#include <string>

#include "generated_file.hpp"
#include "tool_cli.hpp"
#include "stemd/protocol/dbc_writer.hpp"

using namespace stemd;

namespace {

const char* const kUsage =
    "usage: stemd-dbc [--out FILE | --check FILE]\n"
    "  (no option)   write the DBC to standard output\n"
    "  --out FILE    write it to FILE\n"
    "  --check FILE  exit 0 if FILE is exactly the DBC this build writes, 1 if not\n";

}  // namespace

int main(int argc, char** argv)
{
    CLI::App app{"stemd-dbc"};
    std::string out, check;
    app.add_option("--out", out)->excludes(app.add_option("--check", check));
    if (const auto exit_code = tools::parse(app, argc, argv, {.tool = "stemd-dbc", .usage = kUsage,
                                                               .usage_after_error = true}))
        return *exit_code;
    std::ostringstream text;
    protocol::write_dbc(text);
    const std::string& path = check.empty() ? out : check;
    return tools::write_or_check_generated("stemd-dbc", text.str(), path, !check.empty(),
                                           "the message table (src/protocol/messages.cpp)",
                                           std::string(argv[0]) + " --out " + path);
}
