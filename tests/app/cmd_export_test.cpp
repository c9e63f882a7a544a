// augrig export through the real binary (docs/REPLAY.md): on a recording this test writes with
// recorder::Recorder from frames it augments itself, the EuRoC layout, exit codes and messages of
// bad inputs, a truncated recording, and OUT/INCOMPLETE of a killed export; --ground-truth against
// the replay's own ground-truth files and the masks, and its error on a recording without depth;
// a run's stats.csv, shadow columns included, against the export of its recording (EuRoC and the
// MCAP statistics messages), and a recording of schema 2 exported with its shadow 0.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "app/commands.hpp"
#include "core/npy.hpp"
#include "nav/logs.hpp"
#include "pipeline/flight_nav.hpp"
#include "recorder/mcap_reader.hpp"
#include "recorder/plot.hpp"
#include "recorder/reader.hpp"
#include "recorder/recorder.hpp"
#include "recorder/store.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "ros2/messages.hpp"
#include "sim/scenario.hpp"
#include "tests/support/mcap_messages.hpp"
#include "tests/support/output_files.hpp"
#include "tests/support/recording_fixture.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;
using test::augrig_binary;
using test::output_dir;
using test::run_command;
using test::small_rig;
using test::truncated_copy;

int augrig(const std::string& args, std::string* output = nullptr) {
  return test::run_augrig(args, output);
}

// One recording per test process (CTest runs each test in its own process, in parallel).
const std::string& recording() {
  return test::recording_of_this_test("cmd_export_");
}

std::size_t lines_of(const std::string& path) {
  std::ifstream in(path);
  std::string l;
  std::size_t n = 0;
  while (std::getline(in, l)) ++n;
  return n;
}

const std::string& long_recording() {
  return test::recording_of_this_test("cmd_export_long_", 60);
}

// export --reaugment goes through the pipeline: its output is what replaying the recording with the
// same options into a new recording and exporting that gives (the oracle, made by commands that
// existed before), and not the recorded augmentation.
TEST(CmdExport, ReaugmentedMcapIsTheReplaysRecordingExported) {
  const std::string dir = output_dir("cmd_export_reaugment_mcap");
  const std::string boom = "--boom fixed:-30,5,14";
  std::string log;
  ASSERT_EQ(augrig("export " + recording() + " " + dir + "/re.mcap " + boom + " --look plain", &log), 0)
      << log;
  EXPECT_NE(log.find("wrote " + dir + "/re.mcap: 8 stereo frame(s)"), std::string::npos) << log;
  ASSERT_EQ(
      augrig("replay " + recording() + " --headless --look plain " + boom + " --record " + dir + "/rec2",
             &log),
      0)
      << log;
  ASSERT_EQ(augrig("export " + dir + "/rec2 " + dir + "/oracle.mcap", &log), 0) << log;
  ASSERT_EQ(augrig("export " + recording() + " " + dir + "/recorded.mcap", &log), 0) << log;
  const auto re = test::mcap_messages(dir + "/re.mcap"), oracle = test::mcap_messages(dir + "/oracle.mcap"),
             recorded = test::mcap_messages(dir + "/recorded.mcap");
  ASSERT_EQ(re.size(), oracle.size());
  ASSERT_EQ(re.size(), recorded.size());
  std::size_t augmented_differ = 0;
  for (std::size_t i = 0; i < re.size(); ++i) {
    EXPECT_EQ(re[i].first, oracle[i].first) << "message " << i;
    // The oracle's /tf_static comes from rec2's stored rig, one more YAML round trip of the
    // rotation (matrix -> quaternion) away: equal to the last bits, not in them.
    if (re[i].first.rfind("/tf_static", 0) == 0) continue;
    EXPECT_TRUE(re[i].second == oracle[i].second) << re[i].first;
    if (re[i].first.rfind("/left/image_augmented", 0) == 0 && re[i].second != recorded[i].second)
      ++augmented_differ;
  }
  EXPECT_GT(augmented_differ, 0u) << "the recorded augmentation came out again";
  // Options of EuRoC alone are refused, naming the option.
  EXPECT_EQ(augrig("export " + recording() + " " + dir + "/x.mcap --reaugment --ground-truth", &log), 2)
      << log;
  EXPECT_NE(log.find("--ground-truth: only for --format euroc"), std::string::npos) << log;
}

