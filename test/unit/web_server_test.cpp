// The live view's server against a loopback socket on a free port: the
// endpoints' answers and shapes, and the requests it must refuse.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <random>
#include <regex>
#include <string>

#include <httplib.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "stemd/geometry/field.hpp"
#include "stemd/runtime/live_feed.hpp"
#include "stemd/runtime/logging.hpp"
#include "stemd/web/web_server.hpp"

using namespace stemd;

namespace {

const cv::Size kSize(800, 600);

struct Fixture : ::testing::Test {
    // Lent to the feed, so it outlives the server.
    drivers::Frame frame;
    runtime::LiveFeed feed{runtime::FrameShape{kSize}, 30, 16};
    std::unique_ptr<web::WebServer> server;

    void SetUp() override
    {
        runtime::WebConfig config;
        config.max_width_px = 400;
        config.plants = 3;
        web::WebSources sources{.feed = &feed,
                                .totals = [] {
                                    runtime::StatusSnapshot s;
                                    s.frames_in = 42;
                                    s.frames_out = 41;
                                    s.ring_full = 1;
                                    s.files = true;
                                    s.file_lines_written = 812;
                                    s.file_lines_lost = 3;
                                    return s;
                                },
                                .metrics = [] {
                                    web::Metrics m;
                                    m.frames_in = 42;
                                    return m;
                                },
                                .config_yaml = "web:\n  listen: 127.0.0.1:0\n",
                                .control = std::nullopt,
                                .camera = std::nullopt};
        server = std::make_unique<web::WebServer>(config, runtime::ListenAddress{"127.0.0.1", 0}, std::move(sources),
                                                  runtime::make_logger("web"));
        ASSERT_TRUE(server->start());
        ASSERT_GT(server->port(), 0);
    }

    httplib::Client client() const
    {
        httplib::Client c("127.0.0.1", server->port());
        c.set_read_timeout(10, 0);
        return c;
    }

    void publish_frame()
    {
        frame.bgr = cv::Mat(kSize, CV_8UC3, cv::Scalar(40, 60, 80));
        frame.seq = 9;
        vision::Detections detections;
        vision::Plant plant;
        plant.stem = {200, 150};
        plant.bbox = {180, 130, 40, 40};
        detections.plants.push_back(plant);
        vision::BitMask closed(kSize.width, kSize.height);
        const PlantClass classes[1] = {PlantClass::Weed};
        feed.publish(&frame, detections, closed, classes, true, 1);
    }

    // Sends raw bytes, returns the status line (or "" if the server closed).
    std::string raw(const std::string& request) const
    {
        const int fd = socket(AF_INET, SOCK_STREAM, 0);
        sockaddr_in addr{};
        addr.sin_family = AF_INET;
        addr.sin_port = htons(static_cast<std::uint16_t>(server->port()));
        addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        if (connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
            close(fd);
            return "connect failed";
        }
        std::size_t sent = 0;
        while (sent < request.size()) {
            const ssize_t n = send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
            if (n <= 0)
                break;
            sent += static_cast<std::size_t>(n);
        }
        shutdown(fd, SHUT_WR);
        std::string reply;
        char buffer[4096];
        for (ssize_t n; (n = recv(fd, buffer, sizeof buffer, 0)) > 0;)
            reply.append(buffer, static_cast<std::size_t>(n));
        close(fd);
        return reply.substr(0, reply.find("\r\n"));
    }
};

}  // namespace

TEST_F(Fixture, ThePageIsSelfContained)
{
    auto c = client();
    const auto res = c.Get("/");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200);
    EXPECT_NE(res->get_header_value("Content-Type").find("text/html"), std::string::npos);
    EXPECT_NE(res->body.find("<img id=\"frame\""), std::string::npos);
    // No resource from another host: no absolute URL at all, and no
    // protocol-relative one in a src or href.
    EXPECT_EQ(std::regex_search(res->body, std::regex("https?://")), false);
    EXPECT_EQ(std::regex_search(res->body, std::regex("(src|href)\\s*=\\s*[\"']//")), false);
}

