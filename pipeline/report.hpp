// PipelineReport: what a run did, the numbers behind its summary, and the summary's lines
// (print_report: "frames read: ... = 2 x P pairs + ..." adds up, the drops by stage, the
// latencies, the stages' times, the live view's clients, the nav's and the clocks' state).
#pragma once

#include <cstdint>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "capture/stereo_source.hpp"
#include "core/expected.hpp"
#include "net/foxglove_server.hpp"
#include "recorder/recorder.hpp"
#include "render/augmenter.hpp"
#include "render/stats.hpp"

namespace augrig::pipeline {

struct PipelineParts;

// What a run did: the numbers behind its summary.
struct PipelineReport {
  std::uint64_t pairs = 0;               // augmented (captured, with PipelineParts::capture_only)
  std::uint64_t failed_pairs = 0;        // augmentation failed
  TimeSpan failed_t;                     // their key times (t_key_ns), for the drop ledger
  std::uint64_t no_pose_pairs = 0;       // without a pose (boom only, or skipped)
  std::uint64_t skipped_no_pose = 0;     // of those, not augmented (skip_frames_without_pose)
  std::uint64_t stale_pairs = 0;         // with a stale or missing pose
  std::uint64_t seek_skipped_pairs = 0;  // read ahead of a seek and passed over
  // Live runs stopped by the duration, a signal or the window: pairs the cameras had delivered
  // before the stop, augmented after it (in `pairs` too).
  std::uint64_t pairs_after_stop = 0;
  std::uint64_t comparable = 0, reproduced = 0;  // replay: recorded statistics reproduced exactly
  double wall_s = 0, augment_ms = 0;
  Rasterizer rasterizer = Rasterizer::kAuto;
  StereoSourceStats source;
  std::optional<OcclusionStats> last_stats;  // the last augmented pair's
  std::vector<OcclusionStats> all_stats;     // every augmented pair's, with PipelineParts::keep_all_stats
  RunSummary summary;
  SkewStats display_latency, recorder_latency;
  // Time per stage for each pair: from the later frame's arrival on the host to the pipeline
  // (capture queues and pairing; live frames only), the pose, the augmentation, the sinks.
  SkewStats stage_queue, stage_pose, stage_augment, stage_sinks;
  bool stopped_by_signal = false, window_closed = false, source_failed = false;
  std::string source_error;
  std::vector<std::string> lost_cameras;  // not connected at the end
  std::optional<Status> recording_closed;
  recorder::RecorderStats recorder_stats;
  std::optional<net::ServeStats> serve;  // the network view's clients, messages sent and dropped
  std::vector<std::string> outputs;      // what each sink wrote, a line each (their close())
};

// The summary lines of a run's report, for the parts it ran with.
void print_report(const PipelineReport& r, const PipelineParts& parts, std::ostream& out);

}  // namespace augrig::pipeline
