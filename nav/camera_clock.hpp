// Camera clock against GPS time from the images themselves (docs/CLOCK_OFFSETS.md): the camera's
// rotation between consecutive frames, measured on the distant ground by tracked features
// (goodFeaturesToTrack + pyramidal Lucas-Kanade, undistorted rays, RANSAC over rotation-only fits),
// is matched to the tanker's angular rate from nav (rotated into the camera by the rig extrinsic)
// by least squares over the camera clock's offset (and drift). The information is in the angular
// acceleration (manoeuvres, turbulence); without enough of it the estimate says `observable =
// false` and gives no numbers.
//
// Clock model: t_camera = t_gps + offset_s + drift_ppm 1e-6 (t_camera - reference_camera_ns), so
// a frame stamped t_camera happened at GPS time t_camera - offset_at_s(t_camera): the sign of
// `augrig nav --camera-offset-ns` (t_nav = t_camera - offset).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "core/image.hpp"
#include "render/camera_model.hpp"

namespace augrig::nav {

class NavTrajectory;
struct FrameIndex;

// The tanker's angular rate w.r.t. the ground (Earth), body axes FRD, rad/s, at GPS time t_gps_ns;
// nullopt where it is unknown (outside the nav data). A constant error (gyro bias, the Earth's
// rate) is harmless: the fit estimates a rate bias.
using AngularRateFunction = std::function<std::optional<Eigen::Vector3d>(TimestampNs t_gps_ns)>;

// What removes the ground's parallax from the tracked features (optional): the tanker's attitude,
// its velocity over the ground and its height above the ground at GPS time t_gps_ns.
struct GroundMotion {
  Eigen::Matrix3d R_ned_body = Eigen::Matrix3d::Identity();
  Eigen::Vector3d v_ned_mps = Eigen::Vector3d::Zero();
  double height_m = 0;  // above the ground the camera sees (flat terrain)
};
using GroundMotionFunction = std::function<std::optional<GroundMotion>(TimestampNs t_gps_ns)>;

// One camera's rotation between two of its frames, as the images give it.
struct FrameRotation {
  TimestampNs t0_camera_ns = 0, t1_camera_ns = 0;  // the two frames' stamps
  // The camera's rotation from t0 to t1 as a rotation vector in the camera frame at t0:
  // R_cam0_cam1 = Exp(rotvec_cam_rad), about the integral of the camera's angular rate.
  Eigen::Vector3d rotvec_cam_rad = Eigen::Vector3d::Zero();
  int inliers = 0;         // features that agreed with the rotation
  int features = 0;        // features tracked between the frames (flagged ones excluded)
  double rms_rad = 0;      // the inliers' RMS ray misfit
};

struct CameraClockOptions {
  // ---- features and rotations ----
  int max_features = 300;            // tracked features kept per frame
  double min_distance_px = 12;       // between features (goodFeaturesToTrack, and new ones to old)
  double quality_level = 0.005;      // goodFeaturesToTrack
  int lk_window_px = 21;             // calcOpticalFlowPyrLK window side
  int lk_levels = 3;                 // pyramid levels above the image
  double max_forward_backward_px = 0.5;  // tracks that do not come back within this are dropped
  double inlier_px = 0.5;            // RANSAC (MSAC) threshold, in pixels at the focal length
  int ransac_iterations = 100;
  double nav_gate_px = 0.5;          // floor of the nav gate (see CameraRotationTracker)
  int min_inliers = 12;              // fewer: no rotation for that interval
  double max_interval_s = 0.25;      // longer gaps between frames restart the tracks
  // A track whose misfit keeps one direction (the receiver aircraft, moving with the tanker while
  // the ground turns) is flagged and never used again: its exponentially weighted misfit (this
  // memory per interval) beyond 4 sigma of what noise gives.
  double track_memory = 0.97;
  // ---- the fit ----
  double search_s = 0.1;           // offsets searched: [-search_s, +search_s] about prior_offset_s
  double prior_offset_s = 0;       // centre of the search, and the offset used for parallax
  double coarse_step_s = 0.001;    // coarse search step
  double rate_sample_s = 0.002;    // the angular-rate function is sampled on this grid
  double derivative_step_s = 0.05; // the offset's Jacobian is a difference over +-this (smooths nav noise)
  bool estimate_drift = true;      // also fit drift; reported only where it is observable
  bool estimate_scale = true;      // fit a rate scale (focal-length error, residual contamination)
  // Residual correlation allowed for in the sigma (Newey-West window): slow errors (parallax not
  // quite removed, the ground's rendering or optics) last seconds.
  double hac_lag_s = 2.0;
  double max_offset_sigma_s = 0.002;    // a larger 1-sigma: unobservable
  double max_drift_sigma_ppm = 20;      // a larger 1-sigma: drift not observable, fitted as 0
  double min_explained = 0.5;      // the nav rate must explain this share of the rates' variation
  int min_intervals = 30;
  // ---- the 1-sigma beyond the residuals (docs/CLOCK_OFFSETS.md, "1-sigma") ----
  // Blocks of time for the jackknife and the floor: about block_s long (at most max_blocks), each
  // cut moved to where little information lies, so that a manoeuvre (a 4 s roll-in) stays whole.
  double block_s = 8;
  int max_blocks = 12;
  // Floor: the images' own clock error, this much (1-sigma; one roll-in came out up to 0.5 ms off
  // at 480x360 and at 1280x960), correlated over about block_s; in a block cut by the data's start
  // or end (a one-sided manoeuvre) cut_block_bias_factor times as much.
  double block_bias_s = 0.5e-3;
  double cut_block_bias_factor = 3;
};

struct CameraClockEstimate {
  // False when the motion is too weak to tell (reason says why): offset and drift are then NaN.
  bool observable = false;
  std::string reason;
  TimestampNs reference_camera_ns = 0;  // the offset's epoch (the middle of the data)
  double offset_s = 0, offset_sigma_s = 0;  // camera clock minus GPS time at reference_camera_ns
  bool drift_observable = false;
  double drift_ppm = 0, drift_sigma_ppm = 0;  // NaN unless drift_observable (then fitted as 0)
  double scale = 1;                           // camera rates / nav rates
  Eigen::Vector3d bias_cam_radps = Eigen::Vector3d::Zero();  // camera rates minus nav rates
  double residual_rms_radps = 0;   // per axis, after the fit
  double explained = 0;            // share of the camera rates' variation the nav rate explains
  int intervals_used = 0;          // frame intervals in the fit
  int frames = 0;                  // frames given (estimate_camera_clock only)
  // Coarse search: cost (mean squared residual) at offsets prior + i * coarse_step_s - search_s.
  std::vector<double> coarse_cost;

