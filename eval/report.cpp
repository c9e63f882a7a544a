#include "eval/report.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <sstream>
#include <string_view>
#include <system_error>
#include <type_traits>

#include "core/csv.hpp"
#include "recorder/plot.hpp"

namespace augrig::eval {
namespace {

constexpr const char* kFigureKeys[7] = {"pixels",   "valid_pct", "mean_px",    "rms_px",
                                        "bad1_pct", "bad3_pct",  "range_rms_m"};

void append(std::string& s, double v) {
  if (!std::isfinite(v)) return;  // an empty cell
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 7);
  s.append(buf, r.ptr);
}

// The seven figures of one set of pixels, comma first; empty where they have no pixels.
void append_figures(std::string& s, const DisparityErrors& e) {
  s += ',' + std::to_string(e.pixels);
  const bool any = e.pixels > 0, valid = e.valid > 0;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (double v : {any ? e.valid_pct() : nan, e.mean_px(), e.rms_px(), valid ? e.bad1_pct() : nan,
                   valid ? e.bad3_pct() : nan, e.range_rms_m()}) {
    s += ',';
    append(s, v);
  }
}

// "  12.34" or "      -" (no pixels to say it of).
std::string cell(double v, int width, int decimals) {
  char buf[48];
  if (!std::isfinite(v))
    std::snprintf(buf, sizeof buf, "%*s", width, "-");
  else
    std::snprintf(buf, sizeof buf, "%*.*f", width, decimals, v);
  return buf;
}

std::string pair_cells(const DisparityErrors& e) {
  const bool valid = e.valid > 0;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  return cell(e.pixels ? e.valid_pct() : nan, 7, 1) + cell(e.mean_px(), 8, 2) + cell(e.rms_px(), 8, 2) +
         cell(valid ? e.bad1_pct() : nan, 7, 1) + cell(valid ? e.bad3_pct() : nan, 7, 1) +
         cell(e.range_rms_m(), 9, 3);
}

// Every field of an EvaluatedFrame with its evaluation_sums.csv column name, in column order:
// the one list the header, the writer and the reader share. `visit(name, field)` is called with
// std::uint64_t&, std::int64_t&, int& or double& fields (const versions for a const frame).
template <typename Frame, typename Visit>
void for_each_sum_field(Frame& f, Visit&& visit) {
  visit("frame", f.frame);
  visit("t_s", f.t_s);
  visit("occluded_pct_left", f.occluded_pct_left);
  visit("occluded_pct_right", f.occluded_pct_right);
  auto& e = f.evaluation;
  visit("matched_x", e.matched.x);
  visit("matched_y", e.matched.y);
  visit("matched_w", e.matched.width);
  visit("matched_h", e.matched.height);
  visit("receiver_px", e.receiver_px);
  visit("out_of_range_px", e.out_of_range_px);
  visit("prepare_ms", e.prepare_ms);
  visit("match_ms", e.match_ms);
  visit("score_ms", e.score_ms);
  std::string name;
  for (int pair = 0; pair < 2; ++pair)
    for (int set = 0; set < 2; ++set)
      for (int k = 0; k < 5; ++k) {
        auto& score = pair ? e.augmented : e.raw;
        auto& d = (set ? score.boom_excluded : score.all)[static_cast<std::size_t>(k)];
        const std::string prefix =
            std::string(pair ? "aug_" : "raw_") + (set ? "noboom_" : "all_") + kClassKeys[k] + "_";
        visit((prefix + "pixels").c_str(), d.pixels);
        visit((prefix + "valid").c_str(), d.valid);
        visit((prefix + "sum_error_px").c_str(), d.sum_error_px);
        visit((prefix + "sum_sq_px2").c_str(), d.sum_sq_px2);
        visit((prefix + "bad1").c_str(), d.bad1);
        visit((prefix + "bad3").c_str(), d.bad3);
        visit((prefix + "sum_range_error_m").c_str(), d.sum_range_error_m);
        visit((prefix + "sum_range_sq_m2").c_str(), d.sum_range_sq_m2);
        visit((prefix + "range_n").c_str(), d.range_n);
      }
}

// A sum as evaluation_sums.csv writes it: %.17g reads back to the same double (glibc's printf and
// from_chars are exact); non-finite values as from_chars reads them.
void append_exact(std::string& s, double v) {
  if (std::isnan(v)) {
    s += "nan";
  } else if (std::isinf(v)) {
    s += v > 0 ? "inf" : "-inf";
  } else {
    char buf[40];
    const int n = std::snprintf(buf, sizeof buf, "%.17g", v);
    s.append(buf, static_cast<std::size_t>(n));
  }
}

// One cell of evaluation_sums.csv into its field; false when it is not a whole number of the
// field's kind.
template <typename T>
bool parse_cell(std::string_view cell, T& out) {
  if (cell.empty()) return false;
  const char* b = cell.data();
  const char* e = b + cell.size();
  if constexpr (std::is_same_v<T, double>) {
    if (*b == '+') return false;  // from_chars takes no '+', and the writer writes none
  }
  const auto r = std::from_chars(b, e, out);
  return r.ec == std::errc() && r.ptr == e;
}

}  // namespace

