// The documents stemd-config generates from the configuration schema: the
// documented default configuration (config/stemd.yaml) and the README's key
// table. Only the tool and its tests need them, so they live here, not in
// the daemon's configuration library.
#pragma once

#include <string>

namespace stemd::config {

// Every key at its default, each section's help above it and each key's
// help, type, unit and range above the key; loads as the defaults.
std::string documented_yaml();

// The schema as a Markdown table for the README:
// key | type | unit | default | range / choices | meaning; the keys of
// schema(), then the list item keys ("tools[].offset_mm").
std::string schema_markdown();

}  // namespace stemd::config
