// augrig cameras: what capture devices this machine sees.
// augrig run: the live pipeline from source URIs: capture (a thread per camera) -> pairing (clock
// offsets estimated per camera) -> pose -> augmentation -> statistics and recorder; with a display, the
// live window on the main thread and the pipeline on a worker.
#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdlib>
#include <deque>
#include <iomanip>
#include <map>
#include <mutex>
#include <sstream>

#include "app/cli.hpp"
#include "app/commands.hpp"
#include "app/window_runner.hpp"
#include "capture/aravis_source.hpp"
#include "capture/v4l2_source.hpp"
#include "core/clock.hpp"
#include "nav/imu_stream.hpp"
#include "nav/live_input.hpp"
#include "pipeline/flight_nav.hpp"
#include "pipeline/live_nav.hpp"
#include "pipeline/scene_file.hpp"
#include "pipeline/sources.hpp"
#include "recorder/recorder.hpp"
#include "recorder/replay_source.hpp"
#include "sim/flight_source.hpp"
#include "sim/nav_stream.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "sim/sim_clock.hpp"

namespace augrig::app {
namespace {

// ---- cameras ---------------------------------------------------------------------------------

// A rig file for the first two cameras found: the paper's rig (boom, receiver, mounting) with
// these cameras' resolution and serial-based source URIs (the serial survives a new IP address),
// a 56-degree pinhole as the intrinsics. What is a placeholder is said in its first lines.
void write_rig_template(const std::string& path, const std::vector<AravisDeviceInfo>& cams) {
  std::vector<const AravisDeviceInfo*> usable;
  for (const AravisDeviceInfo& d : cams)
    if (d.width_px > 0 && !d.serial.empty()) usable.push_back(&d);
  if (usable.size() < 2)
    runtime_error("--rig: a stereo rig needs 2 cameras that open; found " + std::to_string(usable.size()) +
                  " (of " + std::to_string(cams.size()) + " listed)");
  Rig rig = Rig::paper_default();
  std::ostringstream head;
  head << "# TEMPLATE written by `augrig cameras --rig` from the cameras found. Replace before use:\n"
       << "#   - each camera's intrinsics and distortion: a 56-degree pinhole here; use your calibration\n"
       << "#     (intrinsics + distortion, or calibration: {format: kalibr|opencv|ros, file: ...}),\n"
       << "#   - each T_body_cam: the seed paper's mounting here (under the fuselage, 0.5 m apart, looking\n"
       << "#     aft 25 deg down); use your installation's,\n"
       << "#   - the boom and receiver sections: a KC-135-class boom and the built-in receiver.\n"
       << "# The left camera is the first found (" << usable[0]->serial << "), the right the second ("
       << usable[1]->serial << "): swap them if the rig has them the other way. Check it: augrig rig show FILE\n";
  for (int c = 0; c < 2; ++c) {
    const AravisDeviceInfo& d = *usable[static_cast<std::size_t>(c)];
    RigCamera& cam = rig.cameras[static_cast<std::size_t>(c)];
    cam.model = CameraModel::pinhole_from_hfov(d.width_px, d.height_px, deg_to_rad(56.0));
    std::string uri = "aravis://" + d.serial;
    std::string params;
    if (!d.pixel_format.empty()) params += "format=" + d.pixel_format;
    if (d.frame_rate_hz > 0) params += std::string(params.empty() ? "" : "&") + "fps=" + fmt_ms(d.frame_rate_hz);
    cam.source_uri = params.empty() ? uri : uri + "?" + params;
  }
  std::ofstream f(path, std::ios::binary);
  f << head.str() << rig_to_yaml(rig);
  if (!f) runtime_error(path + ": cannot write the rig template");
}

int cameras_command(const std::vector<std::string>& args, std::ostream& out) {
  const std::vector<OptionSpec> specs = {
      {"no-open", ArgKind::kFlag, "", "list without opening each camera (no pixel formats, size or rate)"},
      {"rig", ArgKind::kValue, "RIG.yaml",
       "write a rig template for the first two GigE Vision / USB3 Vision cameras found: serial-based source "
       "URIs with their current format and rate, their resolution; intrinsics and mounting to replace with "
       "the calibration"},
  };
  const ParsedArgs a = parse_or_usage(args, specs);
  if (a.help) {
    out << format_help(
        "augrig cameras [--no-open]",
        "Lists the GigE Vision / USB3 Vision cameras Aravis discovers and the V4L2 capture devices,\n"
        "with model, serial, address and pixel formats, and the URI that opens each.",
        specs);
    return kExitOk;
  }
  if (a.has("rig") && a.has("no-open")) usage_error("--rig needs each camera opened (its size, format, rate)");
  const std::vector<AravisDeviceInfo> gige = list_aravis_devices(!a.has("no-open"));
  out << "Aravis (GigE Vision, USB3 Vision): " << gige.size() << " camera(s)\n";
  for (const AravisDeviceInfo& d : gige) {
    out << "  aravis://" << (d.address.empty() ? d.id : d.address) << "\n"
        << "    id " << d.id << ", " << d.vendor << " " << d.model << ", serial " << d.serial << ", "
        << d.protocol << (d.address.empty() ? "" : ", address " + d.address) << "\n";
    if (d.width_px > 0)
      out << "    now: " << d.width_px << "x" << d.height_px << " " << d.pixel_format << " at "
          << fmt_ms(d.frame_rate_hz) << " fps\n";
    if (!d.pixel_formats.empty()) {
      out << "    pixel formats:";
      for (const std::string& f : d.pixel_formats) out << " " << f;
      out << "\n";
    }
    if (!d.error.empty()) out << "    (not opened: " << d.error << ")\n";
  }
  if (a.has("rig")) {
    write_rig_template(a.get("rig"), gige);
    out << "Wrote the rig template " << a.get("rig") << ": its intrinsics and T_body_cam are placeholders "
        << "(check it with augrig rig show)\n";
  }
  auto v4l2 = list_v4l2_devices();
  if (!v4l2) {
    out << "V4L2: " << user_message(v4l2.error()) << "\n";
    return kExitOk;
  }
  out << "V4L2: " << v4l2->size() << " capture device(s)\n";
  for (const V4l2DeviceInfo& d : *v4l2) {
    out << "  v4l2://" << d.path << "\n    " << d.card << " (driver " << d.driver << ", bus " << d.bus_info
        << ")\n";
    if (!d.error.empty()) out << "    (not opened: " << d.error << ")\n";
    if (!d.formats.empty()) {
      out << "    pixel formats:";
      for (const V4l2FormatInfo& f : d.formats)
        out << " " << fourcc_to_string(f.fourcc) << (f.supported ? "" : "(unsupported)");
      out << "\n";
    }
  }
  return kExitOk;
}

// ---- run -------------------------------------------------------------------------------------

// --serve [ADDRESS:]PORT (and --serve-queue-mb): the Foxglove WebSocket server, listening.
std::shared_ptr<net::FoxgloveServer> start_live_view(const ParsedArgs& a, const Rig& rig) {
  const std::string v = a.get("serve");
  net::ServeOptions o;
  const std::size_t colon = v.rfind(':');
  if (colon != std::string::npos) {
    o.address = v.substr(0, colon);
    if (o.address.size() >= 2 && o.address.front() == '[' && o.address.back() == ']')
      o.address = o.address.substr(1, o.address.size() - 2);  // [::1]:8765
    if (o.address.empty()) usage_error("--serve: expected [ADDRESS:]PORT, got '" + v + "'");
  }
  o.port = static_cast<int>(parse_integer("serve", v.substr(colon == std::string::npos ? 0 : colon + 1), 0, 65535));
  if (a.has("serve-queue-mb"))
    o.client_queue_bytes =
        static_cast<std::size_t>(parse_integer("serve-queue-mb", a.get("serve-queue-mb"), 1, 4096)) << 20;
  o.metadata["rig"] = rig.source;
  return unwrap(net::FoxgloveServer::start(o, rig));
}

std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int) {
  g_stop.store(true);
}

}  // namespace

