// The live view's control: the token file, the bearer check, which keys may
// change and how the schema checks them, and the endpoints on a loopback
// server (absent without a token, 401 without the right one).
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>

#include <httplib.h>
#include <nlohmann/json.hpp>

#include "stemd/runtime/logging.hpp"
#include "stemd/web/web_control.hpp"
#include "stemd/web/web_server.hpp"

using namespace stemd;

namespace {

const std::string kToken = "0123456789abcdef-secret";

struct TempDir {
    std::filesystem::path path;
    TempDir()
    {
        char pattern[] = "/tmp/stemd-web-control-XXXXXX";
        path = mkdtemp(pattern);
    }
    ~TempDir() { std::filesystem::remove_all(path); }
    std::string write(const std::string& name, const std::string& text, mode_t mode) const
    {
        const std::filesystem::path file = path / name;
        std::ofstream(file) << text;
        chmod(file.c_str(), mode);
        return file.string();
    }
};

}  // namespace

TEST(WebToken, ReadsTheFirstLineTrimmed)
{
    TempDir dir;
    std::string error;
    const auto token = web::read_token_file(dir.write("t", "  " + kToken + "\n", 0600), error);
    ASSERT_TRUE(token) << error;
    EXPECT_EQ(*token, kToken);
}

TEST(WebToken, RefusesMissingEmptyShortAndSharedFiles)
{
    TempDir dir;
    std::string error;
    EXPECT_FALSE(web::read_token_file((dir.path / "absent").string(), error));
    EXPECT_NE(error.find("No such file"), std::string::npos) << error;
    EXPECT_FALSE(web::read_token_file(dir.write("empty", "", 0600), error));
    EXPECT_NE(error.find("empty"), std::string::npos) << error;
    EXPECT_FALSE(web::read_token_file(dir.write("blank", " \n", 0600), error));
    EXPECT_NE(error.find("at least 16"), std::string::npos) << error;
    EXPECT_FALSE(web::read_token_file(dir.write("short", "abc123\n", 0600), error));
    EXPECT_NE(error.find("has 6 characters"), std::string::npos) << error;
    EXPECT_FALSE(web::read_token_file(dir.write("shared", kToken, 0640), error));
    EXPECT_NE(error.find("mode 0640"), std::string::npos) << error;
    EXPECT_FALSE(web::read_token_file(dir.path.string(), error));
    EXPECT_NE(error.find("not a regular file"), std::string::npos) << error;
    // A FIFO no one writes, even at mode 600: refused at once, never waited on.
    const std::filesystem::path fifo = dir.path / "fifo";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    EXPECT_FALSE(web::read_token_file(fifo.string(), error));
    EXPECT_EQ(error, fifo.string() + ": not a regular file");
}

TEST(WebToken, BearerMatchesOnlyTheExactToken)
{
    EXPECT_TRUE(web::bearer_matches("Bearer " + kToken, kToken));
    EXPECT_FALSE(web::bearer_matches("", kToken));
    EXPECT_FALSE(web::bearer_matches(kToken, kToken)) << "no scheme";
    EXPECT_FALSE(web::bearer_matches("Basic " + kToken, kToken));
    EXPECT_FALSE(web::bearer_matches("Bearer " + kToken.substr(0, kToken.size() - 1), kToken)) << "a prefix";
    EXPECT_FALSE(web::bearer_matches("Bearer " + kToken + "x", kToken)) << "longer";
    std::string last = kToken;
    last.back() = 'X';
    EXPECT_FALSE(web::bearer_matches("Bearer " + last, kToken));
    std::string first = kToken;
    first.front() = 'X';
    EXPECT_FALSE(web::bearer_matches("Bearer " + first, kToken));
    EXPECT_FALSE(web::bearer_matches("Bearer ", "")) << "an empty token matches nothing";
}