TEST_F(Fixture, UnknownPathsAre404)
{
    auto c = client();
    for (const char* path : {"/nope", "/api", "/api/statusx", "/frame.png", "/../etc/passwd"}) {
        const auto res = c.Get(path);
        ASSERT_TRUE(res) << path;
        EXPECT_EQ(res->status, 404) << path;
    }
    const auto post = c.Post("/api/status", "x", "text/plain");
    ASSERT_TRUE(post);
    EXPECT_EQ(post->status, 404) << "read-only: no POST route";
}

TEST_F(Fixture, OversizedAndMalformedRequestsAreRefused)
{
    auto c = client();
    const auto big = c.Post("/", std::string(200 * 1024, 'x'), "text/plain");
    ASSERT_TRUE(big);
    EXPECT_EQ(big->status, 413);
    const auto long_uri = c.Get((std::string("/").append(4000, 'a')).c_str());
    ASSERT_TRUE(long_uri);
    EXPECT_EQ(long_uri->status, 414);
    httplib::Headers many;
    for (int i = 0; i < 100; ++i)
        many.emplace(std::string("X-H").append(std::to_string(i)), "v");
    const auto headers = c.Get("/api/status", many);
    ASSERT_TRUE(headers);
    EXPECT_EQ(headers->status, 431);
    // Not HTTP at all, a request line without a version: httplib answers
    // 400, or closes the connection first when it sees the client's end of
    // stream (which one depends on timing).
    const auto refused = [](const std::string& status) { return status.empty() || status == "HTTP/1.1 400 Bad Request"; };
    EXPECT_PRED1(refused, raw("GARBAGE\r\n\r\n"));
    EXPECT_PRED1(refused, raw("GET /\r\n\r\n"));
    // A header line without a colon: httplib 0.11 drops the line, so the
    // request is an ordinary GET of the page (about 2 in 100 answered 200;
    // otherwise closed at the client's end of stream). It never becomes a
    // header, and nothing fails.
    const auto dropped_line = [&refused](const std::string& status) { return refused(status) || status == "HTTP/1.1 200 OK"; };
    EXPECT_PRED1(dropped_line, raw("GET / HTTP/1.1\r\nno colon here\r\n\r\n"));
    // A header line longer than the library's 8 KiB line limit.
    const std::string huge = raw(std::string("GET / HTTP/1.1\r\nHost: x\r\nX-Big: ").append(64 * 1024, 'h').append("\r\n\r\n"));
    EXPECT_NE(huge.substr(0, 12), "HTTP/1.1 200") << huge;
    // The server is still up.
    const auto after = c.Get("/api/status");
    ASSERT_TRUE(after);
    EXPECT_EQ(after->status, 200);
}

TEST_F(Fixture, StatusJsonHasTheCountersAndHistograms)
{
    auto c = client();
    const auto res = c.Get("/api/status");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200);
    const auto j = nlohmann::json::parse(res->body);
    EXPECT_EQ(j.at("frames_in"), 42);
    EXPECT_EQ(j.at("frames_out"), 41);
    EXPECT_EQ(j.at("drops").at("ring_full"), 1);
    for (const char* cause : {"overwritten", "results_full", "corrupt", "bad_size", "failed"})
        EXPECT_TRUE(j.at("drops").contains(cause)) << cause;
    EXPECT_TRUE(j.at("actuation").is_null());
    EXPECT_TRUE(j.at("trigger").is_null());
    EXPECT_EQ(j.at("files").at("lines_written"), 812);
    EXPECT_EQ(j.at("files").at("lines_lost"), 3);
    const auto& h = j.at("histograms").at("capture_to_result");
    EXPECT_EQ(h.at("counts").size(), h.at("le_ms").size() + 1) << "one bucket beyond the last bound";
    EXPECT_TRUE(j.at("latency_ms").contains("p99"));
    EXPECT_GE(j.at("live").at("requests").get<int>(), 1);
}

TEST_F(Fixture, FrameIsAScaledJpegOfTheLatestPublication)
{
    auto c = client();
    publish_frame();
    const auto res = c.Get("/frame.jpg");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200);
    EXPECT_EQ(res->get_header_value("Content-Type"), "image/jpeg");
    EXPECT_EQ(res->get_header_value("X-Frame-Seq"), "9");
    const std::vector<unsigned char> bytes(res->body.begin(), res->body.end());
    const cv::Mat image = cv::imdecode(bytes, cv::IMREAD_COLOR);
    ASSERT_FALSE(image.empty());
    EXPECT_EQ(image.cols, 400) << "web.max_width_px";
    EXPECT_EQ(image.rows, 300);
}

