// augrig cameras: what capture devices this machine sees.
// augrig run: the live pipeline from source URIs: capture (a thread per camera) -> pairing (clock
// offsets estimated per camera) -> pose -> augmentation -> statistics and recorder; with a display, the
// live window on the main thread and the pipeline on a worker.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "app/cli.hpp"
#include "app/commands.hpp"
#include "app/run_config.hpp"
#include "capture/aravis_source.hpp"
#include "capture/v4l2_source.hpp"
#include "pipeline/live_nav.hpp"
#include "render/video_codec.hpp"
#include "sim/nav_stream.hpp"

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
       << usable[1]->serial
       << "): swap them if the rig has them the other way. Check it: augrig rig show FILE\n";
  for (int c = 0; c < 2; ++c) {
    const AravisDeviceInfo& d = *usable[static_cast<std::size_t>(c)];
    RigCamera& cam = rig.cameras[static_cast<std::size_t>(c)];
    cam.model = CameraModel::pinhole_from_hfov(d.width_px, d.height_px, deg_to_rad(56.0));
    std::string uri = "aravis://" + d.serial;
    std::string params;
    if (!d.pixel_format.empty()) params += "format=" + d.pixel_format;
    if (d.frame_rate_hz > 0)
      params += std::string(params.empty() ? "" : "&") + "fps=" + fmt_ms(d.frame_rate_hz);
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
  if (a.has("rig") && a.has("no-open"))
    usage_error("--rig needs each camera opened (its size, format, rate)");
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
      rig_option(
          "the sim scenario's for sim://, the recording's for replay://, else the paper's; its cameras' "
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
           "; with --record: store each frame's receiver depth in the recording (export --ground-truth "
           "writes "
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
      {"camera-clock", ArgKind::kValue, "online|off",
       "with the live nav: 'online' estimates each camera's clock offset and drift against GPS time from its "
       "images and the tanker's rates during the run, shows them (window, /diagnostics, summary), records "
       "them, and applies them to the poses once the offset's 1-sigma is small enough (default off; "
       "docs/CLOCK_OFFSETS.md)"},
      {"camera-clock-sigma-ms", ArgKind::kValue, "MS",
       "with --camera-clock online: apply an estimate once its offset's 1-sigma is at most MS (default 0.5)"},
      {"terrain-height-m", ArgKind::kValue, "H",
       "with --camera-clock online: the height of the ground the cameras see, metres above the ellipsoid, "
       "for the parallax (default 0)"},
      {"nav-fault", ArgKind::kValue, "STREAM=T0-T1,...",
       "with --nav sim: mute a simulated stream over scenario seconds [T0, T1], e.g. receiver.gps=10-13"},
      {"serve", ArgKind::kValue, "[ADDRESS:]PORT",
       "the live view over the network: a Foxglove WebSocket server (images, masks, poses, statistics, "
       "health; docs/LIVE_VIEW.md) on ADDRESS (default 127.0.0.1, loopback only) and PORT (0: any free one)"},
      {"serve-queue-mb", ArgKind::kValue, "MB",
       "with --serve: each client's queue; what a slow client cannot take beyond it is dropped and counted "
       "(default 32)"},
      {"serve-jpeg-quality", ArgKind::kValue, "Q",
       "with --serve: the JPEG quality of the compressed image topics, 1..100 (default 80)"},
      {"serve-h264-kbps", ArgKind::kValue, "K",
       "with --serve: the H.264 topics' bit-rate cap per view, kbit/s (default 4000; 0: none)"},
      {"serve-h264-preset", ArgKind::kValue, "P",
       "with --serve: x264's speed preset for the H.264 topics, ultrafast .. veryslow (default ultrafast: "
       "the cheapest; superfast codes about 25 % smaller for 1.5 times the CPU)"},
      {"headless", ArgKind::kFlag, "", "no window even when a display is present (docs/DISPLAY.md)"},
      {"screenshot-at", ArgKind::kValue, "N",
       "with the window: a screenshot once the N-th pair is shown (into --out)"},
      {"status-every", ArgKind::kValue, "S", "print a status line every S seconds (default 1; 0: never)"},
  };
  return specs;
}

