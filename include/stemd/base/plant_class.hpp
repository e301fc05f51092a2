// What a plant is, the one class type of stemd: class maps (PNG pixel
// values: 0 soil, 1 crop, 2 weed), ground truth (stems.csv and plants.csv
// `kind`, the plant map's "class"), tracks and TARGET commands (the CAN
// plant_class signal carries the same values). Grass is a shape of weed,
// not a class of its own.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace stemd {

// Unknown is also soil, where a class map has no plant.
enum class PlantClass : std::uint8_t { Unknown = 0, Crop = 1, Weed = 2 };

// A class map's pixel value or a raw signal; values above Weed are Unknown.
constexpr PlantClass plant_class_from_value(std::uint8_t value)
{
    return value <= static_cast<std::uint8_t>(PlantClass::Weed) ? static_cast<PlantClass>(value)
                                                                : PlantClass::Unknown;
}

constexpr std::uint8_t to_value(PlantClass c) { return static_cast<std::uint8_t>(c); }

// The word of the CSV and JSON files: "crop", "weed", "unknown".
constexpr std::string_view to_string(PlantClass c)
{
    switch (c) {
    case PlantClass::Crop: return "crop";
    case PlantClass::Weed: return "weed";
    case PlantClass::Unknown: break;
    }
    return "unknown";
}

constexpr std::optional<PlantClass> parse_plant_class(std::string_view word)
{
    for (const PlantClass c : {PlantClass::Unknown, PlantClass::Crop, PlantClass::Weed})
        if (word == to_string(c))
            return c;
    return std::nullopt;
}

}  // namespace stemd
