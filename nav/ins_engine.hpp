// ins_engine: the error-state Kalman filter behind nav::fuse() (batch, nav/ins.hpp) and
// nav::LiveFusion (real time, nav/live_fusion.hpp). Internal to nav/: the public interfaces are
// those two. One filter, two drivers:
//   batch      run(): all IMU and fixes up front, forward filter to the end, RTS smoother;
//   real time  append_imu() / append_fix() as data arrive, try_initialise(), advance_to(t) over
//              what is certain, at(t) for any recent time (mechanized from the last epoch before
//              it, covariance propagated), trim_before(t) to keep memory bounded.
#pragma once

#include <deque>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nav/ins.hpp"

namespace augrig::nav {

class FusionEngine {
 public:
  explicit FusionEngine(const InsConfig& cfg) : cfg_(cfg), clock_(cfg.imu_clock.estimate) {}
  Expected<NavTrajectory> run(std::span<const ImuSample> imu, std::span<const GpsFix> fixes, bool smooth);

  // ---- real time (no smoother) ----
  // One more IMU sample, strictly after the last (an Error otherwise, nothing changed).
  Status append_imu(const ImuSample& s);
  // One more GPS fix, its time of validity after the last fix's (an Error otherwise); invalid
  // fixes (no fix, dead reckoning) are only counted. `quality` of the newest fix is kept either way.
  Status append_fix(const GpsFix& f);
  bool initialised() const { return initialised_; }
  // Initialises from the first fix when the data allow it (IMU covering 1 s after it, and a second
  // fix or 2 s of IMU); fixes before the first IMU sample are discarded. True once initialised.
  bool try_initialise();
  // Runs the filter up to t_ns (clamped to the IMU data), processing the fixes up to it in order.
  void advance_to(TimestampNs t_ns);
  // The state at t_ns from the last epoch at or before it; past the IMU data the last increment's
  // rates are held for at most max_extrapolation_ns. The covariance is propagated from the epoch.
  // With the IMU clock estimated t_ns is GPS time (as in NavTrajectory::at()); every other time
  // here is the IMU's clock.
  Expected<NavState> at(TimestampNs t_ns, TimestampNs max_extrapolation_ns) const;
  // Forgets epochs and IMU increments that no query at or after t_ns needs (before initialisation:
  // the IMU increments and fixes before t_ns).
  void trim_before(TimestampNs t_ns);

  TimestampNs filter_time_ns() const { return mech_.state().t_ns; }
  TimestampNs imu_end_ns() const { return traj_.imu_.empty() ? 0 : traj_.imu_.back().t1_ns; }
  // The newest valid fix's time of validity on the IMU clock (by the current clock estimate).
  TimestampNs last_fix_ns() const { return fixes_.empty() ? 0 : fix_time(fixes_.back(), false); }
  TimestampNs last_used_fix_ns() const { return t_last_used_; }
  const FusionReport& report() const { return traj_.report_; }
  NavState current() const;
  std::size_t buffered_imu() const { return traj_.imu_.size(); }
  std::size_t buffered_epochs() const { return traj_.epochs_.size(); }

 private:
  using Increment = NavTrajectory::Increment;

  struct Fix {
    TimestampNs t_ns = 0;  // time of validity on the nav clock
    std::size_t index = 0;
    Eigen::Vector3d p_ecef_m;  // antenna
    Eigen::Matrix3d R_en;      // NED at the antenna
    Eigen::Vector3d sigma_ned_m;
    std::optional<double> heading_rad;
    std::optional<Eigen::Vector2d> v_ne_mps;  // from speed over ground and course
  };

