// ins: loosely coupled GPS/INS fusion for one aircraft, offline, with Rauch-Tung-Striebel smoothing.
// docs/NAV_FUSION.md derives the equations; this header states what goes in and what comes out.
//
//   Strapdown     ECEF strapdown mechanization of IMU increments (coning and sculling corrected,
//                 Earth rotation, normal gravity incl. centrifugal, Coriolis). Exact on the ellipsoid.
//   fuse()        15-state error-state Kalman filter (position, velocity, attitude error in ECEF,
//                 gyro and accelerometer biases) driven by the strapdown, updated by GPS positions at
//                 their time of validity (lever arm, chi-square gating), HDT heading and optionally
//                 ground speed/course; then an RTS smoother over the filter's epochs. Optionally two
//                 more states: the IMU clock's offset from GPS time and its drift (InsConfig::imu_clock).
//   NavTrajectory the result: the state at any time inside the data (a camera frame's mid-exposure
//                 time), per-epoch solutions and a report of what was used and rejected.
//
// Frames and conventions: core/conventions.hpp. The error state is
//   dx = [dp(0..2), dv(3..5), dtheta(6..8), dbg(9..11), dba(12..14)], all ECEF except the biases
//   (body FRD), with truth = estimate (+) dx:  p = p^ + dp,  v = v^ + dv,  R_ecef_body =
//   Exp(dtheta) R^_ecef_body,  b = b^ + db. With InsConfig::imu_clock.estimate, two clock error states
//   dc = [offset (s), drift (s/s)] follow (c = c^ + dc); their covariance is kept apart from the
//   15x15 P (ImuClockCovariance), so that a filter without them costs and computes what it did.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "core/pose.hpp"
#include "nav/geodesy.hpp"
#include "nav/types.hpp"

namespace augrig::nav {

using Vector15d = Eigen::Matrix<double, 15, 1>;
using Matrix15d = Eigen::Matrix<double, 15, 15>;

// Offsets of the error-state blocks.
inline constexpr int kErrPos = 0, kErrVel = 3, kErrAtt = 6, kErrGyroBias = 9, kErrAccelBias = 12;

// The nominal (whole-value) inertial state.
struct InertialState {
  TimestampNs t_ns = 0;
  Eigen::Vector3d p_ecef_m = Eigen::Vector3d::Zero();               // body origin (= IMU)
  Eigen::Vector3d v_ecef_mps = Eigen::Vector3d::Zero();             // w.r.t. the Earth, in ECEF axes
  Eigen::Quaterniond q_ecef_body = Eigen::Quaterniond::Identity();  // R_ecef_body
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();        // subtracted from the gyro output
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();  // subtracted from the accelerometer output
  // The IMU clock minus GPS time at t_ns and its rate (InsConfig::imu_clock; 0 when not estimated):
  // an instant at GPS time g is at g + imu_clock_offset_s on the IMU's clock. The strapdown carries
  // the offset forward with the drift.
  double imu_clock_offset_s = 0;
  double imu_clock_drift_s_per_s = 0;

  Pose T_ecef_body() const { return {q_ecef_body, p_ecef_m}; }
};

// The covariance of the two IMU clock error states [offset (s), drift (s/s)] with the 15 inertial
// ones (P_xc) and between themselves (P_cc); all zero when the clock is not estimated.
struct ImuClockCovariance {
  Eigen::Matrix<double, 15, 2> P_xc = Eigen::Matrix<double, 15, 2>::Zero();
  Eigen::Matrix2d P_cc = Eigen::Matrix2d::Zero();
};

// The state with its error covariance (15x15, layout above; the clock states' in `clock`).
struct NavState : InertialState {
  Matrix15d P = Matrix15d::Zero();
  ImuClockCovariance clock;
};

// x (+) dx and a (-) b (the error that takes b to a), in the error-state convention above.
InertialState boxplus(const InertialState& x, const Vector15d& dx);
Vector15d boxminus(const InertialState& a, const InertialState& b);

// Strapdown mechanization in ECEF. One step consumes one IMU increment (or a piece of one):
//   attitude  R(t+dt) = Exp(-w_ie dt) R(t) Exp(a + a_prev x a / 12)          (coning)
//   velocity  v(t+dt) = v + (I - w_ie x dt/2) R(t) (u + a x u / 2 + sculling)
//                         + (g(p_mid) - 2 w_ie x v_mid) dt
//   position  p(t+dt) = p + (v(t) + v(t+dt)) dt / 2
// with a, u the bias-corrected delta-angle and delta-velocity. Gravity is the normal field
// (nav/geodesy.hpp), linearised about a reference point refreshed every 200 m.
// The strapdown's memory of the previous (bias-corrected) increment, for the coning and sculling
// corrections.
struct StrapdownHistory {
  Eigen::Vector3d dtheta_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d dv_mps = Eigen::Vector3d::Zero();
  double dt_s = 0;  // 0: none yet
};

class Strapdown {
 public:
  using History = StrapdownHistory;

