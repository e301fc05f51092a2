// stemd-dbc: writes the DBC of stemd's CAN messages (config/stemd.dbc) from
// the message table, or checks that a file holds exactly that text.
#include <sstream>
#include <string>

#include "generated_file.hpp"
#include "tool_cli.hpp"
#include "stemd/protocol/dbc_writer.hpp"

using namespace stemd;

int main(int argc, char** argv)
{
    const std::string usage = "usage: stemd-dbc [--out FILE | --check FILE]\n"
                              "  (no option)   write the DBC to standard output\n" +
                              std::string(tools::kGeneratedFileUsage);
    CLI::App app{"stemd-dbc"};
    tools::GeneratedFileArgs args;
    tools::add_generated_file_options(app, args);
    if (const auto exit_code = tools::parse(app, argc, argv, {.tool = "stemd-dbc", .usage = usage,
                                                               .usage_after_error = true}))
        return *exit_code;
    std::ostringstream text;
    protocol::write_dbc(text);
    return tools::write_or_check_generated("stemd-dbc", text.str(), args,
                                           "the message table (src/protocol/messages.cpp)", argv[0]);
}
