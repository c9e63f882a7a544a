#include "pipeline/pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <iomanip>
#include <sstream>
#include <thread>

#include "core/clock.hpp"
#include "pipeline/look_stage.hpp"
#include "pipeline/look_updates.hpp"
#include "pipeline/sinks/sinks.hpp"
#include "recorder/plot.hpp"
#include "recorder/replay_source.hpp"
#include "render/gl_context.hpp"

namespace augrig::pipeline {

namespace {

using SteadyClock = std::chrono::steady_clock;

std::string fmt_us(std::int64_t ns) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << static_cast<double>(ns) / 1e3;
  return s.str();
}

bool same_counts(const OcclusionStats& a, const OcclusionStats& b) {
  return a.receiver_px_left == b.receiver_px_left && a.receiver_px_right == b.receiver_px_right &&
         a.boom_px_left == b.boom_px_left && a.boom_px_right == b.boom_px_right &&
         a.boom_overlap_px == b.boom_overlap_px && a.occluded_px_left == b.occluded_px_left &&
         a.occluded_px_right == b.occluded_px_right && a.stereo_both_px == b.stereo_both_px &&
         a.left_only_px == b.left_only_px && a.right_only_px == b.right_only_px &&
         a.neither_px == b.neither_px;
}

// A recording's frame: what was recorded with it (null for other sources).
const recorder::RecordedFrame* recorded(const StereoFrame& f) {
  return f.left.attachment ? f.left.attachment->recorded() : nullptr;
}
// Where the pair lies in its file (a recording's frame, a dataset's pair); none for others.
std::optional<SourcePosition> position(const StereoFrame& f) {
  return f.left.attachment ? f.left.attachment->position() : std::nullopt;
}

}  // namespace

// ---- The pipeline ------------------------------------------------------------------------------

Pipeline::Pipeline(PipelineParts parts) : parts_(std::move(parts)) {}
Pipeline::~Pipeline() = default;

// One run: the stages and the state between pairs. run() is prepare(), read_until_stop(),
// drain_after_stop(), finish(); a pair's path is process().
class Pipeline::Run {
 public:
  Run(PipelineParts& p, std::ostream& out, std::ostream& err)
      : p_(p),
        out_(out),
        err_(err),
        boom_(p.rig, p.models.receptacle_m, p.boom, p.boom_dims),
        boom_default_track_(!p.boom) {}

  Status prepare();
  void read_until_stop();
  void drain_after_stop();
  Expected<PipelineReport> finish();

 private:
  // Setting up.
  Status make_augmenter();
  Status start_source();
  void find_origin();
  void find_phases();
  void make_sinks();
  // One pair.
  void process(StereoFrame& frame);
  bool check_first(const StereoFrame& frame);
  bool pose(const StereoFrame& frame, TimestampNs mid_l, TimestampNs t_in);
  bool augment(StereoFrame& frame, SceneState& scene);
  void count(const StereoFrame& frame);
  void capture(StereoFrame& frame, TimestampNs mid_l, TimestampNs mid_host, TimestampNs t_in);
  void to_sinks(PairContext& pair, TimestampNs t_sinks);
  TimestampNs mid_host_ns(const Frame& f) const;
  // Between pairs.
  bool should_stop();
  void read_one();
  void note_camera_health();
  void exchange_with_view();
  void hud();
  void every_second();
  void progress_line();
  void status_line();
  void health();
  // Events: printed, and to every sink.
  void log_event(const std::string& text);
  void camera_clock_events();
  void sink_event(TimestampNs t_ns, ClockDomain clock, const std::string& text);
  void note_phase(const StereoFrame& frame, TimestampNs t_ns);
  void problem(const Error& e);

