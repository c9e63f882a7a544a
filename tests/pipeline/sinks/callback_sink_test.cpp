// A command's own output as a sink: called with each augmented pair as made, never with a
// captured one, and its error is the run's.
#include <gtest/gtest.h>

#include "pipeline/sinks/sinks.hpp"

namespace augrig::pipeline {
namespace {

TEST(CallbackSink, EachAugmentedPairAndItsError) {
  std::vector<std::uint64_t> seen;
  auto sink = make_callback_sink(
      [&](const StereoFrame& raw, const StereoResult& r, const SceneState&, const FramePoses&) -> Status {
        seen.push_back(raw.pair_sequence);
        if (r.stats.boom_px_left < 0) return make_error("evaluate: matcher failed");
        return {};
      });
  FramePoses poses;
  SceneState scene{};
  for (std::uint64_t i = 0; i < 3; ++i) {
    StereoFrame raw;
    raw.pair_sequence = i;
    StereoResult r;
    PairContext pair{.raw = raw, .result = i == 1 ? nullptr : &r, .scene = &scene, .poses = poses};
    ASSERT_TRUE(sink->consume(pair));
  }
  EXPECT_EQ(seen, (std::vector<std::uint64_t>{0, 2}));
  StereoFrame raw;
  StereoResult bad;
  bad.stats.boom_px_left = -1;
  PairContext pair{.raw = raw, .result = &bad, .scene = &scene, .poses = poses};
  const Status st = sink->consume(pair);
  ASSERT_FALSE(st);
  EXPECT_EQ(st.error().message, "evaluate: matcher failed");
}

}  // namespace
}  // namespace augrig::pipeline