void RunEvaluation::add(const FrameEvaluation& f) {
  raw.merge(f.raw);
  augmented.merge(f.augmented);
  ++frames;
  frames_with_receiver += f.receiver_px > 0;
  out_of_range_px += f.out_of_range_px;
  prepare_ms += f.prepare_ms;
  match_ms += f.match_ms;
  score_ms += f.score_ms;
}

std::string format_evaluation_table(const RunEvaluation& run, const std::string& title,
                                    const MatcherParams& m, const std::string& boom) {
  std::ostringstream o;
  o << title << '\n';
  o << run.frames << " stereo frame(s) evaluated, " << run.frames_with_receiver
    << " with the receiver in the left view. "
    << "Matcher: " << (m.algorithm == "bm" ? "StereoBM" : "StereoSGBM (mode " + m.mode + ")")
    << ", disparities " << m.min_disparity << ".." << m.min_disparity + m.num_disparities - 1 << ", block "
    << m.block_size << ".\n";
  if (run.out_of_range_px)
    o << "WARNING: " << run.out_of_range_px
      << " receiver pixel(s) have a true disparity outside the search range " << m.min_disparity << ".."
      << m.min_disparity + m.num_disparities - 1
      << ": the matcher cannot find them; widen num_disparities (or min_disparity) in the matcher file.\n";
  o << "Pixels: rectified left pixels of the receiver (with a true disparity), summed over the frames. "
       "Valid: the\n"
       "matcher gave a disparity. Errors (estimated - true disparity, px) over the valid pixels; range error "
       "of\n"
       "f B / d in metres. '-': no pixels to say it of.\n";
  char line[256];
  std::snprintf(line, sizeof line, "%-24s %10s | %-46s | %-46s\n", "", "", "Raw pair",
                ("Augmented pair (" + boom + ")").c_str());
  const std::string head = std::string(line);
  std::snprintf(line, sizeof line, "%-24s %10s |%7s%8s%8s%7s%7s%9s |%7s%8s%8s%7s%7s%9s\n", "", "Pixels",
                "valid%", "mean", "RMS", ">1px%", ">3px%", "rangeRMS", "valid%", "mean", "RMS", ">1px%",
                ">3px%", "rangeRMS");
  const std::string cols = std::string(line);
  for (int pass = 0; pass < 2; ++pass) {
    const auto& raw = pass ? run.raw.boom_excluded : run.raw.all;
    const auto& aug = pass ? run.augmented.boom_excluded : run.augmented.all;
    o << '\n'
      << (pass ? "The boom's pixels left out (the left mask's boom bit; an evaluation trusting augrig's "
                 "masks):\n"
               : "Every receiver pixel:\n")
      << head << cols;
    for (int k = 0; k < 5; ++k) {
      std::snprintf(line, sizeof line, "%-24s %10lld |", kClassNames[k],
                    static_cast<long long>(raw[k].pixels));
      o << line << pair_cells(raw[k]) << " |" << pair_cells(aug[k]) << '\n';
    }
  }
  return o.str();
}

Expected<std::unique_ptr<EvaluationCsvWriter>> EvaluationCsvWriter::create(
    const std::filesystem::path& path) {
  std::unique_ptr<EvaluationCsvWriter> w(new EvaluationCsvWriter);
  w->path_ = path;
  w->out_.open(path, std::ios::binary);
  if (!w->out_) return make_error(path.string(), ": cannot write the evaluation file");
  w->out_ << header() << '\n';
  w->out_.flush();
  if (!w->out_) return make_error(path.string(), ": write failed");
  return w;
}