  PipelineParts& p_;
  std::ostream& out_;
  std::ostream& err_;
  PipelineReport rep_;
  std::unique_ptr<GlContext> gl_;
  std::unique_ptr<Augmenter> augmenter_;
  std::unique_ptr<LookStage> look_;
  LookUpdates look_updates_;  // what the look learns, for the recording's `look` table
  BoomStage boom_;
  // Without a boom of the user's, tracking is the default whenever the poses carry no boom of their
  // own; a pose source with a boom (a scene, a recording) keeps it until the user says otherwise.
  bool boom_default_track_;
  StereoSource* source_ = nullptr;
  recorder::ReplaySource* replay_ = nullptr;
  std::vector<std::unique_ptr<FrameSink>> sinks_;  // in the order a pair meets them
  RecorderSink* recorder_ = nullptr;               // among them: the window pauses it
  SinkNeeds needs_;                                // what any of them needs
  StereoResult result_;
  std::optional<Error> fatal_;
  // Between pairs.
  bool paused_ = false, was_stale_ = false, first_ = true, duration_reached_ = false, end_of_stream_ = false;
  TimestampNs first_t_ns_ = 0;
  std::optional<TimestampNs> source_origin_ns_;  // a scripted boom's t = 0 (find_origin)
  std::vector<TimestampNs> sim_offsets_;         // the simulation's cameras' clock offsets
  std::vector<ClockOffsetLog> clocks_;
  std::vector<std::string> last_health_;
  FramePoses poses_;
  PipelineCommands pending_;
  std::optional<std::size_t> seek_target_;  // replay: pairs before it are passed over
  // replay: the recording's time span and the pair last augmented, for the timeline.
  TimestampNs replay_first_ns_ = 0, replay_last_ns_ = 0, shown_t_key_ns_ = 0;
  std::size_t shown_index_ = 0;
  int shown_pass_ = 0;
  std::string phase_;              // the flight's phase at the last pair (PipelineParts::phase_of)
  TimestampNs last_t_key_ns_ = 0;  // the last pair's, for the health messages' stamps
  SteadyClock::time_point t0_, next_status_, next_clocks_, next_progress_, next_health_;
};

Expected<PipelineReport> Pipeline::run(std::ostream& out, std::ostream& err) {
  Run run(parts_, out, err);
  if (Status st = run.prepare(); !st) return st.error();
  run.read_until_stop();
  run.drain_after_stop();
  return run.finish();
}

// ---- Setting up --------------------------------------------------------------------------------

Status Pipeline::Run::prepare() {
  if (!p_.capture_only && !p_.rig.boom.configured)
    return make_error(p_.rig.source,
                      ": no boom section: a capture-only rig (its cameras can be recorded, e.g. augrig run "
                      "--capture-only); augmenting needs a rig with boom: {pivot_body_m, limits} "
                      "(docs/RIG_FORMAT.md; give one with --rig)");
  if (!p_.capture_only && !p_.poses) return make_error("pipeline::Pipeline::run(): no pose source");
  if (Status st = make_augmenter(); !st) return st;
  if (Status st = start_source(); !st) return st;
  last_health_.resize(source_->sources().size());
  // The simulation's cameras are calibrated to GPS time (their offsets are known).
  if (p_.source_info.sim) {
    sim_offsets_ = p_.source_info.sim->scenario.sensors.cameras.clock_offset_ns;
    sim_offsets_.resize(2, 0);
  }
  replay_ = p_.source_info.replay;
  find_origin();
  find_phases();
  make_sinks();
  t0_ = SteadyClock::now();
  next_status_ = t0_ + std::chrono::duration_cast<SteadyClock::duration>(
                           std::chrono::duration<double>(p_.status_every_s));
  next_clocks_ = t0_;
  next_progress_ = next_health_ = t0_ + std::chrono::seconds(1);
  return {};
}

// The augmenter (and its GL context) on this thread, and the camera look's sun and noise. Only
// the boxes the boom changes are made: the recorder stores no more; sinks that need whole images
// have them made (PairContext::make_whole).
Status Pipeline::Run::make_augmenter() {
  LookConfig look_config;
  look_config.look = p_.augment.look;
  look_config.cameras = p_.augment.camera_looks;
  look_config.cameras.resize(p_.rig.cameras.size());
  look_config.synchronous = !p_.source_info.live;  // cameras: estimated beside the pipeline
  look_ = std::make_unique<LookStage>(look_config);
  if (p_.capture_only) return {};
  auto gl_or = create_gl_context(GlBackend::kEglHeadless);
  if (!gl_or) return make_error("cannot create an OpenGL context (EGL headless): ", gl_or.error().message);
  gl_ = std::move(*gl_or);
  AugmentOptions aug_options = p_.augment;
  aug_options.receiver_model = p_.models.receiver_model;
  if (p_.models.boom_model) aug_options.boom_model = p_.models.boom_model;
  aug_options.augmented_output = AugmentedOutput::kChangedBox;
  auto augmenter_or = Augmenter::create(p_.rig, aug_options);
  if (!augmenter_or) return augmenter_or.error();
  augmenter_ = std::move(*augmenter_or);
  rep_.rasterizer = augmenter_->rasterizer();
  return look_->configure(*augmenter_);
}

