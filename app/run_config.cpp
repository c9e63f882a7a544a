// run_config (run_config.hpp): the live pipeline's parts from RunOptions, one step a function, in
// the order the steps must happen (the cameras are opened before the rig is known; the recorder
// exists before the nav inputs that record into it; the source starts with the pipeline).
#include "app/run_config.hpp"

#include <algorithm>
#include <iomanip>
#include <memory>
#include <sstream>

#include "app/window_runner.hpp"
#include "nav/live_input.hpp"
#include "pipeline/flight_nav.hpp"
#include "pipeline/live_nav.hpp"
#include "pipeline/sinks/registry.hpp"
#include "pipeline/sources.hpp"
#include "recorder/recorder.hpp"
#include "recorder/replay_source.hpp"
#include "sim/nav_stream.hpp"
#include "sim/scenario.hpp"

namespace augrig::app {

double parse_duration_arg(const std::string& v) {
  const double s = parse_real("duration", v);
  if (s < 0) usage_error("--duration: expected seconds >= 0");
  return s;
}

std::uint64_t parse_max_pairs_arg(const std::string& v) {
  return static_cast<std::uint64_t>(parse_integer("frames", v, 1, 1LL << 40));
}

Look parse_look_arg(const std::string& v) {
  Look look = Look::kCamera;
  if (!parse_look(v, look)) usage_error("--look: expected plain or camera, got '" + v + "'");
  return look;
}

namespace {

std::string fmt_us(std::int64_t ns) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << static_cast<double>(ns) / 1e3;
  return s.str();
}

// What run owns besides the pipeline's parts; it outlives the pipeline (the parts point into it).
struct RunSetup {
  PipelineParts parts;
  std::unique_ptr<LiveNav> live_nav;
  // After live_nav: destroyed (its workers stopped) before the nav it reads.
  std::unique_ptr<CameraClocks> camera_clocks;
  std::unique_ptr<NavInputs> nav_inputs;
  std::shared_ptr<std::unique_ptr<sim::NavStreamer>> nav_streamer;
  nav::InsConfig ins_used[2];  // the live fusion's aircraft settings (recorded for a re-fusion)
  std::string poses_text;      // where the poses come from, in words
};

// The source opened and the rig it runs with.
struct RunSource {
  std::string uri, right_uri;  // right_uri: the rig's right camera, when the rig names the cameras
  OpenedSource opened;
  OpenedSourceInfo info;
  std::optional<Rig> recorded_rig;  // replay://: the recording's own
  Rig rig;
  bool capture_only = false;
  bool is_sim() const { return !info.scenario.empty(); }
};

// The live nav's inputs: --nav sim's loopback UDP streams or --nav's; `use` when both aircraft have
// streams (then they are fused into the poses).
struct NavPlan {
  std::vector<std::pair<std::string, std::string>> items;
  bool use = false;
};

// Nothing is augmented when capturing only: the flags that would augment are refused, saying why.
void refuse_augmenting_flags(const RunOptions& o, const std::optional<Rig>& rig) {
  const std::pair<const char*, bool> given[] = {{"out", o.out.has_value()},
                                                {"every", o.every != 0},
                                                {"ground-truth", o.ground_truth},
                                                {"boom", o.boom.has_value()},
                                                {"receiver-draw", o.receiver_draw.has_value()},
                                                {"scene", o.scene.has_value()}};
  for (const auto& [flag, has] : given)
    if (has)
      usage_error(std::string("--") + flag + ": nothing is augmented when capturing only" +
                  (o.capture_only ? std::string(" (--capture-only)")
                                  : " (" + rig->source + " has no boom section: a capture-only rig)"));
}

// A source without poses of its own (cameras, datasets) needs a pose source: said before any
// camera is opened. sim:// has its truth, replay:// its recorded poses.
void require_pose_source(const RunOptions& o, const std::string& uri, bool capture_only) {
  const std::string scheme = uri.substr(0, uri.find_first_of(":"));
  const bool own_poses = scheme == "sim" || scheme == "replay";
  if (!own_poses && !o.scene && !o.poses_csv && !o.nav_given && !capture_only)
    usage_error("a pose source is needed for " + uri +
                ": --scene SCENE.yaml, --poses POSES.csv, or --nav with streams of both aircraft "
                "(tanker.*, receiver.*)");
}

// The frames' URIs (--source, else the rig's cameras'), the source opened (not started) and the
// rig: --rig, else the simulation's, the recording's, or the paper's.
RunSource open_run_source(const RunOptions& o) {
  std::optional<Rig> rig;
  if (o.rig) rig = load_rig_arg(*o.rig);
  RunSource s;
  s.capture_only = o.capture_only || (rig && !rig->boom.configured);
  if (s.capture_only) refuse_augmenting_flags(o, rig);
  s.uri = o.source_uri;
  if (s.uri.empty()) {
    if (!rig) usage_error("give --source URI, or --rig RIG whose cameras have 'source' keys");
    s.uri = rig->left().source_uri;
    s.right_uri = rig->right().source_uri;
    if (s.uri.empty() || s.right_uri.empty())
      runtime_error(rig->source + ": cameras[0] and cameras[1] need a 'source' URI, or give --source");
  }
  require_pose_source(o, s.uri, s.capture_only);
  s.opened = unwrap(open_sources(s.uri, s.right_uri, rig ? rig->pairing : RigPairing{}));
  s.info = s.opened;
  if (s.opened.replay)
    if (const std::string yaml = s.opened.replay->reader().meta("rig_yaml"); !yaml.empty())
      s.recorded_rig = unwrap(parse_rig(yaml, s.opened.replay->reader().path() + " (meta rig_yaml)"));
  s.rig = rig              ? *rig
          : s.is_sim()     ? s.info.sim->scenario.rig
          : s.recorded_rig ? *s.recorded_rig
                           : Rig::paper_default();
  if (s.rig.cameras.size() != 2)
    runtime_error(s.rig.source + ": the rig needs 2 cameras, has " + std::to_string(s.rig.cameras.size()));
  return s;
}

// The nav inputs and whether they give poses; one source of poses only.
NavPlan plan_nav(const RunOptions& o, const RunSource& s) {
  if (o.nav_sim && !s.is_sim()) usage_error("--nav sim needs a sim:// source");
  NavPlan nav;
  if (o.nav_sim) {
    // The simulated streams come in through the same UDP inputs as in flight (ports chosen free).
    for (const sim::NavStreamTarget& t : sim::loopback_targets(0, 0, 0, 0))
      nav.items.emplace_back(t.stream, std::string("udp://127.0.0.1:0?format=") +
                                           (t.kind == sim::NavStreamKind::kGps ? "nmea" : "imu"));
  } else {
    nav.items = o.nav_streams;
  }
  bool nav_of[2] = {false, false};
  for (const auto& item : nav.items)
    if (const auto ac = aircraft_of_stream(item.first)) nav_of[static_cast<int>(*ac)] = true;
  nav.use = nav_of[0] && nav_of[1];
  if (o.scene.has_value() + o.poses_csv.has_value() + nav.use > 1)
    usage_error(
        "--scene, --poses and --nav with streams of both aircraft are three sources of poses: give one");
  if (o.nav_given && !o.nav_sim && !nav.use && !o.scene && !o.poses_csv && !s.opened.replay && !s.is_sim())
    usage_error("--nav needs streams of both aircraft (tanker.*, receiver.*) to give poses");
  return nav;
}

// The live fusion of both aircraft's nav streams: their settings from the simulation (--nav sim)
// or defaults, each replaced by --aircraft's file; `ins_used` gets them.
std::unique_ptr<LiveNav> make_live_nav(const RunOptions& o, const Rig& rig,
                                       const Eigen::Vector3d& receptacle_m, const SimulatedFlight* sim,
                                       nav::InsConfig ins_used[2]) {
  if (sim) {
    ins_used[0] = ins_config_for(sim->scenario.sensors.tanker);
    ins_used[1] = ins_config_for(sim->scenario.sensors.receiver);
  }
  for (const auto& [who, file] : o.aircraft)
    ins_used[static_cast<int>(*aircraft_of_stream(who))] = unwrap(load_aircraft_config(file));
  LiveNavOptions nopt;
  if (o.nav_stale_s) nopt.stale_after_s = *o.nav_stale_s;
  return std::make_unique<LiveNav>(rig, BoomDimensions{}, receptacle_m, ins_used[0], ins_used[1], nopt);
}

// --camera-clock online: each camera's clock estimated from its images against the tanker's rates
// from the live nav, applied to the poses once confident; priors as the poses map frames today.
void make_camera_clocks(const RunOptions& o, const Rig& rig, PoseSources& ps, RunSetup& setup) {
  CameraClockOnlineOptions co;
  co.apply_sigma_s = o.camera_clock_apply_sigma_ms * 1e-3;
  const LiveNav* nav = setup.live_nav.get();
  auto host_to_nav = [nav](TimestampNs host_ns) -> std::optional<TimestampNs> {
    const Expected<TimestampNs> t = nav->host_to_nav(host_ns);
    return t ? std::optional<TimestampNs>(*t) : std::nullopt;
  };
  setup.camera_clocks = std::make_unique<CameraClocks>(rig, ps.camera_offset_ns, host_to_nav,
                                                       nav->tanker_ground_motion(o.terrain_height_m), co);
  setup.live_nav->feed_tanker_rates(setup.camera_clocks->rates());
  ps.camera_clocks = setup.parts.camera_clocks = setup.camera_clocks.get();
}

// Where each frame's receiver pose comes from (pipeline/poses.hpp's order): a fixed scene, a poses
// CSV, the live nav, the recording's own poses (replay://), or (sim://) the simulation's truth.
void choose_run_poses(const RunOptions& o, const RunSource& s, const NavPlan& nav, RunSetup& setup) {
  PipelineParts& parts = setup.parts;
  PoseSources ps;
  ps.scene_path = o.scene.value_or("");
  ps.boom_dims = BoomDimensions{};
  ps.poses_csv_path = o.poses_csv.value_or("");
  ps.pose_tolerance_ns = o.pose_tolerance_ns;
  if (nav.use && ps.scene_path.empty() && ps.poses_csv_path.empty()) {
    setup.live_nav = make_live_nav(o, s.rig, parts.models.receptacle_m,
                                   o.nav_sim ? s.info.sim.get() : nullptr, setup.ins_used);
    ps.live_nav = parts.live_nav = setup.live_nav.get();
    if (o.nav_sim) {
      ps.camera_offset_ns = s.info.sim->scenario.sensors.cameras.assumed_clock_offsets_ns(2);
    }
    if (o.camera_clock_online) make_camera_clocks(o, s.rig, ps, setup);
  }
  if (o.camera_clock_online && !setup.camera_clocks)
    usage_error(
        "--camera-clock online needs the live nav: --nav with streams of both aircraft (tanker.*, "
        "receiver.*) and no --scene or --poses (the tanker's rates come from it)");
  ps.recorded = s.opened.replay != nullptr;
  ps.recorded_rig = s.recorded_rig;
  if (s.is_sim()) ps.sim = s.info.sim.get();
  parts.poses = unwrap(choose_poses(ps, s.rig, parts.models.receptacle_m)).provider;
  if (!parts.poses && !s.capture_only)
    usage_error(
        "a pose source is needed: --scene SCENE.yaml, --poses POSES.csv, or --nav with streams of both "
        "aircraft (tanker.*, receiver.*)");
  parts.capture_only = s.capture_only;
  setup.poses_text = parts.poses ? parts.poses->describe() : std::string("none (capture only)");
  if (setup.camera_clocks) {
    std::ostringstream t;
    t << "; camera clocks estimated online, applied at 1-sigma <= " << o.camera_clock_apply_sigma_ms << " ms";
    setup.poses_text += t.str();
  }
}

// The boom, the receiver's drawing, the look (with the rig's per-camera looks) and --sink's sinks.
void configure_augmentation(const RunOptions& o, PipelineParts& parts) {
  if (o.boom) parts.boom = *o.boom;
  parts.augment.receiver_draw = o.receiver_draw.value_or(ReceiverDraw::kMaskOnly);
  parts.augment.look = o.look;
  parts.augment.camera_looks.clear();
  for (const RigCamera& c : parts.rig.cameras) parts.augment.camera_looks.push_back(c.look);
  for (const std::string& spec : o.sinks) {
    auto sink = pipeline::make_sink(spec, {parts.rig});
    if (!sink) usage_error(sink.error().message);
    parts.sinks.push_back(std::move(*sink));
  }
}

// --record: the recording, with what a later export or re-fusion needs to know in its metadata.
std::unique_ptr<recorder::Recorder> make_run_recorder(const RunOptions& o, const RunSource& s,
                                                      const NavPlan& nav, const RunSetup& setup) {
  recorder::RecordingInfo rinfo;
  rinfo.rig_yaml = rig_to_yaml(s.rig);
  rinfo.scene = o.scene ? *o.scene : setup.poses_text;
  if (s.capture_only)
    rinfo.extra["capture_only"] = "raw frames only: nothing augmented (augrig run --capture-only)";
  rinfo.clock_domains = s.info.live ? "frames: each camera's device clock (t_ns, mid-exposure) and host "
                                      "CLOCK_MONOTONIC (t_host_ns); offsets in events 'clock_offset'"
                                    : "frames: the source's clocks as recorded";
  if (nav.use) {
    rinfo.clock_domains += "; nav inputs: arrival on host CLOCK_MONOTONIC, sensor times inside the data";
    // Each aircraft's settings, so that an export can re-fuse the recording offline.
    rinfo.extra["aircraft_yaml.tanker"] = aircraft_config_to_yaml(setup.ins_used[0]);
    rinfo.extra["aircraft_yaml.receiver"] = aircraft_config_to_yaml(setup.ins_used[1]);
  }
  if (setup.camera_clocks)
    rinfo.extra["camera_clock"] =
        "online: each camera's clock (t_gps = t_camera - offset) estimated from its images against the "
        "tanker's rates; each fit in events 'camera_clock', state changes as events 'camera clock ...' "
        "(docs/CLOCK_OFFSETS.md)";
  rinfo.extra["source"] = s.uri + (s.right_uri.empty() ? "" : " + " + s.right_uri);
  if (s.opened.replay) rinfo.extra["re_augmented_from"] = s.opened.replay->reader().path();
  return create_recorder(*o.record, rinfo, o.overwrite);
}

// --nav sim: the simulated streams' sender, started with the first frame (the flight's clock starts
// there), to the ports the inputs were bound to, muted over --nav-fault's windows.
void stream_simulated_nav(const RunOptions& o, const RunSource& s, RunSetup& setup) {
  const NavInputs& in = *setup.nav_inputs;
  std::vector<sim::NavStreamTarget> targets = sim::loopback_targets(
      in.port("tanker.gps"), in.port("tanker.imu"), in.port("receiver.gps"), in.port("receiver.imu"));
  for (const NavFault& f : o.nav_faults)
    std::find_if(targets.begin(), targets.end(), [&](const sim::NavStreamTarget& t) {
      return t.stream == f.stream;
    })->mute_s.emplace_back(f.t0_s, f.t1_s);
  setup.nav_streamer = std::make_shared<std::unique_ptr<sim::NavStreamer>>();
  setup.parts.on_first_frame = [streamer = setup.nav_streamer, targets, sim = s.info.sim,
                                clock = s.info.sim_clock](const StereoFrame&) {
    sim::NavStreamOptions so;
    so.scenario_start_gps_ns = sim->scenario.start_gps_ns;
    *streamer = unwrap(sim::NavStreamer::start(sim->logs, targets, clock, so));
  };
  setup.parts.on_stop = [streamer = setup.nav_streamer] {
    if (*streamer) (*streamer)->stop();
  };
}

// Live nav inputs: each read on a thread of its own; every unit recorded exactly as received.
void open_nav_inputs(const RunOptions& o, const RunSource& s, const NavPlan& nav, RunSetup& setup) {
  setup.nav_inputs = std::make_unique<NavInputs>();
  check(setup.nav_inputs->open(nav.items, setup.parts.recorder.get(), setup.live_nav.get()));
  if (o.nav_sim) stream_simulated_nav(o, s, setup);
  setup.parts.nav_inputs = setup.nav_inputs.get();
}

// --out: stats.csv, and with --every the images (and ground truth) of every K-th pair.
void configure_files(const RunOptions& o, PipelineParts& parts) {
  if (!o.out) return;
  make_dirs(*o.out);
  parts.stats_csv = unwrap(StatsCsvWriter::create(fs::path(*o.out) / "stats.csv"));
  if (o.every) parts.frame_files = FrameFiles{*o.out, o.every, {}, o.ground_truth};
}

// The stop conditions, the status lines, how problems are printed, the window's mailbox and the
// network live view (its address printed and flushed: whoever started the run reads it at once).
void configure_run_control(const RunOptions& o, PipelineParts& parts, std::ostream& out, std::ostream& err) {
  parts.duration_s = o.duration_s;
  parts.max_pairs = o.max_pairs;
  parts.status_every_s = o.status_every_s;
  parts.stop_flag = install_stop_signals();
  parts.on_problem = [&err](const Error& e) { err << "augrig run: " << user_message(e) << "\n"; };
  if (!o.headless && display_present()) parts.view = std::make_shared<LiveView>();
  if (o.serve) {
    net::ServeOptions so = *o.serve;
    so.metadata["rig"] = parts.rig.source;
    parts.serve = unwrap(net::FoxgloveServer::start(so, parts.rig));
    out << "live view: " << parts.serve->url() << " (Foxglove: open a connection, Foxglove WebSocket)"
        << std::endl;
  }
}

// "run: URI (lockstep|live)[; pairing ...]; rig ...; poses from ...[; recording to ...]", then each
// camera as it is set now: every setting in effect, the URI's and the device's own.
void print_run_banner(const RunSource& s, const RunSetup& setup, std::ostream& out) {
  const PipelineParts& parts = setup.parts;
  const OpenedSource& opened = *parts.unstarted_source;
  std::string pairing_text;  // cameras: how their frames pair (the stereo URI's or the rig's `pairing`)
  if (opened.live) {
    const StereoPairerConfig& pc = opened.options.pairing;
    std::ostringstream p;
    p << "; pairing by " << to_string(pc.mode) << ", tolerance " << fmt_us(pc.tolerance_ns) << " us, "
      << (pc.clock_offsets ? "each camera's clock to host time" : "one clock");
    pairing_text = p.str();
  }
  out << "run: " << s.uri << (s.right_uri.empty() ? "" : " + " + s.right_uri)
      << (opened.options.lossless ? " (lockstep)" : " (live)") << pairing_text << "; rig " << s.rig.source
      << (s.capture_only ? "; capture only (nothing augmented)" : "") << "; poses from " << setup.poses_text
      << (parts.recorder ? "; recording to " + parts.recorder->path() : std::string()) << "\n";
  for (const auto& src : opened.sources)
    if (const std::string st = src->settings(); !st.empty()) out << "  " << src->uri() << ": " << st << "\n";
}

// After the run: the nav inputs' summary, the recorder's (its drops as it counts them), and the
// exit code: a stopped recording, a lost camera or a failed source fail the run.
int finish_run(const Pipeline& pipeline, const PipelineReport& report, const RunSetup& setup,
               std::ostream& out, std::ostream& err) {
  setup.nav_inputs->summary(out);
  if (report.recording_closed) {
    const recorder::RecorderStats& rs = report.recorder_stats;
    out << "recorded " << rs.frames_committed << " stereo frames to " << pipeline.parts().recorder->path()
        << " (" << rs.frames_dropped << " dropped by the recorder";
    if (rs.small_items_dropped) out << ", and " << rs.small_items_dropped << " nav inputs or events";
    out << ")\n";
    if (!*report.recording_closed)
      runtime_error("the recording stopped: " + user_message(report.recording_closed->error()));
  }
  if (!report.lost_cameras.empty()) {
    for (std::size_t i = 1; i < report.lost_cameras.size(); ++i)
      err << "augrig run: " << report.lost_cameras[i] << "\n";
    runtime_error(report.lost_cameras.front());
  }
  return report.source_failed ? kExitRuntime : kExitOk;
}

}  // namespace

int run_live(const RunOptions& o, std::ostream& out, std::ostream& err) {
  RunSource s = open_run_source(o);
  RunSetup setup;
  PipelineParts& parts = setup.parts;
  parts.rig = s.rig;
  parts.models = unwrap(load_rig_models(s.rig));
  parts.source_info = s.info;
  const NavPlan nav = plan_nav(o, s);
  choose_run_poses(o, s, nav, setup);
  configure_augmentation(o, parts);
  if (o.record) {
    parts.recorder = make_run_recorder(o, s, nav, setup);
    parts.record_ground_truth = o.ground_truth;
  }
  open_nav_inputs(o, s, nav, setup);
  configure_files(o, parts);
  // Started by the pipeline once its augmenter is ready (cameras capture from their start).
  parts.unstarted_source = std::make_unique<OpenedSource>(std::move(s.opened));
  configure_run_control(o, parts, out, err);
  print_run_banner(s, setup, out);

  Pipeline pipeline(std::move(parts));
  const PipelineReport report =
      run_pipeline(pipeline, !o.headless, o.out.value_or("."), out, err, o.screenshot_at);
  return finish_run(pipeline, report, setup, out, err);
}

}  // namespace augrig::app
