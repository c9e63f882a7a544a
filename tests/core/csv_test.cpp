// core/csv: lines cut into cells (empty cells, Windows line ends, trimming) and the header and
// field-count checks with the file, line and column they name.
#include "core/csv.hpp"

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace augrig {
namespace {

std::vector<std::string> strings(const std::vector<std::string_view>& v) {
  return {v.begin(), v.end()};
}

TEST(Csv, SplitKeepsEveryCellEmptyOnesIncluded) {
  EXPECT_EQ(strings(split_csv_line("a,b,c")), (std::vector<std::string>{"a", "b", "c"}));
  EXPECT_EQ(strings(split_csv_line(",x,,")), (std::vector<std::string>{"", "x", "", ""}));
  EXPECT_EQ(strings(split_csv_line("")), (std::vector<std::string>{""}));
  EXPECT_TRUE(is_blank_csv_line(split_csv_line("")));
  EXPECT_TRUE(is_blank_csv_line(split_csv_line("\r")));
  EXPECT_FALSE(is_blank_csv_line(split_csv_line(",")));
}

TEST(Csv, SplitDropsOnlyAWindowsLineEnd) {
  EXPECT_EQ(strings(split_csv_line("1,2\r")), (std::vector<std::string>{"1", "2"}));
  // Spaces are data in augrig's own files: a reader that parses numbers refuses them.
  EXPECT_EQ(strings(split_csv_line(" 1, 2 ")), (std::vector<std::string>{" 1", " 2 "}));
  EXPECT_EQ(strings(split_csv_line("a\r,b")), (std::vector<std::string>{"a\r", "b"}));
}

TEST(Csv, TrimmedSplitForHandWrittenLogs) {
  EXPECT_EQ(strings(split_csv_line_trimmed(" 1 ,\t2,3 \r")), (std::vector<std::string>{"1", "2", "3"}));
  EXPECT_EQ(strings(split_csv_line_trimmed("  ")), (std::vector<std::string>{""}));
  EXPECT_EQ(trim_csv_cell(" \t x y\r\n"), "x y");
  EXPECT_EQ(trim_csv_cell(""), "");
}

TEST(Csv, HeaderCheckNamesTheFirstColumnThatDiffers) {
  const std::vector<std::string_view> names = {"t_ns", "a", "b"};
  EXPECT_FALSE(check_csv_header(split_csv_line("t_ns,a,b"), names, "f.csv", "f's header"));
  EXPECT_FALSE(check_csv_header(split_csv_line("t_ns,a,b\r"), names, "f.csv", "f's header"));
  auto e = check_csv_header(split_csv_line("t_ns,x,b"), names, "f.csv", "f's header");
  ASSERT_TRUE(e);
  EXPECT_EQ(e->message, "f.csv:1: not f's header: column 2 is 'x', expected 'a' (3 columns, header 3)");
  e = check_csv_header(split_csv_line("t_ns,a"), names, "f.csv", "f's header");
  ASSERT_TRUE(e);
  EXPECT_EQ(e->message, "f.csv:1: not f's header: column 3 is '(none)', expected 'b' (3 columns, header 2)");
  e = check_csv_header(split_csv_line("t_ns,a,b,c"), names, "f.csv", "f's header");
  ASSERT_TRUE(e);
  EXPECT_EQ(e->message, "f.csv:1: not f's header: column 4 is 'c', expected '(none)' (3 columns, header 4)");
}

TEST(Csv, FieldCountCheckNamesTheLine) {
  EXPECT_FALSE(check_csv_field_count(split_csv_line("1,2,3"), 3, "f.csv", 7));
  const auto e = check_csv_field_count(split_csv_line("1,2"), 3, "f.csv", 7);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->message, "f.csv:7: 2 fields, expected 3 (one per header column)");
}

TEST(Csv, NumberCellsAreWholeCellsOnly) {
  std::int64_t i = 0;
  EXPECT_TRUE(parse_csv_int64("-1403636579763555584", i));
  EXPECT_EQ(i, -1403636579763555584);
  for (const char* bad : {"", "12 ", " 12", "1.5", "+3", "abc", "99999999999999999999"})
    EXPECT_FALSE(parse_csv_int64(bad, i)) << bad;
  double d = 0;
  EXPECT_TRUE(parse_csv_double("-9.81e0", d));
  EXPECT_EQ(d, -9.81);
  for (const char* bad : {"", "nan", "inf", "1e999", "1,5", "2 "})
    EXPECT_FALSE(parse_csv_double(bad, d)) << bad;
}

// The data lines of a file with their line numbers: comments ('#' headers) and blank lines
// skipped, cells trimmed, Windows line ends dropped; the first error stops the walk.
TEST(Csv, ForEachRowSkipsCommentsAndBlankLines) {
  const std::string path = ::testing::TempDir() + "/csv_test_rows.csv";
  {
    std::ofstream f(path, std::ios::binary);
    f << "#timestamp [ns],filename\r\n1, a.png\r\n\n   \n  # a note\n2 ,b.png\n3,c.png";
  }
  std::vector<std::pair<std::size_t, std::vector<std::string>>> rows;
  auto collect = [&](std::size_t no, const std::vector<std::string_view>& cells) -> Status {
    rows.emplace_back(no, strings(cells));
    return {};
  };
  ASSERT_TRUE(for_each_csv_row(path, "r(): ", collect));
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0], (std::pair<std::size_t, std::vector<std::string>>{2, {"1", "a.png"}}));
  EXPECT_EQ(rows[1], (std::pair<std::size_t, std::vector<std::string>>{6, {"2", "b.png"}}));
  EXPECT_EQ(rows[2], (std::pair<std::size_t, std::vector<std::string>>{7, {"3", "c.png"}}));

  rows.clear();
  const Status s = for_each_csv_row(path, "r(): ", [&](std::size_t no, const auto& cells) -> Status {
    if (no == 6) return make_error("stop at ", no);
    return collect(no, cells);
  });
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message, "stop at 6");
  EXPECT_EQ(rows.size(), 1u);
  std::filesystem::remove(path);
}

TEST(Csv, ForEachRowNamesAFileItCannotRead) {
  auto none = [](std::size_t, const std::vector<std::string_view>&) -> Status { return {}; };
  const std::string missing = ::testing::TempDir() + "/csv_test_no_such.csv";
  Status s = for_each_csv_row(missing, "r(): ", none);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message, "r(): " + missing + ": cannot open the file");
  const std::string dir = ::testing::TempDir();
  s = for_each_csv_row(dir, "r(): ", none);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("is a directory, expected a file"), std::string::npos)
      << s.error().message;
}

}  // namespace
}  // namespace augrig
