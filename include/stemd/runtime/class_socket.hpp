// classify.provider: socket. stemd listens on a Unix SOCK_SEQPACKET socket
// (classify.socket); one peer at a time connects to it. For each captured
// frame stemd sends a frame message (its t_capture_ns, seq, size and name:
// what a peer needs to match it with the frame it classes), and the peer
// answers with a class map message for that t_capture_ns (byte layout in
// class_message.hpp, README "External class provider").
//
// A receiver thread of its own does every socket call: it takes the frames
// from the capture thread through a ring, sends them (those captured while
// no peer was connected too, as long as their timeout has not passed),
// accepts, receives into a buffer allocated at start, and stores the maps
// in a ClassSlotTable. The actuator thread only looks a result's map up
// there. Malformed messages are counted and dropped; a peer hanging up is
// logged and the socket accepts the next one. Nothing here stops the daemon.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <spdlog/logger.h>

#include "stemd/base/spsc_ring.hpp"
#include "stemd/base/unique_fd.hpp"
#include "stemd/runtime/class_provider.hpp"
#include "stemd/runtime/class_slots.hpp"

namespace stemd::runtime {

class SocketClassProvider final : public ClassProvider {
public:
    // Allocates the slots, rings and receive buffer (a map at most the
    // frame's size).
    SocketClassProvider(std::string path, cv::Size frame_size, double timeout_ms);
    ~SocketClassProvider() override;

    std::string_view name() const override { return "socket"; }
    // Binds (replacing a stale socket file) and listens, starts the
    // receiver thread; false (logged, naming the path) if it cannot.
    bool start() override;
    void stop() override;
    void on_capture(const drivers::Frame& frame) noexcept override;
    void classify(const drivers::Frame& frame, const vision::Params& params, const vision::Workspace& workspace,
                  FrameResult& result) override;
    bool resolve(FrameResult& result, std::int64_t now_ns) noexcept override;

    bool peer_connected() const { return peer_connected_.load(std::memory_order_acquire); }

private:
    struct Captured {
        std::int64_t t_capture_ns = 0;
        std::uint64_t seq = 0;
        drivers::FrameName name;
        bool sent = false;       // to the peer connected now
        bool answered = false;   // its map came (not sent again to a new peer)
    };
    void receive_loop();
    void send_recent(std::int64_t now_ns);
    void receive(std::int64_t now_ns);
    void hang_up(const char* why);

    const std::string path_;
    const cv::Size frame_size_;
    const std::int64_t timeout_ns_;
    const std::shared_ptr<spdlog::logger> log_;
    ClassSlotTable table_;
    base::SpscRing<Captured> captured_;   // capture -> receiver
    // Receiver only: the frames whose timeout has not passed, oldest first
    // (a ring of fixed size), so that a peer connecting late, or again
    // after hanging up, still gets those it has not answered.
    std::vector<Captured> recent_;
    std::size_t recent_head_ = 0, recent_count_ = 0;
    std::vector<std::uint8_t> rx_, tx_;
    base::UniqueFd listen_fd_, peer_fd_;
    std::atomic<bool> peer_connected_{false};
    std::atomic<bool> stop_{false};
    std::thread thread_;
};

}  // namespace stemd::runtime
