// The warning a camera backend logs for a frame it skips (a failed request,
// a short buffer, a size that does not fit the slot): such frames can come
// with every frame, so at most one line a second is logged
// (base::LogThrottle), each saying how many were left out since. The
// frames themselves are counted by the caller, every one.
#pragma once

#include <cstdint>
#include <iterator>
#include <string_view>
#include <utility>

#include <opencv2/core/mat.hpp>
#include <spdlog/fmt/fmt.h>
#include <spdlog/logger.h>

#include "stemd/base/log_throttle.hpp"

namespace stemd::drivers {

class SkippedFrameLog {
public:
    // `what` names the source and the frame and says what is wrong;
    // "; skipped (N more ...)" is added.
    template <typename... Args>
    void warn(spdlog::logger& log, std::int64_t now_ns, fmt::format_string<Args...> what, Args&&... args)
    {
        std::uint64_t left_out = 0;
        if (!throttle_.allow(now_ns, left_out))
            return;
        fmt::memory_buffer text;   // inline up to 500 bytes: these lines do not reach the heap
        fmt::format_to(std::back_inserter(text), what, std::forward<Args>(args)...);
        log.warn("{}; skipped ({} more skipped frames not logged since the last warning)",
                 std::string_view(text.data(), text.size()), left_out);
    }

    // The frame the device delivers is not the slot's size or type.
    void wrong_size(spdlog::logger& log, std::int64_t now_ns, std::string_view source, cv::Size frame,
                    const cv::Mat& slot)
    {
        warn(log, now_ns, "{}: frame is {}x{}, the slot is {}x{} type {}", source, frame.width, frame.height,
             slot.cols, slot.rows, slot.type());
    }

private:
    base::LogThrottle throttle_;
};

}  // namespace stemd::drivers
