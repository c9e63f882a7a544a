// stats.csv as a sink: a row per augmented pair, none for a captured one.
#include <fstream>

#include <gtest/gtest.h>

#include "pipeline/sinks/sinks.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

TEST(StatsSink, OneRowPerAugmentedPair) {
  const std::string path = test::output_dir("stats_sink") + "/stats.csv";
  auto sink = make_stats_sink(StatsCsvWriter::create(path).value());
  StereoFrame raw;
  FramePoses poses;
  for (int i = 0; i < 3; ++i) {
    StereoResult r;
    r.stats.t_ns = 100 + i;
    r.stats.boom_px_left = 10 * i;
    PairContext pair{.raw = raw, .result = i == 1 ? nullptr : &r, .scene = nullptr, .poses = poses};
    ASSERT_TRUE(sink->consume(pair));
  }
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  ASSERT_EQ(lines.size(), 3u) << "the header and two rows";
  EXPECT_EQ(lines[1].rfind("100,", 0), 0u) << lines[1];
  EXPECT_EQ(lines[2].rfind("102,", 0), 0u) << lines[2];
}

}  // namespace
}  // namespace augrig::pipeline
