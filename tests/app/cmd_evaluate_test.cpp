// augrig evaluate through the real binary on simulated flights, where the answer is known: the raw
// pair matches near the true disparity on the textured receiver, the boom's errors fall in the
// classes it occludes, a recording of a flight evaluates exactly as the flight itself, and bad
// inputs and flags fail with their messages.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>

#include <gtest/gtest.h>

#include "eval/report.hpp"
#include "recorder/plot.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;

int augrig(const std::string& args, std::string* output = nullptr) {
  return test::run_augrig(args, output);
}

// evaluation.csv as rows of column name -> cell (empty cells kept as "").
struct Csv {
  std::vector<std::string> header;
  std::vector<std::map<std::string, std::string>> rows;
  double num(std::size_t r, const std::string& col) const {
    const std::string& v = rows.at(r).at(col);
    return v.empty() ? std::nan("") : std::stod(v);
  }
};
std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, ',')) out.push_back(cell);
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}
Csv read_csv(const std::string& path) {
  Csv c;
  std::ifstream f(path);
  std::string line;
  EXPECT_TRUE(std::getline(f, line)) << path;
  c.header = split(line);
  while (std::getline(f, line)) {
    const auto cells = split(line);
    EXPECT_EQ(cells.size(), c.header.size()) << path << ": " << line.substr(0, 80);
    std::map<std::string, std::string> row;
    for (std::size_t i = 0; i < cells.size() && i < c.header.size(); ++i) row[c.header[i]] = cells[i];
    c.rows.push_back(std::move(row));
  }
  return c;
}

TEST(Evaluate, SimulatedFlightRawMatchesAndTheBoomSpoilsWhatItOccludes) {
  const std::string dir = test::output_dir("evaluate_sim");
  std::string out;
  // Every 90th frame of the demo flight: observation to contact.
  ASSERT_EQ(augrig("evaluate 'sim://demo?every=90' --out " + dir + " --images 4", &out), 0) << out;
  const Csv csv = read_csv(dir + "/evaluation.csv");
  ASSERT_GE(csv.rows.size(), 8u) << out;
  EXPECT_NE(out.find("Evaluated " + std::to_string(csv.rows.size()) + " of " +
                     std::to_string(csv.rows.size()) + " augmented stereo frame(s)"),
            std::string::npos)
      << out;
  int occluded_frames = 0;
  for (std::size_t r = 0; r < csv.rows.size(); ++r) {
    SCOPED_TRACE("frame " + csv.rows[r].at("frame"));
    ASSERT_GT(csv.num(r, "receiver_px"), 1000);
    EXPECT_EQ(csv.num(r, "out_of_range_px"), 0);
    // The raw pair, where both cameras see the receiver: the true disparity, nearly everywhere.
    EXPECT_GT(csv.num(r, "raw_all_both_valid_pct"), 95);
    EXPECT_LT(std::abs(csv.num(r, "raw_all_both_mean_px")), 0.3);
    EXPECT_LT(csv.num(r, "raw_all_both_bad3_pct"), 2.5);
    // The augmented pair where the boom is in front of the receiver in the left image.
    if (csv.num(r, "aug_all_right_only_pixels") > 200) {
      ++occluded_frames;
      EXPECT_GT(csv.num(r, "aug_all_right_only_bad3_pct"), 50);
      EXPECT_GT(csv.num(r, "aug_all_receiver_bad3_pct"), csv.num(r, "raw_all_receiver_bad3_pct") + 3);
      EXPECT_LT(csv.num(r, "aug_noboom_receiver_bad3_pct"), csv.num(r, "aug_all_receiver_bad3_pct"));
    }
    // Every pixel the boom hides from the left camera carries the boom's mask bit.
    EXPECT_EQ(csv.num(r, "aug_noboom_right_only_pixels"), 0);
    EXPECT_EQ(csv.num(r, "aug_noboom_neither_pixels"), 0);
    // The classes add up to the receiver.
    EXPECT_EQ(csv.num(r, "raw_all_receiver_pixels"),
              csv.num(r, "raw_all_both_pixels") + csv.num(r, "raw_all_left_only_pixels") +
                  csv.num(r, "raw_all_right_only_pixels") + csv.num(r, "raw_all_neither_pixels"));
  }
  EXPECT_GE(occluded_frames, 3);
  // The table, printed and written.
  EXPECT_NE(out.find("Stereo: right only"), std::string::npos) << out;
  std::ifstream t(dir + "/evaluation.txt");
  std::stringstream table;
  table << t.rdbuf();
  EXPECT_NE(table.str().find("The boom's pixels left out"), std::string::npos);
  // The camera look by default, said on the title line.
  EXPECT_EQ(table.str().rfind("Stereo evaluation: sim://demo?every=90; look: camera (", 0), 0u)
      << table.str();
  EXPECT_TRUE(fs::exists(dir + "/stats.csv"));
  EXPECT_TRUE(fs::exists(dir + "/disparity/000000_true.png"));
  EXPECT_TRUE(fs::exists(dir + "/disparity/000004_view.png"));
  if (!recorder::find_gnuplot().empty()) {
    EXPECT_GT(fs::file_size(dir + "/evaluation.png"), 10000u);
  }
}

