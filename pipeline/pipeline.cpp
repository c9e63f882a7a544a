#include "pipeline/pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <iomanip>
#include <sstream>
#include <thread>

#include "core/clock.hpp"
#include "pipeline/look_stage.hpp"
#include "pipeline/look_updates.hpp"
#include "recorder/euroc.hpp"
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
std::string fmt_ms(double ms) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << ms;
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

// The last latencies (ms) for the HUD's p50/p99.
LatencyHud rolling_hud(std::vector<double> v) {
  LatencyHud h;
  if (v.empty()) return h;
  std::sort(v.begin(), v.end());
  h.p50_ms = v[v.size() / 2];
  h.p99_ms = v[std::min(v.size() - 1, v.size() * 99 / 100)];
  return h;
}

const recorder::RecordedFrame* recorded(const StereoFrame& f) {
  return dynamic_cast<const recorder::RecordedFrame*>(f.left.attachment.get());
}

}  // namespace

// ---- Commands and the mailbox -----------------------------------------------------------------

void PipelineCommands::merge(const PipelineCommands& o) {
  quit = quit || o.quit;
  toggle_pause = toggle_pause != o.toggle_pause;
  toggle_recording = toggle_recording != o.toggle_recording;
  if (o.boom_mode) boom_mode = o.boom_mode;
  boom_nudge.elevation_rad += o.boom_nudge.elevation_rad;
  boom_nudge.azimuth_rad += o.boom_nudge.azimuth_rad;
  boom_nudge.extension_m += o.boom_nudge.extension_m;
  steps += o.steps;
  if (o.seek_frame) seek_frame = o.seek_frame;
  if (o.rate) rate = o.rate;
}

void LiveView::publish(StereoResult& result, const SceneState& scene, TimestampNs mid_host_ns) {
  std::lock_guard lock(mutex_);
  std::swap(newest_.result, result);
  newest_.scene = scene;
  newest_.id++;
  newest_mid_host_ns_ = mid_host_ns;
  changed_.notify_all();
}

void LiveView::set_hud(HudState hud, std::optional<Playback> playback) {
  std::lock_guard lock(mutex_);
  hud.latency_display = rolling_hud(recent_ms_);
  hud_ = std::move(hud);
  playback_ = playback;
}

PipelineCommands LiveView::take_commands() {
  std::lock_guard lock(mutex_);
  PipelineCommands c = std::move(commands_);
  commands_ = {};
  return c;
}

void LiveView::finish() {
  std::lock_guard lock(mutex_);
  finished_ = true;
  changed_.notify_all();
}

bool LiveView::wait_newer(std::uint64_t shown_id, std::chrono::nanoseconds timeout) const {
  std::unique_lock lock(mutex_);
  return changed_.wait_for(lock, timeout, [&] { return newest_.id != shown_id || finished_; });
}

TimestampNs LiveView::take_newest(Shown& shown) {
  std::lock_guard lock(mutex_);
  if (newest_.id == shown.id) return 0;
  std::swap(newest_.result, shown.result);
  shown.scene = newest_.scene;
  shown.id = newest_.id;
  return newest_mid_host_ns_;
}

HudState LiveView::hud() const {
  std::lock_guard lock(mutex_);
  return hud_;
}

std::optional<Playback> LiveView::playback() const {
  std::lock_guard lock(mutex_);
  return playback_;
}

void LiveView::post(const PipelineCommands& c) {
  std::lock_guard lock(mutex_);
  commands_.merge(c);
}

bool LiveView::finished() const {
  std::lock_guard lock(mutex_);
  return finished_;
}

void LiveView::drawn(TimestampNs mid_host_ns) {
  if (mid_host_ns) add_latency(monotonic_now_ns() - mid_host_ns);
}

void LiveView::add_latency(TimestampNs ns) {
  std::lock_guard lock(mutex_);
  if (recent_ms_.size() == 300) recent_ms_.erase(recent_ms_.begin());
  recent_ms_.push_back(static_cast<double>(ns) / 1e6);
  display_hist_.add(ns);
}

LatencyHud LiveView::display_latency() const {
  std::lock_guard lock(mutex_);
  return rolling_hud(recent_ms_);
}

// ---- The pipeline ------------------------------------------------------------------------------

Pipeline::Pipeline(PipelineParts parts) : parts_(std::move(parts)) {}
Pipeline::~Pipeline() = default;

struct Pipeline::State {
  PipelineReport report;
  bool recording_on = true, paused = false, recorder_failed = false, was_stale = false;
  TimestampNs first_t_ns = 0;
  bool first = true;
  TimeSpan failed_t;  // the pairs whose augmentation failed (t_key_ns), for the ledger
  std::vector<ClockOffsetLog> clocks;
  std::vector<std::string> last_health;
  FramePoses poses;
  std::vector<double> recorder_recent_ms;
  std::optional<std::size_t> seek_target;  // replay: pairs before it are passed over
  // replay: the recording's time span and the pair last augmented, for the timeline.
  TimestampNs replay_first_ns = 0, replay_last_ns = 0, shown_t_key_ns = 0;
  std::size_t shown_index = 0;
  int shown_pass = 0;
  std::string phase;              // the flight's phase at the last pair (PipelineParts::phase_of)
  TimestampNs last_t_key_ns = 0;  // the last pair's, for the health messages' stamps
};

void Pipeline::log_event(State& s, const std::string& text, std::ostream& out) {
  out << "  " << text << "\n";
  // The network view shows each event as the health until the next status.
  if (parts_.serve) parts_.serve->publish_health(s.last_t_key_ns, net::HealthLevel::kWarn, text);
  if (parts_.recorder)
    parts_.recorder->push(recorder::EventRecord{monotonic_now_ns(), ClockDomain::kHostMonotonic, text});
}

