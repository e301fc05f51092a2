#include "stemd/web/web_server.hpp"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include <httplib.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "stemd/base/clock.hpp"
#include "stemd/base/log_throttle.hpp"
#include "stemd/viz/overlay.hpp"
#include "stemd/web/web_control.hpp"
#include "stemd/web/web_json.hpp"
#include "stemd/web_page.hpp"   // generated from src/web/page.html

namespace stemd::web {

namespace {

constexpr std::size_t kMaxBodyBytes = 64 * 1024;
constexpr std::size_t kMaxTargetBytes = 2048;
constexpr std::size_t kMaxHeaderCount = 64;
constexpr int kNice = 10;
constexpr int kWorkers = 2;
// Accepted connections waiting for a worker. Each holds a descriptor, and
// the descriptors are the process's: a camera's reopen, the CAN socket, the
// replay's next frame and the output files need theirs. Beyond this many,
// the listening thread serves the next connection itself and accepts no
// other meanwhile; further clients wait in the kernel's listen backlog,
// holding none of ours. The view then uses at most kWorkers +
// kMaxWaitingConnections + 2 descriptors (the listening socket and the
// connection served on it), whatever a client or a scanner does.
constexpr std::size_t kMaxWaitingConnections = 16;

// The server's threads run at nice 10 under SCHED_OTHER: on two cores the
// real-time threads (and the rest of the machine) come first. Linux applies
// setpriority(PRIO_PROCESS, tid) to one thread.
void lower_priority(const char* name)
{
    setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), kNice);
    pthread_setname_np(pthread_self(), name);
}

// httplib's request queue, on threads this server starts and names.
class WorkerQueue : public httplib::TaskQueue {
public:
    WorkerQueue(int threads, void (*thread_start)(), spdlog::logger& log) : log_(log)
    {
        for (int i = 0; i < threads; ++i)
            threads_.emplace_back([this, thread_start] {
                if (thread_start != nullptr)
                    thread_start();
                lower_priority("stemd-web");
                run();
            });
    }
    // On the listening thread, once per accepted connection.
    void enqueue(std::function<void()> fn) override
    {
        {
            std::lock_guard lock(mutex_);
            if (jobs_.size() < kMaxWaitingConnections) {
                jobs_.push_back(std::move(fn));
                fn = nullptr;
            }
        }
        if (fn == nullptr) {
            wake_.notify_one();
            return;
        }
        if (std::uint64_t left_out = 0; full_log_.allow(base::monotonic_ns(), left_out))
            log_.warn("web view: {} connections wait for its {} workers; new ones wait in the kernel until one is "
                      "served ({} more times since the last warning)",
                      kMaxWaitingConnections, kWorkers, left_out);
        fn();
    }
    void shutdown() override
    {
        {
            std::lock_guard lock(mutex_);
            stop_ = true;
        }
        wake_.notify_all();
        for (std::thread& t : threads_)
            t.join();
    }

private:
    void run()
    {
        for (;;) {
            std::function<void()> job;
            {
                std::unique_lock lock(mutex_);
                wake_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
                if (jobs_.empty())
                    return;
                job = std::move(jobs_.front());
                jobs_.pop_front();
            }
            job();
        }
    }
    spdlog::logger& log_;
    base::LogThrottle full_log_{60'000'000'000};   // the listening thread's
    std::mutex mutex_;
    std::condition_variable wake_;
    std::deque<std::function<void()>> jobs_;
    bool stop_ = false;
    std::vector<std::thread> threads_;
};

// Box-filter downscale, serial on purpose: cv::resize hands its rows to
// OpenCV's worker pool (TBB), whose threads are shared with the processing
// thread's OpenCV calls and run at its priority, not this thread's.
void downscale(const cv::Mat& in, cv::Mat& out, int width_px)
{
    const int height_px = std::max(1, static_cast<int>(static_cast<long>(in.rows) * width_px / in.cols));
    out.create(height_px, width_px, CV_8UC3);
    for (int y = 0; y < height_px; ++y) {
        const int y0 = y * in.rows / height_px, y1 = std::max(y0 + 1, (y + 1) * in.rows / height_px);
        unsigned char* o = out.ptr<unsigned char>(y);
        for (int x = 0; x < width_px; ++x) {
            const int x0 = x * in.cols / width_px, x1 = std::max(x0 + 1, (x + 1) * in.cols / width_px);
            unsigned sum[3] = {0, 0, 0};
            for (int yy = y0; yy < y1; ++yy) {
                const unsigned char* p = in.ptr<unsigned char>(yy) + 3 * x0;
                for (int xx = x0; xx < x1; ++xx, p += 3) {
                    sum[0] += p[0];
                    sum[1] += p[1];
                    sum[2] += p[2];
                }
            }
            const unsigned n = static_cast<unsigned>((y1 - y0) * (x1 - x0));
            for (int c = 0; c < 3; ++c)
                o[3 * x + c] = static_cast<unsigned char>((sum[c] + n / 2) / n);
        }
    }
}

const cv::Scalar kCrop(255, 200, 0);    // BGR: light blue
const cv::Scalar kWeed(255, 0, 255);    // magenta
const cv::Scalar kSent(0, 230, 0);      // green: TARGET sent
const cv::Scalar kSpared(160, 160, 160);   // grey: policy, no tool, disabled
const cv::Scalar kMissed(0, 0, 255);    // red: deadline, bus, no odometry

// Targets kept to draw: more than fit in one view.
constexpr std::size_t kRecentTargets = 64;

const cv::Scalar& target_colour(runtime::MapReason reason)
{
    using runtime::MapReason;
    switch (reason) {
    case MapReason::sent: return kSent;
    case MapReason::policy:
    case MapReason::no_tool:
    case MapReason::disabled: return kSpared;
    default: return kMissed;
    }
}

}  // namespace

