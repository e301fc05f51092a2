// stemd: the program the robot runs. Capture -> stem pipeline -> actuator
// (field coordinates, one target per plant, deadline-checked TARGET
// commands on the CAN bus or into a candump log; optional detections CSV
// and plant map).
//   stemd [--config FILE]... [--set KEY=VALUE]... [--check-config]
//         [--replay DIR] [--once] [--detections-csv FILE]
//         [--can-log FILE] [--map FILE] [--map-geojson FILE]
// Exit: 0 on SIGTERM/SIGINT or, with --once, after the last frame; 1 when the
// source or an output fails; 2 on bad arguments or configuration.
#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <spdlog/spdlog.h>

#include "tool_cli.hpp"

#include "stemd/runtime/actuation_factory.hpp"
#include "stemd/runtime/camera_config.hpp"
#include "stemd/config/command_line.hpp"
#include "stemd/config/config.hpp"
#include "stemd/runtime/class_socket.hpp"
#include "stemd/runtime/daemon.hpp"
#include "stemd/runtime/sd_notify.hpp"
#include "stemd/runtime/detection_sink.hpp"
#include "stemd/runtime/logging.hpp"
#include "stemd/runtime/geojson_writer.hpp"
#include "stemd/runtime/signals.hpp"
#include "stemd/runtime/source_factory.hpp"
#include "stemd/runtime/status.hpp"
#include "stemd/base/clock.hpp"
#include "stemd/runtime/live_feed.hpp"
#include "stemd/runtime/web_config.hpp"
#include "stemd/web/web_json.hpp"
#include "stemd/web/web_control.hpp"
#include "stemd/web/web_server.hpp"

using namespace stemd;
using namespace std::chrono_literals;

namespace {

using tools::kUsageError;

// The options: here, in Args and in parse_args.
const char* const kUsage =
    "usage: stemd [--config FILE]... [--set KEY=VALUE]... [--check-config]\n"
    "             [--replay DIR] [--once] [--detections-csv FILE]\n"
    "             [--can-log FILE] [--map FILE] [--map-geojson FILE]\n"
    "  --config          configuration file (see config/stemd.yaml); repeated, later files\n"
    "                    override earlier ones key by key\n"
    "  --set             override one configuration key, e.g. --set ring.capacity=8\n"
    "  --check-config    validate the configuration and exit (0 ok, 2 error)\n"
    "  --replay          replay a recording directory (overrides source.*)\n"
    "  --once            play the recording once; exit 0 after its last frame\n"
    "  --detections-csv  write the stemd-detect CSV with a leading t_ns column\n"
    "  --can-log         write the CAN frames to FILE (candump -L format) instead of a bus\n"
    "  --map             write the plant map (JSON lines) to FILE\n"
    "  --map-geojson     also write it as GeoJSON points (WGS84, with gnss.source) to FILE,\n"
    "                    rewritten every 30 s and at exit\n";

struct Args {
    config::ConfigArgs config;
    bool check_config = false;
    std::string replay_dir;
    bool once = false;
    std::string detections_csv;
    std::string can_log;
    std::string map;
    std::string map_geojson;
};

const tools::CommandLine kCommandLine{
    .tool = "stemd", .usage = kUsage, .usage_after_error = true, .pass_unknown = true};

// Every option of the daemon. nullopt: go
// on; else the exit code (0 after --help, 2 after a usage error).
std::optional<int> parse_args(int argc, char** argv, Args& args)
{
    // -h or --help anywhere is help, even where an option's value belongs.
    if (std::any_of(argv + 1, argv + argc, [](std::string_view a) { return a == "-h" || a == "--help"; })) {
        std::cout << kUsage;
        return 0;
    }
    CLI::App app("stemd");
    tools::add_config_options(app, args.config);
    app.add_flag("--check-config", args.check_config);
    app.add_flag("--once", args.once);
    for (const auto& [name, value] : {std::pair{"--replay", &args.replay_dir},
                                      {"--detections-csv", &args.detections_csv},
                                      {"--can-log", &args.can_log},
                                      {"--map", &args.map},
                                      {"--map-geojson", &args.map_geojson}})
        app.add_option(name, *value);
    if (const auto exit = tools::parse(app, argc, argv, kCommandLine))
        return exit;
    if (const std::vector<std::string> rest = app.remaining(); !rest.empty())
        return tools::usage_error(kCommandLine, "unknown argument " + rest.front());
    return std::nullopt;
}

}  // namespace