TEST_F(Fixture, PlantsJsonKeepsTheLastN)
{
    for (int i = 0; i < 5; ++i) {
        runtime::LivePlant p;
        p.id = i;
        p.s_mm = 100.0 * i;
        p.y_mm = -5;
        p.plant_class = PlantClass::Weed;
        p.entry.reason = i == 4 ? runtime::MapReason::deadline_miss : runtime::MapReason::sent;
        p.entry.has_tool = i != 4;
        ASSERT_TRUE(feed.push_plant(p));
    }
    auto c = client();
    const auto res = c.Get("/api/plants");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200);
    const auto j = nlohmann::json::parse(res->body);
    const auto& plants = j.at("plants");
    ASSERT_EQ(plants.size(), 3u) << "web.plants";
    EXPECT_EQ(plants[0].at("id"), 2);
    EXPECT_EQ(plants[2].at("id"), 4);
    EXPECT_EQ(plants[2].at("treated"), false);
    EXPECT_EQ(plants[2].at("reason"), "deadline_miss");
    EXPECT_FALSE(plants[2].contains("tool"));
    EXPECT_EQ(plants[1].at("treated"), true);
    EXPECT_EQ(plants[1].at("class"), "weed");
    EXPECT_EQ(plants[1].at("tool"), 0);
    EXPECT_TRUE(plants[1].contains("fire_odom_mm"));
}

TEST_F(Fixture, ConfigAndMetricsAreServed)
{
    auto c = client();
    const auto config = c.Get("/api/config");
    ASSERT_TRUE(config);
    EXPECT_EQ(nlohmann::json::parse(config->body).at("yaml"), "web:\n  listen: 127.0.0.1:0\n");
    const auto metrics = c.Get("/metrics");
    ASSERT_TRUE(metrics);
    EXPECT_EQ(metrics->status, 200);
    EXPECT_NE(metrics->get_header_value("Content-Type").find("version=0.0.4"), std::string::npos);
    EXPECT_NE(metrics->body.find("\nstemd_frames_in_total 42\n"), std::string::npos);
}

TEST_F(Fixture, ATakenPortIsReportedAndNotServed)
{
    web::WebServer second(runtime::WebConfig{}, runtime::ListenAddress{"127.0.0.1", server->port()}, {},
                          runtime::make_logger("web"));
    EXPECT_FALSE(second.start());
    EXPECT_FALSE(second.serving());
    const std::string text = second.status_text();
    EXPECT_NE(text.find("not serving"), std::string::npos) << text;
    EXPECT_NE(text.find(std::string("127.0.0.1:").append(std::to_string(server->port()))), std::string::npos) << text;
    EXPECT_NE(text.find(std::string("errno ").append(std::to_string(EADDRINUSE))), std::string::npos) << text;
}

TEST(WebListen, ParsesAddressesAndRefusesTheRest)
{
    std::string error;
    const auto v4 = runtime::parse_listen_address("127.0.0.1:8080", error);
    ASSERT_TRUE(v4);
    EXPECT_EQ(v4->host, "127.0.0.1");
    EXPECT_EQ(v4->port, 8080);
    const auto v6 = runtime::parse_listen_address("[::1]:0", error);
    ASSERT_TRUE(v6);
    EXPECT_EQ(v6->host, "::1");
    EXPECT_EQ(v6->to_string(), "[::1]:0");
    for (const char* bad : {"localhost:8080", "127.0.0.1", "127.0.0.1:", "127.0.0.1:65536", "127.0.0.1:-1",
                            "::1:8080", "[::1]", "1.2.3:80", "127.0.0.1:80x", ""}) {
        error.clear();
        EXPECT_FALSE(runtime::parse_listen_address(bad, error)) << bad;
        EXPECT_FALSE(error.empty()) << bad;
    }
}

