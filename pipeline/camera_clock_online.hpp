// camera_clock_online: each camera's clock against GPS time estimated while `augrig run` runs with
// live nav (issue 35 §4), by the method of `augrig nav --camera-clock` (nav/camera_clock.hpp,
// docs/CLOCK_OFFSETS.md): the camera's frame-to-frame rotations from its images matched to the
// tanker's angular rate from the live nav. Per camera:
//   frames   offered by the pipeline, decimated (min_interval_s apart), copied into a bounded queue
//            and tracked (nav::CameraRotationTracker) on a worker thread; never blocks: with the queue
//            full the frame is skipped and counted. A frame waits until the nav rates cover it.
//   rates    the tanker's gyro increments as the live nav receives them (TankerRates), on GPS time.
//   fit      every refit_every_s of camera time, nav::fit_camera_clock over the last window_s: offset,
//            drift and their honest 1-sigma (fit, jackknife or floor), or "not observable" and why.
//   applied  once the offset's 1-sigma is at most apply_sigma_s; from then on the poses use the
//            estimate (a later confident fit replaces it; a later unconfident one leaves it held).
//            Before, the configured (prior) offset is used, as without this stage.
// Sign convention (nav/camera_clock.hpp): t_camera = t_gps + offset + drift (t_camera - t_ref), so a
// frame stamped t_camera happened at GPS time t_gps = t_camera - offset_at(t_camera).
// "Camera time" is the frame's stamp where the cameras' offsets to GPS time are configured (the
// simulation), else its mid-exposure on the host clock; the offset then holds what host_to_nav()
// leaves (the GPS receiver's output latency).
#pragma once

#include <array>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "core/frame.hpp"
#include "nav/camera_clock.hpp"
#include "nav/types.hpp"
#include "render/rig.hpp"

namespace augrig::pipeline {

// The tanker's angular rate (body FRD, w.r.t. inertial space: the gyro's; the fit's rate bias takes
// the gyro bias and the Earth's rate) on GPS time, as it arrives; thread-safe, bounded to keep_s.
class TankerRates {
 public:
  explicit TankerRates(double keep_s = 200) : keep_ns_(s_to_ns(keep_s)) {}
  // One gyro increment over (t_gps_end_ns - dt, t_gps_end_ns]: its mean rate at the middle.
  void add_increment(TimestampNs t_gps_end_ns, double dt_s, const Eigen::Vector3d& dtheta_rad);
  void add(TimestampNs t_gps_ns, const Eigen::Vector3d& omega_body_radps);
  // Linear between samples; nullopt outside them or across a gap over 50 ms.
  std::optional<Eigen::Vector3d> at(TimestampNs t_gps_ns) const;
  TimestampNs newest_ns() const;  // 0: none
  // A copy of [t0_ns, t1_ns] (plus a sample each side) as a function of its own, for a fit.
  nav::AngularRateFunction snapshot(TimestampNs t0_ns, TimestampNs t1_ns) const;

 private:
  mutable std::mutex mutex_;
  TimestampNs keep_ns_;
  std::deque<std::pair<TimestampNs, Eigen::Vector3d>> samples_;
};

struct CameraClockOnlineOptions {
  double min_interval_s = 0.05;   // frames closer to the last one taken are passed over (every 2nd at 30 fps)
  double refit_every_s = 5;       // camera time between fits
  double window_s = 120;          // a fit uses the last window_s of rotations (drift is followed)
  double apply_sigma_s = 0.5e-3;  // applied once the offset's reported 1-sigma is at most this
  int queue_frames = 8;           // frames waiting for the worker; beyond: skipped and counted
  double rate_wait_s = 1.0;       // a frame waits (wall time) at most this long for rates covering it
  bool synchronous = false;       // track on the caller's thread (tests, offline): nothing skipped
  nav::CameraClockOptions clock;  // tracker and fit (prior_offset_s is set from the prior offset)
};

enum class CameraClockState { kCollecting, kNotObservable, kEstimated, kApplied };
std::string_view to_string(CameraClockState s);  // "collecting", "not observable", "estimated", "applied"

struct CameraClockOnlineStatus {
  int camera = 0;
  std::string name;  // "left", "right"
  CameraClockState state = CameraClockState::kCollecting;
  std::string reason;                               // why not observable (or still collecting)
  double prior_offset_s = 0;                        // used until applied
  std::optional<nav::CameraClockEstimate> latest;   // the latest fit, observable
  std::optional<nav::CameraClockEstimate> applied;  // in use by the poses
  TimestampNs t_applied_camera_ns = 0;              // the newest rotation of the fit applied
  std::uint64_t frames_offered = 0, frames_taken = 0, frames_skipped_busy = 0, frames_tracked = 0;
  std::uint64_t rotations = 0, fits = 0;
  double last_fit_ms = 0;
  // The numbers shown: the applied estimate, else the latest; NaN where none.
  double offset_ms() const;
  double sigma_ms() const;
  double drift_ppm() const;  // NaN where the drift is not observable
  double drift_sigma_ppm() const;
  // "left: +3.712 +- 0.321 ms, drift +1.2 +- 3.0 ppm, applied" / "left: not observable (...)".
  std::string text() const;
  // The same, short enough for the window's status panel, state first: "left  applied  +3.712 +-
  // 0.321 ms, drift -1.2 +- 3.0 ppm", "left  not observable: too little motion; prior +1.200 ms" (the prior
  // in use).
  std::string hud_text() const;
};

// One camera's online estimate.
class CameraClockOnline {
 public:
  // `prior_offset_ns`: the configured offset (camera time minus GPS time), used until applied.
  // `ground` (optional) removes the parallax, as in nav::CameraRotationTracker. `rates` outlives it.
  CameraClockOnline(int camera, std::string name, const CameraModel& model, const Eigen::Matrix3d& R_cam_body,
                    TimestampNs prior_offset_ns, std::shared_ptr<const TankerRates> rates,
                    nav::GroundMotionFunction ground, const CameraClockOnlineOptions& options = {});
  ~CameraClockOnline();  // stops the worker
  CameraClockOnline(const CameraClockOnline&) = delete;
  CameraClockOnline& operator=(const CameraClockOnline&) = delete;

