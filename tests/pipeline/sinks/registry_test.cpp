// The sink registry: each scheme found, its usage listed, an unknown scheme or a missing argument
// named with what is known.
#include "pipeline/sinks/registry.hpp"

#include <gtest/gtest.h>

#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

TEST(SinkRegistry, UsagesNameEveryScheme) {
  const std::vector<std::string> u = sink_usages();
  ASSERT_EQ(u.size(), 8u);
  EXPECT_EQ(u[0].rfind("video:FILE.mp4", 0), 0u);
  EXPECT_EQ(u[1].rfind("tum:FILE.txt", 0), 0u);
  EXPECT_EQ(u[2].rfind("mcap:FILE.mcap", 0), 0u);
  EXPECT_EQ(u[3].rfind("euroc:DIR", 0), 0u);
  EXPECT_EQ(u[4].rfind("kitti:DIR", 0), 0u);
  EXPECT_EQ(u[5].rfind("middlebury:DIR", 0), 0u);
  EXPECT_EQ(u[6].rfind("coco:DIR", 0), 0u);
  EXPECT_EQ(u[7].rfind("yolo:DIR", 0), 0u);
}

TEST(SinkRegistry, MakesBySchemeAndNamesWhatIsWrong) {
  const Rig rig = Rig::paper_default();
  const std::string dir = test::output_dir("sink_registry");
  auto tum = make_sink("tum:" + dir + "/t.txt", {rig});
  EXPECT_TRUE(tum) << tum.error().message;
  auto unknown = make_sink("rosbag:" + dir, {rig});
  ASSERT_FALSE(unknown);
  EXPECT_EQ(unknown.error().message,
            "--sink rosbag:" + dir + ": unknown sink (known: video:, tum:, mcap:, euroc:, kitti:, middlebury:, coco:, yolo:)");
  for (const std::string spec : {"tum", "tum:"}) {
    auto missing = make_sink(spec, {rig});
    ASSERT_FALSE(missing) << spec;
    EXPECT_EQ(missing.error().message, "--sink " + spec +
                                           ": expected tum:FILE.txt  the receiver's pose in the "
                                           "left camera per pair (TUM trajectory format)");
  }
}

}  // namespace
}  // namespace augrig::pipeline