// --serve [ADDRESS:]PORT (and --serve-queue-mb, --serve-jpeg-quality, --serve-h264-kbps,
// --serve-h264-preset): the Foxglove WebSocket server's options (it is started once the rig is known).
std::optional<net::ServeOptions> parse_serve(const ParsedArgs& a) {
  if (!a.has("serve")) {
    for (const char* k : {"serve-queue-mb", "serve-jpeg-quality", "serve-h264-kbps", "serve-h264-preset"})
      if (a.has(k)) usage_error(std::string("--") + k + " needs --serve");
    return std::nullopt;
  }
  const std::string v = a.get("serve");
  net::ServeOptions o;
  const std::size_t colon = v.rfind(':');
  if (colon != std::string::npos) {
    o.address = v.substr(0, colon);
    if (o.address.size() >= 2 && o.address.front() == '[' && o.address.back() == ']')
      o.address = o.address.substr(1, o.address.size() - 2);  // [::1]:8765
    if (o.address.empty()) usage_error("--serve: expected [ADDRESS:]PORT, got '" + v + "'");
  }
  o.port = static_cast<int>(
      parse_integer("serve", v.substr(colon == std::string::npos ? 0 : colon + 1), 0, 65535));
  if (a.has("serve-queue-mb"))
    o.client_queue_bytes =
        static_cast<std::size_t>(parse_integer("serve-queue-mb", a.get("serve-queue-mb"), 1, 4096)) << 20;
  if (a.has("serve-jpeg-quality"))
    o.jpeg_quality =
        static_cast<int>(parse_integer("serve-jpeg-quality", a.get("serve-jpeg-quality"), 1, 100));
  if (a.has("serve-h264-kbps"))
    o.h264_max_kbps =
        static_cast<int>(parse_integer("serve-h264-kbps", a.get("serve-h264-kbps"), 0, 1'000'000));
  if (a.has("serve-h264-preset")) {
    o.h264_preset = a.get("serve-h264-preset");
    if (!is_x264_preset(o.h264_preset))
      usage_error("--serve-h264-preset: expected one of " + x264_preset_names() + ", got '" + o.h264_preset +
                  "'");
  }
  return o;
}
// The frames, the outputs, the stops and the window.
void parse_run_outputs(const ParsedArgs& a, RunOptions& o) {
  if (a.has("duration")) o.duration_s = parse_duration_arg(a.get("duration"));
  if (a.has("status-every")) o.status_every_s = parse_real("status-every", a.get("status-every"));
  if (a.has("every")) o.every = static_cast<int>(parse_integer("every", a.get("every"), 1, 1000000));
  if (o.every && !a.has("out")) usage_error("--every needs --out");
  if (a.has("ground-truth") && !o.every && !a.has("record"))
    usage_error(
        "--ground-truth needs --out DIR and --every K (the frames whose files are written) or --record DIR "
        "(stored in the recording)");
  if (a.has("frames")) o.max_pairs = parse_max_pairs_arg(a.get("frames"));
  o.source_uri = a.get("source");
  if (a.has("rig")) o.rig = a.get("rig");
  o.capture_only = a.has("capture-only");
  if (a.has("record")) o.record = a.get("record");
  o.overwrite = a.has("overwrite");
  if (a.has("out")) o.out = a.get("out");
  o.ground_truth = a.has("ground-truth");
  o.serve = parse_serve(a);
  o.headless = a.has("headless");
  o.screenshot_at = parse_screenshot_at(a);
}

// --nav-fault STREAM=T0-T1,...: each a simulated stream's name and a window of scenario seconds.
std::vector<NavFault> parse_nav_faults(const std::string& v) {
  std::vector<NavFault> faults;
  const std::vector<sim::NavStreamTarget> streams = sim::loopback_targets(0, 0, 0, 0);
  for (const auto& [stream, window] : parse_named_list_arg(v, "--nav-fault: expected STREAM=T0-T1")) {
    NavFault f{stream};
    char extra = 0;
    if (std::sscanf(window.c_str(), "%lf-%lf%c", &f.t0_s, &f.t1_s, &extra) != 2 || !(f.t1_s >= f.t0_s))
      usage_error("--nav-fault: expected STREAM=T0-T1 (scenario seconds), got '" + stream + "=" + window +
                  "'");
    if (std::none_of(streams.begin(), streams.end(),
                     [&](const sim::NavStreamTarget& t) { return t.stream == f.stream; }))
      usage_error("--nav-fault: no stream '" + stream +
                  "' (tanker.gps, tanker.imu, receiver.gps, receiver.imu)");
    faults.push_back(f);
  }
  return faults;
}

// Streams of both aircraft (tanker.*, receiver.*): the live nav gives poses.
bool streams_of_both_aircraft(const std::vector<std::pair<std::string, std::string>>& items) {
  bool nav_of[2] = {false, false};
  for (const auto& item : items)
    if (const auto ac = aircraft_of_stream(item.first)) nav_of[static_cast<int>(*ac)] = true;
  return nav_of[0] && nav_of[1];
}

