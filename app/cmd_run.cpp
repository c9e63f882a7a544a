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
#include <thread>

#include "app/cli.hpp"
#include "app/commands.hpp"
#include "app/display.hpp"
#include "app/flight_nav.hpp"
#include "app/live_nav.hpp"
#include "app/scene_file.hpp"
#include "app/sources.hpp"
#include "capture/aravis_source.hpp"
#include "capture/v4l2_source.hpp"
#include "core/clock.hpp"
#include "core/thread_name.hpp"
#include "nav/imu_stream.hpp"
#include "nav/live_input.hpp"
#include "recorder/recorder.hpp"
#include "sim/flight_source.hpp"
#include "sim/nav_stream.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "sim/sim_clock.hpp"

namespace augrig::app {
namespace {

// ---- cameras ---------------------------------------------------------------------------------

int cameras_command(const std::vector<std::string>& args, std::ostream& out) {
  const std::vector<OptionSpec> specs = {
      {"no-open", ArgKind::kFlag, "", "list without opening each camera (no pixel formats)"},
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
  const std::vector<AravisDeviceInfo> gige = list_aravis_devices(!a.has("no-open"));
  out << "Aravis (GigE Vision, USB3 Vision): " << gige.size() << " camera(s)\n";
  for (const AravisDeviceInfo& d : gige) {
    out << "  aravis://" << (d.address.empty() ? d.id : d.address) << "\n"
        << "    id " << d.id << ", " << d.vendor << " " << d.model << ", serial " << d.serial << ", "
        << d.protocol << (d.address.empty() ? "" : ", address " + d.address) << "\n";
    if (!d.pixel_formats.empty()) {
      out << "    pixel formats:";
      for (const std::string& f : d.pixel_formats) out << " " << f;
      out << "\n";
    }
    if (!d.error.empty()) out << "    (not opened: " << d.error << ")\n";
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

const std::vector<OptionSpec>& run_specs() {
  static const std::vector<OptionSpec> specs = {
      {"rig", ArgKind::kValue, "RIG.yaml|default",
       "the rig (cameras, boom, receiver); its cameras' 'source' keys name the sources. Default: the sim "
       "scenario's rig for sim://, else the paper's"},
      {"source", ArgKind::kValue, "URI",
       "frame source: sim://SCENARIO, replay://DIR, stereo:[..]//{L}{R} (docs/CAPTURE.md); overrides the "
       "rig's"},
      {"scene", ArgKind::kValue, "SCENE.yaml",
       "a fixed scene (boom articulation, receiver pose); sim:// without it uses the simulation's truth"},
      {"boom", ArgKind::kValue, "track|fixed:EL,AZ,EXT|script:FILE",
       "boom articulation (default: the scene's)"},
      {"record", ArgKind::kValue, "DIR", "record raw, augmented and mask frames with poses and statistics"},
      {"duration", ArgKind::kValue, "S", "stop after S seconds (default: until the source ends or Ctrl-C)"},
      {"out", ArgKind::kValue, "DIR", "write stats.csv (and with --every, images) here"},
      {"every", ArgKind::kValue, "K", "with --out: write the images of every K-th stereo frame"},
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
      {"headless", ArgKind::kFlag, "", "no window even when a display is present (docs/DISPLAY.md)"},
      {"status-every", ArgKind::kValue, "S", "print a status line every S seconds (default 1; 0: never)"},
  };
  return specs;
}

// The simulation's truth per camera frame, for sim:// runs without a scene or nav.
struct SimTruth {
  std::map<std::pair<int, TimestampNs>, sim::FrameTruth> by_frame;
};
SimTruth sim_truth(const SimulatedFlight& sim) {
  SimTruth t;
  for (const sim::FrameTruth& f : sim::frame_truths(sim.scenario, *sim.flight, sim.logs.cameras))
    t.by_frame[{f.camera, f.t_camera_ns}] = f;
  return t;
}

// The last frames' latencies (ms) for the HUD's p50/p99.
class RollingLatency {
 public:
  void add(double ms) {
    if (values_.size() == 300) values_.erase(values_.begin());
    values_.push_back(ms);
  }
  LatencyHud hud() const {
    LatencyHud h;
    if (values_.empty()) return h;
    std::vector<double> v = values_;
    std::sort(v.begin(), v.end());
    h.p50_ms = v[v.size() / 2];
    h.p99_ms = v[std::min(v.size() - 1, v.size() * 99 / 100)];
    return h;
  }

 private:
  std::vector<double> values_;
};

std::string fmt_us(std::int64_t ns) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << static_cast<double>(ns) / 1e3;
  return s.str();
}

// The run's live nav inputs: "STREAM=URI,..." opened, each read on its own thread, each unit of
// input pushed to the recorder as received (NavInputRecord: text lines and gpsd reports as TEXT,
// IMU datagrams as BLOB), the parsed events counted and, for streams of an aircraft (tanker.*,
// receiver.*), fed to the live fusion.
class NavInputs {
 public:
  // "STREAM=URI,..." split, checked (usage errors name the item).
  static std::vector<std::pair<std::string, std::string>> parse(const std::string& spec) {
    std::vector<std::pair<std::string, std::string>> items;
    std::size_t pos = 0;
    while (pos <= spec.size()) {
      const std::size_t comma = std::min(spec.find(',', pos), spec.size());
      const std::string item = spec.substr(pos, comma - pos);
      pos = comma + 1;
      if (item.empty()) continue;
      const std::size_t eq = item.find('=');
      if (eq == std::string::npos || eq == 0)
        usage_error("--nav: expected STREAM=URI (e.g. tanker.gps=udp://0.0.0.0:10110?format=nmea), got '" +
                    item + "'");
      items.emplace_back(item.substr(0, eq), item.substr(eq + 1));
    }
    return items;
  }

  void open(const std::vector<std::pair<std::string, std::string>>& items, recorder::Recorder* rec,
            LiveNav* live_nav) {
    for (const auto& [stream, uri] : items) {
      Input in;
      in.stream = stream;
      in.aircraft = aircraft_of_stream(stream);
      in.input = unwrap(nav::open_nav_input(uri));
      inputs_.push_back(std::move(in));
    }
    for (Input& in : inputs_) {
      if (rec) {
        in.input->set_raw_tap(
            [rec, stream = in.stream](std::string_view data, TimestampNs arrival_ns, bool binary) {
              recorder::NavInputRecord r;
              r.stream = stream;
              r.clock = ClockDomain::kUnknown;  // the sensor time is inside the data
              r.arrival_ns = arrival_ns;
              r.data = std::string(data);
              r.binary = binary;
              rec->push(std::move(r));
            });
      }
      in.thread = std::thread([this, &in, live_nav] {
        set_thread_name("augrig-nav");
        nav::NavEvent e;
        while (!stop_) {
          auto r = in.input->read(e, std::chrono::milliseconds(100));
          if (!r) {
            in.error = r.error().message;
            return;
          }
          if (*r == nav::NavReadStatus::kEnd) return;
          if (*r != nav::NavReadStatus::kEvent) continue;
          (e.is_imu() ? in.imu : in.fixes)++;
          if (live_nav && in.aircraft) live_nav->add(*in.aircraft, e);
        }
      });
    }
  }
  // The UDP port a stream's input is bound to (0: not a UDP input).
  std::uint16_t port(const std::string& stream) const {
    for (const Input& in : inputs_) {
      if (in.stream != stream) continue;
      if (const auto* u = dynamic_cast<const nav::UdpNmeaInput*>(in.input.get())) return u->port();
      if (const auto* u = dynamic_cast<const nav::UdpImuInput*>(in.input.get())) return u->port();
    }
    return 0;
  }
  void stop() {
    stop_ = true;
    for (Input& in : inputs_)
      if (in.thread.joinable()) in.thread.join();
  }
  ~NavInputs() { stop(); }
  void summary(std::ostream& out) const {
    for (const Input& in : inputs_) {
      const nav::NavInputStats st = in.input->stats();
      out << "nav " << in.stream << " (" << in.input->uri() << "): " << in.fixes << " fixes, " << in.imu
          << " IMU samples; malformed " << st.malformed << ", oversized " << st.oversized << ", lost "
          << st.dropped << (in.error.empty() ? "" : "; stopped: " + in.error)
          << (st.last_errors.empty() ? "" : "; last problem: " + st.last_errors.back()) << "\n";
    }
  }
  void ledger(recorder::Recorder& rec) const {
    for (const Input& in : inputs_) {
      const nav::NavInputStats st = in.input->stats();
      const std::uint64_t lost = st.malformed + st.oversized + st.dropped;
      if (lost)
        rec.push(recorder::DropRecord{recorder::DropStage::kTransport, lost, 0, 0,
                                      in.stream + ": malformed, oversized or lost nav input", "nav_input"});
    }
  }

 private:
  struct Input {
    std::string stream;
    std::optional<Aircraft> aircraft;
    std::unique_ptr<nav::NavInput> input;
    std::thread thread;
    std::uint64_t fixes = 0, imu = 0;
    std::string error;
  };
  std::deque<Input> inputs_;  // stable addresses for the threads
  std::atomic<bool> stop_{false};
};

// Latencies over the whole run, for the summary: SkewStats is a log-binned histogram of |ns|
// (bins 9 % wide, quantiles capped at the max), constant memory, as good for latency as for skew.
using LatencyHistogram = SkewStats;

int run_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  const ParsedArgs a = parse_or_usage(args, run_specs());
  if (a.help) {
    out << format_help(
        "augrig run [--rig RIG] [--source URI] [--scene SCENE.yaml] [--record DIR] [--duration S] "
        "[--headless]",
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

  // Sources: --source, else the rig's per-camera URIs.
  std::optional<Rig> rig;
  if (a.has("rig")) rig = load_rig_arg(a.get("rig"));
  std::string uri = a.get("source"), right_uri;
  if (uri.empty()) {
    if (!rig) usage_error("give --source URI, or --rig RIG whose cameras have 'source' keys");
    uri = rig->left().source_uri;
    right_uri = rig->right().source_uri;
    if (uri.empty() || right_uri.empty())
      runtime_error(rig->source + ": cameras[0] and cameras[1] need a 'source' URI, or give --source");
  }
  OpenedSource opened = unwrap(open_sources(uri, right_uri, rig ? rig->pairing : RigPairing{}));
  // sim://: the flight (kept here: `opened` is handed to the stereo source below).
  const std::shared_ptr<const SimulatedFlight> sim_flight = opened.sim;
  const bool is_sim = !opened.scenario.empty();
  if (!rig) rig = is_sim ? sim_flight->scenario.rig : Rig::paper_default();
  const ReceiverSetup receiver = receiver_setup(*rig);
  const BoomDimensions boom_dims;

  // Where each frame's receiver pose comes from: a fixed scene, the live nav, or (sim:// without
  // --nav) the simulation's truth.
  std::optional<SceneState> fixed_scene;
  if (a.has("scene"))
    fixed_scene = unwrap(load_scene(a.get("scene"), *rig, boom_dims, receiver.receptacle_m));
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
    nav_items = NavInputs::parse(a.get("nav"));
  }
  bool nav_of[2] = {false, false};
  for (const auto& item : nav_items)
    if (const auto ac = aircraft_of_stream(item.first)) nav_of[static_cast<int>(*ac)] = true;
  const bool use_nav = !fixed_scene && nav_of[0] && nav_of[1];
  std::optional<SimTruth> truth;
  if (!fixed_scene && !use_nav) {
    if (!is_sim)
      usage_error(
          "a pose source is needed: --scene SCENE.yaml, or --nav with streams of both aircraft "
          "(tanker.*, receiver.*)");
    truth = sim_truth(*sim_flight);
  }
  std::optional<BoomArg> boom_arg;
  if (a.has("boom")) boom_arg = parse_boom_arg(a.get("boom"));

  // The live fusion: each aircraft's settings from --aircraft, the scenario (--nav sim), or defaults.
  std::unique_ptr<LiveNav> live_nav;
  const sim::SensorLogs* sim_logs = nullptr;
  if (use_nav) {
    nav::InsConfig ins[2];
    if (nav_sim) {
      ins[0] = ins_config_for(sim_flight->scenario.sensors.tanker);
      ins[1] = ins_config_for(sim_flight->scenario.sensors.receiver);
    }
    if (a.has("aircraft")) {
      for (const auto& [who, file] : NavInputs::parse(a.get("aircraft"))) {
        const auto ac = aircraft_of_stream(who);
        if (!ac) usage_error("--aircraft: expected tanker=FILE or receiver=FILE, got '" + who + "'");
        ins[static_cast<int>(*ac)] = unwrap(load_aircraft_config(file));
      }
    }
    LiveNavOptions nopt;
    if (a.has("nav-stale")) nopt.stale_after_s = parse_real("nav-stale", a.get("nav-stale"));
    if (!(nopt.stale_after_s > 0)) usage_error("--nav-stale: expected seconds > 0");
    live_nav = std::make_unique<LiveNav>(*rig, boom_dims, receiver.receptacle_m, ins[0], ins[1], nopt);
    if (nav_sim) sim_logs = &sim_flight->logs;
  }

  std::unique_ptr<recorder::Recorder> rec;
  if (a.has("record")) {
    recorder::RecordingInfo info;
    info.rig_yaml = rig_to_yaml(*rig);
    info.scene = fixed_scene ? a.get("scene")
                 : use_nav   ? "live nav (" + a.get("nav") + ")"
                             : "sim truth of " + opened.scenario;
    info.clock_domains = opened.live ? "frames: each camera's device clock (t_ns, mid-exposure) and host "
                                       "CLOCK_MONOTONIC (t_host_ns); offsets in events 'clock_offset'"
                                     : "frames: the source's clocks as recorded";
    if (use_nav)
      info.clock_domains += "; nav inputs: arrival on host CLOCK_MONOTONIC, sensor times inside the data";
    info.extra["source"] = uri + (right_uri.empty() ? "" : " + " + right_uri);
    rec = unwrap(recorder::Recorder::create(a.get("record"), info));
  }
  // Live nav inputs: each read on a thread of its own; every unit recorded exactly as received.
  NavInputs nav_inputs;
  nav_inputs.open(nav_items, rec.get(), live_nav.get());
  // --nav sim: the streams' sender, started with the first frame (the flight's clock starts there).
  std::vector<sim::NavStreamTarget> nav_targets;
  std::unique_ptr<sim::NavStreamer> nav_streamer;
  if (nav_sim) {
    nav_targets = sim::loopback_targets(nav_inputs.port("tanker.gps"), nav_inputs.port("tanker.imu"),
                                        nav_inputs.port("receiver.gps"), nav_inputs.port("receiver.imu"));
    if (a.has("nav-fault")) {
      for (const auto& [stream, window] : NavInputs::parse(a.get("nav-fault"))) {
        double t0 = 0, t1 = 0;
        char extra = 0;
        if (std::sscanf(window.c_str(), "%lf-%lf%c", &t0, &t1, &extra) != 2 || !(t1 >= t0))
          usage_error("--nav-fault: expected STREAM=T0-T1 (scenario seconds), got '" + stream + "=" + window +
                      "'");
        // A named copy: clang 14 cannot capture a structured binding in a lambda.
        const std::string& name = stream;
        auto it = std::find_if(nav_targets.begin(), nav_targets.end(),
                               [&](const sim::NavStreamTarget& t) { return t.stream == name; });
        if (it == nav_targets.end())
          usage_error("--nav-fault: no stream '" + stream +
                      "' (tanker.gps, tanker.imu, receiver.gps, receiver.imu)");
        it->mute_s.emplace_back(t0, t1);
      }
    }
  }
  // The simulation's cameras are calibrated to GPS time (their clock offsets are known).
  std::vector<TimestampNs> sim_camera_offsets;
  if (sim_flight) {
    sim_camera_offsets = sim_flight->scenario.sensors.cameras.clock_offset_ns;
    sim_camera_offsets.resize(2, 0);
  }
  const std::shared_ptr<sim::SimClock> sim_clock = opened.sim_clock;

  std::optional<StatsCsv> csv;
  if (a.has("out")) {
    make_dirs(a.get("out"));
    csv.emplace(fs::path(a.get("out")) / "stats.csv");
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
  auto stereo = unwrap(start_stereo(std::move(opened)));
  out << "run: " << stereo->uri() << (lossless ? " (lockstep)" : " (live)") << pairing_text << "; rig "
      << rig->source << "; poses from "
      << (fixed_scene ? "the scene " + a.get("scene")
          : use_nav   ? std::string("the live nav (GPS/INS of both aircraft)")
                      : std::string("the simulation's truth"))
      << (rec ? "; recording to " + rec->path() : std::string()) << "\n";

  // The window, when a display is present and --headless was not given.
  // The window runs on this thread; the pipeline (augmentation, recording) on a worker with its
  // own EGL context, handing over each augmented pair (by swap) and the HUD, and taking commands.
  std::unique_ptr<Display> display;
  struct Shared {
    std::mutex mutex;
    StereoResult result;
    SceneState scene;
    std::uint64_t id = 0;
    HudState hud;
    DisplayCommands commands;  // from the window, for the pipeline
    bool done = false;
    TimestampNs mid_exposure_host_ns = 0;  // of the pair with `id` (0: unknown)
    // Mid-exposure to the window (or, headless, to the hand-off): the HUD's last frames and the run's.
    RollingLatency latency_display;
    LatencyHistogram display_hist;
  } shared;
  if (!a.has("headless") && std::getenv("DISPLAY") && *std::getenv("DISPLAY")) {
    DisplayOptions dopt;
    dopt.screenshot_dir = a.has("out") ? a.get("out") : ".";
    dopt.receiver_model = receiver.model;
    auto d = Display::create(dopt);
    if (d) {
      display = std::move(*d);
      out << "run: live display open (F1 lists the keys)\n";
    } else {
      err << "augrig run: no window: " << user_message(d.error()) << "; running headless\n";
    }
  }
  bool recording_on = rec != nullptr, paused = false;
  DisplayBoomMode boom_mode = !boom_arg ? DisplayBoomMode::kFixed
                              : boom_arg->mode == BoomMode::kTrackReceptacle
                                  ? DisplayBoomMode::kTrackReceptacle
                              : boom_arg->mode == BoomMode::kScripted ? DisplayBoomMode::kScripted
                                                                      : DisplayBoomMode::kFixed;
  std::optional<BoomArticulation> interactive_boom;
  RollingLatency latency_recorder;
  LatencyHistogram recorder_hist;
  std::uint64_t shown_id = 0;
  TimestampNs shown_mid_host_ns = 0;
  SceneState shown_scene;
  bool have_shown = false;

  g_stop = false;
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);

  const auto t0 = Clock::now();
  auto next_status = t0 + std::chrono::duration<double>(status_s);
  auto next_clocks = t0;
  RunSummary all;
  std::size_t no_pose = 0, stale_pairs = 0, processing_drops = 0;
  TimeSpan processing_failed_t;  // the pairs whose augmentation failed (t_key_ns), for the ledger
  bool was_stale = false, recorder_failed = false;
  std::optional<BoomArticulation> last_boom;
  std::vector<ClockOffsetLog> clocks;  // the cameras' clock estimates, refreshed each second
  FrameNav frame_nav;
  double augment_ms = 0;
  Rasterizer rasterizer = Rasterizer::kAuto;  // what the augmenter chose (the summary says)
  std::vector<std::string> last_health(stereo->sources().size());
  StereoResult result;
  TimestampNs first_t_ns = 0;
  bool source_failed = false;
  auto log_event = [&](const std::string& text) {
    out << "  " << text << "\n";
    if (rec) rec->push(recorder::EventRecord{monotonic_now_ns(), ClockDomain::kHostMonotonic, text});
  };
  // The pipeline: its GL context and augmenter live on the thread that runs it.
  auto pipeline = [&] {
    const auto gl = make_gl_context();
    AugmentOptions aug_options;
    aug_options.receiver_model = receiver.model;
    // Only the boxes the boom changes: the recorder stores no more; the window and the PNG files
    // get whole images made for them.
    aug_options.augmented_output = AugmentedOutput::kChangedBox;
    const auto augmenter = unwrap(Augmenter::create(*rig, aug_options));
    rasterizer = augmenter->rasterizer();
    for (;;) {
      if (g_stop) {
        out << "run: stopped by signal\n";
        break;
      }
      if (duration_s > 0 && std::chrono::duration<double>(Clock::now() - t0).count() >= duration_s) break;
      StereoFrame frame;
      auto r = stereo->read(frame, std::chrono::milliseconds(200));
      // Camera state changes are events: printed, and recorded with the frames.
      const std::vector<SourceHealth> health = stereo->health();
      for (std::size_t i = 0; i < health.size(); ++i)
        if (health[i].message != last_health[i]) {
          if (!last_health[i].empty() || !health[i].connected) log_event(health[i].message);
          last_health[i] = health[i].message;
        }
      if (!r) {
        err << "augrig run: " << user_message(r.error()) << "\n";
        source_failed = true;
        break;
      }
      if (*r == ReadStatus::kEndOfStream) break;
      if (*r == ReadStatus::kFrame) {
        if (!first_t_ns) {
          first_t_ns = frame.left.t_ns;
          // --nav sim: the nav streams start with the flight's first frame (on the same clock).
          if (sim_logs) {
            sim::NavStreamOptions so;
            so.scenario_start_gps_ns = sim_flight->scenario.start_gps_ns;
            nav_streamer = unwrap(sim::NavStreamer::start(*sim_logs, nav_targets, sim_clock, so));
          }
        }
        // Each camera's mid-exposure on the host clock: the simulation's own clock, the estimated
        // device-to-host offset, or the kernel's host timestamp (0: unknown, e.g. replay).
        auto mid_host_ns = [&](const Frame& f) -> TimestampNs {
          if (sim_clock && sim_clock->paced())
            return sim_clock->host_ns(f.t_ns - sim_camera_offsets[index_of(f.camera)]);
          if (f.clock == ClockDomain::kHostMonotonic) return f.t_ns;
          if (f.clock == ClockDomain::kDevice)
            for (const ClockOffsetLog& c : clocks)
              if (c.camera == f.camera && c.samples) return f.t_ns + c.offset_ns;
          return 0;
        };
        const TimestampNs mid_l = mid_host_ns(frame.left), mid_r = mid_host_ns(frame.right);
        const TimestampNs mid_host =
            mid_l && mid_r ? std::min(mid_l, mid_r) : 0;  // the earlier: latency not flattered

        std::optional<SceneState> scene = fixed_scene;
        if (!scene && truth) {
          const auto it = truth->by_frame.find({index_of(frame.left.camera), frame.left.t_ns});
          if (it != truth->by_frame.end())
            scene = SceneState{it->second.boom, it->second.T_body_receiver, true};
        }
        bool stale = false;
        if (!scene && live_nav) {
          // The pose at the left camera's mid-exposure on the nav clock (the right's differs by the skew).
          std::optional<TimestampNs> t_nav;
          if (sim_flight) {
            t_nav = frame.left.t_ns - sim_camera_offsets[0];
          } else if (mid_l) {
            if (auto t = live_nav->host_to_nav(mid_l)) t_nav = *t;
          }
          if (t_nav) {
            frame_nav = live_nav->at(0, *t_nav);
          } else {
            frame_nav = FrameNav{};
            frame_nav.problems.push_back("no nav clock for this frame yet (no GPS fix received)");
            frame_nav.hud.status = "no pose: " + frame_nav.problems.back();
          }
          if (frame_nav.pose)
            scene = SceneState{frame_nav.pose->boom.articulation, frame_nav.pose->body.T_a_receiver, true};
          stale = frame_nav.stale;
        }
        // Without a pose the frame is still shown and recorded: the boom alone (it needs no nav),
        // the receiver left out of the masks, and the frame marked.
        if (!scene) {
          ++no_pose;
          stale = true;
          scene = SceneState{last_boom ? *last_boom : BoomArticulation{}, Pose::identity(), false};
        }
        if (stale) ++stale_pairs;
        if (stale != was_stale) {
          std::ostringstream e;
          e << "nav " << (stale ? "stale" : "good again") << " from pair " << frame.pair_sequence << " (t_ns "
            << frame.t_key_ns << ")";
          if (stale && !frame_nav.problems.empty()) e << ": " << frame_nav.problems.front();
          log_event(e.str());
          was_stale = stale;
        }
        {
          {
            // The boom: the scene's, the --boom mode's, or the operator's (display commands).
            const BoomCommand tracked = track_point(scene->T_body_receiver * receiver.receptacle_m,
                                                    rig->boom.pivot_body_m, boom_dims, rig->boom.limits);
            const double t_s = ns_to_s(frame.left.t_ns - first_t_ns);
            switch (boom_mode) {
              case DisplayBoomMode::kTrackReceptacle:
                // Without a receiver pose there is nothing to track: the boom holds still.
                if (scene->receiver_present) scene->boom = tracked.articulation;
                break;
              case DisplayBoomMode::kScripted:
              case DisplayBoomMode::kFixed:
                if (boom_arg &&
                    (boom_mode == DisplayBoomMode::kScripted) == (boom_arg->mode == BoomMode::kScripted))
                  scene->boom = boom_arg->command(t_s, tracked, rig->boom.limits).articulation;
                break;
              case DisplayBoomMode::kInteractive:
                if (!interactive_boom) interactive_boom = scene->boom;
                scene->boom = *interactive_boom;
                break;
            }
            last_boom = scene->boom;
          }
          if (Status s = augmenter->augment(frame, *scene, result); !s) {
            ++processing_drops;
            processing_failed_t.add(frame.t_key_ns);
            err << "augrig run: frame " << frame.pair_sequence << ": " << user_message(s.error()) << "\n";
          } else {
            augment_ms += augmenter->timings().total_ms;
            result.stats.t_ns = frame.t_key_ns;
            if (csv) csv->add(result.stats);
            if (every && all.frames() % static_cast<std::size_t>(every) == 0) {
              std::ostringstream stem;
              stem << std::setw(6) << std::setfill('0') << frame.pair_sequence;
              write_frame_outputs(a.get("out"), {stem.str(), stem.str()}, frame, result);
            }
            // The recorder takes the boxes (copied here); the window then gets whole images.
            std::optional<recorder::FrameRecord> fr;
            if (rec && recording_on) fr = frame_record(result);
            if (display && !paused) {
              make_whole_augmented(frame.left.image, result.left);
              make_whole_augmented(frame.right.image, result.right);
            }
            if (!paused) {
              shown_id++;
              shown_scene = *scene;
              shown_mid_host_ns = mid_host;
              have_shown = true;
              if (!display && mid_host) {  // headless: the hand-off is as far as a frame goes
                const TimestampNs ns = monotonic_now_ns() - mid_host;
                std::lock_guard lock(shared.mutex);
                shared.latency_display.add(static_cast<double>(ns) / 1e6);
                shared.display_hist.add(ns);
              }
            }
            if (fr) {  // recording (fr was made above)
              if (mid_host) {
                const TimestampNs ns = monotonic_now_ns() - mid_host;
                latency_recorder.add(static_cast<double>(ns) / 1e6);
                recorder_hist.add(ns);
              }
              fr->raw = std::move(frame);
              fr->T_body_receiver = scene->T_body_receiver;
              fr->receiver_present = scene->receiver_present;
              for (int c = 0; c < 2; ++c)
                fr->T_cam_receiver[c] = rig->cameras[c].T_body_cam.inverse() * scene->T_body_receiver;
              if (frame_nav.pose && !fixed_scene && live_nav) {
                fr->sigma_pos_m = frame_nav.hud.sigma_pos_m;
                fr->sigma_att_deg = frame_nav.hud.sigma_att_deg;
              }
              fr->boom = scene->boom;
              rec->push(std::move(*fr));
            }
            all.add(result.stats);
          }
        }
      }
      if (display) {
        // Hand the last augmented pair (frozen while paused) and the HUD to the window; take its
        // commands.
        const StereoSourceStats st = stereo->stats();
        const double t = std::max(1e-9, std::chrono::duration<double>(Clock::now() - t0).count());
        HudState hud;
        hud.fps = {st.frames[0] / t, st.frames[1] / t};
        if (st.pairing.skew.count) {
          hud.skew_p50_ms = st.pairing.skew.p50_abs_ns() / 1e6;
          hud.skew_p99_ms = st.pairing.skew.p99_abs_ns() / 1e6;
        }
        hud.drops = {
            st.camera_drops, st.transport_drops, st.pairing.unpaired_left + st.pairing.unpaired_right,
            st.queue_drops[0] + st.queue_drops[1] + processing_drops, rec ? rec->stats().frames_dropped : 0};
        if (live_nav) {
          hud.nav = frame_nav.hud;
          for (const std::string& p : frame_nav.problems) hud.messages.push_back(p);
        } else {
          hud.nav.status = fixed_scene ? "fixed scene (no nav)" : "simulation truth";
          hud.nav.fix = fixed_scene ? nav::FixQuality::kInvalid : nav::FixQuality::kRtkFixed;
          if (!fixed_scene) hud.nav.age_s = 0;
        }
        hud.stale_pose = was_stale;
        hud.latency_recorder = latency_recorder.hud();
        hud.recording = rec && recording_on;
        hud.recording_path = rec ? rec->path() : "";
        hud.paused = paused;
        hud.boom_mode = boom_mode;
        for (const SourceHealth& h : stereo->health())
          if (!h.connected) hud.messages.push_back(h.message);
        if (rec && !rec->status())
          hud.messages.push_back("recording stopped: " + user_message(rec->status().error()));
        DisplayCommands c;
        {
          std::lock_guard lock(shared.mutex);
          if (have_shown && shared.id != shown_id) {
            std::swap(shared.result, result);
            shared.scene = shown_scene;
            shared.id = shown_id;
            shared.mid_exposure_host_ns = shown_mid_host_ns;
          }
          hud.latency_display = shared.latency_display.hud();
          shared.hud = std::move(hud);
          c = std::move(shared.commands);
          shared.commands = {};
        }
        if (c.quit) g_stop = true;
        if (c.toggle_pause) paused = !paused;
        if (c.toggle_recording && rec) {
          recording_on = !recording_on;
          log_event(recording_on ? "recording resumed" : "recording paused");
        }
        if (c.boom_mode) boom_mode = *c.boom_mode;
        if (c.boom_nudge.any() && interactive_boom) {
          BoomArticulation b = *interactive_boom;
          b.elevation_rad += c.boom_nudge.elevation_rad;
          b.azimuth_rad += c.boom_nudge.azimuth_rad;
          b.extension_m += c.boom_nudge.extension_m;
          interactive_boom = clamp_to_limits(b, rig->boom.limits).articulation;
        }
      }
      if (rec && !recorder_failed && !rec->status()) {
        // Disk full or a write error: the recording ends valid with what it holds; the run goes on.
        recorder_failed = true;
        out << "  recording stopped: " << user_message(rec->status().error())
            << " (what was recorded stays valid; the run goes on)\n";
      }
      if (Clock::now() >= next_clocks) {
        next_clocks += std::chrono::seconds(1);
        clocks = stereo->stats().clocks;
      }
      if (status_s > 0 && Clock::now() >= next_status) {
        next_status += std::chrono::duration<double>(status_s);
        const StereoSourceStats st = stereo->stats();
        const double t = std::chrono::duration<double>(Clock::now() - t0).count();
        out << "  t " << std::fixed << std::setprecision(1) << t << " s: " << all.frames() << " pairs ("
            << std::setprecision(1) << all.frames() / std::max(t, 1e-9) << "/s), skew p50/p99 "
            << fmt_us(st.pairing.skew.p50_abs_ns()) << "/" << fmt_us(st.pairing.skew.p99_abs_ns())
            << " us, drops camera " << st.camera_drops << " transport " << st.transport_drops << " pairing "
            << st.pairing.unpaired_left + st.pairing.unpaired_right << " queue "
            << st.queue_drops[0] + st.queue_drops[1] << "\n";
        for (const ClockOffsetLog& c : st.clocks) {
          std::ostringstream e;
          e << "clock_offset camera=" << to_string(c.camera) << " t_device_ns=" << c.t_device_ns
            << " offset_ns=" << c.offset_ns << " drift_ppm=" << std::setprecision(3) << c.drift_ppm
            << " uncertainty_ns=" << c.uncertainty_ns << " samples=" << c.samples << " resets=" << c.resets;
          if (rec) rec->push(recorder::EventRecord{c.t_host_ns, ClockDomain::kHostMonotonic, e.str()});
        }
      }
    }
  };
  std::vector<std::string> screenshots;
  bool had_window = false;
  if (!display) {
    pipeline();
  } else {
    std::optional<CommandError> failed;
    std::thread worker([&] {
      set_thread_name("augrig-pipe");
      try {
        pipeline();
      } catch (const CommandError& e) {
        failed = e;
      } catch (const std::exception& e) {
        failed = CommandError{kExitRuntime, std::string("internal error: ") + e.what()};
      }
      std::lock_guard lock(shared.mutex);
      shared.done = true;
    });
    // The window's loop, about 60 times a second; it never waits for the pipeline.
    StereoResult shown;
    SceneState scene;
    std::uint64_t id = 0;
    for (;;) {
      DisplayInput in;
      TimestampNs new_mid_host_ns = 0;  // a new pair's mid-exposure, for its latency once drawn
      {
        std::lock_guard lock(shared.mutex);
        if (shared.done) break;
        if (shared.id != id) {
          std::swap(shared.result, shown);
          scene = shared.scene;
          id = shared.id;
          new_mid_host_ns = shared.mid_exposure_host_ns;
        }
        in.hud = shared.hud;
      }
      if (id) {
        HudState hud = std::move(in.hud);
        in = display_input(shown, *rig, scene, id);
        in.hud = std::move(hud);
      }
      in.rig = &*rig;
      const bool open = display->frame(in);
      if (new_mid_host_ns) {  // drawn and swapped: on its way to the screen
        const TimestampNs ns = monotonic_now_ns() - new_mid_host_ns;
        std::lock_guard lock(shared.mutex);
        shared.latency_display.add(static_cast<double>(ns) / 1e6);
        shared.display_hist.add(ns);
      }
      DisplayCommands c = display->poll_commands();
      for (const std::string& shot : c.screenshots) screenshots.push_back(shot);
      if (!open) c.quit = true;
      {
        std::lock_guard lock(shared.mutex);
        DisplayCommands& q = shared.commands;
        q.quit = q.quit || c.quit;
        q.toggle_pause = q.toggle_pause != c.toggle_pause;
        q.toggle_recording = q.toggle_recording != c.toggle_recording;
        if (c.boom_mode) q.boom_mode = c.boom_mode;
        q.boom_nudge.elevation_rad += c.boom_nudge.elevation_rad;
        q.boom_nudge.azimuth_rad += c.boom_nudge.azimuth_rad;
        q.boom_nudge.extension_m += c.boom_nudge.extension_m;
      }
      if (c.quit) g_stop = true;
      std::this_thread::sleep_for(std::chrono::milliseconds(16));
    }
    worker.join();
    display.reset();
    had_window = true;
    if (failed) throw *failed;
  }
  for (const std::string& shot : screenshots) out << "screenshot " << shot << "\n";
  stereo->stop();
  if (nav_streamer) nav_streamer->stop();
  nav_inputs.stop();
  const double wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  const StereoSourceStats st = stereo->stats();

  // The summary and the drop ledger: every frame is accounted for, by stage.
  if (all.frames()) out << all.format();
  const std::uint64_t pairing = st.pairing.unpaired_left + st.pairing.unpaired_right;
  const std::uint64_t queue = st.queue_drops[0] + st.queue_drops[1];
  const std::uint64_t pending = st.pending.count;
  out << "run: " << all.frames() << " stereo frames augmented in " << std::fixed << std::setprecision(1)
      << wall_s << " s (" << all.frames() / std::max(wall_s, 1e-9) << "/s";
  if (all.frames())
    out << ", augmenter " << fmt_ms(augment_ms / static_cast<double>(all.frames())) << " ms/frame, "
        << to_string(rasterizer) << " rasteriser";
  // Every frame read is in a pair or a ledger row: read = 2 pairs + pairing + queue + pending.
  const std::uint64_t pairs_read = all.frames() + processing_drops;
  out << "); frames read: left " << st.frames[0] << ", right " << st.frames[1] << " = 2 x " << pairs_read
      << " pairs + " << pairing << " unpaired + " << queue << " dropped from full queues + " << pending
      << " pending at the stop\n"
      << "drops: camera " << st.camera_drops << ", transport " << st.transport_drops << ", pairing "
      << pairing << ", processing " << queue + processing_drops * 2 + pending << " (queue " << queue
      << ", failed " << processing_drops << " pairs, pending at the stop " << pending << "), recorder "
      << (rec ? rec->stats().frames_dropped : 0) << "\n";
  // Latency from each pair's mid-exposure (the earlier camera's) on the host clock.
  auto latency_line = [&](const char* what, const LatencyHistogram& h) {
    if (h.count)
      out << "latency mid-exposure to " << what << ": p50 " << fmt_ms(h.p50_abs_ns() / 1e6) << " ms, p99 "
          << fmt_ms(h.p99_abs_ns() / 1e6) << " ms, max " << fmt_ms(h.max_abs_ns / 1e6) << " ms (" << h.count
          << " pairs)\n";
  };
  latency_line(had_window ? "display" : "display hand-off", shared.display_hist);
  latency_line("recorder", recorder_hist);
  if (live_nav) {
    out << "nav: " << no_pose << " pairs without a pose (boom only), " << stale_pairs
        << " with a stale or missing pose\n";
    for (Aircraft ac : {Aircraft::kTanker, Aircraft::kReceiver}) {
      const nav::LiveFusionStatus ns = live_nav->status(ac);
      out << "nav " << to_string(ac) << ": " << (ns.initialised ? "fused" : "never initialised") << ", "
          << ns.imu_samples << " IMU samples (" << ns.imu_refused << " refused), " << ns.fixes
          << " fixes: " << ns.fixes_used << " used, " << ns.fixes_rejected << " rejected by the gate, "
          << ns.fixes_invalid << " without a fix, " << ns.fixes_late << " late\n";
    }
  } else if (no_pose) {
    out << "nav: " << no_pose << " pairs without a pose (boom only)\n";
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
  std::vector<std::string> lost_for_good;  // cameras not connected at the end: the run failed
  for (std::size_t i = 0; i < stereo->sources().size(); ++i) {
    const SourceHealth h = stereo->health()[i];
    if (h.disconnects)
      out << stereo->sources()[i]->uri() << ": lost " << h.disconnects << " time(s), reconnected "
          << h.reconnects << " time(s)" << (h.connected ? "" : "; not connected at the end") << "\n";
    if (!h.connected)
      lost_for_good.push_back(stereo->sources()[i]->uri() + " was lost and never came back (" + h.message +
                              ")");
  }
  nav_inputs.summary(out);
  if (rec) {
    nav_inputs.ledger(*rec);
    // The sources count their own gaps without timestamps; every other row has the first and last
    // frame time of what it counts.
    auto ledger = [&](recorder::DropStage stage, std::uint64_t n, const TimeSpan& t, const std::string& why) {
      if (n) rec->push(recorder::DropRecord{stage, n, t.first_t_ns, t.last_t_ns, why, "frame"});
    };
    ledger(recorder::DropStage::kCamera, st.camera_drops, {}, "frame-id gaps reported by the cameras");
    ledger(recorder::DropStage::kTransport, st.transport_drops, {}, "incomplete or failed buffers");
    ledger(recorder::DropStage::kPairing, pairing, st.pairing.unpaired_t, "frames without a stereo partner");
    ledger(recorder::DropStage::kProcessing, queue, st.queue_drop_t,
           "capture queue full (the pipeline fell behind)");
    ledger(recorder::DropStage::kProcessing, processing_drops * 2, processing_failed_t,
           "augmentation failed (both frames of the pair)");
    ledger(recorder::DropStage::kProcessing, pending, st.pending,
           "pending in the capture queues or the pairer when the run stopped");
    const Status closed = rec->close();
    const recorder::RecorderStats rs = rec->stats();
    out << "recorded " << rs.frames_committed << " stereo frames to " << rec->path() << " ("
        << rs.frames_dropped << " dropped by the recorder)\n";
    if (!closed) runtime_error("the recording stopped: " + user_message(closed.error()));
  }
  if (!lost_for_good.empty()) {
    for (std::size_t i = 1; i < lost_for_good.size(); ++i) err << "augrig run: " << lost_for_good[i] << "\n";
    runtime_error(lost_for_good.front());
  }
  if (source_failed) return kExitRuntime;
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
