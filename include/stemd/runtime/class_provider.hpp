// Where each plant's class (crop, weed, unknown) comes from in the daemon,
// chosen by classify.provider:
//   - model: the in-box classifier (classify.model, vision/classify), run
//     by the processing thread on each frame;
//   - recording: a replayed recording's class column (its class map per
//     frame); frames without one leave every plant unknown and the result
//     without a class map (scheduler.policy auto then treats all);
//   - socket: another process (a CNN elsewhere) sends a class map per frame
//     over a Unix socket (class_socket.hpp); a result waits at the actuator
//     for its map until classify.provider_timeout_ms after capture, then
//     its plants are unknown.
// Per frame none of them locks, allocates or blocks.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <opencv2/core/mat.hpp>

#include "stemd/base/plant_class.hpp"
#include "stemd/drivers/frame_source.hpp"
#include "stemd/runtime/daemon_config.hpp"
#include "stemd/runtime/detection_sink.hpp"
#include "stemd/vision/cells.hpp"
#include "stemd/vision/classify.hpp"
#include "stemd/vision/detect.hpp"

namespace stemd::runtime {

// Each written by one thread (relaxed), read by the status line.
struct ClassCounters {
    std::atomic<std::uint64_t> bad_class{0};      // plants whose class-map window held values above 2
    std::atomic<std::uint64_t> weed_parts{0};     // weed targets from a crop/unknown plant's weed cells (model)
    std::atomic<std::uint64_t> stemless_weeds{0}; // weed targets from a stemless weed plant's cells (model)
    std::atomic<std::uint64_t> weed_cover{0};     // further targets on weeds wider than weed_cover_radius_mm (model)
    std::atomic<std::uint64_t> cells_over_budget{0};   // vegetated cells left unclassified by classify.max_cells (model)
    std::atomic<std::uint64_t> frames_over_budget{0};  // frames with any (model)
    std::atomic<std::uint64_t> timeouts{0};       // frames whose class map did not come in time (plants unknown)
    std::atomic<std::uint64_t> maps{0};           // class maps received (socket)
    std::atomic<std::uint64_t> bad_messages{0};   // malformed messages, dropped (socket)
    std::atomic<std::uint64_t> peers{0};          // connections accepted (socket)
};

class ClassProvider {
public:
    virtual ~ClassProvider() = default;
    virtual std::string_view name() const = 0;

    // Before the daemon's threads: false (logged) if it cannot run.
    virtual bool start() { return true; }
    // After they are joined.
    virtual void stop() {}

    // Capture thread, as soon as a frame is stamped. Must not block.
    virtual void on_capture(const drivers::Frame& /*frame*/) noexcept {}

    // Processing thread, after detect() returned ok on `frame` (the
    // Detections in `result`): result.plant_class and has_class_map as far
    // as known now, and result.classes_pending if they come later.
    virtual void classify(const drivers::Frame& frame, const vision::Params& params,
                          const vision::Workspace& workspace, FrameResult& result) = 0;

    // Actuator thread, for a result left pending: true once its classes are
    // in (they came, or the timeout made its plants unknown); false: not
    // yet, ask again. Never blocks.
    virtual bool resolve(FrameResult& /*result*/, std::int64_t /*now_ns*/) noexcept { return true; }

    const ClassCounters& counters() const { return counters_; }

protected:
    ClassCounters counters_;
};

// The class of each plant from a class map around its stem: the vision
// library's, shared with the in-box model's cells.
using vision::plant_classes_from_map;

// The in-box model.
class ModelClassProvider final : public ClassProvider {
public:
    ModelClassProvider(vision::PlantClassifier model, cv::Size frame_size, const vision::Params& params,
                       const vision::ModelClassParams& class_params);
    std::string_view name() const override { return "model"; }
    void classify(const drivers::Frame& frame, const vision::Params& params, const vision::Workspace& workspace,
                  FrameResult& result) override;

private:
    vision::PlantClassifier model_;
    vision::ClassifyWorkspace workspace_;
    vision::CellWorkspace cells_;
    std::array<float, vision::kMaxPlants> probabilities_{};
    vision::ModelClassParams params_;
};

// A replayed recording's class column.
class RecordingClassProvider final : public ClassProvider {
public:
    std::string_view name() const override { return "recording"; }
    void classify(const drivers::Frame& frame, const vision::Params& params, const vision::Workspace& workspace,
                  FrameResult& result) override;
};

}  // namespace stemd::runtime
