#include "pipeline/flight_nav.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "core/file_check.hpp"
#include "core/yaml_reader.hpp"
#include "nav/gps_time.hpp"
#include "nav/nmea.hpp"
#include "pipeline/baseline_nav.hpp"
#include "sim/scenario.hpp"

namespace augrig::pipeline {

namespace fs = std::filesystem;

constexpr double kMaxLeverArmM = 1000.0;  // an antenna farther than 1 km from the IMU is a typo

// ---- aircraft.yaml --------------------------------------------------------------------------------

Expected<nav::InsConfig> parse_aircraft_config(const std::string& yaml_text, const std::string& name) {
  using namespace yaml;
  const Context c{"aircraft::parse(): ", name};
  return guarded(c, [&]() -> nav::InsConfig {
    nav::InsConfig cfg;
    const YAML::Node root = YAML::Load(yaml_text);
    if (!root || root.IsNull()) return cfg;  // an empty file: the defaults
    expect_map(c, root, "", "a map of aircraft nav settings");
    check_keys(c, root, "",
               {"lever_arm_m", "imu_time_offset_ns", "gps_time_offset_ns", "gps_leap_seconds", "imu", "gps",
                "heading", "imu_clock", "moving_baseline_antenna_m"});
    // Every value has an upper bound too (docs/NAV_FORMATS.md): 1e300 would square to inf in the
    // filter's covariances, and a time offset must stay inside int64 once added to a timestamp.
    auto nonneg = [&](const YAML::Node& n, const std::string& key, const char* what, double max) {
      const std::string expected = std::string(what) + " and <= " + fmt(max);
      const double v = to_number(c, n, key, expected);
      if (!(v >= 0 && v <= max)) fail(c, n, key, "expected " + expected + ", got " + got(n));
      return v;
    };
    if (root["lever_arm_m"]) {
      const YAML::Node n = root["lever_arm_m"];
      cfg.lever_arm_body_m = to_vec3(c, n, "lever_arm_m", "[x, y, z] in metres, body FRD");
      for (int i = 0; i < 3; ++i) {
        if (!(std::abs(cfg.lever_arm_body_m[i]) <= kMaxLeverArmM)) {
          fail(c, n[i], "lever_arm_m",
               "expected each component within +-" + fmt(kMaxLeverArmM) + " m, got " + got(n[i]) +
                   " as element " + std::to_string(i));
        }
      }
    }
    if (root["moving_baseline_antenna_m"]) {
      const YAML::Node n = root["moving_baseline_antenna_m"];
      const Eigen::Vector3d v = to_vec3(c, n, "moving_baseline_antenna_m", "[x, y, z] in metres, body FRD");
      for (int i = 0; i < 3; ++i)
        if (!(std::abs(v[i]) <= kMaxLeverArmM))
          fail(c, n[i], "moving_baseline_antenna_m",
               "expected each component within +-" + fmt(kMaxLeverArmM) + " m, got " + got(n[i]) + " as element " +
                   std::to_string(i));
      cfg.baseline_antenna_body_m = v;
    }
    // Checked before the cast to int64: 1e30 would wrap around (undefined behaviour).
    auto offset_ns = [&](const char* key) {
      const YAML::Node n = root[key];
      const double v = to_number(c, n, key, "a time offset in ns");
      if (!(std::abs(v) <= static_cast<double>(nav::kMaxAbsTimeOffsetNs))) {
        fail(c, n, key,
             std::string("expected a time offset in ") + nav::kTimeOffsetRangeText + ", " + got(n));
      }
      return static_cast<TimestampNs>(v);
    };
    if (root["imu_time_offset_ns"]) cfg.imu_time_offset_ns = offset_ns("imu_time_offset_ns");
    if (root["gps_time_offset_ns"]) cfg.gps_time_offset_ns = offset_ns("gps_time_offset_ns");
    if (const YAML::Node n = root["gps_leap_seconds"]) {
      const std::string what = "GPS - UTC in whole seconds, 0..100 (18 since 2017-01-01)";
      const double v = to_number(c, n, "gps_leap_seconds", what);
      if (!(v >= 0 && v <= 100 && v == std::floor(v)))
        fail(c, n, "gps_leap_seconds", "expected " + what + ", " + got(n));
      cfg.gps_leap_seconds = static_cast<int>(v);
    }
    if (const YAML::Node imu = root["imu"]) {
      expect_map(c, imu, "imu", "a map of IMU noise values");
      check_keys(c, imu, "imu",
                 {"gyro_arw_deg_per_sqrt_h", "accel_vrw_mps_per_sqrt_h", "gyro_bias_deg_per_h",
                  "accel_bias_mg", "bias_tau_s"});
      if (imu["gyro_arw_deg_per_sqrt_h"])
        cfg.imu.gyro_arw_rad_psqrts =
            deg_to_rad(
                nonneg(imu["gyro_arw_deg_per_sqrt_h"], "imu.gyro_arw_deg_per_sqrt_h", "a number >= 0", 1e4)) /
            60.0;
      if (imu["accel_vrw_mps_per_sqrt_h"])
        cfg.imu.accel_vrw_mps_psqrts =
            nonneg(imu["accel_vrw_mps_per_sqrt_h"], "imu.accel_vrw_mps_per_sqrt_h", "a number >= 0", 1e4) /
            60.0;
      if (imu["gyro_bias_deg_per_h"])
        cfg.imu.gyro_bias.sigma =
            deg_to_rad(nonneg(imu["gyro_bias_deg_per_h"], "imu.gyro_bias_deg_per_h", "a number >= 0", 1e6)) /
            3600.0;
      if (imu["accel_bias_mg"])
        cfg.imu.accel_bias.sigma =
            nonneg(imu["accel_bias_mg"], "imu.accel_bias_mg", "a number >= 0", 1e6) * 1e-3 * 9.80665;
      if (imu["bias_tau_s"]) {
        const double tau = nonneg(imu["bias_tau_s"], "imu.bias_tau_s", "a correlation time >= 0 s", 1e9);
        cfg.imu.gyro_bias.tau_s = cfg.imu.accel_bias.tau_s = tau;
      }
    }
    if (const YAML::Node gps = root["gps"]) {
      expect_map(c, gps, "gps", "a map of GPS noise values");
      check_keys(c, gps, "gps", {"rtk_fixed_m", "rtk_float_m", "use_gst"});
      if (gps["rtk_fixed_m"])
        cfg.gps.rtk_fixed_m = nonneg(gps["rtk_fixed_m"], "gps.rtk_fixed_m", "a sigma >= 0 m", 1e6);
      if (gps["rtk_float_m"])
        cfg.gps.rtk_float_m = nonneg(gps["rtk_float_m"], "gps.rtk_float_m", "a sigma >= 0 m", 1e6);
      if (gps["use_gst"]) cfg.gps.use_gst = to_bool(c, gps["use_gst"], "gps.use_gst");
    }
    if (const YAML::Node h = root["heading"]) {
      expect_map(c, h, "heading", "a map {use, offset_deg, sigma_deg}");
      check_keys(c, h, "heading", {"use", "offset_deg", "sigma_deg"});
      if (h["use"]) cfg.use_heading = to_bool(c, h["use"], "heading.use");
      if (h["offset_deg"]) {
        const double deg = to_number(c, h["offset_deg"], "heading.offset_deg", "an angle in degrees");
        if (!(std::abs(deg) <= 360)) {
          fail(c, h["offset_deg"], "heading.offset_deg",
               "expected an angle in degrees within +-360, " + got(h["offset_deg"]));
        }
        cfg.heading_offset_rad = deg_to_rad(deg);
      }
      if (h["sigma_deg"])
        cfg.heading_sigma_rad =
            deg_to_rad(nonneg(h["sigma_deg"], "heading.sigma_deg", "a sigma >= 0 deg", 180));
    }
    if (const YAML::Node k = root["imu_clock"]) {
      // The IMU clock against GPS time as filter states (docs/NAV_FUSION.md, "IMU clock").
      expect_map(c, k, "imu_clock",
                 "a map {estimate, offset_sigma_ms, drift_sigma_ppm, offset_random_walk_us_per_sqrt_s, "
                 "drift_random_walk_ppm_per_sqrt_s}");
      check_keys(c, k, "imu_clock",
                 {"estimate", "offset_sigma_ms", "drift_sigma_ppm", "offset_random_walk_us_per_sqrt_s",
                  "drift_random_walk_ppm_per_sqrt_s"});
      nav::ImuClockModel& m = cfg.imu_clock;
      // The initial sigmas > 0: the filter's covariance must stay positive definite.
      auto positive = [&](const YAML::Node& n, const std::string& key, const char* what, double max) {
        const std::string expected = std::string(what) + " > 0 and <= " + fmt(max);
        const double v = to_number(c, n, key, expected);
        if (!(v > 0 && v <= max)) fail(c, n, key, "expected " + expected + ", " + got(n));
        return v;
      };
      if (k["estimate"]) m.estimate = to_bool(c, k["estimate"], "imu_clock.estimate");
      if (k["offset_sigma_ms"])
        m.offset_sigma_s =
            1e-3 * positive(k["offset_sigma_ms"], "imu_clock.offset_sigma_ms", "a sigma in ms", 1e4);
      if (k["drift_sigma_ppm"])
        m.drift_sigma =
            1e-6 * positive(k["drift_sigma_ppm"], "imu_clock.drift_sigma_ppm", "a sigma in ppm", 1e4);
      if (k["offset_random_walk_us_per_sqrt_s"])
        m.offset_random_walk_s_psqrts =
            1e-6 * nonneg(k["offset_random_walk_us_per_sqrt_s"], "imu_clock.offset_random_walk_us_per_sqrt_s",
                          "a density >= 0 us/sqrt(s)", 1e6);
      if (k["drift_random_walk_ppm_per_sqrt_s"])
        m.drift_random_walk_psqrts =
            1e-6 * nonneg(k["drift_random_walk_ppm_per_sqrt_s"], "imu_clock.drift_random_walk_ppm_per_sqrt_s",
                          "a density >= 0 ppm/sqrt(s)", 1e4);
    }
    return cfg;
  });
}

Expected<nav::InsConfig> load_aircraft_config(const std::string& path) {
  auto text = read_text_file("aircraft::load(): ", path, "aircraft file");
  if (!text) return text.error();
  return parse_aircraft_config(*text, path);
}

std::string aircraft_config_to_yaml(const nav::InsConfig& c) {
  using yaml::fmt;
  std::ostringstream o;
  o << "# augrig aircraft nav settings (docs/NAV_FORMATS.md)\n"
    << "lever_arm_m: [" << fmt(c.lever_arm_body_m.x()) << ", " << fmt(c.lever_arm_body_m.y()) << ", "
    << fmt(c.lever_arm_body_m.z()) << "]\n"
    << "imu_time_offset_ns: " << c.imu_time_offset_ns << "\n"
    << "gps_time_offset_ns: " << c.gps_time_offset_ns << "\n";
  if (c.gps_leap_seconds) o << "gps_leap_seconds: " << *c.gps_leap_seconds << "\n";
  if (const auto& b = c.baseline_antenna_body_m)
    o << "moving_baseline_antenna_m: [" << fmt(b->x()) << ", " << fmt(b->y()) << ", " << fmt(b->z()) << "]\n";
  o << "imu:\n"
    << "  gyro_arw_deg_per_sqrt_h: " << fmt(rad_to_deg(c.imu.gyro_arw_rad_psqrts) * 60.0) << "\n"
    << "  accel_vrw_mps_per_sqrt_h: " << fmt(c.imu.accel_vrw_mps_psqrts * 60.0) << "\n"
    << "  gyro_bias_deg_per_h: " << fmt(rad_to_deg(c.imu.gyro_bias.sigma) * 3600.0) << "\n"
    << "  accel_bias_mg: " << fmt(c.imu.accel_bias.sigma / (1e-3 * 9.80665)) << "\n"
    << "  bias_tau_s: " << fmt(c.imu.gyro_bias.tau_s) << "\n"
    << "gps:\n"
    << "  rtk_fixed_m: " << fmt(c.gps.rtk_fixed_m) << "\n"
    << "  rtk_float_m: " << fmt(c.gps.rtk_float_m) << "\n"
    << "  use_gst: " << (c.gps.use_gst ? "true" : "false") << "\n"
    << "heading:\n"
    << "  use: " << (c.use_heading ? "true" : "false") << "\n"
    << "  offset_deg: " << fmt(rad_to_deg(c.heading_offset_rad)) << "\n"
    << "  sigma_deg: " << fmt(rad_to_deg(c.heading_sigma_rad)) << "\n";
  const nav::ImuClockModel& k = c.imu_clock;
  if (k.estimate || k.offset_sigma_s != nav::ImuClockModel{}.offset_sigma_s ||
      k.drift_sigma != nav::ImuClockModel{}.drift_sigma || k.offset_random_walk_s_psqrts > 0 ||
      k.drift_random_walk_psqrts > 0) {
    o << "imu_clock:\n"
      << "  estimate: " << (k.estimate ? "true" : "false") << "\n"
      << "  offset_sigma_ms: " << fmt(k.offset_sigma_s * 1e3) << "\n"
      << "  drift_sigma_ppm: " << fmt(k.drift_sigma * 1e6) << "\n"
      << "  offset_random_walk_us_per_sqrt_s: " << fmt(k.offset_random_walk_s_psqrts * 1e6) << "\n"
      << "  drift_random_walk_ppm_per_sqrt_s: " << fmt(k.drift_random_walk_psqrts * 1e6) << "\n";
  }
  return o.str();
}

// The nav settings a user would write for a simulated aircraft: the surveyed lever arm and the IMU's
// datasheet noise (the sim's own model; zero noise keeps a small floor so the filter stays regular).
nav::InsConfig ins_config_for(const sim::AircraftSensors& s) {
  nav::InsConfig c;
  c.lever_arm_body_m = s.gps.lever_arm_m;
  const auto& g = s.imu.errors.gyro;
  const auto& a = s.imu.errors.accel;
  c.imu.gyro_arw_rad_psqrts = std::max(g.arw_rad_per_sqrt_s, 1e-7);
  c.imu.accel_vrw_mps_psqrts = std::max(a.vrw_mps_per_sqrt_s, 1e-6);
  c.imu.gyro_bias.sigma = std::max(std::hypot(g.bias_instability_radps, g.turn_on_bias_radps), 1e-8);
  c.imu.gyro_bias.tau_s = g.bias_tau_s;
  c.imu.accel_bias.sigma = std::max(std::hypot(a.bias_instability_mps2, a.turn_on_bias_mps2), 1e-6);
  c.imu.accel_bias.tau_s = a.bias_tau_s;
  c.gps.rtk_fixed_m = std::max(s.gps.sigma_horizontal_m, 1e-3);
  c.gps.rtk_float_m = std::max(s.gps.float_sigma_horizontal_m, 1e-3);
  c.use_heading = s.gps.heading;
  c.heading_sigma_rad = std::max(s.gps.heading_sigma_rad, 1e-6);
  // An IMU that does not stamp on GPS time: its clock is estimated (from a prior of 0).
  c.imu_clock.estimate = s.imu.clock_offset_ns != 0 || s.imu.clock_drift_ppm != 0;
  return c;
}

// ---- Logs -----------------------------------------------------------------------------------------

Expected<AircraftLogs> load_aircraft_logs(const std::string& folder, const AircraftLoadOptions& options) {
  AircraftLogs logs;
  logs.folder = folder;
  const fs::path dir(folder);
  if (!fs::is_directory(dir))
    return make_error("aircraft::load_logs(): ", folder,
                      ": not a folder (expected gps.nmea, imu.csv, aircraft.yaml)");
  // aircraft.yaml first: it may say the leap seconds gps.nmea needs.
  const std::string yaml_path = (dir / "aircraft.yaml").string();
  std::error_code ec;
  if (fs::exists(yaml_path, ec) || fs::is_symlink(yaml_path, ec)) {
    auto cfg = load_aircraft_config(yaml_path);
    if (!cfg) return cfg.error();
    logs.config = *cfg;
  } else if (options.allow_default_config) {
    logs.default_config = true;
    logs.notes.push_back("no " + yaml_path +
                         ": the defaults are used (antenna at the IMU, no time offsets, a tactical IMU, 2 cm RTK; "
                         "docs/NAV_FORMATS.md): the pose and its sigma assume them, and a wrong lever arm shows in "
                         "the GPS innovations only when the aircraft turns");
  } else {
    return make_error("aircraft::load_logs(): ", folder, ": no aircraft.yaml (expected ", yaml_path,
                      ": the antenna lever arm, IMU and GPS noise and time offsets, docs/NAV_FORMATS.md); "
                      "fusing without it would assume the antenna at the IMU and a tactical IMU, and report a "
                      "sigma that does not hold: write one, or ask for the defaults (augrig nav --default-aircraft)");
  }
  nav::NmeaOptions nmea;
  if (options.leap_seconds) {
    nmea.leap_seconds = options.leap_seconds;
    logs.leap_seconds_source = options.leap_seconds_source;
    if (logs.config.gps_leap_seconds && *logs.config.gps_leap_seconds != *options.leap_seconds) {
      logs.warnings.push_back(options.leap_seconds_source + " " + std::to_string(*options.leap_seconds) +
                              " overrides " + yaml_path + "'s gps_leap_seconds " +
                              std::to_string(*logs.config.gps_leap_seconds));
    }
  } else if (logs.config.gps_leap_seconds) {
    nmea.leap_seconds = logs.config.gps_leap_seconds;
    logs.leap_seconds_source = "aircraft.yaml gps_leap_seconds";
  }
  auto gps = nav::read_nmea_file((dir / "gps.nmea").string(), nmea);
  if (!gps) return gps.error();
  auto imu = nav::read_imu_csv((dir / "imu.csv").string());
  if (!imu) return imu.error();
  logs.leap_seconds = gps->leap_seconds;
  const nav::LeapSecondsUse& leap = logs.leap_seconds;
  if (leap.disagreements) {
    // Given and wrong (the receiver's report or the table disagree), or the receiver against the
    // table (its value used): said with the file and line of the first such fix.
    logs.warnings.push_back(leap.first_disagreement + " (" + std::to_string(leap.disagreements) + " of " +
                            std::to_string(gps->fixes.size()) + " fixes" +
                            (leap.given ? "; given by " + logs.leap_seconds_source : std::string()) + ")");
  }
  logs.gps = std::move(gps->fixes);
  logs.gps_issues = std::move(gps->issues);
  logs.imu = std::move(imu->samples);
  logs.imu_issues = std::move(imu->issues);
  return logs;
}

Status write_aircraft_logs(const std::string& folder, const std::vector<nav::ImuSample>& imu,
                           const std::vector<nav::GpsFix>& gps, const nav::InsConfig& config) {
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec)
    return make_error("aircraft::write_logs(): ", folder, ": cannot create the folder (", ec.message(), ")");
  nav::NmeaWriterOptions nmea;
  nmea.write_arrival_prefix = true;  // the arrival time is part of what a recorder keeps
  if (auto s = nav::write_nmea_file((fs::path(folder) / "gps.nmea").string(), gps, nmea); !s) return s;
  if (auto s = nav::write_imu_csv((fs::path(folder) / "imu.csv").string(), imu); !s) return s;
  std::ofstream out(fs::path(folder) / "aircraft.yaml", std::ios::binary);
  out << aircraft_config_to_yaml(config);
  if (!out) return make_error("aircraft::write_logs(): ", folder, "/aircraft.yaml: write failed");
  return {};
}

