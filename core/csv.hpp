// core/csv: augrig's own comma-separated files read back. A line is cut into its cells and a
// header is checked against the columns a reader expects, with errors that name the file, the
// line and the column. No quoting: these files hold numbers and plain names only.
#pragma once

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

}  // namespace augrig