  Strapdown() = default;
  explicit Strapdown(const InertialState& x, const History& history = {}) { reset(x, history); }
  void reset(const InertialState& x, const History& history = {});

  // Advances to t_end_ns > state().t_ns with the raw increments measured over that interval (the
  // state's biases are removed here). Times are the IMU's clock; with an IMU clock drift d in the
  // state the step lasts (t_end - t)(1 - d) of GPS time, over which it integrates (and it carries
  // the clock offset forward by d (t_end - t)).
  void step(const Eigen::Vector3d& dtheta_rad, const Eigen::Vector3d& dv_mps, TimestampNs t_end_ns);

  const InertialState& state() const { return x_; }
  InertialState& state() { return x_; }
  const History& history() const { return history_; }
  // Of the last step, for the error-state transition: R_ecef_body at its start and the specific-force
  // velocity increment in ECEF.
  const Eigen::Matrix3d& last_R_ecef_body() const { return last_R_; }
  const Eigen::Vector3d& last_dv_ecef() const { return last_dv_ecef_; }

 private:
  void refresh_gravity(const Eigen::Vector3d& p_ecef_m);

  InertialState x_;
  History history_;
  Eigen::Matrix3d last_R_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d last_dv_ecef_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d p_ref_ = Eigen::Vector3d::Zero(), g_ref_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d G_ref_ = Eigen::Matrix3d::Zero();
  bool have_ref_ = false;
};

// Gravity gradient d(gravity_ecef)/dp (spherical term plus centrifugal), 1/s^2.
Eigen::Matrix3d gravity_gradient_ecef(const Eigen::Vector3d& p_ecef_m);

// A sensor bias: first-order Gauss-Markov with correlation time tau_s (sigma is its steady-state and
// initial 1-sigma), or, when tau_s <= 0, a random walk of density random_walk (units/sqrt(s)) with
// initial 1-sigma sigma.
struct BiasModel {
  double sigma = 0;
  double tau_s = 3600;
  double random_walk = 0;
};

// Defaults: a tactical-grade IMU (0.15 deg/sqrt(h), 3 deg/h, 0.05 m/s/sqrt(h), 2 mg).
struct ImuNoiseModel {
  double gyro_arw_rad_psqrts = deg_to_rad(0.15) / 60.0;  // angle random walk
  double accel_vrw_mps_psqrts = 0.05 / 60.0;             // velocity random walk
  BiasModel gyro_bias{deg_to_rad(3.0) / 3600.0, 3600.0, 0.0};
  BiasModel accel_bias{2e-3 * 9.80665, 3600.0, 0.0};
};

// GPS position noise, 1-sigma. GST sigmas are used when present; otherwise the horizontal sigma of
// the fix quality, times vertical_factor for the vertical, times hdop when scale_by_hdop. Never
// below floor_m.
struct GpsNoiseModel {
  double rtk_fixed_m = 0.02;
  double rtk_float_m = 0.2;
  double dgps_m = 0.5;  // also PPS
  double single_m = 2.5;
  double vertical_factor = 1.7;
  double floor_m = 0.005;
  bool use_gst = true;
  bool scale_by_hdop = false;
};

// The IMU clock against GPS time (both after InsConfig's time offsets), estimated online as two more
// error states: offset c (IMU clock - GPS time, s; prior 0) and its drift (s/s), with the initial
// 1-sigmas below and optional random walks (docs/NAV_FUSION.md, "IMU clock"). A fix valid at GPS
// time g is then applied at g + c on the IMU's clock, and every time the trajectory reports or is
// asked for (NavTrajectory::at(), epochs(), begin_ns()) is GPS time: the smoothed (forward only:
// filtered) offset is applied. Off: c = 0 and the filter is the 15-state one.
struct ImuClockModel {
  bool estimate = false;
  double offset_sigma_s = 0.05;
  double drift_sigma = 100e-6;             // s/s (100 ppm)
  double offset_random_walk_s_psqrts = 0;  // white frequency noise, s/sqrt(s)
  double drift_random_walk_psqrts = 0;     // drift random walk, (s/s)/sqrt(s)
};

struct InsConfig {
  // Added to each stream's timestamps to put it on the nav clock. A fix is processed at
  // t_ns + gps_time_offset_ns (its time of validity on the IMU's clock), not at its arrival.
  TimestampNs imu_time_offset_ns = 0;
  TimestampNs gps_time_offset_ns = 0;
  // The IMU clock against GPS time, estimated online when imu_clock.estimate (ImuClockModel).
  ImuClockModel imu_clock;
  // GPS - UTC of the aircraft's NMEA log when stated (aircraft.yaml gps_leap_seconds); unset: the
  // receiver's own report or the table by date (nav/nmea.hpp). For whoever reads the log into fixes
  // (pipeline::load_aircraft_logs); the filter itself never uses it.
  std::optional<int> gps_leap_seconds;