TEST(Evaluate, ARecordingEvaluatesAsTheFlightItRecorded) {
  const std::string dir = test::output_dir("evaluate_recording");
  std::string out;
  ASSERT_EQ(
      augrig("run --source 'sim://demo?every=120&rate=0' --frames 5 --headless --status-every 0 --record " +
                 dir + "/rec",
             &out),
      0)
      << out;
  // The plain look: a recording stores no sun, so the camera look would light the boom by the
  // default sun there and by the ephemeris' in the flight (docs/LOOK.md).
  ASSERT_EQ(augrig("evaluate " + dir + "/rec --look plain --out " + dir + "/from_rec --no-plot", &out), 0)
      << out;
  ASSERT_EQ(
      augrig("evaluate 'sim://demo?every=120' --look plain --frames 5 --out " + dir + "/from_sim --no-plot",
             &out),
      0)
      << out;
  const Csv a = read_csv(dir + "/from_rec/evaluation.csv"), b = read_csv(dir + "/from_sim/evaluation.csv");
  ASSERT_EQ(a.rows.size(), 5u);
  ASSERT_EQ(b.rows.size(), 5u);
  // The recorded raw frames and poses are the flight's: every score the same.
  for (std::size_t r = 0; r < a.rows.size(); ++r)
    for (const std::string& col : a.header)
      if (col != "t_s") {
        EXPECT_EQ(a.rows[r].at(col), b.rows[r].at(col)) << "row " << r << " " << col;
      }
  EXPECT_FALSE(fs::exists(dir + "/from_rec/evaluation.png"));
}

// The lines of a file after its header; `drop`: columns left out (by header name).
std::vector<std::string> rows_of(const std::string& path, const std::vector<std::string>& drop = {}) {
  std::ifstream f(path);
  std::string line;
  EXPECT_TRUE(std::getline(f, line)) << path;
  std::vector<bool> keep;
  for (const std::string& h : split(line))
    keep.push_back(std::find(drop.begin(), drop.end(), h) == drop.end());
  std::vector<std::string> rows;
  while (std::getline(f, line)) {
    const std::vector<std::string> cells = split(line);
    EXPECT_EQ(cells.size(), keep.size()) << path << ": " << line.substr(0, 80);
    std::string r;
    for (std::size_t i = 0; i < cells.size() && i < keep.size(); ++i)
      if (keep[i]) r += cells[i] + ",";
    rows.push_back(r);
  }
  return rows;
}