struct WebServer::Impl {
    runtime::WebConfig config;
    runtime::ListenAddress address;
    WebSources sources;
    std::shared_ptr<spdlog::logger> log;
    void (*thread_start)() = nullptr;
    httplib::Server server;
    std::thread listener;
    std::atomic<bool> serving{false};
    std::atomic<bool> listener_done{false};
    std::atomic<int> port{0};
    std::atomic<std::uint64_t> requests{0};
    std::atomic<std::uint64_t> frames_encoded{0};
    std::atomic<std::uint64_t> unauthorized{0};
    std::mutex control_mutex;   // the control's configuration, one change at a time
    std::string failure;   // why it is not serving (set before start() returns)
    const std::int64_t t_start_ns = base::monotonic_ns();

    // The web threads' own state, behind one mutex (never touched by the
    // real-time threads).
    std::mutex mutex;
    std::vector<unsigned char> jpeg;
    std::uint64_t jpeg_seq = 0;
    bool have_jpeg = false;
    double odom_mm = std::numeric_limits<double>::quiet_NaN();
    std::deque<runtime::LivePlant> plants;
    std::deque<runtime::LiveTarget> targets;
    cv::Mat canvas, scaled;

    Metrics metrics()
    {
        Metrics m = sources.metrics ? sources.metrics() : Metrics{};
        if (sources.feed != nullptr) {
            m.live_frames_published = sources.feed->frames_published();
            m.live_plants_dropped = sources.feed->plants_dropped();
        }
        m.live_frames_encoded = frames_encoded.load(std::memory_order_relaxed);
        m.web_requests = requests.load(std::memory_order_relaxed);
        m.web_unauthorized = unauthorized.load(std::memory_order_relaxed);
        return m;
    }

    // Under `mutex`: the ring's new plants into the last-N list.
    void drain_plants()
    {
        runtime::LivePlant p;
        while (sources.feed != nullptr && sources.feed->pop_plant(p)) {
            plants.push_back(p);
            while (plants.size() > static_cast<std::size_t>(config.plants))
                plants.pop_front();
        }
    }

