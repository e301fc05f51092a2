#include "stemd/runtime/signals.hpp"

#include <pthread.h>

#include <cerrno>

namespace stemd::runtime {

ShutdownSignals::ShutdownSignals()
{
    sigemptyset(&set_);
    sigaddset(&set_, SIGTERM);
    sigaddset(&set_, SIGINT);
    pthread_sigmask(SIG_BLOCK, &set_, &previous_);
}

ShutdownSignals::~ShutdownSignals()
{
    pthread_sigmask(SIG_SETMASK, &previous_, nullptr);
}

std::optional<int> ShutdownSignals::wait(std::chrono::milliseconds timeout)
{
    const auto ms = timeout.count();
    const timespec ts{static_cast<time_t>(ms / 1000), static_cast<long>(ms % 1000) * 1'000'000};
    for (;;) {
        const int sig = sigtimedwait(&set_, nullptr, &ts);
        if (sig > 0)
            return sig;
        if (errno != EINTR)   // EAGAIN: the timeout passed
            return std::nullopt;
    }
}

bool ShutdownSignals::pending() const
{
    sigset_t waiting;
    if (sigpending(&waiting) != 0)
        return false;
    return sigismember(&waiting, SIGTERM) == 1 || sigismember(&waiting, SIGINT) == 1;
}

}  // namespace stemd::runtime
