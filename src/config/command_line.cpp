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

}  // namespace stemd::config