// evaluate --from-frame A --frames N over consecutive ranges gives the whole run's rows of every
// file, so a campaign's shards concatenate to the unsharded run; the frames are named, selected
// (--every) and timed by their place in the source, not in the part.
void expect_parts_make_the_whole(const std::string& source, const std::string& args, const std::string& dir,
                                 const std::vector<std::pair<int, int>>& ranges) {
  std::string out;
  ASSERT_EQ(augrig("evaluate " + source + " " + args + " --out " + dir + "/whole --no-plot", &out), 0) << out;
  // The wall times of matching are not the same twice: the only cells that may differ.
  const std::vector<std::string> timing = {"prepare_ms", "match_ms", "score_ms"};
  std::vector<std::string> evaluation, sums, stats;
  for (const auto& [from, frames] : ranges) {
    const std::string part = dir + "/part" + std::to_string(from);
    ASSERT_EQ(augrig("evaluate " + source + " " + args + " --from-frame " + std::to_string(from) +
                         " --frames " + std::to_string(frames) + " --out " + part + " --no-plot",
                     &out),
              0)
        << out;
    for (std::string& r : rows_of(part + "/evaluation.csv")) evaluation.push_back(std::move(r));
    for (std::string& r : rows_of(part + "/evaluation_sums.csv", timing)) sums.push_back(std::move(r));
    for (std::string& r : rows_of(part + "/stats.csv")) stats.push_back(std::move(r));
  }
  EXPECT_EQ(evaluation, rows_of(dir + "/whole/evaluation.csv"));
  EXPECT_EQ(sums, rows_of(dir + "/whole/evaluation_sums.csv", timing));
  EXPECT_EQ(stats, rows_of(dir + "/whole/stats.csv"));
}

TEST(Evaluate, PartsOfARecordingOrEurocFolderConcatenateToTheWholeRun) {
  const std::string dir = test::output_dir("evaluate_parts");
  std::string out;
  ASSERT_EQ(
      augrig("run --source 'sim://demo?every=120&rate=0' --frames 7 --headless --status-every 0 --record " +
                 dir + "/rec",
             &out),
      0)
      << out;
  // Every 2nd frame, the disparity images of every 2nd evaluated one; the first part ends on an odd
  // frame count, so the second starts on a frame --every skips. The plain look: the camera look's
  // light and noise estimates build up from the run's first frame, so a part's boom is not drawn
  // exactly as in the whole run (docs/EVALUATE.md).
  expect_parts_make_the_whole(dir + "/rec", "--every 2 --images 2 --look plain", dir, {{0, 3}, {3, 4}});
  const Csv whole = read_csv(dir + "/whole/evaluation.csv");
  ASSERT_EQ(whole.rows.size(), 4u);
  for (std::size_t r = 0; r < 4; ++r) EXPECT_EQ(whole.rows[r].at("frame"), std::to_string(2 * r));
  EXPECT_EQ(whole.rows[0].at("t_s"), "0");
  const Csv second = read_csv(dir + "/part3/evaluation.csv");
  ASSERT_EQ(second.rows.size(), 2u);
  EXPECT_EQ(second.rows[0].at("frame"), "4");  // the recording's frame 4, not the part's 1st
  EXPECT_GT(second.num(0, "t_s"), 10.0);       // seconds after the recording's first frame
  // The disparity images are named by the source's frame: 0 and 4 in the whole run, 4 in the part.
  EXPECT_TRUE(fs::exists(dir + "/whole/disparity/000000_raw.png"));
  EXPECT_TRUE(fs::exists(dir + "/whole/disparity/000004_raw.png"));
  EXPECT_FALSE(fs::exists(dir + "/whole/disparity/000002_raw.png"));
  EXPECT_TRUE(fs::exists(dir + "/part3/disparity/000004_view.png"));
  EXPECT_FALSE(fs::exists(dir + "/part3/disparity/000006_view.png"));
  // evaluation_sums.csv rebuilds the whole run's table.
  auto frames = eval::load_evaluation_sums(dir + "/whole/evaluation_sums.csv");
  ASSERT_TRUE(frames) << frames.error().message;
  eval::RunEvaluation run;
  for (const eval::EvaluatedFrame& f : *frames) run.add(f.evaluation);
  std::ifstream t(dir + "/whole/evaluation.txt");
  std::stringstream table;
  table << t.rdbuf();
  EXPECT_EQ(eval::format_evaluation_table(run,
                                          "Stereo evaluation: " + dir +
                                              "/rec; look: plain (the boom drawn in, a clean rendering under "
                                              "a fixed light)",
                                          eval::MatcherParams{}),
            table.str());

  // The recording as a EuRoC folder, with the recorded poses.
  ASSERT_EQ(augrig("export " + dir + "/rec --format euroc " + dir + "/euroc --no-plot", &out), 0) << out;
  expect_parts_make_the_whole(dir + "/euroc",
                              "--poses " + dir + "/euroc/poses.csv --rig " + dir +
                                  "/euroc/rig.yaml --pair-tolerance-ns 1000000 --every 3 --look plain",
                              dir + "/euroc_parts", {{0, 2}, {2, 3}, {5, 9}});
  const Csv euroc = read_csv(dir + "/euroc_parts/part5/evaluation.csv");
  ASSERT_EQ(euroc.rows.size(), 1u);
  EXPECT_EQ(euroc.rows[0].at("frame"), "6");
}