  Eigen::Vector3d lever_arm_body_m = Eigen::Vector3d::Zero();  // GPS antenna phase centre, body FRD
  // The moving-baseline RTK receiver's antenna when it is not the GPS antenna above (for whoever
  // fuses the baseline, pipeline/baseline_nav.hpp; the filter itself never uses it).
  std::optional<Eigen::Vector3d> baseline_antenna_body_m;
  Eigen::Vector3d baseline_antenna() const { return baseline_antenna_body_m.value_or(lever_arm_body_m); }
  ImuNoiseModel imu;
  GpsNoiseModel gps;
  double gate_chi2 = 16.27;  // position innovation gate, chi-square with 3 dof (p = 0.001)
  // After this many consecutive rejected fixes the next one is accepted unconditionally (counted
  // as forced), so that a filter that has drifted off cannot lock itself out.
  int max_consecutive_rejections = 50;
  // Gating starts once the filter has levelled itself: roll/pitch 1-sigma below this.
  double gate_tilt_sigma_rad = deg_to_rad(1.0);

  // HDT: heading of the dual-antenna baseline = yaw of the body x axis + heading_offset_rad.
  bool use_heading = true;
  double heading_offset_rad = 0;
  double heading_sigma_rad = deg_to_rad(0.1);
  double heading_gate_chi2 = 10.83;  // 1 dof, p = 0.001

  // RMC/VTG speed over ground and course as a horizontal velocity measurement of the antenna.
  bool use_ground_velocity = false;
  double ground_velocity_sigma_mps = 0.1;
  double min_ground_speed_mps = 5.0;         // below this the course is meaningless
  double ground_velocity_gate_chi2 = 13.82;  // 2 dof, p = 0.001

  // The covariance is propagated in steps of at most covariance_step_s (the strapdown runs at every
  // IMU sample); an epoch (a stored smoother node) is made at every fix and at least every
  // max_epoch_interval_s.
  double covariance_step_s = 0.05;
  double max_epoch_interval_s = 0.1;

  // Initialisation (see docs/NAV_FUSION.md): 1-sigma of the initial attitude and velocity. The
  // velocity from two fixes gets the fixes' noise plus init_velocity_sigma_mps for the manoeuvre
  // between them.
  double init_velocity_sigma_mps = 0.5;
  double init_tilt_sigma_rad = deg_to_rad(3.0);              // in motion (plus 15 % of the initial roll)
  double init_level_sigma_rad = deg_to_rad(0.5);             // roll/pitch from accelerometer levelling
  double init_yaw_from_course_sigma_rad = deg_to_rad(10.0);  // course instead of heading (crab)
  double init_yaw_unknown_sigma_rad = deg_to_rad(30.0);      // neither HDT nor motion
  double stationary_speed_mps = 1.0;                         // below: level from the accelerometers
  double airborne_speed_mps = 40.0;                          // above: roll from the coordinated-turn relation

  double outage_factor = 3.0;  // a gap between used fixes longer than this x nominal period is an outage

