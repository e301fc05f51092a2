// Files generated from a table in the code (config/stemd.dbc from the CAN
// message table, config/stemd.yaml from the configuration schema): written
// to standard output or a file, or checked against the committed copy.
#pragma once

#include <string>
#include <string_view>

namespace stemd::tools {

// `text` to standard output (path empty), into `path` (check false), or
// compared with `path` (check true: 0 if equal, else 1 and a message naming
// the first different line, `source` and how to regenerate). 1 on I/O errors.
int write_or_check_generated(std::string_view tool, const std::string& text, const std::string& path, bool check,
                             std::string_view source, std::string_view regenerate);

}  // namespace stemd::tools
