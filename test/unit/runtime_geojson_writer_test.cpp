// The GeoJSON writer thread: it rewrites the document from the growing
// plant map, the file parses as a whole document whenever a reader opens
// it, and a process killed in the middle of rewriting leaves a whole one.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>
#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>

#include "stemd/base/clock.hpp"
#include "stemd/runtime/geojson_writer.hpp"

using namespace stemd;
using namespace stemd::runtime;

namespace {

std::shared_ptr<spdlog::logger> quiet()
{
    return std::make_shared<spdlog::logger>("geojson", std::make_shared<spdlog::sinks::null_sink_mt>());
}

std::filesystem::path temp_dir(const char* name)
{
    const auto dir = std::filesystem::temp_directory_path() /
                     ("stemd-geojson-" + std::string(name) + "-" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

void append_plants(const std::filesystem::path& map, int first, int n)
{
    std::ofstream m(map, std::ios::app);
    for (int i = first; i < first + n; ++i)
        m << R"({"id":)" << i % 4096 << R"(,"s_mm":)" << i * 10.0
          << R"(,"y_mm":-5.0,"class":"weed","leaves":4,"sightings":5,"first_frame":1,"last_frame":5,)"
             R"("treated":true,"reason":"sent","lat_deg":50.6255,"lon_deg":6.9912,"georef":"fix",)"
             R"("gnss_mode":"3d","gnss_status":"rtk_fixed","eph_mm":11.0})"
          << "\n";
}

// The document's feature count; -1 when the file is there but not a whole
// GeoJSON document, -2 when it is not there.
long features_in(const std::filesystem::path& p)
{
    std::ifstream in(p);
    if (!in)
        return -2;
    std::stringstream text;
    text << in.rdbuf();
    const auto doc = nlohmann::json::parse(text.str(), nullptr, false);
    if (doc.is_discarded() || !doc.is_object() || doc.value("type", "") != "FeatureCollection" ||
        !doc.contains("features") || !doc["features"].is_array())
        return -1;
    return static_cast<long>(doc["features"].size());
}

// Polls (bounded) until pred() holds.
template <typename Pred>
bool within_20_s(Pred pred)
{
    const std::int64_t deadline = base::monotonic_ns() + 20'000'000'000;
    while (base::monotonic_ns() < deadline) {
        if (pred())
            return true;
        base::sleep_for_ns(200'000);
    }
    return false;
}

}  // namespace

TEST(GeojsonWriter, TheFileParsesWheneverItIsReadWhileTheThreadRewritesIt)
{
    const auto dir = temp_dir("read");
    const auto map = dir / "map.jsonl";
    const auto out = dir / "map.geojson";
    append_plants(map, 0, 500);
    GeojsonWriter writer(map, out, std::chrono::nanoseconds(0), quiet());
    writer.start();
    ASSERT_TRUE(within_20_s([&] { return writer.rewrites() > 0; }));
    // The map grows while the thread rewrites back to back: each read sees
    // a whole document, never fewer plants than an earlier read.
    long seen = 0;
    int reads = 0;
    for (int round = 0; round < 8; ++round) {
        append_plants(map, 500 + round * 100, 100);
        const std::uint64_t before = writer.rewrites();
        while (writer.rewrites() < before + 2) {
            const long n = features_in(out);
            ASSERT_GE(n, seen) << "read " << reads << ": not a whole document (-1) or fewer plants";
            seen = n;
            ++reads;
        }
    }
    ASSERT_TRUE(writer.finish());
    EXPECT_EQ(writer.features(), 1300u);
    EXPECT_EQ(features_in(out), 1300);
    EXPECT_FALSE(std::filesystem::exists(dir.string() + "/map.geojson.tmp"));
    std::filesystem::remove_all(dir);
}

TEST(GeojsonWriter, AKillInTheMiddleOfRewritingLeavesAWholeDocument)
{
    const auto dir = temp_dir("kill");
    const auto map = dir / "map.jsonl";
    const auto out = dir / "map.geojson";
    append_plants(map, 0, 5000);   // about 1.5 MB: each rewrite takes a while
    for (int run = 0; run < 3; ++run) {
        std::filesystem::remove(out);
        const pid_t child = ::fork();
        ASSERT_GE(child, 0);
        if (child == 0) {
            GeojsonWriter writer(map, out, std::chrono::nanoseconds(0), quiet());
            writer.start();
            for (;;)
                ::pause();
        }
        // Killed once the document has been replaced a few times: the
        // thread is then always in the middle of another rewrite.
        ino_t inode = 0;
        int replaced = 0;
        const bool rewriting = within_20_s([&] {
            struct stat st {};
            if (::stat(out.c_str(), &st) == 0 && st.st_ino != inode) {
                inode = st.st_ino;
                ++replaced;
            }
            return replaced >= 2 + run;
        });
        ::kill(child, SIGKILL);
        int status = 0;
        ::waitpid(child, &status, 0);
        ASSERT_TRUE(rewriting) << "run " << run << ": the writer did not rewrite the file";
        ASSERT_TRUE(WIFSIGNALED(status));
        EXPECT_EQ(features_in(out), 5000) << "run " << run;
    }
    std::filesystem::remove_all(dir);
}
