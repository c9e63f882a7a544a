// logs: the CSV logs of the nav module, IMU increments and per-epoch navigation solutions.
// Schemas, units and frames: docs/NAV_FORMATS.md.
//
// Both are plain CSV with one header line naming the columns (in any order; required columns must
// be present, unknown ones are an error). Lines starting with '#' are comments; "# key: value"
// comments are kept as metadata, and "# clock: gps" (a core/conventions.hpp ClockDomain name)
// states the clock of t_ns. Writers print every double in its shortest exact text
// (std::to_chars), so a write/read round trip is bit-exact.
//
// Readers fail (Expected error) on what makes a file unusable: a missing or bad header, a row with
// the wrong number of fields, a field that is not a finite number, naming file:line and column.
// Samples that are out of order or repeat their predecessor's time are dropped and counted in
// LogIssues; gaps are counted.
#pragma once

#include <iosfwd>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "nav/types.hpp"

namespace augrig::nav {

// IMU CSV: t_ns,dt_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps[,arrival_ns]
struct ImuLog {
  std::vector<ImuSample> samples;  // strictly increasing t_ns
  LogIssues issues;                // gaps: t_ns - previous t_ns > 1.5 dt_s (at least one sample missing)
  ClockDomain clock = ClockDomain::kGps;        // from "# clock: ...", kGps when not stated
  std::map<std::string, std::string> metadata;  // "# key: value" comments
};

// One navigation solution epoch, column for column as in the CSV:
// t_ns,lat_deg,lon_deg,h_m,vn_mps,ve_mps,vd_mps,yaw_deg,pitch_deg,roll_deg,
// sigma_n_m,sigma_e_m,sigma_d_m,sigma_yaw_deg,sigma_pitch_deg,sigma_roll_deg
// [,imu_clock_offset_ms,imu_clock_drift_ppm,sigma_imu_clock_offset_ms,sigma_imu_clock_drift_ppm]
// Position of the body origin (WGS84, ellipsoidal height), velocity in NED, attitude
// R_ned_body as yaw-pitch-roll (Z-Y'-X'', core/conventions.hpp), 1-sigma errors, and, when the
// fusion estimated it (nav::InsConfig::imu_clock), the IMU clock minus GPS time and its drift with
// 1-sigma. The sigma and clock columns are optional: absent columns or empty fields read as NaN
// (unknown), and NaN is written as an empty field; the clock columns are written only when a row
// has a clock offset.
struct NavSolutionRow {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

  TimestampNs t_ns = 0;
  double lat_deg = 0, lon_deg = 0, h_m = 0;
  double vn_mps = 0, ve_mps = 0, vd_mps = 0;
  double yaw_deg = 0, pitch_deg = 0, roll_deg = 0;
  double sigma_n_m = kNaN, sigma_e_m = kNaN, sigma_d_m = kNaN;
  double sigma_yaw_deg = kNaN, sigma_pitch_deg = kNaN, sigma_roll_deg = kNaN;
  double imu_clock_offset_ms = kNaN, imu_clock_drift_ppm = kNaN;
  double sigma_imu_clock_offset_ms = kNaN, sigma_imu_clock_drift_ppm = kNaN;
};

struct NavSolutionLog {
  std::vector<NavSolutionRow> rows;  // strictly increasing t_ns
  LogIssues issues;                  // gaps: intervals longer than twice the median interval
  ClockDomain clock = ClockDomain::kGps;
  std::map<std::string, std::string> metadata;
};

// Options of both writers.
struct CsvWriteOptions {
  ClockDomain clock = ClockDomain::kGps;        // written as "# clock: <name>"
  std::map<std::string, std::string> metadata;  // more "# key: value" lines (no newlines in them)
};

// `name` names the stream in messages ("imu.csv:12: ...").
Expected<ImuLog> parse_imu_csv(std::istream& in, const std::string& name);
Expected<ImuLog> read_imu_csv(const std::string& path);
// The arrival_ns column is written when any sample has arrival_ns != 0. Non-finite values are an
// error (the reader would reject them).
Status write_imu_csv(std::ostream& out, const std::vector<ImuSample>& samples,
                     const CsvWriteOptions& options = {});
Status write_imu_csv(const std::string& path, const std::vector<ImuSample>& samples,
                     const CsvWriteOptions& options = {});

Expected<NavSolutionLog> parse_nav_solution_csv(std::istream& in, const std::string& name);
Expected<NavSolutionLog> read_nav_solution_csv(const std::string& path);
Status write_nav_solution_csv(std::ostream& out, const std::vector<NavSolutionRow>& rows,
                              const CsvWriteOptions& options = {});
Status write_nav_solution_csv(const std::string& path, const std::vector<NavSolutionRow>& rows,
                              const CsvWriteOptions& options = {});

// Frame index CSV: one row per delivered camera frame, in delivery order.
//   sequence,camera,t_ns,file
// t_ns is the frame's mid-exposure timestamp as the camera stamped it ("# clock: device" usually: the
// camera's own clock; nav maps it with a configured per-camera offset). `file` is relative to the
// index's folder (no commas). Frames the camera dropped have no row.
struct FrameIndexRow {
  std::uint64_t sequence = 0;  // the camera's frame counter (stereo frames share it)
  int camera = 0;              // index into the rig's cameras
  TimestampNs t_ns = 0;
  std::string file;
};
struct FrameIndex {
  std::vector<FrameIndexRow> rows;
  ClockDomain clock = ClockDomain::kDevice;
  std::map<std::string, std::string> metadata;
};
Expected<FrameIndex> parse_frame_index_csv(std::istream& in, const std::string& name);
Expected<FrameIndex> read_frame_index_csv(const std::string& path);
Status write_frame_index_csv(const std::string& path, const FrameIndex& index);

// Camera pose CSV: the receiver in one camera at one frame (truth written by `augrig sim`, estimates
// by `augrig nav`):
//   sequence,camera,t_ns,t_nav_ns,x_m,y_m,z_m,qw,qx,qy,qz[,sigma_pos_m,sigma_att_deg,
//   boom_elevation_deg,boom_azimuth_deg,boom_extension_m]
// t_ns is the frame's timestamp as in the frame index, t_nav_ns the same instant in GPS time.
// (x, y, z) and q are T_cam_receiver (OpenCV camera frame; receiver body FRD): the receiver body
// origin in the camera and R_cam_receiver as a unit quaternion. Optional columns read as NaN when
// absent; NaN is written as an empty field.
struct CameraPoseRow {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  std::uint64_t sequence = 0;
  int camera = 0;
  TimestampNs t_ns = 0;
  TimestampNs t_nav_ns = 0;
  double x_m = 0, y_m = 0, z_m = 0;
  double qw = 1, qx = 0, qy = 0, qz = 0;
  double sigma_pos_m = kNaN, sigma_att_deg = kNaN;
  double boom_elevation_deg = kNaN, boom_azimuth_deg = kNaN, boom_extension_m = kNaN;
};
struct CameraPoseLog {
  std::vector<CameraPoseRow> rows;
  std::map<std::string, std::string> metadata;
};
Expected<CameraPoseLog> parse_camera_pose_csv(std::istream& in, const std::string& name);
Expected<CameraPoseLog> read_camera_pose_csv(const std::string& path);
Status write_camera_pose_csv(const std::string& path, const std::vector<CameraPoseRow>& rows,
                             const CsvWriteOptions& options = {});

}  // namespace augrig::nav