    // Under `mutex`: each target the actuator decided since, as a square on
    // its stem where the frame saw the ground: sent green, spared grey,
    // missed red.
    void draw_targets(const runtime::LiveFrame& f)
    {
        runtime::LiveTarget t;
        while (sources.feed != nullptr && sources.feed->pop_target(t)) {
            targets.push_back(t);
            while (targets.size() > kRecentTargets)
                targets.pop_front();
        }
        if (!sources.camera || targets.empty())
            return;
        // The frame's odometer: its own reading, else the actuator's at the
        // newest target's frame carried on at its speed (a recording
        // without odometer column, constant-speed odometry).
        const runtime::LiveTarget& ref = targets.back();
        const double odom_mm = std::isfinite(f.odom_mm)
                                   ? f.odom_mm
                                   : ref.odom_at_capture_mm +
                                         ref.speed_mm_per_s * static_cast<double>(f.t_sample_ns - ref.t_sample_ns) / 1e9;
        const geometry::Mount& mount = sources.camera->mount();
        for (const runtime::LiveTarget& target : targets) {
            const auto px = sources.camera->ground_to_pixel(mount.x_mm + (target.s_mm - odom_mm), target.y_mm);
            if (!px || px->x < 0 || px->y < 0 || px->x >= canvas.cols || px->y >= canvas.rows)
                continue;
            const cv::Point c(cvRound(px->x), cvRound(px->y));
            const cv::Scalar& colour = target_colour(target.reason);
            cv::rectangle(canvas, c - cv::Point(20, 20), c + cv::Point(20, 20), colour, 4, cv::LINE_AA);
            char label[48];
            std::snprintf(label, sizeof label, "T%u %s", static_cast<unsigned>(target.target_id),
                          std::string(runtime::to_string(target.reason)).c_str());
            cv::putText(canvas, label, c + cv::Point(24, -24), cv::FONT_HERSHEY_SIMPLEX, 0.7, colour, 2, cv::LINE_AA);
        }
    }

    // Under `mutex`: the newest published frame, drawn and encoded once.
    void encode(const runtime::LiveFrame& f)
    {
        odom_mm = f.odom_mm;
        if (!f.has_image)
            return;
        f.frame->bgr.copyTo(canvas);
        viz::draw_overlay(canvas, f.detections, f.closed);
        for (std::size_t i = 0; f.has_class && i < f.detections.plants.size(); ++i) {
            const vision::Plant& p = f.detections.plants[i];
            if (!p.has_stem || f.plant_class[i] == PlantClass::Unknown)
                continue;
            cv::circle(canvas, cv::Point(cvRound(p.stem.x), cvRound(p.stem.y)), 14,
                       f.plant_class[i] == PlantClass::Crop ? kCrop : kWeed, 3, cv::LINE_AA);
        }
        draw_targets(f);
        const cv::Mat* out = &canvas;
        if (canvas.cols > config.max_width_px) {
            downscale(canvas, scaled, config.max_width_px);
            out = &scaled;
        }
        char label[96];
        std::snprintf(label, sizeof label, "frame %llu", static_cast<unsigned long long>(f.seq));
        cv::putText(*const_cast<cv::Mat*>(out), label, cv::Point(8, 22), cv::FONT_HERSHEY_SIMPLEX, 0.6,
                    cv::Scalar(255, 255, 255), 2, cv::LINE_AA);
        cv::imencode(".jpg", *out, jpeg, {cv::IMWRITE_JPEG_QUALITY, 75});
        jpeg_seq = f.seq;
        have_jpeg = true;
        frames_encoded.fetch_add(1, std::memory_order_relaxed);
    }

