// baseline_fusion: the moving-baseline RTK vector (UBX NAV-RELPOSNED: the receiver's GPS antenna
// relative to the tanker's, NED at the tanker's antenna) fused, as a relative measurement, with the
// same vector as the two aircraft's GPS/INS solutions give it. Their difference is the error of the
// INS baseline, e(t) = truth - ins; it is what ties the two solutions together, and it is what a
// joint filter's relative states would estimate. Here it is estimated on its own, by a Kalman
// filter and RTS smoother over the measurement epochs, which is equivalent as long as the two
// solutions' errors are independent of the baseline's:
//   model        e is a second-order (critically damped) Gauss-Markov process, state [e, de/dt],
//                with the stationary covariance the solutions report, S = s^2 Sigma(t) (Sigma: the
//                sum of the two antennas' position covariances) and correlation time tau: bounded
//                by what the absolute GPS says, and as smooth as the INS makes it;
//   measurement  z_k = baseline_k - ins_baseline(t_k) = e(t_k) + v_k,  v_k ~ N(0, sigma_k^2), sigma_k
//                the receiver's reported accuracy (float solutions at least float_sigma_floor_m;
//                invalid ones, without relPosValid, skipped), gated by the innovation's chi-square
//                (3 degrees of freedom);
//   s and tau    unless given, the pair whose innovations are most likely (a grid): s > 1 says the
//                solutions' sigma is optimistic (a filter fed slowly wandering single-point errors
//                as if white reports centimetres for metres);
//   at(t)        the smoothed e at t (between epochs: interpolated; gaps are filled with prediction
//                epochs so an outage's sigma grows and falls as it should), with its covariance.
// With metres-off absolute GPS the baseline decides (S is large); with RTK on both aircraft the two
// average, better than either; far from any baseline the correction fades to zero and its sigma to
// the solutions' own.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/expected.hpp"
#include "core/frame.hpp"

namespace augrig::nav {

struct BaselineMeasurement {
  TimestampNs t_ns = 0;                                   // time of validity, on the nav clock (GPS time)
  TimestampNs arrival_ns = 0;                             // host arrival (live inputs; 0: unknown)
  Eigen::Vector3d ned_m = Eigen::Vector3d::Zero();        // base (tanker) antenna -> rover (receiver) antenna
  Eigen::Vector3d sigma_ned_m = Eigen::Vector3d::Zero();  // 1-sigma per axis, as reported
  int carr_soln = 2;                                      // 0 none, 1 float, 2 fixed
  bool valid = true;                                      // relPosValid
};

// The two solutions' antenna-to-antenna vector at a time, NED at the base antenna, and the sum of
// the antennas' position covariances (NED).
struct InsBaselineSample {
  Eigen::Vector3d ned_m = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov_ned_m2 = Eigen::Matrix3d::Identity();
};

struct BaselineFusionOptions {
  double sigma_scale = 0;             // s; 0: the most likely of 1 .. 1000
  double correlation_s = 0;           // tau; 0: the most likely of 0.3 .. 300 s
  double sigma_floor_m = 0.005;       // no measurement trusted below this per axis
  double float_sigma_floor_m = 0.30;  // float solutions (ambiguities not fixed: biased by decimetres)
  bool use_float = true;
  double gate_chi2 = 16.27;        // innovation chi-square (3 dof) beyond this: rejected (p = 0.001)
  int reset_after_rejections = 5;  // so many fixed solutions rejected in a row: the filter restarts there
  double fill_step_s = 0.2;        // gaps longer than this get prediction epochs this far apart
  double max_gap_s = 5.0;          // no correction farther than this before the first or after the last
};

// What a fusion does with a measurement: uses it, or drops it as invalid (no valid vector, no
// carrier solution, a non-finite vector) or as a float solution that `options` leave out.
enum class BaselineUse { kUse, kInvalid, kFloatSkipped };
BaselineUse baseline_use(const BaselineMeasurement& m, const BaselineFusionOptions& options);

// A measurement's noise covariance (NED, diagonal): the receiver's accuracy, at least
// sigma_floor_m, at least float_sigma_floor_m for float solutions.
Eigen::Matrix3d baseline_noise(const BaselineMeasurement& m, const BaselineFusionOptions& options);

struct BaselineCorrection {
  Eigen::Vector3d e_ned_m = Eigen::Vector3d::Zero();     // add to the INS baseline
  Eigen::Matrix3d cov_ned_m2 = Eigen::Matrix3d::Zero();  // of the corrected baseline
  Eigen::Vector3d sigma_ned_m() const { return cov_ned_m2.diagonal().cwiseSqrt(); }
};

struct BaselineFusionReport {
  std::size_t measurements = 0, used = 0, used_float = 0;
  std::size_t invalid = 0, float_skipped = 0, outside_ins = 0, rejected = 0, resets = 0;
  double innovation_rms_m = 0;  // of the used measurements, before the update
  double sigma_scale = 1;       // s, as given or chosen
  double correlation_s = 0;     // tau, as given or chosen
  std::string summary() const;  // one line, every count
};

// One model's (s, tau) forward filter, measurement by measurement: the offline fusion's forward
// pass for each model it weighs.
class BaselineFilter {
 public:
  BaselineFilter(double sigma_scale, double correlation_s, const BaselineFusionOptions& options,
                 bool keep_history = false);
  // A measurement epoch: z = baseline - INS baseline, its noise R, the solutions' covariance Sigma
  // there. Times must increase (an older one is counted out of order and left out).
  void measure(TimestampNs t_ns, const Eigen::Vector3d& z, const Eigen::Matrix3d& R,
               const Eigen::Matrix3d& Sigma, bool is_float);
  // A prediction epoch (in a gap), after the first measurement.
  void predict(TimestampNs t_ns, const Eigen::Matrix3d& Sigma);
  // The newest state carried forward to t_ns; nullopt before it, before any measurement, or more
  // than max_gap_s after it.
  std::optional<BaselineCorrection> at(TimestampNs t_ns) const;

