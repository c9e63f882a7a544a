// app/window_runner.hpp: a configured pipeline run to its end headless (asked for, or no display
// to open a window on), its summary printed and its report returned; with a window (under Xvfb,
// the CTest WindowRunner.UnderXvfb), the pipeline on its worker and the window's loop here: every
// pair published, the screenshot of --screenshot-at N written and described, the window closed when
// the pipeline stops. The window's pixels are checked in tests/app/cmd_recording_test.cpp.
#include "app/window_runner.hpp"

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <sstream>

#include <gtest/gtest.h>

#include "app/cli.hpp"
#include "pipeline/sources.hpp"
#include "tests/support/test_support.hpp"
#include "tests/support/pipeline_parts.hpp"
#include "tests/support/window_shot.hpp"

namespace augrig::app {
namespace {

// A pipeline over the short simulated approach (the simulation's truth as poses), `pairs` pairs.
PipelineParts sim_parts(std::uint64_t pairs) {
  PipelineParts p = test::pipeline_parts("sim://" + test::data_path("scenarios/short_approach.yaml"));
  p.max_pairs = pairs;
  return p;
}

TEST(WindowRunner, HeadlessRunsToTheEndAndPrintsTheSummary) {
  Pipeline pipeline(sim_parts(5));
  std::ostringstream out, err;
  const PipelineReport r =
      run_pipeline(pipeline, false, test::output_dir("window_runner_headless"), out, err);
  EXPECT_EQ(r.pairs, 5u) << err.str();
  std::ostringstream summary;
  pipeline.print_summary(r, summary);
  EXPECT_NE(out.str().find(summary.str()), std::string::npos) << out.str();
  EXPECT_EQ(out.str().find("live display open"), std::string::npos) << out.str();
  EXPECT_EQ(out.str().find("screenshot "), std::string::npos) << out.str();
}

TEST(WindowRunner, AWindowWithoutADisplayRunsHeadless) {
  // No X display to open it on: the run goes on headless, as the commands' --headless would.
  const char* display = std::getenv("DISPLAY");
  const std::string saved = display ? display : "";
  unsetenv("DISPLAY");
  unsetenv("WAYLAND_DISPLAY");
  ASSERT_FALSE(display_present());
  Pipeline pipeline(sim_parts(3));
  std::ostringstream out, err;
  const PipelineReport r =
      run_pipeline(pipeline, true, test::output_dir("window_runner_no_display"), out, err, 2);
  if (display) setenv("DISPLAY", saved.c_str(), 1);
  EXPECT_EQ(r.pairs, 3u) << err.str();
  EXPECT_EQ(out.str().find("live display open"), std::string::npos) << out.str();
  EXPECT_EQ(out.str().find("screenshot "), std::string::npos) << "no window, no screenshot: " << out.str();
}

// Under Xvfb only (the CTest WindowRunner.UnderXvfb); skipped without a display.
TEST(WindowRunnerWindow, ShowsEveryPairTakesTheScreenshotAndClosesAtTheEnd) {
  if (!display_present()) GTEST_SKIP() << "no display (run under xvfb-run)";
  PipelineParts p = sim_parts(6);
  p.view = std::make_shared<LiveView>();  // the window's mailbox, as the commands give it
  Pipeline pipeline(std::move(p));
  const std::string dir = test::output_dir("window_runner_window");
  std::ostringstream out, err;
  const PipelineReport r = run_pipeline(pipeline, true, dir, out, err, 3);
  EXPECT_EQ(r.pairs, 6u) << err.str();
  EXPECT_NE(out.str().find("live display open"), std::string::npos) << out.str() << err.str();
  const auto shot = test::parse_window_shot(out.str());
  ASSERT_TRUE(shot) << out.str();
  EXPECT_GE(shot->pair, 3u);
  EXPECT_LE(shot->pair, 6u);
  EXPECT_TRUE(std::filesystem::exists(shot->path)) << shot->path;
  EXPECT_GT(shot->views[0].w, 0);
  EXPECT_GT(shot->views[1].w, 0);
  EXPECT_EQ(err.str().find("no screenshot"), std::string::npos) << err.str();
  // The summary comes after the window closed: the report's, as headless.
  std::ostringstream summary;
  pipeline.print_summary(r, summary);
  EXPECT_NE(out.str().find(summary.str()), std::string::npos) << out.str();
}

}  // namespace
}  // namespace augrig::app
