#include "stemd/runtime/class_socket.hpp"

#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "stemd/base/clock.hpp"
#include "stemd/runtime/class_message.hpp"
#include "stemd/runtime/logging.hpp"
#include "stemd/runtime/status.hpp"

namespace stemd::runtime {

namespace {

// Frames kept for sending: far more than a timeout's worth at camera rates.
constexpr std::size_t kRecentFrames = 64;
// Maps kept: a few timeouts' worth of frames, and the one the actuator reads.
constexpr std::size_t kSlots = 16;
// How long the receiver waits in poll(): bounds how late a captured frame
// is sent and how late a stop is seen.
constexpr int kPollMs = 1;

}  // namespace

SocketClassProvider::SocketClassProvider(std::string path, cv::Size frame_size, double timeout_ms)
    : path_(std::move(path)),
      frame_size_(frame_size),
      timeout_ns_(static_cast<std::int64_t>(timeout_ms * 1e6)),
      log_(make_logger("classes")),
      table_(kSlots, static_cast<std::size_t>(frame_size.area())),
      captured_(kRecentFrames),
      recent_(kRecentFrames),
      // One byte more than the largest valid map, so a longer one is seen.
      rx_(kClassMapHeaderBytes + static_cast<std::size_t>(frame_size.area()) + 1),
      tx_(kFrameMessageHeaderBytes + kFrameMessageMaxName)
{
}

SocketClassProvider::~SocketClassProvider() { stop(); }

bool SocketClassProvider::start()
{
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    if (path_.empty() || path_.size() >= sizeof(addr.sun_path)) {
        log_->error("classify.socket {}: empty or longer than {} bytes", path_, sizeof(addr.sun_path) - 1);
        return false;
    }
    std::memcpy(addr.sun_path, path_.data(), path_.size());
    listen_fd_.reset(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC | SOCK_NONBLOCK, 0));
    if (!listen_fd_.valid()) {
        log_->error("classify.socket {}: socket: {}", path_, std::strerror(errno));
        return false;
    }
    // A socket file left by an earlier run would make bind fail; anything
    // else at that path is left alone.
    struct stat st {};
    if (::lstat(path_.c_str(), &st) == 0 && S_ISSOCK(st.st_mode))
        ::unlink(path_.c_str());
    if (::bind(listen_fd_.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0 ||
        ::listen(listen_fd_.get(), 1) != 0) {
        log_->error("classify.socket {}: {}", path_, std::strerror(errno));
        listen_fd_.reset();
        return false;
    }
    log_->info("classify.provider socket: listening on {} (timeout {} ms)", path_, timeout_ns_ / 1'000'000.0);
    stop_.store(false, std::memory_order_release);
    thread_ = std::thread([this] { receive_loop(); });
    return true;
}

void SocketClassProvider::stop()
{
    stop_.store(true, std::memory_order_release);
    if (thread_.joinable())
        thread_.join();
    if (listen_fd_.valid()) {
        listen_fd_.reset();
        ::unlink(path_.c_str());
    }
    peer_fd_.reset();
    peer_connected_.store(false, std::memory_order_release);
}

void SocketClassProvider::on_capture(const drivers::Frame& frame) noexcept
{
    Captured c;
    c.t_capture_ns = frame.t_sample_ns;
    c.seq = frame.seq;
    c.name = frame.name;
    captured_.try_push(c);   // a full ring counts the drop; that frame's plants then time out
}

void SocketClassProvider::classify(const drivers::Frame& /*frame*/, const vision::Params& /*params*/,
                                   const vision::Workspace& /*workspace*/, FrameResult& result)
{
    // Every result has a class map (so scheduler.policy auto treats weeds
    // only), but its classes come later.
    result.has_class_map = true;
    result.classes_pending = true;
    for (std::size_t i = 0; i < result.detections.plants.size(); ++i)
        result.plant_class[i] = PlantClass::Unknown;
}

bool SocketClassProvider::resolve(FrameResult& result, std::int64_t now_ns) noexcept
{
    const auto found = table_.lookup(result.t_sample_ns, now_ns, result.t_sample_ns + timeout_ns_,
                                     [&](const cv::Mat& map) {
                                         bump(counters_.bad_class, plant_classes_from_map(map, frame_size_,
                                                                                          result.detections,
                                                                                          result.plant_class));
                                     });
    if (found == ClassSlotTable::Lookup::miss)
        return false;
    if (found == ClassSlotTable::Lookup::expired) {
        for (std::size_t i = 0; i < result.detections.plants.size(); ++i)
            result.plant_class[i] = PlantClass::Unknown;
        bump(counters_.timeouts);
    }
    result.classes_pending = false;
    return true;
}

void SocketClassProvider::receive_loop()
{
    while (!stop_.load(std::memory_order_acquire)) {
        const std::int64_t now_ns = base::monotonic_ns();
        Captured c;
        while (captured_.try_pop(c)) {
            if (recent_count_ == recent_.size()) {   // full: the oldest goes
                recent_head_ = (recent_head_ + 1) % recent_.size();
                --recent_count_;
            }
            recent_[(recent_head_ + recent_count_++) % recent_.size()] = c;
        }
        // Frames past their timeout are of no use to anyone.
        while (recent_count_ > 0 && recent_[recent_head_].t_capture_ns + timeout_ns_ < now_ns) {
            recent_head_ = (recent_head_ + 1) % recent_.size();
            --recent_count_;
        }
        if (peer_fd_.valid())
            send_recent(now_ns);

        pollfd fd{.fd = peer_fd_.valid() ? peer_fd_.get() : listen_fd_.get(), .events = POLLIN, .revents = 0};
        if (::poll(&fd, 1, kPollMs) <= 0)
            continue;
        if (!peer_fd_.valid()) {
            peer_fd_.reset(::accept4(listen_fd_.get(), nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK));
            if (peer_fd_.valid()) {
                bump(counters_.peers);
                peer_connected_.store(true, std::memory_order_release);
                log_->info("class provider connected to {}", path_);
                for (std::size_t i = 0; i < recent_count_; ++i) {
                    Captured& r = recent_[(recent_head_ + i) % recent_.size()];
                    r.sent = r.answered;
                }
            }
            continue;
        }
        receive(base::monotonic_ns());
    }
}

void SocketClassProvider::send_recent(std::int64_t /*now_ns*/)
{
    for (std::size_t i = 0; i < recent_count_ && peer_fd_.valid(); ++i) {
        Captured& c = recent_[(recent_head_ + i) % recent_.size()];
        if (c.sent)
            continue;
        const std::size_t n = encode_frame_message({.t_capture_ns = c.t_capture_ns,
                                                    .seq = c.seq,
                                                    .width = static_cast<std::uint32_t>(frame_size_.width),
                                                    .height = static_cast<std::uint32_t>(frame_size_.height),
                                                    .name = c.name.view()},
                                                   tx_);
        if (::send(peer_fd_.get(), tx_.data(), n, MSG_DONTWAIT | MSG_NOSIGNAL) == static_cast<ssize_t>(n)) {
            c.sent = true;
            continue;
        }
        if (errno == EAGAIN || errno == EWOULDBLOCK)
            return;   // the peer reads slowly: the rest on a later pass
        hang_up(std::strerror(errno));
    }
}

void SocketClassProvider::receive(std::int64_t now_ns)
{
    for (;;) {
        const ssize_t n = ::recv(peer_fd_.get(), rx_.data(), rx_.size(), MSG_DONTWAIT | MSG_TRUNC);
        if (n == 0) {
            hang_up("hung up");
            return;
        }
        if (n < 0) {
            if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)
                hang_up(std::strerror(errno));
            return;
        }
        ClassMapMessage map;
        const ClassMessageError error =
            static_cast<std::size_t>(n) > rx_.size()
                ? ClassMessageError::too_large
                : parse_class_map_message({rx_.data(), static_cast<std::size_t>(n)},
                                          static_cast<std::uint32_t>(frame_size_.width),
                                          static_cast<std::uint32_t>(frame_size_.height), map);
        if (error != ClassMessageError::ok) {
            // The first of a run is logged; all are counted (status line).
            if (counters_.bad_messages.load(std::memory_order_relaxed) == 0)
                log_->warn("class provider on {}: a message of {} bytes dropped: {} (more are only counted)", path_,
                           n, to_string(error));
            bump(counters_.bad_messages);
            continue;
        }
        table_.store(map.t_capture_ns, static_cast<int>(map.width), static_cast<int>(map.height), map.classes,
                     now_ns);
        bump(counters_.maps);
        for (std::size_t i = 0; i < recent_count_; ++i) {
            Captured& r = recent_[(recent_head_ + i) % recent_.size()];
            if (r.t_capture_ns == map.t_capture_ns)
                r.answered = r.sent = true;
        }
    }
}

void SocketClassProvider::hang_up(const char* why)
{
    log_->warn("class provider on {}: {}; plants are unknown until one connects again", path_, why);
    peer_fd_.reset();
    peer_connected_.store(false, std::memory_order_release);
}

}  // namespace stemd::runtime
