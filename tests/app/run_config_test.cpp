// app/run_config.hpp: the live pipeline configured from typed options (what `augrig run` does after
// parsing its flags, and the demo's window without an argv): a short simulated run headless with
// its banner, stats.csv and images; the refusals that need no camera; the shared flag parsers with
// run's messages. The whole command line is tested in tests/app/cmd_run_test.cpp.
#include "app/run_config.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "tests/support/test_support.hpp"

namespace augrig::app {
namespace {

// The CommandError `body` throws (code 0 and no message when it throws none).
template <typename Body>
CommandError error_of(Body&& body) {
  try {
    body();
  } catch (const CommandError& e) {
    return e;
  }
  return {0, ""};
}

std::size_t count_lines(const std::string& path) {
  std::ifstream f(path);
  std::size_t n = 0;
  for (std::string line; std::getline(f, line);) ++n;
  return n;
}

TEST(RunConfig, RunsASimulatedFlightHeadlessFromOptions) {
  const std::string dir = test::output_dir("run_config_sim");
  RunOptions o;
  o.source_uri = "sim://" + test::data_path("scenarios/short_approach.yaml") + "?rate=0";
  o.out = dir;
  o.every = 2;
  o.max_pairs = 3;
  o.status_every_s = 0;
  o.headless = true;
  std::ostringstream out, err;
  ASSERT_EQ(run_live(o, out, err), kExitOk) << out.str() << err.str();
  EXPECT_NE(out.str().find("run: " + o.source_uri + " (lockstep); rig "), std::string::npos) << out.str();
  EXPECT_NE(out.str().find("run: 3 stereo frames augmented"), std::string::npos) << out.str();
  EXPECT_EQ(count_lines(dir + "/stats.csv"), 4u);  // the header and 3 pairs
  // --every 2: the images of the 1st and the 3rd pair.
  std::size_t images = 0;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir))
    images += e.path().extension() == ".png";
  EXPECT_GT(images, 0u);
}

TEST(RunConfig, CaptureOnlyRefusesWhatWouldAugment) {
  RunOptions o;
  o.source_uri = "sim://demo";
  o.capture_only = true;
  o.out = test::output_dir("run_config_capture_only");
  std::ostringstream out, err;
  const CommandError e = error_of([&] { run_live(o, out, err); });
  EXPECT_EQ(e.code, kExitUsage);
  EXPECT_EQ(e.message, "--out: nothing is augmented when capturing only (--capture-only)");
  EXPECT_EQ(out.str(), "") << "refused before anything was opened or printed";
}

TEST(RunConfig, ASourceWithoutPosesNeedsAPoseSource) {
  RunOptions o;
  o.source_uri = "stereo://{v4l2:///dev/null}{v4l2:///dev/null}";
  std::ostringstream out, err;
  const CommandError e = error_of([&] { run_live(o, out, err); });
  EXPECT_EQ(e.code, kExitUsage);
  EXPECT_NE(e.message.find("a pose source is needed for stereo://"), std::string::npos) << e.message;
}

TEST(RunConfig, OneSourceOfPosesOnly) {
  RunOptions o;
  o.source_uri = "sim://" + test::data_path("scenarios/short_approach.yaml") + "?rate=0";
  o.scene = "a.yaml";
  o.poses_csv = "b.csv";
  std::ostringstream out, err;
  const CommandError e = error_of([&] { run_live(o, out, err); });
  EXPECT_EQ(e.code, kExitUsage);
  EXPECT_EQ(e.message,
            "--scene, --poses and --nav with streams of both aircraft are three sources of poses: give one");
}

TEST(RunConfig, SharedFlagParsersSayWhatRunSays) {
  EXPECT_EQ(parse_duration_arg("2.5"), 2.5);
  EXPECT_EQ(parse_duration_arg("0"), 0.0);
  EXPECT_EQ(error_of([] { parse_duration_arg("-1"); }).message, "--duration: expected seconds >= 0");
  EXPECT_EQ(parse_max_pairs_arg("7"), 7u);
  EXPECT_EQ(error_of([] { parse_max_pairs_arg("0"); }).code, kExitUsage);
  EXPECT_EQ(parse_look_arg("plain"), Look::kPlain);
  EXPECT_EQ(parse_look_arg("camera"), Look::kCamera);
  EXPECT_EQ(error_of([] { parse_look_arg("shiny"); }).message,
            "--look: expected plain or camera, got 'shiny'");
}

}  // namespace
}  // namespace augrig::app
