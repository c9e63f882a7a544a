// augrig sim through the real binary: the dataset it writes, its determinism, and its errors.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <sys/stat.h>

#include "nav/logs.hpp"
#include "nav/nmea.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;
using test::augrig_binary;
using test::data_path;
using test::output_dir;
using test::run_command;

int augrig(const std::string& args, std::string* output = nullptr) {
  return test::run_augrig(args, output);
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(CmdSim, DemoScenarioWritesLogsTruthAndIndexThatReadBack) {
  const std::string dir = output_dir("cmd_sim_demo");
  std::string log;
  ASSERT_EQ(augrig("sim --scenario demo --no-images --out " + dir, &log), 0) << log;
  for (const char* f : {"scenario.yaml", "rig.yaml", "tanker/gps.nmea", "tanker/imu.csv",
                        "tanker/aircraft.yaml", "tanker/nav.csv", "receiver/gps.nmea", "receiver/imu.csv",
                        "truth/tanker.csv", "truth/receiver.csv", "truth/poses.csv", "frames/index.csv"})
    EXPECT_TRUE(fs::exists(fs::path(dir) / f)) << f;
  // The logs read back through the real parsers, clean: 28 s at 10 Hz and 200 Hz.
  auto gps = nav::read_nmea_file(dir + "/tanker/gps.nmea");
  ASSERT_TRUE(gps) << gps.error().message;
  EXPECT_EQ(gps->fixes.size(), 281u);
  EXPECT_EQ(gps->issues.malformed, 0u);
  EXPECT_TRUE(gps->fixes.front().heading_rad.has_value());  // the tanker has a dual-antenna heading
  EXPECT_NE(gps->fixes.front().arrival_ns, 0);
  auto imu = nav::read_imu_csv(dir + "/receiver/imu.csv");
  ASSERT_TRUE(imu) << imu.error().message;
  EXPECT_EQ(imu->samples.size(), 5600u);
  auto onboard = nav::read_nav_solution_csv(dir + "/receiver/nav.csv");
  ASSERT_TRUE(onboard) << onboard.error().message;
  EXPECT_GT(onboard->rows.size(), 250u);
  auto index = nav::read_frame_index_csv(dir + "/frames/index.csv");
  ASSERT_TRUE(index) << index.error().message;
  auto poses = nav::read_camera_pose_csv(dir + "/truth/poses.csv");
  ASSERT_TRUE(poses) << poses.error().message;
  EXPECT_EQ(index->rows.size(), poses->rows.size());
  EXPECT_GT(index->rows.size(), 1600u);  // 2 x 841 frames less the cameras' drops
  // The receiver is in front of the cameras, tens of metres away.
  EXPECT_GT(poses->rows.front().z_m, 10.0);
  EXPECT_NE(log.find("dropped by the cameras"), std::string::npos) << log;
}

TEST(CmdSim, DeterministicForASeedAndDifferentForAnother) {
  const std::string a = output_dir("cmd_sim_seed_a"), b = output_dir("cmd_sim_seed_b"),
                    c = output_dir("cmd_sim_seed_c");
  ASSERT_EQ(augrig("sim --scenario demo --no-images --seed 5 --out " + a), 0);
  ASSERT_EQ(augrig("sim --scenario demo --no-images --seed 5 --out " + b), 0);
  ASSERT_EQ(augrig("sim --scenario demo --no-images --seed 6 --out " + c), 0);
  for (const char* f : {"tanker/gps.nmea", "receiver/imu.csv", "frames/index.csv", "truth/poses.csv"}) {
    EXPECT_EQ(slurp(fs::path(a) / f), slurp(fs::path(b) / f)) << f;
  }
  EXPECT_NE(slurp(fs::path(a) / "tanker/gps.nmea"), slurp(fs::path(c) / "tanker/gps.nmea"));
  EXPECT_NE(slurp(fs::path(a) / "receiver/imu.csv"), slurp(fs::path(c) / "receiver/imu.csv"));
}

TEST(CmdSim, RendersEveryIndexedFrame) {
  const std::string dir = output_dir("cmd_sim_render");
  std::string log;
  ASSERT_EQ(
      augrig("sim --scenario " + data_path("scenarios/short_approach.yaml") + " --every 10 --out " + dir,
             &log),
      0)
      << log;
  auto index = nav::read_frame_index_csv(dir + "/frames/index.csv");
  ASSERT_TRUE(index) << index.error().message;
  ASSERT_GE(index->rows.size(), 10u);  // frames 0, 10, ..., 60 of each camera, less drops
  for (const nav::FrameIndexRow& r : index->rows) {
    EXPECT_EQ(r.sequence % 10, 0u);
    const cv::Mat img = cv::imread(dir + "/frames/" + r.file, cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(img.empty()) << r.file;
    EXPECT_EQ(img.size(), cv::Size(1280, 960));
  }
  EXPECT_NE(log.find("100%"), std::string::npos) << log;  // the progress bar finished
}

TEST(CmdSim, BadInputGivesLocatedErrors) {
  const std::string dir = output_dir("cmd_sim_bad");
  std::string log;
  EXPECT_EQ(augrig("sim --scenario nosuch --out " + dir, &log), 1);
  EXPECT_NE(log.find("nosuch"), std::string::npos) << log;
  EXPECT_EQ(augrig("sim --scenario " + data_path("scenarios/bad_preset.yaml") + " --out " + dir, &log), 1);
  EXPECT_NE(log.find("bad_preset.yaml:4"), std::string::npos) << log;
  EXPECT_EQ(augrig("sim --scenario demo --out " + dir + " --every 0", &log), 2);
  EXPECT_NE(log.find("--every"), std::string::npos) << log;
  EXPECT_EQ(augrig("sim --out " + dir, &log), 2);
  EXPECT_EQ(augrig("sim --scenario demo --out /proc/forbidden/x", &log), 1);
}

// The scenario file is read once, so the text flown is the text copied to scenario.yaml: a FIFO,
// which reads once only, used to block the copy for ever. A directory is named as such.
TEST(CmdSim, ScenarioFileIsReadOnceAndADirectoryIsNamed) {
  const std::string dir = output_dir("cmd_sim_read_once");
  const std::string scenario = data_path("scenarios/short_approach.yaml");
  const std::string fifo = dir + "/scenario.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string log;
  // The writer and augrig both under `timeout`: neither can hang the test.
  const int rc = run_command("(timeout 60 sh -c 'cat " + scenario + " > " + fifo +
                                 "' </dev/null >/dev/null 2>&1 &); timeout 60 " + augrig_binary() +
                                 " sim --scenario " + fifo + " --no-images --out " + dir + "/out",
                             &log);
  ASSERT_EQ(rc, 0) << log;
  EXPECT_EQ(slurp(fs::path(dir) / "out/scenario.yaml"), slurp(scenario));

  fs::create_directories(dir + "/dir.yaml");
  EXPECT_EQ(augrig("sim --scenario " + dir + "/dir.yaml --out " + dir + "/out2", &log), 1);
  EXPECT_EQ(log, "augrig sim: " + dir + "/dir.yaml: is a directory, expected a file\n");
}

}  // namespace
}  // namespace augrig
