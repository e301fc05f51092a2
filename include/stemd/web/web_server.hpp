// The operator's live view: an HTTP server (cpp-httplib) on its own threads,
// SCHED_OTHER at nice 10, off the real-time path. It reads the daemon only
// through a LiveFeed (frames, plants) and the counters' relaxed atomics;
// drawing the overlay and encoding JPEGs happen on its threads.
//
//   GET /             the page (HTML + JS built into the binary)
//   GET /frame.jpg    the latest frame with the overlay (and, with a camera
//                     model, the targets decided near it), at most web.fps
//                     new frames a second, at most web.max_width_px wide
//   GET /api/status   counters, drops, latencies, histograms (JSON)
//   GET /api/plants   the last web.plants plants of the plant map (JSON)
//   GET /api/config   the running configuration (JSON: {"yaml": ...})
//   GET /metrics      Prometheus text format 0.0.4
// With a control token (web.token_file) only:
//   GET  /api/control  the enable state and the parameters that may change
//                      (key, type, unit, range, value)
//   POST /api/enable   {"enabled": false}: the operator's disable; true
//                      clears it (the enable input keeps its say)
//   POST /api/param    {"key": "stem.min_confidence", "value": 0.2}
// each POST needing "Authorization: Bearer <token>" (else 401, counted);
// a value the schema refuses gets 400 with the reason (the range).
// Anything else is 404; bodies over 64 KiB get 413, header lines over
// 4 KiB and request lines over 2 KiB are refused, a malformed request gets 400.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <spdlog/logger.h>

#include "stemd/config/config.hpp"
#include "stemd/geometry/camera_model.hpp"
#include "stemd/runtime/live_feed.hpp"
#include "stemd/runtime/status.hpp"
#include "stemd/runtime/web_config.hpp"
#include "stemd/vision/types.hpp"
#include "stemd/web/metrics.hpp"

namespace stemd::web {

// The control endpoints' ends (called on the server's threads).
struct WebControl {
    std::string token;                                       // the bearer token (web.token_file's)
    config::Config config;                                   // the running configuration, changed in place
    std::function<void(const vision::Params&)> set_params;   // to the processing thread
    std::function<void(bool)> set_disabled;                  // the operator's disable
    std::function<bool()> disabled;
    std::function<bool()> enable_input;                      // the enable input (GPIO)
};

// Where the server's numbers come from (called on its threads).
struct WebSources {
    runtime::LiveFeed* feed = nullptr;                  // frames and plants; nullptr: none
    std::function<runtime::StatusSnapshot()> totals;    // whole-run totals
    std::function<Metrics()> metrics;                   // live_* and web_* are filled in by the server
    std::string config_yaml;                            // the running configuration (without control)
    std::optional<WebControl> control;                  // nullopt: read-only, no control endpoints
    // The camera: with it the frame shows the targets near it (field -> pixel).
    std::optional<geometry::CameraModel> camera;
};

class WebServer {
public:
    // thread_start, if given, runs first on every thread the server starts
    // (a test marks them, to tell their allocations from the daemon's).
    WebServer(const runtime::WebConfig& config, runtime::ListenAddress address, WebSources sources,
              std::shared_ptr<spdlog::logger> log, void (*thread_start)() = nullptr);
    ~WebServer();   // stops
    WebServer(const WebServer&) = delete;
    WebServer& operator=(const WebServer&) = delete;

    // Binds and starts serving. False if the address cannot be bound (logged
    // with the address and errno); the daemon then runs without the view.
    bool start();
    void stop();

    bool serving() const;
    int port() const;                  // the bound port (web.listen's port 0: the one the kernel chose)
    std::uint64_t requests() const;
    // For the status line: "web http://127.0.0.1:8080/ 12 requests" or
    // "web not serving (127.0.0.1:8080: Address already in use)".
    std::string status_text() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace stemd::web
