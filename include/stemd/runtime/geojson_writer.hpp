// The --map-geojson rewrite on a thread of its own, at low priority (nice
// 10): every `interval` it reads the plant map's new lines and rewrites the
// GeoJSON (PlantGeojson: FILE.tmp, fsync, rename), so neither the real-time
// threads nor the main thread (signals, watchdog, status) wait on a
// document that grows with the field. finish() stops it and writes the
// last version on the caller's thread, once the map is complete.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <memory>
#include <mutex>
#include <thread>

#include <spdlog/logger.h>

#include "stemd/runtime/plant_geojson.hpp"

namespace stemd::runtime {

class GeojsonWriter {
public:
    GeojsonWriter(const std::filesystem::path& map_jsonl, std::filesystem::path out, std::chrono::nanoseconds interval,
                  std::shared_ptr<spdlog::logger> log);
    ~GeojsonWriter();
    GeojsonWriter(const GeojsonWriter&) = delete;
    GeojsonWriter& operator=(const GeojsonWriter&) = delete;

    // Starts the thread; the first rewrite is one interval after.
    void start();
    // Stops the thread (an interrupted wait, or the rewrite in progress
    // completes), then reads the rest of the map and rewrites once more.
    // False (logged) if that last rewrite failed.
    bool finish();

    // Rewrites completed so far (any thread).
    std::uint64_t rewrites() const { return rewrites_.load(std::memory_order_relaxed); }
    // After finish(): the document's features and those with a point.
    std::size_t features() const { return geojson_.features(); }
    std::size_t placed() const { return geojson_.placed(); }

private:
    void run();
    bool rewrite();   // update + write; logs a failure

    PlantGeojson geojson_;
    const std::filesystem::path out_;
    const std::chrono::nanoseconds interval_;
    const std::shared_ptr<spdlog::logger> log_;
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stop_ = false;   // under mutex_
    std::atomic<std::uint64_t> rewrites_{0};
    std::thread thread_;
};

}  // namespace stemd::runtime