    void frame(httplib::Response& res)
    {
        runtime::LiveFeed* feed = sources.feed;
        if (feed == nullptr) {
            res.status = 404;
            return;
        }
        feed->want_frames(base::monotonic_ns());
        std::unique_lock lock(mutex);
        // A first viewer waits (up to 2 s) for the first frame it asked for.
        for (int i = 0; i < 200 && !have_jpeg; ++i) {
            if (feed->take_frame()) {
                encode(feed->frame());
                break;
            }
            lock.unlock();
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
            lock.lock();
        }
        if (feed->take_frame())
            encode(feed->frame());
        if (!have_jpeg) {
            res.status = 503;
            res.set_header("Retry-After", "1");
            res.set_content("no frame yet\n", "text/plain");
            return;
        }
        res.set_header("Cache-Control", "no-store");
        res.set_header("X-Frame-Seq", std::to_string(jpeg_seq));
        res.set_content(reinterpret_cast<const char*>(jpeg.data()), jpeg.size(), "image/jpeg");
    }

    // Who asked, for the log: the peer's address and port.
    static std::string peer(const httplib::Request& req)
    {
        return req.remote_addr + ":" + std::to_string(req.remote_port);
    }

    static void json_reply(httplib::Response& res, int status, const nlohmann::json& body)
    {
        res.status = status;
        res.set_header("Cache-Control", "no-store");
        res.set_content(body.dump(), "application/json");
    }

    // The POST's token; false (401 sent, counted, logged) if wrong or missing.
    bool authorised(const httplib::Request& req, httplib::Response& res)
    {
        if (bearer_matches(req.get_header_value("Authorization"), sources.control->token))
            return true;
        unauthorized.fetch_add(1, std::memory_order_relaxed);
        log->warn("web control: {} {} from {} refused: missing or wrong token", req.method, req.path, peer(req));
        res.set_header("WWW-Authenticate", "Bearer");
        json_reply(res, 401, {{"error", "missing or wrong token (Authorization: Bearer TOKEN)"}});
        return false;
    }

    // The request's JSON object, or nullopt (400 sent).
    static std::optional<nlohmann::json> json_body(const httplib::Request& req, httplib::Response& res)
    {
        nlohmann::json body = nlohmann::json::parse(req.body, nullptr, false);
        if (body.is_discarded() || !body.is_object()) {
            json_reply(res, 400, {{"error", "the body must be a JSON object"}});
            return std::nullopt;
        }
        return body;
    }

    // Under control_mutex.
    nlohmann::json control_json()
    {
        WebControl& c = *sources.control;
        nlohmann::json params = nlohmann::json::array();
        for (const std::string& key : controllable_keys()) {
            const config::KeySpec& spec = *config::find_key(key);
            nlohmann::json p = {{"key", key},
                                {"type", std::string(config::to_string(spec.type))},
                                {"unit", std::string(spec.unit)},
                                {"value", c.config.value_of(key)},
                                {"help", std::string(spec.help)}};
            if (spec.type == config::ValueType::integer || spec.type == config::ValueType::real) {
                p["min"] = spec.min;
                p["max"] = spec.max;
            }
            if (spec.type == config::ValueType::choice)
                p["choices"] = config::list_choices(spec, "|");
            params.push_back(std::move(p));
        }
        const bool disabled = c.disabled ? c.disabled() : false;
        const bool input = c.enable_input ? c.enable_input() : true;
        return {{"operator_disabled", disabled},
                {"enable_input", input},
                {"enabled", input && !disabled},
                {"params", std::move(params)}};
    }

    // A control POST: the token checked, the body parsed as a JSON object,
    // before `handle` sees it.
    template <class Handle>
    void post(const char* path, Handle handle)
    {
        server.Post(path, [this, handle](const httplib::Request& req, httplib::Response& res) {
            if (!authorised(req, res))
                return;
            if (const auto body = json_body(req, res))
                handle(req, res, *body);
        });
    }

