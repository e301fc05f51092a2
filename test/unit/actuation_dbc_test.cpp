// config/stemd.dbc against the C++ encoder, field by field, plus the DBC reader itself.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "stemd/actuation/crc8.hpp"
#include "stemd/actuation/dbc.hpp"
#include "stemd/actuation/e2e.hpp"
#include "stemd/actuation/messages.hpp"

using namespace stemd::actuation;

namespace {

const std::filesystem::path kDbcPath = std::filesystem::path(STEMD_SOURCE_DIR) / "config" / "stemd.dbc";

const dbc::Database& database()
{
    static const dbc::Database db = [] {
        std::string error;
        auto parsed = dbc::read_file(kDbcPath, error);
        EXPECT_TRUE(parsed) << error;
        return parsed ? *parsed : dbc::Database{};
    }();
    return db;
}

// One encoded frame and what every signal should read, keyed by the signal
// names the test expects (written here by hand, independently of the
// library's own layout table).
struct Sample {
    CanFrame frame;
    std::map<std::string, std::int64_t> expected;
};

std::uint8_t reference_crc(const CanFrame& f)
{
    std::vector<std::uint8_t> bytes{static_cast<std::uint8_t>(f.id & 0xFF), static_cast<std::uint8_t>(f.id >> 8)};
    bytes.insert(bytes.end(), f.data.begin() + 1, f.data.end());
    return crc8_sae_j1850(bytes);
}

template <typename Msg>
CanFrame encoded(const Msg& m, std::uint8_t counter)
{
    CanFrame f;
    const CodecResult r = encode(m, counter, CanIds{}, f);
    EXPECT_TRUE(r) << to_string(r.error) << " " << r.signal;
    return f;
}

Sample sample(const TargetCommand& t, std::uint8_t counter)
{
    return {encoded(t, counter),
            {{"e2e_counter", counter},
             {"target_id", t.target_id},
             {"tool_id", t.tool_id},
             {"lane", t.lane},
             {"fire_odom_mm", t.fire_odom_mm % 262144},
             {"lateral_mm", t.lateral_mm},
             {"plant_class", static_cast<int>(t.plant_class)}}};
}

Sample sample(const Odometry& o, std::uint8_t counter)
{
    return {encoded(o, counter), {{"e2e_counter", counter}, {"odom_mm", o.odom_mm}, {"speed_mm_per_s", o.speed_mm_per_s}}};
}

Sample sample(const ToolStatus& s, std::uint8_t counter)
{
    return {encoded(s, counter),
            {{"e2e_counter", counter},
             {"tools_ready_mask", s.tools_ready_mask},
             {"last_target_id", s.last_target_id},
             {"last_target_valid", s.last_target_valid ? 1 : 0},
             {"error_code", s.error_code},
             {"targets_executed", s.targets_executed}}};
}

Sample sample(const Heartbeat& h, std::uint8_t counter)
{
    return {encoded(h, counter),
            {{"e2e_counter", counter},
             {"state", static_cast<int>(h.state)},
             {"targets_sent", static_cast<std::int64_t>(h.targets_sent % 65536)},
             {"deadline_misses", static_cast<std::int64_t>(std::min<std::uint64_t>(h.deadline_misses, 4095))},
             {"targets_dropped", static_cast<std::int64_t>(std::min<std::uint64_t>(h.targets_dropped, 4095))},
             {"rx_rejected", static_cast<std::int64_t>(std::min<std::uint64_t>(h.rx_rejected, 255))}}};
}

// Limits, then random values, for every message.
std::vector<Sample> samples()
{
    std::vector<Sample> out;
    std::mt19937 rng(99);
    auto counter = [&] { return static_cast<std::uint8_t>(rng() % 15); };
    out.push_back(sample(TargetCommand{0, 0, 0, 0, -2047, PlantClass::Unknown}, 0));
    out.push_back(sample(TargetCommand{4095, 15, 15, 262143, 2047, PlantClass::Weed}, 14));
    out.push_back(sample(TargetCommand{0xA5A, 0xA, 0x5, 0x2A5A5, -1, PlantClass::Crop}, 5));
    out.push_back(sample(Odometry{0, -32767}, 0));
    out.push_back(sample(Odometry{0xFFFFFFFFu, 32767}, 14));
    out.push_back(sample(ToolStatus{}, 0));
    out.push_back(sample(ToolStatus{0xFFFF, 4095, true, 255, 255}, 14));
    out.push_back(sample(Heartbeat{DaemonState::Starting, 0, 0, 0, 0}, 0));
    out.push_back(sample(Heartbeat{DaemonState::Fault, 70000, 9999, 4095, 300}, 14));
    for (int i = 0; i < 200; ++i) {
        out.push_back(sample(TargetCommand{static_cast<std::uint16_t>(rng() % 4096), static_cast<std::uint8_t>(rng() % 16),
                                           static_cast<std::uint8_t>(rng() % 16), static_cast<std::uint32_t>(rng()),
                                           static_cast<std::int16_t>(static_cast<int>(rng() % 4095) - 2047),
                                           static_cast<PlantClass>(rng() % 3)},
                             counter()));
        out.push_back(sample(Odometry{static_cast<std::uint32_t>(rng()),
                                      static_cast<std::int16_t>(static_cast<int>(rng() % 65535) - 32767)},
                             counter()));
        out.push_back(sample(ToolStatus{static_cast<std::uint16_t>(rng()), static_cast<std::uint16_t>(rng() % 4096),
                                        rng() % 2 == 0, static_cast<std::uint8_t>(rng()), static_cast<std::uint8_t>(rng())},
                             counter()));
        out.push_back(sample(Heartbeat{static_cast<DaemonState>(rng() % 5), rng(), rng() % 5000, rng() % 5000, rng() % 300},
                             counter()));
    }
    return out;
}

std::set<std::string> names_of(const dbc::Message& m)
{
    std::set<std::string> names;
    for (const auto& s : m.signals)
        names.insert(s.name);
    return names;
}

}  // namespace

