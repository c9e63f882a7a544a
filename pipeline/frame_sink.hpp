// FrameSink: one interface for every output of a run, like GStreamer's sink elements. The recorder,
// stats.csv, the per-frame files, the window, the network live view, a video file and a command's
// own per-pair output (evaluate, the demo) are each one FrameSink in one file under
// pipeline/sinks/; the pipeline configures them and hands each stereo pair to all of them.
//
// A pair's trip through the sinks (Pipeline's frame path):
//   1. consume(): every sink, the ones reading the changed boxes first, then those that asked for
//      whole augmented images (SinkNeeds::whole_images; made once, by the first to ask,
//      PairContext::make_whole()), each in the order it was configured;
//   2. release(): every sink again, in the same order; only here may a sink take something for
//      itself: the raw frame (the recorder, moved, never copied) or the result's buffers (the
//      window's mailbox swaps them). The pipeline reuses what is left for the next pair.
// Besides the pairs a sink hears the run's events (printed lines: cameras lost, pose stale, the
// flight's phase), once a second its health when it asked for it, and a close() with the final
// report when the run stops (the report's source counts are final by then).
//
// A sink's Error from consume() or close() stops the run (a file that cannot be written): the
// pipeline stops reading, closes every sink and returns that error.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "capture/stereo_source.hpp"
#include "core/expected.hpp"
#include "core/frame.hpp"
#include "pipeline/poses.hpp"
#include "recorder/record.hpp"
#include "render/augmenter.hpp"
#include "render/rig.hpp"

namespace augrig::pipeline {

struct PipelineReport;

// What a sink needs of each pair, so that the pipeline makes nothing that no sink needs, and
// nothing twice.
struct SinkNeeds {
  bool whole_images = false;  // whole augmented views (else: the changed boxes the augmenter made)
  bool look_updates = false;  // the camera look's new estimates (PairContext::look_updates)
  bool health = false;        // the run's health once a second (FrameSink::health)
};

// One stereo pair as the sinks see it.
struct PairContext {
  StereoFrame& raw;         // the pair as read; its images are the raw images
  StereoResult* result;     // the augmentation (boxes, or whole after make_whole()); null: captured only
  const SceneState* scene;  // the scene it was augmented in; null: no pose (captured only)
  const FramePoses& poses;
  std::uint64_t pair = 0;       // this pair's count in the run, from 1 (PipelineReport::pairs)
  TimestampNs mid_host_ns = 0;  // its mid-exposure on the host clock (the earlier camera's; 0: unknown)
  std::optional<SourcePosition> position =
      std::nullopt;     // where it lies in its file (a recording: index, pass)
  bool paused = false;  // the window paused the run (a live run goes on recording)
  bool replay = false;  // the source is a recording (paused, it only steps)
  std::vector<recorder::LookRecord>* look_updates = nullptr;  // the look's new estimates, if any

  // Makes both augmented views whole (once; a no-op when they are).
  void make_whole();
  bool made_whole = false;
};

// An event of the run: printed by the pipeline, recorded, shown on the network view.
struct SinkEvent {
  TimestampNs t_ns = 0;  // when, on `clock`
  ClockDomain clock = ClockDomain::kHostMonotonic;
  std::string text;
  // Shown to the people watching (the live view's health until the next status); false: kept
  // only (the look's status, clock offsets, the flight's phase).
  bool notify = true;
  TimestampNs pair_t_key_ns = 0;  // the last pair's key time, for stamps on the pairs' clock
};

// The run's health, once a second, for the sinks that asked (SinkNeeds::health).
struct RunHealth {
  std::uint64_t pairs = 0, failed_pairs = 0, stale_pairs = 0;
  StereoSourceStats source;
  std::vector<SourceHealth> cameras;
  bool pose_shown = false;  // there is a pose source to speak of
  bool pose_stale = false;
  std::string pose_problem;  // the first, when stale
  std::string recording;     // "on", "paused", "stopped"; empty: no recorder
  std::uint64_t recorder_dropped = 0;
  TimestampNs pair_t_key_ns = 0;  // the last pair's
  // The online camera clocks (empty: off): a line each, and /diagnostics' values
  // (camera0_clock_offset_ms, camera0_clock_sigma_ms, camera0_clock_applied, ...).
  std::vector<std::string> camera_clocks;
  std::vector<std::pair<std::string, std::string>> camera_clock_values;
};

// The scene a pair was augmented in, as a recording keeps it, into `r` (a recorder::FrameRecord or
// a recorder::McapFrame): the receiver in the tanker body and in each camera, its presence, the
// poses' sigmas, and the boom flown (none when the pair was captured only). Nothing without a scene.
template <class Record>
void record_scene(const PairContext& pair, const Rig& rig, Record& r) {
  const SceneState* scene = pair.scene;
  if (!scene) return;
  r.T_body_receiver = scene->T_body_receiver;
  r.receiver_present = scene->receiver_present;
  for (std::size_t c = 0; c < 2; ++c) r.T_cam_receiver[c] = rig.cameras[c].T_body_cam.inverse() * scene->T_body_receiver;
  r.sigma_pos_m = pair.poses.sigma_pos_m;
  r.sigma_att_deg = pair.poses.sigma_att_deg;
  if (pair.result) r.boom = scene->boom;
}

class FrameSink {
 public:
  virtual ~FrameSink() = default;
  virtual SinkNeeds needs() const { return {}; }
  // Each pair (see above). An Error stops the run.
  virtual Status consume(PairContext& pair) = 0;
  // After every sink consumed the pair: the only place to take the raw frame or the result's buffers.
  virtual void release(PairContext& /*pair*/) {}
  virtual void event(const SinkEvent& /*e*/) {}
  virtual void health(const RunHealth& /*h*/) {}
  // The run stopped; the report is final but for what the sinks add to it. An Error is the run's.
  virtual Status close(PipelineReport& /*report*/) { return {}; }
};

}  // namespace augrig::pipeline