TEST(CmdExport, ReaugmentedEurocIsTheReplaysRecordingExported) {
  const std::string dir = output_dir("cmd_export_reaugment_euroc");
  const std::string boom = "--boom fixed:-25,-5,13";
  std::string log;
  ASSERT_EQ(augrig("export " + recording() + " " + dir + "/re --no-plot " + boom, &log), 0) << log;
  ASSERT_EQ(augrig("replay " + recording() + " --headless " + boom + " --record " + dir + "/rec2", &log), 0)
      << log;
  // The oracle is given the recording's rig as it is (rec2 stores it after one more YAML round trip
  // of the rotation: equal to the last bits, not in them).
  {
    auto rec = recorder::RecordingReader::open(recording());
    ASSERT_TRUE(rec) << rec.error().message;
    std::ofstream(dir + "/rig.yaml") << (*rec)->meta("rig_yaml");
  }
  ASSERT_EQ(augrig("export " + dir + "/rec2 " + dir + "/oracle --no-plot --rig " + dir + "/rig.yaml", &log),
            0)
      << log;
  // rig.yaml names the rig's source file; everything else is the same, byte for byte.
  const auto re = test::files_under(dir + "/re", "rig.yaml"),
             oracle = test::files_under(dir + "/oracle", "rig.yaml");
  ASSERT_EQ(re.size(), oracle.size());
  ASSERT_TRUE(re.count("mav0/cam0_augmented/data.csv"));
  for (const auto& [name, bytes] : re) {
    ASSERT_TRUE(oracle.count(name)) << name;
    EXPECT_TRUE(bytes == oracle.at(name)) << name;
  }
  // ... and not the recorded augmentation.
  ASSERT_EQ(augrig("export " + recording() + " " + dir + "/recorded --no-plot", &log), 0) << log;
  const auto recorded = test::files_under(dir + "/recorded", "rig.yaml");
  for (const auto& [name, bytes] : re) {
    if (name.rfind("mav0/cam0/data/", 0) == 0) {
      EXPECT_TRUE(recorded.at(name) == bytes) << "raw " << name;
    }
  }
  EXPECT_FALSE(recorded.at("stats.csv") == re.at("stats.csv"));
  std::size_t augmented_differ = 0;
  for (const auto& [name, bytes] : re)
    if (name.rfind("mav0/cam0_augmented/data/", 0) == 0 && recorded.at(name) != bytes) ++augmented_differ;
  EXPECT_GT(augmented_differ, 0u) << "the recorded augmentation came out again";
}

// A recording's nav inputs go with its re-augmented export (imu0 and the nav logs, /nav topics).
TEST(CmdExport, ReaugmentedExportsKeepTheNavInputs) {
  const std::string dir = output_dir("cmd_export_reaugment_nav");
  std::string log;
  ASSERT_EQ(augrig("run --source 'sim://demo?every=30' --nav sim --record " + dir +
                       "/rec --duration 3 --headless --status-every 0",
                   &log),
            0)
      << log;
  ASSERT_EQ(augrig("export " + dir + "/rec " + dir + "/re --reaugment --look plain --no-plot", &log), 0)
      << log;
  EXPECT_NE(log.find("imu0 ("), std::string::npos) << log;
  EXPECT_GT(lines_of(dir + "/re/mav0/imu0/data.csv"), 100u);
  EXPECT_TRUE(fs::exists(dir + "/re/nav/tanker/gps.nmea"));
  ASSERT_EQ(augrig("export " + dir + "/rec " + dir + "/re.mcap --reaugment", &log), 0) << log;
  std::map<std::string, int> topics;
  for (const auto& m : test::mcap_messages(dir + "/re.mcap")) ++topics[m.first.substr(0, m.first.find(' '))];
  EXPECT_GT(topics["/nav/tanker/imu"], 100) << log;
  EXPECT_GT(topics["/nav/receiver/gps"], 5) << log;
}

// A recording cut in half: export said "Exported 99 of 99" and exited 0 while the summary said
// 201. It must say what is missing, exit 1 and mark its output.
// --format kitti|middlebury: the recording augmented again into the benchmark's layout, a file per
// pair and tree (the files themselves: tests/pipeline/sinks/stereo_benchmark_sink_test.cpp); the
// options of the other formats refused.
TEST(CmdExport, BenchmarkLayoutsFromARecording) {
  const std::string dir = output_dir("cmd_export_benchmarks");
  fs::remove_all(dir);
  std::string log;
  ASSERT_EQ(augrig("export " + recording() + " " + dir + "/k --format kitti --look plain", &log), 0) << log;
  EXPECT_NE(log.find(dir + "/k: 8 stereo pair(s) in the KITTI layout"), std::string::npos) << log;
  EXPECT_EQ(lines_of(dir + "/k/frames.csv"), 2u + 8u);
  for (const char* f : {"raw/training/image_2/000007_10.png", "augmented/training/image_3/000007_10.png",
                        "augmented/training/disp_occ_0/000007_10.png", "raw/training/disp_noc_0/000007_10.png",
                        "augmented/training/boom_mask_1/000007_10.png", "raw/training/calib_cam_to_cam/000007.txt"})
    EXPECT_TRUE(fs::exists(dir + "/k/" + f)) << f;
  ASSERT_EQ(augrig("export " + recording() + " " + dir + "/m --format middlebury", &log), 0) << log;
  EXPECT_NE(log.find(dir + "/m: 8 stereo pair(s) in the Middlebury layout"), std::string::npos) << log;
  EXPECT_TRUE(fs::exists(dir + "/m/raw/000000/disp0GT.pfm"));
  EXPECT_TRUE(fs::exists(dir + "/m/augmented/000007/calib.txt"));
  // Again into the same folder: named, nothing overwritten.
  EXPECT_EQ(augrig("export " + recording() + " " + dir + "/m --format middlebury", &log), 1) << log;
  EXPECT_NE(log.find("holds a benchmark export already"), std::string::npos) << log;
  EXPECT_EQ(augrig("export " + recording() + " " + dir + "/x --format kitti --no-masks", &log), 2) << log;
  EXPECT_NE(log.find("--no-masks: only for --format euroc or mcap"), std::string::npos) << log;
}