std::vector<nav::NavSolutionRow> nav_solution_rows(const nav::NavTrajectory& t) {
  std::vector<nav::NavSolutionRow> rows;
  for (const nav::NavSolution& s : t.solutions()) {
    nav::NavSolutionRow r;
    r.t_ns = s.t_ns;
    r.lat_deg = rad_to_deg(s.position.lat_rad), r.lon_deg = rad_to_deg(s.position.lon_rad),
    r.h_m = s.position.h_m;
    r.vn_mps = s.v_ned_mps.x(), r.ve_mps = s.v_ned_mps.y(), r.vd_mps = s.v_ned_mps.z();
    r.yaw_deg = rad_to_deg(s.attitude.yaw_rad), r.pitch_deg = rad_to_deg(s.attitude.pitch_rad);
    r.roll_deg = rad_to_deg(s.attitude.roll_rad);
    r.sigma_n_m = s.sigma_pos_ned_m.x(), r.sigma_e_m = s.sigma_pos_ned_m.y(),
    r.sigma_d_m = s.sigma_pos_ned_m.z();
    r.sigma_yaw_deg = rad_to_deg(s.sigma_ypr_rad.x()), r.sigma_pitch_deg = rad_to_deg(s.sigma_ypr_rad.y());
    r.sigma_roll_deg = rad_to_deg(s.sigma_ypr_rad.z());
    r.imu_clock_offset_ms = 1e3 * s.imu_clock_offset_s, r.imu_clock_drift_ppm = 1e6 * s.imu_clock_drift_s_per_s;
    r.sigma_imu_clock_offset_ms = 1e3 * s.sigma_imu_clock_offset_s;
    r.sigma_imu_clock_drift_ppm = 1e6 * s.sigma_imu_clock_drift;
    rows.push_back(r);
  }
  return rows;
}

