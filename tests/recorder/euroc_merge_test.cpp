// merge_euroc(): EuRoC folders of consecutive frame ranges joined, on parts written here by hand
// (the campaign's merge test joins the real sink's parts and compares them with one export of the
// whole: tests/campaign/merge_test.cpp). Tables joined under the header the parts share, images
// linked not copied, what the parts wrote alike taken once, the receiver's velocities made again
// across the join, phases each once with seconds from the whole's first row; overlapping parts,
// parts out of order, parts that disagree and a part that is not a EuRoC folder are errors naming
// the file; an incomplete part is a problem the joined folder's INCOMPLETE lists.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "recorder/euroc.hpp"
#include "render/stats.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::recorder {
namespace {

namespace fs = std::filesystem;

std::string read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << text;
}

// A state row: t, p = (x, 0, 0), q = identity, v as the part wrote it (one-sided at its ends), biases.
std::string state_row(TimestampNs t, double x, double v) {
  std::ostringstream s;
  s << t << "," << x << ",0,0,1,0,0,0," << v << ",0,0,0,0,0,0,0,0\n";
  return s.str();
}

// A part of frames at `times` (ns): cam0 images and data.csv, sensor.yaml and rig.yaml alike in
// every part, stats.csv, poses-like frames.csv with a metadata header, the receiver moving 1 m per
// 100 ns (v = 1e7 m/s), and phases.
void write_part(const fs::path& dir, const std::vector<TimestampNs>& times, const std::string& phases) {
  std::string data = "#timestamp [ns],filename\n",
              frames = "# augrig frame index\n# clock: gps\nsequence,t_ns\n";
  std::ostringstream stats;
  write_stats_csv_header(stats);
  std::string states = "#timestamp, p_RS_R_x [m], ... 17 columns\n";
  for (std::size_t i = 0; i < times.size(); ++i) {
    const TimestampNs t = times[i];
    write(dir / "mav0/cam0/data" / (std::to_string(t) + ".png"), "image " + std::to_string(t));
    data += std::to_string(t) + "," + std::to_string(t) + ".png\n";
    frames += std::to_string(t / 100) + "," + std::to_string(t) + "\n";
    OcclusionStats s;
    s.t_ns = t;
    s.receiver_px_left = static_cast<std::int64_t>(t);
    write_stats_csv_row(stats, s);
    states += state_row(t, static_cast<double>(t) / 100.0, times.size() > 1 ? 1e7 : 0.0);
  }
  write(dir / "mav0/cam0/data.csv", data);
  write(dir / "mav0/cam0/sensor.yaml", "sensor_type: camera\nrate_hz: 10\n");
  write(dir / "mav0/imu0/data.csv", "#timestamp [ns],w\n5,0.1\n");  // the whole recording's, in each part
  write(dir / "mav0/state_groundtruth_estimate0/data.csv", states);
  write(dir / "rig.yaml", "cameras: []\n");
  write(dir / "frames.csv", frames);
  write(dir / "stats.csv", stats.str());
  if (!phases.empty()) write(dir / "phases.csv", "#t_ns,t_s,phase\n" + phases);
}

struct MergeEurocTest : ::testing::Test {
  fs::path dir;
  std::string a, b;
  void SetUp() override {
    dir = test::output_dir("euroc_merge");
    a = (dir / "a").string();
    b = (dir / "b").string();
    write_part(a, {100, 200}, "100,0.000000,approach\n");
    // b opens with the phase it starts in, as a shard's export does: no change at 300.
    write_part(b, {300, 400}, "300,0.000000,approach\n350,0.000000,contact\n");
  }
};

TEST_F(MergeEurocTest, JoinsTablesLinksImagesAndRemakesWhatSpansTheJoin) {
  EurocMergeReport r;
  const Status s = merge_euroc({a, b}, (dir / "m").string(), {false, ""}, r);
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(r.frames, 4u);
  EXPECT_EQ(r.images, 4u);
  EXPECT_TRUE(r.problems.empty());
  EXPECT_FALSE(fs::exists(dir / "m/INCOMPLETE"));
  EXPECT_EQ(read(dir / "m/mav0/cam0/data.csv"),
            "#timestamp [ns],filename\n100,100.png\n200,200.png\n300,300.png\n400,400.png\n");
  EXPECT_EQ(read(dir / "m/frames.csv"),
            "# augrig frame index\n# clock: gps\nsequence,t_ns\n1,100\n2,200\n3,300\n4,400\n");
  // Linked, not copied: the part keeps its image, the joined folder's is the same file.
  EXPECT_TRUE(fs::equivalent(dir / "m/mav0/cam0/data/300.png", fs::path(b) / "mav0/cam0/data/300.png"));
  EXPECT_EQ(read(dir / "m/mav0/cam0/data/100.png"), "image 100");
  // What each part wrote alike, once.
  EXPECT_EQ(read(dir / "m/mav0/imu0/data.csv"), "#timestamp [ns],w\n5,0.1\n");
  EXPECT_EQ(read(dir / "m/rig.yaml"), "cameras: []\n");
  // The statistics row for row.
  auto stats = read_stats_csv((dir / "m/stats.csv").string());
  ASSERT_TRUE(stats) << stats.error().message;
  ASSERT_EQ(stats->size(), 4u);
  EXPECT_EQ((*stats)[2].t_ns, 300);
  EXPECT_EQ((*stats)[3].receiver_px_left, 400);
  // The rows at the join (200 and 300) from both neighbours, as one export of the four writes them
  // (the shortest text of 1 m per 100 ns).
  std::istringstream states(read(dir / "m/mav0/state_groundtruth_estimate0/data.csv"));
  std::string line;
  std::getline(states, line);
  std::vector<std::string> rows;
  while (std::getline(states, line)) rows.push_back(line);
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[1], "200,2,0,0,1,0,0,0,1e+07,0,0,0,0,0,0,0,0");
  EXPECT_EQ(rows[2], "300,3,0,0,1,0,0,0,1e+07,0,0,0,0,0,0,0,0");
  // The phases: each change once ("approach" not again at b's start), seconds from the whole's first row (t = 100).
  EXPECT_EQ(read(dir / "m/phases.csv"), "#t_ns,t_s,phase\n100,0.000000,approach\n350,0.000000,contact\n");
}

