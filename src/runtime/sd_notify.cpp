#include "stemd/runtime/sd_notify.hpp"

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

namespace stemd::runtime {

SystemdNotifier::SystemdNotifier()
{
    const char* socket_path = std::getenv("NOTIFY_SOCKET");
    if (socket_path == nullptr || socket_path[0] == '\0')
        return;
    address_ = socket_path;
    if ((address_[0] != '/' && address_[0] != '@') || address_.size() >= sizeof(sockaddr_un::sun_path)) {
        error_ = "NOTIFY_SOCKET '" + address_ + "' is not a socket path";
        return;
    }
    fd_.reset(::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0));
    if (!fd_.valid()) {
        error_ = std::string("socket(AF_UNIX): ") + std::strerror(errno);
        return;
    }
    // The watchdog applies to us when WATCHDOG_PID is absent or names us.
    const char* usec = std::getenv("WATCHDOG_USEC");
    const char* pid = std::getenv("WATCHDOG_PID");
    if (usec != nullptr && (pid == nullptr || std::atol(pid) == static_cast<long>(::getpid())))
        watchdog_ = std::chrono::microseconds(std::atoll(usec));
}

SystemdNotifier::~SystemdNotifier() = default;

bool SystemdNotifier::notify(std::string_view state)
{
    if (!fd_.valid())
        return false;
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::memcpy(addr.sun_path, address_.data(), address_.size());
    socklen_t length = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + address_.size());
    if (address_[0] == '@')
        addr.sun_path[0] = '\0';  // abstract namespace: no terminating NUL counted
    else
        length += 1;
    const ssize_t sent = ::sendto(fd_.get(), state.data(), state.size(), MSG_NOSIGNAL,
                                  reinterpret_cast<const sockaddr*>(&addr), length);
    if (sent < 0) {
        error_ = address_ + ": sendto: " + std::strerror(errno);
        return false;
    }
    return true;
}

}  // namespace stemd::runtime
