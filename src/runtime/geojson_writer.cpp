#include "stemd/runtime/geojson_writer.hpp"

#include <pthread.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <string>
#include <utility>

namespace stemd::runtime {

GeojsonWriter::GeojsonWriter(const std::filesystem::path& map_jsonl, std::filesystem::path out,
                             std::chrono::nanoseconds interval, std::shared_ptr<spdlog::logger> log)
    : geojson_(map_jsonl), out_(std::move(out)), interval_(interval), log_(std::move(log))
{
}

GeojsonWriter::~GeojsonWriter()
{
    {
        const std::lock_guard lock(mutex_);
        stop_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable())
        thread_.join();
}

void GeojsonWriter::start()
{
    if (thread_.joinable())
        return;
    thread_ = std::thread([this] { run(); });
    pthread_setname_np(thread_.native_handle(), "geojson");
}

bool GeojsonWriter::rewrite()
{
    std::string error;
    if (!(geojson_.update(error) && geojson_.write(out_, error))) {
        log_->error("{}", error);
        return false;
    }
    rewrites_.fetch_add(1, std::memory_order_relaxed);
    return true;
}

void GeojsonWriter::run()
{
    // Below the other threads: Linux takes a thread's nice value per thread.
    // Not SCHED_IDLE, which a busy pipeline could starve for good.
    if (::setpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)), 10) != 0)
        log_->warn("geojson thread: cannot lower its priority (nice 10)");
    std::unique_lock lock(mutex_);
    while (!stop_) {
        if (wake_.wait_for(lock, interval_, [this] { return stop_; }))
            break;
        lock.unlock();
        rewrite();
        lock.lock();
    }
}

bool GeojsonWriter::finish()
{
    {
        const std::lock_guard lock(mutex_);
        stop_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable())
        thread_.join();
    return rewrite();
}

}  // namespace stemd::runtime