// ---- Relative navigation --------------------------------------------------------------------------

nav::PoseWithCovariance pose_with_covariance(const nav::NavState& s) {
  nav::PoseWithCovariance p;
  p.T_ecef_body = s.T_ecef_body();
  // Error-state layout [dp 0..2, dv 3..5, dtheta 6..8, ...]: position and attitude blocks.
  p.cov.topLeftCorner<3, 3>() = s.P.block<3, 3>(0, 0);
  p.cov.topRightCorner<3, 3>() = s.P.block<3, 3>(0, 6);
  p.cov.bottomLeftCorner<3, 3>() = s.P.block<3, 3>(6, 0);
  p.cov.bottomRightCorner<3, 3>() = s.P.block<3, 3>(6, 6);
  return p;
}

RelativeNav::RelativeNav(nav::NavTrajectory tanker, nav::NavTrajectory receiver, Rig rig, BoomDimensions boom,
                         Eigen::Vector3d receptacle_m, std::vector<TimestampNs> camera_offset_ns)
    : tanker_(std::move(tanker)),
      receiver_(std::move(receiver)),
      rig_(std::move(rig)),
      boom_(boom),
      receptacle_m_(receptacle_m),
      camera_offset_ns_(std::move(camera_offset_ns)) {}

FramePose frame_pose(const nav::NavState& tanker, const nav::NavState& receiver, TimestampNs t_nav_ns,
                     const Rig& rig, int camera, const BoomDimensions& boom,
                     const Eigen::Vector3d& receptacle_m) {
  FramePose f;
  f.t_nav_ns = t_nav_ns;
  f.T_ecef_tanker = Pose{tanker.q_ecef_body, tanker.p_ecef_m};
  // Camera-relative in double before anything narrows to float (render/ does that).
  f.body = nav::relative_pose(pose_with_covariance(tanker), pose_with_covariance(receiver));
  f.camera = nav::in_frame(rig.cameras[camera].T_body_cam.inverse(), f.body);
  f.boom = track_point(f.body.T_a_receiver * receptacle_m, rig.boom.pivot_body_m, boom, rig.boom.limits);
  return f;
}

