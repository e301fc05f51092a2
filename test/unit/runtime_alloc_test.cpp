// Real-time discipline of the running daemon: once it runs, the capture
// (replay, preloaded), processing and actuator threads allocate nothing per
// frame, CSV output included. Every operator new in this test binary is
// counted (so this file replaces them for all runtime tests).
//
// The replay source is preloaded here: decoding PNGs allocates inside
// OpenCV and libpng, which is the replay source's own I/O (see
// drivers/replay/replay_source.hpp); a camera driver fills slots directly.
#include <gtest/gtest.h>

#include "counting_new.hpp"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <cstring>
#include <filesystem>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <new>
#include <thread>

#include <httplib.h>
#include <opencv2/imgcodecs.hpp>

#include "replay/replay_source.hpp"
#include "runtime_test_util.hpp"
#include "canlog/canlog_bus.hpp"
#include "stemd/base/clock.hpp"
#include "stemd/runtime/actuation_stage.hpp"
#include "stemd/runtime/class_message.hpp"
#include "stemd/runtime/class_socket.hpp"
#include "stemd/runtime/daemon.hpp"
#include "stemd/runtime/live_feed.hpp"
#include "stemd/runtime/logging.hpp"
#include "stemd/web/web_server.hpp"
#include "stemd/synth/synth.hpp"


using namespace stemd;

namespace {

// A GNSS receiver with a fix every 100 ms of CLOCK_MONOTONIC, moving north.
class PacedGnss final : public drivers::GnssSource {
public:
    std::string_view name() const override { return "paced"; }
    bool start() override { return true; }
    void stop() override {}
    bool try_pop(drivers::GnssFix& out) noexcept override
    {
        const std::int64_t now = base::monotonic_ns();
        if (now < next_ns_)
            return false;
        next_ns_ = now + 100'000'000;
        out = {};
        out.timestamp_sample_ns = now;
        out.mode = 3;
        out.lat_deg = 50.6 + static_cast<double>(now % 1'000'000'000'000) * 1e-17;
        out.lon_deg = 7.0;
        return true;
    }
    drivers::GnssCounters counters() const override { return {}; }

private:
    std::int64_t next_ns_ = 0;
};

// A recording of `frames` synthetic late-stage frames, with an odom_mm column.
std::filesystem::path write_recording(int frames, cv::Size size)
{
    const auto dir = test::scratch_dir("alloc");
    std::filesystem::create_directories(dir / "rgb");
    std::ofstream csv(dir / "frames.csv");
    csv << "t_ns,rgb,nir,mask,odom_mm\n";
    synth::Options options;
    options.width_px = size.width;
    options.height_px = size.height;
    for (int i = 0; i < frames; ++i) {
        const auto frame = synth::generate_frame(options, i);
        const std::string name = "rgb/" + std::to_string(i) + ".png";
        cv::imwrite((dir / name).string(), frame.bgr);
        csv << i * 33'333'333LL << "," << name << ",,," << i * 10 << "\n";
    }
    return dir;
}

// A recording of a moving field strip (synth::generate_strip), with the
// exact odometer of every frame: plants move through the view as the
// odometer says, however fast or slow the pipeline is.
std::filesystem::path write_strip_recording(const synth::StripOptions& options)
{
    const auto dir = test::scratch_dir("alloc-strip");
    std::filesystem::create_directories(dir / "rgb");
    std::ofstream csv(dir / "frames.csv");
    csv << "t_ns,rgb,nir,mask,odom_mm\n";
    const synth::Strip strip = synth::generate_strip(options);
    for (int k = 0; k < strip.frame_count; ++k) {
        const synth::StripFrame frame = synth::render_strip_frame(strip, k);
        const std::string name = "rgb/" + std::to_string(k) + ".png";
        cv::imwrite((dir / name).string(), frame.bgr);
        csv << frame.t_ns << "," << name << ",,," << frame.odom_mm << "\n";
    }
    return dir;
}

}  // namespace

