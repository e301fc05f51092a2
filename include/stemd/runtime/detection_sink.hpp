// What the actuator thread does with each frame's detections in this slice:
// logs them (debug level: one line per frame) and, with --detections-csv,
// writes the stemd-detect CSV (same rows: plants with a stem) with a leading
// t_ns column, the frame's recorded time (a recording's t_ns). The CAN
// actuation (tracker, scheduler) takes its place later.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string_view>

#include <spdlog/logger.h>

#include "stemd/base/plant_class.hpp"
#include "stemd/drivers/frame_source.hpp"
#include "stemd/runtime/record_output.hpp"
#include "stemd/vision/types.hpp"

namespace stemd::runtime {

// One processed frame, built in place in the result ring by the processing
// thread (it is ~150 KiB: the Detections are fixed-capacity).
struct FrameResult {
    std::uint64_t seq = 0;             // the runtime's frame number
    std::int64_t t_sample_ns = 0;      // CLOCK_MONOTONIC of the exposure (drivers::Frame)
    std::int64_t t_recorded_ns = 0;    // the frame's own time (recording t_ns)
    std::int64_t t_result_ns = 0;      // CLOCK_MONOTONIC when detect() returned
    std::int64_t pipeline_ns = 0;      // detect() wall time
    double odom_mm = 0;                // the frame's odometer (recording column); NaN if unknown
    bool has_class_map = false;        // plant_class below is meaningful
    bool classes_pending = false;      // plant_class still to come (ClassProvider::resolve)
    drivers::FrameName name;
    vision::Detections detections;
    // Per plant (parallel to detections.plants): the class map's value at
    // its stem (majority of crop/weed pixels around it).
    std::array<PlantClass, vision::kMaxPlants> plant_class{};
};

class DetectionSink {
public:
    explicit DetectionSink(std::shared_ptr<spdlog::logger> log);
    DetectionSink(const DetectionSink&) = delete;
    DetectionSink& operator=(const DetectionSink&) = delete;

    // Opens the CSV and writes its header; false (logged with errno) if it
    // cannot.
    bool open_csv(const std::filesystem::path& path);

    // After open_csv(): rows go through `writer` (which must outlive
    // close()), whose thread makes the write(2)s.
    void attach(RecordWriter& writer) { csv_.attach(writer); }
    bool csv_open() const { return csv_.is_open(); }

    // Per frame, on the actuator thread: no allocation. Each row is
    // formatted into a fixed buffer and handed to the writer (or, without
    // one, written here), one write(2) per row (base::RecordFile), so a
    // kill leaves only complete rows. Without --detections-csv nothing is
    // written. False if a row was lost (the writer counts and logs it).
    bool consume(const FrameResult& result, std::int64_t latency_ns);

    // Waits for the writer's last row (at most
    // RecordWriter::kCloseTimeoutNs), closes the CSV; false if anything was
    // lost (logged). If the writer stalled, the CSV is left open (see
    // PlantMap::close()).
    bool close() { return csv_.close(); }

    static constexpr std::string_view kCsvHeader = "t_ns,image,plant,x,y,method,leaves,area_px,estimator,confidence";

private:
    std::shared_ptr<spdlog::logger> log_;
    RecordOutput csv_;
};

}  // namespace stemd::runtime
