#include "stemd/actuation/dbc.hpp"

#include <charconv>
#include <fstream>
#include <sstream>

namespace stemd::actuation::dbc {

namespace {

enum class Tok { End, Ident, Number, String, Punct };

struct Token {
    Tok kind = Tok::End;
    std::string text;  // identifier, number as written, string without quotes, or the punctuation char
    int line = 0;
    int column = 0;  // 0-based
};

bool ident_start(char c) { return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || c == '_'; }
bool digit(char c) { return c >= '0' && c <= '9'; }

class Lexer {
public:
    explicit Lexer(std::string_view text) : text_(text) {}

    // Returns false on a lexical error (message in error_).
    bool next(Token& t)
    {
        skip_space();
        t = Token{};
        t.line = line_;
        t.column = static_cast<int>(pos_ - line_start_);
        if (pos_ >= text_.size())
            return true;
        const char c = text_[pos_];
        if (c == '"') {
            ++pos_;
            t.kind = Tok::String;
            while (true) {
                if (pos_ >= text_.size()) {
                    error_ = "unterminated string";
                    return false;
                }
                const char d = text_[pos_++];
                if (d == '"')
                    break;
                if (d == '\\' && pos_ < text_.size()) {
                    t.text += text_[pos_++];
                    continue;
                }
                if (d == '\n')
                    newline();
                t.text += d;
            }
            return true;
        }
        if (ident_start(c)) {
            t.kind = Tok::Ident;
            while (pos_ < text_.size() && (ident_start(text_[pos_]) || digit(text_[pos_])))
                t.text += text_[pos_++];
            return true;
        }
        const bool signed_number = (c == '-' || c == '+') && pos_ + 1 < text_.size() &&
                                   (digit(text_[pos_ + 1]) || text_[pos_ + 1] == '.');
        if (digit(c) || c == '.' || signed_number) {
            t.kind = Tok::Number;
            t.text += text_[pos_++];
            while (pos_ < text_.size()) {
                const char d = text_[pos_];
                const bool exponent_sign = (d == '-' || d == '+') && !t.text.empty() &&
                                           (t.text.back() == 'e' || t.text.back() == 'E');
                if (!(digit(d) || d == '.' || d == 'e' || d == 'E' || exponent_sign))
                    break;
                t.text += d;
                ++pos_;
            }
            return true;
        }
        t.kind = Tok::Punct;
        t.text = std::string(1, c);
        ++pos_;
        return true;
    }

    const std::string& error() const { return error_; }

private:
    void newline()
    {
        ++line_;
        line_start_ = pos_;
    }
    void skip_space()
    {
        while (pos_ < text_.size()) {
            const char c = text_[pos_];
            if (c == '\n') {
                ++pos_;
                newline();
            } else if (c == ' ' || c == '\t' || c == '\r') {
                ++pos_;
            } else if (c == '/' && pos_ + 1 < text_.size() && text_[pos_ + 1] == '/') {
                while (pos_ < text_.size() && text_[pos_] != '\n')
                    ++pos_;
            } else {
                break;
            }
        }
    }

    std::string_view text_;
    std::size_t pos_ = 0;
    std::size_t line_start_ = 0;
    int line_ = 1;
    std::string error_;
};

class Parser {
public:
    explicit Parser(std::string_view text) : lex_(text) {}