std::atomic<bool>* install_stop_signals() {
  g_stop = false;
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
  return &g_stop;
}

namespace {

const std::vector<OptionSpec>& run_specs() {
  static const std::vector<OptionSpec> specs = {
      rig_option("the sim scenario's for sim://, the recording's for replay://, else the paper's; its cameras' "
                 "'source' keys name the sources"),
      {"source", ArgKind::kValue, "URI",
       "frame source: sim://SCENARIO, replay://DIR, stereo:[..]//{L}{R} (docs/CAPTURE.md); overrides the "
       "rig's"},
      scene_option("the simulation's truth for sim://, the recorded poses for replay://"),
      poses_option(),
      pose_tolerance_option(),
      boom_option("the pose source's boom where it has one, a scene or a recording; else track"),
      receiver_draw_option(),
      look_option(),
      sink_option(),
      {"record", ArgKind::kValue, "DIR", "record raw, augmented and mask frames with poses and statistics"},
      {"overwrite", ArgKind::kFlag, "", "with --record: replace a recording already in DIR"},
      {"capture-only", ArgKind::kFlag, "",
       "record (and show) the cameras' frames raw, augmenting nothing: no boom, masks or statistics; the "
       "poses are recorded where a pose source is given (none is needed). A rig without a boom section "
       "means this. Augment later: augrig replay DIR --record NEW --rig RIG_WITH_BOOM"},
      {"frames", ArgKind::kValue, "N", "stop after N augmented stereo frames"},
      {"duration", ArgKind::kValue, "S", "stop after S seconds (default: until the source ends or Ctrl-C)"},
      {"out", ArgKind::kValue, "DIR", "write stats.csv (and with --every, images) here"},
      {"every", ArgKind::kValue, "K", "with --out: write the images of every K-th stereo frame"},
      {"ground-truth", ArgKind::kFlag, "",
       "with --every: " + std::string(kGroundTruthHelp) +
           "; with --record: store each frame's receiver depth in the recording (export --ground-truth writes "
           "the rest from it)"},
      {"nav", ArgKind::kValue, "STREAM=URI,...|sim",
       "live nav inputs, recorded as received and, for streams named tanker.* and receiver.*, fused in "
       "real time into the receiver's pose at each frame's mid-exposure, e.g. tanker.gps=udp://0.0.0.0:10110?"
       "format=nmea,tanker.imu=udp://0.0.0.0:10111?format=imu,receiver.gps=gpsd://127.0.0.1 "
       "(docs/NAV_LIVE.md). 'sim' with sim://: the simulated GPS and IMU of both aircraft sent over UDP "
       "on loopback in real time and received through the same inputs"},
      {"aircraft", ArgKind::kValue, "tanker=FILE,receiver=FILE",
       "each aircraft's aircraft.yaml (GPS lever arm, IMU noise, time offsets; docs/NAV_FORMATS.md) for "
       "the live fusion (default with --nav sim: the scenario's; otherwise the defaults)"},
      {"nav-stale", ArgKind::kValue, "S",
       "a frame's pose is stale when a fix or IMU sample of either aircraft is older than S at its "
       "mid-exposure (default 0.5)"},
      {"nav-fault", ArgKind::kValue, "STREAM=T0-T1,...",
       "with --nav sim: mute a simulated stream over scenario seconds [T0, T1], e.g. receiver.gps=10-13"},
      {"serve", ArgKind::kValue, "[ADDRESS:]PORT",
       "the live view over the network: a Foxglove WebSocket server (images, masks, poses, statistics, "
       "health; docs/LIVE_VIEW.md) on ADDRESS (default 127.0.0.1, loopback only) and PORT (0: any free one)"},
      {"serve-queue-mb", ArgKind::kValue, "MB",
       "with --serve: each client's queue; what a slow client cannot take beyond it is dropped and counted "
       "(default 32)"},
      {"headless", ArgKind::kFlag, "", "no window even when a display is present (docs/DISPLAY.md)"},
      {"screenshot-at", ArgKind::kValue, "N",
       "with the window: a screenshot once the N-th pair is shown (into --out)"},
      {"status-every", ArgKind::kValue, "S", "print a status line every S seconds (default 1; 0: never)"},
  };
  return specs;
}

std::string fmt_us(std::int64_t ns) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << static_cast<double>(ns) / 1e3;
  return s.str();
}

