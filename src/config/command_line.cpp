#include "stemd/config/command_line.hpp"

namespace stemd::config {

std::optional<ConfigError> build_config(const ConfigArgs& args, Config& out)
{
    for (const std::string& file : args.files)
        if (auto error = out.load_file(file))
            return error;
    for (const std::string& set : args.sets)
        if (auto error = out.set_override(set))
            return error;
    return std::nullopt;
}

}  // namespace stemd::config