TEST(Dbc, FileParsesWithNodesAndMessages)
{
    const dbc::Database& db = database();
    EXPECT_FALSE(db.version.empty());
    EXPECT_EQ(db.nodes, (std::vector<std::string>{"STEMD", "DRIVE", "TOOL"}));
    EXPECT_EQ(db.messages.size(), kMessageKindCount);
    EXPECT_FALSE(db.comment.empty());
    for (const auto& node : db.nodes)
        EXPECT_TRUE(db.node_comments.count(node)) << node;
}

// Every message of the encoder is in the DBC with the same identifier (for
// the default base), DLC, transmitter, receivers and signal set, and every
// signal has the same bits, sign, scale, range, unit and value names.
TEST(Dbc, LayoutAgreesWithEncoder)
{
    const dbc::Database& db = database();
    const CanIds ids;
    for (MessageKind kind : kAllMessageKinds) {
        const MessageDef& def = message_def(kind);
        SCOPED_TRACE(std::string(def.name));
        const dbc::Message* m = db.message(def.name);
        ASSERT_NE(m, nullptr);
        EXPECT_EQ(m->id, ids.id(kind));
        EXPECT_FALSE(m->extended);
        EXPECT_EQ(m->dlc, 8u);
        EXPECT_EQ(m->transmitter, def.transmitter);
        EXPECT_FALSE(m->comment.empty());

        std::set<std::string> encoder_names;
        for (const SignalDef& s : def.signals)
            encoder_names.insert(std::string(s.name));
        EXPECT_EQ(names_of(*m), encoder_names);

        for (const SignalDef& s : def.signals) {
            SCOPED_TRACE(std::string(s.name));
            const dbc::Signal* d = m->signal(s.name);
            ASSERT_NE(d, nullptr);
            EXPECT_EQ(d->start_bit, s.start_bit);
            EXPECT_EQ(d->length, s.length);
            EXPECT_TRUE(d->little_endian);
            EXPECT_EQ(d->is_signed, s.is_signed);
            EXPECT_EQ(d->factor, 1.0);
            EXPECT_EQ(d->offset, 0.0);
            EXPECT_EQ(d->min, static_cast<double>(s.min));
            EXPECT_EQ(d->max, static_cast<double>(s.max));
            EXPECT_EQ(d->unit, s.unit);
            EXPECT_TRUE(d->fits(m->dlc));
            EXPECT_FALSE(d->comment.empty());
            std::vector<std::string> receivers(def.receivers.begin(), def.receivers.end());
            EXPECT_EQ(d->receivers, receivers);
            std::map<std::int64_t, std::string> values;
            for (const ValueName& v : s.values)
                values.emplace(v.value, std::string(v.name));
            EXPECT_EQ(d->values, values);
        }
    }
    // No message in the DBC that the encoder lacks.
    for (const dbc::Message& m : db.messages) {
        bool known = false;
        for (MessageKind kind : kAllMessageKinds)
            known = known || message_def(kind).name == m.name;
        EXPECT_TRUE(known) << m.name;
    }
}

