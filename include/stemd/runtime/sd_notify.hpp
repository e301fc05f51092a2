// The systemd notification protocol (sd_notify(3)) without libsystemd: one
// datagram per message to the AF_UNIX socket named by $NOTIFY_SOCKET.
// Outside systemd (no $NOTIFY_SOCKET) every call is a no-op.
#pragma once

#include <chrono>
#include <string>
#include <string_view>
#include "stemd/base/unique_fd.hpp"

namespace stemd::runtime {

class SystemdNotifier {
public:
    // Reads NOTIFY_SOCKET, WATCHDOG_USEC and WATCHDOG_PID from the environment.
    SystemdNotifier();
    ~SystemdNotifier();
    SystemdNotifier(const SystemdNotifier&) = delete;
    SystemdNotifier& operator=(const SystemdNotifier&) = delete;

    bool enabled() const { return fd_.valid(); }
    // The service's WatchdogSec= when it applies to this process, else zero.
    std::chrono::microseconds watchdog_interval() const { return watchdog_; }

    // Sends e.g. "READY=1", "WATCHDOG=1", "STATUS=...", "STOPPING=1".
    // False (and errno-named log by the caller) if the datagram was not sent.
    bool notify(std::string_view state);
    const std::string& error() const { return error_; }

private:
    base::UniqueFd fd_;
    std::string address_;   // the socket path; a leading '@' is the abstract namespace
    std::chrono::microseconds watchdog_{0};
    std::string error_;
};

}  // namespace stemd::runtime