// Everything run needs from its flags besides the pipeline's parts.
struct RunSetup {
  pipeline::PipelineParts parts;
  std::unique_ptr<LiveNav> live_nav;
  std::unique_ptr<NavInputs> nav_inputs;
  std::shared_ptr<std::unique_ptr<sim::NavStreamer>> nav_streamer;
  std::string banner;
};

// The live fusion of both aircraft's nav streams (--nav): their settings from the simulation
// (--nav sim) or defaults, each replaced by --aircraft's file; `ins_used` gets them.
std::unique_ptr<LiveNav> make_live_nav(const ParsedArgs& a, const Rig& rig,
                                       const Eigen::Vector3d& receptacle_m, const SimulatedFlight* sim,
                                       nav::InsConfig ins_used[2]) {
  if (sim) {
    ins_used[0] = ins_config_for(sim->scenario.sensors.tanker);
    ins_used[1] = ins_config_for(sim->scenario.sensors.receiver);
  }
  if (a.has("aircraft")) {
    for (const auto& [who, file] :
         parse_named_list_arg(a.get("aircraft"), "--aircraft: expected tanker=FILE,receiver=FILE")) {
      const auto ac = aircraft_of_stream(who);
      if (!ac) usage_error("--aircraft: expected tanker=FILE or receiver=FILE, got '" + who + "'");
      ins_used[static_cast<int>(*ac)] = unwrap(load_aircraft_config(file));
    }
  }
  LiveNavOptions nopt;
  if (a.has("nav-stale")) nopt.stale_after_s = parse_real("nav-stale", a.get("nav-stale"));
  if (!(nopt.stale_after_s > 0)) usage_error("--nav-stale: expected seconds > 0");
  return std::make_unique<LiveNav>(rig, BoomDimensions{}, receptacle_m, ins_used[0], ins_used[1], nopt);
}

