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

// The critically damped second-order Gauss-Markov process of angular frequency w = 1 / tau over dt
// seconds, the same for each axis: exp(A dt), A = [[0, 1], [-w^2, -2 w]].
Mat6 transition(double dt, double w) {
  const double a = std::exp(-w * dt);
  Mat6 F;
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  F << a * (1 + w * dt) * I, a * dt * I, -a * w * w * dt * I, a * (1 - w * dt) * I;
  return F;
}
// Its stationary covariance for position covariance S: the velocity's is w^2 S, uncorrelated.
Mat6 stationary(const Eigen::Matrix3d& S, double w) {
  Mat6 P = Mat6::Zero();
  P.topLeftCorner<3, 3>() = S;
  P.bottomRightCorner<3, 3>() = w * w * S;
  return P;
}
// The state carried dt seconds on; with dt < 0 back in time (the stationary process reversed:
// the same law with the velocity's sign flipped).
void carry(double dt, double w, const Mat6& P_stationary, Vec6& x, Mat6& P) {
  Mat6 flip = Mat6::Identity();
  if (dt < 0) flip.bottomRightCorner<3, 3>() *= -1;
  const Mat6 F = transition(std::abs(dt), w);
  x = flip * F * flip * x;
  P = flip * (F * (flip * P * flip) * F.transpose() + P_stationary - F * P_stationary * F.transpose()) * flip;
}

// The models the likelihood chooses among (offline and live alike).
std::vector<double> scales_of(const BaselineFusionOptions& o) {
  return o.sigma_scale > 0 ? std::vector<double>{o.sigma_scale}
                           : std::vector<double>{1, 2, 5, 10, 20, 50, 100, 200, 500, 1000};
}
std::vector<double> taus_of(const BaselineFusionOptions& o) {
  return o.correlation_s > 0 ? std::vector<double>{o.correlation_s}
                             : std::vector<double>{0.3, 1, 3, 10, 30, 100, 300};
}

// One epoch as the offline fusion prepares it: a measurement z = baseline - INS baseline with its
// noise, or (in a gap) none, and the solutions' covariance there.
struct Step {
  TimestampNs t_ns;
  Eigen::Vector3d z;
  Eigen::Matrix3d R, Sigma;
  bool measured, is_float;
};

BaselineFilter forward(const std::vector<Step>& steps, double scale, double tau_s,
                       const BaselineFusionOptions& options, bool keep_history) {
  BaselineFilter f(scale, tau_s, options, keep_history);
  for (const Step& m : steps) {
    if (m.measured)
      f.measure(m.t_ns, m.z, m.R, m.Sigma, m.is_float);
    else
      f.predict(m.t_ns, m.Sigma);
  }
  return f;
}

}  // namespace

// A measurement's noise: the receiver's accuracy, floored (float solutions higher).
BaselineUse baseline_use(const BaselineMeasurement& m, const BaselineFusionOptions& options) {
  if (!m.valid || m.carr_soln == 0 || !m.ned_m.allFinite()) return BaselineUse::kInvalid;
  if (m.carr_soln == 1 && !options.use_float) return BaselineUse::kFloatSkipped;
  return BaselineUse::kUse;
}

Eigen::Matrix3d baseline_noise(const BaselineMeasurement& m, const BaselineFusionOptions& options) {
  Eigen::Matrix3d R = Eigen::Matrix3d::Zero();
  const bool is_float = m.carr_soln == 1;
  for (int k = 0; k < 3; ++k) {
    const double floor = is_float ? options.float_sigma_floor_m : options.sigma_floor_m;
    const double sg = std::isfinite(m.sigma_ned_m[k]) ? std::max(m.sigma_ned_m[k], floor) : floor;
    R(k, k) = sg * sg;
  }
  return R;
}

std::string BaselineFusionReport::summary() const {
  std::ostringstream o;
  o << "moving-baseline RTK: " << measurements << " measurements: " << used << " used (" << used_float
    << " float), " << invalid << " without a valid vector, " << float_skipped << " float skipped, "
    << outside_ins << " outside the INS solutions, " << rejected << " rejected by the gate; " << resets
    << " restart(s); innovations " << std::fixed;
  o.precision(3);
  o << innovation_rms_m << " m RMS; the solutions' sigma ";
  o.precision(1);
  o << "x" << sigma_scale << " (" << (sigma_scale > 1.5 ? "optimistic" : "held")
    << "), their error's correlation time " << correlation_s << " s";
  return o.str();
}

BaselineFilter::BaselineFilter(double sigma_scale, double correlation_s, const BaselineFusionOptions& options,
                               bool keep_history)
    : scale_(sigma_scale), w_(1.0 / correlation_s), options_(options), keep_history_(keep_history) {}

