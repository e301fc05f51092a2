#include "stemd/runtime/thread_settings.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstring>

namespace stemd::runtime {

namespace {

std::string describe(const char* what, int error)
{
    return std::string(what) + ": " + std::strerror(error) + " (errno " + std::to_string(error) + ")";
}

void append(std::string& out, const std::string& clause)
{
    if (!out.empty())
        out += "; ";
    out += clause;
}

}  // namespace

std::string apply_thread_settings(std::thread& thread, const char* name, const ThreadSettings& settings)
{
    std::string failures;
    const pthread_t handle = thread.native_handle();
    // Names longer than 15 characters are refused (ERANGE); ours are shorter.
    if (const int rc = pthread_setname_np(handle, name); rc != 0)
        append(failures, std::string(name) + ": " + describe("thread name", rc));
    sched_param param{};
    if (settings.fifo_priority > 0) {
        param.sched_priority = settings.fifo_priority;
        if (const int rc = pthread_setschedparam(handle, SCHED_FIFO, &param); rc != 0)
            append(failures,
                   std::string(name) + ": " + describe(("SCHED_FIFO " + std::to_string(settings.fifo_priority)).c_str(), rc));
    } else if (const int rc = pthread_setschedparam(handle, SCHED_OTHER, &param); rc != 0) {
        append(failures, std::string(name) + ": " + describe("SCHED_OTHER", rc));
    }
    if (settings.cpu >= 0) {
        cpu_set_t set;
        CPU_ZERO(&set);
        CPU_SET(static_cast<std::size_t>(settings.cpu), &set);
        if (const int rc = pthread_setaffinity_np(handle, sizeof set, &set); rc != 0)
            append(failures, std::string(name) + ": " + describe(("CPU " + std::to_string(settings.cpu)).c_str(), rc));
    }
    return failures;
}

StartupPriority::StartupPriority(int priority)
{
    if (priority <= 0)
        return;
    sched_param old{};
    if (const int rc = pthread_getschedparam(pthread_self(), &old_policy_, &old); rc != 0) {
        failure_ = describe("start-up: pthread_getschedparam", rc);
        return;
    }
    old_priority_ = old.sched_priority;
    sched_param param{};
    param.sched_priority = priority;
    if (const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param); rc != 0) {
        failure_ = describe(("start-up: SCHED_FIFO " + std::to_string(priority)).c_str(), rc);
        return;
    }
    raised_ = true;
}

StartupPriority::~StartupPriority()
{
    if (!raised_)
        return;
    sched_param param{};
    param.sched_priority = old_priority_;
    // Lowering one's own priority is always allowed.
    pthread_setschedparam(pthread_self(), old_policy_, &param);
}

std::string lock_all_memory()
{
    if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
        return describe("mlockall", errno);
    return {};
}

}  // namespace stemd::runtime
