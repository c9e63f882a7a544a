// merge: the shards' outputs joined into one report per flight and variant and one for the
// campaign (docs/CAMPAIGN.md, "Reports"). Per flight, the shards' per-frame files (stats.csv,
// evaluation.csv, evaluation_sums.csv) are concatenated in frame order, and the summaries are made
// again from the joined frames: the occlusion summary from stats.csv, the evaluation table from the
// exact per-frame sums re-added in frame order, the plot from the same points. So a flight's report
// equals what one unsharded `augrig evaluate`/`replay` of it writes, frame for frame.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "campaign/campaign.hpp"
#include "core/expected.hpp"

namespace augrig::campaign {

struct MergeOptions {
  bool partial = false;  // merge the flights whose shards are all done, list the others
  bool plot = true;      // evaluation.png per flight (gnuplot)
};

struct MergeSummary {
  std::filesystem::path report_dir;  // OUT/report
  std::size_t flights_merged = 0, flights_incomplete = 0;
  std::size_t frames = 0, evaluated = 0;
  std::size_t frames_left_out = 0;      // planned frames not in the shards' outputs (damaged input, no pose)
  std::vector<std::string> incomplete;  // "variant/flight: shards 3, 7 not done"
};

// Writes OUT/report/VARIANT/FLIGHT/{stats.csv, summary.txt, evaluation.csv, evaluation_sums.csv,
// evaluation.txt, evaluation.png} and OUT/report/campaign.{txt,csv}. Errors: a shard not done
// (unless `partial`), shards whose files do not join (headers differ, frames missing or repeated).
Expected<MergeSummary> merge_campaign(const Manifest& m, const MergeOptions& options, std::ostream& out);

}  // namespace augrig::campaign