Expected<PipelineReport> Pipeline::run(std::ostream& out, std::ostream& err) {
  PipelineParts& p = parts_;
  State s;
  PipelineReport& rep = s.report;
  s.recording_on = p.recorder != nullptr;
  BoomStage boom(p.rig, p.models.receptacle_m, p.boom, p.boom_dims);
  // Without a boom of the user's, tracking is the default whenever the poses carry no boom of their
  // own; a pose source with a boom (a scene, a recording) keeps it until the user says otherwise.
  bool boom_default_track = !p.boom;

  if (!p.capture_only && !p.rig.boom.configured)
    return make_error(p.rig.source,
                      ": no boom section: a capture-only rig (its cameras can be recorded, e.g. augrig run "
                      "--capture-only); augmenting needs a rig with boom: {pivot_body_m, limits} "
                      "(docs/RIG_FORMAT.md; give one "
                      "with --rig)");
  if (!p.capture_only && !p.poses) return make_error("pipeline::Pipeline::run(): no pose source");

  // The augmenter (and its GL context) on this thread. Only the boxes the boom changes are made:
  // the recorder stores no more; the window and the image files get whole images made for them.
  std::unique_ptr<GlContext> gl;
  std::unique_ptr<Augmenter> augmenter;
  if (!p.capture_only) {
    auto gl_or = create_gl_context(GlBackend::kEglHeadless);
    if (!gl_or) return make_error("cannot create an OpenGL context (EGL headless): ", gl_or.error().message);
    gl = std::move(*gl_or);
    AugmentOptions aug_options = p.augment;
    aug_options.receiver_model = p.models.receiver_model;
    if (p.models.boom_model) aug_options.boom_model = p.models.boom_model;
    aug_options.augmented_output = AugmentedOutput::kChangedBox;
    auto augmenter_or = Augmenter::create(p.rig, aug_options);
    if (!augmenter_or) return augmenter_or.error();
    augmenter = std::move(*augmenter_or);
    rep.rasterizer = augmenter->rasterizer();
  }
  // The camera look's sun and noise (nothing with the plain look).
  LookConfig look_config;
  look_config.look = p.augment.look;
  look_config.cameras = p.augment.camera_looks;
  look_config.cameras.resize(p.rig.cameras.size());
  look_config.synchronous = !p.source_info.live;  // cameras: estimated beside the pipeline
  LookStage look(look_config);
  LookUpdates look_updates;  // what the look learns, for the recording's `look` table
  if (augmenter)
    if (auto st = look.configure(*augmenter); !st) return st.error();
  if (!p.source) {
    // One augmentation of a blank pair first (buffers, worker threads), then the cameras start:
    // the first real pair then finds the pipeline ready instead of queues filling behind it.
    if (augmenter) {
      StereoFrame blank;
      for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
        const CameraModel& m = p.rig.cameras[static_cast<std::size_t>(index_of(id))].model;
        blank[id].image = Image(m.width_px, m.height_px, PixelFormat::kRGB8);
        blank[id].camera = id;
      }
      StereoResult warm;
      (void)augmenter->augment(blank, SceneState{BoomArticulation{}, Pose::identity(), false, {}}, warm);
    }
    if (!p.unstarted_source) return make_error("pipeline::Pipeline::run(): no source");
    auto started = start_stereo(std::move(*p.unstarted_source));
    p.unstarted_source.reset();
    if (!started) return started.error();
    p.source = std::move(*started);
  }
  StereoSource& source = *p.source;
  s.last_health.resize(source.sources().size());

  // The simulation's cameras are calibrated to GPS time (their offsets are known).
  std::vector<TimestampNs> sim_offsets;
  if (p.source_info.sim) {
    sim_offsets = p.source_info.sim->scenario.sensors.cameras.clock_offset_ns;
    sim_offsets.resize(2, 0);
  }
  recorder::ReplaySource* replay = p.source_info.replay;
  // A scripted boom's t = 0: a recording's or a EuRoC folder's own first frame, so that a run
  // that starts later in it (--from-frame, --seek, one part of a campaign) flies the boom where the
  // whole run would at each frame; else (live, simulated) the first frame processed.
  std::optional<TimestampNs> source_origin_ns;
  if (replay) {
    source_origin_ns = replay->first_t_ns();
  } else if (source.sources().size() == 1) {
    if (const auto* euroc = dynamic_cast<const recorder::EurocSource*>(source.sources().front().get()))
      source_origin_ns = euroc->first_t_ns();
  }
  if (replay) {
    bool any = false;
    for (const auto& t : replay->frame_times())
      if (t) {
        if (!any) s.replay_first_ns = *t;
        s.replay_last_ns = *t;
        any = true;
      }
  }

  // The flight's phases when the command gave none: the simulation's, or those recorded in the
  // recording replayed (each pair in the phase its recorded statistics' time lies in).
  if (!p.phase_of && p.source_info.sim)
    p.phase_of = sim_phases(sim::frame_truths(p.source_info.sim->scenario, *p.source_info.sim->flight,
                                              p.source_info.sim->logs.cameras));
  if (!p.phase_of && replay)
    if (auto events = replay->reader().events(); events)
      if (auto phases = recorder::phase_events(*events); !phases.empty())
        p.phase_of = [phases = std::move(phases)](const StereoFrame& frame) -> std::string {
          const recorder::RecordedFrame* rf = recorded(frame);
          const TimestampNs t = rf && rf->record.stats ? rf->record.stats->t_ns : frame.t_key_ns;
          const auto after =
              std::upper_bound(phases.begin(), phases.end(), t,
                               [](TimestampNs v, const recorder::PhaseEvent& e) { return v < e.t_ns; });
          return after == phases.begin() ? std::string() : std::prev(after)->name;
        };

  const auto t0 = SteadyClock::now();
  auto next_status = t0 + std::chrono::duration<double>(p.status_every_s);
  auto next_clocks = t0;
  auto next_progress = t0 + std::chrono::seconds(1);
  auto next_health = t0 + std::chrono::seconds(1);
  StereoResult result;
  std::optional<Error> fatal;

  // The run's health for the network view, once a second: rate, cameras, pose, recording, drops.
  std::uint64_t health_pairs = 0;
  auto health_t = SteadyClock::now();
  auto publish_health = [&] {
    const auto now = SteadyClock::now();
    const double dt = std::chrono::duration<double>(now - health_t).count();
    const double rate = dt > 0 ? static_cast<double>(rep.pairs - health_pairs) / dt : 0.0;
    health_pairs = rep.pairs, health_t = now;
    const StereoSourceStats st = source.stats();
    const std::uint64_t pairing = st.pairing.unpaired_left + st.pairing.unpaired_right;
    const std::uint64_t queue = st.queue_drops[0] + st.queue_drops[1];
    net::HealthLevel level = net::HealthLevel::kOk;
    std::ostringstream text;
    text << std::fixed << std::setprecision(1) << rate << " pairs/s";
    std::string cameras;
    for (std::size_t i = 0; i < s.last_health.size(); ++i)
      if (const SourceHealth h = source.health()[i]; !h.connected) {
        cameras += (cameras.empty() ? "" : "; ") + h.message;
        level = net::HealthLevel::kError;
      }
    text << "; cameras " << (cameras.empty() ? std::string("streaming") : cameras);
    if (!p.capture_only || p.poses) {
      text << "; pose " << (s.was_stale ? "stale" : "good");
      if (s.was_stale && !s.poses.problems.empty()) text << " (" << s.poses.problems.front() << ")";
      if (s.was_stale && level == net::HealthLevel::kOk) level = net::HealthLevel::kWarn;
    }
    if (p.recorder) {
      text << "; recording " << (s.recorder_failed ? "stopped" : s.recording_on ? "on" : "paused");
      if (s.recorder_failed) level = net::HealthLevel::kError;
    }
    text << "; drops: camera " << st.camera_drops << ", pairing " << pairing << ", queue " << queue;
    if (rep.pairs == 0 && level == net::HealthLevel::kOk) level = net::HealthLevel::kStale;
    p.serve->publish_health(
        s.last_t_key_ns, level, text.str(),
        {{"pairs", std::to_string(rep.pairs)},
         {"pairs_per_s", std::to_string(rate)},
         {"drops_camera", std::to_string(st.camera_drops)},
         {"drops_transport", std::to_string(st.transport_drops)},
         {"drops_pairing", std::to_string(pairing)},
         {"drops_queue", std::to_string(queue)},
         {"failed_pairs", std::to_string(rep.failed_pairs)},
         {"stale_pairs", std::to_string(rep.stale_pairs)},
         {"recorder_dropped", std::to_string(p.recorder ? p.recorder->stats().frames_dropped : 0)}});
  };

  auto problem = [&](const Error& e) {
    if (p.on_problem)
      p.on_problem(e);
    else
      err << "pipeline: " << e.message << "\n";
  };

  // Each camera's mid-exposure on the host clock: the simulation's own clock, the estimated
  // device-to-host offset, or the kernel's host timestamp (0: unknown, e.g. replay).
  auto mid_host_ns = [&](const Frame& f) -> TimestampNs {
    if (p.source_info.sim_clock && p.source_info.sim_clock->paced())
      return p.source_info.sim_clock->host_ns(f.t_ns - sim_offsets[index_of(f.camera)]);
    if (const recorder::RecordedFrame* rf = dynamic_cast<const recorder::RecordedFrame*>(f.attachment.get()))
      return rf->released_host_ns;  // a paced replay: when the frame was due (0: not paced)
    if (f.clock == ClockDomain::kHostMonotonic) return f.t_ns;
    if (f.clock == ClockDomain::kDevice)
      for (const ClockOffsetLog& c : s.clocks)
        if (c.camera == f.camera && c.samples) return f.t_ns + c.offset_ns;
    return 0;
  };

  // A new phase of the flight: an event at the pair's statistics time (`t_ns`, on the nav clock
  // where the poses map frames onto it), so that plots can mark it.
  auto note_phase = [&](const StereoFrame& frame, TimestampNs t_ns) {
    if (!p.phase_of) return;
    std::string phase = p.phase_of(frame);
    if (phase.empty() || phase == s.phase) return;
    s.phase = std::move(phase);
    out << "  phase: " << s.phase << " from pair " << frame.pair_sequence << " (t_ns " << t_ns << ")\n";
    if (p.recorder)
      p.recorder->push(recorder::EventRecord{t_ns, s.poses.t_nav_ns ? ClockDomain::kGps : frame.left.clock,
                                             "phase: " + s.phase});
  };

  // Capture only: the pair, with its poses where there is a pose source, to the window (raw) and
  // the recorder; nothing augmented.
  auto capture = [&](StereoFrame& frame, TimestampNs mid_l, TimestampNs mid_host, TimestampNs t_in) {
    std::optional<SceneState> scene;
    FramePoses& fp = s.poses;
    fp = p.poses ? p.poses->at(frame, mid_l) : FramePoses{};
    scene = fp.scene;
    if (p.poses && !scene) ++rep.no_pose_pairs;
    const TimestampNs t_sinks = monotonic_now_ns();
    rep.stage_pose.add(t_sinks - t_in);
    ++rep.pairs;
    note_phase(frame, fp.t_nav_ns.value_or(frame.t_key_ns));
    if (p.serve)
      p.serve->publish_pair(frame, nullptr, scene ? &*scene : nullptr,
                            {rep.pairs, fp.sigma_pos_m, fp.sigma_att_deg});
    if (p.view && !s.paused) {
      // The window shows the raw images (no masks: nothing is overlaid).
      for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
        ViewResult& v = id == CameraId::kLeft ? result.left : result.right;
        v.augmented = Image::copy_of(frame[id].image.cview());
        v.mask = Image();
      }
      p.view->publish(result, scene.value_or(SceneState{BoomArticulation{}, Pose::identity(), false, {}}),
                      mid_host);
    } else if (!p.view && mid_host) {
      rep.display_latency.add(monotonic_now_ns() - mid_host);
    }
    if (p.recorder && s.recording_on) {
      if (mid_host) rep.recorder_latency.add(monotonic_now_ns() - mid_host);
      recorder::FrameRecord fr;
      fr.raw = std::move(frame);
      if (scene) {
        fr.T_body_receiver = scene->T_body_receiver;
        fr.receiver_present = scene->receiver_present;
        for (int c = 0; c < 2; ++c)
          fr.T_cam_receiver[c] = p.rig.cameras[c].T_body_cam.inverse() * scene->T_body_receiver;
        fr.sigma_pos_m = fp.sigma_pos_m;
        fr.sigma_att_deg = fp.sigma_att_deg;
      }
      p.recorder->push(std::move(fr));
    }
    rep.stage_sinks.add(monotonic_now_ns() - t_sinks);
  };

  // One stereo frame through pose, boom, augmentation and the sinks.
  auto process = [&](StereoFrame& frame) {
    if (s.first) {
      s.first = false;
      s.first_t_ns = source_origin_ns.value_or(frame.left.t_ns);
      if (p.on_first_frame) p.on_first_frame(frame);
      // A configuration that cannot work fails here, once, before anything is augmented.
      for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
        const Image& im = frame[id].image;
        const RigCamera& cam = p.rig.cameras[static_cast<std::size_t>(index_of(id))];
        if (im.width() != cam.model.width_px || im.height() != cam.model.height_px) {
          // A recording's frames name its file; an MCAP file's (recorded frames too, no reader) its URI.
          const recorder::RecordedFrame* rf = p.source_info.replay ? recorded(frame) : nullptr;
          fatal = make_error(rf ? p.source_info.replay->reader().path() : source.uri(), ": frame ",
                             rf ? rf->index : frame.pair_sequence, ": the ", to_string(id), " image is ",
                             im.width(), "x", im.height(), ", the rig's ", cam.name, " camera is ",
                             cam.model.width_px, "x", cam.model.height_px, " (", p.rig.source,
                             "; give the rig that matches the images, or set the cameras' size)");
          return;
        }
      }
    }
    s.last_t_key_ns = frame.t_key_ns;
    const TimestampNs mid_l = mid_host_ns(frame.left), mid_r = mid_host_ns(frame.right);
    const TimestampNs mid_host = mid_l && mid_r ? std::min(mid_l, mid_r) : 0;  // the earlier: not flattered

    // Time per stage, for the summary: from the later frame's arrival to here (capture queues and
    // pairing; only for frames stamped on this host's clock), then each stage.
    const TimestampNs t_in = monotonic_now_ns();
    const TimestampNs arrived = std::max(frame.left.t_host_ns, frame.right.t_host_ns);
    if (arrived > 0 && t_in >= arrived && t_in - arrived < 10'000'000'000)
      rep.stage_queue.add(t_in - arrived);

    if (p.capture_only) {
      capture(frame, mid_l, mid_host, t_in);
      return;
    }

    // 1. The pose.
    s.poses = p.poses->at(frame, mid_l);
    const TimestampNs t_pose = monotonic_now_ns();
    rep.stage_pose.add(t_pose - t_in);
    FramePoses& fp = s.poses;
    bool stale = fp.stale;
    if (!fp.scene) {
      ++rep.no_pose_pairs;
      stale = true;
      if (p.skip_frames_without_pose) {
        if (rep.skipped_no_pose++ < 5)
          problem(make_error(fp.problems.empty() ? "pair " + std::to_string(frame.pair_sequence) + ": no pose"
                                                 : fp.problems.front(),
                             "; not augmented"));
        return;
      }
      // Without a pose the frame is still shown and recorded: the boom alone, the receiver left out
      // of the masks, and the frame marked.
      fp.scene = SceneState{BoomArticulation{}, Pose::identity(), false, {}};
    }
    if (stale) ++rep.stale_pairs;
    if (stale != s.was_stale) {
      std::ostringstream e;
      e << (p.poses->live() ? "nav " : "pose ") << (stale ? "stale" : "good again") << " from pair "
        << frame.pair_sequence << " (t_ns " << frame.t_key_ns << ")";
      if (stale && !fp.problems.empty()) e << ": " << fp.problems.front();
      log_event(s, e.str(), out);
      s.was_stale = stale;
    }
    SceneState& scene = *fp.scene;

    // 2. The boom.
    if (boom_default_track) {
      boom.set_mode(fp.boom_given ? DisplayBoomMode::kFixed : DisplayBoomMode::kTrackReceptacle);
      boom_default_track = false;
    }
    boom.apply(scene, ns_to_s(frame.left.t_ns - s.first_t_ns));
    for (const std::string& note : look.before_augment(frame, scene, *augmenter)) log_event(s, note, out);

    // 3. The augmentation.
    const TimestampNs t_aug = monotonic_now_ns();
    const Status augmented = augmenter->augment(frame, scene, result);
    if (augmented) look.after_augment(frame, scene, result, p.rig);
    const TimestampNs t_sinks = monotonic_now_ns();
    rep.stage_augment.add(t_sinks - t_aug);
    if (Status st = augmented; !st) {
      ++rep.failed_pairs;
      s.failed_t.add(frame.t_key_ns);
      problem(make_error("pair ", frame.pair_sequence, ": ", st.error().message));
      return;
    }
    // The look's new estimates to the recording, when there are any (a sink: timed with the sinks).
    if (p.recorder)
      for (recorder::LookRecord& u : look_updates.take(look, *augmenter, frame, scene.light))
        p.recorder->push(std::move(u));
    rep.augment_ms += augmenter->timings().total_ms;
    result.stats.t_ns = fp.t_nav_ns.value_or(frame.t_key_ns);
    ++rep.pairs;
    rep.summary.add(result.stats);
    rep.last_stats = result.stats;
    if (p.keep_all_stats) rep.all_stats.push_back(result.stats);
    note_phase(frame, result.stats.t_ns);
    const recorder::RecordedFrame* rf = recorded(frame);
    if (rf && rf->record.stats) {
      ++rep.comparable;
      rep.reproduced += same_counts(result.stats, *rf->record.stats);
    }

    // 4. The sinks.
    if (p.stats_csv)
      if (Status st = p.stats_csv->add(result.stats); !st) {
        fatal = st.error();
        return;
      }
    if (p.frame_files && (rep.pairs - 1) % static_cast<std::uint64_t>(p.frame_files->every) == 0) {
      FrameNames names;
      if (p.frame_files->names) {
        names = p.frame_files->names(frame);
      } else {
        std::ostringstream stem;
        if (rf && rf->pass) stem << "pass" << rf->pass << "_";
        stem << std::setw(6) << std::setfill('0') << (rf ? rf->index : frame.pair_sequence);
        names = {stem.str(), stem.str()};
      }
      if (Status st = write_frame_images(p.frame_files->dir, names, frame, result); !st) {
        fatal = st.error();
        return;
      }
      if (p.frame_files->ground_truth)
        if (Status st = write_ground_truth(p.frame_files->dir, names, result, p.rig); !st) {
          fatal = st.error();
          return;
        }
    }
    if (p.on_pair)
      if (Status st = p.on_pair(frame, result, scene, fp); !st) {
        fatal = st.error();
        return;
      }
    if (p.serve) p.serve->publish_pair(frame, &result, &scene, {rep.pairs, fp.sigma_pos_m, fp.sigma_att_deg});
    // The recorder takes the boxes (copied here); the window then gets whole images.
    std::optional<recorder::FrameRecord> fr;
    if (p.recorder && s.recording_on) fr = frame_record(result, p.record_ground_truth);
    if (p.view && !s.paused) {
      make_whole_augmented(frame.left.image, result.left);
      make_whole_augmented(frame.right.image, result.right);
    }
    if (rf) {
      s.shown_index = rf->index;
      s.shown_pass = rf->pass;
      s.shown_t_key_ns = frame.t_key_ns;
    }
    if (p.view) {
      // A paused live run keeps processing and recording; the window keeps the frozen pair.
      if (!s.paused || replay) p.view->publish(result, scene, mid_host);
    } else if (mid_host) {
      // Headless: the hand-off is as far as a frame goes.
      rep.display_latency.add(monotonic_now_ns() - mid_host);
    }
    if (fr) {
      if (mid_host) rep.recorder_latency.add(monotonic_now_ns() - mid_host);
      fr->raw = std::move(frame);
      fr->T_body_receiver = scene.T_body_receiver;
      fr->receiver_present = scene.receiver_present;
      for (int c = 0; c < 2; ++c)
        fr->T_cam_receiver[c] = p.rig.cameras[c].T_body_cam.inverse() * scene.T_body_receiver;
      fr->sigma_pos_m = fp.sigma_pos_m;
      fr->sigma_att_deg = fp.sigma_att_deg;
      fr->boom = scene.boom;
      p.recorder->push(std::move(*fr));
    }
    rep.stage_sinks.add(monotonic_now_ns() - t_sinks);
  };

  // The HUD and the commands, once per loop when a window is open.
  auto exchange_with_view = [&] {
    const StereoSourceStats st = source.stats();
    const double t = std::max(1e-9, std::chrono::duration<double>(SteadyClock::now() - t0).count());
    HudState hud;
    hud.fps = {st.frames[0] / t, st.frames[1] / t};
    if (st.pairing.skew.count) {
      hud.skew_p50_ms = st.pairing.skew.p50_abs_ns() / 1e6;
      hud.skew_p99_ms = st.pairing.skew.p99_abs_ns() / 1e6;
    }
    hud.drops = {st.camera_drops, st.transport_drops, st.pairing.unpaired_left + st.pairing.unpaired_right,
                 st.queue_drops[0] + st.queue_drops[1] + rep.failed_pairs * 2,
                 p.recorder ? p.recorder->stats().frames_dropped : 0};
    hud.nav = s.poses.hud;
    for (const std::string& m : s.poses.problems) hud.messages.push_back(m);
    hud.stale_pose = s.was_stale;
    hud.occlusion = rep.last_stats;
    hud.latency_recorder = rolling_hud(s.recorder_recent_ms);
    hud.recording = p.recorder && s.recording_on;
    hud.recording_path = p.recorder ? p.recorder->path() : "";
    hud.paused = s.paused;
    hud.boom_mode = boom.mode();
    for (const SourceHealth& h : source.health())
      if (!h.connected) hud.messages.push_back(h.message);
    if (p.recorder && !p.recorder->status())
      hud.messages.push_back("recording stopped: " + p.recorder->status().error().message);
    std::optional<Playback> pb;
    if (replay) {
      Playback b;
      b.frame_count = replay->frame_count();
      b.frame = s.shown_index;
      b.pass = s.shown_pass;
      b.t_s = s.shown_t_key_ns ? ns_to_s(s.shown_t_key_ns - s.replay_first_ns) : 0;
      b.duration_s = ns_to_s(s.replay_last_ns - s.replay_first_ns);
      b.rate = replay->rate();
      pb = b;
    }
    p.view->set_hud(std::move(hud), pb);
    PipelineCommands c = p.view->take_commands();
    if (c.quit) {
      rep.window_closed = true;
    }
    if (c.toggle_pause) {
      s.paused = !s.paused;
      if (replay) replay->set_paused(s.paused);
    }
    if (c.toggle_recording && p.recorder) {
      s.recording_on = !s.recording_on;
      log_event(s, s.recording_on ? "recording resumed" : "recording paused", out);
    }
    if (c.boom_mode) {
      boom.set_mode(*c.boom_mode);
      boom_default_track = false;
    }
    if (c.boom_nudge.any()) {
      boom.nudge(c.boom_nudge);
      boom_default_track = false;
    }
    return c;
  };

  PipelineCommands pending;
  bool duration_reached = false;
  for (;;) {
    if (fatal) break;
    if (p.stop_flag && p.stop_flag->load()) {
      rep.stopped_by_signal = true;
      out << "run: stopped by signal\n";
      break;
    }
    if (rep.window_closed) break;
    if (p.duration_s > 0 && std::chrono::duration<double>(SteadyClock::now() - t0).count() >= p.duration_s) {
      duration_reached = true;
      break;
    }
    if (p.max_pairs && rep.pairs >= p.max_pairs) break;
    StereoFrame frame;
    // A paused replay reads nothing until a step or a seek.
    const bool hold = replay && s.paused && pending.steps == 0 && !s.seek_target;
    Expected<ReadStatus> r = ReadStatus::kTimeout;
    if (hold) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    } else {
      r = source.read(frame, std::chrono::milliseconds(200));
    }
    // Camera state changes are events: printed, and recorded with the frames.
    const std::vector<SourceHealth> health = source.health();
    for (std::size_t i = 0; i < health.size(); ++i)
      if (health[i].message != s.last_health[i]) {
        if (!s.last_health[i].empty() || !health[i].connected) log_event(s, health[i].message, out);
        s.last_health[i] = health[i].message;
      }
    if (!r) {
      rep.source_failed = true;
      rep.source_error = r.error().message;
      problem(r.error());
      break;
    }
    for (const std::string& e : source.take_errors()) problem(Error{e});
    if (*r == ReadStatus::kEndOfStream) break;
    if (*r == ReadStatus::kFrame) {
      const recorder::RecordedFrame* rf = recorded(frame);
      if (rf) {
        // A recorded pair keeps its recorded key, skew and sequence.
        frame.t_key_ns = rf->record.raw.t_key_ns;
        frame.skew_ns = rf->record.raw.skew_ns;
        frame.pair_sequence = rf->record.raw.pair_sequence;
      }
      if (s.seek_target && rf && rf->index != *s.seek_target) {
        ++rep.seek_skipped_pairs;  // read ahead before the seek
      } else {
        s.seek_target.reset();
        if (pending.steps > 0) --pending.steps;
        process(frame);
      }
    }
    if (p.view) {
      PipelineCommands c = exchange_with_view();
      if (replay && c.seek_frame && *c.seek_frame < replay->frame_count()) {
        if (Status st = replay->seek_frame(*c.seek_frame); st) {
          s.seek_target = *c.seek_frame;
          if (s.paused) replay->step(1);
        }
      }
      if (replay && c.rate) {
        if (Status st = replay->set_rate(*c.rate); !st) problem(st.error());
      }
      if (replay && c.steps > 0 && s.paused) {
        replay->step(static_cast<std::size_t>(c.steps));
        pending.steps += c.steps;
      }
    }
    if (p.recorder && !s.recorder_failed && !p.recorder->status()) {
      // Disk full or a write error: the recording ends valid with what it holds; the run goes on.
      s.recorder_failed = true;
      out << "  recording stopped: " << p.recorder->status().error().message
          << " (what was recorded stays valid; the run goes on)\n";
    }
    if (SteadyClock::now() >= next_clocks) {
      next_clocks += std::chrono::seconds(1);
      s.clocks = source.stats().clocks;
    }
    if (p.progress_total && !p.view && SteadyClock::now() >= next_progress) {
      next_progress += std::chrono::seconds(1);
      const double t = std::chrono::duration<double>(SteadyClock::now() - t0).count();
      const std::uint64_t done = rep.pairs + rep.failed_pairs + rep.skipped_no_pose;
      const double rate = done / std::max(t, 1e-9);
      out << "  " << done << " of " << p.progress_total << " pairs, " << std::fixed << std::setprecision(1)
          << rate << "/s";
      if (rate > 0 && done < p.progress_total) {
        const auto eta_s = static_cast<long long>((p.progress_total - done) / rate + 0.5);
        out << ", ETA " << (eta_s >= 60 ? std::to_string(eta_s / 60) + " min " : "") << eta_s % 60 << " s";
      }
      out << std::endl;
    }
    if (p.serve && SteadyClock::now() >= next_health) {
      next_health += std::chrono::seconds(1);
      publish_health();
    }
    if (p.status_every_s > 0 && SteadyClock::now() >= next_status) {
      next_status += std::chrono::duration<double>(p.status_every_s);
      const StereoSourceStats st = source.stats();
      const double t = std::chrono::duration<double>(SteadyClock::now() - t0).count();
      out << "  t " << std::fixed << std::setprecision(1) << t << " s: " << rep.pairs << " pairs ("
          << std::setprecision(1) << rep.pairs / std::max(t, 1e-9) << "/s), skew p50/p99 "
          << fmt_us(st.pairing.skew.p50_abs_ns()) << "/" << fmt_us(st.pairing.skew.p99_abs_ns())
          << " us, drops camera " << st.camera_drops << " transport " << st.transport_drops << " pairing "
          << st.pairing.unpaired_left + st.pairing.unpaired_right << " queue "
          << st.queue_drops[0] + st.queue_drops[1] << "\n";
      if (look.look() == Look::kCamera) {
        out << "    " << look.status() << "\n";
        if (p.recorder)
          p.recorder->push(recorder::EventRecord{monotonic_now_ns(), ClockDomain::kHostMonotonic, look.status()});
      }
      for (const ClockOffsetLog& c : st.clocks) {
        std::ostringstream e;
        e << "clock_offset camera=" << to_string(c.camera) << " t_device_ns=" << c.t_device_ns
          << " offset_ns=" << c.offset_ns << " drift_ppm=" << std::setprecision(3) << c.drift_ppm
          << " uncertainty_ns=" << c.uncertainty_ns << " samples=" << c.samples << " resets=" << c.resets;
        if (p.recorder)
          p.recorder->push(recorder::EventRecord{c.t_host_ns, ClockDomain::kHostMonotonic, e.str()});
      }
    }
  }
  // Stopped by the duration, a signal or the window on a live source: capture stops, and what the
  // cameras had already delivered still goes through (the pairs in the queues and the pairer), so
  // that only frames whose partner never came stay pending. A frame limit stops exactly there; a
  // lossless (finite) source's read-ahead stays pending, as it is still in its file.
  if (!fatal && (duration_reached || rep.stopped_by_signal || rep.window_closed) && !source.lossless()) {
    source.stop();
    StereoFrame frame;
    for (Expected<ReadStatus> r = source.read(frame, std::chrono::nanoseconds(0));
         !fatal && r && *r == ReadStatus::kFrame; r = source.read(frame, std::chrono::nanoseconds(0))) {
      process(frame);
      ++rep.pairs_after_stop;
    }
  }
  if (p.view) p.view->finish();
  if (p.serve) {
    p.serve->publish_health(s.last_t_key_ns, net::HealthLevel::kStale,
                            "the run has ended after " + std::to_string(rep.pairs) + " pairs");
    rep.serve = p.serve->stats();
  }
  source.stop();
  if (p.on_stop) p.on_stop();
  if (p.nav_inputs) p.nav_inputs->stop();
  rep.wall_s = std::chrono::duration<double>(SteadyClock::now() - t0).count();
  rep.source = source.stats();
  if (p.view) rep.display_latency = p.view->display_histogram();
  for (std::size_t i = 0; i < source.sources().size(); ++i) {
    const SourceHealth h = source.health()[i];
    if (!h.connected)
      rep.lost_cameras.push_back(source.sources()[i]->uri() + " was lost and never came back (" + h.message +
                                 ")");
  }

  // The drop ledger into the recording, and the recording closed: every frame is accounted for.
  if (p.recorder) {
    if (p.nav_inputs) p.nav_inputs->ledger(*p.recorder);
    const StereoSourceStats& st = rep.source;
    // The sources count their own gaps without timestamps; every other row has the first and last
    // frame time of what it counts.
    auto ledger = [&](recorder::DropStage stage, std::uint64_t n, const TimeSpan& t, const std::string& why) {
      if (n) p.recorder->push(recorder::DropRecord{stage, n, t.first_t_ns, t.last_t_ns, why, "frame"});
    };
    ledger(recorder::DropStage::kCamera, st.camera_drops, {}, "frame-id gaps reported by the cameras");
    ledger(recorder::DropStage::kTransport, st.transport_drops, {}, "incomplete or failed buffers");
    ledger(recorder::DropStage::kPairing, st.pairing.unpaired_at_start.count, st.pairing.unpaired_at_start,
           "frames without a stereo partner before the first pair (the cameras' streams began at different "
           "moments)");
    ledger(recorder::DropStage::kPairing, st.pairing.unpaired_after_start.count,
           st.pairing.unpaired_after_start, "frames without a stereo partner");
    ledger(recorder::DropStage::kProcessing, st.queue_drops[0] + st.queue_drops[1], st.queue_drop_t,
           "capture queue full (the pipeline fell behind)");
    ledger(recorder::DropStage::kProcessing, rep.failed_pairs * 2, s.failed_t,
           "augmentation failed (both frames of the pair)");
    ledger(recorder::DropStage::kProcessing, st.pending.count, st.pending,
           "pending in the capture queues or the pairer when the run stopped");
    rep.recording_closed = p.recorder->close();
    rep.recorder_stats = p.recorder->stats();
  }
  if (fatal) return *fatal;
  return rep;
}

