// A file of records (one line each) written with one write(2) per record:
// nothing waits in a user-space buffer, so a kill (SIGKILL, a crash, power
// after the page cache is written back) loses no record that write()
// returned for, and leaves no line torn. The caller formats each record into
// its own preallocated buffer; nothing here allocates after open().
#pragma once

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <string_view>

#include "stemd/base/unique_fd.hpp"

namespace stemd::base {

class RecordFile {
public:
    // Creates (truncates) or appends to `path`; 0 or the errno.
    int open(const char* path, bool append = false) noexcept
    {
        const int flags = O_WRONLY | O_CREAT | O_CLOEXEC | (append ? O_APPEND : O_TRUNC);
        UniqueFd fd(::open(path, flags, 0644));
        if (!fd.valid())
            return errno;
        struct stat st {};
        regular_ = ::fstat(fd.get(), &st) == 0 && S_ISREG(st.st_mode);
        size_ = regular_ ? st.st_size : 0;
        fd_ = std::move(fd);
        return 0;
    }
    // Shares an already open descriptor (standard output): a duplicate of it,
    // so the file is neither truncated nor written from offset 0 over what
    // the shell or another writer put there. Never cut back after a failed
    // write: others may have written after our last record. 0 or the errno.
    int open_duplicate(int fd) noexcept
    {
        UniqueFd copy(::fcntl(fd, F_DUPFD_CLOEXEC, 0));
        if (!copy.valid())
            return errno;
        regular_ = false;
        size_ = 0;
        fd_ = std::move(copy);
        return 0;
    }
    bool is_open() const noexcept { return fd_.valid(); }
    void close() noexcept { fd_.reset(); }

    // Writes the whole record: one write(2), continued only if the kernel
    // took part of it. 0 or the errno. A record the file could not take
    // whole (a full disk) is cut off again, so the file still ends on a
    // complete line.
    int write(std::string_view record) noexcept
    {
        if (!fd_.valid())
            return EBADF;
        std::size_t done = 0;
        while (done < record.size()) {
            const ssize_t n = ::write(fd_.get(), record.data() + done, record.size() - done);
            if (n < 0 && errno == EINTR)
                continue;
            if (n <= 0) {
                const int err = n < 0 ? errno : ENOSPC;
                if (done > 0 && regular_) {
                    // Best effort: if even this fails, the error is reported anyway.
                    const int cut = ::ftruncate(fd_.get(), size_);
                    static_cast<void>(cut);
                }
                return err;
            }
            done += static_cast<std::size_t>(n);
        }
        size_ += static_cast<off_t>(done);
        return 0;
    }

private:
    UniqueFd fd_;
    bool regular_ = false;
    off_t size_ = 0;   // regular files: the end of the last complete record
};

}  // namespace stemd::base
