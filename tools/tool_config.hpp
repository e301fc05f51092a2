// Number parsing the tools share (--config/--set live in
// stemd/config/command_line.hpp, shared with stemd).
#pragma once

#include <string>

namespace stemd::tools {

// Parses a finite double or an integer; false if the text is not one.
bool parse_number(const std::string& text, double& out);
bool parse_int(const std::string& text, long& out);

}  // namespace stemd::tools
