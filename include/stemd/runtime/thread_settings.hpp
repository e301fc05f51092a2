// Real-time settings: SCHED_FIFO priority, CPU affinity and thread names
// for the daemon's threads, and mlockall. Each returns what failed rather
// than logging, so the caller can warn once for all of them.
#pragma once

#include <string>
#include <thread>

#include "stemd/runtime/daemon_config.hpp"

namespace stemd::runtime {

// Names the thread (as top shows it, 15 characters at most) and applies
// `settings`. Empty on success; otherwise "capture: SCHED_FIFO 40: Operation
// not permitted (errno 1)" and so on, one clause per failure.
std::string apply_thread_settings(std::thread& thread, const char* name, const ThreadSettings& settings);

// mlockall(MCL_CURRENT | MCL_FUTURE). Empty on success, else why.
std::string lock_all_memory();

}  // namespace stemd::runtime
