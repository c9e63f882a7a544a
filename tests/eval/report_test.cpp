// eval/report.hpp: a run's totals (RunEvaluation::add), its table, the per-frame CSV and the plot.
// Oracles: every figure is recomputed here by hand from the (true, estimated) disparity lists the
// DisparityErrors were filled from (mean, RMS, > 1 / > 3 px, range RMS of f B / d); the table and
// the CSV are parsed back and compared with those numbers; the plot is read back with OpenCV (its
// size, and the curves' colours present in it).
#include "eval/report.hpp"

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
