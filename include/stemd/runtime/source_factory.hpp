// The configured frame source (source.kind: v4l2, libcamera or replay) built
// from a DaemonConfig: one place for the daemon (src/main.cpp) and the tools
// that open the same sources (tools/stemd-record.cpp).
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "stemd/drivers/frame_source.hpp"
#include "stemd/config/config.hpp"
#include "stemd/runtime/actuation_config.hpp"
#include "stemd/runtime/daemon_config.hpp"

namespace stemd::runtime {

// Checks the schema cannot make about the source: a configured replay
// directory must be a recording, replay needs a directory (unless
// `check_only`), libcamera needs a build with libcamera. The message names
// where the value came from: `replay_from_cli` means --replay, else the
// configuration's origin (file:line). nullopt when the source can be built.
std::optional<std::string> check_source_config(const DaemonConfig& d, const config::Config& config,
                                               bool replay_from_cli, bool check_only = false);

// segment.method auto made concrete for the configured source, before
// anything is sized by it: exg_and_ndvi when the source delivers a NIR
// plane with every frame (source.kind v4l2 with source.nir_device, or a
// replayed recording whose every frame has a nir image), chromatic_exg
// otherwise. Returns a line for the log naming the choice and why; empty
// when the method was not auto. A replay directory that cannot be read
// resolves to chromatic_exg (the source then reports it).
std::string resolve_auto_segmentation(DaemonConfig& d);

// odometry.source auto made concrete for the configured source before the
// actuator starts: recording when the replayed recording carries odom_mm in
// any frame (its frames without it then have no odometer and are not
// actuated), constant otherwise (cameras, recordings without the column).
// Returns a line for the log naming the choice and why; empty when the
// source was not auto.
std::string resolve_auto_odometry(const DaemonConfig& d, ActuationConfig& actuation);

// The source config.source_kind names, not yet opened. Loggers are named
// after the backend ("v4l2", "libcamera", "replay"). `cancelled`, if set,
// is polled during the source's slow start-up steps (a replay's preload).
std::unique_ptr<drivers::FrameSource> make_frame_source(const DaemonConfig& config,
                                                        std::function<bool()> cancelled = {});

}  // namespace stemd::runtime
