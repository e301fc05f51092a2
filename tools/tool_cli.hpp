// The tools' command lines on CLI11: the options they share (--config FILE,
// --set KEY=VALUE), value checks that word their errors alike, and one way
// of ending on a usage error: "<tool>: <message>" on stderr, exit 2.
#pragma once

#include <charconv>
#include <cmath>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>

#include <CLI/CLI.hpp>

#include "stemd/config/command_line.hpp"

namespace stemd::tools {

constexpr int kUsageError = 2;

// Parses the whole text as a finite double or an integer; false if it is not one.
bool parse_number(const std::string& text, double& out);
bool parse_int(const std::string& text, long& out);

// --config FILE (repeatable: files load in order, later ones override
// earlier ones key by key) and --set KEY=VALUE (repeatable; applied in order
// after the files).
void add_config_options(CLI::App& app, config::ConfigArgs& out);

// A check of an option's text: it must read whole as a T (a finite number
// for floating point) for which `ok` holds, else "'<text>' is not <what>"
// (CLI11 puts the option's name in front).
template <typename T>
CLI::Validator value_check(std::string what, std::function<bool(T)> ok)
{
    return CLI::Validator(
        [what, ok](std::string& text) -> std::string {
            T value{};
            const char* const end = text.data() + text.size();
            const auto [ptr, ec] = std::from_chars(text.data(), end, value);
            bool good = !text.empty() && ec == std::errc() && ptr == end && ok(value);
            if constexpr (std::is_floating_point_v<T>)
                good = good && std::isfinite(value);
            return good ? std::string() : "'" + text + "' is not " + what;
        },
        what);
}

// How a tool reports its command line.
struct CommandLine {
    std::string_view tool{};    // "stemd-detect": the prefix of every message
    std::string_view usage{};   // printed on --help; empty: CLI11's help
    std::string_view after{};   // after an error message, e.g. " (see --help)"
    bool usage_after_error = false;   // print `usage` on stderr after an error too
    bool pass_unknown = false;        // leave unknown arguments to the caller (app.remaining())
};

// Parses argv into `app` (single-valued options keep the last value given).
// nullopt: go on; else the exit code, the help or the error printed: 0
// after --help, 2 after a usage error worded as "--x needs a value",
// "--x: '<text>' is not ...", "--config needs a file name, got ''",
// "unknown option --x", "unexpected argument x".
std::optional<int> parse(CLI::App& app, int argc, char** argv, const CommandLine& how);

// `v` with `decimals` digits after the point, as the tools' text reports write numbers.
std::string fixed(double v, int decimals);

// Loads --config and --set into `config`; on an error prints
// "<tool>: <file>:<line>: key '<key>': <message>" and returns 2.
std::optional<int> load_config(const CommandLine& how, const config::ConfigArgs& args, config::Config& config);

// Prints "<tool>: <message><after>" (and the usage if asked); returns 2.
int usage_error(const CommandLine& how, const std::string& message);

}  // namespace stemd::tools
