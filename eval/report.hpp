// What `augrig evaluate` reports: the run's table (the seed paper's Table 1 rows, the receiver and
// its four stereo classes, extended by the matcher's scores on the raw and the augmented pair), a
// CSV row per frame, and plots over the run (gnuplot). docs/EVALUATE.md defines every figure.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "core/expected.hpp"
#include "eval/evaluator.hpp"
#include "render/stats.hpp"

namespace augrig::eval {

// The class names, index = StereoClass (0: every receiver pixel).
inline constexpr const char* kClassNames[5] = {"Receiver (all pixels)", "Stereo: visible to both",
                                               "Stereo: left only", "Stereo: right only", "Stereo: neither"};
// Their short names, for CSV columns: receiver, both, left_only, right_only, neither.
inline constexpr const char* kClassKeys[5] = {"receiver", "both", "left_only", "right_only", "neither"};

// A run's totals: every evaluated frame's scores merged (errors pooled over all their pixels).
struct RunEvaluation {
  PairScore raw, augmented;
  std::uint64_t frames = 0;                // evaluated
  std::uint64_t frames_with_receiver = 0;  // of them, with receiver pixels to score
  std::int64_t out_of_range_px = 0;        // receiver pixels whose true disparity the search misses
  double prepare_ms = 0, match_ms = 0, score_ms = 0;  // summed
  void add(const FrameEvaluation& f);
};

// The table: per class, pixels and for the raw and the augmented pair valid %, mean and RMS error,
// bad > 1 / > 3 px and the range RMS; once over all pixels, once with the boom's left pixels left
// out (an evaluation that trusts the masks). `title` heads it; `matcher` says what matched;
// `boom` says how the augmented pair holds the boom (drawn in, or there in the scene).
std::string format_evaluation_table(const RunEvaluation& run, const std::string& title,
                                    const MatcherParams& matcher,
                                    const std::string& boom = "the boom drawn in");

// One CSV row per evaluated frame: frame, t_s, the occlusion percentages, the matched region, the
// receiver's pixels and those out of the search range, and per pair (raw, aug),
// boom pixels kept or left out (all, noboom) and class: pixels, valid_pct, mean_px, rms_px,
// bad1_pct, bad3_pct, range_rms_m. Empty cells where a figure has no pixels.
class EvaluationCsvWriter {
 public:
  static Expected<std::unique_ptr<EvaluationCsvWriter>> create(const std::filesystem::path& path);
  Status add(std::uint64_t frame, double t_s, const OcclusionStats& stats, const FrameEvaluation& f);
  const std::filesystem::path& path() const { return path_; }
  static std::string header();

 private:
  EvaluationCsvWriter() = default;
  std::filesystem::path path_;
  std::ofstream out_;
};

// The figures plotted over a run, one per evaluated frame.
struct EvaluationPoint {
  double t_s = 0;
  double occluded_pct_left = 0, occluded_pct_right = 0;
  // Over all receiver pixels: raw, augmented, augmented with the boom's pixels left out.
  double bad3_pct[3] = {0, 0, 0};
  double rms_px[3] = {0, 0, 0};
  double valid_pct[3] = {0, 0, 0};
};
EvaluationPoint evaluation_point(double t_s, const OcclusionStats& stats, const FrameEvaluation& f);

// One evaluated frame as evaluation_sums.csv stores it: every sum at full precision (%.17g), so
// that re-adding the frames in order rebuilds the run's RunEvaluation and its plot exactly (a run
// split into parts merges into the whole run's table, bit for bit).
struct EvaluatedFrame {
  std::uint64_t frame = 0;                               // the source's frame index (recording order)
  double t_s = 0;                                        // seconds after the source's first frame
  double occluded_pct_left = 0, occluded_pct_right = 0;  // from the frame's OcclusionStats
  // The raw and augmented PairScore (every DisparityErrors field), receiver_px, out_of_range_px,
  // the matched rectangle and the prepare/match/score times.
  FrameEvaluation evaluation;
};

// evaluation_sums.csv: a header and one row per evaluated frame, flushed per row. Columns: frame,
// t_s, occluded_pct_left, occluded_pct_right, matched_x, matched_y, matched_w, matched_h,
// receiver_px, out_of_range_px, prepare_ms, match_ms, score_ms, and per pair (raw, aug), boom
// pixels kept or left out (all, noboom) and class (kClassKeys): pixels, valid, sum_error_px,
// sum_sq_px2, bad1, bad3, sum_range_error_m, sum_range_sq_m2, range_n. Integers as integers,
// every other number as %.17g (nan, inf and -inf where not finite).
class EvaluationSumsWriter {
 public:
  static Expected<std::unique_ptr<EvaluationSumsWriter>> create(const std::filesystem::path& path);
  Status add(const EvaluatedFrame& f);
  const std::filesystem::path& path() const { return path_; }
  static std::string header();

 private:
  EvaluationSumsWriter() = default;
  std::filesystem::path path_;
  std::ofstream out_;
};

// Reads what EvaluationSumsWriter wrote, rows in file order; every number exactly as it was added.
// Errors name file:line (and the column) and what was expected: a header that is not exactly
// header(), a row with another number of fields, a cell that is not a number of its column's kind.
Expected<std::vector<EvaluatedFrame>> load_evaluation_sums(const std::filesystem::path& path);

// The point evaluation_point(f.t_s, stats, f.evaluation) gives for the frame's OcclusionStats.
EvaluationPoint evaluation_point(const EvaluatedFrame& f);

// Three panels over time: the boom's occlusion (% of the receiver, left and right); bad > 3 px (%)
// and the RMS error for the raw pair, the augmented pair, and the augmented pair without the boom's
// pixels. Errors: no points, gnuplot missing or failing.
Status plot_evaluation(const std::vector<EvaluationPoint>& points, const std::string& png_path,
                       const std::string& title);

}  // namespace augrig::eval
