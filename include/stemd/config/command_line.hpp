// What stemd and its tools share on the command line: --help, walking the
// arguments, and --config FILE / --set KEY=VALUE into a Config.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "stemd/config/config.hpp"

namespace stemd::config {

struct ConfigArgs {
    std::string file;                // empty: defaults only
    std::vector<std::string> sets;   // KEY=VALUE, applied in order after the file
};

// Loads the file then the overrides; the first error is returned.
std::optional<ConfigError> build_config(const ConfigArgs& args, Config& out);

// -h or --help anywhere among the arguments.
bool wants_help(int argc, char** argv);

// Walks argv[1..] one option at a time.
class ArgReader {
public:
    ArgReader(int argc, char** argv) : argc_(argc), argv_(argv) {}

    // Advances to the next argument; false past the last.
    bool next();
    const std::string& arg() const { return arg_; }

    // Takes the argument after the current option as its value; false and
    // error() = "<option> needs a value" when there is none.
    bool value(std::string& out);
    // --config FILE or --set KEY=VALUE into `config`: true if the current
    // argument was one of them (check failed() for a missing value).
    bool config_option(ConfigArgs& config);

    bool failed() const { return !error_.empty(); }
    const std::string& error() const { return error_; }

private:
    int argc_;
    char** argv_;
    int index_ = 0;
    std::string arg_;
    std::string error_;
};

}  // namespace stemd::config
