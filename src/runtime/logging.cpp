#include "stemd/runtime/logging.hpp"

#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

namespace stemd::runtime {

namespace {

// One sink, so that lines of different loggers never interleave mid-line.
std::shared_ptr<spdlog::sinks::stderr_sink_mt> shared_sink()
{
    static const auto sink = [] {
        auto s = std::make_shared<spdlog::sinks::stderr_sink_mt>();
        s->set_pattern("%H:%M:%S.%e %-10n %-5l %v");
        return s;
    }();
    return sink;
}

}  // namespace

void set_log_level(const std::string& level)
{
    const auto parsed = spdlog::level::from_str(level);
    spdlog::set_level(parsed);   // existing loggers
    spdlog::apply_all([parsed](const std::shared_ptr<spdlog::logger>& l) { l->set_level(parsed); });
}

std::shared_ptr<spdlog::logger> make_logger(const std::string& subsystem)
{
    if (auto existing = spdlog::get(subsystem))
        return existing;
    auto logger = std::make_shared<spdlog::logger>(subsystem, shared_sink());
    logger->set_level(spdlog::get_level());
    // Warnings and errors reach stderr at once; a crash must not eat them.
    logger->flush_on(spdlog::level::warn);
    spdlog::register_logger(logger);
    return logger;
}

}  // namespace stemd::runtime
