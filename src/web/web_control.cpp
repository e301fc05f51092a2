#include "stemd/web/web_control.hpp"

#include <sys/stat.h>

#include <cstdio>

#include "stemd/base/strings.hpp"
#include "stemd/base/whole_file.hpp"
#include "stemd/config/schema.hpp"

namespace stemd::web {

namespace {

using base::cat;

constexpr std::string_view kSpace = " \t\r\n";

// A token is a line; anything far longer is not a token file.
constexpr std::size_t kMaxTokenFileBytes = 64 * 1024;

}  // namespace

std::optional<std::string> read_token_file(const std::string& path, std::string& error)
{
    // One open for the checks and the read: a file swapped after a stat(2)
    // (for a FIFO that would hang the start) is not read.
    std::string text;
    const base::WholeFileResult read = base::read_whole_file(path.c_str(), kMaxTokenFileBytes, text);
    if (!read.ok()) {
        error = cat(path, ": ", base::why_unread(read, kMaxTokenFileBytes));
        return std::nullopt;
    }
    if ((read.mode & (S_IRWXG | S_IRWXO)) != 0) {
        char mode[8];
        std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(read.mode & 07777));
        error = cat(path, ": mode ", mode, " lets group or others at the token (chmod 600)");
        return std::nullopt;
    }
    if (text.empty()) {
        error = cat(path, ": cannot read the token (empty file)");
        return std::nullopt;
    }
    const std::string_view line = std::string_view(text).substr(0, text.find('\n'));
    const std::string token(base::trim(line, kSpace));
    if (token.size() < kMinTokenChars) {
        error = cat(path, ": the token has ", std::to_string(token.size()), " characters, at least ",
                    std::to_string(kMinTokenChars), " are needed");
        return std::nullopt;
    }
    return token;
}

bool bearer_matches(std::string_view authorization, std::string_view token)
{
    constexpr std::string_view kScheme = "Bearer ";
    if (token.empty() || authorization.substr(0, kScheme.size()) != kScheme)
        return false;
    const std::string_view given = authorization.substr(kScheme.size());
    // Every byte of the expected token is compared whatever the given one
    // holds, so the time says nothing about where they first differ.
    unsigned diff = given.size() == token.size() ? 0U : 1U;
    for (std::size_t i = 0; i < token.size(); ++i) {
        const unsigned char g = i < given.size() ? static_cast<unsigned char>(given[i]) : 0;
        diff |= static_cast<unsigned>(g ^ static_cast<unsigned char>(token[i]));
    }
    return diff == 0;
}

bool is_controllable(std::string_view key)
{
    const config::KeySpec* spec = config::find_key(key);
    if (spec == nullptr || spec->type == config::ValueType::text)
        return false;
    if (key == "segment.method" || key == "segment.opening_radius_px" || key == "segment.edge_radius_px")
        return false;
    return key.substr(0, 8) == "segment." || key.substr(0, 5) == "stem.";
}

std::vector<std::string> controllable_keys()
{
    std::vector<std::string> out;
    for (const config::KeySpec& spec : config::schema())
        if (is_controllable(spec.key))
            out.emplace_back(spec.key);
    return out;
}

ParamChange change_param(config::Config& config, std::string_view key, std::string_view value)
{
    ParamChange change;
    if (!is_controllable(key)) {
        change.error = cat("'", key,
                           "' is not a parameter the view may change (segment.* and stem.* but segment.method, "
                           "segment.opening_radius_px and segment.edge_radius_px)");
        return change;
    }
    change.old_value = config.value_of(key);
    if (const auto error = config.set_override(cat(key, "=", value), "web")) {
        change.error = cat("key '", key, "': ", error->message);
        return change;
    }
    change.new_value = config.value_of(key);
    change.ok = true;
    return change;
}

}  // namespace stemd::web