// COCO and YOLO labels from a recording (tests/pipeline/sinks/labels_sink_test.cpp checks them).
TEST(CmdExport, PoseLabelsFromARecording) {
  const std::string dir = output_dir("cmd_export_labels");
  std::string log;
  ASSERT_EQ(augrig("export " + recording() + " " + dir + "/c --format coco --look plain", &log), 0) << log;
  EXPECT_NE(log.find(dir + "/c: 16 image(s) of 8 pair(s) labelled in COCO's keypoint format (10 keypoints: "),
            std::string::npos)
      << log;
  EXPECT_TRUE(fs::exists(dir + "/c/annotations.json"));
  EXPECT_TRUE(fs::exists(dir + "/c/images/000007_right.png"));
  EXPECT_FALSE(fs::exists(dir + "/c/INCOMPLETE"));
  EXPECT_EQ(lines_of(dir + "/c/keypoints.csv"), 2u + 16u * 10u);
  ASSERT_EQ(augrig("export " + recording() + " " + dir + "/y --format yolo --look plain", &log), 0) << log;
  EXPECT_NE(log.find("labelled in YOLO's pose format"), std::string::npos) << log;
  EXPECT_TRUE(fs::exists(dir + "/y/labels/000000_left.txt"));
  EXPECT_TRUE(fs::exists(dir + "/y/dataset.yaml"));
  // Again into the same folder: named, nothing overwritten.
  EXPECT_EQ(augrig("export " + recording() + " " + dir + "/y --format yolo", &log), 1) << log;
  EXPECT_NE(log.find("holds labels already (dataset.yaml)"), std::string::npos) << log;
  EXPECT_EQ(augrig("export " + recording() + " " + dir + "/z --format coco --threads 2", &log), 2) << log;
  EXPECT_NE(log.find("--threads: only for --format euroc or mcap"), std::string::npos) << log;
  EXPECT_EQ(augrig("export " + recording() + " " + dir + "/z --format cocoa", &log), 2) << log;
  EXPECT_NE(log.find("expected euroc, mcap, kitti, middlebury, coco or yolo, got 'cocoa'"), std::string::npos)
      << log;
}