// A source given unstarted starts once the augmenter is ready, after one augmentation of a blank
// pair (buffers, worker threads): the first real pair then finds the pipeline ready instead of
// the cameras' queues filling behind it.
Status Pipeline::Run::start_source() {
  if (!p_.source) {
    if (augmenter_) {
      StereoFrame blank;
      for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
        const CameraModel& m = p_.rig.cameras[static_cast<std::size_t>(index_of(id))].model;
        blank[id].image = Image(m.width_px, m.height_px, PixelFormat::kRGB8);
        blank[id].camera = id;
      }
      StereoResult warm;
      (void)augmenter_->augment(blank, SceneState{BoomArticulation{}, Pose::identity(), false, {}, {}}, warm);
    }
    if (!p_.unstarted_source) return make_error("pipeline::Pipeline::run(): no source");
    auto started = start_stereo(std::move(*p_.unstarted_source));
    p_.unstarted_source.reset();
    if (!started) return started.error();
    p_.source = std::move(*started);
  }
  source_ = p_.source.get();
  return {};
}

// A scripted boom's t = 0: a recording's or a EuRoC folder's own first frame, so that a run that
// starts later in it (--from-frame, --seek, one part of a campaign) flies the boom where the whole
// run would at each frame; else (live, simulated) the first frame processed. A recording's time
// span, for the window's timeline.
void Pipeline::Run::find_origin() {
  if (replay_) {
    source_origin_ns_ = replay_->first_t_ns();
    bool any = false;
    for (const auto& t : replay_->frame_times())
      if (t) {
        if (!any) replay_first_ns_ = *t;
        replay_last_ns_ = *t;
        any = true;
      }
  } else if (source_->sources().size() == 1) {
    source_origin_ns_ = source_->sources().front()->origin_t_ns();
  }
}

// The flight's phases when the command gave none: the simulation's, or those recorded in the
// recording replayed (each pair in the phase its recorded statistics' time lies in).
void Pipeline::Run::find_phases() {
  if (!p_.phase_of && p_.source_info.sim)
    p_.phase_of = sim_phases(sim::frame_truths(p_.source_info.sim->scenario, *p_.source_info.sim->flight,
                                               p_.source_info.sim->logs.cameras));
  if (p_.phase_of || !replay_) return;
  auto events = replay_->reader().events();
  if (!events) return;
  auto phases = recorder::phase_events(*events);
  if (phases.empty()) return;
  p_.phase_of = [phases = std::move(phases)](const StereoFrame& frame) -> std::string {
    const recorder::RecordedFrame* rf = recorded(frame);
    const TimestampNs t = rf && rf->record.stats ? rf->record.stats->t_ns : frame.t_key_ns;
    const auto after =
        std::upper_bound(phases.begin(), phases.end(), t,
                         [](TimestampNs v, const recorder::PhaseEvent& e) { return v < e.t_ns; });
    return after == phases.begin() ? std::string() : std::prev(after)->name;
  };
}

// The parts' outputs as sinks, in the order a pair meets them: those reading the changed boxes
// first (the files, the command's own output, the network view, the recorder, then the registry's),
// those that need whole images after them (the registry's, then the window).
void Pipeline::Run::make_sinks() {
  if (p_.stats_csv) sinks_.push_back(make_stats_sink(std::move(p_.stats_csv)));
  if (p_.frame_files) sinks_.push_back(make_frame_files_sink(std::move(*p_.frame_files), p_.rig));
  if (p_.on_pair) sinks_.push_back(make_callback_sink(std::move(p_.on_pair)));
  if (p_.serve) sinks_.push_back(make_foxglove_sink(p_.serve));
  if (p_.recorder) {
    auto rec = std::make_unique<RecorderSink>(*p_.recorder, p_.rig, p_.record_ground_truth, p_.nav_inputs);
    recorder_ = rec.get();
    sinks_.push_back(std::move(rec));
  }
  for (auto& sink : p_.sinks) sinks_.push_back(std::move(sink));
  p_.sinks.clear();
  if (p_.view) sinks_.push_back(make_view_sink(p_.view));
  std::stable_partition(sinks_.begin(), sinks_.end(), [](const auto& s) { return !s->needs().whole_images; });
  for (const auto& s : sinks_) {
    const SinkNeeds n = s->needs();
    needs_.whole_images |= n.whole_images;
    needs_.look_updates |= n.look_updates;
    needs_.health |= n.health;
  }
}

// ---- One pair ----------------------------------------------------------------------------------

