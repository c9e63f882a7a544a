// Flight nav: what `augrig nav` and `augrig demo` do between logs and the augmenter.
//   aircraft folder  gps.nmea + imu.csv + aircraft.yaml (antenna lever arm, IMU noise, stream time
//                    offsets: docs/NAV_FORMATS.md), as `augrig sim` writes them per aircraft;
//   fusion           nav::fuse() per aircraft (forward filter + RTS smoother);
//   RelativeNav      the receiver in each camera at any camera timestamp (mapped to the nav clock by
//                    a per-camera offset), with its 1-sigma, and the boom tracking the receptacle.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/expected.hpp"
#include "nav/ins.hpp"
#include "nav/logs.hpp"
#include "nav/nmea.hpp"
#include "nav/relative_pose.hpp"
#include "nav/types.hpp"
#include "render/boom_control.hpp"
#include "render/rig.hpp"
#include "sim/scenario.hpp"

namespace augrig::pipeline {

// aircraft.yaml: the per-aircraft part of nav::InsConfig a user states (the rest keeps its defaults).
//   lever_arm_m: [x, y, z]          GPS antenna phase centre in the body frame (FRD), metres
//   moving_baseline_antenna_m: [x, y, z]  the moving-baseline receiver's antenna, when not that one
//   imu_time_offset_ns: 0           added to IMU timestamps to put them on the nav clock
//   gps_time_offset_ns: 0           added to GPS fix times
//   gps_leap_seconds: N             GPS - UTC of gps.nmea (optional: the receiver's PUBX,04, else the
//                                   table of leap seconds by the log's UTC date)
//   imu: {gyro_arw_deg_per_sqrt_h, accel_vrw_mps_per_sqrt_h, gyro_bias_deg_per_h, accel_bias_mg,
//         bias_tau_s}
//   gps: {rtk_fixed_m, rtk_float_m, use_gst}
//   heading: {use: true, offset_deg: 0, sigma_deg: 0.1}
//   imu_clock: {estimate: false, offset_sigma_ms: 50, drift_sigma_ppm: 100,
//               offset_random_walk_us_per_sqrt_s: 0, drift_random_walk_ppm_per_sqrt_s: 0}
//                                   the IMU clock against GPS time as filter states (nav::ImuClockModel)
Expected<nav::InsConfig> load_aircraft_config(const std::string& path);
Expected<nav::InsConfig> parse_aircraft_config(const std::string& yaml_text, const std::string& name);
std::string aircraft_config_to_yaml(const nav::InsConfig& c);

// The nav settings a user would write for a simulated aircraft: the surveyed lever arm and the IMU's
// datasheet noise (the sim's own model; zero noise keeps a small floor so the filter stays regular);
// the IMU clock estimated when the sim's IMU does not stamp on GPS time.
nav::InsConfig ins_config_for(const sim::AircraftSensors& s);

struct AircraftLoadOptions {
  // Without FOLDER/aircraft.yaml: false, an Error naming the file expected; true, the defaults of
  // nav::InsConfig (antenna at the IMU, a tactical IMU, 2 cm RTK), said in AircraftLogs::notes.
  bool allow_default_config = false;
  // GPS - UTC for gps.nmea, overriding aircraft.yaml's gps_leap_seconds (augrig nav --leap-seconds).
  std::optional<int> leap_seconds;
  std::string leap_seconds_source = "--leap-seconds";  // how a message names it
};

struct AircraftLogs {
  std::string folder;
  std::vector<nav::ImuSample> imu;
  std::vector<nav::GpsFix> gps;
  nav::InsConfig config;
  nav::LogIssues imu_issues, gps_issues;
  bool default_config = false;       // no aircraft.yaml: nav::InsConfig's defaults
  nav::LeapSecondsUse leap_seconds;  // as gps.nmea was converted to GPS time
  std::string leap_seconds_source;   // "--leap-seconds", "aircraft.yaml gps_leap_seconds", or "" (from the log)
  std::vector<std::string> notes;     // what was assumed, in plain words
  std::vector<std::string> warnings;  // what looks wrong (a leap-second disagreement, naming file and line)
};
// Reads FOLDER/gps.nmea, FOLDER/imu.csv and FOLDER/aircraft.yaml (required unless
// options.allow_default_config). GPS - UTC: options.leap_seconds, else aircraft.yaml's
// gps_leap_seconds, else what the log says (nav::NmeaOptions::leap_seconds).
Expected<AircraftLogs> load_aircraft_logs(const std::string& folder, const AircraftLoadOptions& options = {});
// Writes the same three files.
Status write_aircraft_logs(const std::string& folder, const std::vector<nav::ImuSample>& imu,
                           const std::vector<nav::GpsFix>& gps, const nav::InsConfig& config);

// A trajectory's per-epoch solutions as nav-solution CSV rows (nav/logs.hpp).
std::vector<nav::NavSolutionRow> nav_solution_rows(const nav::NavTrajectory& t);

// One camera frame's estimate.
struct FramePose {
  TimestampNs t_nav_ns = 0;
  nav::RelativePose body;    // receiver in the tanker body frame
  nav::RelativePose camera;  // receiver in the camera (T_cam_receiver)
  BoomCommand boom;          // track-receptacle articulation
  bool baseline_corrected = false;  // the moving baseline corrected the relative position
  Pose T_ecef_tanker;               // the tanker's body in ECEF at t_nav_ns (the sun's direction)
  nav::CameraPoseRow row(std::uint64_t sequence, int camera_index, TimestampNs t_camera_ns) const;
};

// The frame pose from both aircraft's states at t_nav_ns (camera: an index into rig.cameras).
FramePose frame_pose(const nav::NavState& tanker, const nav::NavState& receiver, TimestampNs t_nav_ns,
                     const Rig& rig, int camera, const BoomDimensions& boom,
                     const Eigen::Vector3d& receptacle_m);

class BaselineNav;  // pipeline/baseline_nav.hpp

class RelativeNav {
 public:
  RelativeNav(nav::NavTrajectory tanker, nav::NavTrajectory receiver, Rig rig, BoomDimensions boom,
              Eigen::Vector3d receptacle_m, std::vector<TimestampNs> camera_offset_ns);
  // t_nav = t_camera - camera_offset_ns[camera]. Error outside either aircraft's nav data.
  Expected<FramePose> at(int camera, TimestampNs t_camera_ns) const;
  // Either aircraft's forward-only filter not yet converged at t_nav_ns (its sigma optimistic there;
  // nav::NavTrajectory::converging). Never with smoothed trajectories.
  bool converging(TimestampNs t_nav_ns) const {
    return tanker_.converging(t_nav_ns) || receiver_.converging(t_nav_ns);
  }
  // When both forward filters had converged (nav clock); nullopt: one never did, or smoothed.
  std::optional<TimestampNs> converged_ns() const;
  // The moving baseline's correction of the relative position, where it has one (null: none).
  void set_baseline(std::shared_ptr<const BaselineNav> baseline) { baseline_ = std::move(baseline); }
  const nav::NavTrajectory& tanker() const { return tanker_; }
  const nav::NavTrajectory& receiver() const { return receiver_; }

