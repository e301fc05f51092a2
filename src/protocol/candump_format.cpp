#include "stemd/protocol/candump_format.hpp"

#include <array>
#include <limits>

namespace stemd::protocol {

namespace {

constexpr char kHex[] = "0123456789ABCDEF";

// A bounded writer into a char span.
class Writer {
public:
    explicit Writer(std::span<char> out) : out_(out) {}

    void put(char c)
    {
        if (n_ < out_.size())
            out_[n_] = c;
        ++n_;
    }
    void put(std::string_view s)
    {
        for (char c : s)
            put(c);
    }
    // Decimal, zero-padded to at least `width` digits.
    void put_dec(std::uint64_t v, int width)
    {
        std::array<char, 20> digits{};
        int n = 0;
        do {
            digits[static_cast<std::size_t>(n++)] = static_cast<char>('0' + v % 10);
            v /= 10;
        } while (v != 0);
        for (int i = n; i < width; ++i)
            put('0');
        while (n > 0)
            put(digits[static_cast<std::size_t>(--n)]);
    }
    // Upper-case hex, exactly `digits` digits.
    void put_hex(std::uint32_t v, int digits)
    {
        for (int i = digits - 1; i >= 0; --i)
            put(kHex[(v >> (4 * i)) & 0xF]);
    }
    bool fits() const { return n_ <= out_.size(); }
    std::size_t size() const { return n_; }

private:
    std::span<char> out_;
    std::size_t n_ = 0;
};

int hex_value(char c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    return -1;
}

bool is_space(char c) { return c == ' ' || c == '\t'; }

void skip_spaces(std::string_view line, std::size_t& pos)
{
    while (pos < line.size() && is_space(line[pos]))
        ++pos;
}

// The word at `pos` after any spaces; `pos` moves past it.
std::string_view next_word(std::string_view line, std::size_t& pos)
{
    skip_spaces(line, pos);
    const std::size_t begin = pos;
    while (pos < line.size() && !is_space(line[pos]))
        ++pos;
    return line.substr(begin, pos - begin);
}

bool fail(std::string& error, std::string_view reason)
{
    error.assign(reason);
    return false;
}

}  // namespace

bool valid_interface_name(std::string_view name)
{
    if (name.empty() || name.size() > kInterfaceNameMax)
        return false;
    for (char c : name) {
        if (static_cast<unsigned char>(c) <= ' ' || c == '(' || c == ')' || c == '#' || c == 0x7F)
            return false;
    }
    return true;
}

std::size_t format_candump_line(std::span<char> out, std::uint64_t time_us, std::string_view interface,
                                const CanFrame& frame)
{
    if (!valid_interface_name(interface) || frame.dlc > 8 ||
        frame.id > (frame.extended ? kMaxExtendedId : kMaxStandardId))
        return 0;
    Writer w(out);
    w.put('(');
    w.put_dec(time_us / 1000000, 10);
    w.put('.');
    w.put_dec(time_us % 1000000, 6);
    w.put(") ");
    w.put(interface);
    w.put(' ');
    w.put_hex(frame.id, frame.extended ? 8 : 3);
    w.put('#');
    for (std::size_t i = 0; i < frame.dlc; ++i)
        w.put_hex(frame.data[i], 2);
    return w.fits() ? w.size() : 0;
}

std::string format_candump_line(std::uint64_t time_us, std::string_view interface, const CanFrame& frame)
{
    std::array<char, kCandumpLineMax> buf{};
    const std::size_t n = format_candump_line(buf, time_us, interface, frame);
    return std::string(buf.data(), n);
}

bool parse_candump_line(std::string_view line, CandumpRecord& out, std::string& error)
{
    if (!line.empty() && line.back() == '\n')
        line.remove_suffix(1);
    if (!line.empty() && line.back() == '\r')
        line.remove_suffix(1);

    // "(sec.usec)"
    if (line.empty() || line.front() != '(')
        return fail(error, "expected '(' and a timestamp");
    const std::size_t close = line.find(')');
    if (close == std::string_view::npos)
        return fail(error, "expected ')' after the timestamp");
    const std::string_view stamp = line.substr(1, close - 1);
    const std::size_t dot = stamp.find('.');
    if (dot == std::string_view::npos || dot == 0 || stamp.size() - dot - 1 != 6)
        return fail(error, "timestamp must be seconds.microseconds with 6 digits of microseconds");
    // time_us = sec * 1000000 + usec must fit 64 bits.
    constexpr std::uint64_t kMaxUs = std::numeric_limits<std::uint64_t>::max();
    constexpr std::uint64_t kMaxSec = kMaxUs / 1000000;
    std::uint64_t sec = 0;
    for (char c : stamp.substr(0, dot)) {
        if (c < '0' || c > '9')
            return fail(error, "timestamp: not a number");
        const auto d = static_cast<std::uint64_t>(c - '0');
        if (sec > (kMaxSec - d) / 10)
            return fail(error, "timestamp: too large");
        sec = sec * 10 + d;
    }
    std::uint64_t usec = 0;
    for (char c : stamp.substr(dot + 1)) {
        if (c < '0' || c > '9')
            return fail(error, "timestamp: not a number");
        usec = usec * 10 + static_cast<std::uint64_t>(c - '0');
    }
    if (sec == kMaxSec && usec > kMaxUs % 1000000)
        return fail(error, "timestamp: too large");

    // " interface "
    std::size_t pos = close + 1;
    if (pos >= line.size() || !is_space(line[pos]))
        return fail(error, "expected a space after the timestamp");
    const std::string_view iface = next_word(line, pos);
    if (!valid_interface_name(iface))
        return fail(error, "bad interface name");

    // "ID#DATA" [ " T" | " R" ]
    const std::string_view text = next_word(line, pos);
    skip_spaces(line, pos);
    const std::string_view rest = line.substr(pos);
    if (!rest.empty() && rest != "T" && rest != "R")
        return fail(error, "unexpected text after the frame");

    const std::size_t hash = text.find('#');
    if (hash == std::string_view::npos)
        return fail(error, "expected ID#DATA");
    const std::string_view id_text = text.substr(0, hash);
    std::string_view data_text = text.substr(hash + 1);
    if (!data_text.empty() && data_text.front() == '#')
        return fail(error, "CAN FD frames are not supported");
    if (!data_text.empty() && (data_text.front() == 'R' || data_text.front() == 'r'))
        return fail(error, "remote frames are not supported");
    if (id_text.size() != 3 && id_text.size() != 8)
        return fail(error, "identifier must have 3 (11-bit) or 8 (29-bit) hex digits");
    std::uint32_t id = 0;
    for (char c : id_text) {
        const int v = hex_value(c);
        if (v < 0)
            return fail(error, "identifier: not hex");
        id = (id << 4) | static_cast<std::uint32_t>(v);
    }
    const bool extended = id_text.size() == 8;
    if (id > (extended ? kMaxExtendedId : kMaxStandardId))
        return fail(error, extended ? "29-bit identifier out of range (error frame?)" : "11-bit identifier out of range");
    if (data_text.size() % 2 != 0 || data_text.size() > 16)
        return fail(error, "data must be 0 to 8 bytes of 2 hex digits each");

    CanFrame f;
    f.id = id;
    f.extended = extended;
    f.dlc = static_cast<std::uint8_t>(data_text.size() / 2);
    for (std::size_t i = 0; i < f.dlc; ++i) {
        const int hi = hex_value(data_text[2 * i]);
        const int lo = hex_value(data_text[2 * i + 1]);
        if (hi < 0 || lo < 0)
            return fail(error, "data: not hex");
        f.data[i] = static_cast<std::uint8_t>(hi << 4 | lo);
    }
    out.time_us = sec * 1000000 + usec;
    out.interface.assign(iface);
    out.frame = f;
    return true;
}

}  // namespace stemd::protocol