// A sequence (a frame index of PNG files, as `augrig sim` writes a flight) with its poses CSV: the
// same frames and poses as the flight itself, so the same evaluation up to the poses' text
// rounding (a pixel at a silhouette here and there).
TEST(Evaluate, AnMcapFileEvaluatesAsTheRecordingItWasExportedFrom) {
  std::string why;
  const std::string rec = test::sim_recording("campaign/flight_a.yaml", 3, "campaign_a", &why);
  ASSERT_FALSE(rec.empty()) << why;
  const std::string dir = test::output_dir("evaluate_mcap");
  std::string out;
  ASSERT_EQ(augrig("export " + rec + " --format mcap " + dir + "/flight.mcap", &out), 0) << out;
  // The rig comes from the file's metadata (the recording's is 640x480; the default 1280x960).
  ASSERT_EQ(
      augrig("evaluate " + dir + "/flight.mcap --frames 6 --every 2 --no-plot --out " + dir + "/m", &out), 0)
      << out;
  ASSERT_EQ(augrig("evaluate " + rec + " --frames 6 --every 2 --no-plot --out " + dir + "/r", &out), 0)
      << out;
  const Csv m = read_csv(dir + "/m/evaluation.csv"), r = read_csv(dir + "/r/evaluation.csv");
  ASSERT_EQ(m.rows.size(), 3u);
  ASSERT_EQ(r.rows.size(), 3u);
  for (std::size_t i = 0; i < m.rows.size(); ++i)
    for (const std::string& col : m.header)
      EXPECT_EQ(m.rows[i].at(col), r.rows[i].at(col)) << "row " << i << " " << col;
  // Read front to back: no starting elsewhere.
  EXPECT_EQ(augrig("evaluate " + dir + "/flight.mcap --from-frame 2", &out), 2) << out;
  EXPECT_NE(out.find("an MCAP file is evaluated from its first frame"), std::string::npos) << out;
  // A rig that does not fit its images is an error naming the file, not a crash.
  EXPECT_EQ(augrig("evaluate " + dir + "/flight.mcap --rig default --frames 2", &out), 1) << out;
  EXPECT_NE(out.find("flight.mcap"), std::string::npos) << out;
  EXPECT_NE(out.find("the left image is 640x480, the rig's left camera is 1280x960"), std::string::npos)
      << out;
}

