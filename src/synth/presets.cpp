#include "presets.hpp"

#include "stemd/base/enum_names.hpp"

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
    case Preset::canopy:
        return {.crop = {{22, 30}, {70, 110}, {6, 9}},
                .weed = {{60, 90}, {15, 35}, {3, 6}},
                .grass = {},
                .fragmentation = 0,
                .clods_per_m2 = 800,
                .stones_per_m2 = 120,
                .real_camera = true,
                .overlap = 0.8};
    case Preset::dense:
        break;
    }
    return {.crop = {{6, 10}, {25, 50}, {4, 7}},
            .weed = {{5, 10}, {6, 15}, {2, 4}},
            .grass = {{3, 6}, {25, 60}, {5, 10}},
            .fragmentation = 0.3};
}

namespace {

constexpr base::EnumName<Preset> kPresets[]{
    {Preset::early, "early"}, {Preset::late, "late"}, {Preset::dense, "dense"}, {Preset::seedling, "seedling"},
    {Preset::canopy, "canopy"}};

}  // namespace

std::optional<Preset> parse_preset(std::string_view name) { return base::value_of(kPresets, name); }
std::string_view to_string(Preset preset) { return base::name_of(kPresets, preset, "late"); }

}  // namespace stemd::synth