TEST_F(Fixture, RandomRequestsNeitherCrashNorStopTheServer)
{
    // A small fuzz of the request parser: mutated valid requests and raw
    // noise, each on its own connection (fixed seed: reproducible). Whether
    // each gets an answer depends on timing (httplib may close first on the
    // client's end of stream); the server must survive them all and still
    // answer a good request afterwards.
    std::mt19937 random(1234);
    const std::string valid = "GET /api/status HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 0\r\n\r\n";
    using namespace std::string_literals;
    const std::string alphabet = "GET/ HTP1.\r\n:\0\xff%?&=ContentLgh-0123456789abc"s;
    for (int i = 0; i < 150; ++i) {
        std::string request;
        if (i % 3 == 0) {
            const std::size_t length = random() % 512;
            for (std::size_t k = 0; k < length; ++k)
                request.push_back(static_cast<char>(random() % 256));
        } else {
            request = valid;
            const int edits = 1 + static_cast<int>(random() % 6);
            for (int e = 0; e < edits; ++e) {
                const std::size_t at = random() % request.size();
                const char c = alphabet[random() % alphabet.size()];
                switch (random() % 3) {
                case 0: request[at] = c; break;
                case 1: request.insert(at, 1, c); break;
                default: request.erase(at, 1 + random() % 8); break;
                }
                if (request.empty())
                    request.push_back('x');
            }
        }
        raw(request);
    }
    auto c = client();
    const auto res = c.Get("/api/status");
    ASSERT_TRUE(res) << "the server stopped answering";
    EXPECT_EQ(res->status, 200);
}

// A target the actuator decided from a stem at pixel P shows on the frame
// as a square around P (field -> pixel undoes pixel -> field), coloured by
// its outcome.
TEST(WebFrameTargets, DrawnWhereTheirStemsWereAndColouredByOutcome)
{
    const auto camera = geometry::CameraModel::nadir(
        {.gsd_mm_per_px = 0.5, .principal_px = geometry::image_centre(kSize), .mount = {}});
    ASSERT_TRUE(camera);
    drivers::Frame frame;   // lent to the feed: outlives the server
    runtime::LiveFeed feed{runtime::FrameShape{kSize}, 30, 16};
    runtime::WebConfig config;
    config.max_width_px = 400;   // half size
    web::WebSources sources;
    sources.feed = &feed;
    sources.camera = *camera;
    web::WebServer server(config, runtime::ListenAddress{"127.0.0.1", 0}, std::move(sources),
                          runtime::make_logger("web"));
    ASSERT_TRUE(server.start());

    constexpr double kOdomMm = 1000;
    const auto target_at = [&](cv::Point2f px, std::uint16_t id, runtime::MapReason reason) {
        const auto field = geometry::field_position(*camera, px, kOdomMm);
        EXPECT_TRUE(field);
        feed.push_target({.target_id = id, .s_mm = field->s_mm, .y_mm = field->y_mm, .reason = reason});
    };
    target_at({200, 150}, 1, runtime::MapReason::sent);
    target_at({600, 450}, 2, runtime::MapReason::disabled);
    target_at({400, 300}, 3, runtime::MapReason::deadline_miss);

    frame.bgr = cv::Mat(kSize, CV_8UC3, cv::Scalar(40, 60, 80));
    frame.seq = 3;
    frame.odom_mm = kOdomMm;
    const vision::BitMask closed(kSize.width, kSize.height);
    feed.publish(&frame, vision::Detections{}, closed, nullptr, false, 1);

    httplib::Client c("127.0.0.1", server.port());
    c.set_read_timeout(10, 0);
    const auto res = c.Get("/frame.jpg");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200);
    const cv::Mat image = cv::imdecode(std::vector<unsigned char>(res->body.begin(), res->body.end()), cv::IMREAD_COLOR);
    ASSERT_EQ(image.cols, 400);
    // Each square's left edge (20 px left of the stem, halved), its centre untouched.
    const auto at = [&](int x, int y) { return image.at<cv::Vec3b>(y / 2, x / 2); };
    const cv::Vec3b sent = at(180, 150), spared = at(580, 450), missed = at(380, 300);
    EXPECT_GT(sent[1], 150);
    EXPECT_LT(sent[0], 100);
    EXPECT_LT(sent[2], 100);
    EXPECT_GT(spared[0], 110);
    EXPECT_GT(spared[1], 110);
    EXPECT_GT(spared[2], 110);
    EXPECT_GT(missed[2], 150);
    EXPECT_LT(missed[1], 100);
    const cv::Vec3b centre = at(200, 150);
    EXPECT_LT(std::abs(centre[1] - 60), 20) << "the stem itself is not painted over";
}