std::string EvaluationCsvWriter::header() {
  std::string h =
      "frame,t_s,occluded_pct_left,occluded_pct_right,matched_x,matched_y,matched_w,matched_h,receiver_px,"
      "out_of_range_px";
  for (const char* pair : {"raw", "aug"})
    for (const char* set : {"all", "noboom"})
      for (const char* k : kClassKeys)
        for (const char* f : kFigureKeys) h += std::string(",") + pair + "_" + set + "_" + k + "_" + f;
  return h;
}

Status EvaluationCsvWriter::add(std::uint64_t frame, double t_s, const OcclusionStats& stats,
                                const FrameEvaluation& f) {
  std::string s = std::to_string(frame) + ',';
  append(s, t_s);
  s += ',';
  append(s, stats.occluded_pct_left);
  s += ',';
  append(s, stats.occluded_pct_right);
  s += ',' + std::to_string(f.matched.x) + ',' + std::to_string(f.matched.y) + ',' +
       std::to_string(f.matched.width) + ',' + std::to_string(f.matched.height) + ',' +
       std::to_string(f.receiver_px) + ',' + std::to_string(f.out_of_range_px);
  for (const PairScore* p : {&f.raw, &f.augmented})
    for (const auto* set : {&p->all, &p->boom_excluded})
      for (const DisparityErrors& e : *set) append_figures(s, e);
  out_ << s << '\n';
  out_.flush();
  if (!out_) return make_error(path_.string(), ": write failed");
  return {};
}

EvaluationPoint evaluation_point(double t_s, const OcclusionStats& stats, const FrameEvaluation& f) {
  EvaluationPoint p;
  p.t_s = t_s;
  p.occluded_pct_left = stats.occluded_pct_left;
  p.occluded_pct_right = stats.occluded_pct_right;
  const DisparityErrors* e[3] = {&f.raw.all[0], &f.augmented.all[0], &f.augmented.boom_excluded[0]};
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int i = 0; i < 3; ++i) {
    p.bad3_pct[i] = e[i]->valid ? e[i]->bad3_pct() : nan;
    p.rms_px[i] = e[i]->rms_px();
    p.valid_pct[i] = e[i]->pixels ? e[i]->valid_pct() : nan;
  }
  return p;
}

Expected<std::unique_ptr<EvaluationSumsWriter>> EvaluationSumsWriter::create(
    const std::filesystem::path& path) {
  std::unique_ptr<EvaluationSumsWriter> w(new EvaluationSumsWriter);
  w->path_ = path;
  w->out_.open(path, std::ios::binary);
  if (!w->out_)
    return make_error("eval::EvaluationSumsWriter::create(): ", path.string(), ": cannot write the file");
  w->out_ << header() << '\n';
  w->out_.flush();
  if (!w->out_) return make_error("eval::EvaluationSumsWriter::create(): ", path.string(), ": write failed");
  return w;
}

std::string EvaluationSumsWriter::header() {
  std::string h;
  EvaluatedFrame f;
  for_each_sum_field(f, [&h](const char* name, auto&) {
    if (!h.empty()) h += ',';
    h += name;
  });
  return h;
}

Status EvaluationSumsWriter::add(const EvaluatedFrame& f) {
  std::string s;
  s.reserve(4096);
  bool first = true;
  for_each_sum_field(f, [&](const char*, const auto& v) {
    if (!first) s += ',';
    first = false;
    if constexpr (std::is_same_v<std::decay_t<decltype(v)>, double>)
      append_exact(s, v);
    else
      s += std::to_string(v);
  });
  out_ << s << '\n';
  out_.flush();
  if (!out_) return make_error("eval::EvaluationSumsWriter::add(): ", path_.string(), ": write failed");
  return {};
}