    std::optional<Database> run(std::string& error)
    {
        if (!advance() || !parse_all()) {
            error = "line " + std::to_string(err_line_) + ": " + err_;
            return std::nullopt;
        }
        return std::move(db_);
    }

private:
    // ---- token helpers ----
    bool advance()
    {
        if (!lex_.next(tok_))
            return fail(lex_.error());
        return true;
    }
    bool fail(std::string reason)
    {
        if (err_.empty()) {
            err_ = std::move(reason);
            err_line_ = tok_.line;
        }
        return false;
    }
    bool fail_at(int line, std::string reason)
    {
        if (err_.empty()) {
            err_ = std::move(reason);
            err_line_ = line;
        }
        return false;
    }
    bool is_punct(char c) const { return tok_.kind == Tok::Punct && tok_.text.size() == 1 && tok_.text[0] == c; }
    bool expect_punct(char c)
    {
        if (!is_punct(c))
            return fail(std::string("expected '") + c + "'" + near());
        return advance();
    }
    std::string near() const
    {
        if (tok_.kind == Tok::End)
            return " at end of file";
        if (tok_.kind == Tok::String)
            return " near '\"" + tok_.text + "\"'";
        return " near '" + tok_.text + "'";
    }
    bool ident(std::string& out)
    {
        if (tok_.kind != Tok::Ident)
            return fail("expected a name" + near());
        out = tok_.text;
        return advance();
    }
    bool string(std::string& out)
    {
        if (tok_.kind != Tok::String)
            return fail("expected a string" + near());
        out = tok_.text;
        return advance();
    }
    template <typename T>
    bool integer(T& out)
    {
        if (tok_.kind != Tok::Number)
            return fail("expected an integer" + near());
        const char* b = tok_.text.data();
        const char* e = b + tok_.text.size();
        if (*b == '+')
            ++b;
        const auto r = std::from_chars(b, e, out);
        if (r.ec != std::errc{} || r.ptr != e)
            return fail("bad integer '" + tok_.text + "'");
        return advance();
    }
    bool real(double& out)
    {
        if (tok_.kind != Tok::Number)
            return fail("expected a number" + near());
        const char* b = tok_.text.data();
        const char* e = b + tok_.text.size();
        if (*b == '+')
            ++b;
        const auto r = std::from_chars(b, e, out);
        if (r.ec != std::errc{} || r.ptr != e)
            return fail("bad number '" + tok_.text + "'");
        return advance();
    }
    bool skip_statement()  // to and including the next ';'
    {
        while (tok_.kind != Tok::End && !is_punct(';'))
            if (!advance())
                return false;
        if (tok_.kind == Tok::End)
            return fail("expected ';' at end of file");
        return advance();
    }

    // ---- statements ----
    bool parse_all()
    {
        while (tok_.kind != Tok::End) {
            if (tok_.kind != Tok::Ident)
                return fail("expected a keyword" + near());
            const std::string kw = tok_.text;
            const int line = tok_.line;
            if (!advance())
                return false;
            bool ok = true;
            if (kw == "VERSION")
                ok = string(db_.version);
            else if (kw == "NS_")
                ok = parse_ns();
            else if (kw == "BS_")
                ok = parse_rest_of_line(line);
            else if (kw == "BU_")
                ok = parse_bu(line);
            else if (kw == "BO_")
                ok = parse_bo(line);
            else if (kw == "SG_")
                ok = parse_sg(line);
            else if (kw == "CM_")
                ok = parse_cm();
            else if (kw == "VAL_")
                ok = parse_val();
            else if (kw == "SIG_VALTYPE_")
                ok = fail("SIG_VALTYPE_ (float signals) is not supported");
            else if (kw == "BA_DEF_" || kw == "BA_DEF_DEF_" || kw == "BA_" || kw == "BA_DEF_REL_" ||
                     kw == "BA_REL_" || kw == "BA_DEF_DEF_REL_" || kw == "VAL_TABLE_" || kw == "BO_TX_BU_" ||
                     kw == "SIG_GROUP_" || kw == "EV_" || kw == "ENVVAR_DATA_" || kw == "SGTYPE_" ||
                     kw == "CAT_DEF_" || kw == "CAT_" || kw == "FILTER" || kw == "BU_SG_REL_" ||
                     kw == "BU_EV_REL_" || kw == "BU_BO_REL_" || kw == "SG_MUL_VAL_")
                ok = skip_statement();
            else
                ok = fail("unknown keyword '" + kw + "'");
            if (!ok)
                return false;
        }
        return true;
    }

    // NS_ : followed by indented symbol names, up to the next token in column 0.
    bool parse_ns()
    {
        if (!expect_punct(':'))
            return false;
        while (tok_.kind != Tok::End && tok_.column != 0)
            if (!advance())
                return false;
        return true;
    }

