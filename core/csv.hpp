// core/csv: augrig's own comma-separated files read back. A line is cut into its cells and a
// header is checked against the columns a reader expects, with errors that name the file, the
// line and the column. No quoting: these files hold numbers and plain names only.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/expected.hpp"

namespace augrig {

// The cells of one line, views into `line`; a trailing '\r' (a file that went through Windows) is
// dropped. An empty line gives one empty cell.
std::vector<std::string_view> split_csv_line(std::string_view line);

// `s` without the spaces, tabs and line ends around it.
std::string_view trim_csv_cell(std::string_view s);

// The cells of one line, each trimmed (hand-written logs put spaces after their commas).
std::vector<std::string_view> split_csv_line_trimmed(std::string_view line);

// Whether `cells` is a blank line (one empty cell): the end of a file, skipped by readers.
inline bool is_blank_csv_line(const std::vector<std::string_view>& cells) {
  return cells.size() == 1 && cells[0].empty();
}

// Nothing when the header's cells are exactly `names`, in order; else "WHERE:1: not WHAT: column
// i is 'x', expected 'y' (n columns, header m)".
std::optional<Error> check_csv_header(const std::vector<std::string_view>& cells,
                                      const std::vector<std::string_view>& names, std::string_view where,
                                      std::string_view what);

// Nothing when a data line has one cell per column; else "WHERE:LINE: k fields, expected n (one
// per header column)".
std::optional<Error> check_csv_field_count(const std::vector<std::string_view>& cells, std::size_t columns,
                                           std::string_view where, std::size_t line_no);

// A whole cell as a number, nothing before or after it (trim first): int64 in decimal, or a finite
// double (std::from_chars: no '+', no "nan" or "inf" accepted as a value).
bool parse_csv_int64(std::string_view cell, std::int64_t& v);
bool parse_csv_double(std::string_view cell, double& v);

// One data line of a file: its 1-based line number and its cells, trimmed.
using CsvRowFn = std::function<Status(std::size_t line_no, const std::vector<std::string_view>& cells)>;

// Reads `path` line by line and calls `row` for every line that is neither blank nor a comment
// ('#' first, after spaces: a header such as EuRoC's "#timestamp [ns],..."); stops at the first
// error `row` returns and returns it. A directory or a file that cannot be opened is
// "WHERE PATH: is a directory, expected a file" or "WHERE PATH: cannot open the file".
Status for_each_csv_row(const std::string& path, std::string_view where, const CsvRowFn& row);

}  // namespace augrig