std::optional<TimestampNs> RelativeNav::converged_ns() const {
  const nav::FusionReport &a = tanker_.report(), &b = receiver_.report();
  if (a.smoothed || b.smoothed || !a.converged || !b.converged) return std::nullopt;
  return std::max(a.converged_ns, b.converged_ns);
}

Expected<FramePose> RelativeNav::at(int camera, TimestampNs t_camera_ns) const {
  if (camera < 0 || camera >= static_cast<int>(rig_.cameras.size()))
    return make_error("RelativeNav::at(): no camera ", camera, " in the rig");
  const TimestampNs offset =
      camera < static_cast<int>(camera_offset_ns_.size()) ? camera_offset_ns_[camera] : 0;
  const TimestampNs t_nav_ns = t_camera_ns - offset;
  auto tk = tanker_.at(t_nav_ns);
  if (!tk) return make_error("RelativeNav::at(): tanker: ", tk.error().message);
  auto rx = receiver_.at(t_nav_ns);
  if (!rx) return make_error("RelativeNav::at(): receiver: ", rx.error().message);
  const bool corrected = baseline_ && baseline_->correct(t_nav_ns, *tk, *rx);
  FramePose f = frame_pose(*tk, *rx, t_nav_ns, rig_, camera, boom_, receptacle_m_);
  f.baseline_corrected = corrected;
  return f;
}

