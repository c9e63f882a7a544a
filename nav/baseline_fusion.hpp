// baseline_fusion: the moving-baseline RTK vector (UBX NAV-RELPOSNED: the receiver's GPS antenna
// relative to the tanker's, NED at the tanker's antenna) fused, as a relative measurement, with the
// same vector as the two aircraft's GPS/INS solutions give it. Their difference is the error of the
// INS baseline, e(t) = truth - ins; it is what ties the two solutions together, and it is what a
// joint filter's relative states would estimate. Here it is estimated on its own: a Kalman filter
// and RTS smoother over the measurement epochs with state [e, de/dt] (per NED axis: constant
// velocity driven by white acceleration of spectral density accel_psd), each measurement
//   z_k = baseline_k - ins_baseline(t_k) = e(t_k) + v_k,  v_k ~ N(0, sigma_k^2)
// with sigma_k the receiver's reported accuracy (float solutions at least float_sigma_floor_m;
// invalid ones, without relPosValid, skipped), gated by its innovation's chi-square (3 degrees of
// freedom). The corrected baseline at any time t inside the measurements' span is ins(t) + e(t),
// e interpolated between the smoothed epochs, with its 1-sigma. Because e varies slowly (both INS
// solutions are smooth), centimetre baselines at a few hertz give centimetre relative positions at
// every camera frame, even when the absolute GPS of both aircraft is metres off.
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
  Eigen::Vector3d ned_m = Eigen::Vector3d::Zero();        // base (tanker) antenna -> rover (receiver) antenna
  Eigen::Vector3d sigma_ned_m = Eigen::Vector3d::Zero();  // 1-sigma per axis, as reported
  int carr_soln = 2;                                      // 0 none, 1 float, 2 fixed
  bool valid = true;                                      // relPosValid
};

struct BaselineFusionOptions {
  // White acceleration of e driving the model, (m/s^2)^2/Hz; 0: the most likely one given the
  // measurements (maximum likelihood of the innovations over 1e-7..1e2, half decades).
  double accel_psd_m2ps3 = 0;
  double sigma_floor_m = 0.005;       // no measurement trusted below this per axis
  double float_sigma_floor_m = 0.10;  // float solutions (ambiguities not fixed) at least this
  bool use_float = true;
  double gate_chi2 = 16.27;        // innovation chi-square (3 dof) beyond this: rejected (p = 0.001)
  int reset_after_rejections = 5;  // so many rejections in a row: the filter restarts there
  double max_gap_s = 2.0;          // no correction farther than this from a used measurement
};

struct BaselineCorrection {
  Eigen::Vector3d e_ned_m = Eigen::Vector3d::Zero();      // add to the INS baseline
  Eigen::Vector3d sigma_ned_m = Eigen::Vector3d::Zero();  // 1-sigma of the corrected baseline
};

struct BaselineFusionReport {
  std::size_t measurements = 0, used = 0, used_float = 0;
  std::size_t invalid = 0, float_skipped = 0, outside_ins = 0, rejected = 0, resets = 0;
  double innovation_rms_m = 0;  // of the used measurements, before the update
  double accel_psd_m2ps3 = 0;   // the model's, as given or chosen
  std::string summary() const;  // one line, every count
};

class BaselineFusion {
 public:
  // `ins_baseline(t_ns)`: the INS solutions' base -> rover antenna vector (NED at the base
  // antenna) at t_ns, nullopt outside their span. Measurements need not be sorted. Errors: no
  // measurement could be used.
  static Expected<BaselineFusion> fuse(
      std::vector<BaselineMeasurement> measurements,
      const std::function<std::optional<Eigen::Vector3d>(TimestampNs)>& ins_baseline,
      const BaselineFusionOptions& options = {});
  // The correction at t_ns; nullopt before the first or after the last used measurement by more
  // than max_gap_s, or in a gap between used measurements longer than 2 max_gap_s.
  std::optional<BaselineCorrection> at(TimestampNs t_ns) const;
  const BaselineFusionReport& report() const { return report_; }

 private:
  struct Epoch {
    TimestampNs t_ns = 0;
    Eigen::Matrix<double, 6, 1> x;  // smoothed [e, de/dt]
    Eigen::Matrix<double, 6, 6> P;
    bool segment_start = false;  // a restart: no interpolation across it
  };
  std::vector<Epoch> epochs_;
  BaselineFusionOptions options_;
  BaselineFusionReport report_;
};

}  // namespace augrig::nav
