// A stand-in for an external class provider (a CNN elsewhere), for the
// daemon's end-to-end test: it connects to stemd's classify.socket, and for
// each frame message answers with the recording's own class map for that
// frame (class/NAME for rgb/NAME), scaled down by --scale.
//
//   stemd-test-class-peer SOCKET RECORDING_DIR MODE [--scale N] [--late-ms MS]
//                         [--garbage] [--reconnect-after N]
//   MODE: serve (answer at once), late (answer --late-ms after the frame
//   message came), never (read the frame messages, answer none).
//
// It waits up to 30 s for the socket to take a connection, and exits 0 when
// stemd hangs up, printing "frames N answered N" on stdout.
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "stemd/runtime/class_message.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using stemd::runtime::FrameMessage;

int connect_to(const std::string& path, Clock::duration patience)
{
    const auto end = Clock::now() + patience;
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::memcpy(addr.sun_path, path.data(), std::min(path.size(), sizeof(addr.sun_path) - 1));
    while (Clock::now() < end) {
        const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
        if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) == 0)
            return fd;
        ::close(fd);
        std::this_thread::sleep_for(std::chrono::milliseconds(5));   // the socket is not there yet
    }
    return -1;
}

std::vector<std::uint8_t> answer_for(const FrameMessage& frame, const std::string& dir, int scale)
{
    std::string name(frame.name);
    if (name.rfind("rgb/", 0) == 0)
        name.replace(0, 3, "class");
    const cv::Mat full = cv::imread(dir + "/" + name, cv::IMREAD_UNCHANGED);
    if (full.empty() || full.type() != CV_8UC1) {
        std::fprintf(stderr, "class peer: no class map %s/%s\n", dir.c_str(), name.c_str());
        return {};
    }
    cv::Mat map;
    cv::resize(full, map, cv::Size(full.cols / scale, full.rows / scale), 0, 0, cv::INTER_NEAREST);
    std::vector<std::uint8_t> packet(stemd::runtime::kClassMapHeaderBytes + map.total());
    stemd::runtime::encode_class_map_header(
        frame.t_capture_ns, static_cast<std::uint32_t>(map.cols), static_cast<std::uint32_t>(map.rows),
        std::span<std::uint8_t, stemd::runtime::kClassMapHeaderBytes>(packet.data(),
                                                                      stemd::runtime::kClassMapHeaderBytes));
    for (int y = 0; y < map.rows; ++y)
        std::memcpy(packet.data() + stemd::runtime::kClassMapHeaderBytes + static_cast<std::size_t>(y) * map.cols,
                    map.ptr(y), static_cast<std::size_t>(map.cols));
    return packet;
}

}  // namespace

int main(int argc, char** argv)
{
    if (argc < 4) {
        std::fprintf(stderr, "usage: stemd-test-class-peer SOCKET RECORDING_DIR serve|late|never [--scale N] "
                             "[--late-ms MS] [--garbage] [--reconnect-after N]\n");
        return 2;
    }
    const std::string socket_path = argv[1], dir = argv[2], mode = argv[3];
    int scale = 4;
    long late_ms = 0, reconnect_after = 0;
    bool garbage = false;
    for (int i = 4; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--scale" && i + 1 < argc)
            scale = std::max(1, std::atoi(argv[++i]));
        else if (a == "--late-ms" && i + 1 < argc)
            late_ms = std::atol(argv[++i]);
        else if (a == "--reconnect-after" && i + 1 < argc)
            reconnect_after = std::atol(argv[++i]);
        else if (a == "--garbage")
            garbage = true;
        else {
            std::fprintf(stderr, "class peer: unknown argument %s\n", a.c_str());
            return 2;
        }
    }
    if (mode != "serve" && mode != "late" && mode != "never") {
        std::fprintf(stderr, "class peer: unknown mode %s\n", mode.c_str());
        return 2;
    }
    int fd = connect_to(socket_path, std::chrono::seconds(30));
    if (fd < 0) {
        std::fprintf(stderr, "class peer: cannot connect to %s\n", socket_path.c_str());
        return 1;
    }
    if (garbage) {
        const char junk[] = "not a class map";
        ::send(fd, junk, sizeof junk, MSG_NOSIGNAL);
    }
    struct Due {
        Clock::time_point at;
        std::vector<std::uint8_t> packet;
    };
    std::deque<Due> due;
    long frames = 0, answered = 0, since_connect = 0;
    std::vector<std::uint8_t> buf(stemd::runtime::kFrameMessageHeaderBytes + stemd::runtime::kFrameMessageMaxName);
    for (;;) {
        while (!due.empty() && due.front().at <= Clock::now()) {
            if (::send(fd, due.front().packet.data(), due.front().packet.size(), MSG_NOSIGNAL) > 0)
                ++answered;
            due.pop_front();
        }
        int wait_ms = 1000;
        if (!due.empty())
            wait_ms = static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                           due.front().at - Clock::now()).count()) + 1;
        pollfd p{.fd = fd, .events = POLLIN, .revents = 0};
        if (::poll(&p, 1, std::max(wait_ms, 0)) <= 0)
            continue;
        const ssize_t n = ::recv(fd, buf.data(), buf.size(), 0);
        if (n <= 0)
            break;   // stemd hung up: the run is over
        FrameMessage frame;
        if (stemd::runtime::parse_frame_message({buf.data(), static_cast<std::size_t>(n)}, frame) !=
            stemd::runtime::ClassMessageError::ok) {
            std::fprintf(stderr, "class peer: a malformed frame message\n");
            return 1;
        }
        ++frames;
        if (mode == "never")
            continue;
        std::vector<std::uint8_t> packet = answer_for(frame, dir, scale);
        if (packet.empty())
            return 1;
        const auto at = Clock::now() + std::chrono::milliseconds(mode == "late" ? late_ms : 0);
        due.push_back({at, std::move(packet)});
        if (mode == "serve") {
            if (::send(fd, due.back().packet.data(), due.back().packet.size(), MSG_NOSIGNAL) > 0)
                ++answered;
            due.pop_back();
            if (reconnect_after > 0 && ++since_connect == reconnect_after) {
                // Hang up and come back: stemd must take the peer again and
                // resend the frames still within their timeout.
                ::close(fd);
                since_connect = 0;
                reconnect_after = 0;
                fd = connect_to(socket_path, std::chrono::seconds(30));
                if (fd < 0)
                    return 1;
            }
        }
    }
    ::close(fd);
    std::printf("frames %ld answered %ld\n", frames, answered);
    return 0;
}