nav::CameraPoseRow FramePose::row(std::uint64_t sequence, int camera_index, TimestampNs t_camera_ns) const {
  nav::CameraPoseRow r;
  r.sequence = sequence;
  r.camera = camera_index;
  r.t_ns = t_camera_ns;
  r.t_nav_ns = t_nav_ns;
  const Eigen::Vector3d& t = camera.T_a_receiver.translation_m;
  const Eigen::Quaterniond& q = camera.T_a_receiver.rotation;
  r.x_m = t.x(), r.y_m = t.y(), r.z_m = t.z();
  r.qw = q.w(), r.qx = q.x(), r.qy = q.y(), r.qz = q.z();
  r.sigma_pos_m = camera.sigma_position_m();
  r.sigma_att_deg = rad_to_deg(camera.sigma_attitude_rad());
  r.boom_elevation_deg = rad_to_deg(boom.articulation.elevation_rad);
  r.boom_azimuth_deg = rad_to_deg(boom.articulation.azimuth_rad);
  r.boom_extension_m = boom.articulation.extension_m;
  return r;
}

PoseErrorStats compare_poses(const std::vector<nav::CameraPoseRow>& estimate,
                             const std::vector<nav::CameraPoseRow>& truth) {
  std::map<std::pair<std::uint64_t, int>, const nav::CameraPoseRow*> by_key;
  for (const nav::CameraPoseRow& t : truth) by_key[{t.sequence, t.camera}] = &t;
  PoseErrorStats s;
  double sum_p2 = 0, sum_a2 = 0;
  std::size_t inside = 0;
  for (const nav::CameraPoseRow& e : estimate) {
    const auto it = by_key.find({e.sequence, e.camera});
    if (it == by_key.end()) continue;
    const nav::CameraPoseRow& t = *it->second;
    const double dp = (Eigen::Vector3d(e.x_m, e.y_m, e.z_m) - Eigen::Vector3d(t.x_m, t.y_m, t.z_m)).norm();
    const Eigen::Quaterniond qe(e.qw, e.qx, e.qy, e.qz), qt(t.qw, t.qx, t.qy, t.qz);
    const double da = rad_to_deg(qe.angularDistance(qt));
    ++s.matched;
    sum_p2 += dp * dp, sum_a2 += da * da;
    s.pos_max_m = std::max(s.pos_max_m, dp);
    s.att_max_deg = std::max(s.att_max_deg, da);
    if (std::isfinite(e.sigma_pos_m) && dp <= e.sigma_pos_m) ++inside;
  }
  if (s.matched) {
    s.pos_rms_m = std::sqrt(sum_p2 / s.matched);
    s.att_rms_deg = std::sqrt(sum_a2 / s.matched);
    s.within_1sigma = static_cast<double>(inside) / s.matched;
  }
  return s;
}

