#include "stemd/io/csv.hpp"

#include <fstream>

namespace stemd::io {

std::vector<std::string> split_csv_line(std::string_view line)
{
    std::vector<std::string> fields;
    std::string field;
    bool quoted = false;
    for (std::size_t i = 0; i < line.size(); ++i) {
        const char c = line[i];
        if (quoted) {
            if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
                field += '"';
                ++i;
            } else if (c == '"') {
                quoted = false;
            } else {
                field += c;
            }
        } else if (c == '"') {
            quoted = true;
        } else if (c == ',') {
            fields.push_back(std::move(field));
            field.clear();
        } else {
            field += c;
        }
    }
    fields.push_back(std::move(field));
    return fields;
}

std::string csv_field(std::string_view value)
{
    if (value.find_first_of(",\"\n\r") == std::string_view::npos)
        return std::string(value);
    std::string out = "\"";
    for (const char c : value) {
        if (c == '"')
            out += '"';
        out += c;
    }
    out += '"';
    return out;
}

int CsvTable::column(std::string_view name) const
{
    for (std::size_t i = 0; i < header.size(); ++i)
        if (header[i] == name)
            return static_cast<int>(i);
    return -1;
}

std::optional<CsvTable> read_csv(const std::filesystem::path& path, std::string& error)
{
    std::ifstream in(path);
    if (!in) {
        error = path.string() + ": cannot open";
        return std::nullopt;
    }
    CsvTable table;
    std::string line;
    int line_no = 0;
    bool have_header = false;
    while (std::getline(in, line)) {
        ++line_no;
        if (!line.empty() && line.back() == '\r')
            line.pop_back();
        if (line.find_first_not_of(" \t") == std::string::npos)
            continue;
        auto fields = split_csv_line(line);
        if (!have_header) {
            table.header = std::move(fields);
            have_header = true;
            continue;
        }
        if (fields.size() != table.header.size()) {
            error = path.string() + ":" + std::to_string(line_no) + ": expected " +
                    std::to_string(table.header.size()) + " fields, found " + std::to_string(fields.size());
            return std::nullopt;
        }
        table.rows.push_back({line_no, std::move(fields)});
    }
    if (!have_header) {
        error = path.string() + ": empty file, no header";
        return std::nullopt;
    }
    return table;
}

}  // namespace stemd::io