TEST(Evaluate, ASequenceWithItsPosesEvaluatesAsTheFlight) {
  const std::string dir = test::output_dir("evaluate_sequence");
  std::string out;
  ASSERT_EQ(augrig("sim --scenario demo --every 400 --out " + dir + "/ds", &out), 0) << out;
  // The plain look: the poses CSV has no sun (the camera look would take the default one).
  ASSERT_EQ(
      augrig("evaluate " + dir + "/ds/frames/index.csv --poses " + dir + "/ds/truth/poses.csv --rig " + dir +
                 "/ds/rig.yaml --boom fixed:30,0,3.5 --look plain --out " + dir + "/seq --no-plot",
             &out),
      0)
      << out;
  // The flight's own boom tracks the receptacle; the poses CSV holds the scenario's: one boom for both.
  ASSERT_EQ(augrig("evaluate 'sim://demo?every=400' --boom fixed:30,0,3.5 --look plain --out " + dir +
                       "/sim --no-plot",
                   &out),
            0)
      << out;
  const Csv a = read_csv(dir + "/seq/evaluation.csv"), b = read_csv(dir + "/sim/evaluation.csv");
  ASSERT_EQ(a.rows.size(), b.rows.size());
  ASSERT_GE(a.rows.size(), 2u);
  for (std::size_t r = 0; r < a.rows.size(); ++r) {
    SCOPED_TRACE("row " + std::to_string(r));
    EXPECT_NEAR(a.num(r, "receiver_px"), b.num(r, "receiver_px"), 0.002 * b.num(r, "receiver_px") + 2);
    EXPECT_NEAR(a.num(r, "aug_all_right_only_pixels"), b.num(r, "aug_all_right_only_pixels"),
                0.01 * b.num(r, "aug_all_right_only_pixels") + 5);
    EXPECT_NEAR(a.num(r, "raw_all_receiver_bad3_pct"), b.num(r, "raw_all_receiver_bad3_pct"), 0.3);
    EXPECT_NEAR(a.num(r, "aug_all_receiver_bad3_pct"), b.num(r, "aug_all_receiver_bad3_pct"), 0.5);
  }
  // Without poses a sequence cannot be augmented: said before anything is opened.
  EXPECT_EQ(augrig("evaluate " + dir + "/ds/frames/index.csv", &out), 2) << out;
  EXPECT_NE(out.find("--poses POSES.csv"), std::string::npos) << out;
}

// --look physical: the simulator's frames with the boom in the scene are the augmented pair (and,
// being the source's frames, the raw one too); the augmenter flies the scenario's boom, the one in
// the frames, so its masks and stereo classes are those of the physical boom.
TEST(Evaluate, ThePhysicalBoomIsTheSimulatorsFramesWithTheScenariosBoom) {
  const std::string dir = test::output_dir("evaluate_physical");
  std::string out;
  ASSERT_EQ(
      augrig("evaluate 'sim://demo?every=400' --look physical --out " + dir + "/physical --no-plot", &out), 0)
      << out;
  EXPECT_NE(out.find("sim://demo?every=400&boom=physical"), std::string::npos) << out;
  // The progress knows the simulated flight's pair count (it once took 0: no count, no ETA).
  EXPECT_NE(out.find(" of 3 pairs, "), std::string::npos) << out;
  EXPECT_NE(out.find("the scenario's boom"), std::string::npos) << out;
  {
    std::ifstream t(dir + "/physical/evaluation.txt");
    std::string title;
    std::getline(t, title);
    EXPECT_EQ(title,
              "Stereo evaluation: sim://demo?every=400; look: physical boom (the simulator's frames with the "
              "boom in the scene)");
    // The table's augmented columns say that the boom is there, not drawn in.
    const std::string rest((std::istreambuf_iterator<char>(t)), std::istreambuf_iterator<char>());
    EXPECT_NE(rest.find("Augmented pair (the boom in the scene)"), std::string::npos) << rest;
    EXPECT_EQ(rest.find("drawn in"), std::string::npos) << rest;
  }
  // The camera look with the same boom (--boom scenario): the same masks and classes.
  ASSERT_EQ(
      augrig("evaluate 'sim://demo?every=400' --boom scenario --out " + dir + "/camera --no-plot", &out), 0)
      << out;
  const Csv p = read_csv(dir + "/physical/evaluation.csv"), c = read_csv(dir + "/camera/evaluation.csv");
  ASSERT_EQ(p.rows.size(), 3u);
  ASSERT_EQ(c.rows.size(), 3u);
  int occluded_frames = 0;
  for (std::size_t r = 0; r < p.rows.size(); ++r) {
    SCOPED_TRACE("frame " + p.rows[r].at("frame"));
    // The same frames in both columns: every figure the same.
    for (const std::string& col : p.header)
      if (col.rfind("raw_", 0) == 0) {
        EXPECT_EQ(p.rows[r].at(col), p.rows[r].at("aug_" + col.substr(4))) << col;
      }
    for (const std::string& col : p.header)
      if (col.size() > 7 && col.substr(col.size() - 7) == "_pixels") {
        EXPECT_EQ(p.rows[r].at(col), c.rows[r].at(col)) << col;
      }
    // The boom is in the frames, where the masks say: what it hides from the left camera is
    // matched to the boom; what both cameras see is matched as on a boom-free pair (with augrig's
    // tracking boom instead, up to a quarter of these pixels were the physical boom's).
    EXPECT_LT(p.num(r, "raw_all_both_bad3_pct"), 3);
    if (p.num(r, "aug_all_right_only_pixels") > 200) {
      ++occluded_frames;
      EXPECT_GT(p.num(r, "aug_all_right_only_bad3_pct"), 50);
    }
  }
  EXPECT_GE(occluded_frames, 2);
}

