// web.*: the operator's live view (an HTTP server on its own low-priority
// thread; off unless web.listen names an address).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace stemd::runtime {

struct WebConfig {
    std::string listen;          // "" (none): no server; "127.0.0.1:8080", "[::1]:8080"
    int fps = 5;                 // frames a second the view is sent at most
    int max_width_px = 640;      // frames wider than this are scaled down before encoding
    int plants = 200;            // the last N plants the field strip shows
    std::string token_file;      // "" (none): read-only view, no control endpoints
};

// A numeric IPv4 or bracketed IPv6 address and a port (0: any free port).
struct ListenAddress {
    std::string host;   // "127.0.0.1", "::1" (without brackets)
    int port = 0;
    std::string to_string() const;   // "127.0.0.1:8080", "[::1]:8080"
};

// Parses web.listen. Names are refused (no resolver on the robot, and an
// address says exactly which interface is exposed). nullopt and `error`
// (one line) if it is not an address and port.
std::optional<ListenAddress> parse_listen_address(const std::string& text, std::string& error);

}  // namespace stemd::runtime
