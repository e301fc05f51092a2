// The external class provider: its messages, the slot table the actuator
// looks maps up in, a map's classes per plant, and the socket provider
// against a peer in this process.
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <functional>
#include <memory>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "stemd/base/clock.hpp"
#include "stemd/base/unique_fd.hpp"
#include "stemd/runtime/class_message.hpp"
#include "stemd/runtime/class_provider.hpp"
#include "stemd/runtime/class_slots.hpp"
#include "stemd/runtime/class_socket.hpp"
#include "runtime_test_util.hpp"
#include "temp_dir_test.hpp"

namespace stemd::runtime {
namespace {

std::vector<std::uint8_t> class_map_packet(std::int64_t t, std::uint32_t w, std::uint32_t h, std::uint8_t fill)
{
    std::vector<std::uint8_t> p(kClassMapHeaderBytes + static_cast<std::size_t>(w) * h, fill);
    encode_class_map_header(t, w, h, std::span<std::uint8_t, kClassMapHeaderBytes>(p.data(), kClassMapHeaderBytes));
    return p;
}

TEST(ClassMessage, FrameMessageRoundTrips)
{
    std::vector<std::uint8_t> buf(kFrameMessageHeaderBytes + kFrameMessageMaxName);
    const std::size_t n = encode_frame_message(
        {.t_capture_ns = -5'000'000'123, .seq = 77, .width = 1296, .height = 966, .name = "rgb/000012.png"}, buf);
    ASSERT_EQ(n, kFrameMessageHeaderBytes + 14);
    // Little-endian on the wire, whatever the host: the magic, then version 1.
    EXPECT_EQ(std::memcmp(buf.data(), "STCM", 4), 0);
    EXPECT_EQ(buf[4], 1);
    EXPECT_EQ(buf[5], 0);
    EXPECT_EQ(buf[24], 1296 & 0xff);
    EXPECT_EQ(buf[25], 1296 >> 8);
    FrameMessage m;
    ASSERT_EQ(parse_frame_message({buf.data(), n}, m), ClassMessageError::ok);
    EXPECT_EQ(m.t_capture_ns, -5'000'000'123);
    EXPECT_EQ(m.seq, 77u);
    EXPECT_EQ(m.width, 1296u);
    EXPECT_EQ(m.height, 966u);
    EXPECT_EQ(m.name, "rgb/000012.png");
    EXPECT_EQ(parse_frame_message({buf.data(), n - 1}, m), ClassMessageError::bad_size);
}

TEST(ClassMessage, ClassMapParses)
{
    const auto p = class_map_packet(123456789, 4, 3, 2);
    ClassMapMessage m;
    ASSERT_EQ(parse_class_map_message(p, 8, 8, m), ClassMessageError::ok);
    EXPECT_EQ(m.t_capture_ns, 123456789);
    EXPECT_EQ(m.width, 4u);
    EXPECT_EQ(m.height, 3u);
    EXPECT_EQ(m.classes, p.data() + kClassMapHeaderBytes);
    EXPECT_EQ(m.classes[11], 2);
}

TEST(ClassMessage, MalformedClassMapsAreRefused)
{
    ClassMapMessage m;
    const auto good = class_map_packet(1, 4, 3, 1);
    auto p = good;
    p[0] = 'X';
    EXPECT_EQ(parse_class_map_message(p, 8, 8, m), ClassMessageError::bad_magic);
    p = good;
    p[4] = 2;
    EXPECT_EQ(parse_class_map_message(p, 8, 8, m), ClassMessageError::bad_version);
    p = good;
    p[6] = static_cast<std::uint8_t>(ClassMessageType::frame);
    EXPECT_EQ(parse_class_map_message(p, 8, 8, m), ClassMessageError::bad_type);
    EXPECT_EQ(parse_class_map_message({good.data(), kClassMapHeaderBytes - 1}, 8, 8, m),
              ClassMessageError::too_short);
    EXPECT_EQ(parse_class_map_message({good.data(), good.size() - 1}, 8, 8, m), ClassMessageError::bad_size);
    p = good;
    p.push_back(0);
    EXPECT_EQ(parse_class_map_message(p, 8, 8, m), ClassMessageError::bad_size);
    EXPECT_EQ(parse_class_map_message(class_map_packet(1, 0, 3, 0), 8, 8, m), ClassMessageError::bad_size);
    EXPECT_EQ(parse_class_map_message(good, 3, 8, m), ClassMessageError::too_large);
    EXPECT_EQ(parse_class_map_message(good, 4, 2, m), ClassMessageError::too_large);
}

TEST(ClassSlotTable, HitGivesTheMapOnceThenMisses)
{
    ClassSlotTable table(4, 64);
    const std::vector<std::uint8_t> map{0, 1, 2, 1, 2, 0};
    ASSERT_TRUE(table.store(1000, 3, 2, map.data(), 1500));
    cv::Mat seen;
    const auto r = table.lookup(1000, 1600, 2000, [&](const cv::Mat& m) { m.copyTo(seen); });
    ASSERT_EQ(r, ClassSlotTable::Lookup::hit);
    ASSERT_EQ(seen.size(), cv::Size(3, 2));
    EXPECT_EQ(seen.at<std::uint8_t>(1, 1), 2);
    EXPECT_EQ(seen.at<std::uint8_t>(0, 1), 1);
    // Taken: the slot is free again.
    EXPECT_EQ(table.lookup(1000, 1600, 2000, [](const cv::Mat&) { FAIL(); }), ClassSlotTable::Lookup::miss);
}

TEST(ClassSlotTable, MissBeforeTheDeadlineExpiredAfter)
{
    ClassSlotTable table(4, 64);
    const std::uint8_t map[1] = {2};
    ASSERT_TRUE(table.store(1000, 1, 1, map, 1100));
    EXPECT_EQ(table.lookup(999, 1500, 2000, [](const cv::Mat&) { FAIL(); }), ClassSlotTable::Lookup::miss);
    EXPECT_EQ(table.lookup(999, 2000, 2000, [](const cv::Mat&) { FAIL(); }), ClassSlotTable::Lookup::expired);
    // A map received after its frame's deadline is not used, even if asked for later.
    ASSERT_TRUE(table.store(3000, 1, 1, map, 4001));
    EXPECT_EQ(table.lookup(3000, 5000, 4000, [](const cv::Mat&) { FAIL(); }), ClassSlotTable::Lookup::expired);
    // The one received in time still is.
    EXPECT_EQ(table.lookup(1000, 5000, 2000, [](const cv::Mat&) {}), ClassSlotTable::Lookup::hit);
}

TEST(ClassSlotTable, AFullTableReplacesTheOldestFrame)
{
    ClassSlotTable table(2, 4);
    const std::uint8_t map[4] = {1, 1, 1, 1};
    ASSERT_TRUE(table.store(300, 2, 2, map, 0));
    ASSERT_TRUE(table.store(100, 2, 2, map, 0));
    ASSERT_TRUE(table.store(200, 2, 2, map, 0));
    EXPECT_EQ(table.lookup(100, 0, 1000, [](const cv::Mat&) {}), ClassSlotTable::Lookup::miss);
    EXPECT_EQ(table.lookup(200, 0, 1000, [](const cv::Mat&) {}), ClassSlotTable::Lookup::hit);
    EXPECT_EQ(table.lookup(300, 0, 1000, [](const cv::Mat&) {}), ClassSlotTable::Lookup::hit);
    // Larger than a slot: refused.
    const std::uint8_t big[6] = {};
    EXPECT_FALSE(table.store(400, 3, 2, big, 0));
}

TEST(ClassSlotTable, AReaderNeverSeesAMapBeingWritten)
{
    // The receiver writes maps (and, now and then, the previous frame's
    // again, into the slot the reader may be reading) while the actuator
    // takes them: each map must come out whole, its bytes and size those of
    // its own frame. The writer keeps at most slots - 1 frames ahead, as a
    // pipeline does, so none is replaced unread.
    constexpr std::int64_t kFrames = 20000;
    ClassSlotTable table(4, 64);
    std::atomic<std::int64_t> taken{0};
    std::thread writer([&] {
        std::uint8_t map[64];
        for (std::int64_t t = 1; t <= kFrames; ++t) {
            while (t - taken.load(std::memory_order_acquire) > 3)
                std::this_thread::yield();
            for (std::int64_t again : {t, t - 1}) {
                if (again < 1 || (again != t && t % 3 != 0))
                    continue;
                std::memset(map, static_cast<int>(again % 251), sizeof map);
                ASSERT_TRUE(table.store(again, 1 + static_cast<int>(again % 8), 8, map, 0));
            }
        }
    });
    long torn = 0;
    for (std::int64_t t = 1; t <= kFrames; ++t) {
        ClassSlotTable::Lookup r;
        while ((r = table.lookup(t, 0, 1, [&](const cv::Mat& m) {
                    const bool whole = m.cols == 1 + static_cast<int>(t % 8) && m.rows == 8 &&
                                       cv::countNonZero(m != static_cast<int>(t % 251)) == 0;
                    torn += !whole;
                })) == ClassSlotTable::Lookup::miss)
            std::this_thread::yield();
        ASSERT_EQ(r, ClassSlotTable::Lookup::hit) << "frame " << t;
        taken.store(t, std::memory_order_release);
    }
    writer.join();
    EXPECT_EQ(torn, 0);
}

vision::Plant plant_at(float x, float y)
{
    vision::Plant p;
    p.stem = {x, y};
    return p;
}

TEST(PlantClassesFromMap, ACoarseMapIsScaledToTheFrame)
{
    // A 400x200 frame, its map at a quarter of that: crop on the left half,
    // weed on the right.
    cv::Mat map(50, 100, CV_8UC1, cv::Scalar(1));
    map(cv::Rect(50, 0, 50, 50)).setTo(2);
    vision::Detections d;
    d.plants.push_back(plant_at(40, 100));
    d.plants.push_back(plant_at(360, 20));
    vision::Plant stemless = plant_at(360, 20);
    stemless.has_stem = false;
    d.plants.push_back(stemless);
    std::array<PlantClass, vision::kMaxPlants> out{};
    EXPECT_EQ(plant_classes_from_map(map, {400, 200}, d, out), 0u);
    EXPECT_EQ(out[0], PlantClass::Crop);
    EXPECT_EQ(out[1], PlantClass::Weed);
    EXPECT_EQ(out[2], PlantClass::Unknown);
    // Values that are no class are counted.
    map.setTo(7);
    EXPECT_EQ(plant_classes_from_map(map, {400, 200}, d, out), 2u);
    EXPECT_EQ(out[0], PlantClass::Unknown);
}

bool wait_for(const std::function<bool()>& done) { return test::wait_for(done, std::chrono::seconds(10)); }

class SocketClassProviderTest : public test::TempDirTest {
protected:
    base::UniqueFd connect_peer()
    {
        base::UniqueFd fd(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0));
        sockaddr_un addr{};
        addr.sun_family = AF_UNIX;
        const std::string path = socket_path();
        std::memcpy(addr.sun_path, path.data(), path.size());
        EXPECT_EQ(::connect(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)), 0)
            << std::strerror(errno);
        return fd;
    }
    // The next frame message the peer gets, within a deadline.
    bool next_frame(int fd, FrameMessage& out, std::vector<std::uint8_t>& buf)
    {
        pollfd p{.fd = fd, .events = POLLIN, .revents = 0};
        if (::poll(&p, 1, 10'000) != 1)
            return false;
        buf.resize(kFrameMessageHeaderBytes + kFrameMessageMaxName);
        const ssize_t n = ::recv(fd, buf.data(), buf.size(), 0);
        return n > 0 && parse_frame_message({buf.data(), static_cast<std::size_t>(n)}, out) == ClassMessageError::ok;
    }
    std::string socket_path() const { return (dir_ / "classes.sock").string(); }

    static drivers::Frame frame_at(std::int64_t t_ns, std::uint64_t seq, std::string_view name)
    {
        drivers::Frame f;
        f.t_sample_ns = t_ns;
        f.seq = seq;
        f.name.assign(name);
        return f;
    }
};

TEST_F(SocketClassProviderTest, ServesMapsCountsBadOnesTimesOutAndTakesAPeerAgain)
{
    const cv::Size frame_size(400, 200);
    SocketClassProvider provider(socket_path(), frame_size, 60'000);   // a long timeout: only misses expire
    ASSERT_TRUE(provider.start());
    base::UniqueFd peer = connect_peer();
    ASSERT_TRUE(wait_for([&] { return provider.peer_connected(); }));

    const std::int64_t t0 = base::monotonic_ns();
    provider.on_capture(frame_at(t0, 0, "rgb/000000.png"));
    std::vector<std::uint8_t> buf;
    FrameMessage fm;
    ASSERT_TRUE(next_frame(peer.get(), fm, buf));
    EXPECT_EQ(fm.t_capture_ns, t0);
    EXPECT_EQ(fm.seq, 0u);
    EXPECT_EQ(fm.width, 400u);
    EXPECT_EQ(fm.height, 200u);
    EXPECT_EQ(fm.name, "rgb/000000.png");

    // Garbage first: dropped and counted, and the provider goes on.
    const std::uint8_t garbage[5] = {'h', 'e', 'l', 'l', 'o'};
    ASSERT_EQ(::send(peer.get(), garbage, sizeof garbage, 0), 5);
    auto map = class_map_packet(t0, 100, 50, 2);   // a quarter-size map, all weed
    map[7] = 9;   // a type that does not exist
    ASSERT_EQ(::send(peer.get(), map.data(), map.size(), 0), static_cast<ssize_t>(map.size()));
    ASSERT_TRUE(wait_for([&] { return provider.counters().bad_messages.load() == 2; }));

    auto result = std::make_unique<FrameResult>();
    result->t_sample_ns = t0;
    result->detections.plants.push_back(plant_at(200, 100));
    provider.classify(drivers::Frame{}, vision::Params{}, vision::Workspace({400, 200}, vision::Params{}), *result);
    EXPECT_TRUE(result->has_class_map);
    ASSERT_TRUE(result->classes_pending);
    EXPECT_FALSE(provider.resolve(*result, base::monotonic_ns()));   // not sent yet: ask again

    map[7] = 0;
    ASSERT_EQ(::send(peer.get(), map.data(), map.size(), 0), static_cast<ssize_t>(map.size()));
    ASSERT_TRUE(wait_for([&] { return provider.resolve(*result, base::monotonic_ns()); }));
    EXPECT_FALSE(result->classes_pending);
    EXPECT_EQ(result->plant_class[0], PlantClass::Weed);
    EXPECT_EQ(provider.counters().maps.load(), 1u);
    EXPECT_EQ(provider.counters().timeouts.load(), 0u);

    // A frame never answered: unknown once its deadline has passed, counted.
    result->t_sample_ns = t0 - 120'000'000'000;
    result->plant_class[0] = PlantClass::Weed;
    result->classes_pending = true;
    EXPECT_TRUE(provider.resolve(*result, base::monotonic_ns()));
    EXPECT_EQ(result->plant_class[0], PlantClass::Unknown);
    EXPECT_EQ(provider.counters().timeouts.load(), 1u);

    // A frame the peer is sent but never answers before hanging up, and one
    // captured while no peer is connected: the next peer gets both (not
    // the frame already answered).
    const std::int64_t t1 = base::monotonic_ns();
    provider.on_capture(frame_at(t1, 1, "rgb/000001.png"));
    ASSERT_TRUE(next_frame(peer.get(), fm, buf));
    EXPECT_EQ(fm.t_capture_ns, t1);
    peer.reset();
    ASSERT_TRUE(wait_for([&] { return !provider.peer_connected(); }));
    const std::int64_t t2 = base::monotonic_ns();
    provider.on_capture(frame_at(t2, 2, "rgb/000002.png"));
    base::UniqueFd again = connect_peer();
    ASSERT_TRUE(wait_for([&] { return provider.peer_connected(); }));
    std::vector<std::int64_t> got;
    while (got.size() < 2) {
        ASSERT_TRUE(next_frame(again.get(), fm, buf));
        got.push_back(fm.t_capture_ns);
    }
    EXPECT_EQ(got, (std::vector<std::int64_t>{t1, t2}));
    EXPECT_EQ(provider.counters().peers.load(), 2u);
    provider.stop();
    EXPECT_FALSE(std::filesystem::exists(socket_path()));
}

TEST_F(SocketClassProviderTest, AnOversizedMapIsDroppedAndCounted)
{
    SocketClassProvider provider(socket_path(), {40, 20}, 1000);
    ASSERT_TRUE(provider.start());
    base::UniqueFd peer = connect_peer();
    const auto map = class_map_packet(5, 41, 20, 1);
    ASSERT_EQ(::send(peer.get(), map.data(), map.size(), 0), static_cast<ssize_t>(map.size()));
    ASSERT_TRUE(wait_for([&] { return provider.counters().bad_messages.load() == 1; }));
    EXPECT_EQ(provider.counters().maps.load(), 0u);
}

TEST_F(SocketClassProviderTest, AStaleSocketFileIsReplacedAndOtherFilesAreNot)
{
    // A socket file left behind, as after a crash: bound, then closed without unlinking.
    {
        base::UniqueFd stale(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0));
        sockaddr_un addr{};
        addr.sun_family = AF_UNIX;
        const std::string path = socket_path();
        std::memcpy(addr.sun_path, path.data(), path.size());
        ASSERT_EQ(::bind(stale.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)), 0);
    }
    {
        SocketClassProvider provider(socket_path(), {40, 20}, 1000);
        EXPECT_TRUE(provider.start());
        base::UniqueFd peer = connect_peer();
        EXPECT_TRUE(wait_for([&] { return provider.peer_connected(); }));
    }
    // Anything else at the path is not stemd's to remove.
    write("not a socket", "classes.sock");
    SocketClassProvider blocked(socket_path(), {40, 20}, 1000);
    EXPECT_FALSE(blocked.start());
    EXPECT_TRUE(std::filesystem::exists(socket_path()));
}

}  // namespace
}  // namespace stemd::runtime