// --camera-clock online|off, --camera-clock-sigma-ms, --terrain-height-m.
void parse_camera_clock(const ParsedArgs& a, RunOptions& o) {
  const std::string v = a.get("camera-clock", "off");
  if (v != "online" && v != "off") usage_error("--camera-clock: expected online or off, got '" + v + "'");
  o.camera_clock_online = v == "online";
  if (!o.camera_clock_online && (a.has("camera-clock-sigma-ms") || a.has("terrain-height-m")))
    usage_error("--camera-clock-sigma-ms and --terrain-height-m need --camera-clock online");
  if (a.has("camera-clock-sigma-ms")) {
    o.camera_clock_apply_sigma_ms = parse_real("camera-clock-sigma-ms", a.get("camera-clock-sigma-ms"));
    if (!(o.camera_clock_apply_sigma_ms > 0 && o.camera_clock_apply_sigma_ms <= 100))
      usage_error("--camera-clock-sigma-ms: expected milliseconds in (0, 100]");
  }
  if (a.has("terrain-height-m")) {
    o.terrain_height_m = parse_real("terrain-height-m", a.get("terrain-height-m"));
    if (!(std::abs(o.terrain_height_m) <= 10000))
      usage_error("--terrain-height-m: expected metres in [-10000, 10000]");
  }
}

// The pose sources: a scene, a poses CSV, the live nav's streams and its settings (read only where
// the live nav fuses: streams of both aircraft).
void parse_run_poses(const ParsedArgs& a, RunOptions& o) {
  if (a.has("scene")) o.scene = a.get("scene");
  if (a.has("poses")) o.poses_csv = a.get("poses");
  o.nav_given = a.has("nav");
  o.nav_sim = a.get("nav") == "sim";
  if (a.has("nav-fault") && !o.nav_sim) usage_error("--nav-fault needs --nav sim");
  if (o.nav_given && !o.nav_sim)
    o.nav_streams = parse_named_list_arg(a.get("nav"),
                                         "--nav: expected STREAM=URI (e.g. "
                                         "tanker.gps=udp://0.0.0.0:10110?format=nmea)");
  if (o.nav_sim || streams_of_both_aircraft(o.nav_streams)) {
    if (a.has("aircraft"))
      for (const auto& [who, file] :
           parse_named_list_arg(a.get("aircraft"), "--aircraft: expected tanker=FILE,receiver=FILE")) {
        if (!aircraft_of_stream(who))
          usage_error("--aircraft: expected tanker=FILE or receiver=FILE, got '" + who + "'");
        o.aircraft.emplace_back(who, file);
      }
    if (a.has("nav-stale")) o.nav_stale_s = parse_real("nav-stale", a.get("nav-stale"));
    if (o.nav_stale_s && !(*o.nav_stale_s > 0)) usage_error("--nav-stale: expected seconds > 0");
  }
  if (o.nav_sim && a.has("nav-fault")) o.nav_faults = parse_nav_faults(a.get("nav-fault"));
  parse_camera_clock(a, o);
}

// The boom, the receiver's drawing, the look and the sinks.
void parse_run_augmentation(const ParsedArgs& a, RunOptions& o) {
  if (a.has("boom")) o.boom = parse_boom_arg(a.get("boom"));
  if (a.has("receiver-draw")) o.receiver_draw = parse_receiver_draw(a.get("receiver-draw"));
  o.look = parse_look_arg(a.get("look", "camera"));
  o.sinks = a.all("sink");
}

int run_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  const ParsedArgs a = parse_or_usage(args, run_specs());
  if (a.help) {
    out << format_help(
        "augrig run [--rig RIG] [--source URI] [--scene SCENE.yaml|--poses POSES.csv|--nav ...] [--record "
        "DIR] "
        "[--duration S] [--headless]",
        "Runs the live pipeline: each camera captured on its own thread, frames paired by timestamp (each\n"
        "camera's clock related to host time continuously) or trigger id, the boom rendered into both\n"
        "views, occlusion statistics, and with --record everything recorded. Nothing is dropped silently:\n"
        "the summary gives the drops by stage, the pairs' skew and each camera's clock offset.",
        run_specs());
    return kExitOk;
  }
  RunOptions o;
  parse_run_outputs(a, o);
  parse_run_poses(a, o);
  o.pose_tolerance_ns = parse_pose_tolerance(a);
  parse_run_augmentation(a, o);
  return run_live(o, out, err);
}

}  // namespace

int cmd_cameras(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("cameras", err, [&] { return cameras_command(args, out); });
}

int cmd_run(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("run", err, [&] { return run_command(args, out, err); });
}

}  // namespace augrig::app
