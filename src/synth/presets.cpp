#include "presets.hpp"

namespace stemd::synth {

PresetSpec preset_spec(Preset preset)
{
    switch (preset) {
    case Preset::early:
        return {.crop = {{4, 7}, {12, 25}, {2, 4}}, .weed = {{6, 12}, {3, 8}, {2, 4}}, .grass = {}, .fragmentation = 0};
    case Preset::late:
        return {.crop = {{2, 4}, {35, 70}, {4, 8}}, .weed = {{2, 5}, {8, 20}, {2, 4}}, .grass = {}, .fragmentation = 0};
    case Preset::seedling:
        return {.crop = {{3, 4}, {14, 24}, {2, 4}},
                .weed = {{3, 8}, {3, 8}, {2, 4}},
                .grass = {},
                .fragmentation = 0,
                .soil_brightness = 0.6,
                .clods_per_m2 = 1500,
                .stones_per_m2 = 120,
                .real_camera = true};
    case Preset::dense:
        break;
    }
    return {.crop = {{6, 10}, {25, 50}, {4, 7}},
            .weed = {{5, 10}, {6, 15}, {2, 4}},
            .grass = {{3, 6}, {25, 60}, {5, 10}},
            .fragmentation = 0.3};
}

std::optional<Preset> parse_preset(std::string_view name)
{
    for (const Preset p : {Preset::early, Preset::late, Preset::dense, Preset::seedling})
        if (name == to_string(p))
            return p;
    return std::nullopt;
}

std::string_view to_string(Preset preset)
{
    switch (preset) {
    case Preset::early: return "early";
    case Preset::late: return "late";
    case Preset::dense: return "dense";
    case Preset::seedling: return "seedling";
    }
    return "late";
}

}  // namespace stemd::synth
