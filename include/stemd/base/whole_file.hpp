// Reading a whole regular file with a size cap, for every file stemd reads
// whole (the configuration, images, the model, the calibration, CSV
// tables, the web token). Callers word the outcome for their users; this only says what
// happened.
#pragma once

#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "stemd/base/unique_fd.hpp"

namespace stemd::base {

enum class WholeFileStatus {
    ok,
    cannot_open,   // open(2) failed: error_number
    cannot_stat,   // fstat(2) failed: error_number
    directory,
    not_regular,   // a FIFO, a socket or a device
    too_large,     // size_bytes is over the cap; nothing was allocated
    read_error,    // read(2) failed: error_number
    truncated,     // the file ended after read_bytes of its size_bytes
};

struct WholeFileResult {
    WholeFileStatus status = WholeFileStatus::ok;
    int error_number = 0;
    std::uintmax_t size_bytes = 0;
    bool size_is_lower_bound = false;   // too_large past the size fstat(2) gave
    std::size_t read_bytes = 0;
    std::uint32_t mode = 0;             // st_mode of the file opened, once fstat(2) succeeded
    bool ok() const { return status == WholeFileStatus::ok; }
};

// Reads the regular file at `path` into `bytes` (a contiguous byte buffer:
// std::string or std::vector of a byte type), resized to the file's size
// from fstat(2) before one read(2) loop, then read on to the end (one more
// read(2) for a file whose size was right); a reused buffer keeps its
// capacity. The file is opened non-blocking, so a FIFO with no writer is
// refused at once instead of waited on (a reader must never hang a start
// or a capture thread). A file over `max_bytes` is refused from its size,
// before anything is allocated; on failure `bytes` may hold a part.
template <class Bytes>
WholeFileResult read_whole_file(const char* path, std::size_t max_bytes, Bytes& bytes)
{
    WholeFileResult result;
    const UniqueFd file(::open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK));
    if (!file.valid()) {
        result.status = WholeFileStatus::cannot_open;
        result.error_number = errno;
        return result;
    }
    struct stat st {};
    if (::fstat(file.get(), &st) != 0) {
        result.status = WholeFileStatus::cannot_stat;
        result.error_number = errno;
        return result;
    }
    result.mode = static_cast<std::uint32_t>(st.st_mode);
    if (S_ISDIR(st.st_mode)) {
        result.status = WholeFileStatus::directory;
        return result;
    }
    if (!S_ISREG(st.st_mode)) {
        result.status = WholeFileStatus::not_regular;
        return result;
    }
    result.size_bytes = static_cast<std::uintmax_t>(st.st_size);
    if (result.size_bytes > max_bytes) {
        result.status = WholeFileStatus::too_large;
        return result;
    }
    bytes.resize(static_cast<std::size_t>(st.st_size));
    const auto read_some = [&](void* to, std::size_t count) {
        for (;;) {
            const ssize_t n = ::read(file.get(), to, count);
            if (n >= 0 || errno != EINTR)
                return n;
        }
    };
    while (result.read_bytes < bytes.size()) {
        const ssize_t n = read_some(bytes.data() + result.read_bytes, bytes.size() - result.read_bytes);
        if (n < 0) {
            result.status = WholeFileStatus::read_error;
            result.error_number = errno;
            return result;
        }
        if (n == 0) {
            result.status = WholeFileStatus::truncated;
            return result;
        }
        result.read_bytes += static_cast<std::size_t>(n);
    }
    // Until the end, which is usually where the size said: a file that grew
    // since fstat(2), or one of the kernel's (/proc, /sys) that reports 0
    // and holds more, is read on, within the cap.
    char chunk[4096];
    for (;;) {
        const ssize_t n = read_some(chunk, sizeof chunk);
        if (n < 0) {
            result.status = WholeFileStatus::read_error;
            result.error_number = errno;
            return result;
        }
        if (n == 0)
            break;
        result.size_bytes = result.read_bytes + static_cast<std::size_t>(n);
        if (result.size_bytes > max_bytes) {
            result.status = WholeFileStatus::too_large;
            result.size_is_lower_bound = true;
            return result;
        }
        bytes.insert(bytes.end(), chunk, chunk + n);
        result.read_bytes += static_cast<std::size_t>(n);
    }
    return result;
}

// Why a read failed, in words for a log line after "<path>: cannot read
// the ... file: " (empty when it did not fail). Readers whose tests fix
// older wordings (the configuration, images, CSV tables) keep their own.
inline std::string why_unread(const WholeFileResult& result, std::size_t max_bytes)
{
    switch (result.status) {
    case WholeFileStatus::ok: break;
    case WholeFileStatus::cannot_open:
    case WholeFileStatus::cannot_stat:
    case WholeFileStatus::read_error: return std::strerror(result.error_number);
    case WholeFileStatus::directory:
    case WholeFileStatus::not_regular: return "not a regular file";
    case WholeFileStatus::too_large:
        return max_bytes >= (std::size_t{1} << 20) ? "larger than " + std::to_string(max_bytes >> 20) + " MiB"
                                                   : "larger than " + std::to_string(max_bytes) + " bytes";
    case WholeFileStatus::truncated: return "it ended while read";
    }
    return {};
}

}  // namespace stemd::base
