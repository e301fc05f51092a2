#include "stemd/protocol/dbc_writer.hpp"

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "stemd/protocol/messages.hpp"

namespace stemd::protocol {

namespace {

// The symbols a DBC editor expects to find declared; none of them is used.
constexpr std::string_view kNewSymbols =
    "NS_ :\n"
    "\tNS_DESC_\n\tCM_\n\tBA_DEF_\n\tBA_\n\tVAL_\n\tCAT_DEF_\n\tCAT_\n\tFILTER\n\tBA_DEF_DEF_\n\tEV_DATA_\n"
    "\tENVVAR_DATA_\n\tSGTYPE_\n\tSGTYPE_VAL_\n\tBA_DEF_SGTYPE_\n\tBA_SGTYPE_\n\tSIG_TYPE_REF_\n\tVAL_TABLE_\n"
    "\tSIG_GROUP_\n\tSIG_VALTYPE_\n\tSIGTYPE_VALTYPE_\n\tBO_TX_BU_\n\tBA_DEF_REL_\n\tBA_REL_\n\tBA_DEF_DEF_REL_\n"
    "\tBU_SG_REL_\n\tBU_EV_REL_\n\tBU_BO_REL_\n\tSG_MUL_VAL_\n";

// " Bits 12..15 and 45..47 reserved." for the bits no signal uses ("" if none).
std::string reserved_bits(const MessageDef& m)
{
    std::uint64_t used = 0;
    for (const SignalDef& s : m.signals)
        used |= ((std::uint64_t{1} << s.length) - 1) << s.start_bit;
    std::vector<std::string> runs;
    const unsigned bits = kFrameDlc * 8u;
    for (unsigned first = 0; first < bits; ++first) {
        if ((used >> first) & 1)
            continue;
        unsigned last = first;
        while (last + 1 < bits && !((used >> (last + 1)) & 1))
            ++last;
        runs.push_back(first == last ? std::to_string(first) : std::to_string(first) + ".." + std::to_string(last));
        first = last;
    }
    if (runs.empty())
        return {};
    std::string text = runs.size() == 1 && runs[0].find('.') == std::string::npos ? " Bit " : " Bits ";
    for (std::size_t i = 0; i < runs.size(); ++i)
        text += (i == 0 ? "" : i + 1 == runs.size() ? " and " : ", ") + runs[i];
    return text + " reserved.";
}

}  // namespace

void write_dbc(std::ostream& out)
{
    const CanIds ids;
    out << "VERSION \"" << kProtocolVersion << "\"\n\n\n" << kNewSymbols << "\nBS_:\n\nBU_:";
    for (const NodeDef& n : node_defs())
        out << ' ' << n.name;
    out << "\n\n";

    for (MessageKind kind : kAllMessageKinds) {
        const MessageDef& m = message_def(kind);
        out << "\nBO_ " << ids.id(kind) << ' ' << m.name << ": " << int{kFrameDlc} << ' ' << m.transmitter << '\n';
        std::string receivers;
        for (std::string_view r : m.receivers)
            (receivers += receivers.empty() ? "" : ",") += r;
        if (receivers.empty())
            receivers = "Vector__XXX";  // the DBC's "no node"
        for (const SignalDef& s : m.signals) {
            // Intel byte order ("@1") and factor 1, offset 0: the codec packs
            // little-endian and sends the physical value as it is.
            out << " SG_ " << s.name << " : " << int{s.start_bit} << '|' << int{s.length} << "@1"
                << (s.is_signed ? '-' : '+') << " (1,0) [" << s.min << '|' << s.max << "] \"" << s.unit << "\" "
                << receivers << '\n';
        }
    }
    out << "\n\n\n";

    out << "CM_ \"" << protocol_comment() << "\";\n";
    for (const NodeDef& n : node_defs())
        out << "CM_ BU_ " << n.name << " \"" << n.comment << "\";\n";
    for (MessageKind kind : kAllMessageKinds) {
        const MessageDef& m = message_def(kind);
        out << "CM_ BO_ " << ids.id(kind) << " \"" << m.comment << reserved_bits(m) << "\";\n";
        for (const SignalDef& s : m.signals)
            out << "CM_ SG_ " << ids.id(kind) << ' ' << s.name << " \"" << s.comment << "\";\n";
    }
    for (MessageKind kind : kAllMessageKinds) {
        for (const SignalDef& s : message_def(kind).signals) {
            if (s.values.empty())
                continue;
            out << "VAL_ " << ids.id(kind) << ' ' << s.name;
            for (const ValueName& v : s.values)
                out << ' ' << v.value << " \"" << v.name << '"';
            out << " ;\n";
        }
    }
}

}  // namespace stemd::protocol
