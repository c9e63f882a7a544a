// augrig nav: both aircraft's GPS/IMU logs -> the receiver's pose in each camera at every frame.
// Flow: load and check every input (logs with their aircraft.yaml and the leap seconds of their UTC
// times, rig, frame index) -> fuse each aircraft (forward filter, RTS smoother) -> is the reported
// sigma consistent with the GPS innovations? -> the moving baseline (rover.ubx), fused against both
// solutions -> per frame: camera time -> nav time -> relative pose
// with 1-sigma -> boom tracking -> poses.csv; with --truth, the error against it.
#include <algorithm>
#include <cmath>
#include <iostream>
#include <sstream>

#include "app/cli.hpp"
#include "core/yaml_reader.hpp"
#include "nav/camera_clock.hpp"
#include "nav/logs.hpp"
#include "nav/nmea.hpp"
#include "pipeline/baseline_nav.hpp"
#include "pipeline/flight_nav.hpp"

namespace augrig::app {
namespace {

const std::vector<OptionSpec>& nav_specs() {
  static const std::vector<OptionSpec> specs = {
      {"tanker", ArgKind::kValue, "DIR", "tanker logs: gps.nmea, imu.csv, aircraft.yaml (docs/NAV_FORMATS.md)", true},
      {"receiver", ArgKind::kValue, "DIR", "receiver logs, the same files", true},
      rig_option("", true),
      {"frames", ArgKind::kValue, "INDEX.csv", "frame index: sequence,camera,t_ns,file", true},
      {"out", ArgKind::kValue, "POSES.csv", "output: the receiver in each camera per frame", true},
      {"camera-offset-ns", ArgKind::kValue, "L[,R]",
       "camera clock minus nav (GPS) time, per camera (one value: both), ns (default 0): t_nav = t_camera - offset"},
      boom_option("track: the nozzle aims at the receptacle; none with a capture-only rig"),
      {"forward-only", ArgKind::kFlag, "",
       "no RTS smoothing (what a real-time filter would know); the frames before both filters converged are "
       "flagged (their sigma is optimistic)"},
      {"leap-seconds", ArgKind::kValue, "N",
       "GPS - UTC of both aircraft's gps.nmea, whole seconds (default: aircraft.yaml's gps_leap_seconds, else "
       "the receiver's $PUBX,04, else the leap-second table for the log's UTC dates: 17 in 2015-07..2016, 18 "
       "since 2017)"},
      {"default-aircraft", ArgKind::kFlag, "",
       "fuse an aircraft folder without aircraft.yaml with the defaults (antenna at the IMU, tactical IMU, 2 cm "
       "RTK); without this flag that is an error"},
      {"baseline", ArgKind::kValue, "ROVER.ubx",
       "the moving-baseline RTK rover's UBX log (NAV-RELPOSNED: the receiver's GPS antenna relative to the "
       "tanker's), fused as a relative measurement (default: the receiver folder's rover.ubx when there)"},
      {"no-baseline", ArgKind::kFlag, "", "leave the receiver folder's rover.ubx out"},
      {"camera-clock", ArgKind::kFlag, "",
       "estimate each camera's clock offset (and drift) against GPS time from its images (the frame index's "
       "files) and the tanker's angular rate (docs/CLOCK_OFFSETS.md), instead of --camera-offset-ns"},
      {"camera-clock-every", ArgKind::kValue, "N", "with --camera-clock: every N-th frame (default 1)"},
      {"terrain-height-m", ArgKind::kValue, "H",
       "with --camera-clock: the ground's height above the ellipsoid, metres (default 0)"},
      {"truth", ArgKind::kValue, "POSES.csv", "true camera poses (augrig sim's truth/poses.csv): print the error"},
      {"solutions", ArgKind::kValue, "DIR", "also write each aircraft's nav solution per epoch (CSV)"},
  };
  return specs;
}

std::vector<TimestampNs> parse_offsets(const std::string& v) {
  std::vector<TimestampNs> out;
  std::stringstream ss(v);
  std::string item;
  while (std::getline(ss, item, ','))
    out.push_back(parse_integer("camera-offset-ns", item, -(1LL << 50), 1LL << 50));
  if (out.empty() || out.size() > 2) usage_error("--camera-offset-ns: expected one or two values, got '" + v + "'");
  if (out.size() == 1) out.push_back(out[0]);  // one value: both cameras, as in a scenario file
  return out;
}

void print_issues(std::ostream& out, const std::string& what, const nav::LogIssues& i) {
  if (i.malformed + i.out_of_order + i.duplicates + i.gaps == 0) return;
  out << "  " << what << ": " << i.malformed << " malformed lines, " << i.out_of_order << " out of order, "
      << i.duplicates << " duplicates (dropped), " << i.gaps << " gaps\n";
  for (std::size_t k = 0; k < i.messages.size() && k < 5; ++k) out << "    " << i.messages[k] << "\n";
  if (i.messages.size() > 5) out << "    ... " << i.messages.size() - 5 << " more\n";
}

// Every input, read and checked before any work.
struct NavInputs {
  BoomArg boom;
  Rig rig;
  AircraftLogs tanker, receiver;
  nav::FrameIndex index;
  std::vector<nav::CameraPoseRow> truth;
};

NavInputs load_nav_inputs(const ParsedArgs& a, std::ostream& out) {
  BoomArg boom = parse_boom_arg(a.get("boom"));
  Rig rig = load_rig_arg(a.get("rig"));
  AircraftLoadOptions load;
  load.allow_default_config = a.has("default-aircraft");
  if (a.has("leap-seconds"))
    load.leap_seconds = static_cast<int>(parse_integer("leap-seconds", a.get("leap-seconds"), 0, 100));
  AircraftLogs tanker = unwrap(load_aircraft_logs(a.get("tanker"), load));
  AircraftLogs receiver = unwrap(load_aircraft_logs(a.get("receiver"), load));
  nav::FrameIndex index = unwrap(nav::read_frame_index_csv(a.get("frames")));
  std::vector<nav::CameraPoseRow> truth;
  if (a.has("truth")) truth = unwrap(nav::read_camera_pose_csv(a.get("truth"))).rows;
  const std::pair<const char*, const AircraftLogs*> aircraft[] = {{"tanker", &tanker}, {"receiver", &receiver}};
  for (const auto& [who, logs] : aircraft) {
    print_issues(out, std::string(who) + " gps.nmea", logs->gps_issues);
    print_issues(out, std::string(who) + " imu.csv", logs->imu_issues);
    out << who << " gps.nmea: " << nav::describe(logs->leap_seconds)
        << (logs->leap_seconds_source.empty() ? "" : ", by " + logs->leap_seconds_source) << "\n";
    for (const std::string& n : logs->notes) out << "note: " << who << ": " << n << "\n";
    for (const std::string& w : logs->warnings) out << "warning: " << who << ": " << w << "\n";
  }
  return {std::move(boom),     std::move(rig),   std::move(tanker),
          std::move(receiver), std::move(index), std::move(truth)};
}

// The IMU clocks against GPS time, where aircraft.yaml has them estimated (imu_clock).
std::string imu_clock_text(const nav::NavTrajectory& tk, const nav::NavTrajectory& rx, std::ostream& out) {
  std::string imu_clocks;
  for (const auto& [who, r] : {std::pair{"tanker", &tk.report()}, std::pair{"receiver", &rx.report()}}) {
    if (const std::string c = describe_imu_clock(who, *r); !c.empty()) {
      out << c << "\n";
      imu_clocks += (imu_clocks.empty() ? "" : "; ") + c;
    }
  }
  return imu_clocks;
}

// Is the sigma the filters report consistent with what the GPS fixes said (NIS)?
std::string sigma_consistency(const NavInputs& in, const nav::NavTrajectory& tk, const nav::NavTrajectory& rx,
                              std::ostream& out) {
  const std::pair<const char*, const AircraftLogs*> aircraft[] = {{"tanker", &in.tanker},
                                                                  {"receiver", &in.receiver}};
  std::string consistency;
  for (const auto& [who, logs] : aircraft) {
    const nav::FusionReport& r = std::string(who) == "tanker" ? tk.report() : rx.report();
    std::string hint;
    if (logs->default_config) hint = "there was no aircraft.yaml: the defaults were used";
    if (logs->leap_seconds.disagreements) hint += (hint.empty() ? "" : "; ") + std::string("see the leap-second warning above");
    const InnovationCheck c = check_innovations(who, r, hint);
    out << c.summary << "\n";
    if (!c.warning.empty()) out << "warning: " << c.warning << "\n";
    consistency += (consistency.empty() ? "" : "; ") + std::string(who) + " " +
                   (!c.judged ? "not judged" : c.consistent ? "consistent" : c.optimistic ? "optimistic" : "pessimistic") +
                   " (innovations " + yaml::fmt(std::round(r.innovations.scale * 100) / 100) + "x predicted)";
  }
  return consistency;
}

// The moving baseline, when there is one (rover_path set): the relative position from it and
// both solutions.
std::shared_ptr<const BaselineNav> moving_baseline(const ParsedArgs& a, const NavInputs& in,
                                                   const nav::NavTrajectory& tk, const nav::NavTrajectory& rx,
                                                   std::string& rover_path, std::ostream& out) {
  if (a.has("baseline") && a.has("no-baseline")) usage_error("--baseline and --no-baseline exclude each other");
  rover_path = a.has("baseline") ? a.get("baseline") : "";
  if (rover_path.empty() && !a.has("no-baseline") && fs::exists(fs::path(a.get("receiver")) / "rover.ubx"))
    rover_path = (fs::path(a.get("receiver")) / "rover.ubx").string();
  if (rover_path.empty()) return nullptr;
  const TimestampNs reference = in.receiver.gps.empty() ? rx.begin_ns() : in.receiver.gps.front().t_ns;
  const RoverLog rover = unwrap(load_rover_log(rover_path, reference));
  out << rover.summary() << "\n";
  print_issues(out, rover_path, rover.issues);
  auto baseline = std::make_shared<const BaselineNav>(
      unwrap(BaselineNav::fuse(rover.measurements, tk, rx, in.tanker.config.baseline_antenna(),
                               in.receiver.config.baseline_antenna())));
  out << baseline->report().summary() << "\n";
  return baseline;
}

// One camera's clock from its frames: the line that says it (and the estimate where observable).
std::string camera_clock_line(const std::string& who, const std::vector<nav::CameraClockFrame>& frames,
                              const RigCamera& cam, const nav::AngularRateFunction& omega,
                              const nav::GroundMotionFunction& ground,
                              std::optional<nav::CameraClockEstimate>& clock) {
  if (frames.empty()) return who + " clock: no frames in the index";
  const auto t0 = Clock::now();
  auto est = nav::estimate_camera_clock(frames, cam.model, cam.T_body_cam.R().transpose(), omega, {}, ground);
  const std::string took = " (" + std::to_string(frames.size()) + " frames, " + fmt_ms(ms_since(t0)) + " ms)";
  if (!est) return who + " clock: not estimated: " + est.error().message + took;
  if (!est->observable) return who + " clock: not estimated: " + est->reason + took;
  clock = *est;
  char buf[200];
  std::snprintf(buf, sizeof buf, " clock: offset %.3f ms +- %.3f ms (1-sigma)", est->offset_s * 1e3,
                est->offset_sigma_s * 1e3);
  std::string line = who + buf + " " + nav::describe_sigma(*est);
  if (est->drift_observable) {
    std::snprintf(buf, sizeof buf, ", drift %.1f +- %.1f ppm", est->drift_ppm, est->drift_sigma_ppm);
    line += buf;
  }
  return line + took;
}

// Each camera's clock from its images (--camera-clock): the rotation the ground shows against the
// tanker's angular rate (docs/CLOCK_OFFSETS.md). Returns the lines that say them.
std::string estimate_camera_clocks(const ParsedArgs& a, const NavInputs& in, const nav::NavTrajectory& tk,
                                   std::vector<std::optional<nav::CameraClockEstimate>>& clocks,
                                   std::ostream& out) {
  const int every =
      a.has("camera-clock-every")
          ? static_cast<int>(parse_integer("camera-clock-every", a.get("camera-clock-every"), 1, 100))
          : 1;
  const double terrain_m =
      a.has("terrain-height-m") ? parse_real("terrain-height-m", a.get("terrain-height-m")) : 0.0;
  if (!(std::abs(terrain_m) <= 10000))
    usage_error("--terrain-height-m: expected metres in [-10000, 10000], got '" + a.get("terrain-height-m") +
                "'");
  const std::string folder = fs::path(a.get("frames")).parent_path().string();
  const nav::AngularRateFunction omega = nav::angular_rate_from_trajectory(tk);
  const nav::GroundMotionFunction ground = nav::ground_motion_from_trajectory(tk, terrain_m);
  std::string clock_text;
  for (std::size_t c = 0; c < in.rig.cameras.size(); ++c) {
    const auto frames = nav::camera_clock_frames(in.index, static_cast<int>(c), folder, std::nullopt, every);
    const std::string who = "camera " + std::to_string(c) + " (" + in.rig.cameras[c].name + ")";
    const std::string line = camera_clock_line(who, frames, in.rig.cameras[c], omega, ground, clocks[c]);
    out << line << "\n";
    if (!clocks[c]) out << "warning: " << who << ": its frames keep their stamps (offset 0)\n";
    clock_text += (clock_text.empty() ? "" : "; ") + line;
  }
  return clock_text;
}

// The poses of every frame the nav data cover.
struct FramePoses {
  std::vector<nav::CameraPoseRow> rows;
  std::vector<bool> converging;  // per row: a forward filter not yet converged at its time
  std::size_t outside = 0, corrected = 0;
  double query_us = 0;
};

FramePoses frame_poses(const ParsedArgs& a, const NavInputs& in, const RelativeNav& rel,
                       const std::vector<std::optional<nav::CameraClockEstimate>>& clocks) {
  FramePoses fp;
  const auto t1 = Clock::now();
  for (const nav::FrameIndexRow& f : in.index.rows) {
    const auto& clock = f.camera >= 0 && f.camera < static_cast<int>(clocks.size()) ? clocks[f.camera] : std::nullopt;
    auto p = rel.at(f.camera, clock ? f.t_ns - clock->offset_at_ns(f.t_ns) : f.t_ns);
    if (!p) {
      ++fp.outside;  // before the first fix or after the last IMU sample: no pose, said below
      continue;
    }
    p->boom = in.boom.command(ns_to_s(f.t_ns - in.index.rows.front().t_ns), p->boom, in.rig.boom.limits);
    fp.rows.push_back(p->row(f.sequence, f.camera, f.t_ns));
    fp.corrected += p->baseline_corrected ? 1 : 0;
    fp.converging.push_back(rel.converging(p->t_nav_ns));
    // A capture-only rig has no boom to articulate: the boom columns stay empty (whoever augments
    // with these poses flies its own rig's boom), unless --boom says what it does.
    if (!in.rig.boom.configured && !a.has("boom"))
      fp.rows.back().boom_elevation_deg = fp.rows.back().boom_azimuth_deg = fp.rows.back().boom_extension_m =
          nav::CameraPoseRow::kNaN;
  }
  fp.query_us = fp.rows.empty() ? 0 : 1e3 * ms_since(t1) / static_cast<double>(fp.rows.size());
  return fp;
}

// What poses.csv's metadata and the summary say beside the poses.
struct NavNotes {
  bool smooth = true;
  double fuse_ms = 0;
  std::string imu_clocks, consistency, clock_text, rover_path;
  bool baseline = false;
};

// Writes poses.csv and says what was written; with --truth, the error against it.
void write_poses(const ParsedArgs& a, const NavInputs& in, const RelativeNav& rel, const FramePoses& fp,
                 const NavNotes& notes, std::ostream& out) {
  const auto& rows = fp.rows;
  nav::CsvWriteOptions o;
  o.clock = ClockDomain::kDevice;  // t_ns is the camera's stamp; t_nav_ns is GPS time
  o.metadata["t_nav_ns"] = "gps";
  o.metadata["content"] = "estimate: T_cam_receiver from GPS/INS fusion";
  o.metadata["smoothing"] = notes.smooth ? "rts" : "none";
  o.metadata["gps_minus_utc_s"] = "tanker " + nav::describe(in.tanker.leap_seconds) + "; receiver " +
                                  nav::describe(in.receiver.leap_seconds);
  o.metadata["sigma_consistency"] = notes.consistency;
  if (!notes.clock_text.empty()) o.metadata["camera_clock"] = notes.clock_text;
  if (!notes.imu_clocks.empty()) o.metadata["imu_clock"] = notes.imu_clocks;
  if (notes.baseline)
    o.metadata["moving_baseline"] = notes.rover_path + ": " + std::to_string(fp.corrected) + " of " +
                                    std::to_string(rows.size()) + " rows corrected";
  // Forward only: the rows before both filters converged carry an optimistic sigma.
  const auto n_converging =
      static_cast<std::size_t>(std::count(fp.converging.begin(), fp.converging.end(), true));
  std::string converging_text;
  if (!notes.smooth) {
    const auto when = rel.converged_ns();
    converging_text = std::to_string(n_converging) + " of " + std::to_string(rows.size()) +
                      " rows before both forward filters converged (their sigma is optimistic): " +
                      (when ? "t_nav_ns < " + std::to_string(*when)
                            : std::string("a filter had not converged by the end of the data: every row"));
    o.metadata["converging"] = converging_text;
  }
  check(nav::write_camera_pose_csv(a.get("out"), rows, o));
  out << "Poses: " << rows.size() << " of " << in.index.rows.size() << " frames";
  if (fp.outside) out << " (" << fp.outside << " outside the nav data: no pose written)";
  out << "; fusion " << fmt_ms(notes.fuse_ms) << " ms for both aircraft, " << fmt_ms(fp.query_us)
      << " us per frame pose\n";
  if (notes.baseline)
    out << "Moving baseline: " << fp.corrected << " of " << rows.size()
        << " poses corrected (the others: more than "
        << "5 s from a usable baseline; the solutions alone)\n";
  if (!notes.smooth) out << "Converging: " << converging_text << " (docs/NAV_FUSION.md, \"Consistency\")\n";
  if (!in.truth.empty()) {
    out << "Against truth: " << describe(compare_poses(rows, in.truth)) << "\n";
    if (!notes.smooth && n_converging > 0 && n_converging < rows.size()) {
      std::vector<nav::CameraPoseRow> during, after;
      for (std::size_t i = 0; i < rows.size(); ++i) (fp.converging[i] ? during : after).push_back(rows[i]);
      out << "  converging: " << describe(compare_poses(during, in.truth)) << "\n"
          << "  converged:  " << describe(compare_poses(after, in.truth)) << "\n";
    }
  }
  out << "Wrote " << a.get("out") << "\n";
}

int nav_command(const std::vector<std::string>& args, std::ostream& out) {
  const ParsedArgs a = parse_or_usage(args, nav_specs());
  if (a.help) {
    out << format_help(
        "augrig nav --tanker DIR --receiver DIR --rig RIG --frames INDEX.csv --out POSES.csv [options]",
        "Fuses each aircraft's GPS and IMU (error-state Kalman filter + RTS smoother, docs/NAV_FUSION.md)\n"
        "and writes the receiver's pose in each camera at each frame's mid-exposure time, with 1-sigma\n"
        "and the boom articulation that tracks the receptacle.",
        nav_specs());
    return kExitOk;
  }
  if (a.has("camera-clock") && a.has("camera-offset-ns"))
    usage_error("--camera-clock and --camera-offset-ns exclude each other");
  if (!a.has("camera-clock") && (a.has("camera-clock-every") || a.has("terrain-height-m")))
    usage_error("--camera-clock-every and --terrain-height-m need --camera-clock");
  std::vector<TimestampNs> offsets =
      a.has("camera-offset-ns") ? parse_offsets(a.get("camera-offset-ns")) : std::vector<TimestampNs>{};
  const NavInputs in = load_nav_inputs(a, out);

  NavNotes notes;
  notes.smooth = !a.has("forward-only");
  const auto t0 = Clock::now();
  nav::NavTrajectory tk = unwrap(nav::fuse(in.tanker.imu, in.tanker.gps, in.tanker.config, notes.smooth));
  nav::NavTrajectory rx =
      unwrap(nav::fuse(in.receiver.imu, in.receiver.gps, in.receiver.config, notes.smooth));
  notes.fuse_ms = ms_since(t0);
  out << describe("tanker", tk.report()) << "\n" << describe("receiver", rx.report()) << "\n";
  notes.imu_clocks = imu_clock_text(tk, rx, out);
  notes.consistency = sigma_consistency(in, tk, rx, out);
  if (a.has("solutions")) {
    const fs::path d = a.get("solutions");
    make_dirs(d);
    check(nav::write_nav_solution_csv((d / "tanker.csv").string(), nav_solution_rows(tk)));
    check(nav::write_nav_solution_csv((d / "receiver.csv").string(), nav_solution_rows(rx)));
  }
  const std::shared_ptr<const BaselineNav> baseline = moving_baseline(a, in, tk, rx, notes.rover_path, out);
  notes.baseline = baseline != nullptr;
  std::vector<std::optional<nav::CameraClockEstimate>> clocks(in.rig.cameras.size());
  if (a.has("camera-clock")) {
    notes.clock_text = estimate_camera_clocks(a, in, tk, clocks, out);
    offsets.clear();  // the estimates apply per frame (with their drift)
  }

  Eigen::Vector3d receptacle = receptacle_of(in.rig);
  RelativeNav rel(std::move(tk), std::move(rx), in.rig, BoomDimensions{}, receptacle, offsets);
  rel.set_baseline(baseline);
  const FramePoses fp = frame_poses(a, in, rel, clocks);
  write_poses(a, in, rel, fp, notes, out);
  return kExitOk;
}

}  // namespace

int cmd_nav(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("nav", err, [&] { return nav_command(args, out); });
}

}  // namespace augrig::app