// One stereo pair through pose, boom, augmentation and the sinks.
void Pipeline::Run::process(StereoFrame& frame) {
  if (first_ && !check_first(frame)) return;
  last_t_key_ns_ = frame.t_key_ns;
  const TimestampNs mid_l = mid_host_ns(frame.left), mid_r = mid_host_ns(frame.right);
  const TimestampNs mid_host = mid_l && mid_r ? std::min(mid_l, mid_r) : 0;  // the earlier: not flattered

  // Time per stage, for the summary: from the later frame's arrival to here (capture queues and
  // pairing; only for frames stamped on this host's clock), then each stage.
  const TimestampNs t_in = monotonic_now_ns();
  const TimestampNs arrived = std::max(frame.left.t_host_ns, frame.right.t_host_ns);
  if (arrived > 0 && t_in >= arrived && t_in - arrived < 10'000'000'000) rep_.stage_queue.add(t_in - arrived);
  // The camera clocks' frames are copied to their workers, or skipped when they are busy.
  if (p_.camera_clocks) p_.camera_clocks->offer(frame, mid_l, mid_r);
  if (p_.capture_only) return capture(frame, mid_l, mid_host, t_in);

  // 1. The pose (none: the pair is skipped, or augmented with the boom alone).
  if (!pose(frame, mid_l, t_in)) return;
  SceneState& scene = *poses_.scene;

  // 2. The boom, and the camera look's light and noise for this pair.
  if (boom_default_track_) {
    boom_.set_mode(poses_.boom_given ? DisplayBoomMode::kFixed : DisplayBoomMode::kTrackReceptacle);
    boom_default_track_ = false;
  }
  boom_.apply(scene, ns_to_s(frame.left.t_ns - first_t_ns_));
  for (const std::string& note : look_->before_augment(frame, scene, *augmenter_)) log_event(note);

  // 3. The augmentation.
  const TimestampNs t_aug = monotonic_now_ns();
  if (!augment(frame, scene)) return;
  const TimestampNs t_sinks = monotonic_now_ns();
  rep_.stage_augment.add(t_sinks - t_aug);
  std::vector<recorder::LookRecord> updates;
  if (needs_.look_updates) updates = look_updates_.take(*look_, *augmenter_, frame, scene.light);
  count(frame);

  // 4. The sinks.
  PairContext pair{frame,   &result_,           &scene,  poses_, rep_.pairs, mid_host, position(frame),
                   paused_, replay_ != nullptr, &updates};
  to_sinks(pair, t_sinks);
}

// A configuration that cannot work fails at the first pair, once, before anything is augmented.
bool Pipeline::Run::check_first(const StereoFrame& frame) {
  first_ = false;
  first_t_ns_ = source_origin_ns_.value_or(frame.left.t_ns);
  if (p_.on_first_frame) p_.on_first_frame(frame);
  for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
    const Image& im = frame[id].image;
    const RigCamera& cam = p_.rig.cameras[static_cast<std::size_t>(index_of(id))];
    if (im.width() == cam.model.width_px && im.height() == cam.model.height_px) continue;
    // A recording's frames name its file; an MCAP file's (recorded frames too, no reader) its URI.
    const std::optional<SourcePosition> at = replay_ ? position(frame) : std::nullopt;
    fatal_ = make_error(at ? replay_->reader().path() : source_->uri(), ": frame ",
                        at ? at->index : frame.pair_sequence, ": the ", to_string(id), " image is ",
                        im.width(), "x", im.height(), ", the rig's ", cam.name, " camera is ",
                        cam.model.width_px, "x", cam.model.height_px, " (", p_.rig.source,
                        "; give the rig that matches the images, or set the cameras' size)");
    return false;
  }
  return true;
}

// The receiver's pose at the left camera's mid-exposure. Without one the pair is skipped (false),
// or still shown and recorded: the boom alone, the receiver left out of the masks, the pair marked.
bool Pipeline::Run::pose(const StereoFrame& frame, TimestampNs mid_l, TimestampNs t_in) {
  poses_ = p_.poses->at(frame, mid_l);
  rep_.stage_pose.add(monotonic_now_ns() - t_in);
  bool stale = poses_.stale;
  if (!poses_.scene) {
    ++rep_.no_pose_pairs;
    stale = true;
    if (p_.skip_frames_without_pose) {
      if (rep_.skipped_no_pose++ < 5)
        problem(make_error(poses_.problems.empty()
                               ? "pair " + std::to_string(frame.pair_sequence) + ": no pose"
                               : poses_.problems.front(),
                           "; not augmented"));
      return false;
    }
    poses_.scene = SceneState{BoomArticulation{}, Pose::identity(), false, {}, {}};
  }
  if (stale) ++rep_.stale_pairs;
  if (stale != was_stale_) {
    std::ostringstream e;
    e << (p_.poses->live() ? "nav " : "pose ") << (stale ? "stale" : "good again") << " from pair "
      << frame.pair_sequence << " (t_ns " << frame.t_key_ns << ")";
    if (stale && !poses_.problems.empty()) e << ": " << poses_.problems.front();
    log_event(e.str());
    was_stale_ = stale;
  }
  return true;
}

