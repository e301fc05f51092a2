#include "stemd/runtime/config_schema.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <system_error>

namespace stemd::config {

namespace {

// Concatenation without "literal" + std::string&&, which GCC 12 at -O3
// misreports under -Wrestrict.
template <class... Parts>
std::string cat(const Parts&... parts)
{
    std::string out;
    (out.append(std::string_view(parts)), ...);
    return out;
}

using enum ValueType;

// Later issues add capture/CAN/actuator sections: append rows, keep each
// section's rows together.
constexpr std::array kSchema{
    KeySpec{"camera.gsd_mm_per_px", real, "mm/px", 0.01, 10, "0.33", "",
            "ground sampling distance: millimetres of ground per image pixel"},

    KeySpec{"segment.method", choice, "", 0, 0, "exg", "exg|ndvi|mask",
            "vegetation index: Excess Green (RGB), NDVI (RGB+NIR) or an external mask"},
    KeySpec{"segment.threshold", choice, "", 0, 0, "otsu", "otsu|triangle|min_error",
            "automatic threshold on the vegetation index"},
    KeySpec{"segment.mask_vegetation", choice, "", 0, 0, "nonzero", "nonzero|zero",
            "which pixel value of an external mask is vegetation"},

    KeySpec{"closing.radius_px", integer, "px", 0, 50, "10", "",
            "radius m of the elliptic closing kernel (size 2m+1); 0 disables closing"},

    KeySpec{"plants.min_area_mm2", real, "mm2", 0, 100000, "10", "",
            "plants with a smaller area are dropped as noise"},

    KeySpec{"leaves.defect_depth_mm", real, "mm", 0.1, 100, "3.3", "",
            "convexity defects deeper than this cut the contour into leaves"},

    KeySpec{"stem.method", choice, "", 0, 0, "leaves", "leaves|com",
            "stem estimate: intersection of leaf lines, or the centre of mass"},
    KeySpec{"stem.min_leaves", integer, "count", 2, 16, "3", "",
            "the paper's N: plants with fewer leaves use the centre of mass"},
    KeySpec{"stem.min_angle_deg", real, "deg", 0, 45, "10", "",
            "pairs of leaf lines meeting at a smaller angle are skipped (0: only exactly parallel ones)"},
};

}  // namespace

std::string_view to_string(ValueType type)
{
    switch (type) {
    case integer: return "integer";
    case real: return "real";
    case choice: return "choice";
    case boolean: return "boolean";
    case text: return "text";
    }
    return "?";
}

std::span<const KeySpec> schema()
{
    return kSchema;
}

const KeySpec* find_key(std::string_view key)
{
    for (const KeySpec& spec : kSchema)
        if (spec.key == key)
            return &spec;
    return nullptr;
}

bool is_choice(const KeySpec& spec, std::string_view value)
{
    std::string_view rest = spec.choices;
    while (!rest.empty()) {
        const std::size_t bar = rest.find('|');
        if (rest.substr(0, bar) == value)
            return true;
        if (bar == std::string_view::npos)
            break;
        rest.remove_prefix(bar + 1);
    }
    return false;
}

std::string list_choices(const KeySpec& spec, std::string_view separator)
{
    std::string out;
    for (const char c : spec.choices) {
        if (c == '|')
            out += separator;
        else
            out += c;
    }
    return out;
}

std::string format_number(double value)
{
    // Plain shortest to_chars prefers "1e+05" to "100000"; fixed notation
    // (still the shortest that reads back exactly) where it stays readable.
    std::array<char, 400> buffer{};
    const double magnitude = std::fabs(value);
    const bool fixed = magnitude == 0.0 || (magnitude >= 1e-6 && magnitude < 1e15);
    const auto [end, ec] = fixed
        ? std::to_chars(buffer.data(), buffer.data() + buffer.size(), value, std::chars_format::fixed)
        : std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
    if (ec != std::errc())
        return "?";
    return std::string(buffer.data(), end);
}

std::string schema_markdown()
{
    std::string out =
        "| key | type | unit | default | range / choices | meaning |\n"
        "|---|---|---|---|---|---|\n";
    for (const KeySpec& spec : kSchema) {
        std::string range;
        if (spec.type == integer || spec.type == real)
            range = cat("[", format_number(spec.min), ", ", format_number(spec.max), "]");
        else if (spec.type == choice)
            range = cat("`", list_choices(spec, "`, `"), "`");
        else if (spec.type == boolean)
            range = "`true`, `false`";
        out += "| `";
        out += spec.key;
        out += "` | ";
        out += to_string(spec.type);
        out += " | ";
        out += spec.unit;
        out += " | `";
        out += spec.default_value;
        out += "` | ";
        out += range;
        out += " | ";
        out += spec.help;
        out += " |\n";
    }
    return out;
}

}  // namespace stemd::config