  // A frame of this camera (any time order is refused quietly: older than the last taken). False
  // when passed over (decimation) or skipped (queue full); never blocks (unless synchronous).
  bool offer(TimestampNs t_camera_ns, ConstImageView image);
  // Camera time minus GPS time at t_camera_ns: the applied estimate (drift included), else the prior.
  TimestampNs offset_ns(TimestampNs t_camera_ns) const;
  bool applied() const;
  CameraClockOnlineStatus status() const;
  // State changes since the last call, in words ("camera clock left: applied +3.712 ms ...").
  std::vector<std::string> take_changes();
  // Tests: waits until the queue is empty and the worker idle.
  void wait_idle();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Both cameras of a run, fed by the pipeline (frames) and the live nav (the tanker's rates).
class CameraClocks {
 public:
  // `prior_offset_ns`: each camera's configured offset where frames reach GPS time through it (the
  // simulation); empty: host-timed frames, whose prior is the live nav's host_to_nav() at the first
  // frame. `host_to_nav` maps host time to GPS time (nullopt: not yet known).
  CameraClocks(const Rig& rig, std::vector<TimestampNs> prior_offset_ns,
               std::function<std::optional<TimestampNs>(TimestampNs host_ns)> host_to_nav,
               nav::GroundMotionFunction ground, const CameraClockOnlineOptions& options = {});
  ~CameraClocks();

  std::shared_ptr<TankerRates> rates() const { return rates_; }
  // Each camera's frame; `mid_host_ns`: its mid-exposure on the host clock (0: unknown), for
  // host-timed frames. Never blocks.
  void offer(const StereoFrame& frame, TimestampNs mid_host_left_ns, TimestampNs mid_host_right_ns);
  // The GPS time of camera c's frame: t_camera - the applied offset; nullopt until applied (the
  // caller then maps the frame as without this stage). `t_camera_ns` as in offer(): the stamp, or
  // the host mid-exposure for host-timed frames.
  std::optional<TimestampNs> to_gps(int camera, TimestampNs t_camera_ns) const;
  bool host_timed() const { return host_timed_; }
  std::vector<CameraClockOnlineStatus> status() const;  // per camera (collecting before its first frame)
  std::vector<std::string> take_changes();
  // "camera0_clock_offset_ms", "camera0_clock_sigma_ms", "camera0_clock_drift_ppm",
  // "camera0_clock_state", "camera0_clock_applied", ... for /diagnostics.
  std::vector<std::pair<std::string, std::string>> diagnostics() const;
  // For the recording: a line per camera refitted since the last call ("camera_clock camera=left
  // state=applied offset_ms=... sigma_ms=... drift_ppm=... ...").
  std::vector<std::string> take_record_lines();
  void wait_idle();  // tests

 private:
  CameraClockOnline* camera(int c, TimestampNs mid_host_ns);

  Rig rig_;
  std::vector<TimestampNs> prior_offset_ns_;
  bool host_timed_ = false;
  std::function<std::optional<TimestampNs>(TimestampNs)> host_to_nav_;
  nav::GroundMotionFunction ground_;
  CameraClockOnlineOptions options_;
  std::shared_ptr<TankerRates> rates_;
  mutable std::mutex mutex_;  // the cameras are made at their first frame
  std::array<std::unique_ptr<CameraClockOnline>, 2> cameras_;
  std::array<std::uint64_t, 2> recorded_fits_{};
};

}  // namespace augrig::pipeline