// The augmenter's masks, depth, composite and statistics; a failure is counted (the ledger) and
// the run goes on.
bool Pipeline::Run::augment(StereoFrame& frame, SceneState& scene) {
  const Status augmented = augmenter_->augment(frame, scene, result_);
  if (augmented) {
    look_->after_augment(frame, scene, result_, p_.rig);
    return true;
  }
  ++rep_.failed_pairs;
  rep_.failed_t.add(frame.t_key_ns);
  problem(make_error("pair ", frame.pair_sequence, ": ", augmented.error().message));
  return false;
}

// The augmented pair in the report: its statistics, the flight's phase, whether a replay
// reproduced the recorded statistics, and where the window's timeline stands.
void Pipeline::Run::count(const StereoFrame& frame) {
  rep_.augment_ms += augmenter_->timings().total_ms;
  result_.stats.t_ns = poses_.t_nav_ns.value_or(frame.t_key_ns);
  ++rep_.pairs;
  rep_.summary.add(result_.stats);
  rep_.last_stats = result_.stats;
  if (p_.keep_all_stats) rep_.all_stats.push_back(result_.stats);
  note_phase(frame, result_.stats.t_ns);
  if (const recorder::RecordedFrame* rf = recorded(frame); rf && rf->record.stats) {
    ++rep_.comparable;
    rep_.reproduced += same_counts(result_.stats, *rf->record.stats);
  }
  if (const std::optional<SourcePosition> at = position(frame)) {
    shown_index_ = at->index;
    shown_pass_ = at->pass;
    shown_t_key_ns_ = frame.t_key_ns;
  }
}

// Captured only: the pair, with its poses where there is a pose source, to the sinks; nothing
// augmented.
void Pipeline::Run::capture(StereoFrame& frame, TimestampNs mid_l, TimestampNs mid_host, TimestampNs t_in) {
  poses_ = p_.poses ? p_.poses->at(frame, mid_l) : FramePoses{};
  if (p_.poses && !poses_.scene) ++rep_.no_pose_pairs;
  const TimestampNs t_sinks = monotonic_now_ns();
  rep_.stage_pose.add(t_sinks - t_in);
  ++rep_.pairs;
  note_phase(frame, poses_.t_nav_ns.value_or(frame.t_key_ns));
  PairContext pair{frame,           nullptr,    poses_.scene ? &*poses_.scene : nullptr,
                   poses_,          rep_.pairs, mid_host,
                   position(frame), paused_,    replay_ != nullptr,
                   nullptr};
  to_sinks(pair, t_sinks);
}

// Every sink consumes the pair, then releases it (frame_sink.hpp); a sink's error stops the run.
void Pipeline::Run::to_sinks(PairContext& pair, TimestampNs t_sinks) {
  for (const auto& sink : sinks_)
    if (Status st = sink->consume(pair); !st) {
      fatal_ = st.error();
      return;
    }
  for (const auto& sink : sinks_) sink->release(pair);
  // Headless: the hand-off is as far as a frame goes.
  if (!p_.view && pair.mid_host_ns) rep_.display_latency.add(monotonic_now_ns() - pair.mid_host_ns);
  rep_.stage_sinks.add(monotonic_now_ns() - t_sinks);
}

// Each camera's mid-exposure on the host clock: the simulation's own clock, the estimated
// device-to-host offset, or the kernel's host timestamp (0: unknown, e.g. replay).
TimestampNs Pipeline::Run::mid_host_ns(const Frame& f) const {
  if (p_.source_info.sim_clock && p_.source_info.sim_clock->paced())
    return p_.source_info.sim_clock->host_ns(f.t_ns - sim_offsets_[index_of(f.camera)]);
  if (f.attachment && f.attachment->recorded())
    return f.attachment->due_host_ns();  // a paced replay: when the frame was due (0: not paced)
  if (f.clock == ClockDomain::kHostMonotonic) return f.t_ns;
  if (f.clock == ClockDomain::kDevice)
    for (const ClockOffsetLog& c : clocks_)
      if (c.camera == f.camera && c.samples) return f.t_ns + c.offset_ns;
  return 0;
}

// ---- Between pairs -----------------------------------------------------------------------------

// Reads pairs until a stop condition: the source ends or fails, the duration or the pair count is
// reached, a signal, the window closed, a sink failed.
void Pipeline::Run::read_until_stop() {
  while (!should_stop()) {
    read_one();
    if (rep_.source_failed) break;
    if (p_.view) exchange_with_view();
    if (recorder_)
      if (std::optional<std::string> failed = recorder_->newly_failed())
        // Disk full or a write error: the recording ends valid with what it holds; the run goes on.
        out_ << "  recording stopped: " << *failed << " (what was recorded stays valid; the run goes on)\n";
    every_second();
  }
}

