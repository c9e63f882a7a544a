// Flight nav: what `augrig nav` and `augrig demo` do between logs and the augmenter.
//   aircraft folder  gps.nmea + imu.csv + aircraft.yaml (antenna lever arm, IMU noise, stream time
//                    offsets: docs/NAV_FORMATS.md), as `augrig sim` writes them per aircraft;
//   fusion           nav::fuse() per aircraft (forward filter + RTS smoother);
//   RelativeNav      the receiver in each camera at any camera timestamp (mapped to the nav clock by
//                    a per-camera offset), with its 1-sigma, and the boom tracking the receptacle.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/expected.hpp"
#include "nav/ins.hpp"
#include "nav/logs.hpp"
#include "nav/relative_pose.hpp"
#include "nav/types.hpp"
#include "render/boom_control.hpp"
#include "render/rig.hpp"
#include "sim/scenario.hpp"

namespace augrig::pipeline {

// aircraft.yaml: the per-aircraft part of nav::InsConfig a user states (the rest keeps its defaults).
//   lever_arm_m: [x, y, z]          GPS antenna phase centre in the body frame (FRD), metres
//   imu_time_offset_ns: 0           added to IMU timestamps to put them on the nav clock
//   gps_time_offset_ns: 0           added to GPS fix times
//   imu: {gyro_arw_deg_per_sqrt_h, accel_vrw_mps_per_sqrt_h, gyro_bias_deg_per_h, accel_bias_mg,
//         bias_tau_s}
//   gps: {rtk_fixed_m, rtk_float_m, use_gst}
//   heading: {use: true, offset_deg: 0, sigma_deg: 0.1}
Expected<nav::InsConfig> load_aircraft_config(const std::string& path);
Expected<nav::InsConfig> parse_aircraft_config(const std::string& yaml_text, const std::string& name);
std::string aircraft_config_to_yaml(const nav::InsConfig& c);

// The nav settings a user would write for a simulated aircraft: the surveyed lever arm and the IMU's
// datasheet noise (the sim's own model; zero noise keeps a small floor so the filter stays regular).
nav::InsConfig ins_config_for(const sim::AircraftSensors& s);

struct AircraftLogs {
  std::string folder;
  std::vector<nav::ImuSample> imu;
  std::vector<nav::GpsFix> gps;
  nav::InsConfig config;
  nav::LogIssues imu_issues, gps_issues;
};
// Reads FOLDER/gps.nmea, FOLDER/imu.csv and FOLDER/aircraft.yaml (optional: defaults without it).
Expected<AircraftLogs> load_aircraft_logs(const std::string& folder);
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
  nav::CameraPoseRow row(std::uint64_t sequence, int camera_index, TimestampNs t_camera_ns) const;
};

// The frame pose from both aircraft's states at t_nav_ns (camera: an index into rig.cameras).
FramePose frame_pose(const nav::NavState& tanker, const nav::NavState& receiver, TimestampNs t_nav_ns,
                     const Rig& rig, int camera, const BoomDimensions& boom,
                     const Eigen::Vector3d& receptacle_m);

class RelativeNav {
 public:
  RelativeNav(nav::NavTrajectory tanker, nav::NavTrajectory receiver, Rig rig, BoomDimensions boom,
              Eigen::Vector3d receptacle_m, std::vector<TimestampNs> camera_offset_ns);
  // t_nav = t_camera - camera_offset_ns[camera]. Error outside either aircraft's nav data.
  Expected<FramePose> at(int camera, TimestampNs t_camera_ns) const;
  const nav::NavTrajectory& tanker() const { return tanker_; }
  const nav::NavTrajectory& receiver() const { return receiver_; }

 private:
  nav::NavTrajectory tanker_, receiver_;
  Rig rig_;
  BoomDimensions boom_;
  Eigen::Vector3d receptacle_m_;
  std::vector<TimestampNs> camera_offset_ns_;
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

}  // namespace augrig::pipeline
