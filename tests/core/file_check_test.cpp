// A directory where a file is expected is named as such, not read as an empty file.
#include "core/file_check.hpp"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

TEST(FileCheck, DirectoryIsNamedAsSuch) {
  const std::string dir = test::output_dir("file_check_dir") + "/imu.csv";
  std::filesystem::create_directories(dir);
  const auto c = check_not_directory("x::load(): ", dir);
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().message, "x::load(): " + dir + ": is a directory, expected a file");
  const auto t = read_text_file("x::load(): ", dir, "rig file");
  ASSERT_FALSE(t);
  EXPECT_EQ(t.error().message, "x::load(): " + dir + ": is a directory, expected a file");
}

TEST(FileCheck, ReadsAFileAndNamesAMissingOne) {
  const std::string dir = test::output_dir("file_check_file");
  const std::string path = dir + "/a.txt";
  std::ofstream(path) << "hello\n";
  EXPECT_TRUE(check_not_directory("x: ", path));
  const auto t = read_text_file("x: ", path, "text file");
  ASSERT_TRUE(t) << t.error().message;
  EXPECT_EQ(*t, "hello\n");
  const auto m = read_text_file("x: ", dir + "/missing.txt", "text file");
  ASSERT_FALSE(m);
  EXPECT_NE(m.error().message.find("missing.txt: cannot open the text file (No such file"), std::string::npos)
      << m.error().message;
}

}  // namespace
}  // namespace augrig
