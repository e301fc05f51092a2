// The plant map as GeoJSON (RFC 7946: a FeatureCollection of Points,
// [longitude, latitude] in WGS84), for QGIS and other GIS software
// (--map-geojson FILE). Built from the plant map's JSON lines, which stay
// the record: the GeoJSON is one document that cannot be appended to line
// by line, so it is rewritten whole, to FILE.tmp and renamed over FILE (a
// kill leaves the previous complete version or the new one, never a torn
// file). GeojsonWriter does this on a low-priority thread every 30 s, and
// once more at exit; never the real-time threads.
//
// Each feature: geometry a Point, or null for a plant without a position
// (georef other than fix/extrapolated/degraded, or a map without GNSS);
// properties id, class, treated, reason, leaves, s_mm, y_mm, georef,
// gnss_mode, gnss_status, eph_mm (a GIS can filter out degraded points).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

namespace stemd::runtime {

class PlantGeojson {
public:
    explicit PlantGeojson(std::filesystem::path map_jsonl);

    // Reads the map's complete lines added since the last call (a line
    // still being written waits for the next). False with `error` set when
    // the map cannot be read or a line is not a plant.
    bool update(std::string& error);
    // Writes the collection to `out` (through out.tmp and a rename).
    bool write(const std::filesystem::path& out, std::string& error) const;

    std::size_t features() const { return features_.size(); }
    std::size_t placed() const { return placed_; }

private:
    std::filesystem::path map_;
    std::uintmax_t offset_ = 0;   // bytes of the map already read
    std::uint64_t line_no_ = 0;
    nlohmann::json features_ = nlohmann::json::array();
    std::size_t placed_ = 0;
};

}  // namespace stemd::runtime