    void control_routes()
    {
        server.Get("/api/control", [this](const httplib::Request&, httplib::Response& res) {
            std::lock_guard lock(control_mutex);
            json_reply(res, 200, control_json());
        });
        post("/api/enable", [this](const httplib::Request& req, httplib::Response& res, const nlohmann::json& body) {
            if (!body.contains("enabled") || !body["enabled"].is_boolean()) {
                json_reply(res, 400, {{"error", "expected {\"enabled\": true|false}"}});
                return;
            }
            const bool disable = !body["enabled"].get<bool>();
            std::lock_guard lock(control_mutex);
            WebControl& c = *sources.control;
            const bool was = c.disabled();
            c.set_disabled(disable);
            log->warn("web control: {} {} the operator's disable ({} -> {}){}", peer(req),
                      disable ? "set" : "cleared", was ? "disabled" : "not disabled",
                      disable ? "disabled" : "not disabled",
                      !disable && !c.enable_input() ? "; the enable input is off and keeps the tools off" : "");
            json_reply(res, 200, control_json());
        });
        post("/api/param", [this](const httplib::Request& req, httplib::Response& res, const nlohmann::json& body) {
            const auto key = body.find("key");
            const auto value = body.find("value");
            if (key == body.end() || !key->is_string() || value == body.end() ||
                !(value->is_string() || value->is_number() || value->is_boolean())) {
                json_reply(res, 400, {{"error", "expected {\"key\": \"segment.KEY\" or \"stem.KEY\", \"value\": ...}"}});
                return;
            }
            const std::string text = value->is_string() ? value->get<std::string>() : value->dump();
            std::lock_guard lock(control_mutex);
            WebControl& c = *sources.control;
            const ParamChange change = change_param(c.config, key->get<std::string>(), text);
            if (!change.ok) {
                log->warn("web control: {} asked {}={}: refused: {}", peer(req), key->get<std::string>(), text,
                          change.error);
                json_reply(res, 400, {{"error", change.error}});
                return;
            }
            c.set_params(c.config.settings().daemon.vision);
            log->info("web control: {} changed {}: {} -> {} (from the next frame; not written to any file)",
                      peer(req), key->get<std::string>(), change.old_value, change.new_value);
            json_reply(res, 200, {{"key", key->get<std::string>()}, {"old", change.old_value}, {"value", change.new_value}});
        });
    }

    void routes()
    {
        server.set_payload_max_length(kMaxBodyBytes);
        // SO_REUSEADDR only: httplib's default adds SO_REUSEPORT, with which
        // a second daemon would bind the same port and share the requests
        // instead of being told the port is taken.
        server.set_socket_options([](int sock) {
            const int yes = 1;
            setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
        });
        server.set_read_timeout(5, 0);
        server.set_write_timeout(5, 0);
        server.set_keep_alive_timeout(2);
        server.set_keep_alive_max_count(100);
        server.new_task_queue = [this] { return new WorkerQueue(kWorkers, thread_start, *log); };
        server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
            requests.fetch_add(1, std::memory_order_relaxed);
            if (req.target.size() > kMaxTargetBytes) {
                res.status = 414;
                return httplib::Server::HandlerResponse::Handled;
            }
            if (req.headers.size() > kMaxHeaderCount) {
                res.status = 431;
                return httplib::Server::HandlerResponse::Handled;
            }
            return httplib::Server::HandlerResponse::Unhandled;
        });
        server.set_exception_handler([this](const httplib::Request& req, httplib::Response& res, std::exception_ptr ep) {
            try {
                std::rethrow_exception(ep);
            } catch (const std::exception& e) {
                log->warn("web: {} {}: {}", req.method, req.path, e.what());
            } catch (...) {
                log->warn("web: {} {}: unknown exception", req.method, req.path);
            }
            res.status = 500;
        });
        server.Get("/", [](const httplib::Request&, httplib::Response& res) {
            res.set_header("Cache-Control", "no-store");
            res.set_content(kWebPage, "text/html; charset=utf-8");
        });
        server.Get("/frame.jpg", [this](const httplib::Request&, httplib::Response& res) { frame(res); });
        server.Get("/api/status", [this](const httplib::Request&, httplib::Response& res) {
            const runtime::StatusSnapshot totals = sources.totals ? sources.totals() : runtime::StatusSnapshot{};
            const double uptime_s = static_cast<double>(base::monotonic_ns() - t_start_ns) / 1e9;
            res.set_header("Cache-Control", "no-store");
            res.set_content(status_json(totals, metrics(), uptime_s).dump(), "application/json");
        });
        server.Get("/api/plants", [this](const httplib::Request&, httplib::Response& res) {
            std::lock_guard lock(mutex);
            drain_plants();
            res.set_header("Cache-Control", "no-store");
            res.set_content(plants_json(plants, odom_mm).dump(), "application/json");
        });
        server.Get("/api/config", [this](const httplib::Request&, httplib::Response& res) {
            if (sources.control) {
                std::lock_guard lock(control_mutex);
                json_reply(res, 200, {{"yaml", sources.control->config.to_yaml()}});
                return;
            }
            json_reply(res, 200, {{"yaml", sources.config_yaml}});
        });
        if (sources.control)
            control_routes();
        server.Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
            res.set_content(format_metrics(metrics()), "text/plain; version=0.0.4; charset=utf-8");
        });
    }
};

