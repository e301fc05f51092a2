#include "stemd/config/command_line.hpp"

namespace stemd::config {

std::optional<ConfigError> build_config(const ConfigArgs& args, Config& out)
{
    if (!args.file.empty())
        if (auto error = out.load_file(args.file))
            return error;
    for (const std::string& set : args.sets)
        if (auto error = out.set_override(set))
            return error;
    return std::nullopt;
}

bool wants_help(int argc, char** argv)
{
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--help" || a == "-h")
            return true;
    }
    return false;
}

bool ArgReader::next()
{
    if (index_ + 1 >= argc_)
        return false;
    arg_ = argv_[++index_];
    return true;
}

bool ArgReader::value(std::string& out)
{
    if (index_ + 1 >= argc_) {
        error_ = arg_ + " needs a value";
        return false;
    }
    out = argv_[++index_];
    return true;
}

bool ArgReader::config_option(ConfigArgs& config)
{
    if (arg_ == "--config") {
        // An empty name would silently mean the defaults.
        if (value(config.file) && config.file.empty())
            error_ = "--config needs a file name, got ''";
        return true;
    }
    if (arg_ == "--set") {
        std::string set;
        if (value(set))
            config.sets.push_back(std::move(set));
        return true;
    }
    return false;
}

}  // namespace stemd::config