  // Where offset_sigma_s and drift_sigma_ppm come from: each is the largest of three 1-sigmas (NaN
  // where there is none). The fit's own (residuals or Newey-West) misses the images' error along a
  // manoeuvre's signal; the jackknife over blocks of time (each left out in turn) shows it when the
  // information comes from several manoeuvres; the floor (a bias of block_bias_s per block) stands
  // in where it comes from fewer than three blocks or from one cut by the data's start or end.
  enum class SigmaSource { kFit, kJackknife, kFloor };
  SigmaSource sigma_source = SigmaSource::kFit;  // the offset's
  double offset_sigma_fit_s = 0, offset_sigma_jackknife_s = 0, offset_sigma_floor_s = 0;
  double drift_sigma_fit_ppm = 0, drift_sigma_jackknife_ppm = 0, drift_sigma_floor_ppm = 0;
  int jackknife_blocks = 0;     // blocks of time the data were cut into
  int jackknife_refits = 0;     // refits (each block left out) that were observable
  double effective_blocks = 0;  // 1 / sum(share^2) of the blocks' information: about how many manoeuvres
  bool edge_cut = false;        // a block that counts was cut by the data's start or end

  // Offset at a camera time (drift applied when observable): t_gps = t_camera - offset_at_s(t_camera).
  double offset_at_s(TimestampNs t_camera_ns) const;
  TimestampNs offset_at_ns(TimestampNs t_camera_ns) const { return s_to_ns(offset_at_s(t_camera_ns)); }
};

// Measures one camera's frame-to-frame rotations from its images, fed in time order.
class CameraRotationTracker {
 public:
  // `ground` may be null (parallax then left to the fit's bias). `omega_body` may be null; given, a
  // rotation must lie within what the nav rate allows over prior_offset_s +- search_s (plus
  // nav_gate_px): a receiver filling the view cannot then win the consensus over the ground.
  CameraRotationTracker(const CameraModel& model, const Eigen::Matrix3d& R_cam_body,
                        const CameraClockOptions& options = {}, GroundMotionFunction ground = nullptr,
                        AngularRateFunction omega_body = nullptr);
  ~CameraRotationTracker();
  CameraRotationTracker(const CameraRotationTracker&) = delete;
  CameraRotationTracker& operator=(const CameraRotationTracker&) = delete;

