// Pipeline: the runtime behind every augrig command that moves frames (run, demo's window,
// replay). One stereo frame's path, all of it in Pipeline::process():
//
//   source    a StereoSource (capture thread per source, bounded queues, pairing) over any
//             FrameSource by URI (sources.hpp): sim://, replay://, euroc://, aravis://, v4l2://
//   pose      a PoseProvider (poses.hpp): the receiver's pose at the frame's mid-exposure, with a
//             verdict (good, stale, none) in plain words
//   boom      the BoomStage (boom_stage.hpp): the source's boom, fixed, scripted, tracking the
//             receptacle, or the operator's
//   augment   the Augmenter: masks, receiver depth, the boom composited, occlusion statistics
//   sinks     each optional: the recorder, stats.csv, per-frame images, the live window's mailbox
//             (LiveView), the network live view (net::FoxgloveServer), and the run's summary
//             (PipelineReport)
//
// run() reads pairs until a stop condition: the source ends, the duration or the pair count is
// reached, the stop flag is raised (a signal), the window is closed, or something fails. Every
// frame read is accounted for: read = 2 x pairs + each row of the drop ledger (pairing, queue,
// failed, pending at the stop), which the report prints and the recorder stores. A configuration
// that cannot work (a frame size that is not the rig's) fails at the first frame with one message.
//
// Threads: run() on one thread (the app runs it on a worker when a window is open; the window
// talks to it only through LiveView). The GL context the augmenter needs is made on that thread.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "capture/stereo_source.hpp"
#include "core/expected.hpp"
#include "net/foxglove_server.hpp"
#include "pipeline/boom_stage.hpp"
#include "pipeline/nav_inputs.hpp"
#include "pipeline/outputs.hpp"
#include "pipeline/poses.hpp"
#include "pipeline/sources.hpp"
#include "pipeline/status.hpp"
#include "recorder/recorder.hpp"
#include "render/augmenter.hpp"
#include "render/rig.hpp"
#include "render/stats.hpp"

namespace augrig::recorder {
class ReplaySource;
}

namespace augrig::pipeline {

// What the window (or any controller) asks of the running pipeline; merged until taken.
struct PipelineCommands {
  bool quit = false;
  bool toggle_pause = false;
  bool toggle_recording = false;
  std::optional<DisplayBoomMode> boom_mode;
  BoomNudge boom_nudge;
  int steps = 0;                          // paused: advance this many stereo frames (replay)
  std::optional<std::size_t> seek_frame;  // replay: jump to this recorded frame
  std::optional<double> rate;             // replay: real rate x (0: as fast as possible)
  void merge(const PipelineCommands& o);
};

// Where the playback of a recording stands, for the window's timeline.
struct Playback {
  std::size_t frame = 0;           // the recorded index of the frame shown
  std::size_t frame_count = 0;     // frames in the recording
  double t_s = 0, duration_s = 0;  // from the first frame
  int pass = 0;
  double rate = 0;  // real rate x; 0: as fast as possible
};

// The mailbox between the pipeline's thread and the window's: the newest augmented pair (by
// swap, never copied), the HUD, the playback position, and commands back. Neither side waits.
class LiveView {
 public:
  // ---- The pipeline's side ----
  // Hands over a new augmented pair (whole augmented images); `result` gets the previous buffers.
  void publish(StereoResult& result, const SceneState& scene, TimestampNs mid_host_ns);
  void set_hud(HudState hud, std::optional<Playback> playback);
  PipelineCommands take_commands();
  void finish();  // the pipeline stopped: the window closes
  // ---- The window's side ----
  struct Shown {
    StereoResult result;
    SceneState scene;
    std::uint64_t id = 0;  // 0: nothing yet
  };
  // Swaps the newest pair into `shown` when there is one newer than shown.id; returns its
  // mid-exposure on the host clock (0: no new pair or unknown).
  TimestampNs take_newest(Shown& shown);
  HudState hud() const;
  std::optional<Playback> playback() const;
  void post(const PipelineCommands& c);
  bool finished() const;
  // Waits until a pair newer than `shown_id` is published or the pipeline finished (true), or the
  // timeout passed (false): the window draws a new pair as soon as it is handed over.
  bool wait_newer(std::uint64_t shown_id, std::chrono::nanoseconds timeout) const;
  // The window drew the pair with mid-exposure `mid_host_ns`: its latency to the screen.
  void drawn(TimestampNs mid_host_ns);
  // Mid-exposure to the window's draw (or, headless, to the hand-off), over the last pairs.
  LatencyHud display_latency() const;
  const SkewStats& display_histogram() const { return display_hist_; }

