#include "stemd/eval/targets.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>

#include "stemd/actuation/candump_format.hpp"

namespace stemd::eval {

namespace {

std::vector<std::string> split(const std::string& line)
{
    std::vector<std::string> out;
    std::string cell;
    for (const char c : line) {
        if (c == ',') {
            out.push_back(cell);
            cell.clear();
        } else if (c != '\r') {
            cell += c;
        }
    }
    out.push_back(cell);
    return out;
}

bool to_double(const std::string& s, double& out)
{
    try {
        std::size_t used = 0;
        out = std::stod(s, &used);
        return used == s.size() && std::isfinite(out);
    } catch (...) {
        return false;
    }
}

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
    std::ifstream in(csv);
    if (!in) {
        error = csv.string() + ": cannot read";
        return std::nullopt;
    }
    std::string line;
    if (!std::getline(in, line)) {
        error = csv.string() + ":1: empty file";
        return std::nullopt;
    }
    const auto header = split(line);
    int col_id = -1, col_s = -1, col_y = -1, col_kind = -1, col_radius = -1;
    for (int i = 0; i < static_cast<int>(header.size()); ++i) {
        const std::string& h = header[static_cast<std::size_t>(i)];
        if (h == "id")
            col_id = i;
        else if (h == "s_mm")
            col_s = i;
        else if (h == "y_mm")
            col_y = i;
        else if (h == "kind")
            col_kind = i;
        else if (h == "radius_mm")
            col_radius = i;
    }
    if (col_id < 0 || col_s < 0 || col_y < 0 || col_kind < 0) {
        error = csv.string() + ":1: expected columns id, s_mm, y_mm, kind";
        return std::nullopt;
    }
    std::vector<TruthPlant> plants;
    for (int n = 2; std::getline(in, line); ++n) {
        if (line.empty() || line == "\r")
            continue;
        const auto cells = split(line);
        const int need = std::max({col_id, col_s, col_y, col_kind});
        TruthPlant p;
        double id = 0;
        if (static_cast<int>(cells.size()) <= need || !to_double(cells[static_cast<std::size_t>(col_id)], id) ||
            !to_double(cells[static_cast<std::size_t>(col_s)], p.s_mm) ||
            !to_double(cells[static_cast<std::size_t>(col_y)], p.y_mm)) {
            error = csv.string() + ":" + std::to_string(n) + ": expected id, s_mm and y_mm numbers";
            return std::nullopt;
        }
        p.id = static_cast<long>(id);
        p.kind = cells[static_cast<std::size_t>(col_kind)];
        if (col_radius >= 0 && (static_cast<int>(cells.size()) <= col_radius ||
                                !to_double(cells[static_cast<std::size_t>(col_radius)], p.radius_mm))) {
            error = csv.string() + ":" + std::to_string(n) + ": radius_mm is not a number";
            return std::nullopt;
        }
        plants.push_back(p);
    }
    return plants;
}

std::optional<TargetLog> read_target_log(const std::filesystem::path& log, const actuation::CanIds& ids,
                                         std::string& error)
{
    std::ifstream in(log);
    if (!in) {
        error = log.string() + ": cannot read";
        return std::nullopt;
    }
    TargetLog out;
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
        if (line.empty())
            continue;
        actuation::CandumpRecord record;
        std::string why;
        if (!actuation::parse_candump_line(line, record, why)) {
            error = log.string() + ":" + std::to_string(n) + ": " + why;
            return std::nullopt;
        }
        if (ids.kind_of(record.frame) != actuation::MessageKind::Target) {
            ++out.other_frames;
            continue;
        }
        actuation::TargetCommand t;
        if (!actuation::decode(record.frame, ids, t)) {
            ++out.bad_targets;
            continue;
        }
        out.targets.push_back(t);
    }
    return out;
}

TargetScore score_targets(std::span<const TruthPlant> plants, std::span<const actuation::TargetCommand> commands,
                          const std::array<double, 16>& tool_offset_mm, double tol_mm)
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
    constexpr double kModulo = actuation::kFireOdomModulo;
    for (std::size_t c = 0; c < commands.size(); ++c) {
        const double offset = tool_offset_mm[commands[c].tool_id & 15U];
        if (!std::isfinite(offset)) {
            ++score.unknown_tool;
            continue;
        }
        known_tool[c] = true;
        for (std::size_t p = 0; p < plants.size(); ++p) {
            // Along-track error modulo 2^18, into [-2^17, 2^17).
            double along = std::fmod(commands[c].fire_odom_mm - (plants[p].s_mm + offset), kModulo);
            if (along < -kModulo / 2)
                along += kModulo;
            if (along >= kModulo / 2)
                along -= kModulo;
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
