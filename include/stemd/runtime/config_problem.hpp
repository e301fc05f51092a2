// A setting the daemon cannot run with, and the key to blame (the caller
// names the key's origin: file and line, --set, or default).
#pragma once

#include <string>

namespace stemd::runtime {

struct ConfigProblem {
    std::string key;       // "gpio.enable_line"
    std::string message;   // why, in one line
};

}  // namespace stemd::runtime