Expected<std::vector<EvaluatedFrame>> load_evaluation_sums(const std::filesystem::path& path) {
  const std::string where = "eval::load_evaluation_sums(): " + path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) return make_error(where, ": cannot read the file");
  const std::string head = EvaluationSumsWriter::header();
  const std::vector<std::string_view> names = split_csv_line(head);
  std::string line;
  if (!std::getline(in, line))
    return make_error(where, ": empty, expected the header line (", names.size(), " columns: frame,t_s,...)");
  if (auto bad = check_csv_header(split_csv_line(line), names, where, "evaluation_sums.csv's header"))
    return *bad;
  std::vector<EvaluatedFrame> frames;
  for (std::size_t line_no = 2; std::getline(in, line); ++line_no) {
    const std::vector<std::string_view> cells = split_csv_line(line);
    if (is_blank_csv_line(cells)) continue;  // the file's end
    if (auto bad = check_csv_field_count(cells, names.size(), where, line_no)) return *bad;
    EvaluatedFrame f;
    std::size_t i = 0;
    std::optional<Error> bad;
    for_each_sum_field(f, [&](const char* name, auto& v) {
      const std::size_t c = i++;
      if (bad || parse_cell(cells[c], v)) return;
      using T = std::decay_t<decltype(v)>;
      bad = make_error(where, ":", line_no, ":", name, ": expected ",
                       std::is_same_v<T, double>          ? "a number"
                       : std::is_same_v<T, std::uint64_t> ? "an integer >= 0"
                                                          : "an integer",
                       ", got '", std::string(cells[c]), "'");
    });
    if (bad) return *bad;
    frames.push_back(std::move(f));
  }
  if (in.bad()) return make_error(where, ": read failed");
  return frames;
}

EvaluationPoint evaluation_point(const EvaluatedFrame& f) {
  OcclusionStats stats;
  stats.occluded_pct_left = f.occluded_pct_left;
  stats.occluded_pct_right = f.occluded_pct_right;
  return evaluation_point(f.t_s, stats, f.evaluation);
}

Status plot_evaluation(const std::vector<EvaluationPoint>& points, const std::string& png_path,
                       const std::string& title) {
  const char* caller = "eval::plot_evaluation(): ";
  if (points.empty()) return make_error(caller, png_path, ": no evaluated frames to plot");
  std::string s = recorder::gnuplot_png_terminal(1200, 1000);
  s += "set output " + recorder::gnuplot_quote(png_path) + "\n$d << EOD\n";
  const double t0 = points.front().t_s;
  auto value = [&s](double v) {
    s += ' ';
    if (std::isfinite(v))
      append(s, v);
    else
      s += "NaN";
  };
  for (const EvaluationPoint& p : points) {
    value(p.t_s - t0);
    value(p.occluded_pct_left);
    value(p.occluded_pct_right);
    for (int i = 0; i < 3; ++i) value(p.bad3_pct[i]);
    for (int i = 0; i < 3; ++i) value(p.rms_px[i]);
    s += '\n';
  }
  s += "EOD\n";
  const std::string style = std::string("linespoints pointtype 7 pointsize ") +
                            (points.size() == 1 ? "1.2" : "0.35") + " linewidth 2";
  s += recorder::gnuplot_time_panels(3, title, 40);
  s += "set yrange [0:*]\nset offsets 0, 0, graph 0.05, 0\n";
  s += "set title 'Receiver occluded by the boom (% of its pixels)'\nset ylabel '%'\n";
  s += "plot $d using 1:2 with " + style +
       " linecolor rgb '#1f77b4' title 'left', \\\n"
       "     $d using 1:3 with " +
       style + " linecolor rgb '#d62728' title 'right'\n";
  const char* names[3] = {"raw pair", "augmented pair", "augmented, boom pixels left out"};
  const char* colours[3] = {"#2ca02c", "#d62728", "#9467bd"};
  for (int panel = 0; panel < 2; ++panel) {
    s += panel == 0 ? "set title 'Bad disparities over the receiver (|error| > 3 px, % of the valid "
                      "pixels)'\nset ylabel '%'\n"
                    : "set title 'RMS disparity error over the receiver (px)'\nset ylabel 'px'\n";
    s += "plot ";
    for (int i = 0; i < 3; ++i) {
      if (i) s += ", \\\n     ";
      s += "$d using 1:" + std::to_string(4 + 3 * panel + i) + " with " + style + " linecolor rgb '" +
           colours[i] + "' title '" + names[i] + "'";
    }
    s += '\n';
  }
  s += "unset multiplot\nset output\n";
  return recorder::run_gnuplot(s, png_path, caller);
}

}  // namespace augrig::eval