std::string describe(const PoseErrorStats& s) {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "%zu frames: position RMS %.1f mm, max %.1f mm; attitude RMS %.4f deg, max %.4f deg; "
                "%.0f%% within the reported 1-sigma",
                s.matched, 1e3 * s.pos_rms_m, 1e3 * s.pos_max_m, s.att_rms_deg, s.att_max_deg,
                100.0 * s.within_1sigma);
  return buf;
}

std::string describe(const std::string& who, const nav::FusionReport& r) {
  std::ostringstream o;
  o << who << ": " << r.imu_samples << " IMU samples (" << r.imu_gaps << " gaps), " << r.fixes
    << " fixes: " << r.fixes_used << " used, " << r.fixes_rejected << " rejected by the gate, "
    << r.fixes_invalid << " invalid, " << r.fixes_outside << " outside the IMU data; " << r.heading_updates
    << " heading updates; " << r.outages << " outages (longest gap "
    << yaml::fmt(std::round(r.longest_fix_gap_s * 1000) / 1000) << " s); " << r.epochs << " epochs"
    << (r.smoothed ? ", smoothed" : ", forward only");
  return o.str();
}

std::string describe_imu_clock(const std::string& who, const nav::FusionReport& r) {
  if (!r.imu_clock_estimated) return "";
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "%s IMU clock - GPS time: %+.3f ms (1-sigma %.3f ms), drift %+.2f ppm (1-sigma %.2f ppm), at "
                "t_nav_ns %lld (%s)",
                who.c_str(), 1e3 * r.imu_clock_offset_s, 1e3 * r.imu_clock_offset_sigma_s,
                1e6 * r.imu_clock_drift_s_per_s, 1e6 * r.imu_clock_drift_sigma,
                static_cast<long long>(r.imu_clock_t_ns),
                r.smoothed ? "smoothed, the first epoch" : "forward filter, the last epoch");
  return buf;
}