TEST(Evaluate, BadInputsAndFlags) {
  const std::string dir = test::output_dir("evaluate_bad");
  std::string out;
  {
    std::ofstream m(dir + "/m.yaml");
    m << "algorithm: sgbm\nnum_disparities: 100\n";
  }
  EXPECT_EQ(augrig("evaluate 'sim://demo?every=300' --matcher " + dir + "/m.yaml", &out), 1) << out;
  EXPECT_NE(out.find("m.yaml:2:"), std::string::npos) << out;
  EXPECT_NE(out.find("num_disparities"), std::string::npos) << out;
  EXPECT_EQ(augrig("evaluate 'sim://demo' --images 3", &out), 2) << out;
  EXPECT_NE(out.find("--images needs --out"), std::string::npos) << out;
  EXPECT_EQ(augrig("evaluate " + dir + "/nothing_here", &out), 1) << out;
  EXPECT_NE(out.find("nothing_here: no such recording"), std::string::npos) << out;
  fs::create_directories(dir + "/euroc/mav0");
  EXPECT_EQ(augrig("evaluate " + dir + "/euroc", &out), 2) << out;
  EXPECT_NE(out.find("--scene SCENE.yaml or --poses"), std::string::npos) << out;
  EXPECT_EQ(augrig("evaluate 'sim://demo' --seek 3", &out), 2) << out;
  EXPECT_EQ(augrig("evaluate 'sim://no-such-scenario'", &out), 1) << out;
  // The looks: the physical boom only in a simulated flight, and with its own boom.
  EXPECT_EQ(augrig("evaluate 'sim://demo' --look bogus", &out), 2) << out;
  EXPECT_NE(out.find("--look: expected plain, camera or physical, got 'bogus'"), std::string::npos) << out;
  EXPECT_EQ(augrig("evaluate " + dir + "/euroc --poses p.csv --look physical", &out), 2) << out;
  EXPECT_NE(out.find("--look physical: only a simulated flight"), std::string::npos) << out;
  EXPECT_EQ(augrig("evaluate 'sim://demo?boom=none' --look physical", &out), 2) << out;
  EXPECT_NE(out.find("--look physical: the source says boom=none"), std::string::npos) << out;
  EXPECT_EQ(augrig("evaluate 'sim://demo' --look physical --boom track", &out), 2) << out;
  EXPECT_NE(out.find("--look physical and --boom track"), std::string::npos) << out;
  EXPECT_EQ(augrig("evaluate " + dir + "/euroc --poses p.csv --boom scenario", &out), 2) << out;
  EXPECT_NE(out.find("--boom scenario: only a simulated flight"), std::string::npos) << out;
  // A search range the receiver's disparity does not fit in: said plainly.
  {
    std::ofstream m(dir + "/narrow.yaml");
    m << "num_disparities: 16\n";
  }
  ASSERT_EQ(augrig("evaluate 'sim://demo?every=800' --matcher " + dir + "/narrow.yaml", &out), 0) << out;
  EXPECT_NE(out.find("WARNING"), std::string::npos) << out;
  EXPECT_NE(out.find("outside the search range 0..15"), std::string::npos) << out;
}

}  // namespace
}  // namespace augrig