void Pipeline::print_summary(const PipelineReport& r, std::ostream& out) const {
  const StereoSourceStats& st = r.source;
  if (r.summary.frames()) out << r.summary.format();
  const std::uint64_t pairing = st.pairing.unpaired_left + st.pairing.unpaired_right;
  const std::uint64_t queue = st.queue_drops[0] + st.queue_drops[1];
  const std::uint64_t pending = st.pending.count;
  out << "run: " << r.pairs << " stereo frames "
      << (parts_.capture_only ? "captured (not augmented)" : "augmented") << " in " << std::fixed
      << std::setprecision(1) << r.wall_s << " s (" << r.pairs / std::max(r.wall_s, 1e-9) << "/s";
  if (r.pairs && !parts_.capture_only)
    out << ", augmenter " << fmt_ms(r.augment_ms / static_cast<double>(r.pairs)) << " ms/frame, "
        << to_string(r.rasterizer) << " rasteriser";
  // Every frame read is in a pair or a ledger row: read = 2 pairs + pairing + queue + pending.
  const std::uint64_t pairs_read = r.pairs + r.failed_pairs + r.skipped_no_pose + r.seek_skipped_pairs;
  out << "); frames read: left " << st.frames[0] << ", right " << st.frames[1] << " = 2 x " << pairs_read
      << " pairs + " << pairing << " unpaired + " << queue << " dropped from full queues + " << pending
      << " pending at the stop\n";
  if (st.pairing.unpaired_at_start.count)
    out << "pairing at the start: " << st.pairing.unpaired_at_start.count
        << " of the unpaired frames came before the first pair (the cameras' streams began at different "
           "moments)\n";
  if (r.pairs_after_stop)
    out << "stop: " << r.pairs_after_stop
        << " pair(s) the cameras had delivered before it were still augmented (in the pairs above)\n";
  if (r.skipped_no_pose || r.seek_skipped_pairs)
    out << "pairs read but not augmented: " << r.skipped_no_pose << " without a pose, "
        << r.seek_skipped_pairs << " passed over by a seek\n";
  out << "drops: camera " << st.camera_drops << ", transport " << st.transport_drops << ", pairing "
      << pairing << ", processing " << queue + r.failed_pairs * 2 + pending << " (queue " << queue
      << ", failed " << r.failed_pairs << " pairs, pending at the stop " << pending << "), recorder "
      << r.recorder_stats.frames_dropped << "\n";
  // Latency from each pair's mid-exposure (the earlier camera's) on the host clock.
  auto latency_line = [&](const char* what, const SkewStats& h) {
    if (h.count)
      out << "latency mid-exposure to " << what << ": p50 " << fmt_ms(h.p50_abs_ns() / 1e6) << " ms, p99 "
          << fmt_ms(h.p99_abs_ns() / 1e6) << " ms, max " << fmt_ms(h.max_abs_ns / 1e6) << " ms (" << h.count
          << " pairs)\n";
  };
  // Where a pair's time goes, stage by stage.
  if (r.stage_augment.count) {
    auto stage = [&](const char* name, const SkewStats& h) {
      out << name << " " << fmt_ms(h.p50_abs_ns() / 1e6) << " / " << fmt_ms(h.p99_abs_ns() / 1e6);
    };
    out << "stages per pair, p50 / p99 ms: ";
    if (r.stage_queue.count) {
      stage("capture queues and pairing", r.stage_queue);
      out << ", ";
    }
    stage("pose", r.stage_pose);
    out << ", ";
    stage("augment", r.stage_augment);
    out << ", ";
    stage("sinks", r.stage_sinks);
    out << "\n";
  }
  latency_line(parts_.view ? "display" : "display hand-off", r.display_latency);
  if (r.serve) {
    const net::ServeStats& v = *r.serve;
    out << "live view (" << (parts_.serve ? parts_.serve->url() : std::string()) << "): " << v.clients_ever
        << " client(s), " << v.messages_sent << " messages sent, " << v.messages_dropped
        << " dropped for slow clients, " << v.disconnects_slow << " client(s) cut off for not reading\n";
  }
  latency_line("recorder", r.recorder_latency);
  if (parts_.live_nav) {
    out << "nav: " << r.no_pose_pairs << " pairs without a pose (boom only), " << r.stale_pairs
        << " with a stale or missing pose\n";
    for (Aircraft ac : {Aircraft::kTanker, Aircraft::kReceiver}) {
      const nav::LiveFusionStatus ns = parts_.live_nav->status(ac);
      out << "nav " << to_string(ac) << ": " << (ns.initialised ? "fused" : "never initialised") << ", "
          << ns.imu_samples << " IMU samples (" << ns.imu_refused << " refused), " << ns.fixes
          << " fixes: " << ns.fixes_used << " used, " << ns.fixes_rejected << " rejected by the gate, "
          << ns.fixes_invalid << " without a fix, " << ns.fixes_late << " late\n";
    }
    if (const LiveBaselineReport b = parts_.live_nav->baseline_report(); b.received)
      out << "nav " << b.summary() << "\n";
  } else if (r.no_pose_pairs && !r.skipped_no_pose) {
    out << "nav: " << r.no_pose_pairs << " pairs without a pose (boom only)\n";
  }
  if (st.pairing.skew.count)
    out << "pair skew: p50 " << fmt_us(st.pairing.skew.p50_abs_ns()) << " us, p99 "
        << fmt_us(st.pairing.skew.p99_abs_ns()) << " us, max " << fmt_us(st.pairing.skew.max_abs_ns) << " us"
        << (st.pairing.pairs_within_uncertainty
                ? ", " + std::to_string(st.pairing.pairs_within_uncertainty) +
                      " pair(s) beyond the tolerance but within the clock estimates' uncertainty"
                : std::string())
        << "\n";
  for (const ClockOffsetLog& c : st.clocks)
    out << "clock " << to_string(c.camera) << ": host - device " << c.offset_ns << " ns, drift "
        << std::setprecision(2) << c.drift_ppm << " ppm, +-" << fmt_us(c.uncertainty_ns) << " us ("
        << c.samples << " samples, " << c.resets << " resets)\n";
  for (std::size_t i = 0; i < parts_.source->sources().size(); ++i) {
    const SourceHealth h = parts_.source->health()[i];
    if (h.disconnects)
      out << parts_.source->sources()[i]->uri() << ": lost " << h.disconnects << " time(s), reconnected "
          << h.reconnects << " time(s)" << (h.connected ? "" : "; not connected at the end") << "\n";
  }
}

}  // namespace augrig::pipeline
