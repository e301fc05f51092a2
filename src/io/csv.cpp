#include "stemd/io/csv.hpp"

#include <cstring>

#include "stemd/base/whole_file.hpp"

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
    // Read whole through the shared reader: a FIFO named frames.csv must not
    // hang the replay's start, nor /dev/zero fill the memory.
    std::string text;
    const base::WholeFileResult read = base::read_whole_file(path.c_str(), kMaxCsvBytes, text);
    switch (read.status) {
    case base::WholeFileStatus::ok: break;
    case base::WholeFileStatus::cannot_open:
        error = path.string() + ": cannot open: " + std::strerror(read.error_number) + " (errno " +
                std::to_string(read.error_number) + ")";
        return std::nullopt;
    case base::WholeFileStatus::cannot_stat:
    case base::WholeFileStatus::read_error:
        error = path.string() + ": cannot read: " + std::strerror(read.error_number);
        return std::nullopt;
    case base::WholeFileStatus::directory:
    case base::WholeFileStatus::not_regular: error = path.string() + ": not a regular file"; return std::nullopt;
    case base::WholeFileStatus::too_large:
        error = path.string() + ": larger than " + std::to_string(kMaxCsvBytes >> 20) + " MiB; is it a CSV table?";
        return std::nullopt;
    case base::WholeFileStatus::truncated:
        error = path.string() + ": cannot read: it ended while read";
        return std::nullopt;
    }
    CsvTable table;
    int line_no = 0;
    bool have_header = false;
    for (std::size_t start = 0; start < text.size();) {
        const std::size_t newline = text.find('\n', start);
        const std::size_t end = newline == std::string::npos ? text.size() : newline;
        std::string_view line(text.data() + start, end - start);
        start = end + 1;
        ++line_no;
        if (!line.empty() && line.back() == '\r')
            line.remove_suffix(1);
        if (line.find_first_not_of(" \t") == std::string_view::npos)
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
