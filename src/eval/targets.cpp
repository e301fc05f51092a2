#include "stemd/eval/targets.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>

#include "stemd/protocol/candump_format.hpp"
#include "stemd/eval/eval.hpp"
#include "stemd/io/csv.hpp"

namespace stemd::eval {

namespace {

// p in [0, 1] of sorted values, nearest rank.
double percentile(const std::vector<double>& sorted, double p)
{
    if (sorted.empty())
        return 0;
    const auto rank = static_cast<std::size_t>(std::ceil(p * static_cast<double>(sorted.size())));
    return sorted[std::clamp<std::size_t>(rank, 1, sorted.size()) - 1];
}

}  // namespace

std::optional<std::vector<TruthPlant>> read_truth_plants(const std::filesystem::path& csv, std::string& error)
{
    const auto table = io::read_csv(csv, error);
    if (!table)
        return std::nullopt;
    const int col_id = table->column("id"), col_s = table->column("s_mm"), col_y = table->column("y_mm"),
              col_kind = table->column("kind"), col_radius = table->column("radius_mm");
    if (col_id < 0 || col_s < 0 || col_y < 0 || col_kind < 0) {
        error = csv.string() + ":1: expected columns id, s_mm, y_mm, kind";
        return std::nullopt;
    }
    std::vector<TruthPlant> plants;
    for (const auto& row : table->rows) {
        const auto cell = [&](int col) -> const std::string& { return row.fields[static_cast<std::size_t>(col)]; };
        const std::string where = csv.string() + ":" + std::to_string(row.line) + ": ";
        TruthPlant p;
        double id = 0;
        if (!parse_finite(cell(col_id), id) || !parse_finite(cell(col_s), p.s_mm) || !parse_finite(cell(col_y), p.y_mm)) {
            error = where + "expected id, s_mm and y_mm numbers";
            return std::nullopt;
        }
        if (col_radius >= 0 && !parse_finite(cell(col_radius), p.radius_mm)) {
            error = where + "radius_mm is not a number";
            return std::nullopt;
        }
        p.id = static_cast<long>(id);
        p.kind = parse_plant_class(cell(col_kind)).value_or(PlantClass::Unknown);
        plants.push_back(p);
    }
    return plants;
}

std::optional<TargetLog> read_target_log(const std::filesystem::path& log, const protocol::CanIds& ids,
                                         std::string& error)
{
    std::ifstream in(log);
    if (!in) {
        error = log.string() + ": cannot read";
        return std::nullopt;
    }
    TargetLog out;
    double speed = std::numeric_limits<double>::quiet_NaN();
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
        if (line.empty())
            continue;
        protocol::CandumpRecord record;
        std::string why;
        if (!protocol::parse_candump_line(line, record, why)) {
            error = log.string() + ":" + std::to_string(n) + ": " + why;
            return std::nullopt;
        }
        const auto kind = ids.kind_of(record.frame);
        if (kind == protocol::MessageKind::Odometry) {
            if (protocol::Odometry o; protocol::decode(record.frame, ids, o))
                speed = o.speed_mm_per_s;
        } else if (kind == protocol::MessageKind::ToolFired) {
            // The newest TARGET for this target and tool that has none yet.
            if (protocol::ToolFired f; protocol::decode(record.frame, ids, f))
                for (std::size_t i = out.targets.size(); i-- > 0;)
                    if (out.targets[i].target_id == f.target_id && out.targets[i].tool_id == f.tool_id) {
                        if (std::isnan(out.fired_odom_mm[i]))
                            out.fired_odom_mm[i] = f.fired_odom_mm;
                        break;
                    }
        }
        if (kind != protocol::MessageKind::Target) {
            ++out.other_frames;
            continue;
        }
        protocol::TargetCommand t;
        if (!protocol::decode(record.frame, ids, t)) {
            ++out.bad_targets;
            continue;
        }
        out.targets.push_back(t);
        out.speed_mm_per_s.push_back(speed);
        out.fired_odom_mm.push_back(std::numeric_limits<double>::quiet_NaN());
    }
    return out;
}