    bool parse_rest_of_line(int line)
    {
        while (tok_.kind != Tok::End && tok_.line == line)
            if (!advance())
                return false;
        return true;
    }

    bool parse_bu(int line)
    {
        if (!expect_punct(':'))
            return false;
        while (tok_.kind == Tok::Ident && tok_.line == line) {
            db_.nodes.push_back(tok_.text);
            if (!advance())
                return false;
        }
        return true;
    }

    bool parse_bo(int line)
    {
        Message m;
        std::uint32_t raw_id = 0;
        if (!integer(raw_id) || !ident(m.name) || !expect_punct(':') || !integer(m.dlc) || !ident(m.transmitter))
            return false;
        m.extended = (raw_id & 0x80000000u) != 0;
        m.id = raw_id & 0x7FFFFFFFu;
        if (m.transmitter == "Vector__XXX")
            m.transmitter.clear();
        if (db_.message(m.name) || db_.message_by_id(m.id, m.extended))
            return fail_at(line, "duplicate message '" + m.name + "' or identifier " + std::to_string(raw_id));
        db_.messages.push_back(std::move(m));
        return true;
    }

    bool parse_sg(int line)
    {
        if (db_.messages.empty())
            return fail("SG_ before any BO_");
        Signal s;
        if (!ident(s.name))
            return false;
        if (tok_.kind == Tok::Ident)  // "M" or "m<n>"
            return fail("multiplexed signal '" + s.name + "' is not supported");
        unsigned order = 0;
        if (!expect_punct(':') || !integer(s.start_bit) || !expect_punct('|') || !integer(s.length) ||
            !expect_punct('@') || !integer(order))
            return false;
        if (order > 1)
            return fail("byte order must be 0 or 1");
        s.little_endian = order == 1;
        if (is_punct('+'))
            s.is_signed = false;
        else if (is_punct('-'))
            s.is_signed = true;
        else
            return fail("expected '+' or '-'" + near());
        if (!advance())
            return false;
        if (!expect_punct('(') || !real(s.factor) || !expect_punct(',') || !real(s.offset) || !expect_punct(')') ||
            !expect_punct('[') || !real(s.min) || !expect_punct('|') || !real(s.max) || !expect_punct(']') ||
            !string(s.unit))
            return false;
        while (tok_.kind == Tok::Ident && tok_.line == line) {
            if (tok_.text != "Vector__XXX")
                s.receivers.push_back(tok_.text);
            if (!advance())
                return false;
            if (is_punct(',') && tok_.line == line && !advance())
                return false;
        }
        if (s.length == 0 || s.length > 64)
            return fail_at(line, "signal '" + s.name + "': length must be 1..64");
        Message& m = db_.messages.back();
        if (m.signal(s.name))
            return fail_at(line, "duplicate signal '" + s.name + "' in " + m.name);
        m.signals.push_back(std::move(s));
        return true;
    }

    static Signal* find_signal(Message& m, std::string_view name)
    {
        for (Signal& s : m.signals)
            if (s.name == name)
                return &s;
        return nullptr;
    }

    Message* find_message(std::uint32_t raw_id)
    {
        for (Message& m : db_.messages)
            if (m.id == (raw_id & 0x7FFFFFFFu) && m.extended == ((raw_id & 0x80000000u) != 0))
                return &m;
        return nullptr;
    }

    bool parse_cm()
    {
        std::string text;
        if (tok_.kind == Tok::String) {
            if (!string(db_.comment))
                return false;
        } else {
            std::string what;
            if (!ident(what))
                return false;
            if (what == "BU_") {
                std::string node;
                if (!ident(node) || !string(text))
                    return false;
                db_.node_comments[node] = text;
            } else if (what == "BO_" || what == "SG_") {
                std::uint32_t raw_id = 0;
                std::string sig;
                if (!integer(raw_id) || (what == "SG_" && !ident(sig)) || !string(text))
                    return false;
                Message* m = find_message(raw_id);
                if (!m)
                    return fail("CM_ for unknown message " + std::to_string(raw_id));
                if (what == "BO_") {
                    m->comment = text;
                } else {
                    Signal* s = find_signal(*m, sig);
                    if (!s)
                        return fail("CM_ for unknown signal " + m->name + "." + sig);
                    s->comment = text;
                }
            } else {
                return skip_statement();  // EV_ comments
            }
        }
        return expect_punct(';');
    }

