// The per-frame files as a sink: every K-th augmented pair, named by the command's rule, else by
// the pair's place in its file (a replay's recorded index, and its loop pass after the first) or
// its sequence; an unwritable folder is the run's error.
#include <filesystem>

#include <gtest/gtest.h>

#include "pipeline/sinks/sinks.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

namespace fs = std::filesystem;

struct Pair {
  StereoFrame raw;
  StereoResult result;
  FramePoses poses;
  explicit Pair(std::uint64_t seq) {
    raw.pair_sequence = seq;
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) raw[id].image = Image(8, 6, PixelFormat::kMono8);
    for (ViewResult* v : {&result.left, &result.right}) {
      v->augmented = Image(2, 2, PixelFormat::kMono8);
      v->augmented_box = {1, 1, 3, 3};
      v->mask = Image(8, 6, PixelFormat::kMono8);
    }
  }
};

TEST(FrameFilesSink, EveryKthPairNamedByItsPlace) {
  const std::string dir = test::output_dir("frame_files_sink");
  const Rig rig = Rig::paper_default();
  auto sink = make_frame_files_sink(FrameFiles{dir, 2, nullptr, false}, rig);
  for (std::uint64_t i = 1; i <= 3; ++i) {
    Pair p(40 + i);
    PairContext pair{.raw = p.raw, .result = &p.result, .scene = nullptr, .poses = p.poses, .pair = i};
    if (i == 3) pair.position = SourcePosition{7, 1};  // a replay's frame 7 in its second pass
    ASSERT_TRUE(sink->consume(pair));
  }
  EXPECT_TRUE(fs::exists(fs::path(dir) / "left/augmented/000041.png"));
  EXPECT_FALSE(fs::exists(fs::path(dir) / "left/augmented/000042.png")) << "every 2nd pair only";
  EXPECT_TRUE(fs::exists(fs::path(dir) / "right/mask/pass1_000007.png"));
  EXPECT_TRUE(fs::exists(fs::path(dir) / "vis/boom_overlap/pass1_000007.png"));
}

TEST(FrameFilesSink, TheCommandsNamesAndAnUnwritableFolder) {
  const std::string dir = test::output_dir("frame_files_sink_names");
  const Rig rig = Rig::paper_default();
  auto named = make_frame_files_sink(FrameFiles{dir, 1,
                                                [](const StereoFrame&) {
                                                  return FrameNames{"img_l", "img_r"};
                                                },
                                                false},
                                     rig);
  Pair p(1);
  PairContext pair{.raw = p.raw, .result = &p.result, .scene = nullptr, .poses = p.poses, .pair = 1};
  ASSERT_TRUE(named->consume(pair));
  EXPECT_TRUE(fs::exists(fs::path(dir) / "left/augmented/img_l.png"));
  EXPECT_TRUE(fs::exists(fs::path(dir) / "right/augmented/img_r.png"));
  auto blocked = make_frame_files_sink(FrameFiles{"/proc/augrig-no-such-dir", 1, nullptr, false}, rig);
  EXPECT_FALSE(blocked->consume(pair));
}

}  // namespace
}  // namespace augrig::pipeline