BaselineFilter::Record BaselineFilter::predicted(TimestampNs t_ns, const Eigen::Matrix3d& Sigma) const {
  Record s;
  s.t_ns = t_ns;
  s.P_stationary = stationary(scale_ * scale_ * Sigma, w_);
  s.start = !started_;
  if (s.start) {
    // No measurement yet: the error is what the solutions say it can be.
    s.F = Mat6::Identity();
    s.x_pred.setZero();
    s.P_pred = s.P_stationary;
  } else {
    const double dt = static_cast<double>(t_ns - last_.t_ns) / 1e9;
    s.F = transition(dt, w_);
    s.x_pred = s.F * last_.x;
    s.P_pred = s.F * last_.P * s.F.transpose() + s.P_stationary - s.F * s.P_stationary * s.F.transpose();
    s.P_pred = 0.5 * (s.P_pred + s.P_pred.transpose()).eval();
  }
  return s;
}

void BaselineFilter::push(const Record& r) {
  last_ = r;
  started_ = true;
  if (keep_history_) history_.push_back(r);
}

void BaselineFilter::predict(TimestampNs t_ns, const Eigen::Matrix3d& Sigma) {
  if (!started_ || t_ns <= last_.t_ns) return;
  Record s = predicted(t_ns, Sigma);
  s.x = s.x_pred, s.P = s.P_pred;
  push(s);
}

void BaselineFilter::measure(TimestampNs t_ns, const Eigen::Vector3d& z, const Eigen::Matrix3d& R,
                             const Eigen::Matrix3d& Sigma, bool is_float) {
  if (started_ && t_ns <= last_.t_ns) {
    ++counts_.out_of_order;  // the filter runs forward only
    return;
  }
  Record s = predicted(t_ns, Sigma);
  Eigen::Vector3d y = z - s.x_pred.head<3>();
  Eigen::LDLT<Eigen::Matrix3d> Sf(s.P_pred.topLeftCorner<3, 3>() + R);
  const double nis = y.dot(Sf.solve(y));
  const double log_det = std::log(Sf.vectorD().prod());
  if (!s.start && nis > options_.gate_chi2) {
    ++counts_.rejected;
    // Counted as no likelier than the gate, so a model that rejects more does not look better.
    log_likelihood_ -= 0.5 * (options_.gate_chi2 + log_det);
    // Fixed baselines rejected again and again: the INS solutions jumped for good; start again
    // from here. (Float ones off the track are what float solutions are: biased.)
    if (is_float || ++rejected_in_a_row_ < options_.reset_after_rejections) return;
    ++counts_.resets;
    s.start = true;
    s.F = Mat6::Identity();
    s.x_pred.setZero();
    s.P_pred = s.P_stationary;
    y = z;
    Sf.compute(s.P_pred.topLeftCorner<3, 3>() + R);
  } else {
    log_likelihood_ -= 0.5 * (nis + log_det);
    if (!s.start) {
      counts_.innovation_sq += y.squaredNorm();
      ++counts_.innovations;
    }
  }
  rejected_in_a_row_ = 0;
  const Eigen::Matrix<double, 6, 3> K =
      s.P_pred.leftCols<3>() * Sf.solve(Eigen::Matrix3d::Identity());  // P H^T S^-1, H = [I 0]
  s.x = s.x_pred + K * y;
  Eigen::Matrix<double, 3, 6> H = Eigen::Matrix<double, 3, 6>::Zero();
  H.leftCols<3>().setIdentity();
  const Mat6 IKH = Mat6::Identity() - K * H;
  s.P = IKH * s.P_pred * IKH.transpose() + K * R * K.transpose();  // Joseph form
  push(s);
  ++counts_.used, counts_.used_float += is_float;
}

std::optional<BaselineCorrection> BaselineFilter::at(TimestampNs t_ns) const {
  if (!started_ || t_ns < last_.t_ns ||
      t_ns - last_.t_ns > static_cast<TimestampNs>(options_.max_gap_s * 1e9))
    return std::nullopt;
  Vec6 x = last_.x;
  Mat6 P = last_.P;
  carry(static_cast<double>(t_ns - last_.t_ns) / 1e9, w_, last_.P_stationary, x, P);
  return BaselineCorrection{x.head<3>(), P.topLeftCorner<3, 3>()};
}