TEST(CmdExport, ATruncatedRecordingSaysWhatIsMissing) {
  const std::uintmax_t size = fs::file_size(long_recording() + "/recording.sqlite");
  const std::string half = truncated_copy(long_recording(), "cmd_export_truncated", size / 2);
  std::string log;
  const std::string out = output_dir("cmd_export_truncated_export");
  ASSERT_EQ(augrig("export " + half + " --format euroc " + out + " --no-plot", &log), 1) << log;
  EXPECT_NE(log.find("readable (60 recorded) stereo frame(s)"), std::string::npos) << log;
  EXPECT_NE(log.find("the export is incomplete"), std::string::npos) << log;
  std::ifstream marker(out + "/INCOMPLETE");
  ASSERT_TRUE(marker) << "the output is not marked incomplete";
  const std::string text((std::istreambuf_iterator<char>(marker)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("summary says 60 frames were recorded"), std::string::npos) << text;

  // Cut before the first frame: nothing to export, and it says so with exit 1.
  const std::string head = truncated_copy(long_recording(), "cmd_export_truncated_head", 3 * 65536);
  const std::string out2 = output_dir("cmd_export_truncated_head_export");
  EXPECT_EQ(augrig("export " + head + " --format euroc " + out2 + " --no-plot", &log), 1) << log;
  if (fs::exists(out2 + "/mav0")) {
    EXPECT_TRUE(fs::exists(out2 + "/INCOMPLETE")) << log;
  }
}

TEST(CmdExport, WritesTheEurocLayout) {
  const std::string out = output_dir("cmd_export_layout");
  const bool plot = !recorder::find_gnuplot().empty();
  std::string log;
  ASSERT_EQ(augrig("export " + recording() + " --format euroc " + out + (plot ? "" : " --no-plot"), &log), 0)
      << log;
  EXPECT_NE(log.find("Exported 8 of 8 stereo frame(s) to " + out +
                     "/mav0: cam0, cam1, cam0_augmented, cam1_augmented, cam0_mask, cam1_mask"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("note: no nav inputs in the recording: imu0 not written"), std::string::npos) << log;
  EXPECT_EQ(lines_of(out + "/mav0/cam0/data.csv"), 9u);
  EXPECT_EQ(lines_of(out + "/mav0/cam1_mask/data.csv"), 9u);
  EXPECT_TRUE(fs::exists(out + "/mav0/cam1/sensor.yaml"));
  EXPECT_EQ(lines_of(out + "/stats.csv"), 9u);
  EXPECT_GT(lines_of(out + "/poses.csv"), 16u);
  if (plot) {
    EXPECT_TRUE(fs::exists(out + "/stats.png"));
  }

  EXPECT_EQ(augrig("export " + recording() + " --format euroc " + out, &log), 1) << log;
  EXPECT_NE(log.find("augrig export: " + out + "/mav0: exists already"), std::string::npos) << log;
  EXPECT_EQ(augrig("export " + recording() + " --format kitty " + out, &log), 2) << log;
  EXPECT_NE(log.find("--format: expected euroc, mcap, kitti, middlebury, coco or yolo, got 'kitty'"), std::string::npos)
      << log;
  // Without --format: EuRoC into a folder (here one that holds an export already), MCAP into a .mcap.
  EXPECT_EQ(augrig("export " + recording() + " " + out, &log), 1) << log;
  EXPECT_NE(log.find("augrig export: " + out + "/mav0: exists already"), std::string::npos) << log;
  ASSERT_EQ(augrig("export " + recording() + " " + out + "_default.mcap --no-augmented --no-masks", &log), 0)
      << log;
  {
    std::ifstream m(out + "_default.mcap", std::ios::binary);
    char magic[5] = {};
    m.read(magic, 5);
    EXPECT_EQ(std::string(magic + 1, 4), "MCAP") << "an MCAP file";
  }
  EXPECT_EQ(augrig("export " + recording() + " --format euroc", &log), 2) << log;
  EXPECT_NE(log.find("expected DIR OUT, got '" + recording() + "'"), std::string::npos) << log;
  EXPECT_EQ(augrig("export " + output_dir("cmd_export_missing") + "/x --format=euroc " + out + "2", &log), 1)
      << log;
  EXPECT_NE(log.find("/x: no such file"), std::string::npos) << log;
}

// A finished export leaves no marker; one killed part-way leaves OUT/INCOMPLETE next to what it
// wrote (it once left PNGs and empty data.csv files that looked like a finished export).
TEST(CmdExport, AKilledExportIsMarkedIncomplete) {
  const std::string done = output_dir("cmd_export_done");
  std::string log;
  ASSERT_EQ(augrig("export " + long_recording() + " --format euroc " + done + " --no-plot", &log), 0) << log;
  EXPECT_FALSE(fs::exists(done + "/INCOMPLETE"));
  int killed = 0;
  // The export of 60 small frames takes a few tenths of a second on one thread: kills from 20 ms on.
  for (const char* after : {"0.02", "0.05", "0.08", "0.12", "0.2", "0.3"}) {
    const std::string out = output_dir(std::string("cmd_export_killed_") + after);
    const int rc = run_command("timeout -s KILL " + std::string(after) + " " + augrig_binary() + " export " +
                                   long_recording() + " --format euroc " + out + " --no-plot --threads 1",
                               &log);
    if (rc == 0) {
      EXPECT_FALSE(fs::exists(out + "/INCOMPLETE"));
      continue;
    }
    ++killed;
    if (fs::exists(out + "/mav0") && !fs::exists(out + "/INCOMPLETE")) {
      // Killed after the export had finished (the marker is removed last): then all of it is there.
      for (const char* csv : {"/mav0/cam0/data.csv", "/mav0/cam1_mask/data.csv"}) {
        std::ifstream a(done + csv), b(out + csv);
        const std::string want((std::istreambuf_iterator<char>(a)), {}),
            got((std::istreambuf_iterator<char>(b)), {});
        EXPECT_EQ(got, want) << "killed after " << after << " s without INCOMPLETE, yet " << csv
                             << " differs";
      }
    }
  }
  EXPECT_GT(killed, 0) << "no export was killed part-way: the test did not test";
}

// A recording made with live nav (IMU as binary datagrams, rows with t_ns 0 and clock unknown)
// exports: imu0 from the datagrams, per aircraft the logs augrig nav fuses, the frame index on GPS
// time; augrig nav on them (RTS smoothing) gives the poses the live filter recorded, to within
// what the live (forward-only) filter itself claimed: |difference| <= 3 sigma_pos_m + 2 cm, and
// 3 sigma_att_deg + 0.05 deg. The two filters see the same data on the same clock (the frames'
// GPS times are estimated to well under a millisecond, ~0.2 mm of relative motion here), so what
// remains is smoothing against filtering: within the forward filter's own 1-sigma most of the time.
TEST(CmdExport, ALiveNavRecordingIsReFusedOffline) {
  const std::string dir = output_dir("cmd_export_live");
  std::string log;
  ASSERT_EQ(augrig("run --source 'sim://demo?every=3' --nav sim --record " + dir +
                       "/rec --duration 15 --headless --status-every 0",
                   &log),
            0)
      << log;
  // The aircraft settings the run used (--nav sim: the scenario's sensors), as files.
  const sim::Scenario scenario = *sim::builtin_scenario("demo");
  for (const auto& [who, sensors] :
       {std::pair{"tanker", &scenario.sensors.tanker}, std::pair{"receiver", &scenario.sensors.receiver}})
    std::ofstream(dir + "/" + who + ".yaml")
        << pipeline::aircraft_config_to_yaml(pipeline::ins_config_for(*sensors));
  const std::string out = dir + "/euroc";
  ASSERT_EQ(augrig("export " + dir + "/rec --format euroc " + out + " --no-plot --aircraft tanker=" + dir +
                       "/tanker.yaml,receiver=" + dir + "/receiver.yaml",
                   &log),
            0)
      << log;
  EXPECT_NE(log.find("imu0 ("), std::string::npos) << log;
  EXPECT_NE(log.find("Clock: gps for every timestamp exported"), std::string::npos) << log;
  EXPECT_NE(log.find("export: "), std::string::npos) << "no progress line: " << log;
  EXPECT_FALSE(fs::exists(out + "/INCOMPLETE"));
  for (const char* who : {"tanker", "receiver"})
    for (const char* f : {"gps.nmea", "imu.csv", "aircraft.yaml"})
      EXPECT_TRUE(fs::exists(out + "/nav/" + who + "/" + f)) << who << "/" << f;
  // imu0 rows: one per datagram sample, none missing: consecutive rows 5 ms apart (the demo's IMU is
  // 200 Hz). How many depends on how much of the 6 s the run covered on a loaded machine, so the count
  // itself is only bounded below.
  {
    std::ifstream in(out + "/mav0/imu0/data.csv");
    std::vector<std::int64_t> t_ns;
    for (std::string l; std::getline(in, l);)
      if (!l.empty() && l[0] != '#') t_ns.push_back(std::stoll(l.substr(0, l.find(','))));
    ASSERT_GT(t_ns.size(), 400u) << "less than 2 s of IMU exported";
    std::size_t gaps = 0;
    for (std::size_t i = 1; i < t_ns.size(); ++i) gaps += (t_ns[i] - t_ns[i - 1] != 5'000'000) ? 1 : 0;
    EXPECT_EQ(gaps, 0u) << "of " << t_ns.size() << " IMU rows";
  }

  ASSERT_EQ(augrig("nav --tanker " + out + "/nav/tanker --receiver " + out + "/nav/receiver --rig " + out +
                       "/rig.yaml --frames " + out + "/frames.csv --out " + dir + "/refused.csv",
                   &log),
            0)
      << log;
  auto recorded = nav::read_camera_pose_csv(out + "/poses.csv");
  auto refused = nav::read_camera_pose_csv(dir + "/refused.csv");
  ASSERT_TRUE(recorded) << recorded.error().message;
  ASSERT_TRUE(refused) << refused.error().message;
  std::map<std::pair<int, TimestampNs>, nav::CameraPoseRow> by_key;
  for (const nav::CameraPoseRow& r : refused->rows) by_key[{r.camera, r.t_ns}] = r;
  // The live filter's sigma is optimistic while it converges (its first seconds: docs/NAV_FUSION.md,
  // "Consistency"; the live status says CONVERGING, the recording does not carry it): the claim is
  // checked on the poses from 10 s after the first one on, when both of the demo's filters have
  // settled (8.8 and 9.3 s at most).
  TimestampNs first_pose_ns = std::numeric_limits<TimestampNs>::max();
  for (const nav::CameraPoseRow& a : recorded->rows) first_pose_ns = std::min(first_pose_ns, a.t_ns);
  std::size_t compared = 0, settled = 0;
  for (const nav::CameraPoseRow& a : recorded->rows) {
    const auto it = by_key.find({a.camera, a.t_ns});
    if (it == by_key.end()) continue;
    ++compared;  // every recorded pose has its offline counterpart
    if (a.t_ns < first_pose_ns + 10'000'000'000) continue;
    ++settled;
    const nav::CameraPoseRow& b = it->second;
    const double dp = std::sqrt((a.x_m - b.x_m) * (a.x_m - b.x_m) + (a.y_m - b.y_m) * (a.y_m - b.y_m) +
                                (a.z_m - b.z_m) * (a.z_m - b.z_m));
    const double dot = std::abs(a.qw * b.qw + a.qx * b.qx + a.qy * b.qy + a.qz * b.qz);
    const double da_deg = rad_to_deg(2.0 * std::acos(std::min(1.0, dot)));
    EXPECT_LE(dp, 3 * a.sigma_pos_m + 0.02) << "camera " << a.camera << " t_ns " << a.t_ns;
    EXPECT_LE(da_deg, 3 * a.sigma_att_deg + 0.05) << "camera " << a.camera << " t_ns " << a.t_ns;
  }
  // Every recorded pose (frames with the receiver) has its offline counterpart.
  EXPECT_EQ(compared, recorded->rows.size());
  // How many frames had a live pose depends on the machine's load (the paced simulated cameras lose
  // late frames; the live filter needs its first fixes): under the sanitizers beside two compiles,
  // 4 of them in 6 s. A few settled ones are enough for the comparison to mean something.
  EXPECT_GT(settled, 3u);
}

// The rows of a EuRoC data.csv: the file names, in order.
std::vector<std::string> csv_files(const std::string& path) {
  std::vector<std::string> files;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line))
    if (!line.empty() && line[0] != '#') files.push_back(line.substr(line.find(',') + 1));
  return files;
}

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

bool same_png(const std::string& a, const std::string& b) {
  const cv::Mat ma = cv::imread(a, cv::IMREAD_UNCHANGED), mb = cv::imread(b, cv::IMREAD_UNCHANGED);
  return !ma.empty() && ma.size == mb.size && ma.type() == mb.type() &&
         std::equal(ma.datastart, ma.dataend, mb.datastart);
}

// A simulated run recorded without depth: export --ground-truth refuses it, saying how to store the
// depth; replayed with --record --ground-truth (and the per-frame files written by the same replay),
// the export's ground truth equals the replay's files bit for bit, and the depth is finite exactly
// where the exported mask has the receiver bit.
TEST(CmdExport, GroundTruthAgreesWithTheReplaysFilesAndTheMasks) {
  const std::string dir = output_dir("cmd_export_ground_truth");
  std::string log;
  ASSERT_EQ(
      augrig("run --source 'sim://demo?every=60&rate=0' --frames 3 --headless --status-every 0 --record " +
                 dir + "/plain 2>&1",
             &log),
      0)
      << log;
  // No depth recorded: a clear error, non-zero exit, nothing written.
  EXPECT_EQ(
      augrig("export " + dir + "/plain --format euroc " + dir + "/refused --ground-truth --no-plot 2>&1",
             &log),
      1)
      << log;
  EXPECT_NE(log.find("augrig export: " + dir + "/plain/recording.sqlite: frame 0 (pair_sequence "),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("holds no receiver depth (3 of 3 frames hold none)"), std::string::npos) << log;
  EXPECT_NE(log.find("augrig replay " + dir + "/plain --record NEW --ground-truth"), std::string::npos)
      << log;
  EXPECT_FALSE(fs::exists(dir + "/refused/mav0"));
  // Without --ground-truth the same recording exports as ever.
  ASSERT_EQ(augrig("export " + dir + "/plain --format euroc " + dir + "/plain_export --no-plot 2>&1", &log),
            0)
      << log;
  EXPECT_FALSE(fs::exists(dir + "/plain_export/mav0/cam0_depth"));

  ASSERT_EQ(augrig("replay " + dir + "/plain --headless --out " + dir +
                       "/files --every 1 --ground-truth --record " + dir + "/gt 2>&1",
                   &log),
            0)
      << log;
  ASSERT_EQ(augrig("check " + dir + "/gt", &log), 0) << log;
  EXPECT_NE(log.find("receiver depth: 3 frames\n"), std::string::npos) << log;
  const std::string out = dir + "/export";
  ASSERT_EQ(
      augrig("export " + dir + "/gt --format euroc " + out + " --ground-truth --no-plot --threads 2 2>&1",
             &log),
      0)
      << log;
  EXPECT_NE(log.find("cam0_stereo_class (3 frames)"), std::string::npos) << log;
  const std::string mav0 = out + "/mav0/";
  const std::vector<std::string> masks = csv_files(mav0 + "cam0_mask/data.csv");
  const std::vector<std::string> depth0 = csv_files(mav0 + "cam0_depth/data.csv");
  const std::vector<std::string> depth1 = csv_files(mav0 + "cam1_depth/data.csv");
  const std::vector<std::string> mm0 = csv_files(mav0 + "cam0_depth_mm/data.csv");
  const std::vector<std::string> mm1 = csv_files(mav0 + "cam1_depth_mm/data.csv");
  const std::vector<std::string> uv = csv_files(mav0 + "cam0_right_px/data.csv");
  const std::vector<std::string> cls = csv_files(mav0 + "cam0_stereo_class/data.csv");
  ASSERT_EQ(depth0.size(), 3u);
  ASSERT_EQ(masks.size(), 3u);
  for (const auto* v : {&depth1, &mm0, &mm1, &uv, &cls}) ASSERT_EQ(v->size(), 3u);
  EXPECT_TRUE(fs::exists(mav0 + "cam0_right_px/sensor.yaml"));
  std::size_t receiver_px = 0;
  for (std::size_t k = 0; k < 3; ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    // The replay names its files by the recorded frame's index.
    char stem[16];
    std::snprintf(stem, sizeof stem, "%06zu", k);
    const std::string f = dir + "/files/";
    // The file named for the left camera's time is the left camera's, in frame order.
    EXPECT_EQ(depth0[k].substr(0, depth0[k].size() - 4), masks[k].substr(0, masks[k].size() - 4));
    auto z0 = read_npy_f32(mav0 + "cam0_depth/data/" + depth0[k]);
    auto z1 = read_npy_f32(mav0 + "cam1_depth/data/" + depth1[k]);
    auto uvx = read_npy_f32(mav0 + "cam0_right_px/data/" + uv[k]);
    auto z0_files = read_npy_f32(f + "left/depth/" + stem + ".npy");
    auto z1_files = read_npy_f32(f + "right/depth/" + stem + ".npy");
    auto uv_files = read_npy_f32(f + "left/right_px/" + stem + ".npy");
    for (const auto* a : {&z0, &z1, &uvx, &z0_files, &z1_files, &uv_files})
      ASSERT_TRUE(*a) << a->error().message;
    EXPECT_EQ(z0->shape, (std::vector<std::int64_t>{960, 1280}));
    EXPECT_EQ(uvx->shape, (std::vector<std::int64_t>{960, 1280, 2}));
    EXPECT_TRUE(same_bits(z0->values, z0_files->values));
    EXPECT_TRUE(same_bits(z1->values, z1_files->values));
    EXPECT_TRUE(same_bits(uvx->values, uv_files->values));
    EXPECT_TRUE(same_png(mav0 + "cam0_depth_mm/data/" + mm0[k], f + "left/depth_mm/" + stem + ".png"));
    EXPECT_TRUE(same_png(mav0 + "cam1_depth_mm/data/" + mm1[k], f + "right/depth_mm/" + stem + ".png"));
    EXPECT_TRUE(
        same_png(mav0 + "cam0_stereo_class/data/" + cls[k], f + "left/stereo_class/" + stem + ".png"));
    // Finite depth exactly where the exported mask has the receiver bit.
    const cv::Mat mask = cv::imread(mav0 + "cam0_mask/data/" + masks[k], cv::IMREAD_UNCHANGED);
    ASSERT_EQ(mask.total(), z0->values.size());
    std::size_t mismatched = 0;
    for (std::size_t i = 0; i < mask.total(); ++i) {
      const bool receiver = (mask.data[i] & kMaskReceiver) != 0;
      receiver_px += receiver;
      mismatched += receiver != std::isfinite(z0->values[i]);
    }
    EXPECT_EQ(mismatched, 0u);
  }
  EXPECT_GT(receiver_px, 1000u) << "the receiver must be in view for the comparison to mean anything";
}

// The rows of a stats.csv (read_stats_csv: the current header or the 19 columns before the shadow's).
std::vector<OcclusionStats> stats_rows(const std::string& path) {
  auto rows = read_stats_csv(path);
  EXPECT_TRUE(rows) << rows.error().message;
  return rows ? *rows : std::vector<OcclusionStats>{};
}

// Every /augrig/occlusion_stats message of an MCAP file, decoded, in file order.
std::vector<OcclusionStats> mcap_stats(const std::string& path) {
  std::vector<OcclusionStats> out;
  auto r = recorder::McapReader::open(path);
  EXPECT_TRUE(r) << r.error().message;
  if (!r) return out;
  const std::uint16_t channel = (*r)->channel_id("/augrig/occlusion_stats");
  EXPECT_NE(channel, 0);
  recorder::McapMessage m;
  for (;;) {
    auto more = (*r)->next(m);
    EXPECT_TRUE(more) << more.error().message;
    if (!more || !*more) break;
    if (m.channel_id != channel) continue;
    auto st = ros2::decode_occlusion_stats(m.data);
    EXPECT_TRUE(st) << st.error().message;
    if (st) out.push_back(*st);
  }
  return out;
}

// A stats.csv row (percentages to 4 decimals) but for t_ns, which the export puts on the clock it
// chooses.
std::string counts_of(OcclusionStats s) {
  s.t_ns = 0;
  std::ostringstream row;
  write_stats_csv_row(row, s);
  return row.str();
}

// A simulated run with the camera look (the default) under the ephemeris sun, which casts the
// boom's shadow on the receiver near contact, records (the look's updates too) and writes
// stats.csv; exported, its recording gives back the same rows, the shadow columns included, in
// stats.csv and in the MCAP statistics messages. The same recording as schema 2 wrote it (no
// shadow columns) exports with the shadow 0 and every other column as before.
TEST(CmdExport, ARunsShadowColumnsComeBackFromItsRecording) {
  const std::string dir = output_dir("cmd_export_shadow");
  std::string log;
  ASSERT_EQ(
      augrig("run --source 'sim://demo?every=200&rate=0' --frames 5 --headless --status-every 0 --record " +
                 dir + "/rec --out " + dir + "/run 2>&1",
             &log),
      0)
      << log;
  const std::vector<OcclusionStats> run = stats_rows(dir + "/run/stats.csv");
  ASSERT_EQ(run.size(), 5u);  // frames 0, 200, ..., 800: the shadow falls on the receiver near contact
  std::int64_t shadow_px = 0;
  for (const OcclusionStats& s : run) shadow_px += s.shadow_px_left + s.shadow_px_right;
  ASSERT_GT(shadow_px, 0) << "the run must see the boom's shadow for the comparison to mean anything";
  // Each pair (6.7 s apart) sampled by the look: both cameras' noise estimated and the light measured.
  ASSERT_EQ(augrig("check " + dir + "/rec", &log), 0) << log;
  EXPECT_NE(log.find("look updates: 10 noise, 5 light\n"), std::string::npos) << log;

  ASSERT_EQ(augrig("export " + dir + "/rec --format euroc " + dir + "/euroc --no-plot 2>&1", &log), 0) << log;
  const std::vector<OcclusionStats> exported = stats_rows(dir + "/euroc/stats.csv");
  ASSERT_EQ(exported.size(), run.size());
  for (std::size_t i = 0; i < run.size(); ++i)
    EXPECT_EQ(counts_of(exported[i]), counts_of(run[i])) << "row " << i;

  ASSERT_EQ(augrig("export " + dir + "/rec --format mcap " + dir + "/rec.mcap 2>&1", &log), 0) << log;
  const std::vector<OcclusionStats> messages = mcap_stats(dir + "/rec.mcap");
  ASSERT_EQ(messages.size(), run.size());
  for (std::size_t i = 0; i < run.size(); ++i)
    EXPECT_EQ(counts_of(messages[i]), counts_of(run[i])) << "message " << i;

  // As schema 2 wrote it: no shadow columns.
  const std::string old = output_dir("cmd_export_shadow_schema2");
  fs::copy_file(dir + "/rec/recording.sqlite", old + "/recording.sqlite",
                fs::copy_options::overwrite_existing);
  {
    auto d = recorder::Database::open(old + "/recording.sqlite", SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->exec("DROP TABLE look; UPDATE meta SET value = '2' WHERE key = 'schema_version'"));
    for (const std::string& c : recorder::frame_columns_added_after(2))
      ASSERT_TRUE(d->exec("ALTER TABLE frames DROP COLUMN " + c)) << c;
  }
  ASSERT_EQ(augrig("check " + old, &log), 0) << log;
  EXPECT_NE(log.find("schema version: 2"), std::string::npos) << log;
  ASSERT_EQ(augrig("export " + old + " --format euroc " + old + "/euroc --no-plot 2>&1", &log), 0) << log;
  const std::vector<OcclusionStats> before = stats_rows(old + "/euroc/stats.csv");
  ASSERT_EQ(before.size(), run.size());
  for (std::size_t i = 0; i < run.size(); ++i) {
    OcclusionStats want = run[i];
    want.shadow_px_left = want.shadow_px_right = 0;
    want.shadow_pct_left = want.shadow_pct_right = 0;
    EXPECT_EQ(counts_of(before[i]), counts_of(want)) << "row " << i;
  }
}

}  // namespace
}  // namespace augrig