WebServer::WebServer(const runtime::WebConfig& config, runtime::ListenAddress address, WebSources sources,
                     std::shared_ptr<spdlog::logger> log, void (*thread_start)())
    : impl_(std::make_unique<Impl>())
{
    impl_->config = config;
    impl_->address = std::move(address);
    impl_->sources = std::move(sources);
    impl_->log = std::move(log);
    impl_->thread_start = thread_start;
    impl_->routes();
}

WebServer::~WebServer() { stop(); }

bool WebServer::start()
{
    Impl& s = *impl_;
    errno = 0;
    bool bound = false;
    if (s.address.port == 0) {
        const int port = s.server.bind_to_any_port(s.address.host);
        bound = port > 0;
        if (bound)
            s.port = port;
    } else {
        bound = s.server.bind_to_port(s.address.host, s.address.port);
        if (bound)
            s.port = s.address.port;
    }
    if (!bound) {
        const int err = errno;
        s.failure = s.address.to_string() + ": " + (err != 0 ? std::strerror(err) : "cannot bind") +
                    " (errno " + std::to_string(err) + ")";
        s.log->error("web view: cannot listen on {}; running without it", s.failure);
        return false;
    }
    s.serving = true;
    s.listener = std::thread([&s] {
        if (s.thread_start != nullptr)
            s.thread_start();
        lower_priority("stemd-web");
        s.server.listen_after_bind();
        s.listener_done = true;
    });
    runtime::ListenAddress shown = s.address;
    shown.port = s.port;
    s.log->info("web view at http://{}/ (nice {}, {} new frames/s at most, {} px wide)", shown.to_string(), kNice,
                s.config.fps, s.config.max_width_px);
    return true;
}

void WebServer::stop()
{
    if (impl_->listener.joinable()) {
        // httplib's stop() does nothing before its loop runs: wait for it.
        while (!impl_->server.is_running() && !impl_->listener_done)
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
        impl_->server.stop();
        impl_->listener.join();
    }
    impl_->serving = false;
}

bool WebServer::serving() const { return impl_->serving.load(); }
int WebServer::port() const { return impl_->port.load(); }
std::uint64_t WebServer::requests() const { return impl_->requests.load(std::memory_order_relaxed); }

std::string WebServer::status_text() const
{
    if (!serving())
        return "web not serving" + (impl_->failure.empty() ? std::string() : " (" + impl_->failure + ")");
    runtime::ListenAddress shown = impl_->address;
    shown.port = port();
    return "web http://" + shown.to_string() + "/ " + std::to_string(requests()) + " requests";
}

}  // namespace stemd::web
