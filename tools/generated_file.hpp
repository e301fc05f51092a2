// Files generated from a table in the code (config/stemd.dbc from the CAN
// message table, config/stemd.yaml from the configuration schema): written
// to standard output or a file, or checked against the committed copy.
#pragma once

#include <string>
#include <string_view>

#include <CLI/CLI.hpp>

namespace stemd::tools {

// Where the generated text goes: standard output (both empty), into `out`,
// or compared with `check`.
struct GeneratedFileArgs {
    std::string out;
    std::string check;
};

// Adds --out FILE and --check FILE (one or the other) to `app`, described
// in the usage by kGeneratedFileUsage.
void add_generated_file_options(CLI::App& app, GeneratedFileArgs& args);
inline constexpr std::string_view kGeneratedFileUsage =
    "  --out FILE    write it to FILE instead of standard output\n"
    "  --check FILE  exit 0 if FILE is exactly the text this build writes, 1 if not\n";

// `text` as `args` say. A check gives 0 if the file holds exactly `text`,
// else 1 and a message naming the first different line, `source` and how to
// regenerate it (`regenerate`, then " --out FILE"). 1 on I/O errors.
int write_or_check_generated(std::string_view tool, const std::string& text, const GeneratedFileArgs& args,
                             std::string_view source, std::string_view regenerate);

}  // namespace stemd::tools
