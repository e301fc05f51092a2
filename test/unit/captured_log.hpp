// A logger whose lines a test reads back: text() is all it has logged so far.
#pragma once

#include <memory>
#include <sstream>
#include <string>

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

namespace stemd::test {

struct CapturedLog {
    std::shared_ptr<std::ostringstream> stream = std::make_shared<std::ostringstream>();
    std::shared_ptr<spdlog::logger> logger =
        std::make_shared<spdlog::logger>("test", std::make_shared<spdlog::sinks::ostream_sink_mt>(*stream));

    std::string text() const { return stream->str(); }
};

}  // namespace stemd::test