TEST(DaemonRealTime, RunningDaemonAllocatesNothingPerFrame)
{
    const cv::Size size(1296, 966);
    const auto dir = write_recording(3, size);
    runtime::DaemonConfig config;
    config.frame_size = size;
    config.replay_fast = true;
    drivers::ReplayOptions replay{.dir = dir, .pacing = drivers::ReplayOptions::Pacing::fast, .loop = true,
                                  .preload = true};
    auto sink = std::make_unique<runtime::DetectionSink>(runtime::make_logger("actuator"));
    ASSERT_TRUE(sink->open_csv(dir / "detections.csv"));
    runtime::Daemon daemon(config, std::make_unique<drivers::ReplaySource>(replay, runtime::make_logger("replay")),
                           std::move(sink));
    ASSERT_TRUE(daemon.start());
    const auto& out = daemon.counters().actuator.frames;
    // Warm-up: first-use allocations (thread-local state in OpenCV, stdio).
    ASSERT_TRUE(test::wait_for([&] { return out.load() >= 10; }, std::chrono::seconds(60)));
    const long before = stemd::test::allocations();
    const std::uint64_t out_before = out.load();
    constexpr std::uint64_t kFrames = 60;
    ASSERT_TRUE(test::wait_for([&] { return out.load() >= out_before + kFrames; }, std::chrono::seconds(120)));
    const long after = stemd::test::allocations();
    const std::uint64_t out_after = out.load();
    daemon.request_stop();
    EXPECT_TRUE(daemon.join());
    EXPECT_EQ(after - before, 0) << "heap allocations over " << out_after - out_before << " frames";
    EXPECT_GT(daemon.counters().actuator.stems.load(), 0u) << "the frames had plants";
    EXPECT_EQ(daemon.counters().processing.failed.load(), 0u);
    std::filesystem::remove_all(dir);
}

