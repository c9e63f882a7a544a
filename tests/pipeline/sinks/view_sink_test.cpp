// The window's sink: augmented pairs made whole and handed over by swap; captured pairs copied
// before the recorder takes them; a paused live run shows nothing new, a paused replay its steps.
#include <gtest/gtest.h>

#include "pipeline/report.hpp"
#include "pipeline/sinks/sinks.hpp"

namespace augrig::pipeline {
namespace {

struct Pair {
  StereoFrame raw;
  StereoResult result;
  FramePoses poses;
  SceneState scene{};
  Pair() {
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      raw[id].image = Image(8, 6, PixelFormat::kMono8);
      raw[id].image.data()[0] = 9;
    }
    for (ViewResult* v : {&result.left, &result.right}) {
      v->augmented = Image(2, 2, PixelFormat::kMono8);
      v->augmented_box = {1, 1, 3, 3};
    }
  }
};

TEST(ViewSink, AugmentedPairsWholeByCaptureByCopyPausedAsAsked) {
  auto view = std::make_shared<LiveView>();
  auto sink = make_view_sink(view);
  EXPECT_TRUE(sink->needs().whole_images);
  LiveView::Shown shown;

  Pair a;
  PairContext pa{
      .raw = a.raw, .result = &a.result, .scene = &a.scene, .poses = a.poses, .pair = 1, .mid_host_ns = 42};
  ASSERT_TRUE(sink->consume(pa));
  sink->release(pa);
  EXPECT_EQ(view->take_newest(shown), 42);
  EXPECT_EQ(shown.result.left.augmented.width(), 8) << "made whole for the window";

  // Paused live: processed, not shown.
  Pair b;
  PairContext pb{
      .raw = b.raw, .result = &b.result, .scene = &b.scene, .poses = b.poses, .pair = 2, .paused = true};
  ASSERT_TRUE(sink->consume(pb));
  sink->release(pb);
  EXPECT_EQ(view->take_newest(shown), 0);
  EXPECT_EQ(b.result.left.augmented.width(), 2) << "not made whole for nobody";

  // Paused replay: a step is shown, whole.
  Pair c;
  PairContext pc{.raw = c.raw,
                 .result = &c.result,
                 .scene = &c.scene,
                 .poses = c.poses,
                 .pair = 3,
                 .paused = true,
                 .replay = true};
  ASSERT_TRUE(sink->consume(pc));
  sink->release(pc);
  EXPECT_EQ(shown.id, 1u);
  view->take_newest(shown);
  EXPECT_EQ(shown.id, 2u);
  EXPECT_EQ(shown.result.left.augmented.width(), 8);

  // Captured only: the raw pair copied at consume (the recorder may take it at release).
  Pair d;
  PairContext pd{.raw = d.raw, .result = nullptr, .scene = nullptr, .poses = d.poses, .pair = 4};
  ASSERT_TRUE(sink->consume(pd));
  d.raw.left.image = Image();  // taken by a sink before this one's release
  sink->release(pd);
  view->take_newest(shown);
  EXPECT_EQ(shown.id, 3u);
  ASSERT_EQ(shown.result.left.augmented.width(), 8);
  EXPECT_EQ(shown.result.left.augmented.data()[0], 9);

  PipelineReport report;
  ASSERT_TRUE(sink->close(report));
  EXPECT_TRUE(view->finished());
}

}  // namespace
}  // namespace augrig::pipeline
