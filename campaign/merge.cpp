#include "campaign/merge.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <ostream>
#include <sstream>

#include "campaign/task.hpp"
#include "eval/matcher.hpp"
#include "eval/report.hpp"
#include "recorder/euroc.hpp"
#include "recorder/mcap_export.hpp"
#include "recorder/reader.hpp"
#include "recorder/recording_merge.hpp"
#include "render/stats.hpp"

namespace augrig::campaign {

namespace fs = std::filesystem;

namespace {

constexpr const char* kWhere = "campaign::merge(): ";

struct Lines {
  std::string header;
  std::vector<std::string> rows;
};

Expected<Lines> read_lines(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) return make_error(kWhere, p.string(), ": cannot read (the shard is incomplete)");
  Lines l;
  std::string line;
  if (!std::getline(in, l.header)) return make_error(kWhere, p.string(), ": empty, expected a header line");
  while (std::getline(in, line))
    if (!line.empty()) l.rows.push_back(line);
  return l;
}

// One per-frame file of every shard, in shard order, as one file with one header.
Status join_file(const std::vector<const Task*>& shards, const std::string& name, const fs::path& to,
                 std::size_t* rows = nullptr) {
  std::ofstream o(to, std::ios::binary);
  std::string header;
  std::size_t n = 0;
  for (const Task* t : shards) {
    auto l = read_lines(t->out / name);
    if (!l) return l.error();
    if (header.empty()) {
      header = l->header;
      o << header << '\n';
    } else if (l->header != header) {
      return make_error(kWhere, (t->out / name).string(), ": its header differs from the first shard's (",
                        (shards.front()->out / name).string(), "): shards of different commands cannot join");
    }
    for (const auto& r : l->rows) o << r << '\n';
    n += l->rows.size();
  }
  if (!o.flush()) return make_error(kWhere, to.string(), ": cannot write");
  if (rows) *rows = n;
  return {};
}

Status write_text(const fs::path& p, const std::string& text) {
  std::ofstream o(p, std::ios::binary);
  o << text;
  if (!o.flush()) return make_error(kWhere, p.string(), ": cannot write");
  return {};
}

// The value after `flag` in a task's command line ("" when absent).
std::string flag_value(const std::vector<std::string>& argv, const std::string& flag) {
  for (std::size_t i = 0; i + 1 < argv.size(); ++i)
    if (argv[i] == flag) return argv[i + 1];
  return "";
}

std::string pct(double v) {
  if (!std::isfinite(v)) return "";
  char b[32];
  std::snprintf(b, sizeof b, "%.2f", v);
  return b;
}

// One row of campaign.csv / line of campaign.txt per flight and variant.
struct FlightLine {
  std::string variant, flight;
  std::size_t shards = 0, frames = 0, evaluated = 0;
  std::size_t left_out = 0;                                    // planned frames not in the outputs
  double occluded_left = NAN, occluded_right = NAN;            // mean over frames, % of the receiver
  double bad3[3] = {NAN, NAN, NAN}, rms[3] = {NAN, NAN, NAN};  // raw, augmented, augmented without boom
};

void scores(const eval::RunEvaluation& run, FlightLine& l) {
  const eval::DisparityErrors* d[3] = {&run.raw.all[0], &run.augmented.all[0],
                                       &run.augmented.boom_excluded[0]};
  for (int i = 0; i < 3; ++i) {
    l.bad3[i] = d[i]->valid ? d[i]->bad3_pct() : NAN;
    l.rms[i] = d[i]->valid ? d[i]->rms_px() : NAN;
  }
}

// Per variant, over all its flights: the occlusion statistics, and where evaluated the
// evaluation and its matcher.
struct VariantTotals {
  std::map<std::string, eval::RunEvaluation> runs;
  std::map<std::string, std::vector<OcclusionStats>> stats;
  std::map<std::string, eval::MatcherParams> matcher;
};

// The shards of a flight not done ("" when all are).
std::string shards_not_done(const Manifest& m, const std::vector<const Task*>& shards, double now) {
  std::string missing;
  for (const Task* t : shards)
    if (task_status(m, *t, now).state != TaskState::kDone)
      missing += (missing.empty() ? "" : ", ") + std::to_string(t->shard.index) + " (task " +
                 std::to_string(t->id) + ")";
  return missing;
}

// The shards (in index order) cover the flight's frames once, in order.
Status check_shards_join(const std::string& label, const std::vector<const Task*>& shards) {
  for (std::size_t i = 1; i < shards.size(); ++i)
    if (shards[i]->shard.from_frame != shards[i - 1]->shard.from_frame + shards[i - 1]->shard.frames)
      return make_error(kWhere, label, ": shards ", shards[i - 1]->shard.index, " and ",
                        shards[i]->shard.index, " do not join (frames ",
                        shards[i - 1]->shard.from_frame + shards[i - 1]->shard.frames, " and ",
                        shards[i]->shard.from_frame, ")");
  return {};
}

// The occlusion statistics, frame by frame, and their summary; the frames added to all_stats.
Status merge_stats(const std::vector<const Task*>& shards, const fs::path& dir, FlightLine& fl,
                   std::vector<OcclusionStats>& all_stats) {
  if (Status s = join_file(shards, "stats.csv", dir / "stats.csv", &fl.frames); !s) return s.error();
  // Frames a shard left out (damaged input, no pose; each shard's task.log says which).
  std::size_t planned = 0;
  for (const Task* t : shards) planned += t->shard.frames;
  if (planned > fl.frames) fl.left_out = planned - fl.frames;
  auto stats = read_stats_csv((dir / "stats.csv").string());
  if (!stats) return stats.error();
  if (!stats->empty()) {
    double l = 0, r = 0;
    for (const auto& s : *stats) {
      l += s.occluded_pct_left;
      r += s.occluded_pct_right;
    }
    fl.occluded_left = l / static_cast<double>(stats->size());
    fl.occluded_right = r / static_cast<double>(stats->size());
  }
  if (Status s = write_text(dir / "summary.txt", format_run_summary(*stats)); !s) return s.error();
  all_stats.insert(all_stats.end(), stats->begin(), stats->end());
  return {};
}

// The flight's recording, for the nav inputs of its MCAP file; null for an MCAP file or a EuRoC
// folder.
Expected<std::unique_ptr<recorder::RecordingReader>> flight_recording(const fs::path& flight) {
  if (!fs::is_directory(flight) || fs::exists(flight / "mav0") || flight.filename() == "mav0")
    return std::unique_ptr<recorder::RecordingReader>();
  auto r = recorder::RecordingReader::open(flight.string());
  if (!r) return r.error();
  return std::move(*r);
}

// The shards' exports (a variant's exports: [mcap, euroc, recording]) joined per flight: their MCAP
// files into DIR/flight.mcap and their recordings into DIR/recording, with the flight's nav inputs
// when it is a recording; their EuRoC folders into DIR/euroc (each shard's holds the recording's
// nav inputs already). Each line says what was joined. Nothing when the variant exports nothing.
Status merge_exports(const std::vector<const Task*>& shards, const fs::path& dir,
                     std::vector<std::string>& lines) {
  const std::vector<std::string>& argv = shards.front()->argv;
  auto has = [&](const std::string& sink) { return std::find(argv.begin(), argv.end(), sink) != argv.end(); };
  const fs::path flight = argv.at(1);
  if (has(std::string("mcap:") + kTaskOut + "/" + kShardMcap)) {
    std::vector<std::string> inputs;
    for (const Task* t : shards) inputs.push_back((t->out / kShardMcap).string());
    auto nav = flight_recording(flight);
    if (!nav) return nav.error();
    recorder::McapExportReport report;
    if (Status s = recorder::merge_mcap(inputs, (dir / kShardMcap).string(), nav->get(), report); !s)
      return make_error(kWhere, s.error().message);
    lines.push_back((dir / kShardMcap).string() + ": " + std::to_string(report.frames) +
                    " stereo frame(s) from the shards' MCAP files");
  }
  if (has(std::string(kTaskOut) + "/" + kShardRecording)) {
    std::vector<std::string> inputs;
    for (const Task* t : shards) inputs.push_back((t->out / kShardRecording).string());
    auto nav = flight_recording(flight);
    if (!nav) return nav.error();
    recorder::RecordingMergeReport report;
    if (Status s = recorder::merge_recordings(inputs, (dir / kShardRecording).string(), nav->get(), report);
        !s)
      return make_error(kWhere, s.error().message);
    lines.push_back((dir / kShardRecording).string() + ": " + std::to_string(report.frames) +
                    " stereo frame(s) from the shards' recordings, " + std::to_string(report.nav_inputs) +
                    " nav input(s) of the flight");
  }
  if (has(kShardEurocSink)) {
    std::vector<std::string> inputs;
    for (const Task* t : shards) inputs.push_back((t->out / kShardEuroc).string());
    std::error_code ec;
    fs::remove_all(dir / kShardEuroc, ec);  // a merge again makes it again
    recorder::EurocMergeReport report;
    if (Status s = recorder::merge_euroc(inputs, (dir / kShardEuroc).string(),
                                         {true, flight.filename().string()}, report);
        !s)
      return make_error(kWhere, s.error().message);
    lines.push_back((dir / kShardEuroc).string() + ": " + std::to_string(report.frames) +
                    " stereo frame(s) from the shards' EuRoC folders (" + std::to_string(report.images) +
                    " files linked)");
    for (const std::string& p : report.problems)
      lines.push_back((dir / kShardEuroc).string() + ": problem: " + p);
  }
  return {};
}

// The evaluation: per-frame files joined, the table from the exact sums re-added in order.
Status merge_evaluation(const std::vector<const Task*>& shards, const fs::path& dir,
                        const std::pair<std::string, std::string>& key, const MergeOptions& options,
                        FlightLine& fl, VariantTotals& totals) {
  if (Status s = join_file(shards, "evaluation.csv", dir / "evaluation.csv"); !s) return s.error();
  if (Status s = join_file(shards, "evaluation_sums.csv", dir / "evaluation_sums.csv"); !s) return s.error();
  auto frames = eval::load_evaluation_sums(dir / "evaluation_sums.csv");
  if (!frames) return frames.error();
  for (std::size_t i = 1; i < frames->size(); ++i)
    if ((*frames)[i].frame <= (*frames)[i - 1].frame)
      return make_error(kWhere, (dir / "evaluation_sums.csv").string(), ": frame ", (*frames)[i].frame,
                        " follows frame ", (*frames)[i - 1].frame, ": the shards overlap");
  eval::MatcherParams matcher;
  if (const std::string mf = flag_value(shards.front()->argv, "--matcher"); !mf.empty()) {
    auto p = eval::load_matcher_params(mf);
    if (!p) return p.error();
    matcher = *p;
  }
  totals.matcher[key.first] = matcher;
  eval::RunEvaluation run;
  std::vector<eval::EvaluationPoint> points;
  auto& campaign_run = totals.runs[key.first];
  for (const auto& f : *frames) {
    run.add(f.evaluation);
    campaign_run.add(f.evaluation);
    points.push_back(eval::evaluation_point(f));
  }
  fl.evaluated = frames->size();
  scores(run, fl);
  const std::string title = "Stereo evaluation: flight " + key.second + ", variant " + key.first;
  if (Status s = write_text(dir / "evaluation.txt", eval::format_evaluation_table(run, title, matcher)); !s)
    return s.error();
  if (options.plot && !points.empty())
    if (Status s = eval::plot_evaluation(points, (dir / "evaluation.png").string(), title); !s)
      return s.error();
  return {};
}

// campaign.txt's opening: what was merged, what was left out or not merged, the columns.
void campaign_heading(const Manifest& m, const MergeSummary& sum, std::ostream& txt) {
  txt << "Campaign '" << m.name << "' (" << m.campaign_file.string() << "): " << sum.flights_merged
      << " flight report(s) merged, " << sum.frames << " stereo frame(s), " << sum.evaluated << " evaluated";
  if (sum.frames_left_out)
    txt << "; " << sum.frames_left_out
        << " planned frame(s) left out (damaged input, or no pose: the 'left out' column, each shard's "
           "task.log)";
  txt << "\n";
  if (!sum.incomplete.empty()) {
    txt << "Not merged (shards not done):\n";
    for (const auto& s : sum.incomplete) txt << "  " << s << "\n";
  }
  txt << "\nPer flight: occlusion of the receiver by the boom (% of its pixels, mean over frames); stereo\n"
         "bad > 3 px (%) and RMS error (px) over the receiver for the raw pair, the augmented pair, and the\n"
         "augmented pair with the boom's pixels left out.\n\n";
}

// A line per flight and variant: campaign.txt's table and campaign.csv.
void flight_rows(const std::vector<FlightLine>& lines, std::ostream& txt, std::ostream& csv) {
  csv << "variant,flight,shards,frames,evaluated,occluded_pct_left_mean,occluded_pct_right_mean,"
         "raw_bad3_pct,aug_bad3_pct,aug_noboom_bad3_pct,raw_rms_px,aug_rms_px,aug_noboom_rms_px,frames_left_"
         "out\n";
  char row[512];
  std::snprintf(row, sizeof row, "%-14s %-16s %6s %8s %8s %9s %8s %8s %8s %8s %9s %8s %8s %9s\n", "variant",
                "flight", "shards", "frames", "left out", "evaluated", "occl L", "occl R", "bad3 raw",
                "bad3 aug", "bad3 -boom", "rms raw", "rms aug", "rms -boom");
  txt << row;
  for (const FlightLine& l : lines) {
    std::snprintf(row, sizeof row, "%-14s %-16s %6zu %8zu %8zu %9zu %8s %8s %8s %8s %9s %8s %8s %9s\n",
                  l.variant.c_str(), l.flight.c_str(), l.shards, l.frames, l.left_out, l.evaluated,
                  pct(l.occluded_left).c_str(), pct(l.occluded_right).c_str(), pct(l.bad3[0]).c_str(),
                  pct(l.bad3[1]).c_str(), pct(l.bad3[2]).c_str(), pct(l.rms[0]).c_str(),
                  pct(l.rms[1]).c_str(), pct(l.rms[2]).c_str());
    txt << row;
    csv << l.variant << ',' << l.flight << ',' << l.shards << ',' << l.frames << ',' << l.evaluated << ','
        << pct(l.occluded_left) << ',' << pct(l.occluded_right) << ',' << pct(l.bad3[0]) << ','
        << pct(l.bad3[1]) << ',' << pct(l.bad3[2]) << ',' << pct(l.rms[0]) << ',' << pct(l.rms[1]) << ','
        << pct(l.rms[2]) << ',' << l.left_out << '\n';
  }
}

// The campaign: a line per flight and variant, and per variant the tables over all its flights.
Status write_campaign_report(const Manifest& m, const MergeSummary& sum, const std::vector<FlightLine>& lines,
                             VariantTotals& totals) {
  std::ostringstream txt, csv;
  campaign_heading(m, sum, txt);
  flight_rows(lines, txt, csv);
  std::vector<std::string> variants;
  for (const FlightLine& l : lines)
    if (std::find(variants.begin(), variants.end(), l.variant) == variants.end())
      variants.push_back(l.variant);
  for (const std::string& v : variants) {
    txt << "\n==== Variant " << v << ": every merged flight ====\n\n";
    txt << format_run_summary(totals.stats[v]);
    if (totals.runs.count(v))
      txt << "\n"
          << eval::format_evaluation_table(
                 totals.runs[v], "Stereo evaluation: variant " + v + ", every flight", totals.matcher[v]);
  }
  if (Status s = write_text(sum.report_dir / "campaign.txt", txt.str()); !s) return s.error();
  if (Status s = write_text(sum.report_dir / "campaign.csv", csv.str()); !s) return s.error();
  return {};
}

}  // namespace