Expected<BaselineFusion> BaselineFusion::fuse(
    std::vector<BaselineMeasurement> measurements,
    const std::function<std::optional<InsBaselineSample>(TimestampNs)>& ins_baseline,
    const BaselineFusionOptions& options) {
  std::stable_sort(
      measurements.begin(), measurements.end(),
      [](const BaselineMeasurement& a, const BaselineMeasurement& b) { return a.t_ns < b.t_ns; });
  BaselineFusion f;
  f.options_ = options;
  BaselineFusionReport& r = f.report_;
  // What the filter can use: valid vectors inside the INS solutions' span, and prediction epochs
  // filling the gaps between them.
  std::vector<Step> steps;
  steps.reserve(measurements.size());
  const TimestampNs fill_ns =
      std::max<TimestampNs>(1'000'000, static_cast<TimestampNs>(options.fill_step_s * 1e9));
  for (const BaselineMeasurement& m : measurements) {
    ++r.measurements;
    if (const BaselineUse use = baseline_use(m, options); use != BaselineUse::kUse) {
      ++(use == BaselineUse::kInvalid ? r.invalid : r.float_skipped);
      continue;
    }
    const bool is_float = m.carr_soln == 1;
    const std::optional<InsBaselineSample> ins = ins_baseline(m.t_ns);
    if (!ins) {
      ++r.outside_ins;
      continue;
    }
    if (!steps.empty())
      for (TimestampNs t = steps.back().t_ns + fill_ns; t + fill_ns / 2 < m.t_ns; t += fill_ns)
        if (const auto g = ins_baseline(t))
          steps.push_back({t, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Zero(), g->cov_ned_m2, false, false});
    steps.push_back(
        {m.t_ns, m.ned_m - ins->ned_m, baseline_noise(m, options), ins->cov_ned_m2, true, is_float});
  }
  // How honest the solutions' sigma is, and how fast their error wanders, unless given: the pair
  // whose innovations are most likely.
  const std::vector<double> scales = scales_of(options), taus = taus_of(options);
  double scale = scales.front(), tau = taus.front();
  if (scales.size() * taus.size() > 1 && !steps.empty()) {
    double best = -std::numeric_limits<double>::infinity();
    for (double sc : scales)
      for (double ta : taus) {
        const double ll = forward(steps, sc, ta, options, false).log_likelihood();
        if (ll > best) best = ll, scale = sc, tau = ta;
      }
  }
  f.options_.sigma_scale = r.sigma_scale = scale;
  f.options_.correlation_s = r.correlation_s = tau;
  const BaselineFilter pass = forward(steps, scale, tau, options, true);
  const std::vector<BaselineFilter::Record>& fw = pass.history();
  const BaselineFilter::Counts& c = pass.counts();
  r.used = c.used, r.used_float = c.used_float, r.rejected = c.rejected, r.resets = c.resets;
  if (c.used == 0)
    return make_error("nav::BaselineFusion::fuse(): no usable moving-baseline measurement (", r.summary(),
                      ")");
  r.innovation_rms_m = c.innovations ? std::sqrt(c.innovation_sq / static_cast<double>(c.innovations)) : 0.0;

  // The RTS smoother, segment by segment (a restart cuts the chain).
  f.epochs_.resize(fw.size());
  for (std::size_t k = fw.size(); k-- > 0;) {
    Epoch& e = f.epochs_[k];
    e.t_ns = fw[k].t_ns;
    e.segment_start = fw[k].start;
    e.P_stationary = fw[k].P_stationary;
    if (k + 1 == fw.size() || fw[k + 1].start) {
      e.x = fw[k].x, e.P = fw[k].P;
      continue;
    }
    // C = P_k F^T P_pred^-1, by a solve.
    const Mat6 C = fw[k + 1].P_pred.ldlt().solve(fw[k + 1].F * fw[k].P).transpose();
    e.x = fw[k].x + C * (f.epochs_[k + 1].x - fw[k + 1].x_pred);
    e.P = fw[k].P + C * (f.epochs_[k + 1].P - fw[k + 1].P_pred) * C.transpose();
    e.P = 0.5 * (e.P + e.P.transpose()).eval();
  }
  return f;
}

std::optional<BaselineCorrection> BaselineFusion::at(TimestampNs t_ns) const {
  if (epochs_.empty()) return std::nullopt;
  const TimestampNs max_gap_ns = static_cast<TimestampNs>(options_.max_gap_s * 1e9);
  const double w = 1.0 / options_.correlation_s;
  // The smoothed state of epoch `e` carried to t_ns (either way) by the model.
  auto carried = [&](const Epoch& e) -> std::optional<BaselineCorrection> {
    if (std::abs(t_ns - e.t_ns) > max_gap_ns) return std::nullopt;
    Vec6 x = e.x;
    Mat6 P = e.P;
    carry(static_cast<double>(t_ns - e.t_ns) / 1e9, w, e.P_stationary, x, P);
    return BaselineCorrection{x.head<3>(), P.topLeftCorner<3, 3>()};
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
  // Between two smoothed epochs of a segment (at most fill_step_s apart in a gap): linear in time.
  const Epoch& b = *after;
  const double u =
      b.t_ns == a.t_ns ? 0.0 : static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  BaselineCorrection c;
  c.e_ned_m = (1 - u) * a.x.head<3>() + u * b.x.head<3>();
  c.cov_ned_m2 = (1 - u) * a.P.topLeftCorner<3, 3>() + u * b.P.topLeftCorner<3, 3>();
  return c;
}

}  // namespace augrig::nav
