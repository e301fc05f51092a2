// SIGTERM and SIGINT as a polled event rather than a handler: the
// constructor blocks them in the calling thread, so every thread started
// afterwards inherits the mask and only wait() ever sees them (sigtimedwait).
// No async-signal-safety questions, and no thread is interrupted mid-frame.
#pragma once

#include <signal.h>

#include <chrono>
#include <optional>

namespace stemd::runtime {

class ShutdownSignals {
public:
    // Construct before starting any thread.
    ShutdownSignals();
    ~ShutdownSignals();  // restores the previous mask
    ShutdownSignals(const ShutdownSignals&) = delete;
    ShutdownSignals& operator=(const ShutdownSignals&) = delete;

    // Waits at most `timeout`; the signal number, or nothing.
    std::optional<int> wait(std::chrono::milliseconds timeout);

    // A signal is waiting for wait() (left pending): for slow start-up
    // steps, such as a replay's preload, to give up early.
    bool pending() const;

private:
    sigset_t set_{};
    sigset_t previous_{};
};

}  // namespace stemd::runtime
