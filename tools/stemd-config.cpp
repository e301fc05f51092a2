// stemd-config: the documents generated from the configuration schema:
// config/stemd.yaml (every key at its default, documented) and the README's
// key table; or a check that config/stemd.yaml is exactly the generated text.
#include <iostream>
#include <string>

#include "generated_file.hpp"
#include "tool_cli.hpp"
#include "stemd/config/config.hpp"
#include "stemd/config/schema.hpp"

using namespace stemd;

namespace {

const char* const kUsage =
    "usage: stemd-config yaml [--out FILE | --check FILE]\n"
    "       stemd-config markdown\n"
    "  yaml          the documented default configuration (config/stemd.yaml)\n"
    "  markdown      the README's configuration table\n"
    "  --out FILE    write it to FILE instead of standard output\n"
    "  --check FILE  exit 0 if FILE is exactly the text this build writes, 1 if not\n";

}  // namespace

int main(int argc, char** argv)
{
    CLI::App app{"stemd-config"};
    app.require_subcommand(1);
    std::string out, check;
    CLI::App* const yaml = app.add_subcommand("yaml");
    yaml->add_option("--out", out)->excludes(yaml->add_option("--check", check));
    app.add_subcommand("markdown");
    if (const auto exit_code = tools::parse(app, argc, argv, {.tool = "stemd-config", .usage = kUsage,
                                                               .usage_after_error = true}))
        return *exit_code;
    using stemd::config::Config;
    const std::string text = yaml->parsed() ? Config{}.to_yaml(Config::YamlComments::documentation)
                                            : stemd::config::schema_markdown();
    const std::string& path = check.empty() ? out : check;
    return tools::write_or_check_generated("stemd-config", text, path, !check.empty(),
                                           "the configuration schema (src/config/schema.cpp)",
                                           std::string(argv[0]) + " yaml --out " + path);
}
