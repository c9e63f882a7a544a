// eval/report.hpp: a run's totals (RunEvaluation::add), its table, the per-frame CSV and the plot.
// Oracles: every figure is recomputed here by hand from the (true, estimated) disparity lists the
// DisparityErrors were filled from (mean, RMS, > 1 / > 3 px, range RMS of f B / d); the table and
// the CSV are parsed back and compared with those numbers; the plot is read back with OpenCV (its
// size, and the curves' colours present in it).
#include "eval/report.hpp"

#include <bit>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "recorder/plot.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::eval {
namespace {

namespace fs = std::filesystem;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kFB = 600.0;  // f_px * baseline_m for the range errors

// One pixel: its true disparity and what the matcher said (NaN: nothing).
struct Px {
  double truth, estimate;
};

DisparityErrors errors_of(const std::vector<Px>& px) {
  DisparityErrors e;
  for (const Px& p : px) e.add(p.truth, p.estimate, kFB);
  return e;
}

// The figures of a set of pixels, computed here from the lists (not through DisparityErrors).
struct Expected7 {
  std::int64_t pixels = 0;
  double valid_pct = kNaN, mean = kNaN, rms = kNaN, bad1 = kNaN, bad3 = kNaN, range_rms = kNaN;
};
Expected7 by_hand(const std::vector<Px>& px) {
  Expected7 x;
  x.pixels = static_cast<std::int64_t>(px.size());
  int valid = 0, b1 = 0, b3 = 0, rn = 0;
  double s = 0, s2 = 0, r2 = 0;
  for (const Px& p : px) {
    if (std::isnan(p.estimate)) continue;
    ++valid;
    const double e = p.estimate - p.truth;
    s += e, s2 += e * e;
    b1 += std::abs(e) > 1.0;
    b3 += std::abs(e) > 3.0;
    if (p.estimate > 0 && p.truth > 0) {
      const double dz = kFB / p.estimate - kFB / p.truth;
      r2 += dz * dz, ++rn;
    }
  }
  if (!px.empty()) x.valid_pct = 100.0 * valid / static_cast<double>(px.size());
  if (valid) {
    x.mean = s / valid;
    x.rms = std::sqrt(s2 / valid);
    x.bad1 = 100.0 * b1 / valid;
    x.bad3 = 100.0 * b3 / valid;
  }
  if (rn) x.range_rms = std::sqrt(r2 / rn);
  return x;
}

std::vector<Px> concat(std::vector<Px> a, const std::vector<Px>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// Two frames' pixel lists per (pair, set, class): [pair][set][class]. Class 4 (neither) has no
// pixels anywhere; class 3 (right only) has pixels but never a valid match.
using Lists = std::vector<Px>[2][2][5];

void fill_frame_a(Lists& l) {
  // raw, all
  l[0][0][1] = {{10, 10.5}, {10, 12}, {20, kNaN}, {8, 4}};
  l[0][0][2] = {{12, 12.2}, {12, 16}};
  l[0][0][3] = {{9, kNaN}};
  l[0][0][0] = concat(concat(l[0][0][1], l[0][0][2]), l[0][0][3]);
  // raw, boom left out: only class 1's first two pixels remain
  l[0][1][1] = {{10, 10.5}, {10, 12}};
  l[0][1][0] = l[0][1][1];
  // augmented, all
  l[1][0][1] = {{10, 10.1}, {10, 10.2}, {20, 25}, {8, 8}};
  l[1][0][2] = {{12, kNaN}, {12, 11}};
  l[1][0][3] = {{9, kNaN}};
  l[1][0][0] = concat(concat(l[1][0][1], l[1][0][2]), l[1][0][3]);
  l[1][1][1] = {{10, 10.1}, {10, 10.2}};
  l[1][1][0] = l[1][1][1];
}

void fill_frame_b(Lists& l) {
  l[0][0][1] = {{10, 9}, {5, 5.2}};
  l[0][0][2] = {{30, 26.5}};
  l[0][0][0] = concat(l[0][0][1], l[0][0][2]);
  l[0][1][1] = l[0][0][1];
  l[0][1][0] = l[0][1][1];
  l[1][0][1] = {{10, 9.9}, {5, -1}};  // a negative estimate: valid, but no range from it
  l[1][0][2] = {{30, 30}};
  l[1][0][0] = concat(l[1][0][1], l[1][0][2]);
  l[1][1][1] = {{10, 9.9}};
  l[1][1][0] = l[1][1][1];
}

FrameEvaluation frame_of(const Lists& l) {
  FrameEvaluation f;
  for (int pair = 0; pair < 2; ++pair) {
    PairScore& p = pair ? f.augmented : f.raw;
    for (int k = 0; k < 5; ++k) {
      p.all[k] = errors_of(l[pair][0][k]);
      p.boom_excluded[k] = errors_of(l[pair][1][k]);
    }
  }
  f.receiver_px = static_cast<std::int64_t>(l[0][0][0].size());
  return f;
}

struct TwoFrames {
  Lists a, b, merged;
  FrameEvaluation fa, fb;
  RunEvaluation run;
  TwoFrames() {
    fill_frame_a(a);
    fill_frame_b(b);
    for (int p = 0; p < 2; ++p)
      for (int s = 0; s < 2; ++s)
        for (int k = 0; k < 5; ++k) merged[p][s][k] = concat(a[p][s][k], b[p][s][k]);
    fa = frame_of(a);
    fa.out_of_range_px = 3;
    fa.prepare_ms = 1.5, fa.match_ms = 10, fa.score_ms = 0.25;
    fb = frame_of(b);
    fb.out_of_range_px = 4;
    fb.prepare_ms = 2.5, fb.match_ms = 20, fb.score_ms = 0.5;
    run.add(fa);
    run.add(fb);
  }
};

void expect_figures(const DisparityErrors& e, const std::vector<Px>& px, const std::string& what) {
  const Expected7 x = by_hand(px);
  EXPECT_EQ(e.pixels, x.pixels) << what;
  if (x.pixels) {
    EXPECT_NEAR(e.valid_pct(), x.valid_pct, 1e-12) << what;
  }
  auto same = [&](double got, double want, const char* name) {
    if (std::isnan(want))
      EXPECT_TRUE(std::isnan(got)) << what << " " << name << " = " << got;
    else
      EXPECT_NEAR(got, want, 1e-12) << what << " " << name;
  };
  same(e.mean_px(), x.mean, "mean");
  same(e.rms_px(), x.rms, "rms");
  if (!std::isnan(x.bad1)) same(e.bad1_pct(), x.bad1, "bad1");
  if (!std::isnan(x.bad3)) same(e.bad3_pct(), x.bad3, "bad3");
  same(e.range_rms_m(), x.range_rms, "range_rms");
}

TEST(RunEvaluation, AddMergesEveryClassOfBothPairsAndSumsTheCounts) {
  const TwoFrames r;
  EXPECT_EQ(r.run.frames, 2u);
  EXPECT_EQ(r.run.frames_with_receiver, 2u);
  EXPECT_EQ(r.run.out_of_range_px, 7);
  EXPECT_DOUBLE_EQ(r.run.prepare_ms, 4.0);
  EXPECT_DOUBLE_EQ(r.run.match_ms, 30.0);
  EXPECT_DOUBLE_EQ(r.run.score_ms, 0.75);
  for (int p = 0; p < 2; ++p)
    for (int s = 0; s < 2; ++s)
      for (int k = 0; k < 5; ++k) {
        const PairScore& ps = p ? r.run.augmented : r.run.raw;
        const DisparityErrors& e = s ? ps.boom_excluded[k] : ps.all[k];
        expect_figures(e, r.merged[p][s][k],
                       std::string(p ? "augmented" : "raw") + (s ? " noboom " : " all ") + kClassKeys[k]);
      }
  // A spot check of the hand oracle itself: raw, both, over the two frames.
  // errors 0.5, 2, -4, -1, 0.2 (one of six pixels not valid)
  const DisparityErrors& both = r.run.raw.all[1];
  EXPECT_EQ(both.pixels, 6);
  EXPECT_EQ(both.valid, 5);
  EXPECT_NEAR(both.mean_px(), -0.46, 1e-12);
  EXPECT_NEAR(both.rms_px(), std::sqrt(21.29 / 5), 1e-12);
  EXPECT_NEAR(both.bad1_pct(), 40.0, 1e-12);
  EXPECT_NEAR(both.bad3_pct(), 20.0, 1e-12);
}

TEST(RunEvaluation, AFrameWithoutReceiverCountsAsEvaluatedOnly) {
  RunEvaluation run;
  FrameEvaluation empty;  // nothing of the receiver in the left view
  run.add(empty);
  TwoFrames r;
  run.add(r.fa);
  EXPECT_EQ(run.frames, 2u);
  EXPECT_EQ(run.frames_with_receiver, 1u);
  EXPECT_EQ(run.raw.all[0].pixels, r.fa.raw.all[0].pixels);
  EXPECT_EQ(run.out_of_range_px, 3);
}

// The row of class `name` in the section that starts at `from`: pixels, then 6 + 6 cells ("-" as
// NaN).
struct TableRow {
  long long pixels = -1;
  std::vector<double> cells;
};
TableRow row_of(const std::string& table, std::size_t from, const std::string& name) {
  TableRow r;
  std::size_t at = table.find("\n" + std::string(name), from);
  if (at == std::string::npos) return r;
  const std::size_t end = table.find('\n', at + 1);
  std::string line = table.substr(at + 1 + std::string(name).size(), end - at - 1 - std::string(name).size());
  for (char& c : line)
    if (c == '|') c = ' ';
  std::istringstream in(line);
  in >> r.pixels;
  for (std::string tok; in >> tok;) r.cells.push_back(tok == "-" ? kNaN : std::stod(tok));
  return r;
}

void expect_cells(const std::vector<double>& cells, std::size_t first, const Expected7& x,
                  const std::string& what) {
  const double want[6] = {x.valid_pct, x.mean, x.rms, x.bad1, x.bad3, x.range_rms};
  const int decimals[6] = {1, 2, 2, 1, 1, 3};
  for (int i = 0; i < 6; ++i) {
    const double got = cells.at(first + i);
    if (std::isnan(want[i]))
      EXPECT_TRUE(std::isnan(got)) << what << " cell " << i << ": '-' expected, got " << got;
    else
      EXPECT_NEAR(got, want[i], 0.5 * std::pow(10.0, -decimals[i]) + 1e-9) << what << " cell " << i;
  }
}

TEST(FormatEvaluationTable, RowsHoldTheFiguresComputedByHandAndDashesWhereNone) {
  const TwoFrames r;
  MatcherParams m;
  m.min_disparity = 4;
  m.num_disparities = 32;
  m.block_size = 7;
  const std::string t = format_evaluation_table(r.run, "My run title", m);
  EXPECT_EQ(t.rfind("My run title\n", 0), 0u) << t;
  EXPECT_NE(t.find("2 stereo frame(s) evaluated, 2 with the receiver in the left view."), std::string::npos)
      << t;
  EXPECT_NE(t.find("StereoSGBM (mode 3way), disparities 4..35, block 7."), std::string::npos) << t;
  // Pixels out of the search range are warned about, with the range.
  EXPECT_NE(t.find("WARNING: 7 receiver pixel(s) have a true disparity outside the search range 4..35"),
            std::string::npos)
      << t;
  const std::size_t all = t.find("Every receiver pixel:");
  const std::size_t noboom = t.find("The boom's pixels left out");
  ASSERT_NE(all, std::string::npos) << t;
  ASSERT_NE(noboom, std::string::npos) << t;
  ASSERT_LT(all, noboom);
  for (int s = 0; s < 2; ++s)
    for (int k = 0; k < 5; ++k) {
      const std::string what = std::string(s ? "noboom " : "all ") + kClassNames[k];
      const TableRow row = row_of(t, s ? noboom : all, kClassNames[k]);
      ASSERT_EQ(row.cells.size(), 12u) << what << "\n" << t;
      EXPECT_EQ(row.pixels, static_cast<long long>(r.merged[0][s][k].size())) << what;
      expect_cells(row.cells, 0, by_hand(r.merged[0][s][k]), what + " raw");
      expect_cells(row.cells, 6, by_hand(r.merged[1][s][k]), what + " augmented");
    }
  // Right only: pixels but no valid match: valid 0.0 %, the error cells '-'.
  const TableRow ro = row_of(t, all, "Stereo: right only");
  ASSERT_EQ(ro.cells.size(), 12u);
  EXPECT_EQ(ro.cells[0], 0.0);
  for (int i = 1; i < 6; ++i) EXPECT_TRUE(std::isnan(ro.cells[i])) << i;
  // Neither: no pixels at all: every cell '-'.
  const TableRow ne = row_of(t, all, "Stereo: neither");
  EXPECT_EQ(ne.pixels, 0);
  for (double c : ne.cells) EXPECT_TRUE(std::isnan(c));
}

TEST(FormatEvaluationTable, BlockMatcherAndNoWarningWhenEverythingIsInRange) {
  RunEvaluation run;
  FrameEvaluation f;
  f.receiver_px = 1;
  f.raw.all[0] = errors_of({{10, 10}});
  run.add(f);
  MatcherParams m;
  m.algorithm = "bm";
  const std::string t = format_evaluation_table(run, "T", m);
  EXPECT_NE(t.find("Matcher: StereoBM, disparities 0..63, block 5."), std::string::npos) << t;
  EXPECT_EQ(t.find("WARNING"), std::string::npos) << t;
  EXPECT_NE(t.find("1 stereo frame(s) evaluated, 1 with the receiver"), std::string::npos) << t;
}

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  for (char c : line) {
    if (c == ',') {
      out.push_back(cell);
      cell.clear();
    } else {
      cell += c;
    }
  }
  out.push_back(cell);
  return out;
}

std::vector<std::string> lines_of(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  return lines;
}

// A cell as written (7 significant digits) against the value: empty for NaN.
void expect_cell(const std::string& cell, double want, const std::string& what) {
  if (std::isnan(want)) {
    EXPECT_TRUE(cell.empty()) << what << ": empty expected, got '" << cell << "'";
    return;
  }
  ASSERT_FALSE(cell.empty()) << what;
  EXPECT_NEAR(std::stod(cell), want, 5e-7 * std::max(1.0, std::abs(want))) << what << " '" << cell << "'";
}

TEST(EvaluationCsvWriter, HeaderAndRowsAgreeAndValuesRoundTrip) {
  const std::string dir = test::output_dir("eval_report_csv");
  const fs::path path = fs::path(dir) / "evaluation.csv";
  auto w = EvaluationCsvWriter::create(path);
  ASSERT_TRUE(w) << w.error().message;
  EXPECT_EQ((*w)->path(), path);
  TwoFrames r;
  r.fa.matched = cv::Rect(100, 200, 300, 40);
  OcclusionStats sa;
  sa.occluded_pct_left = 12.3456789;
  sa.occluded_pct_right = 0.125;
  OcclusionStats sb;
  sb.occluded_pct_left = 1.0 / 3.0;
  sb.occluded_pct_right = 99.5;
  ASSERT_TRUE((*w)->add(7, 1.25, sa, r.fa));
  ASSERT_TRUE((*w)->add(10, 1.3333333333, sb, r.fb));
  FrameEvaluation none;  // no receiver: every figure but the pixel counts empty
  ASSERT_TRUE((*w)->add(13, 1.5, OcclusionStats{}, none));
  // Flushed per row: the file holds every row while the writer is still open.
  const std::vector<std::string> lines = lines_of(path);
  ASSERT_EQ(lines.size(), 4u) << "a header and one row per frame";
  const std::vector<std::string> head = split_csv(lines[0]);
  EXPECT_EQ(lines[0], EvaluationCsvWriter::header());
  EXPECT_EQ(head.size(), 10u + 2 * 2 * 5 * 7);
  std::map<std::string, std::size_t> col;
  for (std::size_t i = 0; i < head.size(); ++i) {
    EXPECT_TRUE(col.emplace(head[i], i).second) << "column named twice: " << head[i];
  }
  for (std::size_t i = 1; i < lines.size(); ++i)
    EXPECT_EQ(split_csv(lines[i]).size(), head.size()) << "row " << i << ": " << lines[i];

  const std::vector<std::string> a = split_csv(lines[1]), b = split_csv(lines[2]), n = split_csv(lines[3]);
  EXPECT_EQ(a[col.at("frame")], "7");
  EXPECT_EQ(b[col.at("frame")], "10");
  EXPECT_EQ(n[col.at("frame")], "13");
  expect_cell(a[col.at("t_s")], 1.25, "t_s");
  expect_cell(b[col.at("t_s")], 1.3333333333, "t_s");
  expect_cell(a[col.at("occluded_pct_left")], 12.3456789, "occluded_pct_left");
  expect_cell(a[col.at("occluded_pct_right")], 0.125, "occluded_pct_right");
  expect_cell(b[col.at("occluded_pct_left")], 1.0 / 3.0, "occluded_pct_left");
  EXPECT_EQ(a[col.at("matched_x")], "100");
  EXPECT_EQ(a[col.at("matched_y")], "200");
  EXPECT_EQ(a[col.at("matched_w")], "300");
  EXPECT_EQ(a[col.at("matched_h")], "40");
  EXPECT_EQ(a[col.at("receiver_px")], std::to_string(r.fa.receiver_px));
  EXPECT_EQ(a[col.at("out_of_range_px")], "3");
  EXPECT_EQ(b[col.at("out_of_range_px")], "4");

  const Lists* lists[2] = {&r.a, &r.b};
  const std::vector<std::string>* rows[2] = {&a, &b};
  for (int fr = 0; fr < 2; ++fr)
    for (int p = 0; p < 2; ++p)
      for (int s = 0; s < 2; ++s)
        for (int k = 0; k < 5; ++k) {
          const std::string prefix =
              std::string(p ? "aug_" : "raw_") + (s ? "noboom_" : "all_") + kClassKeys[k] + "_";
          const Expected7 x = by_hand((*lists[fr])[p][s][k]);
          const std::vector<std::string>& row = *rows[fr];
          const std::string what = "frame " + std::to_string(fr) + " " + prefix;
          EXPECT_EQ(row[col.at(prefix + "pixels")], std::to_string(x.pixels)) << what;
          expect_cell(row[col.at(prefix + "valid_pct")], x.valid_pct, what + "valid_pct");
          expect_cell(row[col.at(prefix + "mean_px")], x.mean, what + "mean_px");
          expect_cell(row[col.at(prefix + "rms_px")], x.rms, what + "rms_px");
          expect_cell(row[col.at(prefix + "bad1_pct")], x.bad1, what + "bad1_pct");
          expect_cell(row[col.at(prefix + "bad3_pct")], x.bad3, what + "bad3_pct");
          expect_cell(row[col.at(prefix + "range_rms_m")], x.range_rms, what + "range_rms_m");
        }
  // The empty frame: pixel counts 0, every figure an empty cell.
  for (std::size_t i = col.at("raw_all_receiver_pixels"); i < head.size(); ++i) {
    if (head[i].ends_with("_pixels"))
      EXPECT_EQ(n[i], "0") << head[i];
    else
      EXPECT_TRUE(n[i].empty()) << head[i] << " = '" << n[i] << "'";
  }
}

TEST(EvaluationCsvWriter, AFileThatCannotBeWrittenFailsNamingIt) {
  const std::string dir = test::output_dir("eval_report_csv_bad");
  const std::string missing = dir + "/no/such/folder/evaluation.csv";
  auto w = EvaluationCsvWriter::create(missing);
  ASSERT_FALSE(w);
  EXPECT_NE(w.error().message.find(missing), std::string::npos) << w.error().message;
  // A folder where the file should be.
  auto d = EvaluationCsvWriter::create(dir);
  ASSERT_FALSE(d);
  EXPECT_NE(d.error().message.find(dir), std::string::npos) << d.error().message;
}

TEST(EvaluationPoint, OverAllReceiverPixelsOfRawAugmentedAndAugmentedWithoutTheBoom) {
  const TwoFrames r;
  OcclusionStats s;
  s.occluded_pct_left = 11, s.occluded_pct_right = 22;
  const EvaluationPoint p = evaluation_point(3.5, s, r.fa);
  EXPECT_EQ(p.t_s, 3.5);
  EXPECT_EQ(p.occluded_pct_left, 11);
  EXPECT_EQ(p.occluded_pct_right, 22);
  const std::vector<Px>* sets[3] = {&r.a[0][0][0], &r.a[1][0][0], &r.a[1][1][0]};
  for (int i = 0; i < 3; ++i) {
    const Expected7 x = by_hand(*sets[i]);
    EXPECT_NEAR(p.bad3_pct[i], x.bad3, 1e-12) << i;
    EXPECT_NEAR(p.rms_px[i], x.rms, 1e-12) << i;
    EXPECT_NEAR(p.valid_pct[i], x.valid_pct, 1e-12) << i;
  }
  // No pixels: NaN, not 0 (a gap in the plot, not a perfect score).
  const EvaluationPoint e = evaluation_point(0, s, FrameEvaluation{});
  for (int i = 0; i < 3; ++i) {
    EXPECT_TRUE(std::isnan(e.bad3_pct[i])) << i;
    EXPECT_TRUE(std::isnan(e.rms_px[i])) << i;
    EXPECT_TRUE(std::isnan(e.valid_pct[i])) << i;
  }
}

// ---------------------------------------------------------------------------------------------
// evaluation_sums.csv: the exact per-frame record a split run is merged from.

bool same_bits(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

// Every field of two frames equal, doubles bit for bit; `what` says which frame.
void expect_same_frame(const EvaluatedFrame& a, const EvaluatedFrame& b, const std::string& what) {
  EXPECT_EQ(a.frame, b.frame) << what;
  EXPECT_TRUE(same_bits(a.t_s, b.t_s)) << what << " t_s " << a.t_s << " vs " << b.t_s;
  EXPECT_TRUE(same_bits(a.occluded_pct_left, b.occluded_pct_left)) << what;
  EXPECT_TRUE(same_bits(a.occluded_pct_right, b.occluded_pct_right)) << what;
  const FrameEvaluation &x = a.evaluation, &y = b.evaluation;
  EXPECT_EQ(x.matched, y.matched) << what;
  EXPECT_EQ(x.receiver_px, y.receiver_px) << what;
  EXPECT_EQ(x.out_of_range_px, y.out_of_range_px) << what;
  EXPECT_TRUE(same_bits(x.prepare_ms, y.prepare_ms)) << what;
  EXPECT_TRUE(same_bits(x.match_ms, y.match_ms)) << what;
  EXPECT_TRUE(same_bits(x.score_ms, y.score_ms)) << what;
  for (int p = 0; p < 2; ++p)
    for (int s = 0; s < 2; ++s)
      for (int k = 0; k < 5; ++k) {
        const PairScore &px = p ? x.augmented : x.raw, &py = p ? y.augmented : y.raw;
        const DisparityErrors& e = (s ? px.boom_excluded : px.all)[k];
        const DisparityErrors& f = (s ? py.boom_excluded : py.all)[k];
        const std::string w = what + " pair " + std::to_string(p) + " set " + std::to_string(s) + " class " +
                              std::to_string(k);
        EXPECT_EQ(e.pixels, f.pixels) << w;
        EXPECT_EQ(e.valid, f.valid) << w;
        EXPECT_EQ(e.bad1, f.bad1) << w;
        EXPECT_EQ(e.bad3, f.bad3) << w;
        EXPECT_EQ(e.range_n, f.range_n) << w;
        EXPECT_TRUE(same_bits(e.sum_error_px, f.sum_error_px)) << w << " " << e.sum_error_px;
        EXPECT_TRUE(same_bits(e.sum_sq_px2, f.sum_sq_px2)) << w << " " << e.sum_sq_px2;
        EXPECT_TRUE(same_bits(e.sum_range_error_m, f.sum_range_error_m)) << w << " " << e.sum_range_error_m;
        EXPECT_TRUE(same_bits(e.sum_range_sq_m2, f.sum_range_sq_m2)) << w << " " << e.sum_range_sq_m2;
      }
}

// Frames whose doubles 7 or 15 significant digits would not bring back: thirds, tenths summed,
// the neighbours of 1, a subnormal, -0, huge and tiny magnitudes; counts that need 64 bits.
std::vector<EvaluatedFrame> awkward_frames() {
  const TwoFrames r;
  std::vector<EvaluatedFrame> v(3);
  v[0].frame = 7;
  v[0].t_s = 1.0 / 3.0;
  v[0].occluded_pct_left = 0.1 + 0.2;
  v[0].occluded_pct_right = std::nextafter(100.0, 0.0);
  v[0].evaluation = r.fa;
  v[0].evaluation.matched = cv::Rect(-3, 200, 300, 40);
  v[0].evaluation.prepare_ms = std::nextafter(1.0, 2.0);
  v[0].evaluation.match_ms = 1e300;
  v[0].evaluation.score_ms = std::numeric_limits<double>::denorm_min();
  v[0].evaluation.raw.all[1].sum_error_px += 1e-17;  // still 1 ulp-ish away from a short decimal
  v[0].evaluation.raw.all[2].sum_sq_px2 = 2.0 / 3.0 * 1e-5;
  v[1].frame = std::numeric_limits<std::uint64_t>::max();
  v[1].t_s = -0.0;
  v[1].occluded_pct_left = std::numeric_limits<double>::quiet_NaN();  // not finite: kept as such
  v[1].occluded_pct_right = -std::numeric_limits<double>::infinity();
  v[1].evaluation = r.fb;
  v[1].evaluation.receiver_px = std::numeric_limits<std::int64_t>::max();
  v[1].evaluation.out_of_range_px = std::numeric_limits<std::int64_t>::min();
  v[1].evaluation.augmented.boom_excluded[4].sum_range_error_m = -123456.78901234567;
  v[2].frame = 0;  // an empty frame: no receiver, every sum 0
  return v;
}

TEST(EvaluationSums, EveryFieldReadsBackBitForBit) {
  const std::string dir = test::output_dir("eval_report_sums");
  const fs::path path = fs::path(dir) / "evaluation_sums.csv";
  const std::vector<EvaluatedFrame> frames = awkward_frames();
  {
    auto w = EvaluationSumsWriter::create(path);
    ASSERT_TRUE(w) << w.error().message;
    EXPECT_EQ((*w)->path(), path);
    for (const EvaluatedFrame& f : frames) ASSERT_TRUE((*w)->add(f));
    // Flushed per row: all there while the writer is open.
    EXPECT_EQ(lines_of(path).size(), 1 + frames.size());
  }
  const std::vector<std::string> lines = lines_of(path);
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[0], EvaluationSumsWriter::header());
  const std::vector<std::string> head = split_csv(lines[0]);
  EXPECT_EQ(head.size(), 13u + 2 * 2 * 5 * 9);
  std::map<std::string, int> seen;
  for (const std::string& h : head) EXPECT_EQ(++seen[h], 1) << "column named twice: " << h;
  for (const char* c : {"frame", "t_s", "receiver_px", "score_ms", "raw_all_receiver_sum_error_px",
                        "aug_noboom_neither_range_n", "raw_noboom_left_only_sum_range_sq_m2"})
    EXPECT_EQ(seen.count(c), 1u) << c;
  EXPECT_EQ(head.front(), "frame");

  auto back = load_evaluation_sums(path);
  ASSERT_TRUE(back) << back.error().message;
  ASSERT_EQ(back->size(), frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) expect_same_frame((*back)[i], frames[i], "frame " + std::to_string(i));
  // Read back and written again: the same text.
  const fs::path again = fs::path(dir) / "again.csv";
  {
    auto w = EvaluationSumsWriter::create(again);
    ASSERT_TRUE(w) << w.error().message;
    for (const EvaluatedFrame& f : *back) ASSERT_TRUE((*w)->add(f));
  }
  EXPECT_EQ(lines_of(again), lines);
}

TEST(EvaluationSums, FramesReAddedInOrderRebuildTheRunsTableAndPlotPoints) {
  const std::string dir = test::output_dir("eval_report_sums_merge");
  // A run split in two files, as two shards of a campaign would write it.
  std::vector<EvaluatedFrame> frames = awkward_frames();
  frames[1].occluded_pct_left = 12.5;  // the plot's points compared below: finite
  frames[1].occluded_pct_right = 0.1 * 3;
  frames[1].evaluation.receiver_px = 123456789012345;
  frames[1].evaluation.out_of_range_px = 98765;
  RunEvaluation whole;
  std::vector<EvaluationPoint> points;
  for (const EvaluatedFrame& f : frames) {
    whole.add(f.evaluation);
    OcclusionStats st;
    st.occluded_pct_left = f.occluded_pct_left;
    st.occluded_pct_right = f.occluded_pct_right;
    points.push_back(evaluation_point(f.t_s, st, f.evaluation));
  }
  for (int part = 0; part < 2; ++part) {
    auto w = EvaluationSumsWriter::create(fs::path(dir) / ("part" + std::to_string(part) + ".csv"));
    ASSERT_TRUE(w) << w.error().message;
    for (std::size_t i = part ? 1 : 0; i < (part ? frames.size() : 1); ++i) ASSERT_TRUE((*w)->add(frames[i]));
  }
  RunEvaluation merged;
  std::vector<EvaluationPoint> merged_points;
  for (int part = 0; part < 2; ++part) {
    auto f = load_evaluation_sums(fs::path(dir) / ("part" + std::to_string(part) + ".csv"));
    ASSERT_TRUE(f) << f.error().message;
    for (const EvaluatedFrame& e : *f) {
      merged.add(e.evaluation);
      merged_points.push_back(evaluation_point(e));
    }
  }
  MatcherParams m;
  EXPECT_EQ(format_evaluation_table(merged, "T", m), format_evaluation_table(whole, "T", m));
  EXPECT_EQ(merged.frames, 3u);
  EXPECT_EQ(merged.frames_with_receiver, whole.frames_with_receiver);
  EXPECT_EQ(merged.out_of_range_px, whole.out_of_range_px);
  EXPECT_TRUE(same_bits(merged.prepare_ms, whole.prepare_ms));
  EXPECT_TRUE(same_bits(merged.match_ms, whole.match_ms));
  EXPECT_TRUE(same_bits(merged.score_ms, whole.score_ms));
  EvaluatedFrame wf, mf;
  wf.evaluation.raw = whole.raw, wf.evaluation.augmented = whole.augmented;
  mf.evaluation.raw = merged.raw, mf.evaluation.augmented = merged.augmented;
  expect_same_frame(mf, wf, "the run's sums");
  ASSERT_EQ(merged_points.size(), points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const EvaluationPoint &a = merged_points[i], &b = points[i];
    EXPECT_TRUE(same_bits(a.t_s, b.t_s)) << i;
    EXPECT_TRUE(same_bits(a.occluded_pct_left, b.occluded_pct_left)) << i;
    EXPECT_TRUE(same_bits(a.occluded_pct_right, b.occluded_pct_right)) << i;
    for (int j = 0; j < 3; ++j) {
      EXPECT_TRUE(same_bits(a.bad3_pct[j], b.bad3_pct[j]) || (std::isnan(a.bad3_pct[j]) && std::isnan(b.bad3_pct[j])))
          << i << " " << j;
      EXPECT_TRUE(same_bits(a.rms_px[j], b.rms_px[j]) || (std::isnan(a.rms_px[j]) && std::isnan(b.rms_px[j])))
          << i << " " << j;
      EXPECT_TRUE(same_bits(a.valid_pct[j], b.valid_pct[j]) ||
                  (std::isnan(a.valid_pct[j]) && std::isnan(b.valid_pct[j])))
          << i << " " << j;
    }
  }
}

TEST(EvaluationSums, ABadFileIsAnErrorNamingFileLineAndColumn) {
  const std::string dir = test::output_dir("eval_report_sums_bad");
  const fs::path good = fs::path(dir) / "good.csv";
  {
    auto w = EvaluationSumsWriter::create(good);
    ASSERT_TRUE(w) << w.error().message;
    for (const EvaluatedFrame& f : awkward_frames()) ASSERT_TRUE((*w)->add(f));
  }
  const std::vector<std::string> lines = lines_of(good);
  // `lines` with line `n` (0: the header) replaced, written as `name`; the load's error message.
  auto error_of = [&](const std::string& name, std::size_t n, const std::string& text) {
    const fs::path p = fs::path(dir) / name;
    std::ofstream o(p, std::ios::binary);
    for (std::size_t i = 0; i < lines.size(); ++i) o << (i == n ? text : lines[i]) << '\n';
    o.close();
    auto r = load_evaluation_sums(p);
    EXPECT_FALSE(r) << name;
    return r ? std::string() : r.error().message;
  };
  std::vector<std::string> cells = split_csv(lines[2]);
  auto joined = [](const std::vector<std::string>& c) {
    std::string s;
    for (const std::string& x : c) s += (s.empty() ? "" : ",") + x;
    return s;
  };

  // A header with one column renamed (evaluation.csv's, say): line 1, the column and what was expected.
  std::string m = error_of("header.csv", 0, EvaluationCsvWriter::header());
  EXPECT_NE(m.find((fs::path(dir) / "header.csv").string() + ":1:"), std::string::npos) << m;
  EXPECT_NE(m.find("expected 'prepare_ms'"), std::string::npos) << m;
  // A row with a field missing.
  std::vector<std::string> c = cells;
  c.pop_back();
  m = error_of("short.csv", 2, joined(c));
  EXPECT_NE(m.find("short.csv:3:"), std::string::npos) << m;
  EXPECT_NE(m.find(std::to_string(cells.size() - 1) + " fields, expected " + std::to_string(cells.size())),
            std::string::npos)
      << m;
  // Not a number where a sum goes.
  c = cells;
  c[split_csv(lines[0]).size() - 2] = "1.5x";
  m = error_of("number.csv", 2, joined(c));
  EXPECT_NE(m.find("number.csv:3:aug_noboom_neither_sum_range_sq_m2: expected a number, got '1.5x'"),
            std::string::npos)
      << m;
  // A fraction where a count goes; a negative frame index.
  c = cells;
  c[8] = "12.5";
  m = error_of("count.csv", 2, joined(c));
  EXPECT_NE(m.find("count.csv:3:receiver_px: expected an integer, got '12.5'"), std::string::npos) << m;
  c = cells;
  c[0] = "-1";
  m = error_of("frame.csv", 1, joined(c));
  EXPECT_NE(m.find("frame.csv:2:frame: expected an integer >= 0, got '-1'"), std::string::npos) << m;
  // An empty cell.
  c = cells;
  c[1] = "";
  m = error_of("empty_cell.csv", 3, joined(c));
  EXPECT_NE(m.find("empty_cell.csv:4:t_s: expected a number, got ''"), std::string::npos) << m;
  // An empty file, and none at all.
  { std::ofstream(fs::path(dir) / "empty.csv"); }
  auto e = load_evaluation_sums(fs::path(dir) / "empty.csv");
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find("empty.csv: empty"), std::string::npos) << e.error().message;
  auto n = load_evaluation_sums(fs::path(dir) / "none.csv");
  ASSERT_FALSE(n);
  EXPECT_NE(n.error().message.find("none.csv: cannot read"), std::string::npos) << n.error().message;
  // A file that cannot be written.
  auto w = EvaluationSumsWriter::create(fs::path(dir) / "no/such/folder/x.csv");
  ASSERT_FALSE(w);
  EXPECT_NE(w.error().message.find("no/such/folder/x.csv"), std::string::npos) << w.error().message;
}

