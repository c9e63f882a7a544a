#include "nav/baseline_fusion.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <Eigen/Dense>

namespace augrig::nav {

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat36 = Eigen::Matrix<double, 3, 6>;

// Constant velocity per axis over dt seconds, driven by white acceleration of density q.
Mat6 transition(double dt) {
  Mat6 F = Mat6::Identity();
  F.block<3, 3>(0, 3) = dt * Eigen::Matrix3d::Identity();
  return F;
}
Mat6 process_noise(double dt, double q) {
  const double a = std::abs(dt);
  Mat6 Q = Mat6::Zero();
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  Q.block<3, 3>(0, 0) = q * a * a * a / 3.0 * I;
  Q.block<3, 3>(0, 3) = Q.block<3, 3>(3, 0) = q * a * a / 2.0 * I;
  Q.block<3, 3>(3, 3) = q * a * I;
  return Q;
}
Mat36 observation() {
  Mat36 H = Mat36::Zero();
  H.block<3, 3>(0, 0).setIdentity();
  return H;
}

}  // namespace

std::string BaselineFusionReport::summary() const {
  std::ostringstream o;
  o << "moving-baseline RTK: " << measurements << " measurements: " << used << " used (" << used_float
    << " float), " << invalid << " without a valid vector, " << float_skipped << " float skipped, "
    << outside_ins << " outside the INS solutions, " << rejected << " rejected by the gate; " << resets
    << " restart(s); innovations " << std::fixed;
  o.precision(3);
  o << innovation_rms_m << " m RMS; model " << std::scientific;
  o.precision(1);
  o << accel_psd_m2ps3 << " (m/s^2)^2/Hz";
  return o.str();
}

namespace {

// One usable measurement, as the filter sees it: z = baseline - INS baseline, with its noise.
struct Prepared {
  TimestampNs t_ns;
  Eigen::Vector3d z;
  Eigen::Matrix3d R;
  bool is_float;
};

// The forward pass, keeping what the smoother needs: filtered and predicted states, transitions.
struct Forward {
  TimestampNs t_ns;
  Vec6 x, x_pred;
  Mat6 P, P_pred, F;
  bool start;
};

struct ForwardPass {
  std::vector<Forward> fw;
  double log_likelihood = 0;  // of the gated innovations (restarts contribute nothing)
  std::size_t used = 0, used_float = 0, rejected = 0, resets = 0, innovations = 0;
  double innovation_sq = 0;
};

ForwardPass forward(const std::vector<Prepared>& ms, double q, const BaselineFusionOptions& options) {
  ForwardPass out;
  std::vector<Forward>& fw = out.fw;
  fw.reserve(ms.size());
  const Mat36 H = observation();
  int rejected_in_a_row = 0;
  auto start_at = [&](const Prepared& m) {
    Forward s;
    s.t_ns = m.t_ns;
    s.x.setZero();
    s.x.head<3>() = m.z;
    s.P.setZero();
    s.P.block<3, 3>(0, 0) = m.R;
    s.P.block<3, 3>(3, 3) = 0.25 * Eigen::Matrix3d::Identity();  // (0.5 m/s)^2: the INS error's rate, unknown
    s.x_pred = s.x, s.P_pred = s.P, s.F = Mat6::Identity();
    s.start = true;
    fw.push_back(s);
    ++out.used, out.used_float += m.is_float;
    rejected_in_a_row = 0;
  };
  for (const Prepared& m : ms) {
    const double dt = fw.empty() ? 0.0 : static_cast<double>(m.t_ns - fw.back().t_ns) / 1e9;
    if (fw.empty() || dt > 2 * options.max_gap_s) {
      start_at(m);
      continue;
    }
    Forward s;
    s.t_ns = m.t_ns;
    s.F = transition(dt);
    s.x_pred = s.F * fw.back().x;
    s.P_pred = s.F * fw.back().P * s.F.transpose() + process_noise(dt, q);
    const Eigen::Vector3d y = m.z - H * s.x_pred;
    const Eigen::Matrix3d S = H * s.P_pred * H.transpose() + m.R;
    const Eigen::LDLT<Eigen::Matrix3d> Sf(S);
    const double nis = y.dot(Sf.solve(y));
    if (nis > options.gate_chi2) {
      ++out.rejected;
      // Counted as no likelier than the gate, so a model that rejects more does not look better.
      out.log_likelihood -= 0.5 * (options.gate_chi2 + std::log(Sf.vectorD().prod()));
      // The INS solutions (or the baseline) jumped for good: start again from here.
      if (++rejected_in_a_row >= options.reset_after_rejections) {
        start_at(m);
        ++out.resets;
      }
      continue;
    }
    rejected_in_a_row = 0;
    out.log_likelihood -= 0.5 * (nis + std::log(Sf.vectorD().prod()));
    const Eigen::Matrix<double, 6, 3> K = s.P_pred * H.transpose() * Sf.solve(Eigen::Matrix3d::Identity());
    s.x = s.x_pred + K * y;
    const Mat6 IKH = Mat6::Identity() - K * H;
    s.P = IKH * s.P_pred * IKH.transpose() + K * m.R * K.transpose();  // Joseph form
    s.start = false;
    fw.push_back(s);
    ++out.used, out.used_float += m.is_float;
    out.innovation_sq += y.squaredNorm();
    ++out.innovations;
  }
  return out;
}

}  // namespace

