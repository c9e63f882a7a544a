#include "core/csv.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>

#include "core/file_check.hpp"

namespace augrig {

std::vector<std::string_view> split_csv_line(std::string_view line) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  std::vector<std::string_view> cells;
  for (std::size_t p = 0; p <= line.size();) {
    const std::size_t q = std::min(line.find(',', p), line.size());
    cells.push_back(line.substr(p, q - p));
    p = q + 1;
  }
  return cells;
}

std::string_view trim_csv_cell(std::string_view s) {
  auto space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!s.empty() && space(s.front())) s.remove_prefix(1);
  while (!s.empty() && space(s.back())) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> split_csv_line_trimmed(std::string_view line) {
  std::vector<std::string_view> cells = split_csv_line(line);
  for (std::string_view& c : cells) c = trim_csv_cell(c);
  return cells;
}

std::optional<Error> check_csv_header(const std::vector<std::string_view>& cells,
                                      const std::vector<std::string_view>& names, std::string_view where,
                                      std::string_view what) {
  for (std::size_t i = 0; i < std::max(cells.size(), names.size()); ++i) {
    if (i < cells.size() && i < names.size() && cells[i] == names[i]) continue;
    const std::string got = i < cells.size() ? std::string(cells[i]) : std::string("(none)");
    const std::string want = i < names.size() ? std::string(names[i]) : std::string("(none)");
    return make_error(std::string(where), ":1: not ", std::string(what), ": column ", i + 1, " is '", got,
                      "', expected '", want, "' (", names.size(), " columns, header ", cells.size(), ")");
  }
  return std::nullopt;
}

std::optional<Error> check_csv_field_count(const std::vector<std::string_view>& cells, std::size_t columns,
                                           std::string_view where, std::size_t line_no) {
  if (cells.size() == columns) return std::nullopt;
  return make_error(std::string(where), ":", line_no, ": ", cells.size(), " fields, expected ", columns,
                    " (one per header column)");
}

bool parse_csv_int64(std::string_view cell, std::int64_t& v) {
  const auto r = std::from_chars(cell.data(), cell.data() + cell.size(), v);
  return r.ec == std::errc() && r.ptr == cell.data() + cell.size() && !cell.empty();
}

bool parse_csv_double(std::string_view cell, double& v) {
  const auto r = std::from_chars(cell.data(), cell.data() + cell.size(), v);
  return r.ec == std::errc() && r.ptr == cell.data() + cell.size() && !cell.empty() && std::isfinite(v);
}

Status for_each_csv_row(const std::string& path, std::string_view where, const CsvRowFn& row) {
  if (auto d = check_not_directory(std::string(where), path); !d) return d.error();
  std::ifstream in(path, std::ios::binary);
  if (!in) return make_error(std::string(where), path, ": cannot open the file");
  std::string line;
  for (std::size_t no = 1; std::getline(in, line); ++no) {
    const std::string_view l = trim_csv_cell(line);
    if (l.empty() || l.front() == '#') continue;
    if (Status s = row(no, split_csv_line_trimmed(l)); !s) return s;
  }
  return {};
}

}  // namespace augrig