// What main() was doing, for the one line a resource failure gets.
struct Phase {
    const char* what = "reading the command line";
    int exit_code = kUsageError;   // 2 while the configuration is read, 1 once running
};

int run(int argc, char** argv, Phase& phase)
{
    Args args;
    if (const auto exit = parse_args(argc, argv, args))
        return *exit;
    // Before any thread exists, so that every thread inherits the blocked
    // mask and only the main loop below receives SIGTERM/SIGINT.
    runtime::ShutdownSignals signals;

    std::string error;
    // The signals wait (blocked) for the main loop; each start-up step
    // looks whether one came meanwhile, so that a stop during a slow start
    // (a large config, a slow device) ends it after that step.
    const auto stop_came = [&signals] {
        const auto sig = signals.wait(0ms);
        if (sig)
            std::cerr << "stemd: " << (*sig == SIGTERM ? "SIGTERM" : "SIGINT") << " while starting: stopping\n";
        return sig.has_value();
    };
    phase.what = "reading the configuration";
    config::Config config;
    if (const auto config_error = config::build_config(args.config, config)) {
        std::cerr << "stemd: " << config_error->to_string() << "\n";
        return kUsageError;
    }
    if (stop_came())
        return 0;
    config::Settings settings = config.settings();
    runtime::DaemonConfig& daemon_config = settings.daemon;
    if (!args.replay_dir.empty()) {
        daemon_config.source_kind = "replay";
        daemon_config.replay_dir = args.replay_dir;
    }
    if (args.once)
        daemon_config.replay_loop = false;
    // Recordings may carry class maps (the scheduler's policy reads them).
    daemon_config.class_maps = daemon_config.source_kind == "replay";
    // Before anything is sized by the method: the frame slots' planes, the
    // model's channels.
    const std::string segmentation_choice = runtime::resolve_auto_segmentation(daemon_config);
    runtime::ActuationConfig& actuation_config = settings.actuation;
    if (!args.can_log.empty()) {
        actuation_config.can_interface.clear();
        actuation_config.can_log_file = args.can_log;
    }
    if (!args.map.empty())
        actuation_config.map_file = args.map;
    const std::string odometry_choice = runtime::resolve_auto_odometry(daemon_config, actuation_config);
    if (!args.map_geojson.empty() && actuation_config.map_file.empty()) {
        std::cerr << "stemd: --map-geojson is made from the plant map: give --map FILE (or map.file) too\n";
        return kUsageError;
    }
    runtime::ConfigProblem problem;
    const auto camera = runtime::camera_model(settings.camera, daemon_config.vision.gsd_mm_per_px,
                                              daemon_config.frame_size, problem);
    if (!camera) {
        std::cerr << "stemd: " << config.blame(problem.key, problem.message) << "\n";
        return kUsageError;
    }
    if (const auto actuation_problem = runtime::check_actuation_config(actuation_config)) {
        std::cerr << "stemd: " << config.blame(actuation_problem->key, actuation_problem->message) << "\n";
        return kUsageError;
    }
    if (const auto problem =
            runtime::check_source_config(daemon_config, config, !args.replay_dir.empty(), args.check_config)) {
        std::cerr << "stemd: " << *problem << "\n";
        return kUsageError;
    }
    // The live view's address: a typo is a configuration error, not a view
    // that silently never appears.
    std::optional<runtime::ListenAddress> web_address;
    if (!daemon_config.web.listen.empty()) {
        web_address = runtime::parse_listen_address(daemon_config.web.listen, error);
        if (!web_address) {
            std::cerr << "stemd: " << config.blame("web.listen", error) << "\n";
            return kUsageError;
        }
    }
    // The control token: read once, here; a view that was meant to be
    // controllable but cannot check tokens does not start.
    std::string web_token;
    if (!daemon_config.web.token_file.empty()) {
        if (!web_address) {
            std::cerr << "stemd: " << config.blame("web.token_file", "needs web.listen (the view is off)") << "\n";
            return kUsageError;
        }
        const auto token = web::read_token_file(daemon_config.web.token_file, error);
        if (!token) {
            std::cerr << "stemd: " << config.blame("web.token_file", error) << "\n";
            return kUsageError;
        }
        web_token = *token;
    }
    // Where plants' classes come from: one provider, so a model and another
    // provider named together is a mistake, not a choice.
    using runtime::ClassProviderChoice;
    const bool has_model = !daemon_config.classify.model.empty();
    ClassProviderChoice provider = daemon_config.classify.provider;
    if (provider == ClassProviderChoice::automatic)
        provider = has_model ? ClassProviderChoice::model : ClassProviderChoice::recording;
    if (provider == ClassProviderChoice::model && !has_model) {
        std::cerr << "stemd: " << config.blame("classify.provider", "model needs classify.model") << "\n";
        return kUsageError;
    }
    if (provider != ClassProviderChoice::model && has_model) {
        std::cerr << "stemd: " << config.blame("classify.model", "is set, but classify.provider is not model") << "\n";
        return kUsageError;
    }
    if (provider == ClassProviderChoice::socket && daemon_config.classify.socket.empty()) {
        std::cerr << "stemd: " << config.blame("classify.provider", "socket needs classify.socket") << "\n";
        return kUsageError;
    }
    // The crop/weed model: refused at start, like any other bad setting,
    // when it is unreadable or made for another camera.
    std::optional<vision::PlantClassifier> classifier;
    if (!daemon_config.classify.model.empty()) {
        classifier = vision::PlantClassifier::load(daemon_config.classify.model, error);
        if (!classifier) {
            std::cerr << "stemd: " << config.blame("classify.model", error) << "\n";
            return kUsageError;
        }
        if (const auto why = classifier->mismatch(daemon_config.vision.gsd_mm_per_px,
                                                  vision::uses_nir(daemon_config.vision.segmentation),
                                                  daemon_config.classify.model)) {
            std::cerr << "stemd: " << config.blame("classify.model", *why) << "\n";
            return kUsageError;
        }
    }
    if (args.check_config) {
        std::cout << "stemd: configuration ok\n";
        return 0;
    }

    phase = {"starting", 1};
    runtime::set_log_level(daemon_config.log_level);
    const auto log = runtime::make_logger("main");
    const auto status_log = runtime::make_logger("status");
    if (!segmentation_choice.empty())
        log->info("{}", segmentation_choice);
    if (!odometry_choice.empty())
        log->info("{}", odometry_choice);

    if (stop_came())
        return 0;
    std::unique_ptr<drivers::FrameSource> source = runtime::make_frame_source(daemon_config, [&signals] { return signals.pending(); });

    auto sink = std::make_unique<runtime::DetectionSink>(runtime::make_logger("actuator"));
    if (!args.detections_csv.empty() && !sink->open_csv(args.detections_csv))
        return 1;
    std::string actuation_error;
    std::unique_ptr<runtime::ActuationStage> actuation =
        runtime::make_actuation(actuation_config, *camera, daemon_config.frame_size, actuation_error);
    if (!actuation) {
        log->error("actuation: {}", actuation_error);
        return 1;
    }
    if (stop_came())
        return 0;

    // The GeoJSON is rebuilt from the plant map's lines on a low-priority thread of its own.
    std::optional<runtime::GeojsonWriter> geojson;
    if (!args.map_geojson.empty()) {
        geojson.emplace(actuation_config.map_file, args.map_geojson, std::chrono::seconds(30), log);
        geojson->start();
    }

    std::unique_ptr<runtime::Daemon> daemon;
    try {
        daemon = std::make_unique<runtime::Daemon>(daemon_config, std::move(source), std::move(sink),
                                                   std::move(actuation));
    } catch (const std::bad_alloc&) {
        log->error("cannot allocate the frame slots and workspace for {}x{} frames", daemon_config.frame_size.width,
                   daemon_config.frame_size.height);
        return 1;
    }
    if (classifier) {
        log->info("classify.model {}: trained on {} at {} mm/px, {}", daemon_config.classify.model,
                  classifier->info().recordings.empty() ? std::string("?") : classifier->info().recordings.front(),
                  classifier->info().gsd_mm_per_px, vision::channels_name(classifier->info().nir));
        daemon->set_class_provider(std::make_unique<runtime::ModelClassProvider>(
            std::move(*classifier), daemon_config.frame_size, daemon_config.vision,
            runtime::model_class_params(daemon_config.classify, settings.camera.mount.forward)));
    } else if (provider == ClassProviderChoice::socket) {
        daemon->set_class_provider(std::make_unique<runtime::SocketClassProvider>(
            daemon_config.classify.socket, daemon_config.frame_size, daemon_config.classify.provider_timeout_ms));
    }
    // The live view's feed is allocated now, with everything else; its
    // server starts once the daemon runs.
    std::unique_ptr<runtime::LiveFeed> live_feed;
    if (web_address) {
        live_feed = std::make_unique<runtime::LiveFeed>(daemon_config.frame_shape(), daemon_config.web.fps,
                                                        static_cast<std::size_t>(daemon_config.web.plants) + 256);
        daemon->attach_live_feed(live_feed.get());
    }
    if (stop_came())
        return 0;
    if (!daemon->start()) {
        // A SIGTERM during a slow start (a long preload) is a stop, not a failure.
        if (const auto sig = signals.wait(0ms)) {
            log->info("{}: stopping", *sig == SIGTERM ? "SIGTERM" : "SIGINT");
            return 0;
        }
        return 1;
    }

    std::unique_ptr<web::WebServer> web_server;
    if (web_address) {
        runtime::Daemon* const d = daemon.get();
        web::WebSources sources{.feed = live_feed.get(),
                                .totals = [d] { return d->snapshot(true); },
                                .metrics = [d] { return web::collect_metrics(*d); },
                                .config_yaml = config.to_yaml(),
                                .control = std::nullopt,
                                .camera = *camera};
        if (!web_token.empty())
            sources.control = web::WebControl{
                .token = web_token,
                .config = config,
                .set_params = [d](const vision::Params& params) { d->set_vision_params(params); },
                .set_disabled = [d](bool disabled) { d->set_operator_disabled(disabled); },
                .disabled = [d] { return d->operator_disabled(); },
                .enable_input = [d] { return d->enable_input(); }};
        web_server = std::make_unique<web::WebServer>(daemon_config.web, *web_address, std::move(sources),
                                                      runtime::make_logger("web"));
        // A taken port is logged with the address and errno; the daemon runs
        // on without the view, and the status line says so.
        web_server->start();
    }
    const auto interval = std::chrono::nanoseconds(static_cast<std::int64_t>(daemon_config.status_interval_s * 1e9));
    const std::int64_t t_start_ns = base::monotonic_ns();
    runtime::StatusSnapshot last = daemon->snapshot(false);
    last.t_ns = t_start_ns;
    std::int64_t next_status_ns = t_start_ns + interval.count();
    int exit_code = 0;
    // systemd (Type=notify): READY=1 once the source delivers, WATCHDOG=1
    // only while all three threads make progress, STATUS= the status line.
    runtime::SystemdNotifier systemd;
    if (!systemd.error().empty())
        log->warn("systemd notification disabled: {}", systemd.error());
    const std::int64_t watchdog_ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(systemd.watchdog_interval()).count();
    std::int64_t next_watchdog_ns = t_start_ns;
    bool ready = false;
    const char* stalled_reported = nullptr;
    auto notify = [&](const std::string& state) {
        if (systemd.enabled() && !systemd.notify(state))
            log->warn("systemd notify '{}' failed: {}", state.substr(0, state.find('=')), systemd.error());
    };
    while (!daemon->finished() && !daemon->thread_failed()) {
        if (const auto sig = signals.wait(100ms)) {
            log->info("{}: stopping", *sig == SIGTERM ? "SIGTERM" : "SIGINT");
            break;
        }
        const std::int64_t now_ns = base::monotonic_ns();
        if (!ready && daemon->snapshot(false).frames_in > 0) {
            ready = true;
            notify("READY=1");
        }
        // systemd starts the watchdog once the service is ready.
        if (ready && watchdog_ns > 0 && now_ns >= next_watchdog_ns) {
            // A thread silent for half the watchdog interval is stuck: stop
            // petting and let systemd restart us.
            const char* stalled = daemon->stalled_thread(now_ns, watchdog_ns / 2);
            if (stalled == nullptr) {
                notify("WATCHDOG=1");
                stalled_reported = nullptr;
            } else if (stalled != stalled_reported) {
                log->error("{} thread has made no progress for {} ms: withholding the watchdog", stalled,
                           watchdog_ns / 2 / 1'000'000);
                stalled_reported = stalled;
            }
            next_watchdog_ns = now_ns + watchdog_ns / 4;
        }
        if (now_ns >= next_status_ns) {
            const runtime::StatusSnapshot now = daemon->snapshot(false);
            std::string line = runtime::format_status(now, last);
            if (web_server)
                line += " | " + web_server->status_text();
            status_log->info("{}", line);
            if (const std::string changed = runtime::format_latency_changes(now, last); !changed.empty())
                log->info("{}", changed);
            notify("STATUS=" + line);
            last = now;
            next_status_ns += interval.count();
        }
    }
    notify("STOPPING=1");
    if (web_server)
        web_server->stop();
    daemon->request_stop();
    if (!daemon->join())
        exit_code = 1;
    if (daemon->source_failed() || daemon->thread_failed())
        exit_code = 1;
    // After join(): the map holds every plant.
    if (geojson) {
        if (geojson->finish())
            log->info("{}: {} plants, {} with a position", args.map_geojson, geojson->features(), geojson->placed());
        else
            exit_code = 1;
    }
    const double run_s = static_cast<double>(base::monotonic_ns() - t_start_ns) / 1e9;
    status_log->info("total: {}", runtime::format_summary(daemon->snapshot(true), run_s));
    if (daemon->output_stalled()) {
        // A write(2) that never returns cannot be cancelled, and the thread
        // in it cannot be joined: end here, without destructors.
        log->error("exiting with an output file stalled");
        std::fflush(nullptr);
        std::_Exit(1);
    }
    return exit_code;
}

int main(int argc, char** argv)
{
    // A file-size limit (ulimit -f) then makes write(2) fail with EFBIG,
    // which the writers report and count, instead of killing the process
    // without a word.
    std::signal(SIGXFSZ, SIG_IGN);
    Phase phase;
    try {
        return run(argc, argv, phase);
    } catch (const std::bad_alloc&) {
        std::cerr << "stemd: out of memory while " << phase.what << " (a memory limit: ulimit -v, MemoryMax=?)\n";
    } catch (const std::system_error& e) {
        std::cerr << "stemd: " << phase.what << ": " << e.what() << " (a resource limit: threads, memory?)\n";
    } catch (const std::exception& e) {
        std::cerr << "stemd: " << phase.what << ": " << e.what() << "\n";
    }
    return phase.exit_code;
}