Expected<BaselineFusion> BaselineFusion::fuse(
    std::vector<BaselineMeasurement> measurements,
    const std::function<std::optional<Eigen::Vector3d>(TimestampNs)>& ins_baseline,
    const BaselineFusionOptions& options) {
  std::stable_sort(
      measurements.begin(), measurements.end(),
      [](const BaselineMeasurement& a, const BaselineMeasurement& b) { return a.t_ns < b.t_ns; });
  BaselineFusion f;
  f.options_ = options;
  BaselineFusionReport& r = f.report_;
  // What the filter can use: valid vectors inside the INS solutions' span.
  std::vector<Prepared> ms;
  ms.reserve(measurements.size());
  for (const BaselineMeasurement& m : measurements) {
    ++r.measurements;
    if (!m.valid || m.carr_soln == 0 || !m.ned_m.allFinite()) {
      ++r.invalid;
      continue;
    }
    const bool is_float = m.carr_soln == 1;
    if (is_float && !options.use_float) {
      ++r.float_skipped;
      continue;
    }
    const std::optional<Eigen::Vector3d> ins = ins_baseline(m.t_ns);
    if (!ins) {
      ++r.outside_ins;
      continue;
    }
    Prepared p{m.t_ns, m.ned_m - *ins, Eigen::Matrix3d::Zero(), is_float};
    for (int k = 0; k < 3; ++k) {
      const double floor = is_float ? options.float_sigma_floor_m : options.sigma_floor_m;
      const double sg = std::isfinite(m.sigma_ned_m[k]) ? std::max(m.sigma_ned_m[k], floor) : floor;
      p.R(k, k) = sg * sg;
    }
    ms.push_back(p);
  }
  // How fast the INS baseline's error wanders depends on the absolute GPS and the IMUs: unless
  // given, the density whose innovations are most likely, over a grid of half decades.
  double q = options.accel_psd_m2ps3;
  if (!(q > 0) && !ms.empty()) {
    double best = -std::numeric_limits<double>::infinity();
    for (double lg = -7.0; lg <= 2.0 + 1e-9; lg += 0.5) {
      const double candidate = std::pow(10.0, lg);
      const double ll = forward(ms, candidate, options).log_likelihood;
      if (ll > best) best = ll, q = candidate;
    }
  }
  if (!(q > 0)) q = 1e-3;
  f.options_.accel_psd_m2ps3 = q;
  r.accel_psd_m2ps3 = q;
  ForwardPass pass = forward(ms, q, options);
  std::vector<Forward>& fw = pass.fw;
  r.used = pass.used, r.used_float = pass.used_float, r.rejected = pass.rejected, r.resets = pass.resets;
  if (fw.empty())
    return make_error("nav::BaselineFusion::fuse(): no usable moving-baseline measurement (", r.summary(),
                      ")");
  r.innovation_rms_m =
      pass.innovations ? std::sqrt(pass.innovation_sq / static_cast<double>(pass.innovations)) : 0.0;

  // The RTS smoother, segment by segment (a restart cuts the chain).
  f.epochs_.resize(fw.size());
  for (std::size_t k = fw.size(); k-- > 0;) {
    Epoch& e = f.epochs_[k];
    e.t_ns = fw[k].t_ns;
    e.segment_start = fw[k].start;
    if (k + 1 == fw.size() || fw[k + 1].start) {
      e.x = fw[k].x, e.P = fw[k].P;
      continue;
    }
    const Mat6 C = fw[k].P * fw[k + 1].F.transpose() * fw[k + 1].P_pred.inverse();
    e.x = fw[k].x + C * (f.epochs_[k + 1].x - fw[k + 1].x_pred);
    e.P = fw[k].P + C * (f.epochs_[k + 1].P - fw[k + 1].P_pred) * C.transpose();
  }
  return f;
}

std::optional<BaselineCorrection> BaselineFusion::at(TimestampNs t_ns) const {
  if (epochs_.empty()) return std::nullopt;
  const TimestampNs max_gap_ns = static_cast<TimestampNs>(options_.max_gap_s * 1e9);
  // The smoothed state of epoch `e` carried to t_ns (either way) by the motion model.
  auto carried = [&](const Epoch& e) -> std::optional<BaselineCorrection> {
    if (std::abs(t_ns - e.t_ns) > max_gap_ns) return std::nullopt;
    const double dt = static_cast<double>(t_ns - e.t_ns) / 1e9;
    const Mat6 F = transition(dt);
    const Vec6 x = F * e.x;
    const Mat6 P = F * e.P * F.transpose() + process_noise(dt, options_.accel_psd_m2ps3);
    return BaselineCorrection{x.head<3>(), P.diagonal().head<3>().cwiseSqrt()};
  };
  const auto after = std::upper_bound(epochs_.begin(), epochs_.end(), t_ns,
                                      [](TimestampNs t, const Epoch& e) { return t < e.t_ns; });
  if (after == epochs_.begin()) return carried(*after);
  const Epoch& a = *(after - 1);
  if (after == epochs_.end() || after->segment_start) {
    // After the last epoch of a segment: carried from it, or back from the next segment's first.
    auto from_a = carried(a);
    if (after != epochs_.end() && (!from_a || after->t_ns - t_ns < t_ns - a.t_ns))
      if (auto from_b = carried(*after)) return from_b;
    return from_a;
  }
  // Between two smoothed epochs of a segment: linear in time between them.
  const Epoch& b = *after;
  const double w =
      b.t_ns == a.t_ns ? 0.0 : static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  BaselineCorrection c;
  c.e_ned_m = (1 - w) * a.x.head<3>() + w * b.x.head<3>();
  c.sigma_ned_m = ((1 - w) * a.P.diagonal().head<3>() + w * b.P.diagonal().head<3>()).cwiseSqrt();
  return c;
}

}  // namespace augrig::nav
