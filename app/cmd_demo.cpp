// augrig demo: the main job, a simulated flight end to end, headless:
//   sim        the built-in "demo" scenario (or --scenario): truth, GPS/IMU logs, camera timing;
//   logs       written in their real formats (NMEA, IMU CSV) and read back through the parsers;
//   nav        each aircraft fused (error-state Kalman filter + RTS smoother), never the truth;
//   boom       tracks the receptacle from the fused relative pose, within its limits;
//   cameras    frames rendered from the truth, paired by timestamp like live capture;
//   augment    every selected stereo frame, with statistics; the pose error against truth.
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "app/cli.hpp"
#include "app/run_config.hpp"
#include "capture/stereo_pairer.hpp"
#include "pipeline/flight_nav.hpp"
#include "pipeline/pipeline.hpp"
#include "recorder/recorder.hpp"
#include "render/visualize.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"

namespace augrig::app {

namespace {

const std::vector<OptionSpec>& demo_specs() {
  static const std::vector<OptionSpec> specs = {
      {"out", ArgKind::kValue, "DIR", "output folder (created)", true},
      {"scenario", ArgKind::kValue, "NAME|FILE.yaml", "the flight (default: the built-in 'demo', 28 s)"},
      {"every", ArgKind::kValue, "K", "augment every K-th camera frame (default 3: 10 of the 30 per second)"},
      {"ground-truth", ArgKind::kFlag, "",
       "for the frames whose images are written (every 30th): " + std::string(kGroundTruthHelp) +
           "; with --record, every recorded frame's receiver depth is stored in the recording too"},
      {"frames", ArgKind::kValue, "N",
       "augment only the last N selected stereo frames (default: all); in the live window, stop after N"},
      boom_option("track: the nozzle aims at the receptacle from nav"),
      {"record", ArgKind::kValue, "DIR",
       "record the run (raw, augmented and mask frames, poses, stats, nav inputs, drops; docs/RECORDING.md)"},
      {"overwrite", ArgKind::kFlag, "", "with --record: replace a recording already in DIR"},
      {"bayer", ArgKind::kOptionalValue, "[=RG|GR|GB|BG]", "simulate raw Bayer cameras (default pattern RG)"},
      receiver_draw_option(),
      look_option(),
      {"headless", ArgKind::kFlag, "",
       "the batch demo even when a display is present (without it, a display opens the live window)"},
      {"duration", ArgKind::kValue, "S",
       "with the live window: stop after S seconds (default: the whole flight)"},
      {"screenshot-at", ArgKind::kValue, "N",
       "with the live window: a screenshot once the N-th pair is shown"},
  };
  return specs;
}

const char* kDemoUsage =
    "augrig demo --out DIR [--scenario NAME|FILE] [--every K] [--frames N] [--bayer] [--receiver-draw MODE]";
const char* kDemoSummary =
    "Flies a simulated approach end to end: the simulator writes GPS/IMU logs, nav fusion turns them\n"
    "into the receiver's pose in each camera, the boom tracks the receptacle, and every selected stereo\n"
    "frame is augmented. Writes stats.csv, poses.csv (estimates), truth_poses.csv, images for every\n"
    "30th augmented frame and the last, and demo.png; prints the statistics and the pose error.";

// Half-size RGB copy of an image with a label in its top-left corner.
cv::Mat contact_tile(const Image& rgb, const std::string& label) {
  const cv::Mat full(rgb.height(), rgb.width(), CV_8UC3, const_cast<std::uint8_t*>(rgb.data()),
                     rgb.stride_bytes());
  cv::Mat half;
  cv::resize(full, half, cv::Size(rgb.width() / 2, rgb.height() / 2), 0, 0, cv::INTER_AREA);
  // Dark band under the label keeps it readable over sky and ground alike.
  const int scale_px = std::max(1, half.rows / 480);
  cv::rectangle(half, cv::Rect(0, 0, half.cols, 28 * scale_px), cv::Scalar(0, 0, 0), cv::FILLED);
  cv::putText(half, label, cv::Point(8 * scale_px, 20 * scale_px), cv::FONT_HERSHEY_SIMPLEX, 0.6 * scale_px,
              cv::Scalar(255, 255, 255), scale_px, cv::LINE_AA);
  return half;
}

// demo.png: a 2x2 montage of the last frame (images are RGB here; converted to BGR on write).
Image contact_sheet(const StereoFrame& stereo, const StereoResult& r) {
  const Image raw = to_rgb8(stereo.left.image);
  const cv::Mat tiles[4] = {
      contact_tile(to_rgb8(whole_augmented(stereo.left.image, r.left)), "left camera, augmented"),
      contact_tile(to_rgb8(whole_augmented(stereo.right.image, r.right)), "right camera, augmented"),
      contact_tile(blend_over(raw, visualize_boom_overlap(r.left.mask, r.right.mask)),
                   "boom: left cyan, right blue, both green"),
      contact_tile(blend_over(raw, visualize_receiver_occlusion(r.left.mask, true)),
                   "left: receiver red (in the boom's shadow dark red), boom cyan, boom over receiver white"),
  };
  cv::Mat top, bottom, sheet;
  cv::hconcat(tiles[0], tiles[1], top);
  cv::hconcat(tiles[2], tiles[3], bottom);
  cv::vconcat(top, bottom, sheet);
  Image out(sheet.cols, sheet.rows, PixelFormat::kRGB8);
  for (int y = 0; y < sheet.rows; ++y) std::copy_n(sheet.ptr<std::uint8_t>(y), 3 * sheet.cols, out.row(y));
  return out;
}

// The demo with a display: the simulated flight in real time through the live pipeline and its
// window (augrig run's), the poses from the live fusion of the simulated GPS/IMU streams (--nav
// sim), recording only with --record. The same flags mean the same here: the sim:// source takes
// the scenario, the frame selection and the Bayer pattern; the pipeline the boom, the receiver
// drawing, the look, the recording and the frame count (in real time: stop after N stereo frames).
RunOptions demo_window_options(const ParsedArgs& a) {
  RunOptions o;
  o.source_uri = "sim://" + a.get("scenario", "demo") + "?every=" + a.get("every", "3");
  if (a.has("bayer"))
    o.source_uri += "&bayer=" + (a.get("bayer").empty() ? std::string("RG") : a.get("bayer"));
  o.out = fs::path(a.get("out")).string();
  o.nav_given = o.nav_sim = true;
  if (a.has("duration")) o.duration_s = parse_duration_arg(a.get("duration"));
  if (a.has("ground-truth")) {  // for the frames whose images are written, as in the batch demo
    o.every = 30;
    o.ground_truth = true;
  }
  if (a.has("frames")) o.max_pairs = parse_max_pairs_arg(a.get("frames"));
  if (a.has("record")) o.record = a.get("record");
  o.overwrite = a.has("overwrite");
  o.screenshot_at = parse_screenshot_at(a);
  if (a.has("boom")) o.boom = parse_boom_arg(a.get("boom"));
  if (a.has("receiver-draw")) o.receiver_draw = parse_receiver_draw(a.get("receiver-draw"));
  o.look = parse_look_arg(a.get("look", "camera"));
  return o;
}

int demo_window(const ParsedArgs& a, std::ostream& out, std::ostream& err) {
  out << "demo: a display is present: the flight in real time in the live window, poses from the live "
         "GPS/INS fusion (--headless for the batch demo)\n";
  // The live pipeline is augrig run's: its errors and problems read "augrig run: ...", as they did
  // when the demo called that command.
  return guarded("run", err, [&] { return run_live(demo_window_options(a), out, err); });
}

// The batch demo's settings from its flags (the look is applied with the rig's models, later).
struct DemoFlags {
  int every = 3;
  long long max_frames = -1;
  BoomArg boom;
  AugmentOptions augment;
  sim::Scenario scenario;
};

DemoFlags parse_demo_flags(const ParsedArgs& a) {
  if (a.has("duration"))
    usage_error("--duration applies to the live window only (no display here, or --headless)");
  DemoFlags f;
  if (a.has("every")) f.every = static_cast<int>(parse_integer("every", a.get("every"), 1, 1000));
  if (a.has("frames")) f.max_frames = parse_integer("frames", a.get("frames"), 1, 1000000);
  f.boom = parse_boom_arg(a.get("boom"));
  f.augment.receiver_draw = parse_receiver_draw(a.get("receiver-draw"));
  f.augment.augmented_output = AugmentedOutput::kChangedBox;  // whole images only for the PNG files
  const std::string which = a.get("scenario", "demo");
  const bool is_file = which.find('/') != std::string::npos || which.ends_with(".yaml");
  f.scenario = unwrap(is_file ? sim::load_scenario(which) : sim::builtin_scenario(which));
  if (a.has("bayer"))
    f.scenario.sensors.cameras.format = parse_bayer(a.get("bayer").empty() ? "RG" : a.get("bayer"));
  const Rig& rig = f.scenario.rig;
  if (rig.cameras.size() != 2)
    runtime_error(rig.source + ": the rig needs 2 cameras, has " + std::to_string(rig.cameras.size()));
  return f;
}

// The simulated sensors' logs, read back, and each aircraft fused from them (never the truth).
struct DemoNav {
  sim::SensorLogs logs;
  AircraftLogs tanker, receiver;           // as read back from the logs on disk
  std::vector<TimestampNs> offsets;        // the cameras' clock offsets to GPS time
  std::shared_ptr<const RelativeNav> rel;  // the receiver in each camera, from the fused logs
  double sim_ms = 0, nav_ms = 0;
};

// 1. the flight's sensors, their logs written in their real formats; 2. nav from the logs as read
// back. Prints the scenario and both aircraft's nav.
DemoNav simulate_and_fuse(const sim::Scenario& scenario, const sim::Flight& flight, const fs::path& out_dir,
                          Clock::time_point t_start, std::ostream& out) {
  DemoNav n;
  n.logs = sim::simulate_sensors(scenario, flight);
  check(write_aircraft_logs((out_dir / "nav" / "tanker").string(), n.logs.tanker_imu, n.logs.tanker_gps,
                            ins_config_for(scenario.sensors.tanker)));
  check(write_aircraft_logs((out_dir / "nav" / "receiver").string(), n.logs.receiver_imu, n.logs.receiver_gps,
                            ins_config_for(scenario.sensors.receiver)));
  n.sim_ms = ms_since(t_start);

  const auto t0 = Clock::now();
  n.tanker = unwrap(load_aircraft_logs((out_dir / "nav" / "tanker").string()));
  n.receiver = unwrap(load_aircraft_logs((out_dir / "nav" / "receiver").string()));
  nav::NavTrajectory tk = unwrap(nav::fuse(n.tanker.imu, n.tanker.gps, n.tanker.config));
  nav::NavTrajectory rx = unwrap(nav::fuse(n.receiver.imu, n.receiver.gps, n.receiver.config));
  n.nav_ms = ms_since(t0);
  out << "demo: scenario '" << scenario.name << "', " << scenario.duration_s << " s; "
      << describe("tanker nav", tk.report()) << "\n  " << describe("receiver nav", rx.report()) << "\n";
  // The cameras' clock offsets to GPS time are calibration, known here from the scenario.
  n.offsets = scenario.sensors.cameras.assumed_clock_offsets_ns(2);
  n.rel = std::make_shared<const RelativeNav>(std::move(tk), std::move(rx), scenario.rig, scenario.boom,
                                              flight.receptacle_m(), n.offsets);
  return n;
}

// 3. The frames to augment: every K-th of those delivered with a nav pose, the last N of them.
std::vector<sim::FrameTruth> select_frames(const DemoFlags& f, const sim::Flight& flight, const DemoNav& n) {
  std::vector<sim::FrameTruth> truths = sim::frame_truths(f.scenario, flight, n.logs.cameras);
  std::erase_if(truths, [&](const sim::FrameTruth& t) { return !n.rel->at(t.camera, t.t_camera_ns); });
  {
    // Keep only sequences both cameras delivered, so every selected frame pairs.
    std::map<std::uint64_t, int> cams;
    for (const auto& t : truths) cams[t.sequence] |= 1 << t.camera;
    std::erase_if(truths,
                  [&](const sim::FrameTruth& t) { return cams[t.sequence] != 3 || t.sequence % f.every; });
  }
  if (f.max_frames > 0 && truths.size() > 2 * static_cast<std::size_t>(f.max_frames))
    truths.erase(truths.begin(), truths.end() - 2 * f.max_frames);
  if (truths.size() / 2 == 0)
    runtime_error("scenario '" + f.scenario.name + "': no stereo frame has a nav pose");
  return truths;
}

// The NMEA lines of one aircraft's log as received ("<arrival_ns> <sentence>"), then its IMU samples.
void record_nav_inputs(recorder::Recorder& rec, const fs::path& out_dir, const std::string& who,
                       const std::vector<nav::ImuSample>& imu) {
  std::ifstream nmea(out_dir / "nav" / who / "gps.nmea", std::ios::binary);
  std::string line;
  while (std::getline(nmea, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    recorder::NavInputRecord r;
    r.stream = who + ".gps";
    const auto space = line.find(' ');
    if (space != std::string::npos && line[0] != '$') {
      r.arrival_ns = std::stoll(line.substr(0, space));
      line.erase(0, space + 1);
    }
    r.data = line;
    rec.push(std::move(r));
  }
  for (const nav::ImuSample& smp : imu) rec.push(recorder::imu_input(smp, who + ".imu"));
}

// The frames the simulated cameras dropped, as one ledger row.
void record_camera_drops(recorder::Recorder& rec, const sim::SensorLogs& logs) {
  std::uint64_t dropped = 0;
  TimestampNs first = 0, last = 0;
  for (const auto& cam : logs.cameras)
    for (const auto& f : cam)
      if (f.dropped) {
        if (!dropped++) first = f.t_camera_ns;
        last = f.t_camera_ns;
      }
  if (dropped)
    rec.push(recorder::DropRecord{recorder::DropStage::kCamera, dropped, first, last,
                                  "the simulated cameras' drop model", "frame"});
}

// --record: everything a flight test keeps, through the same never-blocking recorder a live run
// uses. The nav inputs go in exactly as the logs hold them.
std::unique_ptr<recorder::Recorder> demo_recorder(const ParsedArgs& a, const sim::Scenario& scenario,
                                                  const DemoNav& n, const std::string& source_uri,
                                                  const fs::path& out_dir) {
  recorder::RecordingInfo info;
  info.rig_yaml = rig_to_yaml(scenario.rig);
  if (auto text = sim::builtin_scenario_text(scenario.name)) info.scene = *text;
  info.clock_domains = "frames: device (camera clocks; offsets to gps " + std::to_string(n.offsets[0]) +
                       ", " + std::to_string(n.offsets[1]) + " ns); nav inputs: gps";
  info.extra["source"] = source_uri;
  info.extra["aircraft_yaml.tanker"] = aircraft_config_to_yaml(n.tanker.config);
  info.extra["aircraft_yaml.receiver"] = aircraft_config_to_yaml(n.receiver.config);
  auto rec = create_recorder(a.get("record"), info, a.has("overwrite"));
  record_nav_inputs(*rec, out_dir, "tanker", n.tanker.imu);
  record_nav_inputs(*rec, out_dir, "receiver", n.receiver.imu);
  record_camera_drops(*rec, n.logs);
  return rec;
}

// What the demo adds per pair: the estimated and true poses, the boom's miss, images for a
// subset (PNG encoding costs more than the augmentation itself), a line every 30 frames.
class DemoPairs {
 public:
  DemoPairs(const DemoFlags& f, const sim::Flight& flight, const DemoNav& n,
            const std::vector<sim::FrameTruth>& truths, const fs::path& out_dir, bool ground_truth,
            std::ostream& out)
      : f_(f),
        flight_(flight),
        rel_(*n.rel),
        out_dir_(out_dir),
        ground_truth_(ground_truth),
        out_(out),
        frames_(static_cast<int>(truths.size() / 2)) {
    for (const auto& t : truths) truth_of_[{t.sequence, t.camera}] = t;
  }

  Status on_pair(const StereoFrame& stereo, const StereoResult& result, const SceneState& scene) {
    const auto left = rel_.at(0, stereo.left.t_ns);
    const auto right = rel_.at(1, stereo.right.t_ns);
    if (!left) return left.error();
    if (!right) return right.error();
    est_rows.push_back(left->row(stereo.left.sequence, 0, stereo.left.t_ns));
    est_rows.push_back(right->row(stereo.right.sequence, 1, stereo.right.t_ns));
    const sim::FrameTruth& tl = truth_of_.at({stereo.left.sequence, 0});
    true_rows.push_back(sim::pose_row(tl));
    true_rows.push_back(sim::pose_row(truth_of_.at({stereo.right.sequence, 1})));
    // Where the tracked nozzle tip is against where the true receptacle is.
    const Eigen::Vector3d true_receptacle = tl.T_body_receiver * flight_.receptacle_m();
    const Rig& rig = f_.scenario.rig;
    const double miss_m =
        (nozzle_tip_body(rig.boom.pivot_body_m, f_.scenario.boom, scene.boom) - true_receptacle).norm();
    if (f_.boom.mode == BoomMode::kTrackReceptacle &&
        !left->boom.clamped) {  // the receptacle within the boom's reach: the miss is nav error
      worst_miss_m = std::max(worst_miss_m, miss_m);
      ++reachable;
    }
    const bool last = i_ + 1 == frames_;
    if (i_ % 30 == 0 || last)
      if (Status st = write_images(stereo, result); !st) return st;
    if ((i_ + 1) % 30 == 0 || last) print_line(result.stats, tl, *left);
    if (last) {  // for demo.png
      last_stereo = stereo;
      last_result = result;
    }
    ++i_;
    return {};
  }

  int frames() const { return frames_; }

  std::vector<nav::CameraPoseRow> est_rows, true_rows;
  double write_ms = 0, worst_miss_m = 0;
  int reachable = 0;
  StereoFrame last_stereo;
  StereoResult last_result;

 private:
  // frame_NNNN's images (and with --ground-truth its ground truth).
  Status write_images(const StereoFrame& stereo, const StereoResult& result) {
    const auto w0 = Clock::now();
    char stem[32];
    std::snprintf(stem, sizeof stem, "frame_%04d", i_);
    if (Status st = write_frame_images(out_dir_, {stem, stem}, stereo, result); !st) return st;
    if (ground_truth_)
      if (Status st = write_ground_truth(out_dir_, {stem, stem}, result, f_.scenario.rig); !st) return st;
    write_ms += ms_since(w0);
    return {};
  }

  void print_line(const OcclusionStats& st, const sim::FrameTruth& tl, const FramePose& left) {
    char line[240];
    std::snprintf(line, sizeof line,
                  "frame %4d/%d  t %6.2f s  %-15s receiver %7lld px  boom %7lld px  occluded %5.1f%%  "
                  "pose err %5.1f mm\n",
                  i_ + 1, frames_, tl.t_true_s, tl.phase.c_str(), static_cast<long long>(st.receiver_px_left),
                  static_cast<long long>(st.boom_px_left), st.occluded_pct_left,
                  1e3 * (left.camera.T_a_receiver.translation_m - tl.T_cam_receiver.translation_m).norm());
    out_ << line << std::flush;
  }

  const DemoFlags& f_;
  const sim::Flight& flight_;
  const RelativeNav& rel_;
  const fs::path out_dir_;
  const bool ground_truth_;
  std::ostream& out_;
  const int frames_;
  int i_ = 0;
  std::map<std::pair<std::uint64_t, int>, sim::FrameTruth> truth_of_;
};

// 4. The frames through the runtime pipeline: the simulated cameras (the CPU renderer, on the
// capture thread) paired by mid-exposure time within half a period as live capture pairs them,
// the poses from the fused logs (offline nav), the boom stage, the augmenter and the sinks.
// Prints what goes through; with --record, the recorder (the nav inputs already in it).
PipelineParts demo_parts(const ParsedArgs& a, DemoFlags& f, const sim::Flight& flight, const DemoNav& n,
                         const std::vector<sim::FrameTruth>& truths, const fs::path& out_dir,
                         std::ostream& out) {
  const sim::Scenario& scenario = f.scenario;
  const Rig& rig = scenario.rig;
  auto source = unwrap(sim::FlightSource::create(scenario, flight, truths));
  const std::string source_uri = source->uri();
  OpenedSource opened;
  opened.sources.push_back(std::move(source));
  opened.options.lossless = true;
  opened.options.pairing.tolerance_ns = s_to_ns(0.5 / scenario.sensors.cameras.fps);
  PipelineParts parts;
  parts.rig = rig;
  parts.models = unwrap(load_rig_models(rig));
  parts.models.receptacle_m = flight.receptacle_m();
  parts.boom_dims = scenario.boom;
  parts.boom = f.boom;
  apply_look_arg(a, rig, f.augment);
  parts.augment = f.augment;
  parts.poses = offline_nav_poses(std::make_shared<const RelativeNav>(*n.rel), "the simulated logs");
  parts.stats_csv = unwrap(StatsCsvWriter::create(out_dir / "stats.csv"));
  parts.keep_all_stats = true;  // the summary and Table 1
  out << "demo: " << truths.size() / 2 << " stereo frames (every " << f.every << ") of " << source_uri << ", "
      << to_string(scenario.sensors.cameras.format) << ", " << rig.left().model.width_px << "x"
      << rig.left().model.height_px << " -> " << out_dir.string() << "\n";
  if (a.has("record")) {
    parts.recorder = demo_recorder(a, scenario, n, source_uri, out_dir);
    parts.record_ground_truth = a.has("ground-truth");
  }
  parts.phase_of = sim_phases(truths);  // the flight's phases, as events beside the statistics
  parts.source_info = opened;
  parts.source = unwrap(start_stereo(std::move(opened)));
  return parts;
}

// demo.png (the last frame), poses.csv (the estimates) and truth_poses.csv.
void write_demo_files(const fs::path& out_dir, DemoPairs& pairs) {
  const auto t0 = Clock::now();
  check(write_image_file((out_dir / "demo.png").string(), contact_sheet(pairs.last_stereo, pairs.last_result),
                         3));
  nav::CsvWriteOptions po;
  po.clock = ClockDomain::kDevice;  // t_ns is the camera's stamp; t_nav_ns is GPS time
  po.metadata["t_nav_ns"] = "gps";
  po.metadata["content"] = "estimate: T_cam_receiver from GPS/INS fusion of the simulated logs";
  check(nav::write_camera_pose_csv((out_dir / "poses.csv").string(), pairs.est_rows, po));
  po.metadata["content"] = "truth: T_cam_receiver and the scenario's boom";
  check(nav::write_camera_pose_csv((out_dir / "truth_poses.csv").string(), pairs.true_rows, po));
  pairs.write_ms += ms_since(t0);
}

// The statistics' summary, Table 1 of the last frame, the pose error against truth, the boom's
// tracking.
void print_demo_results(const PipelineReport& r, const DemoPairs& pairs, std::ostream& out) {
  out << "\n" << format_run_summary(r.all_stats) << "\n";
  out << format_table1(r.all_stats.back(),
                       "Last frame, t = " + std::to_string(ns_to_s(r.all_stats.back().t_ns)) + " s (GPS)");
  out << "\nNav against truth (receiver in each camera): "
      << describe(compare_poses(pairs.est_rows, pairs.true_rows)) << "\n";
  if (pairs.reachable > 0) {
    char line[200];
    std::snprintf(
        line, sizeof line,
        "Boom tracking: in the %d frames with the receptacle within the boom's reach, the nozzle tip "
        "(aimed from nav) lies at most %.1f mm from the true receptacle\n",
        pairs.reachable, 1e3 * pairs.worst_miss_m);
    out << line;
  }
}

// Where the time went, what was recorded, how the frames paired, what was written.
struct DemoTimes {
  double sim_ms, nav_ms, pipeline_ms, write_ms;
  Clock::time_point start;
};

void print_demo_accounts(const ParsedArgs& a, const PipelineReport& r, const DemoTimes& t,
                         const fs::path& out_dir, std::ostream& out) {
  const double n = static_cast<double>(r.pairs);
  out << "\nTiming: simulation and logs " << fmt_ms(t.sim_ms) << " ms, nav fusion of both aircraft "
      << fmt_ms(t.nav_ms) << " ms, pipeline " << fmt_ms(t.pipeline_ms / n)
      << " ms per stereo frame (cameras rendered on their own "
      << "thread) with the augmenter " << fmt_ms(r.augment_ms / n) << " ms (" << to_string(r.rasterizer)
      << " rasteriser), PNG writing " << fmt_ms(t.write_ms) << " ms in all, total "
      << fmt_ms(ms_since(t.start) / 1000.0) << " s\n";
  if (r.recording_closed) {
    const recorder::RecorderStats& rs = r.recorder_stats;
    out << "Recording: " << a.get("record") << ": " << rs.frames_committed << " stereo frames, "
        << rs.nav_inputs_committed << " nav inputs, " << rs.frames_dropped << " frames dropped by the recorder";
    if (rs.small_items_dropped) out << " (and " << rs.small_items_dropped << " nav inputs or events)";
    if (rs.image_bytes)
      out << ", images compressed "
          << fmt_ms(double(rs.image_bytes) / double(std::max<std::uint64_t>(rs.stored_bytes, 1))) << ":1";
    out << (*r.recording_closed ? "" : " -- STOPPED: " + user_message(r.recording_closed->error())) << "\n";
  }
  const PairerStats& ps = r.source.pairing;
  out << "Pairing: " << ps.pairs << " pairs, unpaired left " << ps.unpaired_left << ", right " << ps.unpaired_right
      << ", max |skew| " << ps.max_abs_skew_ns << " ns\n";
  out << "Wrote " << (out_dir / "stats.csv").string() << ", poses.csv, truth_poses.csv and "
      << (out_dir / "demo.png").string() << "\n";
}

// Without a display, or with --headless: the simulated flight through the sensors, nav, the
// pipeline and the demo's own outputs, as fast as it goes.
int batch_demo(const ParsedArgs& a, std::ostream& out, std::ostream& err) {
  DemoFlags f = parse_demo_flags(a);
  const fs::path out_dir = a.get("out");
  make_dirs(out_dir);
  const auto t_start = Clock::now();
  const sim::Flight flight = unwrap(sim::Flight::create(f.scenario));
  const DemoNav n = simulate_and_fuse(f.scenario, flight, out_dir, t_start, out);
  const std::vector<sim::FrameTruth> truths = select_frames(f, flight, n);

  DemoPairs pairs(f, flight, n, truths, out_dir, a.has("ground-truth"), out);
  PipelineParts parts = demo_parts(a, f, flight, n, truths, out_dir, out);
  parts.on_pair = [&pairs](const StereoFrame& stereo, const StereoResult& result, const SceneState& scene,
                           const FramePoses&) { return pairs.on_pair(stereo, result, scene); };
  parts.stop_flag = install_stop_signals();
  parts.on_problem = [&err](const Error& e) { err << "augrig demo: " << user_message(e) << "\n"; };
  Pipeline pipeline(std::move(parts));
  const auto t_pipe = Clock::now();
  std::ostringstream pipeline_log;  // the pipeline's events; the demo prints its own summary
  const PipelineReport r = unwrap(pipeline.run(pipeline_log, err));
  const double pipeline_ms = ms_since(t_pipe);
  if (r.pairs == 0) runtime_error("scenario '" + f.scenario.name + "': no stereo frame was augmented");

  write_demo_files(out_dir, pairs);
  print_demo_results(r, pairs, out);
  print_demo_accounts(a, r, {n.sim_ms, n.nav_ms, pipeline_ms, pairs.write_ms, t_start}, out_dir, out);
  // A recording that stopped (a full disk) fails the run, as in augrig run: what it holds is valid.
  if (r.recording_closed && !*r.recording_closed)
    runtime_error("the recording stopped: " + user_message(r.recording_closed->error()) +
                  " (what it holds stays valid; the other outputs were written)");
  return kExitOk;
}

int demo(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  const ParsedArgs a = parse_or_usage(args, demo_specs());
  if (a.help) {
    out << format_help(kDemoUsage, kDemoSummary, demo_specs());
    return kExitOk;
  }
  // With a display the live window (augrig run's pipeline); without one, or with --headless, the batch demo.
  if (!a.has("headless") && display_present()) return demo_window(a, out, err);
  return batch_demo(a, out, err);
}

}  // namespace

int cmd_demo(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("demo", err, [&] { return demo(args, out, err); });
}

}  // namespace augrig::app