bool Pipeline::Run::should_stop() {
  if (fatal_ || rep_.window_closed || rep_.source_failed || end_of_stream_) return true;
  if (p_.stop_flag && p_.stop_flag->load()) {
    rep_.stopped_by_signal = true;
    out_ << "run: stopped by signal\n";
    return true;
  }
  if (p_.duration_s > 0 && std::chrono::duration<double>(SteadyClock::now() - t0_).count() >= p_.duration_s) {
    duration_reached_ = true;
    return true;
  }
  return p_.max_pairs && rep_.pairs >= p_.max_pairs;
}

// One read (up to 200 ms) and its pair processed; a paused replay reads nothing until a step or
// a seek. A recorded pair keeps its recorded key, skew and sequence.
void Pipeline::Run::read_one() {
  StereoFrame frame;
  Expected<ReadStatus> r = ReadStatus::kTimeout;
  if (replay_ && paused_ && pending_.steps == 0 && !seek_target_)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  else
    r = source_->read(frame, std::chrono::milliseconds(200));
  note_camera_health();
  if (!r) {
    rep_.source_failed = true;
    rep_.source_error = r.error().message;
    problem(r.error());
    return;
  }
  for (const std::string& e : source_->take_errors()) problem(Error{e});
  if (*r == ReadStatus::kEndOfStream) end_of_stream_ = true;
  if (*r != ReadStatus::kFrame) return;
  if (const std::optional<RecordedPairing> k = frame.left.attachment ? frame.left.attachment->recorded_pairing()
                                                                      : std::nullopt) {
    frame.t_key_ns = k->t_key_ns;
    frame.skew_ns = k->skew_ns;
    frame.pair_sequence = k->pair_sequence;
  }
  const std::optional<SourcePosition> at = position(frame);
  if (seek_target_ && at && at->index != *seek_target_) {
    ++rep_.seek_skipped_pairs;  // read ahead before the seek
    return;
  }
  seek_target_.reset();
  if (pending_.steps > 0) --pending_.steps;
  process(frame);
}

// Camera state changes are events: printed, and recorded with the frames.
void Pipeline::Run::note_camera_health() {
  const std::vector<SourceHealth> health = source_->health();
  for (std::size_t i = 0; i < health.size(); ++i)
    if (health[i].message != last_health_[i]) {
      if (!last_health_[i].empty() || !health[i].connected) log_event(health[i].message);
      last_health_[i] = health[i].message;
    }
}

// The HUD to the window, and the window's commands: quit, pause, recording, boom, and for a
// replay seek, rate and steps.
void Pipeline::Run::exchange_with_view() {
  hud();
  const PipelineCommands c = p_.view->take_commands();
  if (c.quit) rep_.window_closed = true;
  if (c.toggle_pause) {
    paused_ = !paused_;
    if (replay_) replay_->set_paused(paused_);
  }
  if (c.toggle_recording && recorder_) {
    recorder_->set_on(!recorder_->on());
    log_event(recorder_->on() ? "recording resumed" : "recording paused");
  }
  if (c.boom_mode) boom_.set_mode(*c.boom_mode);
  if (c.boom_nudge.any()) boom_.nudge(c.boom_nudge);
  if (c.boom_mode || c.boom_nudge.any()) boom_default_track_ = false;
  if (!replay_) return;
  if (c.seek_frame && *c.seek_frame < replay_->frame_count())
    if (Status st = replay_->seek_frame(*c.seek_frame); st) {
      seek_target_ = *c.seek_frame;
      if (paused_) replay_->step(1);
    }
  if (c.rate)
    if (Status st = replay_->set_rate(*c.rate); !st) problem(st.error());
  if (c.steps > 0 && paused_) {
    replay_->step(static_cast<std::size_t>(c.steps));
    pending_.steps += c.steps;
  }
}

