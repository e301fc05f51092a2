// Small CSV reader/writer for the project's files (frames.csv, stems.csv,
// detection CSVs): comma-separated, a header row, optional double quotes.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace stemd::io {

// Splits one line; "a,\"b,c\"" -> {a, b,c}. A quote inside a quoted field is "".
std::vector<std::string> split_csv_line(std::string_view line);
// Quotes a field if it holds a comma, a quote or a line break.
std::string csv_field(std::string_view value);

struct CsvTable {
    std::vector<std::string> header;
    struct Row {
        int line = 0;  // 1-based line number in the file
        std::vector<std::string> fields;
    };
    std::vector<Row> rows;

    // Column index by header name, or -1.
    int column(std::string_view name) const;
};

// A recording's frames.csv of ten hours at 30 frames a second is about
// 100 MB; anything larger is no table stemd wrote.
inline constexpr std::size_t kMaxCsvBytes = std::size_t{256} << 20;

// Reads a whole CSV file (a regular file of at most kMaxCsvBytes; a FIFO is
// refused, never waited on); blank lines are skipped. On failure returns
// nullopt and sets `error` to "<path>:<line>: <reason>" (or "<path>: <reason>").
// Every row must have as many fields as the header.
std::optional<CsvTable> read_csv(const std::filesystem::path& path, std::string& error);

}  // namespace stemd::io