namespace {

// The web threads (server and client) may allocate: they are not on the
// per-frame path. Everything else in the process is counted.
void stop_counting() { stemd::test::stop_counting_this_thread(); }

// What a browser does: the frame at 10 fps, the counters and plants every
// second; how many JPEGs it received.
struct WebClient {
    explicit WebClient(int port)
        : thread([this, port] {
              stop_counting();
              httplib::Client c("127.0.0.1", port);
              c.set_read_timeout(10, 0);
              for (int i = 0; !stop.load(); ++i) {
                  if (const auto r = c.Get("/frame.jpg"); r && r->status == 200 && r->body.size() > 100)
                      jpegs.fetch_add(1);
                  if (i % 10 == 0) {
                      c.Get("/api/status");
                      c.Get("/api/plants");
                      c.Get("/metrics");
                  }
                  std::this_thread::sleep_for(std::chrono::milliseconds(100));
              }
          })
    {
    }
    ~WebClient()
    {
        stop = true;
        thread.join();
    }
    std::atomic<bool> stop{false};
    std::atomic<int> jpegs{0};
    std::thread thread;
};

void run_actuation(bool with_web_view)
{
    // The same steady state with the actuation on: field positions, the
    // tracker, the scheduler, TARGET and HEARTBEAT frames into a candump
    // log, GNSS fixes onto the track, and the plant map with positions, all
    // written to files through their buffers.
    // A short strip driven slowly (0.5 km/h, 4.6 mm per frame at 30 fps),
    // replayed at its recorded pace and looped: each pass drives it again
    // with the odometer going on, so every pass brings new plants to track
    // and to treat. Odometer and time then agree, as on a machine, and a
    // plant is in view for over a second, so even a slow sanitizer build
    // that drops frames sees it often enough to confirm and treat it.
    synth::StripOptions strip;
    strip.length_mm = 100;
    strip.width_px = 648;
    strip.height_px = 483;
    strip.speed_kmh = 0.5;
    strip.fps = 30;
    const cv::Size size(strip.width_px, strip.height_px);
    const auto dir = write_strip_recording(strip);
    runtime::DaemonConfig config;
    config.frame_size = size;
    drivers::ReplayOptions replay{.dir = dir, .pacing = drivers::ReplayOptions::Pacing::recorded, .loop = true,
                                  .preload = true};
    runtime::ActuationConfig actuation;
    actuation.tools = {{.id = 0, .offset_mm = 600, .y_min_mm = -220, .y_max_mm = 220, .lanes = 4}};
    actuation.policy = runtime::PolicyChoice::all;
    actuation.odometry = runtime::OdometrySource::recording;
    // A loaded sanitizer build may starve the actuator thread for longer
    // than the 100 ms a live odometer may be extrapolated; that is not what
    // this test is about.
    actuation.max_extrapolation_ns = 1'000'000'000;
    actuation.heartbeat_interval_ns = 1'000'000;
    runtime::ActuationStage::Parts parts;
    auto bus = std::make_unique<drivers::CanLogBus>(drivers::CanLogOptions{.path = dir / "can.log"},
                                                    runtime::make_logger("canlog"));
    ASSERT_TRUE(bus->open());
    const drivers::CanBus& bus_view = *bus;
    parts.bus = std::move(bus);
    parts.map = std::make_unique<runtime::PlantMap>(runtime::make_logger("map"));
    ASSERT_TRUE(parts.map->open(dir / "map.jsonl"));
    parts.gnss = std::make_unique<PacedGnss>();
    geometry::NadirParams nadir;
    nadir.principal_px = geometry::image_centre(size);
    nadir.gsd_mm_per_px = strip.gsd_mm_per_px;
    std::string error;
    auto stage = runtime::ActuationStage::make(actuation, *geometry::CameraModel::nadir(nadir), size,
                                               std::move(parts), runtime::make_logger("actuator"), error);
    ASSERT_TRUE(stage) << error;
    const runtime::ActuationStage& stage_view = *stage;
    // The live view, as stemd wires it: a feed allocated before the start
    // (declared before the daemon, which it outlives), and a server reading
    // it; plus a client polling it throughout.
    runtime::WebConfig web_config;
    web_config.fps = 30;   // every frame it may: the most copying
    runtime::LiveFeed feed(config.frame_shape(), web_config.fps, 256);
    runtime::Daemon daemon(config, std::make_unique<drivers::ReplaySource>(replay, runtime::make_logger("replay")),
                           std::make_unique<runtime::DetectionSink>(runtime::make_logger("actuator")),
                           std::move(stage));
    std::unique_ptr<web::WebServer> server;
    std::unique_ptr<WebClient> client;
    if (with_web_view)
        daemon.attach_live_feed(&feed);
    ASSERT_TRUE(daemon.start());
    if (with_web_view) {
        runtime::Daemon* d = &daemon;
        server = std::make_unique<web::WebServer>(
            web_config, runtime::ListenAddress{"127.0.0.1", 0},
            web::WebSources{.feed = &feed,
                            .totals = [d] { return d->snapshot(true); },
                            .metrics = [d] { return web::collect_metrics(*d); },
                            .config_yaml = "",
                            .control = std::nullopt,
                            .camera = std::nullopt},
            runtime::make_logger("web"), &stop_counting);
        ASSERT_TRUE(server->start());
        client = std::make_unique<WebClient>(server->port());
    }
    const auto& out = daemon.counters().actuator.frames;
    ASSERT_TRUE(test::wait_for([&] { return out.load() >= 10; }, std::chrono::seconds(60)));
    // With the view, counting starts once the client has its first JPEG (the
    // view is live), and ends only after it received more and the processing
    // thread published more: the copy and the serving overlap the counting.
    if (client) {
        ASSERT_TRUE(test::wait_for([&] { return client->jpegs.load() >= 1; }, std::chrono::seconds(120)));
    }
    struct Window {
        const std::atomic<std::uint64_t>& out;
        std::uint64_t out_until;
        const WebClient* client;
        int jpegs_until;
        const runtime::LiveFeed& feed;
        std::uint64_t published_until;
        bool done() const
        {
            return out.load() >= out_until &&
                   (client == nullptr || (client->jpegs.load() >= jpegs_until && feed.frames_published() >= published_until));
        }
    };
    const long before = stemd::test::allocations();
    const std::uint64_t out_before = out.load();
    const std::uint64_t sent_before = bus_view.counters().sent;
    const int jpegs_before = client ? client->jpegs.load() : 0;
    const std::uint64_t published_before = feed.frames_published();
    constexpr std::uint64_t kFrames = 60;
    const Window window{out, out_before + kFrames, client.get(), jpegs_before + 3, feed, published_before + 3};
    // One reference captured: the std::function holds it without allocating.
    ASSERT_TRUE(test::wait_for([&window] { return window.done(); }, std::chrono::seconds(180)));
    const long after = stemd::test::allocations();
    const std::uint64_t sent_after = bus_view.counters().sent;
    client.reset();
    if (server)
        server->stop();
    daemon.request_stop();
    EXPECT_TRUE(daemon.join());
    EXPECT_EQ(after - before, 0) << "heap allocations over " << out.load() - out_before << " frames";
    // The path was exercised: frames sent while counting, targets and map lines.
    EXPECT_GT(sent_after, sent_before);
    const runtime::ActuationCounters& c = stage_view.counters();
    EXPECT_GT(c.sent.load(), 0u) << "frames " << c.frames << ", targets " << c.targets << ", clipped " << c.clipped
                                 << ", off_ground " << c.off_ground << ", no_tool " << c.no_tool
                                 << ", deadline_misses " << c.deadline_misses << ", bus_deadline " << c.bus_deadline
                                 << ", odometry_going_back " << c.odometry_going_back;
    EXPECT_EQ(stage_view.counters().no_odometry.load(), 0u);
    EXPECT_GT(std::filesystem::file_size(dir / "map.jsonl"), 0u);
    ASSERT_NE(stage_view.gnss(), nullptr);
    EXPECT_GT(stage_view.gnss()->counters().on_track, 0u) << "the GNSS path was exercised";
    std::filesystem::remove_all(dir);
}

}  // namespace

