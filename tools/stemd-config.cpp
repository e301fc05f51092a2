// stemd-config: the documents generated from the configuration schema:
// config/stemd.yaml (every key at its default, documented) and the README's
// key table; or a check that config/stemd.yaml is exactly the generated text.
#include <iostream>
#include <string>
#include <string_view>

#include "generated_file.hpp"
#include "stemd/config/config.hpp"
#include "stemd/config/schema.hpp"

namespace {

constexpr int kUsageError = 2;

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
    const std::string_view what = argc >= 2 ? argv[1] : "";
    const std::string_view option = argc >= 3 ? argv[2] : "";
    if (argc == 2 && (what == "-h" || what == "--help")) {
        std::cout << kUsage;
        return 0;
    }
    const bool yaml_ok = what == "yaml" && (argc == 2 || (argc == 4 && (option == "--out" || option == "--check")));
    if (!yaml_ok && !(what == "markdown" && argc == 2)) {
        std::cerr << kUsage;
        return kUsageError;
    }
    using stemd::config::Config;
    const std::string text = what == "markdown" ? stemd::config::schema_markdown()
                                                : Config{}.to_yaml(Config::YamlComments::documentation);
    const std::string path = argc == 4 ? argv[3] : "";
    return stemd::tools::write_or_check_generated("stemd-config", text, path, option == "--check",
                                                  "the configuration schema (src/config/schema.cpp)",
                                                  std::string(argv[0]) + " yaml --out " + path);
}