    bool parse_val()
    {
        std::uint32_t raw_id = 0;
        std::string sig;
        if (!integer(raw_id) || !ident(sig))
            return false;
        Message* m = find_message(raw_id);
        if (!m)
            return fail("VAL_ for unknown message " + std::to_string(raw_id));
        Signal* s = find_signal(*m, sig);
        if (!s)
            return fail("VAL_ for unknown signal " + m->name + "." + sig);
        while (!is_punct(';')) {
            std::int64_t value = 0;
            std::string name;
            if (!integer(value) || !string(name))
                return false;
            if (!s->values.emplace(value, name).second)
                return fail("duplicate value " + std::to_string(value) + " in VAL_ of " + m->name + "." + sig);
        }
        return advance();
    }

    Lexer lex_;
    Token tok_;
    Database db_;
    std::string err_;
    int err_line_ = 0;
};

std::uint64_t bit_at(std::span<const std::uint8_t> data, unsigned pos)
{
    return (data[pos / 8] >> (pos % 8)) & 1u;
}

}  // namespace

bool Signal::fits(unsigned dlc) const
{
    if (length == 0 || length > 64)
        return false;
    if (little_endian)
        return start_bit + length <= 8 * dlc;
    // Motorola: walk from the MSB down to the LSB.
    unsigned pos = start_bit;
    for (unsigned i = 0; i + 1 < length; ++i) {
        if (pos % 8 == 0)
            pos += 15;
        else
            --pos;
    }
    return start_bit < 8 * dlc && pos < 8 * dlc;
}

std::int64_t Signal::raw(std::span<const std::uint8_t> data) const
{
    std::uint64_t value = 0;
    if (little_endian) {
        for (unsigned i = 0; i < length; ++i)
            value |= bit_at(data, start_bit + i) << i;
    } else {
        unsigned pos = start_bit;
        for (unsigned i = 0; i < length; ++i) {
            value = (value << 1) | bit_at(data, pos);
            if (pos % 8 == 0)
                pos += 15;
            else
                --pos;
        }
    }
    if (is_signed && length < 64 && (value >> (length - 1)) != 0)
        value |= ~std::uint64_t{0} << length;
    return static_cast<std::int64_t>(value);
}

double Signal::physical(std::span<const std::uint8_t> data) const
{
    const std::int64_t r = raw(data);
    const double v = is_signed ? static_cast<double>(r) : static_cast<double>(static_cast<std::uint64_t>(r));
    return v * factor + offset;
}

const Signal* Message::signal(std::string_view wanted) const
{
    for (const Signal& s : signals)
        if (s.name == wanted)
            return &s;
    return nullptr;
}

const Message* Database::message(std::string_view wanted) const
{
    for (const Message& m : messages)
        if (m.name == wanted)
            return &m;
    return nullptr;
}

const Message* Database::message_by_id(std::uint32_t id, bool extended) const
{
    for (const Message& m : messages)
        if (m.id == id && m.extended == extended)
            return &m;
    return nullptr;
}

std::optional<Database> parse(std::string_view text, std::string& error)
{
    return Parser(text).run(error);
}

std::optional<Database> read_file(const std::filesystem::path& path, std::string& error)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        error = path.string() + ": cannot open";
        return std::nullopt;
    }
    std::ostringstream ss;
    ss << in.rdbuf();
    std::string parse_error;
    auto db = parse(ss.str(), parse_error);
    if (!db) {
        // "line N: reason" -> "<path>:N: reason"
        constexpr std::string_view kLine = "line ";
        if (parse_error.rfind(kLine, 0) == 0)
            error = path.string() + ":" + parse_error.substr(kLine.size());
        else
            error = path.string() + ": " + parse_error;
    }
    return db;
}

}  // namespace stemd::actuation::dbc