  // The next frame (any of core/image.hpp's formats; Bayer is converted to gray). Stamps must
  // increase. An Error for a wrong image size or format; a frame that gives no rotation is not one.
  Status add_frame(TimestampNs t_camera_ns, ConstImageView image);
  const std::vector<FrameRotation>& rotations() const;
  // The rotations measured since the last call (or the start), moved out: a tracker that runs for
  // hours (pipeline/camera_clock_online.hpp) keeps none itself.
  std::vector<FrameRotation> take_rotations();
  int frames() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Where the offset's 1-sigma came from, in words (for `augrig nav`), e.g. "from the floor for few
// manoeuvres (information from about 1.9 of 5 time blocks, one cut by the data's start or end)".
std::string describe_sigma(const CameraClockEstimate& estimate);

// Fits offset (and drift) to measured rotations: the smaller, cheap-to-test half. After the fit, it
// refits with each block of time left out (CameraClockOptions::block_s) for the jackknife: about
// (blocks + 1) times the cost of one fit.
Expected<CameraClockEstimate> fit_camera_clock(const std::vector<FrameRotation>& rotations,
                                               const Eigen::Matrix3d& R_cam_body,
                                               const AngularRateFunction& omega_body,
                                               const CameraClockOptions& options = {});

// One camera's frame, its image got on demand (from a file, a recording, a renderer).
struct CameraClockFrame {
  TimestampNs t_camera_ns = 0;
  std::function<Expected<Image>()> image;
};

// Both halves: tracks the frames (in time order) and fits. `ground` optional as above.
Expected<CameraClockEstimate> estimate_camera_clock(const std::vector<CameraClockFrame>& frames,
                                                    const CameraModel& model, const Eigen::Matrix3d& R_cam_body,
                                                    const AngularRateFunction& omega_body,
                                                    const CameraClockOptions& options = {},
                                                    const GroundMotionFunction& ground = nullptr);

// One camera's rows of a frame index (nav/logs.hpp, as `augrig sim` writes frames/index.csv), in
// time order, each image read from its file (relative to `folder`, the index's folder) when the
// tracker asks for it; 8-bit gray files are read as the `bayer` mosaic when given. `every`: keep
// every n-th frame (by sequence), to trade precision for time.
std::vector<CameraClockFrame> camera_clock_frames(const FrameIndex& index, int camera, const std::string& folder,
                                                  std::optional<PixelFormat> bayer = std::nullopt, int every = 1);

// From a fused trajectory (nav/ins.hpp), which has no rate query: the rate from the attitude at
// t -+ half_step_s (body w.r.t. ECEF, body axes), and ground motion (NED of the current position,
// height above the ellipsoid less terrain_height_m). The trajectory must outlive the functions.
AngularRateFunction angular_rate_from_trajectory(const NavTrajectory& trajectory, double half_step_s = 0.005);
GroundMotionFunction ground_motion_from_trajectory(const NavTrajectory& trajectory, double terrain_height_m = 0);

}  // namespace augrig::nav