  // Sample s as an increment over (t0, t1] after `prev` (nullptr: the first; then its dt_s, else the
  // spacing to next_t_ns, gives t0); `i` names it in errors. Lost samples are bridged (counted in gaps).
  static Expected<Increment> make_increment(const ImuSample& s, std::size_t i, const InsConfig& cfg,
                                            const Increment* prev, TimestampNs prev_t_ns,
                                            TimestampNs next_t_ns, std::size_t& gaps);
  Status prepare_imu(std::span<const ImuSample> imu);
  Status prepare_fixes(std::span<const GpsFix> fixes);
  // The filter's view of a valid fix (nullopt, counted, when invalid).
  std::optional<Fix> make_fix(const GpsFix& f, std::size_t index);
  Status initialise();
  void forward();
  // The forward filter from its current time to t_end_ns: epochs at fixes and at least every
  // max_epoch_interval_s. batch: a last partial epoch at t_end_ns, and what the RTS smoother needs;
  // otherwise whole epochs only.
  void filter_to(TimestampNs t_end_ns, bool batch);
  void note_fix_gap(TimestampNs t_ns);
  void note_innovation(TimestampNs t_ns, double nis, bool used, bool gated);
  void note_convergence();
  // FusionReport's IMU clock figures from epoch k (with the clock estimated).
  void note_clock(std::size_t k);
  // When the filter applies fix f: its time of validity on the IMU clock by the current estimate of
  // the clock; with `clamp`, at least 1 ns after the filter's time (an estimate that moved back past
  // it; the update then predicts over the difference).
  TimestampNs fix_time(const Fix& f, bool clamp) const;
  void smooth();
  void propagate_covariance();
  void update_at_fix(const Fix& fix);
  // One update; Hc: the measurement's sensitivity to the clock states (used only when estimated).
  template <int M>
  bool kalman_update(const Eigen::Matrix<double, M, 1>& y, const Eigen::Matrix<double, M, 15>& H,
                     const Eigen::Matrix<double, M, M>& R, double gate, bool force, double* nis = nullptr,
                     const Eigen::Matrix<double, M, 2>* Hc = nullptr);
  void store_epoch();

  const InsConfig& cfg_;
  const bool clock_;  // the IMU clock states are estimated
  NavTrajectory traj_;
  std::vector<Fix> fixes_;
  std::size_t first_fix_ = 0;  // index into fixes_ of the initialisation fix
  std::size_t next_fix_ = 0;   // the next fix the forward filter will process
  bool initialised_ = false;
  std::size_t imu_seen_ = 0, fixes_seen_ = 0;  // real time: samples and fixes appended so far
  TimestampNs t_last_used_ = 0;                // the last fix used (the initialisation fix first)
  TimestampNs t_epoch_ = 0;                    // time of the last epoch

  Strapdown mech_;
  std::size_t imu_index_ = 0;
  Matrix15d P_ = Matrix15d::Zero();
  ImuClockCovariance Pc_;  // the clock states' covariance blocks (clock_)
  Matrix15d Phi_epoch_ = Matrix15d::Identity();
  Eigen::Matrix<double, 15, 2> Phi_xc_epoch_ = Eigen::Matrix<double, 15, 2>::Zero();  // its clock coupling
  // Accumulated over the current covariance step.
  Eigen::Matrix3d sum_R_dt_ = Eigen::Matrix3d::Zero();
  Eigen::Vector3d sum_dv_e_ = Eigen::Vector3d::Zero();
  double step_dt_ = 0;
  int rejection_streak_ = 0;
  bool keep_innovations_ = false;  // batch: every GPS position innovation's NIS kept in the trajectory
  // Until converged: the attitude 1-sigmas (yaw, pitch, roll) of the epochs of the last window.
  std::deque<std::pair<TimestampNs, Eigen::Vector3d>> attitude_sigmas_;

  // Smoother inputs, per epoch k: the predicted state and covariance at k and the transition k-1 -> k.
  std::vector<InertialState> x_pred_;
  std::vector<Matrix15d> P_pred_;
  std::vector<ImuClockCovariance> Pc_pred_;  // clock_ only
  std::vector<Matrix15d> Phi_;
  std::vector<Eigen::Matrix<double, 15, 2>> Phi_xc_;  // clock_ only
};

}  // namespace augrig::nav