Expected<MergeSummary> merge_campaign(const Manifest& m, const MergeOptions& options, std::ostream& out) {
  MergeSummary sum;
  sum.report_dir = m.out / "report";
  std::error_code ec;
  fs::create_directories(sum.report_dir, ec);
  if (ec) return make_error(kWhere, sum.report_dir.string(), ": ", ec.message());

  // The tasks of each variant and flight, in manifest order (variants, then flights, then shards).
  std::vector<std::pair<std::string, std::string>> order;
  std::map<std::pair<std::string, std::string>, std::vector<const Task*>> groups;
  for (const Task& t : m.tasks) {
    const auto key = std::make_pair(t.variant, t.flight);
    if (!groups.count(key)) order.push_back(key);
    groups[key].push_back(&t);
  }
  const double now = static_cast<double>(std::time(nullptr));
  std::vector<FlightLine> lines;
  VariantTotals totals;
  for (const auto& key : order) {
    auto& shards = groups[key];
    std::sort(shards.begin(), shards.end(),
              [](const Task* a, const Task* b) { return a->shard.index < b->shard.index; });
    const std::string label = key.first + "/" + key.second;
    // Every shard done, and together they cover the flight's frames once, in order.
    if (const std::string missing = shards_not_done(m, shards, now); !missing.empty()) {
      const std::string what = label + ": shard(s) " + missing + " not done";
      if (!options.partial)
        return make_error(kWhere, what,
                          "; run `augrig campaign status` and `resume`, or merge with --partial");
      sum.incomplete.push_back(what);
      ++sum.flights_incomplete;
      continue;
    }
    if (Status s = check_shards_join(label, shards); !s) return s.error();

    const fs::path dir = sum.report_dir / key.first / key.second;
    fs::create_directories(dir, ec);
    if (ec) return make_error(kWhere, dir.string(), ": ", ec.message());
    FlightLine fl{key.first, key.second};
    fl.shards = shards.size();
    if (Status s = merge_stats(shards, dir, fl, totals.stats[key.first]); !s) return s.error();
    const bool evaluated = shards.front()->argv.front() == "evaluate";
    if (evaluated)
      if (Status s = merge_evaluation(shards, dir, key, options, fl, totals); !s) return s.error();
    std::vector<std::string> exports;
    if (Status s = merge_exports(shards, dir, exports); !s) return s.error();
    sum.frames += fl.frames;
    sum.evaluated += fl.evaluated;
    sum.frames_left_out += fl.left_out;
    ++sum.flights_merged;
    out << "merged " << label << ": " << fl.shards << " shard(s), " << fl.frames << " frame(s)";
    if (evaluated) out << ", " << fl.evaluated << " evaluated";
    if (fl.left_out)
      out << ", " << fl.left_out << " left out (damaged input or no pose: the shards' task.log)";
    out << " -> " << dir.string() << "\n";
    for (const std::string& e : exports) out << "  " << e << "\n";
    lines.push_back(fl);
  }
  if (Status s = write_campaign_report(m, sum, lines, totals); !s) return s.error();
  return sum;
}

}  // namespace augrig::campaign