void Pipeline::Run::hud() {
  const StereoSourceStats st = source_->stats();
  const double t = std::max(1e-9, std::chrono::duration<double>(SteadyClock::now() - t0_).count());
  HudState hud;
  hud.fps = {st.frames[0] / t, st.frames[1] / t};
  if (st.pairing.skew.count) {
    hud.skew_p50_ms = st.pairing.skew.p50_abs_ns() / 1e6;
    hud.skew_p99_ms = st.pairing.skew.p99_abs_ns() / 1e6;
  }
  hud.drops = {st.camera_drops, st.transport_drops, st.pairing.unpaired_left + st.pairing.unpaired_right,
               st.queue_drops[0] + st.queue_drops[1] + rep_.failed_pairs * 2,
               recorder_ ? recorder_->frames_dropped() : 0};
  hud.nav = poses_.hud;
  if (p_.camera_clocks)
    for (const CameraClockOnlineStatus& c : p_.camera_clocks->status()) hud.camera_clocks.push_back(c.hud_text());
  for (const std::string& m : poses_.problems) hud.messages.push_back(m);
  hud.stale_pose = was_stale_;
  hud.occlusion = rep_.last_stats;
  hud.paused = paused_;
  hud.boom_mode = boom_.mode();
  if (recorder_) {
    hud.latency_recorder = recorder_->latency();
    hud.recording = recorder_->on();
    hud.recording_path = recorder_->path();
    if (p_.recorder && !p_.recorder->status())
      hud.messages.push_back("recording stopped: " + p_.recorder->status().error().message);
  }
  for (const SourceHealth& h : source_->health())
    if (!h.connected) hud.messages.push_back(h.message);
  std::optional<Playback> pb;
  if (replay_) {
    Playback b;
    b.frame_count = replay_->frame_count();
    b.frame = shown_index_;
    b.pass = shown_pass_;
    b.t_s = shown_t_key_ns_ ? ns_to_s(shown_t_key_ns_ - replay_first_ns_) : 0;
    b.duration_s = ns_to_s(replay_last_ns_ - replay_first_ns_);
    b.rate = replay_->rate();
    pb = b;
  }
  p_.view->set_hud(std::move(hud), pb);
}

// What runs on a clock rather than per pair: the clock estimates, the progress line, the
// sinks' health, the status line.
void Pipeline::Run::every_second() {
  const auto now = SteadyClock::now();
  if (now >= next_clocks_) {
    next_clocks_ += std::chrono::seconds(1);
    clocks_ = source_->stats().clocks;
    camera_clock_events();
  }
  if (p_.progress_total && !p_.view && now >= next_progress_) {
    next_progress_ += std::chrono::seconds(1);
    progress_line();
  }
  if (needs_.health && now >= next_health_) {
    next_health_ += std::chrono::seconds(1);
    health();
  }
  if (p_.status_every_s > 0 && now >= next_status_) {
    next_status_ +=
        std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(p_.status_every_s));
    status_line();
  }
}

// "N of M pairs, X/s, ETA".
void Pipeline::Run::progress_line() {
  const double t = std::chrono::duration<double>(SteadyClock::now() - t0_).count();
  const std::uint64_t done = rep_.pairs + rep_.failed_pairs + rep_.skipped_no_pose;
  const double rate = done / std::max(t, 1e-9);
  out_ << "  " << done << " of " << p_.progress_total << " pairs, " << std::fixed << std::setprecision(1)
       << rate << "/s";
  if (rate > 0 && done < p_.progress_total) {
    const auto eta_s = static_cast<long long>((p_.progress_total - done) / rate + 0.5);
    out_ << ", ETA " << (eta_s >= 60 ? std::to_string(eta_s / 60) + " min " : "") << eta_s % 60 << " s";
  }
  out_ << std::endl;
}

// The status line, the look's state and each camera clock's estimate (the last two kept, not shown).
void Pipeline::Run::status_line() {
  const StereoSourceStats st = source_->stats();
  const double t = std::chrono::duration<double>(SteadyClock::now() - t0_).count();
  out_ << "  t " << std::fixed << std::setprecision(1) << t << " s: " << rep_.pairs << " pairs ("
       << std::setprecision(1) << rep_.pairs / std::max(t, 1e-9) << "/s), skew p50/p99 "
       << fmt_us(st.pairing.skew.p50_abs_ns()) << "/" << fmt_us(st.pairing.skew.p99_abs_ns())
       << " us, drops camera " << st.camera_drops << " transport " << st.transport_drops << " pairing "
       << st.pairing.unpaired_left + st.pairing.unpaired_right << " queue "
       << st.queue_drops[0] + st.queue_drops[1] << "\n";
  if (look_->look() == Look::kCamera) {
    out_ << "    " << look_->status() << "\n";
    sink_event(monotonic_now_ns(), ClockDomain::kHostMonotonic, look_->status());
  }
  for (const ClockOffsetLog& c : st.clocks) {
    std::ostringstream e;
    e << "clock_offset camera=" << to_string(c.camera) << " t_device_ns=" << c.t_device_ns
      << " offset_ns=" << c.offset_ns << " drift_ppm=" << std::setprecision(3) << c.drift_ppm
      << " uncertainty_ns=" << c.uncertainty_ns << " samples=" << c.samples << " resets=" << c.resets;
    sink_event(c.t_host_ns, ClockDomain::kHostMonotonic, e.str());
  }
}

