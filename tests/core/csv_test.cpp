// core/csv: lines cut into cells (empty cells, Windows line ends, trimming) and the header and
// field-count checks with the file, line and column they name.
#include "core/csv.hpp"

#include <string>
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

}  // namespace
}  // namespace augrig