// The heart of it: encode with the C++ encoder, read the bits back with the
// DBC's definitions, compare with the values put in.
TEST(Dbc, EncodedFramesDecodePerDbc)
{
    const dbc::Database& db = database();
    int checked = 0;
    for (const Sample& s : samples()) {
        const dbc::Message* m = db.message_by_id(s.frame.id);
        ASSERT_NE(m, nullptr) << std::hex << s.frame.id;
        SCOPED_TRACE(m->name);
        ASSERT_EQ(s.frame.dlc, m->dlc);
        // Every DBC signal is one the test knows a value for, and vice versa.
        std::set<std::string> expected_names{"e2e_crc"};
        for (const auto& [name, value] : s.expected)
            expected_names.insert(name);
        ASSERT_EQ(names_of(*m), expected_names);
        for (const dbc::Signal& sig : m->signals) {
            const double value = sig.physical(s.frame.data);
            const double want = sig.name == "e2e_crc" ? reference_crc(s.frame) : static_cast<double>(s.expected.at(sig.name));
            ASSERT_EQ(value, want) << sig.name;
            EXPECT_GE(value, sig.min) << sig.name;
            EXPECT_LE(value, sig.max) << sig.name;
            ++checked;
        }
    }
    EXPECT_GT(checked, 5000);
}

// ---- the reader itself ----

TEST(DbcReader, MotorolaSignedAndScaledSignals)
{
    const std::string text =
        "VERSION \"\"\n"
        "NS_ :\n\tCM_\n\tVAL_\n\n"
        "BS_:\n"
        "BU_: A B\n"
        "BO_ 2147484672 EXT: 4 A\n"  // 0x400 | 0x80000000: extended
        " SG_ be16 : 7|16@0+ (0.5,-10) [-10|22757.5] \"km/h\" B\n"
        " SG_ s4 : 16|4@1- (1e-1,0) [-0.8|0.7] \"\" Vector__XXX\n"
        " SG_ be_s12 : 27|12@0- (1,0) [-2048|2047] \"\" A,B\n"
        "CM_ SG_ 2147484672 be16 \"a comment\n over two lines\";\n"
        "BA_DEF_ BO_ \"GenMsgCycleTime\" INT 0 10000;\n"
        "BA_ \"GenMsgCycleTime\" BO_ 2147484672 100;\n"
        "VAL_ 2147484672 s4 -1 \"minus one\" 0 \"zero\" ;\n";
    std::string error;
    const auto db = dbc::parse(text, error);
    ASSERT_TRUE(db) << error;
    const dbc::Message* m = db->message_by_id(0x400, true);
    ASSERT_NE(m, nullptr);
    EXPECT_EQ(m->dlc, 4u);
    const std::array<std::uint8_t, 4> data{0x12, 0x34, 0xAB, 0xCD};
    const dbc::Signal* be16 = m->signal("be16");
    ASSERT_NE(be16, nullptr);
    EXPECT_FALSE(be16->little_endian);
    EXPECT_EQ(be16->raw(data), 0x1234);
    EXPECT_DOUBLE_EQ(be16->physical(data), 0x1234 * 0.5 - 10);
    EXPECT_EQ(be16->unit, "km/h");
    EXPECT_EQ(be16->receivers, std::vector<std::string>{"B"});
    EXPECT_EQ(be16->comment, "a comment\n over two lines");
    const dbc::Signal* s4 = m->signal("s4");
    EXPECT_EQ(s4->raw(data), -5);  // low nibble of 0xAB = 0xB
    EXPECT_DOUBLE_EQ(s4->physical(data), -0.5);
    EXPECT_TRUE(s4->receivers.empty());
    EXPECT_EQ(s4->values.at(-1), "minus one");
    // Motorola, MSB at bit 27 (byte 3, bit 3): bits 27..24 of byte 3 then byte 4 -> needs 5 bytes.
    const dbc::Signal* be_s12 = m->signal("be_s12");
    EXPECT_FALSE(be_s12->fits(4));
    EXPECT_TRUE(be_s12->fits(5));
    const std::array<std::uint8_t, 5> data5{0, 0, 0, 0x08, 0x01};  // 1000 0000 0001
    EXPECT_EQ(be_s12->raw(data5), -2047);
    EXPECT_EQ(be_s12->receivers, (std::vector<std::string>{"A", "B"}));
}

