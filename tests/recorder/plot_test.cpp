// recorder/plot.hpp: the recorded phases as markers, and the markers drawn on every panel of the
// statistics plot where their times say (found in the picture by their colour).
#include "recorder/plot.hpp"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "tests/support/test_support.hpp"

namespace augrig::recorder {
namespace {

constexpr TimestampNs kT0 = 1'000'000'000'000;

TEST(PhaseEvents, OnlyPhaseEventsInTimeOrder) {
  const std::vector<EventRecord> events = {
      {kT0 + 5, ClockDomain::kGps, "phase: contact"},
      {kT0 + 1, ClockDomain::kGps, "phase: approach"},
      {kT0 + 2, ClockDomain::kHostMonotonic, "nav stale from pair 3"},
      {kT0 + 3, ClockDomain::kGps, "phase: "},      // no name: not a phase
      {kT0 + 4, ClockDomain::kGps, "phases: x"},    // another word
      {kT0 + 6, ClockDomain::kGps, "phase: a: b"},  // the name is the rest of the text
  };
  const std::vector<PhaseEvent> p = phase_events(events);
  ASSERT_EQ(p.size(), 3u);
  EXPECT_EQ(p[0].name, "approach");
  EXPECT_EQ(p[0].t_ns, kT0 + 1);
  EXPECT_EQ(p[1].name, "contact");
  EXPECT_EQ(p[2].name, "a: b");
}

TEST(PhaseMarkers, SecondsFromTheFirstFrameAndThePhaseItStartsIn) {
  const std::vector<PhaseEvent> phases = {
      {kT0 - 3'000'000'000, "observation"}, {kT0 - 1'000'000'000, "pre-contact"},
      {kT0 + 2'500'000'000, "contact"},     {kT0 + 9'000'000'000, "disconnect"}};
  // The plot starts in pre-contact (begun before its first frame): a marker at 0; disconnect is
  // past its end.
  std::vector<PhaseMarker> m = phase_markers(phases, kT0, kT0 + 5'000'000'000);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0].name, "pre-contact");
  EXPECT_DOUBLE_EQ(m[0].t_s, 0.0);
  EXPECT_EQ(m[1].name, "contact");
  EXPECT_DOUBLE_EQ(m[1].t_s, 2.5);
  // A phase that begins exactly at the first frame needs no marker for the one before it.
  m = phase_markers({{kT0 - 1, "a"}, {kT0, "b"}}, kT0, kT0 + 10);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].name, "b");
  // Only earlier phases: the plot lies in the last of them.
  m = phase_markers({{kT0 - 2, "a"}, {kT0 - 1, "b"}}, kT0, kT0 + 10);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].name, "b");
  EXPECT_TRUE(phase_markers({}, kT0, kT0 + 10).empty());
  EXPECT_TRUE(phase_markers({{kT0 + 11, "late"}}, kT0, kT0 + 10).empty());
}

// Columns of the picture holding many pixels of the markers' colour (#9467bd), grouped into runs of
// adjacent columns: one group per marker line, its centre column.
std::vector<double> marker_columns(const cv::Mat& bgr) {
  cv::Mat purple;
  cv::inRange(bgr, cv::Scalar(160, 75, 120), cv::Scalar(215, 135, 175), purple);
  std::vector<double> centres;
  int run_start = -1;
  for (int x = 0; x <= purple.cols; ++x) {
    const bool line = x < purple.cols && cv::countNonZero(purple.col(x)) > 250;
    if (line && run_start < 0) run_start = x;
    if (!line && run_start >= 0) {
      centres.push_back(0.5 * (run_start + x - 1));
      run_start = -1;
    }
  }
  return centres;
}

std::vector<OcclusionStats> ramp(int n) {
  std::vector<OcclusionStats> frames;
  for (int i = 0; i < n; ++i) {
    OcclusionStats s;
    s.t_ns = kT0 + static_cast<TimestampNs>(i) * 100'000'000;  // 10 Hz, 0 .. (n-1)/10 s
    s.receiver_px_left = s.receiver_px_right = 1000;
    s.occluded_pct_left = s.occluded_pct_right = 10.0 + i % 7;
    s.boom_overlap_pct_union = 30.0;
    s.receiver_pct_left = s.receiver_pct_right = 2.0;
    s.boom_pct_left = s.boom_pct_right = 4.0;
    s.stereo_both_px = 700, s.left_only_px = 100, s.right_only_px = 100, s.neither_px = 100;
    frames.push_back(s);
  }
  return frames;
}

TEST(StatsPlot, PhaseMarkersAreLinesWhereTheirTimesAre) {
  if (find_gnuplot().empty())
    GTEST_SKIP() << "gnuplot is not installed (Debian: gnuplot-nox); the plot needs it";
  const std::string dir = test::output_dir("plot/phases");
  const std::vector<OcclusionStats> frames = ramp(101);  // 0 .. 10 s
  StatsPlotOptions o;
  o.title = "phases_with_underscores";
  o.phases = {{2.0, "to_contact"}, {4.0, "contact"}, {8.0, "disconnect"}};
  ASSERT_TRUE(plot_occlusion_stats(frames, dir + "/phases.png", o));
  const cv::Mat png = cv::imread(dir + "/phases.png", cv::IMREAD_COLOR);
  ASSERT_FALSE(png.empty());
  const std::vector<double> x = marker_columns(png);
  ASSERT_EQ(x.size(), 3u) << "one dashed line per phase, down all three panels";
  // Evenly scaled time: 2 s between the first two lines, 4 s between the last two.
  EXPECT_NEAR((x[2] - x[1]) / (x[1] - x[0]), 2.0, 0.05);
  // The same plot without phases has none of their colour.
  ASSERT_TRUE(plot_occlusion_stats(frames, dir + "/none.png", {}));
  EXPECT_TRUE(marker_columns(cv::imread(dir + "/none.png", cv::IMREAD_COLOR)).empty());
}

}  // namespace
}  // namespace augrig::recorder