 private:
  friend class Pipeline;
  void add_latency(TimestampNs ns);
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;  // a new pair or the finish
  Shown newest_;
  TimestampNs newest_mid_host_ns_ = 0;
  HudState hud_;
  std::optional<Playback> playback_;
  PipelineCommands commands_;
  bool finished_ = false;
  std::vector<double> recent_ms_;  // the last 300 latencies, for the HUD
  SkewStats display_hist_;         // the whole run's, for the summary
};

// Per-frame image files: every `every`-th augmented pair, named by `names` when given (e.g. after
// the input files), else by pair sequence (for a replayed recording: recorded index and pass).
struct FrameFiles {
  std::filesystem::path dir;
  int every = 1;
  std::function<FrameNames(const StereoFrame&)> names;
  bool ground_truth = false;  // also the depth, correspondence and class files (write_ground_truth)
};

// Everything a pipeline is made of. The source (started or not), the poses and the rig are required.
struct PipelineParts {
  Rig rig;
  RigModels models;                      // loaded before anything was opened (load_rig_models)
  OpenedSourceInfo source_info;          // what the source URI opened into (live, sim clock, ...)
  std::unique_ptr<StereoSource> source;  // started; or:
  // a source run() starts once the augmenter is ready: cameras capture from the moment they are
  // started, and the augmenter's set-up must not overflow their queues (live runs use this).
  std::unique_ptr<OpenedSource> unstarted_source;
  std::unique_ptr<PoseProvider> poses;  // may be null only with capture_only
  // Capture only: the pairs are recorded (and shown) raw, with their poses where a pose source is
  // given, and nothing is augmented: no boom, masks nor statistics, no GL context. A rig without
  // a boom section (BoomConfig::configured) allows nothing else.
  bool capture_only = false;
  std::optional<BoomArg> boom;  // none: the poses' boom where they have one, else tracking
  BoomDimensions boom_dims;     // the boom's geometry for tracking (a scenario's; default built-in)
  AugmentOptions augment;       // augmented_output is set to kChangedBox (sinks get what they need)
  // Sinks, each optional.
  std::unique_ptr<recorder::Recorder> recorder;
  // The recorder also stores each pair's receiver depth (the ground truth, docs/GROUND_TRUTH.md).
  bool record_ground_truth = false;
  std::unique_ptr<StatsCsvWriter> stats_csv;
  std::optional<FrameFiles> frame_files;
  std::shared_ptr<LiveView> view;
  // The live view over the network (Foxglove WebSocket): every pair as it is augmented (or, capture
  // only, raw), and once a second the run's health in plain words. Never blocks the pipeline.
  std::shared_ptr<net::FoxgloveServer> serve;
  // Stop conditions besides the end of the source.
  double duration_s = 0;                   // 0: none
  std::uint64_t max_pairs = 0;             // augmented pairs; 0: none
  std::atomic<bool>* stop_flag = nullptr;  // raised by a signal handler
  double status_every_s = 0;               // a status line this often (0: never)
  // A progress line ("N of M pairs, X/s, ETA") about once a second on `out` when M is known (a
  // file source); 0: none. Interactive runs (a window) have the window instead.
  std::uint64_t progress_total = 0;
  // Frames without a pose: augmented with the boom alone and marked (live), or not augmented and
  // counted (a recording without a scene for some frames).
  bool skip_frames_without_pose = false;
  // Every pair's statistics kept in the report (finite jobs that print or rewrite them); a live run
  // keeps only the running summary, so its memory stays flat however long it runs.
  bool keep_all_stats = false;
  // The flight's phase at a pair ("approach", "contact", ...; "" where unknown): each change is an
  // event "phase: NAME" at the pair's statistics time (their clock), printed and recorded, which
  // the statistics plot marks. Unset with a sim:// source: the simulation's own phases.
  std::function<std::string(const StereoFrame&)> phase_of;
  // Called once with the first frame (e.g. to start the simulated nav streams on its clock).
  std::function<void(const StereoFrame&)> on_first_frame;
  // The live nav, when the poses come from it (its status goes into the report).
  const LiveNav* live_nav = nullptr;
  // The live nav inputs: stopped with the pipeline, their losses in the recording's ledger.
  NavInputs* nav_inputs = nullptr;
  // Called for every augmented pair after the file sinks and before the recorder takes the frame
  // (a command's own per-pair outputs); an Error ends the run as a sink's would.
  std::function<Status(const StereoFrame& raw, const StereoResult& result, const SceneState& scene,
                       const FramePoses& poses)>
      on_pair;
  // A problem that does not stop the run (a damaged frame skipped, a failed augmentation, a frame
  // without a pose): the command prints it its way. Default: "pipeline: <message>" on err.
  std::function<void(const Error&)> on_problem;
  // Called when the run stops, before the nav inputs stop (e.g. the simulated nav streams).
  std::function<void()> on_stop;
};

// What a run did: the numbers behind its summary.
struct PipelineReport {
  std::uint64_t pairs = 0;               // augmented (captured, with PipelineParts::capture_only)
  std::uint64_t failed_pairs = 0;        // augmentation failed
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
};

class Pipeline {
 public:
  explicit Pipeline(PipelineParts parts);
  ~Pipeline();

  // Runs until a stop condition; prints status lines and events to `out`, per-frame problems to
  // `err`. Fails (an Error) only for what stops the run at once: a frame size that is not the
  // rig's, no GL context, a sink that cannot write. The recorder is closed either way.
  Expected<PipelineReport> run(std::ostream& out, std::ostream& err);

  // The summary lines of a report ("frames read: ... = 2 x P pairs + ..." adds up).
  void print_summary(const PipelineReport& r, std::ostream& out) const;

  const Rig& rig() const { return parts_.rig; }
  const PipelineParts& parts() const { return parts_; }

 private:
  struct State;
  void log_event(State& s, const std::string& text, std::ostream& out);
  PipelineParts parts_;
};

}  // namespace augrig::pipeline
