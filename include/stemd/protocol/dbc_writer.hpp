// The DBC description of stemd's CAN messages, written from the tables of
// messages.hpp (so that config/stemd.dbc cannot drift from the encoder):
// VERSION, BU_, BO_ with its SG_ lines, CM_ for the network, nodes, messages
// and signals, and VAL_. The identifiers are those of the default base ID.
// Not for the real-time path: it allocates.
#pragma once

#include <ostream>

namespace stemd::protocol {

void write_dbc(std::ostream& out);

}  // namespace stemd::protocol
