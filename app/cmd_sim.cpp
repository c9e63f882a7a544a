// augrig sim: writes a simulated flight as a flight-test dataset (docs/SIMULATION.md, "Datasets"):
//   scenario.yaml, rig.yaml                 what was flown, with which rig
//   tanker/, receiver/                      gps.nmea (with arrival times), imu.csv, aircraft.yaml, and
//                                           nav.csv (the aircraft's real-time nav solution);
//                                           receiver/rover.ubx: the moving-baseline RTK rover's log
//                                           (UBX NAV-RELPOSNED), when the scenario has one
//   truth/tanker.csv, truth/receiver.csv    both aircraft in the nav-solution CSV format, 50 Hz
//   truth/poses.csv                         the receiver in each camera at every delivered frame
//   frames/index.csv, frames/left|right/    the rendered frames and their camera timestamps
// Deterministic for a seed. Flow: scenario -> truth (Flight) -> sensors -> files -> frames.
#include <cstdio>
#include <fstream>
#include <iostream>
#include <tuple>

#include "app/cli.hpp"
#include "pipeline/flight_nav.hpp"
#include "core/file_check.hpp"
#include "nav/logs.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"

namespace augrig::app {

namespace {

const std::vector<OptionSpec>& sim_specs() {
  static const std::vector<OptionSpec> specs = {
      {"scenario", ArgKind::kValue, "NAME|FILE.yaml",
       "a built-in scenario (demo, demo-noise-free, contact-10min, contact-10min-noise-free) or a file",
       true},
      {"out", ArgKind::kValue, "DIR", "output folder (created)", true},
      {"seed", ArgKind::kValue, "N", "random seed (default: the scenario's)"},
      {"no-images", ArgKind::kFlag, "", "write truth and logs only, no rendered frames"},
      {"every", ArgKind::kValue, "K", "render every K-th frame only (default 1: all)"},
  };
  return specs;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) runtime_error(path.string() + ": write failed");
}

nav::NavSolutionRow truth_row(const sim::KinematicState& k, TimestampNs t_ns) {
  const nav::Geodetic g = nav::geodetic_from_ecef(k.p_ecef_m);
  const Eigen::Matrix3d R_ned_ecef = nav::R_ecef_ned(g.lat_rad, g.lon_rad).transpose();
  const Eigen::Vector3d v = R_ned_ecef * k.v_ecef_mps;
  const YawPitchRoll e = ypr_from_rotation(R_ned_ecef * k.R_ecef_body());
  nav::NavSolutionRow r;
  r.t_ns = t_ns;
  r.lat_deg = rad_to_deg(g.lat_rad), r.lon_deg = rad_to_deg(g.lon_rad), r.h_m = g.h_m;
  r.vn_mps = v.x(), r.ve_mps = v.y(), r.vd_mps = v.z();
  r.yaw_deg = rad_to_deg(e.yaw_rad), r.pitch_deg = rad_to_deg(e.pitch_rad),
  r.roll_deg = rad_to_deg(e.roll_rad);
  r.sigma_n_m = r.sigma_e_m = r.sigma_d_m = 0;
  r.sigma_yaw_deg = r.sigma_pitch_deg = r.sigma_roll_deg = 0;
  return r;
}

// A progress bar on stderr for long runs (only when it is a terminal would be nicer; a log file
// gets one line per 10 %).
class Progress {
 public:
  Progress(std::string what, std::size_t total) : what_(std::move(what)), total_(total) {}
  void step(std::size_t done) {
    const int pct = total_ ? static_cast<int>(100 * done / total_) : 100;
    if (pct / 10 == last_ / 10 && done != total_) return;
    last_ = pct;
    const int bar = pct / 5;
    std::fprintf(stderr, "\r%s [%.*s%*s] %3d%% (%zu/%zu)", what_.c_str(), bar, "####################",
                 20 - bar, "", pct, done, total_);
    if (done == total_) std::fprintf(stderr, "\n");
    std::fflush(stderr);
  }