// The run's health to the sinks that show it: rate, cameras, pose, recording, drops.
void Pipeline::Run::health() {
  RunHealth h;
  h.pairs = rep_.pairs;
  h.failed_pairs = rep_.failed_pairs;
  h.stale_pairs = rep_.stale_pairs;
  h.source = source_->stats();
  h.cameras = source_->health();
  h.pose_shown = !p_.capture_only || p_.poses;
  h.pose_stale = was_stale_;
  if (was_stale_ && !poses_.problems.empty()) h.pose_problem = poses_.problems.front();
  if (recorder_) {
    h.recording = recorder_->state();
    h.recorder_dropped = recorder_->frames_dropped();
  }
  h.pair_t_key_ns = last_t_key_ns_;
  if (p_.camera_clocks) {
    h.camera_clock_values = p_.camera_clocks->diagnostics();
    for (const CameraClockOnlineStatus& c : p_.camera_clocks->status()) h.camera_clocks.push_back(c.text());
  }
  for (const auto& sink : sinks_)
    if (sink->needs().health) sink->health(h);
}

// The online camera clocks: a state change (collecting, not observable, estimated, applied) is an
// event printed and recorded; each new fit is recorded ("camera_clock camera=left ...").
void Pipeline::Run::camera_clock_events() {
  if (!p_.camera_clocks) return;
  for (const std::string& change : p_.camera_clocks->take_changes()) log_event(change);
  for (const std::string& line : p_.camera_clocks->take_record_lines())
    sink_event(monotonic_now_ns(), ClockDomain::kHostMonotonic, line);
}

void Pipeline::Run::log_event(const std::string& text) {
  out_ << "  " << text << "\n";
  SinkEvent e{monotonic_now_ns(), ClockDomain::kHostMonotonic, text, true, last_t_key_ns_};
  for (const auto& sink : sinks_) sink->event(e);
}

// An event kept by the sinks (recorded), not shown as the run's health.
void Pipeline::Run::sink_event(TimestampNs t_ns, ClockDomain clock, const std::string& text) {
  SinkEvent e{t_ns, clock, text, false, last_t_key_ns_};
  for (const auto& sink : sinks_) sink->event(e);
}

// A new phase of the flight: an event at the pair's statistics time (`t_ns`, on the nav clock
// where the poses map frames onto it), so that plots can mark it.
void Pipeline::Run::note_phase(const StereoFrame& frame, TimestampNs t_ns) {
  if (!p_.phase_of) return;
  std::string phase = p_.phase_of(frame);
  if (phase.empty() || phase == phase_) return;
  phase_ = std::move(phase);
  out_ << "  phase: " << phase_ << " from pair " << frame.pair_sequence << " (t_ns " << t_ns << ")\n";
  sink_event(t_ns, poses_.t_nav_ns ? ClockDomain::kGps : frame.left.clock, "phase: " + phase_);
}

void Pipeline::Run::problem(const Error& e) {
  if (p_.on_problem)
    p_.on_problem(e);
  else
    err_ << "pipeline: " << e.message << "\n";
}

// ---- Stopping ----------------------------------------------------------------------------------

// Stopped by the duration, a signal or the window on a live source: capture stops, and what the
// cameras had already delivered still goes through (the pairs in the queues and the pairer), so
// that only frames whose partner never came stay pending. A frame limit stops exactly there; a
// lossless (finite) source's read-ahead stays pending, as it is still in its file.
void Pipeline::Run::drain_after_stop() {
  if (fatal_ || !(duration_reached_ || rep_.stopped_by_signal || rep_.window_closed) || source_->lossless())
    return;
  source_->stop();
  StereoFrame frame;
  for (Expected<ReadStatus> r = source_->read(frame, std::chrono::nanoseconds(0));
       !fatal_ && r && *r == ReadStatus::kFrame; r = source_->read(frame, std::chrono::nanoseconds(0))) {
    process(frame);
    ++rep_.pairs_after_stop;
  }
}

// The source and the nav stopped, the report's counts final, then every sink closed (the
// recorder's drop ledger: every frame is accounted for).
Expected<PipelineReport> Pipeline::Run::finish() {
  source_->stop();
  if (p_.on_stop) p_.on_stop();
  if (p_.nav_inputs) p_.nav_inputs->stop();
  camera_clock_events();
  rep_.wall_s = std::chrono::duration<double>(SteadyClock::now() - t0_).count();
  rep_.source = source_->stats();
  for (std::size_t i = 0; i < source_->sources().size(); ++i) {
    const SourceHealth h = source_->health()[i];
    if (!h.connected)
      rep_.lost_cameras.push_back(source_->sources()[i]->uri() + " was lost and never came back (" +
                                  h.message + ")");
  }
  for (const auto& sink : sinks_)
    if (Status st = sink->close(rep_); !st && !fatal_) fatal_ = st.error();
  if (fatal_) return *fatal_;
  return rep_;
}

void Pipeline::print_summary(const PipelineReport& r, std::ostream& out) const {
  print_report(r, parts_, out);
}

}  // namespace augrig::pipeline