  // Convergence (docs/NAV_FUSION.md, "Consistency"): the forward filter counts as converged at its
  // first epoch, at least convergence_window_s after its start, over whose last convergence_window_s
  // none of its attitude 1-sigmas (yaw, pitch, roll) fell by more than convergence_sigma_drop (a
  // fraction). Until then it is still learning its attitude from the manoeuvres, and its sigma
  // (forward only, as in real time) was measured optimistic against the simulator's truth.
  double convergence_window_s = 2.0;
  double convergence_sigma_drop = 0.25;
};

// One GPS position fix as the forward filter tested it against its prediction (docs/NAV_FUSION.md,
// "Consistency"): the normalised innovation squared NIS = y^T S^-1 y, S = H P H^T + R. When the
// filter's covariance and noise model are right it is chi-square distributed with 3 degrees of
// freedom: mean 3, median 2.366, 95 % of fixes below 7.815.
struct FixInnovation {
  TimestampNs t_ns = 0;  // the fix's time of validity on the nav clock
  double nis = 0;
  bool used = false;   // passed the gate (or was accepted unconditionally)
  bool gated = false;  // the gate applied: the filter had levelled itself (gate_tilt_sigma_rad)
};

inline constexpr double kNisMedian3Dof = 2.3660;  // median of chi-square with 3 dof
inline constexpr double kNis95_3Dof = 7.8147;     // its 95 % quantile

// The GPS innovations of a run summed up: how their size compares with what the filter predicts.
struct InnovationStats {
  std::size_t count = 0;
  double mean_nis = 0;     // 3 when consistent (sensitive to single outliers)
  double median_nis = 0;   // 2.366 when consistent
  double within_95 = 0;    // share with NIS <= 7.815: 0.95 when consistent
  // How many times larger the innovations are than the filter predicts, from the median (robust to
  // outliers): sqrt(median / 2.366). 1 when consistent; > 1: the filter's sigma is optimistic.
  double scale = 0;
};
InnovationStats innovation_stats(std::span<const FixInnovation> innovations);

struct FusionReport {
  std::size_t imu_samples = 0;
  std::size_t imu_gaps = 0;  // intervals longer than 1.5x the sample's dt_s (bridged with its rate)
  std::size_t fixes = 0;     // all fixes passed in
  std::size_t fixes_used = 0;
  std::size_t fixes_rejected = 0;  // failed the innovation gate
  std::size_t fixes_forced = 0;    // accepted after max_consecutive_rejections
  std::size_t fixes_invalid = 0;   // quality invalid or dead reckoning
  std::size_t fixes_outside = 0;   // before the initialisation fix or after the IMU data
  std::size_t heading_updates = 0;
  std::size_t heading_rejected = 0;
  std::size_t velocity_updates = 0;
  std::size_t velocity_rejected = 0;
  std::size_t outages = 0;
  double longest_fix_gap_s = 0;     // between used fixes
  double nominal_fix_period_s = 0;  // median spacing of the valid fixes
  std::size_t epochs = 0;
  bool smoothed = false;
  double forward_s = 0, smoother_s = 0;  // wall time
  std::string init_summary;              // how the first state was obtained
  // Every GPS position fix tested after the initialisation fix (used or rejected), summed up
  // (batch only: nav::fuse()).
  InnovationStats innovations;
  // When the forward filter's attitude sigmas settled (InsConfig::convergence_window_s); not
  // converged: still settling at the end of the data.
  bool converged = false;
  TimestampNs converged_ns = 0;  // nav clock
  // The IMU clock (InsConfig::imu_clock.estimate): IMU clock minus GPS time at imu_clock_t_ns (GPS
  // time: the first epoch when smoothed, the filter's latest epoch when forward only or live) and its
  // drift, each with its 1-sigma.
  bool imu_clock_estimated = false;
  TimestampNs imu_clock_t_ns = 0;
  double imu_clock_offset_s = 0, imu_clock_offset_sigma_s = 0;
  double imu_clock_drift_s_per_s = 0, imu_clock_drift_sigma = 0;
};

// One epoch as a CSV-ready solution: geodetic position of the body origin, NED velocity, Euler
// angles, and 1-sigma values (position and velocity NED, attitude in yaw/pitch/roll).
struct NavSolution {
  TimestampNs t_ns = 0;
  Geodetic position;
  Eigen::Vector3d v_ned_mps = Eigen::Vector3d::Zero();
  YawPitchRoll attitude;
  Eigen::Vector3d sigma_pos_ned_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d sigma_vel_ned_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d sigma_ypr_rad = Eigen::Vector3d::Zero();
  // IMU clock minus GPS time and its drift with 1-sigma; NaN when the clock is not estimated.
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double imu_clock_offset_s = kNaN, imu_clock_drift_s_per_s = kNaN;
  double sigma_imu_clock_offset_s = kNaN, sigma_imu_clock_drift = kNaN;
};
// nav/logs.hpp writes these as a nav solution CSV (NavSolutionRow).
NavSolution to_solution(const NavState& s);

class NavTrajectory {
 public:
  // The state at t_ns (nav clock), e.g. a camera frame's mid-exposure time: the (smoothed) state of
  // the last epoch at or before t_ns mechanized forward over the stored IMU increments to exactly
  // t_ns. P is interpolated linearly between the neighbouring epochs. Error outside
  // [begin_ns(), end_ns()]. With the IMU clock estimated, t_ns (and every time below) is GPS time:
  // the epoch's estimated IMU clock offset maps it to the IMU's clock.
  Expected<NavState> at(TimestampNs t_ns) const;
  TimestampNs begin_ns() const { return epochs_.empty() ? 0 : epochs_.front().t_gps_ns; }
  TimestampNs end_ns() const;
  const FusionReport& report() const { return report_; }
  // A forward-only trajectory before its filter converged (FusionReport::converged_ns): its sigma
  // there is optimistic. Never for a smoothed one (the smoother's sigma holds from the start).
  bool converging(TimestampNs t_ns) const {
    return !report_.smoothed && (!report_.converged || t_ns < report_.converged_ns);
  }
  // The states at the filter's epochs (smoothed when smoothing ran).
  std::vector<NavState> epochs() const;
  std::vector<NavSolution> solutions() const;
  std::size_t epoch_count() const { return epochs_.size(); }
  // The forward filter's GPS position innovations, one per fix tested, in time order (nav::fuse()
  // only; a real-time filter keeps none).
  const std::vector<FixInnovation>& innovations() const { return innovations_; }

