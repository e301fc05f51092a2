// stemd-config: the documents generated from the configuration schema:
// config/stemd.yaml (every key at its default, documented) and the README's
// key table; or a check that config/stemd.yaml is exactly the generated text.
#include <string>

#include "config_docs.hpp"
#include "generated_file.hpp"
#include "tool_cli.hpp"

using namespace stemd;

int main(int argc, char** argv)
{
    const std::string usage = "usage: stemd-config yaml [--out FILE | --check FILE]\n"
                              "       stemd-config markdown\n"
                              "  yaml          the documented default configuration (config/stemd.yaml)\n"
                              "  markdown      the README's configuration table\n" +
                              std::string(tools::kGeneratedFileUsage);
    CLI::App app{"stemd-config"};
    app.require_subcommand(1);
    tools::GeneratedFileArgs args;
    CLI::App* const yaml = app.add_subcommand("yaml");
    tools::add_generated_file_options(*yaml, args);
    app.add_subcommand("markdown");
    if (const auto exit_code = tools::parse(app, argc, argv, {.tool = "stemd-config", .usage = usage,
                                                               .usage_after_error = true}))
        return *exit_code;
    const std::string text = yaml->parsed() ? config::documented_yaml() : config::schema_markdown();
    return tools::write_or_check_generated("stemd-config", text, args,
                                           "the configuration schema (src/config/schema.cpp)",
                                           std::string(argv[0]) + " yaml");
}
