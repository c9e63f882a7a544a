// The mailbox between the pipeline and the window: hand-over by swap, waking the window, the
// commands merged until taken, the HUD's rolling latencies.
#include "pipeline/live_view.hpp"

#include <cmath>
#include <optional>
#include <thread>

#include <gtest/gtest.h>

namespace augrig::pipeline {
namespace {

// The window waits for the next pair: woken by its hand-over (not a fixed sleep), by the finish,
// else at the timeout; a pair already newer than the one shown returns at once.
TEST(LiveView, WaitNewerWakesAtTheHandOver) {
  LiveView view;
  LiveView::Shown shown;
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(view.wait_newer(shown.id, std::chrono::milliseconds(30)));  // nothing published
  EXPECT_GE(std::chrono::steady_clock::now() - t0, std::chrono::milliseconds(30));

  StereoResult r;
  std::thread pipeline([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    view.publish(r, SceneState{}, 123);
  });
  // Woken by the publish, long before a 60 s timeout.
  EXPECT_TRUE(view.wait_newer(shown.id, std::chrono::seconds(60)));
  pipeline.join();
  EXPECT_TRUE(view.wait_newer(shown.id, std::chrono::seconds(60)));  // still newer: at once
  EXPECT_EQ(view.take_newest(shown), 123);
  EXPECT_EQ(shown.id, 1u);
  EXPECT_FALSE(view.wait_newer(shown.id, std::chrono::milliseconds(1)));

  std::thread finisher([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    view.finish();
  });
  EXPECT_TRUE(view.wait_newer(shown.id, std::chrono::seconds(60)));
  finisher.join();
  EXPECT_TRUE(view.finished());
}

TEST(LiveView, CommandsMergeUntilTaken) {
  LiveView view;
  PipelineCommands a;
  a.toggle_pause = true;
  a.steps = 2;
  a.boom_nudge.extension_m = 0.5;
  view.post(a);
  PipelineCommands b;
  b.toggle_pause = true;  // paused and resumed: no change
  b.steps = 3;
  b.seek_frame = 17;
  b.boom_nudge.extension_m = 0.25;
  view.post(b);
  const PipelineCommands c = view.take_commands();
  EXPECT_FALSE(c.toggle_pause);
  EXPECT_EQ(c.steps, 5);
  EXPECT_EQ(c.seek_frame, std::optional<std::size_t>(17));
  EXPECT_DOUBLE_EQ(c.boom_nudge.extension_m, 0.75);
  EXPECT_EQ(view.take_commands().steps, 0);  // taken
}

TEST(LiveView, RollingHudIsTheMedianAndThe99thPercentile) {
  std::vector<double> ms;
  for (int i = 100; i >= 1; --i) ms.push_back(i);
  const LatencyHud h = rolling_hud(ms);
  EXPECT_DOUBLE_EQ(h.p50_ms, 51);
  EXPECT_DOUBLE_EQ(h.p99_ms, 100);
  EXPECT_TRUE(std::isnan(rolling_hud({}).p50_ms));
}

}  // namespace
}  // namespace augrig::pipeline
