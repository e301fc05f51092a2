#include "stemd/runtime/plant_geojson.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <utility>

#include <unistd.h>

namespace stemd::runtime {

PlantGeojson::PlantGeojson(std::filesystem::path map_jsonl) : map_(std::move(map_jsonl)) {}

bool PlantGeojson::update(std::string& error)
{
    std::ifstream in(map_, std::ios::binary);
    if (!in) {
        error = map_.string() + ": cannot read the plant map: " + std::strerror(errno);
        return false;
    }
    in.seekg(static_cast<std::streamoff>(offset_));
    std::string line;
    while (std::getline(in, line)) {
        if (in.eof())
            break;   // no newline yet: a line still being written
        offset_ += line.size() + 1;
        ++line_no_;
        const nlohmann::json plant = nlohmann::json::parse(line, nullptr, false);
        if (plant.is_discarded() || !plant.is_object() || !plant.contains("s_mm")) {
            error = map_.string() + ":" + std::to_string(line_no_) + ": not a plant map line";
            return false;
        }
        nlohmann::json properties = nlohmann::json::object();
        for (const char* key : {"id", "class", "treated", "reason", "leaves", "s_mm", "y_mm", "georef", "gnss_mode", "gnss_status", "eph_mm"})
            if (plant.contains(key))
                properties[key] = plant[key];
        nlohmann::json feature = {{"type", "Feature"}, {"geometry", nullptr}, {"properties", std::move(properties)}};
        const auto lat = plant.find("lat_deg");
        const auto lon = plant.find("lon_deg");
        if (lat != plant.end() && lon != plant.end() && lat->is_number() && lon->is_number()) {
            // RFC 7946: longitude first.
            feature["geometry"] = {{"type", "Point"}, {"coordinates", {lon->get<double>(), lat->get<double>()}}};
            ++placed_;
        }
        features_.push_back(std::move(feature));
    }
    return true;
}

bool PlantGeojson::write(const std::filesystem::path& out, std::string& error) const
{
    const nlohmann::json collection = {{"type", "FeatureCollection"}, {"features", features_}};
    const std::string text = collection.dump() + "\n";
    const std::filesystem::path tmp = out.string() + ".tmp";
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (f == nullptr) {
        error = tmp.string() + ": cannot create: " + std::strerror(errno);
        return false;
    }
    bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size() && std::fflush(f) == 0;
    int err = ok ? 0 : errno;
    // On disk before the rename: a power cut must not leave an empty FILE.
    if (ok && ::fsync(fileno(f)) != 0) {
        ok = false;
        err = errno;
    }
    if (std::fclose(f) != 0 && ok) {
        ok = false;
        err = errno;
    }
    if (ok && std::rename(tmp.c_str(), out.c_str()) != 0) {
        ok = false;
        err = errno;
    }
    if (!ok) {
        error = out.string() + ": cannot write the GeoJSON: " + std::strerror(err);
        std::remove(tmp.c_str());
    }
    return ok;
}

}  // namespace stemd::runtime
