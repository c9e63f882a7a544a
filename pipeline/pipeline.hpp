// Pipeline: the runtime behind every augrig command that moves frames (run, demo's window,
// replay). One stereo frame's path (pipeline.cpp's Run::process()):
//
//   source    a StereoSource (capture thread per source, bounded queues, pairing) over any
//             FrameSource by URI (sources.hpp): sim://, replay://, euroc://, aravis://, v4l2://
//   pose      a PoseProvider (poses.hpp): the receiver's pose at the frame's mid-exposure, with a
//             verdict (good, stale, none) in plain words
//   boom      the BoomStage (boom_stage.hpp): the source's boom, fixed, scripted, tracking the
//             receptacle, or the operator's
//   augment   the Augmenter: masks, receiver depth, the boom composited, occlusion statistics
//   sinks     FrameSinks (frame_sink.hpp), each optional: the recorder, stats.csv, per-frame
//             images, a command's own output, the network live view (net::FoxgloveServer), the
//             live window's mailbox (LiveView), and any from the registry (a video file); the
//             run's summary is the PipelineReport (report.hpp)
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
#include "pipeline/camera_clock_online.hpp"
#include "pipeline/frame_sink.hpp"
#include "pipeline/live_view.hpp"
#include "pipeline/nav_inputs.hpp"
#include "pipeline/outputs.hpp"
#include "pipeline/poses.hpp"
#include "pipeline/report.hpp"
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
  // Each camera's clock estimated online (camera_clock_online.hpp; `run --camera-clock online`): fed
  // every pair read, shown in the HUD and the health, its changes and fits recorded as events.
  CameraClocks* camera_clocks = nullptr;
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
  // More outputs (sinks/registry.hpp: a video file, ...), after the ones above (frame_sink.hpp
  // gives the order).
  std::vector<std::unique_ptr<FrameSink>> sinks;
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
  class Run;  // one run's state and stages (pipeline.cpp)
  PipelineParts parts_;
};

}  // namespace augrig::pipeline
