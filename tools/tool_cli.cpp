#include "tool_cli.hpp"

#include <cstdio>
#include <iostream>

namespace stemd::tools {

bool parse_number(const std::string& text, double& out)
{
    const char* end = text.data() + text.size();
    const auto [ptr, ec] = std::from_chars(text.data(), end, out);
    return ec == std::errc() && ptr == end && std::isfinite(out);
}

bool parse_int(const std::string& text, long& out)
{
    const char* end = text.data() + text.size();
    const auto [ptr, ec] = std::from_chars(text.data(), end, out);
    return ec == std::errc() && ptr == end;
}

std::string fixed(double v, int decimals)
{
    char text[64];
    std::snprintf(text, sizeof text, "%.*f", decimals, v);
    return text;
}

void add_config_options(CLI::App& app, config::ConfigArgs& out)
{
    // Each --config as it comes: later files override earlier ones key by
    // key. An empty name would silently mean the defaults.
    app.add_option_function<std::string>(
           "--config", [&out](const std::string& file) { out.files.push_back(file); },
           "configuration file (see config/stemd.yaml); repeated: later files override earlier ones")
        ->check(CLI::Validator(
            [](std::string& name) { return name.empty() ? std::string("needs a file name, got ''") : std::string(); },
            "FILE"))
        ->trigger_on_parse();
    // Each --set as it comes, so that options that add overrides of their own
    // (stemd-detect --segment) keep the command line's order.
    app.add_option_function<std::string>(
           "--set", [&out](const std::string& set) { out.sets.push_back(set); },
           "override one configuration key, KEY=VALUE")
        ->trigger_on_parse();
}

namespace {

// CLI11 says "--x: 1 required TEXT missing"; the option is the one whose
// name starts the message.
std::string missing_value(const CLI::App& app, const std::string& what)
{
    for (const CLI::Option* option : app.get_options()) {
        const std::string name = option->get_name();
        if (what.rfind(name + ":", 0) == 0)
            return name + " needs a value";
    }
    return what;
}

}  // namespace

int usage_error(const CommandLine& how, const std::string& message)
{
    std::cerr << how.tool << ": " << message << how.after << "\n";
    if (how.usage_after_error)
        std::cerr << how.usage;
    return kUsageError;
}

std::optional<int> load_config(const CommandLine& how, const config::ConfigArgs& args, config::Config& config)
{
    if (const auto error = config::build_config(args, config)) {
        std::cerr << how.tool << ": " << error->to_string() << "\n";
        return kUsageError;
    }
    return std::nullopt;
}

std::optional<int> parse(CLI::App& app, int argc, char** argv, const CommandLine& how)
{
    // Unknown arguments are worded here, the first one only, as before CLI11.
    app.allow_extras(true);
    for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; }))
        sub->allow_extras(true);
    for (CLI::Option* option : app.get_options())
        if (option->get_items_expected_max() == 1)
            option->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp&) {
        std::cout << (how.usage.empty() ? app.help() : std::string(how.usage));
        return 0;
    } catch (const CLI::ArgumentMismatch& e) {
        return usage_error(how, missing_value(app, e.what()));
    } catch (const CLI::ParseError& e) {
        // "--config: needs a file name" reads like "--set needs a value".
        std::string message = e.what();
        if (const std::size_t at = message.find(": needs "); message.starts_with("--") && at != std::string::npos)
            message.erase(at, 1);
        return usage_error(how, message);
    }
    const std::vector<std::string> rest = app.remaining(true);
    if (!rest.empty() && !how.pass_unknown) {
        const std::string& a = rest.front();
        return usage_error(how, (a.size() > 1 && a[0] == '-' ? "unknown option " : "unexpected argument ") + a);
    }
    return std::nullopt;
}

}  // namespace stemd::tools