TEST(WebParams, OnlySegmentAndStemKeysThatSizeNothing)
{
    EXPECT_TRUE(web::is_controllable("segment.soil_sigmas"));
    EXPECT_TRUE(web::is_controllable("segment.threshold"));
    EXPECT_TRUE(web::is_controllable("stem.min_confidence"));
    EXPECT_TRUE(web::is_controllable("stem.method"));
    EXPECT_FALSE(web::is_controllable("segment.method"));
    EXPECT_FALSE(web::is_controllable("segment.opening_radius_px"));
    EXPECT_FALSE(web::is_controllable("segment.edge_radius_px"));
    EXPECT_FALSE(web::is_controllable("closing.radius_px"));
    EXPECT_FALSE(web::is_controllable("web.listen"));
    EXPECT_FALSE(web::is_controllable("segment.nope"));
    for (const std::string& key : web::controllable_keys())
        EXPECT_TRUE(web::is_controllable(key)) << key;
    EXPECT_FALSE(web::controllable_keys().empty());
}

TEST(WebParams, ChangesGoThroughTheSchemasChecks)
{
    config::Config config;
    const double before = config.settings().daemon.vision.soil_sigmas;
    const web::ParamChange ok = web::change_param(config, "segment.soil_sigmas", "7.5");
    ASSERT_TRUE(ok.ok) << ok.error;
    EXPECT_EQ(ok.old_value, config::format_number(before));
    EXPECT_EQ(ok.new_value, "7.5");
    EXPECT_EQ(config.settings().daemon.vision.soil_sigmas, 7.5);
    // /api/config tells a change made through the view from one on stemd's
    // command line.
    EXPECT_EQ(config.origin_of("segment.soil_sigmas"), "web");
    EXPECT_NE(config.to_yaml().find("soil_sigmas: 7.5  # "), std::string::npos);
    EXPECT_NE(config.to_yaml().find("; web\n"), std::string::npos) << config.to_yaml();
    EXPECT_EQ(config.origin_of("segment.min_class_separation"), "default") << "only the changed key";

    const config::KeySpec& spec = *config::find_key("segment.soil_sigmas");
    const std::string range = "[" + config::format_number(spec.min) + ", " + config::format_number(spec.max) + "]";
    const web::ParamChange high = web::change_param(config, "segment.soil_sigmas", "1000");
    EXPECT_FALSE(high.ok);
    EXPECT_NE(high.error.find(range), std::string::npos) << high.error;
    EXPECT_EQ(config.settings().daemon.vision.soil_sigmas, 7.5) << "a refused value changes nothing";

    EXPECT_FALSE(web::change_param(config, "stem.min_leaves", "3.5").ok) << "an integer key";
    EXPECT_FALSE(web::change_param(config, "stem.method", "magic").ok) << "not one of the choices";
    EXPECT_FALSE(web::change_param(config, "segment.method", "exg").ok);
    EXPECT_TRUE(web::change_param(config, "stem.method", "paper").ok);
    EXPECT_EQ(config.settings().daemon.vision.stem_estimator, vision::StemEstimator::paper);
}

namespace {

struct ControlServer {
    std::atomic<bool> disabled{false};
    std::atomic<int> params_set{0};
    std::atomic<double> min_confidence{-1};
    std::unique_ptr<web::WebServer> server;

    explicit ControlServer(bool with_token)
    {
        web::WebSources sources;
        sources.config_yaml = "read-only\n";
        if (with_token)
            sources.control = web::WebControl{
                .token = kToken,
                .config = config::Config{},
                .set_params =
                    [this](const vision::Params& p) {
                        min_confidence = p.min_confidence;
                        ++params_set;
                    },
                .set_disabled = [this](bool d) { disabled = d; },
                .disabled = [this] { return disabled.load(); },
                .enable_input = [] { return true; }};
        server = std::make_unique<web::WebServer>(runtime::WebConfig{}, runtime::ListenAddress{"127.0.0.1", 0},
                                                  std::move(sources), runtime::make_logger("web"));
        EXPECT_TRUE(server->start());
    }
    httplib::Client client(bool authorised) const
    {
        httplib::Client c("127.0.0.1", server->port());
        c.set_read_timeout(10, 0);
        if (authorised)
            c.set_bearer_token_auth(kToken.c_str());
        return c;
    }
};

}  // namespace