  struct Counts {
    std::size_t used = 0, used_float = 0, rejected = 0, resets = 0, innovations = 0, out_of_order = 0;
    double innovation_sq = 0;  // of the gated innovations
  };
  // An epoch as the smoother needs it: filtered and predicted state, transition, model.
  struct Record {
    TimestampNs t_ns = 0;
    Eigen::Matrix<double, 6, 1> x, x_pred;
    Eigen::Matrix<double, 6, 6> P, P_pred, F, P_stationary;
    bool start = false;  // the first epoch, or a restart
  };
  const Counts& counts() const { return counts_; }
  // Of the innovations so far; a rejected measurement counts as if at the gate.
  double log_likelihood() const { return log_likelihood_; }
  double sigma_scale() const { return scale_; }
  double correlation_s() const { return 1.0 / w_; }
  const std::vector<Record>& history() const { return history_; }  // with keep_history

 private:
  Record predicted(TimestampNs t_ns, const Eigen::Matrix3d& Sigma) const;
  void push(const Record& r);
  double scale_, w_;
  BaselineFusionOptions options_;
  bool keep_history_;
  bool started_ = false;
  Record last_;
  std::vector<Record> history_;
  Counts counts_;
  double log_likelihood_ = 0;
  int rejected_in_a_row_ = 0;
};

class BaselineFusion {
 public:
  // `ins_baseline(t_ns)`: the INS solutions' base -> rover antenna vector and covariance at t_ns,
  // nullopt outside their span. Measurements need not be sorted. Errors: no measurement could be
  // used.
  static Expected<BaselineFusion> fuse(
      std::vector<BaselineMeasurement> measurements,
      const std::function<std::optional<InsBaselineSample>(TimestampNs)>& ins_baseline,
      const BaselineFusionOptions& options = {});
  // The correction at t_ns; nullopt before the first or after the last epoch by more than
  // max_gap_s.
  std::optional<BaselineCorrection> at(TimestampNs t_ns) const;
  const BaselineFusionReport& report() const { return report_; }

 private:
  struct Epoch {
    TimestampNs t_ns = 0;
    Eigen::Matrix<double, 6, 1> x;  // smoothed [e, de/dt]
    Eigen::Matrix<double, 6, 6> P;
    Eigen::Matrix<double, 6, 6> P_stationary;  // the model's there
    bool segment_start = false;                // a restart: no interpolation across it
  };
  std::vector<Epoch> epochs_;
  BaselineFusionOptions options_;
  BaselineFusionReport report_;
};

}  // namespace augrig::nav