TEST(DaemonRealTime, ActuationAllocatesNothingPerFrame)
{
    run_actuation(false);
}

TEST(DaemonRealTime, WebViewWithAClientAllocatesNothingPerFrame)
{
    run_actuation(true);
}

// The socket class provider's per-frame path: a frame handed over at
// capture, sent, its map received and stored by the receiver thread, looked
// up by the actuator (a hit, then a frame past its timeout). Nothing
// allocates once the peer is connected; log lines (connect, hang-up, bad
// messages) are not per frame.
TEST(DaemonRealTime, SocketClassProviderAllocatesNothingPerFrame)
{
    const std::string path = (std::filesystem::temp_directory_path() /
                              ("stemd-class-alloc-" + std::to_string(::getpid()) + ".sock")).string();
    runtime::SocketClassProvider provider(path, {400, 200}, 60'000);
    ASSERT_TRUE(provider.start());
    const int peer = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::memcpy(addr.sun_path, path.data(), path.size());
    ASSERT_EQ(::connect(peer, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)), 0);
    const std::int64_t deadline_ns = base::monotonic_ns() + 10'000'000'000;
    while (!provider.peer_connected() && base::monotonic_ns() < deadline_ns)
        base::sleep_for_ns(1'000'000);
    ASSERT_TRUE(provider.peer_connected());

    // Everything the test side needs, allocated before counting.
    std::vector<std::uint8_t> rx(runtime::kFrameMessageHeaderBytes + runtime::kFrameMessageMaxName);
    std::vector<std::uint8_t> map(runtime::kClassMapHeaderBytes + 100 * 50, 2);
    auto frame = std::make_unique<drivers::Frame>();
    frame->name.assign("rgb/000000.png");
    auto result = std::make_unique<runtime::FrameResult>();
    vision::Plant plant;
    plant.stem = {200, 100};
    result->detections.plants.push_back(plant);
    const vision::Params params;
    const vision::Workspace workspace({400, 200}, params);

    const long before = stemd::test::allocations();
    bool hit = true;
    for (std::uint64_t i = 0; i < 20 && hit; ++i) {
        frame->t_sample_ns = base::monotonic_ns();
        frame->seq = i;
        provider.on_capture(*frame);
        pollfd p{.fd = peer, .events = POLLIN, .revents = 0};
        hit = ::poll(&p, 1, 10'000) == 1 && ::recv(peer, rx.data(), rx.size(), 0) > 0;
        runtime::encode_class_map_header(
            frame->t_sample_ns, 100, 50,
            std::span<std::uint8_t, runtime::kClassMapHeaderBytes>(map.data(), runtime::kClassMapHeaderBytes));
        hit = hit && ::send(peer, map.data(), map.size(), 0) == static_cast<ssize_t>(map.size());
        result->t_sample_ns = frame->t_sample_ns;
        provider.classify(*frame, params, workspace, *result);
        while (hit && !provider.resolve(*result, base::monotonic_ns()) && base::monotonic_ns() < deadline_ns)
            base::sleep_for_ns(100'000);
        hit = hit && !result->classes_pending && result->plant_class[0] == PlantClass::Weed;
    }
    // Past its timeout: unknown, counted.
    result->t_sample_ns -= 120'000'000'000;
    result->classes_pending = true;
    const bool expired = provider.resolve(*result, base::monotonic_ns());
    const long allocated = stemd::test::allocations() - before;
    EXPECT_TRUE(hit) << "a frame's map did not come back";
    EXPECT_TRUE(expired);
    EXPECT_EQ(provider.counters().maps.load(), 20u);
    EXPECT_EQ(provider.counters().timeouts.load(), 1u);
    EXPECT_EQ(allocated, 0);
    ::close(peer);
    provider.stop();
}

TEST(DaemonRealTime, TheCounterSeesAllocations)
{
    // Guards the test above: if operator new were not replaced it would pass vacuously.
    const long before = stemd::test::allocations();
    auto p = std::make_unique<int>(3);
    EXPECT_EQ(stemd::test::allocations() - before, 1);
    EXPECT_EQ(*p, 3);
}
