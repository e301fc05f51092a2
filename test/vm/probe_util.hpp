// Shared bits of the VM driver probes (test/vm/*_probe.cpp): an owning file
// descriptor, failure reporting that names the device and errno, and running a
// "trigger" command once the probe is set up (so the guest script acts on the
// driver only when the probe is ready to see it; no sleeps, no races).
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

namespace stemd::vmprobe {

// Owns one file descriptor; closes it exactly once.
class Fd {
 public:
  Fd() = default;
  explicit Fd(int fd) : fd_(fd) {}
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  Fd(Fd&& other) noexcept : fd_(std::exchange(other.fd_, -1)) {}
  Fd& operator=(Fd&& other) noexcept {
    if (this != &other) {
      reset();
      fd_ = std::exchange(other.fd_, -1);
    }
    return *this;
  }
  ~Fd() { reset(); }
  void reset() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  [[nodiscard]] int get() const { return fd_; }
  [[nodiscard]] bool valid() const { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

// Thrown for any failed check; main() prints it and exits 1.
struct ProbeError {
  std::string message;
};

// "<what> on <device>: <strerror> (errno N)" from the current errno.
[[noreturn]] inline void fail_errno(const std::string& device, const std::string& what) {
  const int e = errno;
  throw ProbeError{what + " on " + device + ": " + std::strerror(e) + " (errno " + std::to_string(e) + ")"};
}

[[noreturn]] inline void fail(const std::string& message) { throw ProbeError{message}; }

inline void info(const std::string& message) {
  std::printf("%s\n", message.c_str());
  std::fflush(stdout);
}

// Runs argv (searched in PATH) and returns its exit status; fails if it could
// not run or was killed.
inline int run_command(const std::vector<std::string>& argv) {
  if (argv.empty()) fail("run_command: empty command");
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) fail_errno("fork", "starting " + argv[0]);
  if (pid == 0) {
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    ::execvp(args[0], args.data());
    std::fprintf(stderr, "exec %s: %s (errno %d)\n", args[0], std::strerror(errno), errno);
    ::_exit(127);
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) fail_errno(argv[0], "waitpid");
  }
  if (!WIFEXITED(status)) fail(argv[0] + " was killed by signal " + std::to_string(WTERMSIG(status)));
  return WEXITSTATUS(status);
}

// Arguments after "--" (the trigger command), or empty.
inline std::vector<std::string> command_after_dashes(int argc, char** argv) {
  std::vector<std::string> cmd;
  bool seen = false;
  for (int i = 1; i < argc; ++i) {
    if (seen) cmd.emplace_back(argv[i]);
    else if (std::strcmp(argv[i], "--") == 0) seen = true;
  }
  return cmd;
}

// Runs body() and maps the outcome to an exit status: 0 pass, 1 fail, 2 usage.
template <typename Body>
int run_probe(const char* name, Body&& body) {
  try {
    body();
    std::printf("%s: PASS\n", name);
    return 0;
  } catch (const ProbeError& e) {
    std::fflush(stdout);
    std::fprintf(stderr, "%s: FAIL: %s\n", name, e.message.c_str());
    return 1;
  }
}

}  // namespace stemd::vmprobe