TEST(DbcReader, ErrorsNameTheLine)
{
    std::string error;
    EXPECT_FALSE(dbc::parse("VERSION \"\"\nBU_: A\nFOO_ 1;\n", error));
    EXPECT_EQ(error, "line 3: unknown keyword 'FOO_'");
    EXPECT_FALSE(dbc::parse("BO_ 1 M: 8 A\n SG_ x m1 : 0|8@1+ (1,0) [0|1] \"\" A\n", error));
    EXPECT_EQ(error, "line 2: multiplexed signal 'x' is not supported");
    EXPECT_FALSE(dbc::parse("BO_ 1 M: 8 A\n SG_ x : 0|8@2+ (1,0) [0|1] \"\" A\n", error));
    EXPECT_EQ(error, "line 2: byte order must be 0 or 1");
    EXPECT_FALSE(dbc::parse("BO_ 1 M: 8 A\n SG_ x : 0|8@1+ (1,0) [0|1 \"\" A\n", error));
    EXPECT_EQ(error, "line 2: expected ']' near '\"\"'");
    EXPECT_FALSE(dbc::parse(" SG_ x : 0|8@1+ (1,0) [0|1] \"\" A\n", error));
    EXPECT_EQ(error, "line 1: SG_ before any BO_");
    EXPECT_FALSE(dbc::parse("CM_ \"open\n", error));
    EXPECT_EQ(error, "line 1: unterminated string");  // where it opens
    EXPECT_FALSE(dbc::parse("BO_ 1 M: 8 A\nVAL_ 1 nope 0 \"x\" ;\n", error));
    EXPECT_EQ(error, "line 2: VAL_ for unknown signal M.nope");
    EXPECT_FALSE(dbc::parse("BO_ 1 M: 8 A\nSIG_VALTYPE_ 1 x : 1;\n", error));
    EXPECT_EQ(error, "line 2: SIG_VALTYPE_ (float signals) is not supported");

    EXPECT_FALSE(dbc::parse("BO_ 1 M: 8 A\n SG_ x : 0|8@1+ (1,0) [0|1] \"\" A\n SG_ x : 8|8@1+ (1,0) [0|1] \"\" A\n\n", error));
    EXPECT_EQ(error, "line 3: duplicate signal 'x' in M");
    EXPECT_FALSE(dbc::parse("BO_ 1 M: 8 A\nBO_ 1 N: 8 A\n", error));
    EXPECT_EQ(error, "line 2: duplicate message 'N' or identifier 1");

    EXPECT_FALSE(dbc::read_file("/nonexistent/x.dbc", error));
    EXPECT_EQ(error, "/nonexistent/x.dbc: cannot open");
}

// An independent reader, if installed (Debian: python3-canmatrix): it must
// read the file and decode the encoder's frames to the same values.
TEST(Dbc, CanmatrixAgrees)
{
    const char* python = "/usr/bin/python3";
    if (access(python, X_OK) != 0 || std::system("/usr/bin/python3 -c 'import canmatrix.formats' >/dev/null 2>&1") != 0)
        GTEST_SKIP() << "python3-canmatrix is not installed";

    const auto dir = std::filesystem::temp_directory_path() / ("stemd-dbc-test-" + std::to_string(getpid()));
    std::filesystem::create_directories(dir);
    {
        std::ofstream frames(dir / "frames.txt");
        for (const Sample& s : samples()) {
            char hex[17];
            for (std::size_t i = 0; i < 8; ++i)
                std::snprintf(hex + 2 * i, 3, "%02X", s.frame.data[i]);
            frames << s.frame.id << ' ' << hex << " e2e_crc=" << int{reference_crc(s.frame)};
            for (const auto& [name, value] : s.expected)
                frames << ' ' << name << '=' << value;
            frames << '\n';
        }
        std::ofstream script(dir / "check.py");
        script << R"PY(
import sys, logging
logging.disable(logging.CRITICAL)
import canmatrix, canmatrix.formats
db = canmatrix.formats.loadp_flat(sys.argv[1])
names = sorted(f.name for f in db.frames)
if names != ["HEARTBEAT", "ODOMETRY", "TARGET", "TOOL_STATUS"]:
    sys.exit("frames: %s" % names)
bad = 0
for line in open(sys.argv[2]):
    parts = line.split()
    frame = db.frame_by_id(canmatrix.ArbitrationId(int(parts[0])))
    decoded = frame.decode(bytes.fromhex(parts[1]))
    want = dict(p.split("=") for p in parts[2:])
    got = {k: int(v.phys_value) for k, v in decoded.items()}
    if got != {k: int(v) for k, v in want.items()}:
        bad += 1
        if bad <= 5:
            print("mismatch", frame.name, got, want)
sys.exit(1 if bad else 0)
)PY";
    }
    const std::string cmd = std::string(python) + " " + (dir / "check.py").string() + " " + kDbcPath.string() + " " +
                            (dir / "frames.txt").string();
    const int rc = std::system(cmd.c_str());
    std::filesystem::remove_all(dir);
    EXPECT_EQ(rc, 0) << cmd;
}