 private:
  nav::NavTrajectory tanker_, receiver_;
  Rig rig_;
  BoomDimensions boom_;
  Eigen::Vector3d receptacle_m_;
  std::vector<TimestampNs> camera_offset_ns_;
  std::shared_ptr<const BaselineNav> baseline_;
};

// Position/attitude block of a nav state's covariance, as nav::PoseWithCovariance wants it.
nav::PoseWithCovariance pose_with_covariance(const nav::NavState& s);

// Errors of estimated camera poses against truth, matched by (sequence, camera).
struct PoseErrorStats {
  std::size_t matched = 0;
  double pos_rms_m = 0, pos_max_m = 0;  // |t_est - t_true| of T_cam_receiver
  double att_rms_deg = 0, att_max_deg = 0;
  double within_1sigma = 0;  // share of frames whose position error <= the reported sigma_pos_m
};
PoseErrorStats compare_poses(const std::vector<nav::CameraPoseRow>& estimate,
                             const std::vector<nav::CameraPoseRow>& truth);
std::string describe(const PoseErrorStats& s);

// A one-paragraph summary of a fusion report for the console.
std::string describe(const std::string& who, const nav::FusionReport& r);
// The estimated IMU clock (nav::FusionReport::imu_clock_*) in one line, "" when not estimated:
// "receiver IMU clock - GPS time: +7.012 ms (1-sigma 0.203 ms), drift ... at t_nav_ns ... (smoothed...)".
std::string describe_imu_clock(const std::string& who, const nav::FusionReport& r);

// The GPS innovations of a fusion against what its filter predicted (nav::InnovationStats), in plain
// words: is the sigma the filter reports consistent with them? Consistent: the innovations' size
// (InnovationStats::scale) within [kMinInnovationScale, kMaxInnovationScale] and at least
// kMinWithin95 of them inside the chi-square 95 % gate; judged from kMinInnovations fixes up.
inline constexpr double kMaxInnovationScale = 1.5, kMinInnovationScale = 0.5, kMinWithin95 = 0.8;
inline constexpr std::size_t kMinInnovations = 20;
struct InnovationCheck {
  bool judged = false;      // enough fixes to say
  bool consistent = true;   // innovations as large as predicted (within the bounds above)
  bool optimistic = false;  // larger: the reported sigma is too small
  std::string summary;      // "receiver GPS innovations: 280 fixes, mean NIS 2.75 (3 when consistent), ..."
  std::string warning;      // plain words when not consistent; empty otherwise
};
// `hint`: what to check, appended to an optimistic warning (e.g. that aircraft.yaml was missing).
InnovationCheck check_innovations(const std::string& who, const nav::FusionReport& r, const std::string& hint = "");

}  // namespace augrig::pipeline