int run_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  const ParsedArgs a = parse_or_usage(args, run_specs());
  if (a.help) {
    out << format_help(
        "augrig run [--rig RIG] [--source URI] [--scene SCENE.yaml|--poses POSES.csv|--nav ...] [--record DIR] "
        "[--duration S] [--headless]",
        "Runs the live pipeline: each camera captured on its own thread, frames paired by timestamp (each\n"
        "camera's clock related to host time continuously) or trigger id, the boom rendered into both\n"
        "views, occlusion statistics, and with --record everything recorded. Nothing is dropped silently:\n"
        "the summary gives the drops by stage, the pairs' skew and each camera's clock offset.",
        run_specs());
    return kExitOk;
  }
  const double duration_s = a.has("duration") ? parse_real("duration", a.get("duration")) : 0.0;
  if (duration_s < 0) usage_error("--duration: expected seconds >= 0");
  const double status_s = a.has("status-every") ? parse_real("status-every", a.get("status-every")) : 1.0;
  const int every = a.has("every") ? static_cast<int>(parse_integer("every", a.get("every"), 1, 1000000)) : 0;
  if (every && !a.has("out")) usage_error("--every needs --out");
  if (a.has("ground-truth") && !every && !a.has("record"))
    usage_error("--ground-truth needs --out DIR and --every K (the frames whose files are written) or --record DIR "
                "(stored in the recording)");
  const long long max_pairs = a.has("frames") ? parse_integer("frames", a.get("frames"), 1, 1LL << 40) : 0;

  // Sources: --source, else the rig's per-camera URIs.
  std::optional<Rig> rig;
  if (a.has("rig")) rig = load_rig_arg(a.get("rig"));
  // Capture only: asked for, or the rig has no boom to augment with.
  const bool capture_only = a.has("capture-only") || (rig && !rig->boom.configured);
  if (capture_only)
    for (const char* f : {"out", "every", "ground-truth", "boom", "receiver-draw", "scene"})
      if (a.has(f))
        usage_error(std::string("--") + f + ": nothing is augmented when capturing only" +
                    (a.has("capture-only") ? std::string(" (--capture-only)")
                                           : " (" + rig->source + " has no boom section: a capture-only rig)"));
  std::string uri = a.get("source"), right_uri;
  if (uri.empty()) {
    if (!rig) usage_error("give --source URI, or --rig RIG whose cameras have 'source' keys");
    uri = rig->left().source_uri;
    right_uri = rig->right().source_uri;
    if (uri.empty() || right_uri.empty())
      runtime_error(rig->source + ": cameras[0] and cameras[1] need a 'source' URI, or give --source");
  }
  // A source without poses of its own (cameras, datasets) needs a pose source: said before any
  // camera is opened. sim:// has its truth, replay:// its recorded poses.
  {
    const std::string scheme = uri.substr(0, uri.find_first_of(":"));
    const bool own_poses = scheme == "sim" || scheme == "replay";
    const bool nav_given = a.has("nav");  // checked in full below
    if (!own_poses && !a.has("scene") && !a.has("poses") && !nav_given && !capture_only)
      usage_error("a pose source is needed for " + uri +
                  ": --scene SCENE.yaml, --poses POSES.csv, or --nav with streams of both aircraft "
                  "(tanker.*, receiver.*)");
  }
  OpenedSource opened = unwrap(open_sources(uri, right_uri, rig ? rig->pairing : RigPairing{}));
  const OpenedSourceInfo info = opened;
  const bool is_sim = !opened.scenario.empty();
  // The rig: --rig, else the simulation's, the recording's, or the paper's.
  std::optional<Rig> recorded_rig;
  if (opened.replay)
    if (const std::string yaml = opened.replay->reader().meta("rig_yaml"); !yaml.empty())
      recorded_rig = unwrap(parse_rig(yaml, opened.replay->reader().path() + " (meta rig_yaml)"));
  if (!rig) rig = is_sim ? info.sim->scenario.rig : recorded_rig ? *recorded_rig : Rig::paper_default();
  if (rig->cameras.size() != 2)
    runtime_error(rig->source + ": the rig needs 2 cameras, has " + std::to_string(rig->cameras.size()));

  RunSetup setup;
  PipelineParts& parts = setup.parts;
  nav::InsConfig ins_used[2];  // the live fusion's aircraft settings
  parts.rig = *rig;
  parts.models = unwrap(load_rig_models(*rig));
  parts.source_info = info;
  const BoomDimensions boom_dims;

  // Where each frame's receiver pose comes from: a fixed scene, a poses CSV, the live nav, the
  // recording's own poses (replay://), or (sim://) the simulation's truth.
  const bool nav_sim = a.get("nav") == "sim";
  if (nav_sim && !is_sim) usage_error("--nav sim needs a sim:// source");
  if (a.has("nav-fault") && !nav_sim) usage_error("--nav-fault needs --nav sim");
  std::vector<std::pair<std::string, std::string>> nav_items;
  if (nav_sim) {
    // The simulated streams come in through the same UDP inputs as in flight (ports chosen free).
    for (const sim::NavStreamTarget& t : sim::loopback_targets(0, 0, 0, 0))
      nav_items.emplace_back(t.stream, std::string("udp://127.0.0.1:0?format=") +
                                           (t.kind == sim::NavStreamKind::kGps ? "nmea" : "imu"));
  } else if (a.has("nav")) {
    nav_items = parse_named_list_arg(a.get("nav"), "--nav: expected STREAM=URI (e.g. "
                                                   "tanker.gps=udp://0.0.0.0:10110?format=nmea)");
  }
  bool nav_of[2] = {false, false};
  for (const auto& item : nav_items)
    if (const auto ac = aircraft_of_stream(item.first)) nav_of[static_cast<int>(*ac)] = true;
  const bool use_nav = nav_of[0] && nav_of[1];
  if (a.has("scene") + a.has("poses") + use_nav > 1)
    usage_error("--scene, --poses and --nav with streams of both aircraft are three sources of poses: give one");
  if (a.has("nav") && !nav_sim && !use_nav && !a.has("scene") && !a.has("poses") && !opened.replay && !is_sim)
    usage_error("--nav needs streams of both aircraft (tanker.*, receiver.*) to give poses");
  PoseSources ps;
  ps.scene_path = a.get("scene", "");
  ps.boom_dims = boom_dims;
  ps.poses_csv_path = a.get("poses", "");
  ps.pose_tolerance_ns = parse_pose_tolerance(a);
  if (use_nav && ps.scene_path.empty() && ps.poses_csv_path.empty()) {
    setup.live_nav =
        make_live_nav(a, *rig, parts.models.receptacle_m, nav_sim ? info.sim.get() : nullptr, ins_used);
    ps.live_nav = parts.live_nav = setup.live_nav.get();
    if (nav_sim) {
      ps.camera_offset_ns = info.sim->scenario.sensors.cameras.clock_offset_ns;
      ps.camera_offset_ns.resize(2, 0);
    }
  }
  ps.recorded = opened.replay != nullptr;
  ps.recorded_rig = recorded_rig;
  if (is_sim) ps.sim = info.sim.get();
  parts.poses = unwrap(choose_poses(ps, *rig, parts.models.receptacle_m)).provider;
  if (!parts.poses && !capture_only)
    usage_error(
        "a pose source is needed: --scene SCENE.yaml, --poses POSES.csv, or --nav with streams of both "
        "aircraft (tanker.*, receiver.*)");
  parts.capture_only = capture_only;
  const std::string poses_text = parts.poses ? parts.poses->describe() : std::string("none (capture only)");
  if (a.has("boom")) parts.boom = parse_boom_arg(a.get("boom"));
  parts.augment.receiver_draw = parse_receiver_draw(a.get("receiver-draw"));
  apply_look_arg(a, parts.rig, parts.augment);
  apply_sink_args(a, parts);

  if (a.has("record")) {
    recorder::RecordingInfo rinfo;
    rinfo.rig_yaml = rig_to_yaml(*rig);
    rinfo.scene = a.has("scene") ? a.get("scene") : poses_text;
    if (capture_only) rinfo.extra["capture_only"] = "raw frames only: nothing augmented (augrig run --capture-only)";
    rinfo.clock_domains = opened.live ? "frames: each camera's device clock (t_ns, mid-exposure) and host "
                                        "CLOCK_MONOTONIC (t_host_ns); offsets in events 'clock_offset'"
                                      : "frames: the source's clocks as recorded";
    if (use_nav) {
      rinfo.clock_domains += "; nav inputs: arrival on host CLOCK_MONOTONIC, sensor times inside the data";
      // Each aircraft's settings, so that an export can re-fuse the recording offline.
      rinfo.extra["aircraft_yaml.tanker"] = aircraft_config_to_yaml(ins_used[0]);
      rinfo.extra["aircraft_yaml.receiver"] = aircraft_config_to_yaml(ins_used[1]);
    }
    rinfo.extra["source"] = uri + (right_uri.empty() ? "" : " + " + right_uri);
    if (opened.replay) rinfo.extra["re_augmented_from"] = opened.replay->reader().path();
    parts.recorder = create_recorder(a.get("record"), rinfo, a.has("overwrite"));
    parts.record_ground_truth = a.has("ground-truth");
  }
  // Live nav inputs: each read on a thread of its own; every unit recorded exactly as received.
  setup.nav_inputs = std::make_unique<NavInputs>();
  check(setup.nav_inputs->open(nav_items, parts.recorder.get(), setup.live_nav.get()));
  // --nav sim: the streams' sender, started with the first frame (the flight's clock starts there).
  if (nav_sim) {
    std::vector<sim::NavStreamTarget> targets = sim::loopback_targets(
        setup.nav_inputs->port("tanker.gps"), setup.nav_inputs->port("tanker.imu"),
        setup.nav_inputs->port("receiver.gps"), setup.nav_inputs->port("receiver.imu"));
    if (a.has("nav-fault")) {
      for (const auto& [stream, window] : parse_named_list_arg(a.get("nav-fault"), "--nav-fault: expected STREAM=T0-T1")) {
        double t0 = 0, t1 = 0;
        char extra = 0;
        if (std::sscanf(window.c_str(), "%lf-%lf%c", &t0, &t1, &extra) != 2 || !(t1 >= t0))
          usage_error("--nav-fault: expected STREAM=T0-T1 (scenario seconds), got '" + stream + "=" + window + "'");
        // A named copy: clang 14 cannot capture a structured binding in a lambda.
        const std::string& name = stream;
        auto it = std::find_if(targets.begin(), targets.end(),
                               [&](const sim::NavStreamTarget& t) { return t.stream == name; });
        if (it == targets.end())
          usage_error("--nav-fault: no stream '" + stream + "' (tanker.gps, tanker.imu, receiver.gps, receiver.imu)");
        it->mute_s.emplace_back(t0, t1);
      }
    }
    setup.nav_streamer = std::make_shared<std::unique_ptr<sim::NavStreamer>>();
    parts.on_first_frame = [streamer = setup.nav_streamer, targets, sim = info.sim,
                            clock = info.sim_clock](const StereoFrame&) {
      sim::NavStreamOptions so;
      so.scenario_start_gps_ns = sim->scenario.start_gps_ns;
      *streamer = unwrap(sim::NavStreamer::start(sim->logs, targets, clock, so));
    };
  }

  if (a.has("out")) {
    make_dirs(a.get("out"));
    parts.stats_csv = unwrap(StatsCsvWriter::create(fs::path(a.get("out")) / "stats.csv"));
    if (every) parts.frame_files = FrameFiles{a.get("out"), every, {}, a.has("ground-truth")};
  }
  const bool lossless = opened.options.lossless;
  // Cameras: how their frames pair (the stereo URI's or the rig's `pairing`).
  std::string pairing_text;
  if (opened.live) {
    const StereoPairerConfig& pc = opened.options.pairing;
    std::ostringstream p;
    p << "; pairing by " << to_string(pc.mode) << ", tolerance " << fmt_us(pc.tolerance_ns) << " us, "
      << (pc.clock_offsets ? "each camera's clock to host time" : "one clock");
    pairing_text = p.str();
  }
  // Started by the pipeline once its augmenter is ready (cameras capture from their start).
  parts.unstarted_source = std::make_unique<OpenedSource>(std::move(opened));
  parts.duration_s = duration_s;
  parts.max_pairs = static_cast<std::uint64_t>(max_pairs);
  parts.status_every_s = status_s;
  parts.stop_flag = install_stop_signals();
  parts.on_problem = [&err](const Error& e) { err << "augrig run: " << user_message(e) << "\n"; };
  const bool want_window = !a.has("headless");
  if (want_window && display_present()) parts.view = std::make_shared<LiveView>();
  if (a.has("serve")) {
    parts.serve = start_live_view(a, *rig);
    // Flushed: whoever starts the run (a script, a crew) reads the address at once.
    out << "live view: " << parts.serve->url() << " (Foxglove: open a connection, Foxglove WebSocket)" << std::endl;
  } else if (a.has("serve-queue-mb")) {
    usage_error("--serve-queue-mb needs --serve");
  }
  out << "run: " << uri << (right_uri.empty() ? "" : " + " + right_uri) << (lossless ? " (lockstep)" : " (live)") << pairing_text << "; rig "
      << rig->source << (capture_only ? "; capture only (nothing augmented)" : "") << "; poses from " << poses_text
      << (parts.recorder ? "; recording to " + parts.recorder->path() : std::string()) << "\n";
  // Each camera as it is set now: every setting in effect, the URI's and the device's own.
  for (const auto& src : parts.unstarted_source->sources)
    if (const std::string st = src->settings(); !st.empty()) out << "  " << src->uri() << ": " << st << "\n";
  parts.nav_inputs = setup.nav_inputs.get();
  if (setup.nav_streamer)
    parts.on_stop = [streamer = setup.nav_streamer] {
      if (*streamer) (*streamer)->stop();
    };

  Pipeline pipeline(std::move(parts));
  const PipelineReport report =
      run_pipeline(pipeline, want_window, a.has("out") ? a.get("out") : ".", out, err,
                   parse_screenshot_at(a));
  setup.nav_inputs->summary(out);
  if (report.recording_closed) {
    // The recorder's drops as its summary counts them: frames, and nav inputs and events.
    const recorder::RecorderStats& rs = report.recorder_stats;
    out << "recorded " << rs.frames_committed << " stereo frames to " << pipeline.parts().recorder->path() << " ("
        << rs.frames_dropped << " dropped by the recorder";
    if (rs.small_items_dropped) out << ", and " << rs.small_items_dropped << " nav inputs or events";
    out << ")\n";
    if (!*report.recording_closed) runtime_error("the recording stopped: " + user_message(report.recording_closed->error()));
  }
  if (!report.lost_cameras.empty()) {
    for (std::size_t i = 1; i < report.lost_cameras.size(); ++i) err << "augrig run: " << report.lost_cameras[i] << "\n";
    runtime_error(report.lost_cameras.front());
  }
  if (report.source_failed) return kExitRuntime;
  return kExitOk;
}

}  // namespace

int cmd_cameras(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("cameras", err, [&] { return cameras_command(args, out); });
}

int cmd_run(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("run", err, [&] { return run_command(args, out, err); });
}

}  // namespace augrig::app
