#include "stemd/runtime/thread_settings.hpp"

#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>

#include <future>
#include <thread>

namespace stemd::runtime {
namespace {

struct Scheduling {
    int policy = -1;
    int priority = -1;
};

Scheduling scheduling_of(pthread_t thread)
{
    Scheduling s;
    sched_param param{};
    if (pthread_getschedparam(thread, &s.policy, &param) == 0)
        s.priority = param.sched_priority;
    return s;
}

TEST(StartupPriority, ZeroLeavesTheThreadAsItIs)
{
    const Scheduling before = scheduling_of(pthread_self());
    {
        const StartupPriority none(0);
        EXPECT_TRUE(none.failure().empty());
        const Scheduling during = scheduling_of(pthread_self());
        EXPECT_EQ(during.policy, before.policy);
        EXPECT_EQ(during.priority, before.priority);
    }
    EXPECT_EQ(scheduling_of(pthread_self()).policy, before.policy);
}

TEST(StartupPriority, ThreadsCreatedMeanwhileStartAtItAndTheCallerGetsItsOwnBack)
{
    const Scheduling before = scheduling_of(pthread_self());
    ASSERT_NE(before.policy, SCHED_FIFO) << "the test runner itself is real-time";
    std::promise<Scheduling> seen_by_thread;
    std::promise<void> settings_applied;
    std::promise<Scheduling> seen_after_settings;
    std::thread worker;
    {
        const StartupPriority startup(10);
        if (!startup.failure().empty())
            GTEST_SKIP() << "needs CAP_SYS_NICE (root or LimitRTPRIO): " << startup.failure();
        const Scheduling during = scheduling_of(pthread_self());
        EXPECT_EQ(during.policy, SCHED_FIFO);
        EXPECT_EQ(during.priority, 10);
        worker = std::thread([&] {
            seen_by_thread.set_value(scheduling_of(pthread_self()));
            settings_applied.get_future().wait();
            seen_after_settings.set_value(scheduling_of(pthread_self()));
        });
        const Scheduling inherited = seen_by_thread.get_future().get();
        EXPECT_EQ(inherited.policy, SCHED_FIFO);
        EXPECT_EQ(inherited.priority, 10);
        // A thread configured without a priority does not keep the borrowed one.
        EXPECT_EQ(apply_thread_settings(worker, "stemd-test", ThreadSettings{}), "");
        settings_applied.set_value();
    }
    const Scheduling after = scheduling_of(pthread_self());
    EXPECT_EQ(after.policy, before.policy);
    EXPECT_EQ(after.priority, before.priority);
    const Scheduling worker_after = seen_after_settings.get_future().get();
    worker.join();
    EXPECT_EQ(worker_after.policy, SCHED_OTHER);
}

}  // namespace
}  // namespace stemd::runtime