namespace {

// a - b modulo 2^18, into [-2^17, 2^17).
double wrapped_difference(double a, double b)
{
    constexpr double kModulo = protocol::kFireOdomModulo;
    double d = std::fmod(a - b, kModulo);
    if (d < -kModulo / 2)
        d += kModulo;
    if (d >= kModulo / 2)
        d -= kModulo;
    return d;
}

}  // namespace

std::vector<double> target_leads_mm(const TargetLog& log, const std::array<double, 16>& tool_latency_ms,
                                    double default_speed_mm_per_s)
{
    std::vector<double> leads(log.targets.size(), 0.0);
    for (std::size_t i = 0; i < log.targets.size(); ++i) {
        const protocol::TargetCommand& t = log.targets[i];
        if (i < log.fired_odom_mm.size() && !std::isnan(log.fired_odom_mm[i])) {
            leads[i] = wrapped_difference(log.fired_odom_mm[i], t.fire_odom_mm);
            continue;
        }
        const double speed = i < log.speed_mm_per_s.size() && !std::isnan(log.speed_mm_per_s[i])
            ? log.speed_mm_per_s[i]
            : default_speed_mm_per_s;
        const double latency = tool_latency_ms[t.tool_id & 15U];
        // Standing or reversing: stemd commands no lead (fire_lag.hpp).
        leads[i] = std::isfinite(latency) && speed > 0 ? speed * latency * 1e-3 : 0.0;
    }
    return leads;
}

TargetScore score_targets(std::span<const TruthPlant> plants, std::span<const protocol::TargetCommand> commands,
                          const std::array<double, 16>& tool_offset_mm, double tol_mm, std::span<const double> lead_mm)
{
    TargetScore score;
    score.plants = plants.size();
    score.commands = commands.size();
    struct Pair {
        double d;
        double along;
        double lateral;
        std::size_t cmd, plant;
    };
    std::vector<Pair> pairs;
    std::vector<bool> known_tool(commands.size(), false);
    for (std::size_t c = 0; c < commands.size(); ++c) {
        const double offset = tool_offset_mm[commands[c].tool_id & 15U];
        if (!std::isfinite(offset)) {
            ++score.unknown_tool;
            continue;
        }
        known_tool[c] = true;
        for (std::size_t p = 0; p < plants.size(); ++p) {
            // Along-track error of the strike point, modulo 2^18.
            const double lead = c < lead_mm.size() ? lead_mm[c] : 0.0;
            const double along = wrapped_difference(commands[c].fire_odom_mm + lead, plants[p].s_mm + offset);
            const double lateral = commands[c].lateral_mm - plants[p].y_mm;
            const double d = std::hypot(along, lateral);
            if (d <= tol_mm)
                pairs.push_back({d, along, lateral, c, p});
        }
    }
    std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
        return a.d != b.d ? a.d < b.d : a.cmd != b.cmd ? a.cmd < b.cmd : a.plant < b.plant;
    });
    std::vector<bool> cmd_used(commands.size(), false), plant_used(plants.size(), false);
    std::vector<double> errors, along, lateral;
    for (const Pair& pr : pairs) {
        if (cmd_used[pr.cmd] || plant_used[pr.plant])
            continue;
        cmd_used[pr.cmd] = plant_used[pr.plant] = true;
        errors.push_back(pr.d);
        along.push_back(std::abs(pr.along));
        lateral.push_back(std::abs(pr.lateral));
    }
    score.matched = errors.size();
    score.missed = plants.size() - score.matched;
    // Unmatched commands: a duplicate if within tol of some plant, else extra.
    std::vector<bool> near_plant(commands.size(), false);
    for (const Pair& pr : pairs)
        near_plant[pr.cmd] = true;
    for (std::size_t c = 0; c < commands.size(); ++c)
        if (!cmd_used[c])
            ++(known_tool[c] && near_plant[c] ? score.duplicates : score.extra);
    for (auto* v : {&errors, &along, &lateral})
        std::sort(v->begin(), v->end());
    score.error_p50_mm = percentile(errors, 0.5);
    score.error_p95_mm = percentile(errors, 0.95);
    score.error_max_mm = errors.empty() ? 0 : errors.back();
    score.along_p50_mm = percentile(along, 0.5);
    score.lateral_p50_mm = percentile(lateral, 0.5);
    return score;
}

}  // namespace stemd::eval