TEST_F(MergeEurocTest, VelocitiesAcrossTheJoinAreMadeAgain) {
  // The receiver stops at the join: b's positions stay at 2 m. One export of the four frames gives
  // 200: (2 - 1) / 200 ns = 5e6 m/s, 300: (2 - 2) / 200 ns = 0.
  write_part(b, {300, 400}, "");
  write(fs::path(b) / "mav0/state_groundtruth_estimate0/data.csv",
        "#timestamp, p_RS_R_x [m], ... 17 columns\n" + state_row(300, 2, 0) + state_row(400, 2, 0));
  EurocMergeReport r;
  ASSERT_TRUE(merge_euroc({a, b}, (dir / "m").string(), {false, ""}, r));
  std::istringstream states(read(dir / "m/mav0/state_groundtruth_estimate0/data.csv"));
  std::string line;
  std::vector<std::string> rows;
  while (std::getline(states, line)) rows.push_back(line);
  ASSERT_EQ(rows.size(), 5u);
  EXPECT_EQ(rows[1], "100,1,0,0,1,0,0,0,1e+07,0,0,0,0,0,0,0,0");
  EXPECT_EQ(rows[2], "200,2,0,0,1,0,0,0,5e+06,0,0,0,0,0,0,0,0");
  EXPECT_EQ(rows[3], "300,2,0,0,1,0,0,0,0,0,0,0,0,0,0,0,0");
}

TEST_F(MergeEurocTest, PartsThatOverlapDisagreeOrAreOutOfOrderAreErrors) {
  EurocMergeReport r;
  // The same part twice: its images twice.
  Status s = merge_euroc({a, a}, (dir / "twice").string(), {false, ""}, r);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("holds this image too: the parts overlap"), std::string::npos)
      << s.error().message;
  // Out of order: b's times before a's.
  s = merge_euroc({b, a}, (dir / "swapped").string(), {false, ""}, r);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("mav0/cam0/data.csv:2: timestamp 100 follows 400"), std::string::npos)
      << s.error().message;
  // A file every part writes alike, different.
  write(fs::path(b) / "mav0/cam0/sensor.yaml", "sensor_type: camera\nrate_hz: 20\n");
  s = merge_euroc({a, b}, (dir / "differ").string(), {false, ""}, r);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message, "recorder::merge_euroc(): " + b + "/mav0/cam0/sensor.yaml: differs from " + a +
                                   "/mav0/cam0/sensor.yaml (each part of one recording writes it alike)");
  // Not a EuRoC folder; a joined folder that exists.
  s = merge_euroc({a, (dir / "nothing").string()}, (dir / "none").string(), {false, ""}, r);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message, "recorder::merge_euroc(): " + (dir / "nothing").string() +
                                   ": not a EuRoC folder (no mav0 in it)");
  EXPECT_FALSE(fs::exists(dir / "none"));
  s = merge_euroc({a}, a, {false, ""}, r);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message,
            "recorder::merge_euroc(): " + a + "/mav0: exists already; join into a new folder");
  s = merge_euroc({}, (dir / "empty").string(), {false, ""}, r);
  ASSERT_FALSE(s);
}

TEST_F(MergeEurocTest, AnIncompletePartIsKeptAndListed) {
  write(fs::path(b) / "INCOMPLETE", "augrig export x -> b is incomplete:\nframe 3: damaged\n");
  EurocMergeReport r;
  ASSERT_TRUE(merge_euroc({a, b}, (dir / "m").string(), {false, ""}, r));
  EXPECT_EQ(r.frames, 4u);
  ASSERT_EQ(r.problems.size(), 1u);
  EXPECT_EQ(r.problems[0], b + ": incomplete (augrig export x -> b is incomplete:)");
  EXPECT_NE(read(dir / "m/INCOMPLETE").find(r.problems[0]), std::string::npos);
}

}  // namespace
}  // namespace augrig::recorder