namespace {

std::string fixed1(double v, const char* format = "%.2f") {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

}  // namespace

InnovationCheck check_innovations(const std::string& who, const nav::FusionReport& r, const std::string& hint) {
  const nav::InnovationStats& n = r.innovations;
  InnovationCheck c;
  c.summary = who + " GPS innovations: " + std::to_string(n.count) + " fixes";
  if (n.count == 0) {
    c.summary += " tested (none after the first): the sigma cannot be checked";
    return c;
  }
  c.summary += ", mean NIS " + fixed1(n.mean_nis) + " (3 when consistent), " + fixed1(100 * n.within_95, "%.0f") +
               " % within the 95 % gate, " + fixed1(n.scale) + "x the predicted size";
  if (n.count < kMinInnovations) {
    c.summary += ": too few fixes to judge the sigma by";
    return c;
  }
  c.judged = true;
  c.optimistic = n.scale > kMaxInnovationScale || n.within_95 < kMinWithin95;
  c.consistent = !c.optimistic && n.scale >= kMinInnovationScale;
  if (c.consistent) {
    c.summary += ": consistent with the filter's sigma";
  } else if (c.optimistic) {
    c.summary += ": NOT consistent (optimistic sigma)";
    c.warning = who + ": GPS innovations are " + fixed1(n.scale, "%.1f") +
                "x larger than the filter's sigma predicts (median; " + fixed1(100 * (1 - n.within_95), "%.0f") +
                " % of the fixes outside its 95 % gate, 5 % expected; mean NIS " + fixed1(n.mean_nis, "%.1f") +
                ", 3 expected): the reported sigma is optimistic; check the lever arm, the IMU and GPS noise, the "
                "time offsets and the leap seconds in aircraft.yaml" +
                (hint.empty() ? "" : "; " + hint);
  } else {
    c.summary += ": NOT consistent (pessimistic sigma)";
    c.warning = who + ": GPS innovations are " + fixed1(n.scale) +
                "x the size the filter's sigma predicts: the reported sigma is pessimistic (too large); the GPS "
                "noise in aircraft.yaml is likely larger than the receiver's";
  }
  return c;
}

}  // namespace augrig::pipeline
