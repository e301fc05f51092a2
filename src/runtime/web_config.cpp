#include "stemd/runtime/web_config.hpp"

#include <arpa/inet.h>

#include <charconv>

namespace stemd::runtime {

std::string ListenAddress::to_string() const
{
    const bool v6 = host.find(':') != std::string::npos;
    return (v6 ? "[" + host + "]" : host) + ":" + std::to_string(port);
}

std::optional<ListenAddress> parse_listen_address(const std::string& text, std::string& error)
{
    const auto fail = [&](const std::string& why) -> std::optional<ListenAddress> {
        error = "'" + text + "': " + why + " (expected ADDRESS:PORT, e.g. 127.0.0.1:8080 or [::1]:8080)";
        return std::nullopt;
    };
    const std::size_t colon = text.rfind(':');
    if (colon == std::string::npos)
        return fail("no port");
    ListenAddress out;
    std::string host = text.substr(0, colon);
    const std::string port = text.substr(colon + 1);
    const bool bracketed = host.size() >= 2 && host.front() == '[' && host.back() == ']';
    if (bracketed)
        host = host.substr(1, host.size() - 2);
    unsigned char buffer[sizeof(in6_addr)];
    if (bracketed) {
        if (inet_pton(AF_INET6, host.c_str(), buffer) != 1)
            return fail("not an IPv6 address");
    } else if (host.find(':') != std::string::npos) {
        return fail("an IPv6 address needs brackets");
    } else if (inet_pton(AF_INET, host.c_str(), buffer) != 1) {
        return fail("not a numeric IPv4 address");
    }
    int value = -1;
    const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), value);
    if (port.empty() || ec != std::errc() || end != port.data() + port.size() || value < 0 || value > 65535)
        return fail("the port must be 0..65535");
    out.host = host;
    out.port = value;
    return out;
}

}  // namespace stemd::runtime
