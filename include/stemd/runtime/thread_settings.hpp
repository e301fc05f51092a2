// Real-time settings: SCHED_FIFO priority, CPU affinity and thread names
// for the daemon's threads, and mlockall. Each returns what failed rather
// than logging, so the caller can warn once for all of them.
#pragma once

#include <string>
#include <thread>

#include "stemd/runtime/daemon_config.hpp"

namespace stemd::runtime {

// Names the thread (as top shows it, 15 characters at most) and applies
// `settings`: SCHED_FIFO at its priority, or SCHED_OTHER when that is 0 (a
// thread may have inherited a borrowed priority, see StartupPriority).
// Empty on success; otherwise "capture: SCHED_FIFO 40: Operation not
// permitted (errno 1)" and so on, one clause per failure.
std::string apply_thread_settings(std::thread& thread, const char* name, const ThreadSettings& settings);

// The calling thread runs at SCHED_FIFO `priority` for this object's life,
// then gets its own scheduling back; priority 0 leaves it as it is. Start-up
// on a loaded machine needs it: a normal-priority thread can wait hundreds
// of milliseconds for a core between starting a paced source and giving the
// real-time threads their priorities, and threads created meanwhile start
// at its priority (they inherit it) instead of at the bottom.
class StartupPriority {
public:
    explicit StartupPriority(int priority);
    ~StartupPriority();
    StartupPriority(const StartupPriority&) = delete;
    StartupPriority& operator=(const StartupPriority&) = delete;

    // Empty when the priority was taken (or none was asked), else why not.
    const std::string& failure() const { return failure_; }

private:
    bool raised_ = false;
    int old_policy_ = 0;
    int old_priority_ = 0;
    std::string failure_;
};

// mlockall(MCL_CURRENT | MCL_FUTURE). Empty on success, else why.
std::string lock_all_memory();

}  // namespace stemd::runtime