TEST(WebControlEndpoints, AbsentWithoutAToken)
{
    ControlServer s(false);
    auto c = s.client(true);
    for (const char* path : {"/api/enable", "/api/param"}) {
        const auto res = c.Post(path, R"({"enabled": false})", "application/json");
        ASSERT_TRUE(res) << path;
        EXPECT_EQ(res->status, 404) << path;
    }
    const auto info = c.Get("/api/control");
    ASSERT_TRUE(info);
    EXPECT_EQ(info->status, 404);
    EXPECT_FALSE(s.disabled);
}

TEST(WebControlEndpoints, RefusedWithoutTheTokenAndCounted)
{
    ControlServer s(true);
    auto anonymous = s.client(false);
    const auto res = anonymous.Post("/api/enable", R"({"enabled": false})", "application/json");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 401);
    httplib::Client wrong("127.0.0.1", s.server->port());
    wrong.set_bearer_token_auth("0123456789abcdef-secreT");
    const auto res2 = wrong.Post("/api/param", R"({"key": "stem.min_confidence", "value": 0.2})", "application/json");
    ASSERT_TRUE(res2);
    EXPECT_EQ(res2->status, 401);
    EXPECT_FALSE(s.disabled);
    EXPECT_EQ(s.params_set, 0);
    const auto metrics = anonymous.Get("/metrics");
    ASSERT_TRUE(metrics);
    EXPECT_NE(metrics->body.find("\nstemd_web_unauthorized_total 2\n"), std::string::npos);
}

TEST(WebControlEndpoints, DisableAndParametersWithTheToken)
{
    ControlServer s(true);
    auto c = s.client(true);
    const auto off = c.Post("/api/enable", R"({"enabled": false})", "application/json");
    ASSERT_TRUE(off);
    EXPECT_EQ(off->status, 200);
    EXPECT_TRUE(s.disabled);
    EXPECT_EQ(nlohmann::json::parse(off->body).at("enabled"), false);
    const auto on = c.Post("/api/enable", R"({"enabled": true})", "application/json");
    ASSERT_TRUE(on);
    EXPECT_FALSE(s.disabled);

    const auto set = c.Post("/api/param", R"({"key": "stem.min_confidence", "value": 0.25})", "application/json");
    ASSERT_TRUE(set);
    EXPECT_EQ(set->status, 200) << set->body;
    EXPECT_EQ(s.params_set, 1);
    EXPECT_EQ(s.min_confidence, 0.25);
    const auto config = c.Get("/api/config");
    ASSERT_TRUE(config);
    EXPECT_NE(nlohmann::json::parse(config->body).at("yaml").get<std::string>().find("min_confidence: 0.25"),
              std::string::npos);

    const auto out = c.Post("/api/param", R"({"key": "stem.min_confidence", "value": 2})", "application/json");
    ASSERT_TRUE(out);
    EXPECT_EQ(out->status, 400);
    EXPECT_NE(nlohmann::json::parse(out->body).at("error").get<std::string>().find("[0, 1]"), std::string::npos)
        << out->body;
    EXPECT_EQ(s.params_set, 1) << "a refused value reaches nothing";

    for (const char* body : {"not json", "[1]", R"({"key": "stem.min_confidence"})", R"({"key": 5, "value": 1})"}) {
        const auto bad = c.Post("/api/param", body, "application/json");
        ASSERT_TRUE(bad) << body;
        EXPECT_EQ(bad->status, 400) << body;
    }
    const auto bad_enable = c.Post("/api/enable", R"({"enabled": "no"})", "application/json");
    ASSERT_TRUE(bad_enable);
    EXPECT_EQ(bad_enable->status, 400);
    EXPECT_FALSE(s.disabled);

    const auto info = c.Get("/api/control");
    ASSERT_TRUE(info);
    const auto j = nlohmann::json::parse(info->body);
    bool found = false;
    for (const auto& p : j.at("params"))
        if (p.at("key") == "stem.min_confidence") {
            found = true;
            EXPECT_EQ(p.at("value"), "0.25");
            EXPECT_EQ(p.at("min"), 0.0);
            EXPECT_EQ(p.at("max"), 1.0);
        }
    EXPECT_TRUE(found);
}