 private:
  std::string what_;
  std::size_t total_;
  int last_ = -100;
};

int sim(const std::vector<std::string>& args, std::ostream& out) {
  const ParsedArgs a = parse_or_usage(args, sim_specs());
  if (a.help) {
    out << format_help("augrig sim --scenario NAME|FILE --out DIR [--seed N] [--no-images] [--every K]",
                       "Simulates a flight: truth, GPS/IMU logs in real formats, rendered stereo frames.",
                       sim_specs());
    return kExitOk;
  }
  const std::string which = a.get("scenario");
  const bool is_file = which.find('/') != std::string::npos || which.ends_with(".yaml");
  // A scenario file is read once: the text flown is the text copied to scenario.yaml (a second read
  // could differ, fail unseen, or block for ever on a FIFO). read_text_file() names a directory.
  const std::string file_text =
      is_file ? unwrap(read_text_file("scenario::load(): ", which, "scenario file")) : std::string();
  sim::Scenario scenario =
      unwrap(is_file ? sim::parse_scenario(file_text, which) : sim::builtin_scenario(which));
  if (a.has("seed"))
    scenario.seed = static_cast<std::uint64_t>(parse_integer("seed", a.get("seed"), 0, 1LL << 62));
  const int every = a.has("every") ? static_cast<int>(parse_integer("every", a.get("every"), 1, 1000)) : 1;

  const fs::path dir = a.get("out");
  make_dirs(dir / "truth");
  const auto t0 = Clock::now();
  const sim::Flight flight = unwrap(sim::Flight::create(scenario));
  const sim::SensorLogs logs = sim::simulate_sensors(scenario, flight);

  // What was flown: the scenario as text (a file is copied; a built-in written out) and the rig.
  if (is_file) {
    write_text(dir / "scenario.yaml", file_text);
  } else {
    const std::string base = which.ends_with("-noise-free") ? which.substr(0, which.size() - 11) : which;
    std::string text = unwrap(sim::builtin_scenario_text(base));
    if (base != which) text += "# run as '" + which + "': every sensor noise-free\n";
    write_text(dir / "scenario.yaml", text);
  }
  write_text(dir / "rig.yaml", rig_to_yaml(scenario.rig));
  check(write_aircraft_logs((dir / "tanker").string(), logs.tanker_imu, logs.tanker_gps,
                            ins_config_for(scenario.sensors.tanker)));
  check(write_aircraft_logs((dir / "receiver").string(), logs.receiver_imu, logs.receiver_gps,
                            ins_config_for(scenario.sensors.receiver)));
  // The rover's moving-baseline RTK log (UBX NAV-RELPOSNED), when the scenario has one.
  const std::vector<sim::MovingBaselineEpoch> baseline = sim::simulate_moving_baseline(scenario, flight);
  if (!baseline.empty()) check(sim::write_relposned_ubx((dir / "receiver" / "rover.ubx").string(), baseline));

  // Each aircraft's own real-time nav solution, as its onboard GPS/INS would log it: the forward
  // filter alone (no smoothing: onboard, the future is unknown), at the filter's epochs.
  for (const auto& [who, imu, gps, sensors] :
       {std::tuple{"tanker", &logs.tanker_imu, &logs.tanker_gps, &scenario.sensors.tanker},
        std::tuple{"receiver", &logs.receiver_imu, &logs.receiver_gps, &scenario.sensors.receiver}}) {
    const nav::NavTrajectory onboard = unwrap(nav::fuse(*imu, *gps, ins_config_for(*sensors), false));
    nav::CsvWriteOptions o;
    o.metadata["content"] = "onboard real-time nav solution (forward GPS/INS filter)";
    check(nav::write_nav_solution_csv((dir / who / "nav.csv").string(), nav_solution_rows(onboard), o));
  }

  // Truth of both aircraft at 50 Hz, in the nav-solution format (sigmas 0).
  std::vector<nav::NavSolutionRow> tanker_truth, receiver_truth;
  const int n50 = static_cast<int>(scenario.duration_s * 50.0);
  for (int i = 0; i <= n50; ++i) {
    const double t = i / 50.0;
    const TimestampNs t_ns = scenario.start_gps_ns + s_to_ns(t);
    tanker_truth.push_back(truth_row(flight.tanker(t), t_ns));
    receiver_truth.push_back(truth_row(flight.receiver(t), t_ns));
  }
  nav::CsvWriteOptions truth_opts;
  truth_opts.metadata["content"] = "truth (scenario " + scenario.name + ")";
  check(nav::write_nav_solution_csv((dir / "truth" / "tanker.csv").string(), tanker_truth, truth_opts));
  check(nav::write_nav_solution_csv((dir / "truth" / "receiver.csv").string(), receiver_truth, truth_opts));

  // Per delivered frame: its camera timestamp and the true pose of the receiver in that camera.
  std::vector<sim::FrameTruth> truths = sim::frame_truths(scenario, flight, logs.cameras);
  std::vector<nav::CameraPoseRow> pose_rows;
  nav::FrameIndex index;
  index.metadata["scenario"] = scenario.name;
  std::size_t dropped = 0;
  for (const auto& cam : logs.cameras)
    for (const auto& f : cam) dropped += f.dropped ? 1 : 0;
  for (const sim::FrameTruth& t : truths) {
    if (t.sequence % every != 0) continue;
    pose_rows.push_back(sim::pose_row(t));
    char name[64];
    std::snprintf(name, sizeof name, "%s/%06llu.png", t.camera == 0 ? "left" : "right",
                  static_cast<unsigned long long>(t.sequence));
    index.rows.push_back({t.sequence, t.camera, t.t_camera_ns, name});
  }
  nav::CsvWriteOptions pose_opts = truth_opts;
  pose_opts.clock = ClockDomain::kDevice;  // t_ns is the camera's stamp; t_nav_ns is GPS time
  pose_opts.metadata["t_nav_ns"] = "gps";
  check(nav::write_camera_pose_csv((dir / "truth" / "poses.csv").string(), pose_rows, pose_opts));
  make_dirs(dir / "frames");
  check(nav::write_frame_index_csv((dir / "frames" / "index.csv").string(), index));
  out << "sim: scenario '" << scenario.name << "' (" << scenario.source << "), " << scenario.duration_s
      << " s, seed " << scenario.seed << "\n"
      << "  tanker: " << logs.tanker_imu.size() << " IMU samples, " << logs.tanker_gps.size()
      << " GPS fixes\n"
      << "  receiver: " << logs.receiver_imu.size() << " IMU samples, " << logs.receiver_gps.size()
      << " GPS fixes\n"
      << "  cameras: " << index.rows.size() << " frames indexed, " << dropped << " dropped by the cameras\n";

  if (!a.has("no-images")) {
    make_dirs(dir / "frames" / "left");
    make_dirs(dir / "frames" / "right");
    // The CPU renderer (sim/synthetic_scene_cpu.hpp): no GL context needed.
    auto source = unwrap(sim::FlightSource::create(scenario, flight, truths, every));
    Progress progress("sim: rendering", source->frame_count());
    Frame f;
    for (std::size_t i = 0; i < index.rows.size(); ++i) {
      if (unwrap(source->read(f, std::chrono::nanoseconds(0))) != ReadStatus::kFrame)
        runtime_error("the simulated cameras ended early, at frame " + std::to_string(i));
      write_png(dir / "frames" / index.rows[i].file, f.image);
      progress.step(i + 1);
    }
  }
  out << "Wrote " << dir.string() << " in " << fmt_ms(ms_since(t0) / 1000.0) << " s\n";
  return kExitOk;
}

}  // namespace

int cmd_sim(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("sim", err, [&] { return sim(args, out); });
}

}  // namespace augrig::app