// Pixels within `tol` of an RGB colour in the plots' area (left of the keys, which hold each
// colour too, and fewer of it).
int colour_pixels(const cv::Mat& bgr, int r, int g, int b, int tol = 12) {
  cv::Mat m;
  cv::inRange(bgr(cv::Rect(0, 0, 900, bgr.rows)), cv::Scalar(b - tol, g - tol, r - tol),
              cv::Scalar(b + tol, g + tol, r + tol), m);
  return cv::countNonZero(m);
}

TEST(PlotEvaluation, APngOfTheStatedSizeWithEveryCurvesColour) {
  if (recorder::find_gnuplot().empty())
    GTEST_SKIP() << "gnuplot is not installed (Debian: gnuplot-nox); plot_evaluation needs it";
  const std::string dir = test::output_dir("eval_report_plot");
  std::vector<EvaluationPoint> pts;
  for (int i = 0; i < 40; ++i) {
    EvaluationPoint p;
    p.t_s = 100.0 + 0.1 * i;
    p.occluded_pct_left = 10 + 5 * std::sin(0.2 * i);
    p.occluded_pct_right = 12 + 5 * std::cos(0.2 * i);
    for (int k = 0; k < 3; ++k) {
      p.bad3_pct[k] = 5 + 10 * k + (i % 5);
      p.rms_px[k] = 0.5 + k + 0.05 * i;
      p.valid_pct[k] = 90;
    }
    if (i == 7) p.rms_px[1] = kNaN;  // a gap, not an error
    pts.push_back(p);
  }
  const std::string png = dir + "/sub/evaluation.png";
  const Status s = plot_evaluation(pts, png, "evaluation_title");
  ASSERT_TRUE(s) << s.error().message;
  const cv::Mat img = cv::imread(png, cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty()) << png;
  EXPECT_EQ(img.cols, 1200);
  EXPECT_EQ(img.rows, 1000);
  // The curves: occlusion left #1f77b4, right #d62728; raw #2ca02c, augmented #d62728, augmented
  // without the boom #9467bd.
  // Each curve runs ~800 px across its panel, 2 px wide.
  EXPECT_GT(colour_pixels(img, 0x1f, 0x77, 0xb4), 700) << "occlusion left";
  EXPECT_GT(colour_pixels(img, 0xd6, 0x27, 0x28), 2000) << "occlusion right, augmented pair (2 panels)";
  EXPECT_GT(colour_pixels(img, 0x2c, 0xa0, 0x2c), 1500) << "raw pair (2 panels)";
  EXPECT_GT(colour_pixels(img, 0x94, 0x67, 0xbd), 1500) << "augmented, boom left out (2 panels)";
  // A single point is plotted too (as a marker).
  const std::string one = dir + "/one.png";
  ASSERT_TRUE(plot_evaluation({pts[0]}, one, "one"));
  EXPECT_FALSE(cv::imread(one, cv::IMREAD_COLOR).empty());
}