 private:
  friend class FusionEngine;

  // One IMU increment over (t0_ns, t1_ns], intervals contiguous.
  struct Increment {
    TimestampNs t0_ns = 0, t1_ns = 0;
    Eigen::Vector3d dtheta_rad, dv_mps;
  };
  struct Epoch {
    InertialState x;             // posterior (smoothed after smoothing)
    Strapdown::History history;  // strapdown memory at t
    std::size_t imu_index = 0;   // the increment holding the IMU data just after t
    // x.t_ns in GPS time: less the estimated IMU clock offset (kept increasing: a forward filter's
    // offset may jump at a fix by more than the time to the epoch before); x.t_ns without the clock.
    TimestampNs t_gps_ns = 0;
  };

  // Mechanizes from the current strapdown time to t_end_ns, starting inside increment `index`.
  // Calls on_step(dt_s) after every strapdown step.
  template <typename OnStep>
  static void advance(const std::vector<Increment>& imu, Strapdown& mech, std::size_t& index,
                      TimestampNs t_end_ns, OnStep&& on_step);
  // A state's time (IMU clock) in GPS time, and GPS time t_ns on the IMU clock by the estimate of
  // state x (identities when the clock is not estimated: its offset and drift stay 0).
  static TimestampNs gps_time(const InertialState& x);
  static TimestampNs imu_time(const InertialState& x, TimestampNs t_ns);
  // GPS time t_ns (at or after epoch e) on the IMU clock, from the epoch on at its clock's rate.
  static TimestampNs query_time(const Epoch& e, TimestampNs t_ns);
  // Sets epochs_[k].t_gps_ns from its state (and epoch k - 1's).
  void set_gps_time(std::size_t k);
  // The last epoch at or before GPS time t_ns (epochs_ non-empty, t_ns >= begin_ns()).
  std::size_t epoch_before(TimestampNs t_ns) const;

  std::vector<Increment> imu_;
  std::vector<Epoch> epochs_;
  std::vector<Matrix15d> P_;                 // per epoch
  std::vector<ImuClockCovariance> clock_P_;  // per epoch, with the IMU clock estimated; else empty
  std::vector<FixInnovation> innovations_;
  FusionReport report_;
  InsConfig config_;  // a forward-only trajectory's at() propagates the covariance with it
};

// Fuses one aircraft's IMU and GPS logs. Both must be in strictly increasing time order (an Error
// names the first offending index); at least one valid fix must lie inside the IMU data. With
// smooth, runs the RTS smoother after the forward filter.
Expected<NavTrajectory> fuse(std::span<const ImuSample> imu, std::span<const GpsFix> fixes,
                             const InsConfig& config, bool smooth = true);

}  // namespace augrig::nav
