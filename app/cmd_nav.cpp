// augrig nav: both aircraft's GPS/IMU logs -> the receiver's pose in each camera at every frame.
// Flow: load and check every input (logs, rig, frame index) -> fuse each aircraft (forward filter,
// RTS smoother) -> per frame: camera time -> nav time -> relative pose with 1-sigma -> boom tracking
// -> poses.csv; with --truth, the error against it.
#include <iostream>
#include <sstream>

#include "app/cli.hpp"
#include "pipeline/flight_nav.hpp"
#include "nav/logs.hpp"

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
      {"forward-only", ArgKind::kFlag, "", "no RTS smoothing (what a real-time filter would know)"},
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
  const std::vector<TimestampNs> offsets =
      a.has("camera-offset-ns") ? parse_offsets(a.get("camera-offset-ns")) : std::vector<TimestampNs>{};
  // Every input is read and checked before any work.
  const BoomArg boom = parse_boom_arg(a.get("boom"));
  const Rig rig = load_rig_arg(a.get("rig"));
  const AircraftLogs tanker = unwrap(load_aircraft_logs(a.get("tanker")));
  const AircraftLogs receiver = unwrap(load_aircraft_logs(a.get("receiver")));
  const nav::FrameIndex index = unwrap(nav::read_frame_index_csv(a.get("frames")));
  std::vector<nav::CameraPoseRow> truth;
  if (a.has("truth")) truth = unwrap(nav::read_camera_pose_csv(a.get("truth"))).rows;
  for (const auto& [who, logs] : {std::pair{"tanker", &tanker}, std::pair{"receiver", &receiver}}) {
    print_issues(out, std::string(who) + " gps.nmea", logs->gps_issues);
    print_issues(out, std::string(who) + " imu.csv", logs->imu_issues);
  }

  const bool smooth = !a.has("forward-only");
  const auto t0 = Clock::now();
  nav::NavTrajectory tk = unwrap(nav::fuse(tanker.imu, tanker.gps, tanker.config, smooth));
  nav::NavTrajectory rx = unwrap(nav::fuse(receiver.imu, receiver.gps, receiver.config, smooth));
  const double fuse_ms = ms_since(t0);
  out << describe("tanker", tk.report()) << "\n" << describe("receiver", rx.report()) << "\n";
  if (a.has("solutions")) {
    const fs::path d = a.get("solutions");
    make_dirs(d);
    check(nav::write_nav_solution_csv((d / "tanker.csv").string(), nav_solution_rows(tk)));
    check(nav::write_nav_solution_csv((d / "receiver.csv").string(), nav_solution_rows(rx)));
  }

  Eigen::Vector3d receptacle = receptacle_of(rig);
  RelativeNav rel(std::move(tk), std::move(rx), rig, BoomDimensions{}, receptacle, offsets);
  std::vector<nav::CameraPoseRow> rows;
  std::size_t outside = 0;
  const auto t1 = Clock::now();
  for (const nav::FrameIndexRow& f : index.rows) {
    auto p = rel.at(f.camera, f.t_ns);
    if (!p) {
      ++outside;  // before the first fix or after the last IMU sample: no pose, said below
      continue;
    }
    p->boom = boom.command(ns_to_s(f.t_ns - index.rows.front().t_ns), p->boom, rig.boom.limits);
    rows.push_back(p->row(f.sequence, f.camera, f.t_ns));
    // A capture-only rig has no boom to articulate: the boom columns stay empty (whoever augments
    // with these poses flies its own rig's boom), unless --boom says what it does.
    if (!rig.boom.configured && !a.has("boom"))
      rows.back().boom_elevation_deg = rows.back().boom_azimuth_deg = rows.back().boom_extension_m = nav::CameraPoseRow::kNaN;
  }
  const double query_us = rows.empty() ? 0 : 1e3 * ms_since(t1) / static_cast<double>(rows.size());
  nav::CsvWriteOptions o;
  o.clock = ClockDomain::kDevice;  // t_ns is the camera's stamp; t_nav_ns is GPS time
  o.metadata["t_nav_ns"] = "gps";
  o.metadata["content"] = "estimate: T_cam_receiver from GPS/INS fusion";
  o.metadata["smoothing"] = smooth ? "rts" : "none";
  check(nav::write_camera_pose_csv(a.get("out"), rows, o));
  out << "Poses: " << rows.size() << " of " << index.rows.size() << " frames";
  if (outside) out << " (" << outside << " outside the nav data: no pose written)";
  out << "; fusion " << fmt_ms(fuse_ms) << " ms for both aircraft, " << fmt_ms(query_us)
      << " us per frame pose\n";
  if (!truth.empty()) out << "Against truth: " << describe(compare_poses(rows, truth)) << "\n";
  out << "Wrote " << a.get("out") << "\n";
  return kExitOk;
}

}  // namespace

int cmd_nav(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("nav", err, [&] { return nav_command(args, out); });
}

}  // namespace augrig::app