TEST(PlotEvaluation, NoPointsIsAnErrorNamingTheFile) {
  const std::string png = test::output_dir("eval_report_plot_empty") + "/empty.png";
  const Status s = plot_evaluation({}, png, "t");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find(png), std::string::npos) << s.error().message;
  EXPECT_NE(s.error().message.find("no evaluated frames"), std::string::npos) << s.error().message;
  EXPECT_FALSE(fs::exists(png));
}

TEST(PlotEvaluation, GnuplotMissingIsAnError) {
  const std::string dir = test::output_dir("eval_report_plot_nognuplot");
  const char* old = std::getenv("AUGRIG_GNUPLOT");
  const std::string saved = old ? old : "";
  ::setenv("AUGRIG_GNUPLOT", (dir + "/not_gnuplot").c_str(), 1);  // no such executable
  EvaluationPoint p;
  const Status s = plot_evaluation({p}, dir + "/x.png", "t");
  if (old)
    ::setenv("AUGRIG_GNUPLOT", saved.c_str(), 1);
  else
    ::unsetenv("AUGRIG_GNUPLOT");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("gnuplot"), std::string::npos) << s.error().message;
  EXPECT_NE(s.error().message.find(dir + "/x.png"), std::string::npos) << s.error().message;
  EXPECT_FALSE(fs::exists(dir + "/x.png"));
}

}  // namespace
}  // namespace augrig::eval
