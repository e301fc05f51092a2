// The sd_notify protocol against a real AF_UNIX datagram socket standing in
// for systemd.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "stemd/runtime/sd_notify.hpp"

using stemd::runtime::SystemdNotifier;

namespace {

class Env {
public:
    Env(const char* key, const std::string& value) : key_(key) { ::setenv(key, value.c_str(), 1); }
    ~Env() { ::unsetenv(key_); }

private:
    const char* key_;
};

// A bound datagram socket; `name` starting with '@' is abstract. Named in
// NOTIFY_SOCKET while it lives, as systemd names its socket to a service.
class FakeSystemd {
public:
    explicit FakeSystemd(const std::string& name) : name_(name)
    {
        fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
        sockaddr_un addr{};
        addr.sun_family = AF_UNIX;
        name.copy(addr.sun_path, name.size());
        socklen_t length = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + name.size());
        if (name[0] == '@')
            addr.sun_path[0] = '\0';
        else {
            ::unlink(name.c_str());
            length += 1;
        }
        bound_ = ::bind(fd_, reinterpret_cast<sockaddr*>(&addr), length) == 0;
        const timeval timeout{2, 0};  // a missing datagram fails the test, never hangs it
        ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
    }
    ~FakeSystemd()
    {
        ::close(fd_);
        if (name_[0] == '/')
            ::unlink(name_.c_str());
    }
    bool bound() const { return bound_; }
    std::string receive()
    {
        char buf[512];
        const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
        return n < 0 ? std::string("<nothing>") : std::string(buf, static_cast<std::size_t>(n));
    }

private:
    std::string name_;
    int fd_ = -1;
    bool bound_ = false;
    Env notify_socket_{"NOTIFY_SOCKET", name_};
};

}  // namespace

TEST(SdNotify, DisabledOutsideSystemd)
{
    ::unsetenv("NOTIFY_SOCKET");
    SystemdNotifier n;
    EXPECT_FALSE(n.enabled());
    EXPECT_FALSE(n.notify("READY=1"));
    EXPECT_EQ(n.watchdog_interval().count(), 0);
}

TEST(SdNotify, SendsToAPathSocket)
{
    const std::string path = "/tmp/stemd-notify-test-" + std::to_string(::getpid());
    FakeSystemd systemd(path);
    ASSERT_TRUE(systemd.bound());
    SystemdNotifier n;
    ASSERT_TRUE(n.enabled()) << n.error();
    EXPECT_TRUE(n.notify("READY=1"));
    EXPECT_TRUE(n.notify("STATUS=in 10.0 fps"));
    EXPECT_EQ(systemd.receive(), "READY=1");
    EXPECT_EQ(systemd.receive(), "STATUS=in 10.0 fps");
}

TEST(SdNotify, SendsToAnAbstractSocket)
{
    const std::string name = "@stemd-notify-test-" + std::to_string(::getpid());
    FakeSystemd systemd(name);
    ASSERT_TRUE(systemd.bound());
    SystemdNotifier n;
    EXPECT_TRUE(n.notify("WATCHDOG=1"));
    EXPECT_EQ(systemd.receive(), "WATCHDOG=1");
}

TEST(SdNotify, WatchdogIntervalOnlyForThisProcess)
{
    const std::string name = "@stemd-notify-wd-" + std::to_string(::getpid());
    const Env socket("NOTIFY_SOCKET", name);
    const Env usec("WATCHDOG_USEC", "4000000");
    {
        const Env pid("WATCHDOG_PID", std::to_string(::getpid()));
        EXPECT_EQ(SystemdNotifier().watchdog_interval().count(), 4000000);
    }
    {
        const Env pid("WATCHDOG_PID", std::to_string(::getpid() + 1));
        EXPECT_EQ(SystemdNotifier().watchdog_interval().count(), 0);
    }
}

TEST(SdNotify, ABadSocketNameIsAnErrorNotACrash)
{
    const Env env("NOTIFY_SOCKET", "relative/path");
    SystemdNotifier n;
    EXPECT_FALSE(n.enabled());
    EXPECT_NE(n.error().find("relative/path"), std::string::npos);
}
