#include "nav/ins.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "nav/ins_engine.hpp"

namespace augrig::nav {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

namespace {

constexpr double kGM = 3.986004418e14;  // WGS84 m^3/s^2
constexpr double kG0 = 9.80665;

Matrix3d skew(const Vector3d& v) {
  Matrix3d S;
  S << 0, -v.z(), v.y(),  //
      v.z(), 0, -v.x(),   //
      -v.y(), v.x(), 0;
  return S;
}

Quaterniond quat_exp(const Vector3d& phi) {
  const double a2 = phi.squaredNorm();
  if (a2 < 1e-24) return Quaterniond(1.0, 0.5 * phi.x(), 0.5 * phi.y(), 0.5 * phi.z()).normalized();
  const double a = std::sqrt(a2);
  const double s = std::sin(0.5 * a) / a;
  return Quaterniond(std::cos(0.5 * a), s * phi.x(), s * phi.y(), s * phi.z());
}

Vector3d quat_log(const Quaterniond& q_in) {
  Quaterniond q = q_in;
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  const double n = q.vec().norm();
  if (n < 1e-12) return 2.0 * q.vec();
  return (2.0 * std::atan2(n, q.w()) / n) * q.vec();
}

// A small rotation in NED (left-multiplied) = M * (d yaw, d pitch, d roll) for Euler ZYX angles.
Matrix3d euler_to_rotation_jacobian(double yaw, double pitch) {
  const double sy = std::sin(yaw), cy = std::cos(yaw);
  const double sp = std::sin(pitch), cp = std::cos(pitch);
  Matrix3d M;
  M << 0, -sy, cy * cp,  //
      0, cy, sy * cp,    //
      1, 0, -sp;
  return M;
}

double wrap_pi(double a) {
  a = std::remainder(a, 2 * kPi);
  return a;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The whole covariance of the 15 inertial and the 2 IMU clock error states [offset, drift] (only
// with the clock estimated: the 15-state filter never builds it).
using Matrix17d = Eigen::Matrix<double, 17, 17>;
using Vector17d = Eigen::Matrix<double, 17, 1>;
constexpr int kErrClock = 15;

Matrix17d assemble(const Matrix15d& P, const ImuClockCovariance& c) {
  Matrix17d A;
  A.topLeftCorner<15, 15>() = P;
  A.topRightCorner<15, 2>() = c.P_xc;
  A.bottomLeftCorner<2, 15>() = c.P_xc.transpose();
  A.bottomRightCorner<2, 2>() = c.P_cc;
  return A;
}

void split(const Matrix17d& A, Matrix15d& P, ImuClockCovariance& c) {
  P = A.topLeftCorner<15, 15>();
  c.P_xc = A.topRightCorner<15, 2>();
  c.P_cc = A.bottomRightCorner<2, 2>();
}

// The clock part of x (+) dx.
void clock_boxplus(InertialState& x, double d_offset_s, double d_drift) {
  x.imu_clock_offset_s += d_offset_s;
  x.imu_clock_drift_s_per_s += d_drift;
}

// A state's error covariance at its GPS time instead of at its IMU-clock time (the IMU clock
// estimated): the state was mechanized to IMU time t, which is GPS time t - c^; the truth at that GPS
// time is the truth at IMU time t + dc, so the position error there is dp + v dc and the attitude
// error dtheta + w dc (w the body rate w.r.t. the Earth, ECEF axes; the velocity's a dc is left out).
// It is what a pose at a camera frame's GPS time is uncertain by: the fixes pin the position at GPS
// time, and dp and dc are strongly anticorrelated.
void covariance_at_gps_time(NavState& s, const StrapdownHistory& h) {
  const double var_c = s.clock.P_cc(0, 0);
  if (!(var_c > 0)) return;
  Vector15d u = Vector15d::Zero();
  u.segment<3>(kErrPos) = s.v_ecef_mps;
  if (h.dt_s > 0) {
    const Vector3d w_eb = h.dtheta_rad / h.dt_s - s.q_ecef_body.conjugate() * earth_rate_ecef();
    u.segment<3>(kErrAtt) = s.q_ecef_body * w_eb;
  }
  const Vector15d pc = s.clock.P_xc.col(0);
  s.P.noalias() += u * pc.transpose() + pc * u.transpose() + var_c * u * u.transpose();
  s.clock.P_xc.noalias() += u * s.clock.P_cc.row(0);
}

// One Kalman update of covariance P (N states) by measurement y = H dx + noise(R), Joseph form: the
// correction dx. False (nothing changed) when S is not positive definite, or the normalised
// innovation squared (into *nis) exceeds `gate` unless `force`.
template <int N, int M>
bool ekf_update(Eigen::Matrix<double, N, N>& P, const Eigen::Matrix<double, M, 1>& y,
                const Eigen::Matrix<double, M, N>& H, const Eigen::Matrix<double, M, M>& R, double gate,
                bool force, double* nis, Eigen::Matrix<double, N, 1>& dx) {
  using MatrixN = Eigen::Matrix<double, N, N>;
  const Eigen::Matrix<double, N, M> PHt = P * H.transpose();
  Eigen::Matrix<double, M, M> S = H * PHt + R;
  const Eigen::LLT<Eigen::Matrix<double, M, M>> llt(S);
  if (llt.info() != Eigen::Success) return false;
  const double chi2 = y.dot(llt.solve(y));
  if (nis) *nis = chi2;
  if (!force && chi2 > gate) return false;
  const Eigen::Matrix<double, N, M> K = llt.solve(PHt.transpose()).transpose();
  dx = K * y;
  // Joseph form.
  MatrixN IKH = MatrixN::Identity();
  IKH.noalias() -= K * H;
  MatrixN tmp;
  tmp.noalias() = IKH * P;
  P.noalias() = tmp * IKH.transpose();
  P.noalias() += K * R * K.transpose();
  P = 0.5 * (P + P.transpose()).eval();
  return true;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Error-state algebra

InertialState boxplus(const InertialState& x, const Vector15d& dx) {
  InertialState y = x;
  y.p_ecef_m += dx.segment<3>(kErrPos);
  y.v_ecef_mps += dx.segment<3>(kErrVel);
  y.q_ecef_body = (quat_exp(dx.segment<3>(kErrAtt)) * x.q_ecef_body).normalized();
  y.gyro_bias_radps += dx.segment<3>(kErrGyroBias);
  y.accel_bias_mps2 += dx.segment<3>(kErrAccelBias);
  return y;
}

Vector15d boxminus(const InertialState& a, const InertialState& b) {
  Vector15d d;
  d.segment<3>(kErrPos) = a.p_ecef_m - b.p_ecef_m;
  d.segment<3>(kErrVel) = a.v_ecef_mps - b.v_ecef_mps;
  d.segment<3>(kErrAtt) = quat_log(a.q_ecef_body * b.q_ecef_body.conjugate());
  d.segment<3>(kErrGyroBias) = a.gyro_bias_radps - b.gyro_bias_radps;
  d.segment<3>(kErrAccelBias) = a.accel_bias_mps2 - b.accel_bias_mps2;
  return d;
}

Matrix3d gravity_gradient_ecef(const Vector3d& p_ecef_m) {
  const double r = p_ecef_m.norm();
  const Vector3d u = p_ecef_m / r;
  Matrix3d G = -(kGM / (r * r * r)) * (Matrix3d::Identity() - 3.0 * u * u.transpose());
  const double w2 = kEarthRate_radps * kEarthRate_radps;
  G(0, 0) += w2;
  G(1, 1) += w2;
  return G;
}

// ---------------------------------------------------------------------------------------------
// Strapdown

void Strapdown::reset(const InertialState& x, const History& history) {
  x_ = x;
  history_ = history;
  have_ref_ = false;
  last_R_ = x.q_ecef_body.toRotationMatrix();
  last_dv_ecef_.setZero();
}

void Strapdown::refresh_gravity(const Vector3d& p_ecef_m) {
  p_ref_ = p_ecef_m;
  g_ref_ = gravity_ecef(p_ref_);
  G_ref_ = gravity_gradient_ecef(p_ref_);
  have_ref_ = true;
}

void Strapdown::step(const Vector3d& dtheta_rad, const Vector3d& dv_mps, TimestampNs t_end_ns) {
  // The step on the IMU clock, dt_clock, lasts dt_clock (1 - drift) of GPS time (the drift is 0
  // unless the IMU clock is estimated): gravity, Earth rate and position integrate over that.
  const double dt_clock = ns_to_s(t_end_ns - x_.t_ns);
  const double dt = dt_clock * (1.0 - x_.imu_clock_drift_s_per_s);
  const Vector3d a = dtheta_rad - x_.gyro_bias_radps * dt;
  const Vector3d u = dv_mps - x_.accel_bias_mps2 * dt;

  // Coning and sculling from the previous increment, scaled to this interval's length.
  Vector3d phi = a;
  Vector3d dv_b = u + 0.5 * a.cross(u);
  if (history_.dt_s > 0) {
    const double s = dt / history_.dt_s;
    const Vector3d ap = s * history_.dtheta_rad, up = s * history_.dv_mps;
    phi += ap.cross(a) * (1.0 / 12.0);
    dv_b += (ap.cross(u) + up.cross(a)) * (1.0 / 12.0);
  }
  history_ = {a, u, dt};

  const Vector3d w = earth_rate_ecef();
  const Matrix3d R = x_.q_ecef_body.toRotationMatrix();
  Vector3d dv_e = R * dv_b;
  dv_e -= (0.5 * dt) * w.cross(dv_e);  // the ECEF frame turns under the body during the interval

  const Vector3d p = x_.p_ecef_m;
  const Vector3d v = x_.v_ecef_mps;
  const Vector3d p_mid = p + (0.5 * dt) * v + (0.125 * dt) * dv_e;
  if (!have_ref_ || (p_mid - p_ref_).squaredNorm() > 200.0 * 200.0) refresh_gravity(p_mid);
  const Vector3d g = g_ref_ + G_ref_ * (p_mid - p_ref_);
  Vector3d v_new = v + dv_e + (g - 2.0 * w.cross(v)) * dt;
  const Vector3d v_mid = 0.5 * (v + v_new);
  v_new = v + dv_e + (g - 2.0 * w.cross(v_mid)) * dt;

  x_.p_ecef_m = p + (0.5 * dt) * (v + v_new);
  x_.v_ecef_mps = v_new;
  const double h = 0.5 * kEarthRate_radps * dt;
  const Quaterniond q_earth(std::cos(h), 0.0, 0.0, -std::sin(h));
  x_.q_ecef_body = (q_earth * x_.q_ecef_body * quat_exp(phi)).normalized();
  x_.imu_clock_offset_s += x_.imu_clock_drift_s_per_s * dt_clock;  // 0 when the clock is not estimated
  x_.t_ns = t_end_ns;
  last_R_ = R;
  last_dv_ecef_ = dv_e;
}

// ---------------------------------------------------------------------------------------------
// IMU increments: splitting one at an arbitrary time

namespace {

// The rate of a stored increment and the time of its midpoint.
template <typename Inc>
double mid_s(const Inc& i, TimestampNs t_ref) {
  return ns_to_s((i.t0_ns - t_ref) + (i.t1_ns - i.t0_ns) / 2);
}

// Part (a, b] of increment j. The rate inside j is modelled as linear, with its slope from the
// neighbours' mean rates; the parts of an increment always sum to the whole increment.
template <typename Inc>
std::pair<Vector3d, Vector3d> piece(const std::vector<Inc>& imu, std::size_t j, TimestampNs a,
                                    TimestampNs b) {
  const Inc& c = imu[j];
  const double len = ns_to_s(c.t1_ns - c.t0_ns);
  const double ua = ns_to_s(a - c.t0_ns) / len, ub = ns_to_s(b - c.t0_ns) / len;
  Vector3d sth = Vector3d::Zero(), sdv = Vector3d::Zero();  // rate slope x len^2
  const std::size_t lo = j > 0 ? j - 1 : j, hi = j + 1 < imu.size() ? j + 1 : j;
  if (hi != lo) {
    const Inc& l = imu[lo];
    const Inc& h = imu[hi];
    const double ll = ns_to_s(l.t1_ns - l.t0_ns), lh = ns_to_s(h.t1_ns - h.t0_ns);
    const double span = mid_s(h, c.t0_ns) - mid_s(l, c.t0_ns);
    const double k = len * len / span;
    sth = (h.dtheta_rad / lh - l.dtheta_rad / ll) * k;
    sdv = (h.dv_mps / lh - l.dv_mps / ll) * k;
  }
  const double qa = 0.5 * ua * (ua - 1.0), qb = 0.5 * ub * (ub - 1.0);
  return {(ub - ua) * c.dtheta_rad + (qb - qa) * sth, (ub - ua) * c.dv_mps + (qb - qa) * sdv};
}

}  // namespace

template <typename OnStep>
void NavTrajectory::advance(const std::vector<Increment>& imu, Strapdown& mech, std::size_t& index,
                            TimestampNs t_end_ns, OnStep&& on_step) {
  while (mech.state().t_ns < t_end_ns) {
    const Increment& inc = imu[index];
    const TimestampNs a = mech.state().t_ns;
    const TimestampNs b = std::min(inc.t1_ns, t_end_ns);
    if (a == inc.t0_ns && b == inc.t1_ns) {
      mech.step(inc.dtheta_rad, inc.dv_mps, b);
    } else {
      const auto [dth, dv] = piece(imu, index, a, b);
      mech.step(dth, dv, b);
    }
    on_step(ns_to_s(b - a));
    if (b == inc.t1_ns) ++index;
  }
}

// ---------------------------------------------------------------------------------------------
// The filter

// Sample s as an increment over (t0, t1] after `prev` (nullptr: the first; then its dt_s, else the
// spacing to `next_t1_ns`, gives t0). Lost samples (an interval longer than 1.5 dt_s) are bridged by
// holding the sample's rates over the gap; `gaps` counts them.
Expected<NavTrajectory::Increment> FusionEngine::make_increment(const ImuSample& s, std::size_t i,
                                                                const InsConfig& cfg,
                                                                const NavTrajectory::Increment* prev,
                                                                TimestampNs prev_t_ns, TimestampNs next_t_ns,
                                                                std::size_t& gaps) {
  if (!s.dtheta_rad.allFinite() || !s.dv_mps.allFinite() || !std::isfinite(s.dt_s))
    return make_error("nav::fuse(): IMU sample ", i, " at t=", s.t_ns, " ns: non-finite values");
  if (prev && s.t_ns <= prev_t_ns)
    return make_error("nav::fuse(): IMU sample ", i, " at t=", s.t_ns, " ns is not after sample ", i - 1,
                      " at t=", prev_t_ns, " ns; IMU timestamps must be strictly increasing");
  NavTrajectory::Increment inc;
  inc.t1_ns = s.t_ns + cfg.imu_time_offset_ns;
  inc.dtheta_rad = s.dtheta_rad;
  inc.dv_mps = s.dv_mps;
  if (!prev) {
    TimestampNs dt_ns = s_to_ns(s.dt_s);
    if (dt_ns <= 0 && next_t_ns > s.t_ns) dt_ns = next_t_ns - s.t_ns;
    if (dt_ns <= 0) return make_error("nav::fuse(): IMU sample ", i, " has no positive dt_s");
    inc.t0_ns = inc.t1_ns - dt_ns;
  } else {
    inc.t0_ns = prev->t1_ns;
    const double len = ns_to_s(inc.t1_ns - inc.t0_ns);
    if (s.dt_s > 0 && len > 1.5 * s.dt_s) {
      ++gaps;
      inc.dtheta_rad *= len / s.dt_s;
      inc.dv_mps *= len / s.dt_s;
    }
  }
  return inc;
}

Status FusionEngine::prepare_imu(std::span<const ImuSample> imu) {
  if (imu.empty()) return make_error("nav::fuse(): no IMU samples");
  FusionReport& rep = traj_.report_;
  rep.imu_samples = imu.size();
  traj_.imu_.reserve(imu.size());
  for (std::size_t i = 0; i < imu.size(); ++i) {
    auto inc = make_increment(imu[i], i, cfg_, i ? &traj_.imu_.back() : nullptr, i ? imu[i - 1].t_ns : 0,
                              imu.size() > 1 ? imu[1].t_ns : 0, rep.imu_gaps);
    if (!inc) return inc.error();
    traj_.imu_.push_back(*inc);
  }
  return {};
}

std::optional<FusionEngine::Fix> FusionEngine::make_fix(const GpsFix& f, std::size_t index) {
  const GpsNoiseModel& n = cfg_.gps;
  const bool finite =
      std::isfinite(f.antenna.lat_rad) && std::isfinite(f.antenna.lon_rad) && std::isfinite(f.antenna.h_m);
  if (f.quality == FixQuality::kInvalid || f.quality == FixQuality::kDeadReckoning || !finite) {
    ++traj_.report_.fixes_invalid;
    return std::nullopt;
  }
  Fix x;
  x.t_ns = f.t_ns + cfg_.gps_time_offset_ns;
  x.index = index;
  x.p_ecef_m = ecef_from_geodetic(f.antenna);
  x.R_en = R_ecef_ned(f.antenna.lat_rad, f.antenna.lon_rad);
  if (n.use_gst && f.sigma_ned_m && f.sigma_ned_m->allFinite() && (f.sigma_ned_m->array() > 0).all()) {
    x.sigma_ned_m = *f.sigma_ned_m;
  } else {
    double h = n.single_m;
    switch (f.quality) {
      case FixQuality::kRtkFixed:
        h = n.rtk_fixed_m;
        break;
      case FixQuality::kRtkFloat:
        h = n.rtk_float_m;
        break;
      case FixQuality::kDgps:
      case FixQuality::kPps:
        h = n.dgps_m;
        break;
      default:
        break;
    }
    if (n.scale_by_hdop && f.hdop > 0) h *= f.hdop;
    x.sigma_ned_m = Vector3d(h, h, h * n.vertical_factor);
  }
  x.sigma_ned_m = x.sigma_ned_m.cwiseMax(n.floor_m);
  if (f.heading_rad && std::isfinite(*f.heading_rad)) x.heading_rad = *f.heading_rad;
  if (f.ground_speed_mps && f.course_rad && std::isfinite(*f.ground_speed_mps) &&
      std::isfinite(*f.course_rad))
    x.v_ne_mps = Eigen::Vector2d(*f.ground_speed_mps * std::cos(*f.course_rad),
                                 *f.ground_speed_mps * std::sin(*f.course_rad));
  return x;
}

Status FusionEngine::prepare_fixes(std::span<const GpsFix> fixes) {
  FusionReport& rep = traj_.report_;
  rep.fixes = fixes.size();
  const TimestampNs t_begin = traj_.imu_.front().t0_ns, t_end = traj_.imu_.back().t1_ns;
  fixes_.reserve(fixes.size());
  for (std::size_t i = 0; i < fixes.size(); ++i) {
    const GpsFix& f = fixes[i];
    if (i > 0 && f.t_ns <= fixes[i - 1].t_ns)
      return make_error("nav::fuse(): GPS fix ", i, " at t=", f.t_ns, " ns is not after fix ", i - 1,
                        " at t=", fixes[i - 1].t_ns, " ns; fix timestamps must be strictly increasing");
    std::optional<Fix> x = make_fix(f, i);
    if (!x) continue;
    if (x->t_ns < t_begin || x->t_ns > t_end) {
      ++rep.fixes_outside;
      continue;
    }
    fixes_.push_back(*x);
  }
  // The initialisation fix must leave IMU data after it.
  while (first_fix_ < fixes_.size() && fixes_[first_fix_].t_ns >= t_end) ++first_fix_;
  if (fixes_.empty() || first_fix_ >= fixes_.size())
    return make_error("nav::fuse(): no valid GPS fix inside the IMU data [", t_begin, ", ", t_end, "] ns (",
                      fixes.size(), " fixes, ", rep.fixes_invalid, " invalid, ", rep.fixes_outside,
                      " outside); check the time offsets");
  if (fixes_.size() > 1) {
    std::vector<TimestampNs> d(fixes_.size() - 1);
    for (std::size_t i = 1; i < fixes_.size(); ++i) d[i - 1] = fixes_[i].t_ns - fixes_[i - 1].t_ns;
    std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
    rep.nominal_fix_period_s = ns_to_s(d[d.size() / 2]);
  }
  return {};
}

Status FusionEngine::initialise() {
  const Fix& f0 = fixes_[first_fix_];
  const Geodetic g0 = geodetic_from_ecef(f0.p_ecef_m);
  const Matrix3d& R_en = f0.R_en;
  std::string how;

  // Velocity: from the first two fixes (mean velocity between them), else ground speed/course.
  // The velocity from two fixes shares the first fix's error with the position: cov(p, v) = -S0/dt.
  Vector3d v_ned = Vector3d::Zero();
  double sigma_v = cfg_.init_velocity_sigma_mps;
  Matrix3d P_vv_fix = Matrix3d::Zero(), P_pv_fix = Matrix3d::Zero();  // NED
  std::optional<std::size_t> second;
  if (first_fix_ + 1 < fixes_.size() && fixes_[first_fix_ + 1].t_ns - f0.t_ns <= s_to_ns(2.0))
    second = first_fix_ + 1;
  if (second) {
    const Fix& f1 = fixes_[*second];
    const double dt = ns_to_s(f1.t_ns - f0.t_ns);
    v_ned = R_en.transpose() * (f1.p_ecef_m - f0.p_ecef_m) / dt;
    const Vector3d s0 = f0.sigma_ned_m.cwiseAbs2(), s1 = f1.sigma_ned_m.cwiseAbs2();
    P_vv_fix = Matrix3d((s0 + s1).asDiagonal()) / (dt * dt);
    P_pv_fix = -Matrix3d(s0.asDiagonal()) / dt;
    how = "velocity from fixes " + std::to_string(f0.index) + "-" + std::to_string(f1.index);
  } else if (f0.v_ne_mps) {
    v_ned = Vector3d(f0.v_ne_mps->x(), f0.v_ne_mps->y(), 0.0);
    sigma_v = std::max(sigma_v, 2.0);
    how = "velocity from speed/course";
  } else {
    sigma_v = 10.0;
    how = "velocity unknown (0)";
  }
  const double speed_h = std::hypot(v_ned.x(), v_ned.y());
  const bool stationary = v_ned.norm() < cfg_.stationary_speed_mps && second.has_value();

  // Attitude.
  double yaw = 0, pitch = 0, roll = 0;
  double sigma_tilt = cfg_.init_tilt_sigma_rad, sigma_yaw = cfg_.init_yaw_unknown_sigma_rad;
  if (cfg_.use_heading && f0.heading_rad) {
    yaw = *f0.heading_rad - cfg_.heading_offset_rad;
    sigma_yaw = std::max(cfg_.heading_sigma_rad, deg_to_rad(0.05));
    how += ", yaw from HDT";
  } else if (speed_h > cfg_.min_ground_speed_mps) {
    yaw = std::atan2(v_ned.y(), v_ned.x());
    sigma_yaw = cfg_.init_yaw_from_course_sigma_rad;
    how += ", yaw from course";
  } else if (f0.v_ne_mps && f0.v_ne_mps->norm() > cfg_.min_ground_speed_mps) {
    yaw = std::atan2(f0.v_ne_mps->y(), f0.v_ne_mps->x());
    sigma_yaw = cfg_.init_yaw_from_course_sigma_rad;
    how += ", yaw from RMC course";
  } else {
    how += ", yaw unknown (0)";
  }
  // Mean body rate and specific force over [from, to).
  const auto& imu = traj_.imu_;
  auto mean_imu = [&](TimestampNs from, TimestampNs to, Vector3d& w_b, Vector3d& f_b) {
    Vector3d sum_th = Vector3d::Zero(), sum_dv = Vector3d::Zero();
    double sum_dt = 0;
    for (std::size_t i = 0; i < imu.size() && imu[i].t0_ns < to; ++i) {
      if (imu[i].t1_ns <= from) continue;
      sum_th += imu[i].dtheta_rad;
      sum_dv += imu[i].dv_mps;
      sum_dt += ns_to_s(imu[i].t1_ns - imu[i].t0_ns);
    }
    if (sum_dt <= 0) return false;
    w_b = sum_th / sum_dt;
    f_b = sum_dv / sum_dt;
    return true;
  };
  Vector3d w_b, f_b;
  if (stationary && mean_imu(f0.t_ns, f0.t_ns + s_to_ns(1.0), w_b, f_b)) {
    roll = std::atan2(-f_b.y(), -f_b.z());
    pitch = std::atan2(f_b.x(), std::hypot(f_b.y(), f_b.z()));
    sigma_tilt = cfg_.init_level_sigma_rad;
    how += ", roll/pitch levelled from the accelerometers (1 s)";
  } else if (!stationary && mean_imu(f0.t_ns, f0.t_ns + s_to_ns(0.2), w_b, f_b)) {
    // Pitch: the body x axis against the plane normal to the specific force, which in coordinated
    // flight at constant speed is the horizontal plane tilted about x by the bank.
    pitch = std::atan2(f_b.x(), std::hypot(f_b.y(), f_b.z()));
    how += ", pitch from the accelerometers";
    if (speed_h > cfg_.airborne_speed_mps) {
      // Roll from the coordinated-turn relation tan(roll) = V * turn rate / g, the turn rate being
      // the gyro rate projected on the vertical (which itself depends on the roll: iterate).
      for (int it = 0; it < 8; ++it) {
        const double sp = std::sin(pitch), cp = std::cos(pitch), sr = std::sin(roll), cr = std::cos(roll);
        const double turn_rate = -sp * w_b.x() + sr * cp * w_b.y() + cr * cp * w_b.z();
        roll = std::atan(speed_h * turn_rate / kG0);
      }
      sigma_tilt += 0.15 * std::abs(roll);  // wind: ground speed is not airspeed
      how += ", roll from the turn rate (coordinated turn)";
    } else {
      how += ", roll 0";
    }
  } else {
    how += ", roll/pitch 0";
  }

  InertialState x;
  x.t_ns = f0.t_ns;
  x.q_ecef_body = Quaterniond(R_en * rotation_from_ypr(yaw, pitch, roll)).normalized();
  x.p_ecef_m = f0.p_ecef_m - x.q_ecef_body * cfg_.lever_arm_body_m;
  x.v_ecef_mps = R_en * v_ned;

  // Initial covariance. The body position inherits the attitude error through the lever arm:
  // dp = dp_fix + [(R l) x] dtheta.
  P_.setZero();
  const Matrix3d M =
      euler_to_rotation_jacobian(yaw, pitch);  // small rotation in NED per (dyaw, dpitch, droll)
  const Vector3d se2(sigma_yaw * sigma_yaw, sigma_tilt * sigma_tilt, sigma_tilt * sigma_tilt);
  const Matrix3d P_att = R_en * M * se2.asDiagonal() * M.transpose() * R_en.transpose();
  const Matrix3d L = skew(x.q_ecef_body * cfg_.lever_arm_body_m);
  P_.block<3, 3>(kErrAtt, kErrAtt) = P_att;
  P_.block<3, 3>(kErrPos, kErrPos) =
      R_en * f0.sigma_ned_m.cwiseAbs2().asDiagonal() * R_en.transpose() + L * P_att * L.transpose();
  P_.block<3, 3>(kErrPos, kErrAtt) = L * P_att;
  P_.block<3, 3>(kErrAtt, kErrPos) = P_.block<3, 3>(kErrPos, kErrAtt).transpose();
  P_.block<3, 3>(kErrVel, kErrVel) =
      Matrix3d::Identity() * sigma_v * sigma_v + R_en * P_vv_fix * R_en.transpose();
  P_.block<3, 3>(kErrPos, kErrVel) = R_en * P_pv_fix * R_en.transpose();
  P_.block<3, 3>(kErrVel, kErrPos) = P_.block<3, 3>(kErrPos, kErrVel).transpose();
  P_.block<3, 3>(kErrGyroBias, kErrGyroBias) =
      Matrix3d::Identity() * cfg_.imu.gyro_bias.sigma * cfg_.imu.gyro_bias.sigma;
  P_.block<3, 3>(kErrAccelBias, kErrAccelBias) =
      Matrix3d::Identity() * cfg_.imu.accel_bias.sigma * cfg_.imu.accel_bias.sigma;
  if (clock_) {
    // The IMU clock: prior offset and drift 0. The first fix was valid at IMU time t0 + c, not t0,
    // so the body position put at t0 is off by -v dc (v the antenna's velocity, its rotation left
    // out): dp = -v dc, with the matching cross-covariance.
    const ImuClockModel& m = cfg_.imu_clock;
    const double s2 = m.offset_sigma_s * m.offset_sigma_s;
    Pc_ = {};
    Pc_.P_cc(0, 0) = s2;
    Pc_.P_cc(1, 1) = m.drift_sigma * m.drift_sigma;
    const Vector3d& v = x.v_ecef_mps;
    P_.block<3, 3>(kErrPos, kErrPos) += (s2 * v) * v.transpose();
    Pc_.P_xc.block<3, 1>(kErrPos, 0) = -s2 * v;
  }

  // The increment holding the data just after t0.
  imu_index_ = static_cast<std::size_t>(
      std::upper_bound(imu.begin(), imu.end(), x.t_ns,
                       [](TimestampNs t, const Increment& i) { return t < i.t1_ns; }) -
      imu.begin());
  mech_.reset(x);
  char buf[160];
  std::snprintf(buf, sizeof buf,
                "at t=%lld ns from fix %zu (lat %.7f, lon %.7f deg): ", static_cast<long long>(x.t_ns),
                f0.index, rad_to_deg(g0.lat_rad), rad_to_deg(g0.lon_rad));
  traj_.report_.init_summary = buf + how;
  return {};
}

namespace {

// One covariance step of length T over which the strapdown accumulated sum(R_ecef_body dt) and
// sum(dv_ecef): P <- Phi P Phi^T + Q with the first-order error model (docs/NAV_FUSION.md) and a
// second-order Phi; the transition is also multiplied into *Phi_acc when given. With `clock` (the
// IMU clock estimated) its blocks too: offset' = drift, and since the strapdown integrates over
// GPS time (Strapdown::step), a drift error dd moves the position by -v dd and the velocity by
// -(g - 2 w_ie x v) dd per second; the transition is [Phi B; 0 C], C = [1 T; 0 1], and B (15x2) is
// accumulated into *Phi_xc_acc when given (the epoch's: B_acc <- Phi B_acc + B, B's offset column
// being 0).
void covariance_step(const InsConfig& cfg, const Vector3d& p_ecef_m, const Vector3d& v_ecef_mps,
                     const Matrix3d& sum_R_dt, const Vector3d& sum_dv_e, double T, Matrix15d& P,
                     Matrix15d* Phi_acc, ImuClockCovariance* clock = nullptr,
                     Eigen::Matrix<double, 15, 2>* Phi_xc_acc = nullptr) {
  const Matrix3d Rbar = sum_R_dt / T;
  const Vector3d fbar = sum_dv_e / T;
  const Matrix3d W = skew(earth_rate_ecef());
  const BiasModel& bg = cfg.imu.gyro_bias;
  const BiasModel& ba = cfg.imu.accel_bias;

  Matrix15d FT = Matrix15d::Zero();
  FT.block<3, 3>(kErrPos, kErrVel).diagonal().setConstant(T);
  FT.block<3, 3>(kErrVel, kErrPos) = gravity_gradient_ecef(p_ecef_m) * T;
  FT.block<3, 3>(kErrVel, kErrVel) = -2.0 * T * W;
  FT.block<3, 3>(kErrVel, kErrAtt) = -T * skew(fbar);
  FT.block<3, 3>(kErrVel, kErrAccelBias) = -T * Rbar;
  FT.block<3, 3>(kErrAtt, kErrAtt) = -T * W;
  FT.block<3, 3>(kErrAtt, kErrGyroBias) = -T * Rbar;
  if (bg.tau_s > 0) FT.block<3, 3>(kErrGyroBias, kErrGyroBias).diagonal().setConstant(-T / bg.tau_s);
  if (ba.tau_s > 0) FT.block<3, 3>(kErrAccelBias, kErrAccelBias).diagonal().setConstant(-T / ba.tau_s);
  Matrix15d Phi = Matrix15d::Identity() + FT;
  Phi.noalias() += 0.5 * FT * FT;

  // Half the process noise before the transition, half after (trapezoid).
  auto bias_q = [](const BiasModel& b) {
    return b.tau_s > 0 ? 2.0 * b.sigma * b.sigma / b.tau_s : b.random_walk * b.random_walk;
  };
  Vector15d q;
  q.segment<3>(kErrPos).setZero();
  q.segment<3>(kErrVel).setConstant(cfg.imu.accel_vrw_mps_psqrts * cfg.imu.accel_vrw_mps_psqrts);
  q.segment<3>(kErrAtt).setConstant(cfg.imu.gyro_arw_rad_psqrts * cfg.imu.gyro_arw_rad_psqrts);
  q.segment<3>(kErrGyroBias).setConstant(bias_q(bg));
  q.segment<3>(kErrAccelBias).setConstant(bias_q(ba));
  q *= 0.5 * T;
  P.diagonal() += q;
  Matrix15d tmp;
  tmp.noalias() = Phi * P;
  P.noalias() = tmp * Phi.transpose();
  if (clock) {
    using Matrix15x2 = Eigen::Matrix<double, 15, 2>;
    Matrix15x2 FTxc = Matrix15x2::Zero();
    FTxc.block<3, 1>(kErrPos, 1) = -T * v_ecef_mps;
    FTxc.block<3, 1>(kErrVel, 1) = -T * (gravity_ecef(p_ecef_m) - 2.0 * earth_rate_ecef().cross(v_ecef_mps));
    Matrix15x2 B = FTxc;
    B.noalias() += 0.5 * FT * FTxc;
    const ImuClockModel& m = cfg.imu_clock;
    const Eigen::Vector2d qc = 0.5 * T *
                               Eigen::Vector2d(m.offset_random_walk_s_psqrts * m.offset_random_walk_s_psqrts,
                                               m.drift_random_walk_psqrts * m.drift_random_walk_psqrts);
    Eigen::Matrix2d& Pcc = clock->P_cc;
    Pcc.diagonal() += qc;
    Matrix15x2 APxc;
    APxc.noalias() = Phi * clock->P_xc;
    // P <- Phi P Phi^T + Phi Pxc B^T + B Pxc^T Phi^T + B Pcc B^T
    tmp.noalias() = APxc * B.transpose();
    P += tmp + tmp.transpose();
    P.noalias() += B * Pcc * B.transpose();
    // Pxc <- (Phi Pxc + B Pcc) C^T, Pcc <- C Pcc C^T
    Matrix15x2 Pxc = APxc;
    Pxc.noalias() += B * Pcc;
    Pxc.col(0) += T * Pxc.col(1);
    clock->P_xc = Pxc;
    Eigen::Matrix2d C;
    C << 1.0, T, 0.0, 1.0;
    Pcc = (C * Pcc * C.transpose()).eval();
    Pcc.diagonal() += qc;
    if (Phi_xc_acc) {
      Matrix15x2 acc = B;
      acc.noalias() += Phi * *Phi_xc_acc;
      *Phi_xc_acc = acc;
    }
  }
  P.diagonal() += q;
  if (Phi_acc) {
    tmp.noalias() = Phi * *Phi_acc;
    *Phi_acc = tmp;
  }
}

}  // namespace

void FusionEngine::propagate_covariance() {
  if (step_dt_ <= 0) return;
  covariance_step(cfg_, mech_.state().p_ecef_m, mech_.state().v_ecef_mps, sum_R_dt_, sum_dv_e_, step_dt_, P_,
                  &Phi_epoch_, clock_ ? &Pc_ : nullptr, clock_ ? &Phi_xc_epoch_ : nullptr);
  sum_R_dt_.setZero();
  sum_dv_e_.setZero();
  step_dt_ = 0;
}

template <int M>
bool FusionEngine::kalman_update(const Eigen::Matrix<double, M, 1>& y, const Eigen::Matrix<double, M, 15>& H,
                                 const Eigen::Matrix<double, M, M>& R, double gate, bool force, double* nis,
                                 const Eigen::Matrix<double, M, 2>* Hc) {
  if (!clock_) {
    Vector15d dx;
    if (!ekf_update<15, M>(P_, y, H, R, gate, force, nis, dx)) return false;
    mech_.state() = boxplus(mech_.state(), dx);
    return true;
  }
  // With the clock states: the same update over all 17.
  Matrix17d P = assemble(P_, Pc_);
  Eigen::Matrix<double, M, 17> H17 = Eigen::Matrix<double, M, 17>::Zero();
  H17.template leftCols<15>() = H;
  if (Hc) H17.template rightCols<2>() = *Hc;
  Vector17d dx;
  if (!ekf_update<17, M>(P, y, H17, R, gate, force, nis, dx)) return false;
  split(P, P_, Pc_);
  InertialState& x = mech_.state();
  x = boxplus(x, dx.head<15>());
  clock_boxplus(x, dx(kErrClock), dx(kErrClock + 1));
  return true;
}

void FusionEngine::update_at_fix(const Fix& fix) {
  FusionReport& rep = traj_.report_;
  InertialState& x = mech_.state();
  const Matrix3d R_eb = x.q_ecef_body.toRotationMatrix();
  const Vector3d l_e = R_eb * cfg_.lever_arm_body_m;
  // With the IMU clock estimated (docs/NAV_FUSION.md, "IMU clock"): the fix was valid at IMU-clock
  // time t_gps + c, the filter is at t (the same but for ns rounding, or a clamp), so each
  // measurement is predicted dt_fix = t_gps + c^ - t ahead along its rate, and its sensitivity to
  // an offset error dc (truth c^ + dc) is that rate: p_fix = p_ant(t_gps + c^ + dc) ~ p_ant(t) +
  // v_ant (dt_fix + dc).
  double dt_fix = 0;
  Vector3d w_ib_b = Vector3d::Zero(), v_antenna = Vector3d::Zero();
  if (clock_) {
    dt_fix = ns_to_s(fix.t_ns - x.t_ns) + x.imu_clock_offset_s;
    const Strapdown::History& h = mech_.history();
    if (h.dt_s > 0) w_ib_b = h.dtheta_rad / h.dt_s;
    v_antenna = x.v_ecef_mps + R_eb * w_ib_b.cross(cfg_.lever_arm_body_m) - earth_rate_ecef().cross(l_e);
  }

  // Position of the antenna.
  {
    Vector3d y = fix.p_ecef_m - (x.p_ecef_m + l_e);
    Eigen::Matrix<double, 3, 15> H = Eigen::Matrix<double, 3, 15>::Zero();
    H.block<3, 3>(0, kErrPos).setIdentity();
    H.block<3, 3>(0, kErrAtt) = -skew(l_e);
    Eigen::Matrix<double, 3, 2> Hc = Eigen::Matrix<double, 3, 2>::Zero();
    if (clock_) {
      y -= v_antenna * dt_fix;
      Hc.col(0) = v_antenna;
    }
    const Matrix3d R = fix.R_en * fix.sigma_ned_m.cwiseAbs2().asDiagonal() * fix.R_en.transpose();
    // No gating while the filter is still levelling itself (tilt 1-sigma above the threshold): its
    // innovations are not yet trustworthy enough to call a fix an outlier.
    const Matrix3d P_att_n = fix.R_en.transpose() * P_.block<3, 3>(kErrAtt, kErrAtt) * fix.R_en;
    const bool converged =
        std::max(P_att_n(0, 0), P_att_n(1, 1)) < cfg_.gate_tilt_sigma_rad * cfg_.gate_tilt_sigma_rad;
    const bool force = !converged || rejection_streak_ >= cfg_.max_consecutive_rejections;
    double nis = -1;
    const bool used = kalman_update<3>(y, H, R, cfg_.gate_chi2, force, &nis, &Hc);
    if (nis >= 0) note_innovation(fix.t_ns, nis, used, converged);
    if (used) {
      ++rep.fixes_used;
      if (force && converged) ++rep.fixes_forced;
      rejection_streak_ = 0;
    } else {
      ++rep.fixes_rejected;
      ++rejection_streak_;
      return;  // a rejected position discredits the rest of the epoch
    }
  }

  // HDT heading of the body x axis.
  if (cfg_.use_heading && fix.heading_rad) {
    const Matrix3d& R_en = fix.R_en;
    const Vector3d c = R_en.transpose() * (x.q_ecef_body * Vector3d::UnitX());
    const double n2 = c.x() * c.x() + c.y() * c.y();
    if (n2 > 1e-6) {
      const Eigen::RowVector3d gvec(-c.y() / n2, c.x() / n2, 0.0);
      Eigen::Matrix<double, 1, 15> H = Eigen::Matrix<double, 1, 15>::Zero();
      H.block<1, 3>(0, kErrAtt) = -gvec * skew(c) * R_en.transpose();
      Eigen::Matrix<double, 1, 1> y, R;
      y(0) = wrap_pi(*fix.heading_rad - cfg_.heading_offset_rad - std::atan2(c.y(), c.x()));
      R(0) = cfg_.heading_sigma_rad * cfg_.heading_sigma_rad;
      Eigen::Matrix<double, 1, 2> Hc = Eigen::Matrix<double, 1, 2>::Zero();
      if (clock_) {
        // The heading's rate: the x axis turning at the body rate w.r.t. the Earth.
        const Vector3d w_eb = w_ib_b - x.q_ecef_body.conjugate() * earth_rate_ecef();
        const Vector3d c_dot = R_en.transpose() * (x.q_ecef_body * w_eb.cross(Vector3d::UnitX()));
        const double yaw_rate = (gvec * c_dot).value();
        dt_fix = ns_to_s(fix.t_ns - x.t_ns) + x.imu_clock_offset_s;  // the position update moved c^
        y(0) -= yaw_rate * dt_fix;
        Hc(0, 0) = yaw_rate;
      }
      if (kalman_update<1>(y, H, R, cfg_.heading_gate_chi2, false, nullptr, &Hc))
        ++rep.heading_updates;
      else
        ++rep.heading_rejected;
    }
  }

  // Speed over ground and course: horizontal velocity of the antenna.
  if (cfg_.use_ground_velocity && fix.v_ne_mps && fix.v_ne_mps->norm() > cfg_.min_ground_speed_mps) {
    const Strapdown::History& h = mech_.history();
    const Vector3d w_b = h.dt_s > 0 ? Vector3d(h.dtheta_rad / h.dt_s) : Vector3d::Zero();
    const Matrix3d Rb = x.q_ecef_body.toRotationMatrix();
    const Vector3d le = Rb * cfg_.lever_arm_body_m;
    const Vector3d wl = Rb * w_b.cross(cfg_.lever_arm_body_m);
    const Vector3d W = earth_rate_ecef();
    const Vector3d v_ant = x.v_ecef_mps + wl - W.cross(le);
    const Eigen::Matrix<double, 2, 3> Rne = fix.R_en.transpose().topRows<2>();
    Eigen::Matrix<double, 2, 15> H = Eigen::Matrix<double, 2, 15>::Zero();
    H.block<2, 3>(0, kErrVel) = Rne;
    H.block<2, 3>(0, kErrAtt) = Rne * (-skew(wl) + skew(W) * skew(le));
    Eigen::Vector2d y = *fix.v_ne_mps - Rne * v_ant;
    const double s2 = cfg_.ground_velocity_sigma_mps * cfg_.ground_velocity_sigma_mps;
    const Eigen::Matrix2d R = Eigen::Matrix2d::Identity() * s2;
    Eigen::Matrix<double, 2, 2> Hc = Eigen::Matrix<double, 2, 2>::Zero();
    if (clock_ && h.dt_s > 0) {
      // The velocity's rate: the body's acceleration (specific force + gravity - Coriolis; the lever
      // arm's angular acceleration left out).
      const Vector3d a_e = Rb * (h.dv_mps / h.dt_s) + gravity_ecef(x.p_ecef_m) - 2.0 * W.cross(x.v_ecef_mps);
      const Eigen::Vector2d a_ne = Rne * a_e;
      dt_fix = ns_to_s(fix.t_ns - x.t_ns) + x.imu_clock_offset_s;
      y -= a_ne * dt_fix;
      Hc.col(0) = a_ne;
    }
    if (kalman_update<2>(y, H, R, cfg_.ground_velocity_gate_chi2, false, nullptr, &Hc))
      ++rep.velocity_updates;
    else
      ++rep.velocity_rejected;
  }
}

void FusionEngine::store_epoch() {
  traj_.epochs_.push_back({mech_.state(), mech_.history(), imu_index_, 0});
  traj_.P_.push_back(P_);
  if (clock_) traj_.clock_P_.push_back(Pc_);
  traj_.set_gps_time(traj_.epochs_.size() - 1);
  note_convergence();
}

void FusionEngine::note_convergence() {
  FusionReport& rep = traj_.report_;
  if (rep.converged || !(cfg_.convergence_window_s > 0)) return;
  NavState s;
  static_cast<InertialState&>(s) = mech_.state();
  s.P = P_;
  const Vector3d sigma = to_solution(s).sigma_ypr_rad;
  const TimestampNs t = s.t_ns, window = s_to_ns(cfg_.convergence_window_s);
  attitude_sigmas_.emplace_back(t, sigma);
  // The oldest kept is the newest at least a window old.
  while (attitude_sigmas_.size() > 1 && t - attitude_sigmas_[1].first >= window) attitude_sigmas_.pop_front();
  const auto& [t_old, sigma_old] = attitude_sigmas_.front();
  if (t - t_old < window) return;
  for (int i = 0; i < 3; ++i)
    if (sigma[i] < (1.0 - cfg_.convergence_sigma_drop) * sigma_old[i]) return;
  rep.converged = true;
  rep.converged_ns = traj_.epochs_.back().t_gps_ns;
  attitude_sigmas_.clear();
}

void FusionEngine::note_clock(std::size_t k) {
  FusionReport& rep = traj_.report_;
  const InertialState& x = traj_.epochs_[k].x;
  const Eigen::Matrix2d& C = traj_.clock_P_[k].P_cc;
  rep.imu_clock_estimated = true;
  rep.imu_clock_t_ns = traj_.epochs_[k].t_gps_ns;
  rep.imu_clock_offset_s = x.imu_clock_offset_s;
  rep.imu_clock_offset_sigma_s = std::sqrt(std::max(C(0, 0), 0.0));
  rep.imu_clock_drift_s_per_s = x.imu_clock_drift_s_per_s;
  rep.imu_clock_drift_sigma = std::sqrt(std::max(C(1, 1), 0.0));
}

TimestampNs FusionEngine::fix_time(const Fix& f, bool clamp) const {
  if (!clock_) return f.t_ns;
  const InertialState& x = mech_.state();
  const TimestampNs t = NavTrajectory::imu_time(x, f.t_ns);
  return clamp ? std::max(t, x.t_ns + 1) : t;
}

void FusionEngine::note_fix_gap(TimestampNs t_ns) {
  FusionReport& rep = traj_.report_;
  const double gap = ns_to_s(t_ns - t_last_used_);
  rep.longest_fix_gap_s = std::max(rep.longest_fix_gap_s, gap);
  if (rep.nominal_fix_period_s > 0 && gap > cfg_.outage_factor * rep.nominal_fix_period_s) ++rep.outages;
  t_last_used_ = t_ns;
}

void FusionEngine::note_innovation(TimestampNs t_ns, double nis, bool used, bool gated) {
  if (keep_innovations_) traj_.innovations_.push_back({t_ns, nis, used, gated});
}

void FusionEngine::filter_to(TimestampNs t_end, bool batch) {
  FusionReport& rep = traj_.report_;
  const TimestampNs max_epoch_ns = s_to_ns(std::max(cfg_.max_epoch_interval_s, 1e-3));
  const double cov_step = cfg_.covariance_step_s;
  auto on_step = [&](double dt) {
    sum_R_dt_ += mech_.last_R_ecef_body() * dt;
    sum_dv_e_ += mech_.last_dv_ecef();
    step_dt_ += dt;
    if (step_dt_ >= cov_step) propagate_covariance();
  };
  while (mech_.state().t_ns < t_end) {
    // The batch ends with a partial epoch at the end of the data; in real time only whole epochs
    // are run, so that the epochs (and every number) are the batch filter's.
    TimestampNs target = t_epoch_ + max_epoch_ns;
    if (batch) target = std::min(target, t_end);
    const Fix* fix = nullptr;
    if (next_fix_ < fixes_.size()) {
      const TimestampNs t_fix = fix_time(fixes_[next_fix_], true);
      // With the IMU clock estimated a fix moves with the estimate: one a little past the longest
      // epoch interval is taken as it is, not after a coasting epoch just before it (in real time
      // the filter waits for the data to reach it, as the batch would take it).
      const bool stretch = clock_ && t_fix <= target + max_epoch_ns / 2 && (!batch || t_fix <= t_end);
      if (t_fix <= target || stretch) {
        fix = &fixes_[next_fix_];
        target = t_fix;
      }
    }
    if (target > t_end) break;
    if (fix) ++next_fix_;
    NavTrajectory::advance(traj_.imu_, mech_, imu_index_, target, on_step);
    propagate_covariance();
    if (batch) {  // the smoother's inputs
      x_pred_.push_back(mech_.state());
      P_pred_.push_back(P_);
      if (clock_) {
        Pc_pred_.push_back(Pc_);
        Phi_xc_.push_back(Phi_xc_epoch_);
      }
      Phi_.push_back(Phi_epoch_);
    }
    Phi_epoch_.setIdentity();
    if (clock_) Phi_xc_epoch_.setZero();
    if (fix) {
      const std::size_t used = rep.fixes_used;
      update_at_fix(*fix);
      if (rep.fixes_used > used) note_fix_gap(target);
    }
    store_epoch();
    t_epoch_ = target;
  }
}

void FusionEngine::forward() {
  const auto t0 = std::chrono::steady_clock::now();
  FusionReport& rep = traj_.report_;
  const TimestampNs t_end = traj_.imu_.back().t1_ns;
  const TimestampNs max_epoch_ns = s_to_ns(std::max(cfg_.max_epoch_interval_s, 1e-3));

  // Reserve for every fix and coasting epoch up front, so the loop does not reallocate.
  const TimestampNs span = t_end - mech_.state().t_ns;
  const std::size_t n_est = static_cast<std::size_t>(span / max_epoch_ns) + fixes_.size() + 2;
  traj_.epochs_.reserve(n_est);
  traj_.P_.reserve(n_est);
  x_pred_.reserve(n_est);
  P_pred_.reserve(n_est);
  Phi_.reserve(n_est);
  if (clock_) {
    traj_.clock_P_.reserve(n_est);
    Pc_pred_.reserve(n_est);
    Phi_xc_.reserve(n_est);
  }

  store_epoch();
  x_pred_.push_back(mech_.state());
  P_pred_.push_back(P_);
  if (clock_) {
    Pc_pred_.push_back(Pc_);
    Phi_xc_.push_back(Eigen::Matrix<double, 15, 2>::Zero());
  }
  Phi_.push_back(Matrix15d::Identity());
  ++rep.fixes_used;  // the initialisation fix
  t_last_used_ = t_epoch_ = mech_.state().t_ns;
  next_fix_ = first_fix_ + 1;
  filter_to(t_end, true);
  if (rep.nominal_fix_period_s > 0 &&
      ns_to_s(t_end - t_last_used_) > cfg_.outage_factor * rep.nominal_fix_period_s) {
    ++rep.outages;  // no fix until the end of the data
    rep.longest_fix_gap_s = std::max(rep.longest_fix_gap_s, ns_to_s(t_end - t_last_used_));
  }
  rep.fixes_outside += fixes_.size() - next_fix_ + first_fix_;  // fixes before the first one used, none after
  rep.epochs = traj_.epochs_.size();
  rep.innovations = innovation_stats(traj_.innovations_);
  rep.forward_s = seconds_since(t0);
}

void FusionEngine::smooth() {
  const auto t0 = std::chrono::steady_clock::now();
  auto& ep = traj_.epochs_;
  auto& P = traj_.P_;
  if (clock_) {
    // The same over the 17 states: the epoch transition is [Phi B; 0 [1 dt; 0 1]].
    auto& Pc = traj_.clock_P_;
    Matrix17d Phi, A, C, Pk, Pp, tmp;
    for (std::size_t k = ep.size() - 1; k-- > 0;) {
      Pp = assemble(P_pred_[k + 1], Pc_pred_[k + 1]);
      Pk = assemble(P[k], Pc[k]);
      Phi.setIdentity();
      Phi.topLeftCorner<15, 15>() = Phi_[k + 1];
      Phi.topRightCorner<15, 2>() = Phi_xc_[k + 1];
      Phi(kErrClock, kErrClock + 1) = ns_to_s(ep[k + 1].x.t_ns - ep[k].x.t_ns);
      A.noalias() = Phi * Pk;
      Eigen::LLT<Matrix17d> llt(Pp);
      if (llt.info() == Eigen::Success) {
        C = llt.solve(A).transpose();
      } else {
        C = Pp.ldlt().solve(A).transpose();
      }
      const InertialState& xs = ep[k + 1].x;
      const InertialState& xp = x_pred_[k + 1];
      Vector17d dx;
      dx.head<15>() = boxminus(xs, xp);
      dx(kErrClock) = xs.imu_clock_offset_s - xp.imu_clock_offset_s;
      dx(kErrClock + 1) = xs.imu_clock_drift_s_per_s - xp.imu_clock_drift_s_per_s;
      const Vector17d d = C * dx;
      ep[k].x = boxplus(ep[k].x, d.head<15>());
      clock_boxplus(ep[k].x, d(kErrClock), d(kErrClock + 1));
      tmp.noalias() = C * (assemble(P[k + 1], Pc[k + 1]) - Pp);
      Pk.noalias() += tmp * C.transpose();
      split(Pk, P[k], Pc[k]);
    }
    for (std::size_t k = 0; k < ep.size(); ++k) traj_.set_gps_time(k);  // by the smoothed clock
    traj_.report_.smoothed = true;
    traj_.report_.smoother_s = seconds_since(t0);
    return;
  }
  Matrix15d A, C, D, tmp;
  for (std::size_t k = ep.size() - 1; k-- > 0;) {
    const Matrix15d& Pp = P_pred_[k + 1];
    A.noalias() = Phi_[k + 1] * P[k];  // = (P_post Phi^T)^T
    Eigen::LLT<Matrix15d> llt(Pp);
    if (llt.info() == Eigen::Success) {
      C = llt.solve(A).transpose();
    } else {
      C = Pp.ldlt().solve(A).transpose();
    }
    const Vector15d dx = boxminus(ep[k + 1].x, x_pred_[k + 1]);
    ep[k].x = boxplus(ep[k].x, C * dx);
    D = P[k + 1] - Pp;
    tmp.noalias() = C * D;
    P[k].noalias() += tmp * C.transpose();
  }
  traj_.report_.smoothed = true;
  traj_.report_.smoother_s = seconds_since(t0);
}

Expected<NavTrajectory> FusionEngine::run(std::span<const ImuSample> imu, std::span<const GpsFix> fixes,
                                          bool do_smooth) {
  keep_innovations_ = true;
  traj_.config_ = cfg_;
  if (Status s = prepare_imu(imu); !s) return s.error();
  if (Status s = prepare_fixes(fixes); !s) return s.error();
  if (Status s = initialise(); !s) return s.error();
  forward();
  if (do_smooth && traj_.epochs_.size() > 1) smooth();
  // The clock: smoothed, best known at the start (as at every epoch); forward only, at the end.
  if (clock_) note_clock(traj_.report_.smoothed ? 0 : traj_.epochs_.size() - 1);
  // Only the posterior (or smoothed) states are needed from here on.
  x_pred_ = {};
  P_pred_ = {};
  Pc_pred_ = {};
  Phi_xc_ = {};
  Phi_ = {};
  return std::move(traj_);
}

// ---------------------------------------------------------------------------------------------
// The same filter in real time (nav/live_fusion.hpp drives it)

Status FusionEngine::append_imu(const ImuSample& s) {
  std::vector<Increment>& imu = traj_.imu_;
  auto inc =
      make_increment(s, imu_seen_, cfg_, imu.empty() ? nullptr : &imu.back(),
                     imu.empty() ? 0 : imu.back().t1_ns - cfg_.imu_time_offset_ns, 0, traj_.report_.imu_gaps);
  if (!inc) return inc.error();
  imu.push_back(*inc);
  ++imu_seen_;
  ++traj_.report_.imu_samples;
  return {};
}

Status FusionEngine::append_fix(const GpsFix& f) {
  FusionReport& rep = traj_.report_;
  const std::size_t index = fixes_seen_++;
  ++rep.fixes;
  std::optional<Fix> x = make_fix(f, index);
  if (!x) return {};
  if (!fixes_.empty() && x->t_ns <= fixes_.back().t_ns)
    return make_error("nav::LiveFusion: GPS fix ", index, " at t=", f.t_ns,
                      " ns is not after the previous fix");
  if (initialised_ && fix_time(*x, false) <= mech_.state().t_ns) {
    ++rep.fixes_outside;  // the filter is past it: too late to use
    return make_error("nav::LiveFusion: GPS fix ", index, " at t=", f.t_ns,
                      " ns arrived after the filter passed ", mech_.state().t_ns, " ns");
  }
  fixes_.push_back(*x);
  // The nominal fix period from the spacing seen so far (for outage detection).
  if (fixes_.size() >= 2) {
    const double d = ns_to_s(fixes_.back().t_ns - fixes_[fixes_.size() - 2].t_ns);
    if (rep.nominal_fix_period_s <= 0 || d < rep.nominal_fix_period_s) rep.nominal_fix_period_s = d;
  }
  return {};
}

bool FusionEngine::try_initialise() {
  if (initialised_) return true;
  const std::vector<Increment>& imu = traj_.imu_;
  if (imu.empty() || fixes_.empty()) return false;
  // A fix before the IMU data cannot start the filter.
  while (!fixes_.empty() && fixes_.front().t_ns < imu.front().t0_ns) {
    fixes_.erase(fixes_.begin());
    ++traj_.report_.fixes_outside;
  }
  if (fixes_.empty()) return false;
  const TimestampNs t0 = fixes_.front().t_ns, t_imu = imu.back().t1_ns;
  if (t_imu < t0 + s_to_ns(1.0)) return false;                       // levelling needs 1 s after it
  if (fixes_.size() < 2 && t_imu < t0 + s_to_ns(2.0)) return false;  // wait for a second fix
  first_fix_ = 0;
  if (!initialise()) return false;
  store_epoch();
  ++traj_.report_.fixes_used;  // the initialisation fix
  t_last_used_ = t_epoch_ = mech_.state().t_ns;
  next_fix_ = 1;
  initialised_ = true;
  return true;
}

void FusionEngine::advance_to(TimestampNs t_ns) {
  if (!initialised_) return;
  // Not into the newest increment: the strapdown splits an increment using its successor's rate.
  filter_to(std::min(t_ns, traj_.imu_.back().t0_ns), false);
  traj_.report_.epochs = traj_.epochs_.size();
  if (clock_) note_clock(traj_.epochs_.size() - 1);
}

NavState FusionEngine::current() const {
  NavState s;
  static_cast<InertialState&>(s) = mech_.state();
  s.P = P_;
  s.clock = Pc_;
  return s;
}

Expected<NavState> FusionEngine::at(TimestampNs t_ns, TimestampNs max_extrapolation_ns) const {
  const auto& epochs = traj_.epochs_;
  if (!initialised_ || epochs.empty()) return make_error("nav::LiveFusion::at(): not initialised yet");
  if (t_ns < epochs.front().t_gps_ns)
    return make_error("nav::LiveFusion::at(): t=", t_ns, " ns is older than the kept history (from ",
                      epochs.front().t_gps_ns, " ns)");
  const std::size_t k = traj_.epoch_before(t_ns);
  const NavTrajectory::Epoch& e = epochs[k];
  // The query on the IMU clock (by the epoch's estimate of it; t_ns itself without the clock states).
  const TimestampNs t_q = clock_ ? std::max(NavTrajectory::query_time(e, t_ns), e.x.t_ns) : t_ns;
  const TimestampNs t_imu = imu_end_ns();
  if (t_q > t_imu + max_extrapolation_ns)
    return make_error("nav::LiveFusion::at(): t=", t_ns, " ns is ", ns_to_s(t_q - t_imu),
                      " s past the last IMU sample (at most ", ns_to_s(max_extrapolation_ns), " s)");
  Strapdown mech(e.x, e.history);
  std::size_t index = e.imu_index;
  NavState s;
  s.P = traj_.P_[k];
  if (clock_) s.clock = traj_.clock_P_[k];
  ImuClockCovariance* clock = clock_ ? &s.clock : nullptr;
  Matrix3d sum_R = Matrix3d::Zero();
  Vector3d sum_dv = Vector3d::Zero();
  double T = 0;
  auto on_step = [&](double dt) {
    sum_R += mech.last_R_ecef_body() * dt;
    sum_dv += mech.last_dv_ecef();
    T += dt;
    if (T >= cfg_.covariance_step_s) {
      covariance_step(cfg_, mech.state().p_ecef_m, mech.state().v_ecef_mps, sum_R, sum_dv, T, s.P, nullptr,
                      clock);
      sum_R.setZero();
      sum_dv.setZero();
      T = 0;
    }
  };
  NavTrajectory::advance(traj_.imu_, mech, index, std::min(t_q, t_imu), on_step);
  if (t_q > t_imu) {
    // Past the data: the last increment's rates held.
    const Increment& last = traj_.imu_.back();
    const double r = ns_to_s(t_q - t_imu) / ns_to_s(last.t1_ns - last.t0_ns);
    mech.step(last.dtheta_rad * r, last.dv_mps * r, t_q);
    on_step(ns_to_s(t_q - t_imu));
  }
  if (T > 0)
    covariance_step(cfg_, mech.state().p_ecef_m, mech.state().v_ecef_mps, sum_R, sum_dv, T, s.P, nullptr,
                    clock);
  static_cast<InertialState&>(s) = mech.state();
  s.t_ns = t_ns;
  if (clock_) covariance_at_gps_time(s, mech.history());
  return s;
}

void FusionEngine::trim_before(TimestampNs t_ns) {
  if (!initialised_) {
    // Before the filter starts only the IMU data a first fix at or after t_ns needs are kept.
    auto& imu = traj_.imu_;
    const auto end =
        std::find_if(imu.begin(), imu.end(), [&](const Increment& i) { return i.t1_ns >= t_ns; });
    imu.erase(imu.begin(), end);
    fixes_.erase(fixes_.begin(),
                 std::find_if(fixes_.begin(), fixes_.end(), [&](const Fix& f) { return f.t_ns >= t_ns; }));
    return;
  }
  auto& epochs = traj_.epochs_;
  // Keep the last epoch at or before t_ns (queries at t_ns start there) and the increment before its
  // IMU index (piece() looks at the neighbours).
  const auto it = std::upper_bound(epochs.begin(), epochs.end(), t_ns,
                                   [](TimestampNs t, const NavTrajectory::Epoch& e) { return t < e.x.t_ns; });
  if (it - epochs.begin() < 2) return;
  const std::size_t k = static_cast<std::size_t>(it - epochs.begin()) - 1;
  const std::size_t drop_imu =
      std::min(epochs[k].imu_index, imu_index_) > 0 ? std::min(epochs[k].imu_index, imu_index_) - 1 : 0;
  epochs.erase(epochs.begin(), epochs.begin() + static_cast<std::ptrdiff_t>(k));
  traj_.P_.erase(traj_.P_.begin(), traj_.P_.begin() + static_cast<std::ptrdiff_t>(k));
  if (clock_)
    traj_.clock_P_.erase(traj_.clock_P_.begin(), traj_.clock_P_.begin() + static_cast<std::ptrdiff_t>(k));
  if (drop_imu) {
    traj_.imu_.erase(traj_.imu_.begin(), traj_.imu_.begin() + static_cast<std::ptrdiff_t>(drop_imu));
    for (auto& e : epochs) e.imu_index -= drop_imu;
    imu_index_ -= drop_imu;
  }
  // Fixes already processed are no longer needed.
  if (next_fix_ > 1) {
    const std::size_t n = next_fix_ - 1;  // keep the last processed one (for append_fix's order check)
    fixes_.erase(fixes_.begin(), fixes_.begin() + static_cast<std::ptrdiff_t>(n));
    next_fix_ -= n;
  }
}

Expected<NavTrajectory> fuse(std::span<const ImuSample> imu, std::span<const GpsFix> fixes,
                             const InsConfig& config, bool smooth) {
  FusionEngine engine(config);
  return engine.run(imu, fixes, smooth);
}

// ---------------------------------------------------------------------------------------------
// Queries and output

InnovationStats innovation_stats(std::span<const FixInnovation> innovations) {
  InnovationStats s;
  s.count = innovations.size();
  if (s.count == 0) return s;
  std::vector<double> v;
  v.reserve(s.count);
  double sum = 0;
  std::size_t within = 0;
  for (const FixInnovation& i : innovations) {
    v.push_back(i.nis);
    sum += i.nis;
    within += i.nis <= kNis95_3Dof ? 1 : 0;
  }
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  double median = v[mid];
  if (v.size() % 2 == 0) median = 0.5 * (median + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid)));
  s.mean_nis = sum / static_cast<double>(s.count);
  s.median_nis = median;
  s.within_95 = static_cast<double>(within) / static_cast<double>(s.count);
  s.scale = std::sqrt(median / kNisMedian3Dof);
  return s;
}

TimestampNs NavTrajectory::gps_time(const InertialState& x) {
  return x.t_ns - std::llround(x.imu_clock_offset_s * 1e9);
}

TimestampNs NavTrajectory::imu_time(const InertialState& x, TimestampNs t_ns) {
  const double c = x.imu_clock_offset_s + x.imu_clock_drift_s_per_s * ns_to_s(t_ns - gps_time(x));
  return t_ns + std::llround(c * 1e9);
}

TimestampNs NavTrajectory::query_time(const Epoch& e, TimestampNs t_ns) {
  return e.x.t_ns +
         std::llround(static_cast<double>(t_ns - e.t_gps_ns) * (1.0 + e.x.imu_clock_drift_s_per_s));
}

void NavTrajectory::set_gps_time(std::size_t k) {
  Epoch& e = epochs_[k];
  if (clock_P_.empty()) {
    e.t_gps_ns = e.x.t_ns;
    return;
  }
  e.t_gps_ns = gps_time(e.x);
  if (k > 0) e.t_gps_ns = std::max(e.t_gps_ns, epochs_[k - 1].t_gps_ns + 1);
}

TimestampNs NavTrajectory::end_ns() const {
  if (imu_.empty()) return 0;
  const TimestampNs t1 = imu_.back().t1_ns;
  if (clock_P_.empty() || epochs_.empty()) return t1;
  const Epoch& e = epochs_.back();
  return e.t_gps_ns + std::llround(static_cast<double>(t1 - e.x.t_ns) * (1.0 - e.x.imu_clock_drift_s_per_s));
}

std::size_t NavTrajectory::epoch_before(TimestampNs t_ns) const {
  const auto it = std::upper_bound(epochs_.begin(), epochs_.end(), t_ns,
                                   [](TimestampNs t, const Epoch& e) { return t < e.t_gps_ns; });
  return it == epochs_.begin() ? 0 : static_cast<std::size_t>(it - epochs_.begin()) - 1;
}

Expected<NavState> NavTrajectory::at(TimestampNs t_ns) const {
  if (epochs_.empty() || t_ns < begin_ns() || t_ns > end_ns())
    return make_error("NavTrajectory::at(): t=", t_ns, " ns is outside the trajectory [", begin_ns(), ", ",
                      end_ns(), "] ns");
  const std::size_t k = epoch_before(t_ns);
  const Epoch& e = epochs_[k];
  // The query on the IMU clock (by the epoch's estimate of it; t_ns itself without the clock states).
  const bool clock = !clock_P_.empty();
  const TimestampNs t_q = clock ? std::clamp(query_time(e, t_ns), e.x.t_ns, imu_.back().t1_ns) : t_ns;
  Strapdown mech(e.x, e.history);
  std::size_t index = e.imu_index;
  NavState s;
  if (!report_.smoothed) {
    // Forward only: the filter's own prediction from the epoch, covariance included (a linear
    // interpolation between two posteriors would miss its growth between fixes).
    s.P = P_[k];
    if (clock) s.clock = clock_P_[k];
    ImuClockCovariance* c = clock ? &s.clock : nullptr;
    Matrix3d sum_R = Matrix3d::Zero();
    Vector3d sum_dv = Vector3d::Zero();
    double T = 0;
    advance(imu_, mech, index, t_q, [&](double dt) {
      sum_R += mech.last_R_ecef_body() * dt;
      sum_dv += mech.last_dv_ecef();
      T += dt;
      if (T >= config_.covariance_step_s) {
        covariance_step(config_, mech.state().p_ecef_m, mech.state().v_ecef_mps, sum_R, sum_dv, T, s.P,
                        nullptr, c);
        sum_R.setZero();
        sum_dv.setZero();
        T = 0;
      }
    });
    if (T > 0)
      covariance_step(config_, mech.state().p_ecef_m, mech.state().v_ecef_mps, sum_R, sum_dv, T, s.P, nullptr,
                      c);
    static_cast<InertialState&>(s) = mech.state();
    s.t_ns = t_ns;
    if (clock) covariance_at_gps_time(s, mech.history());
    return s;
  }
  advance(imu_, mech, index, t_q, [](double) {});
  static_cast<InertialState&>(s) = mech.state();
  s.t_ns = t_ns;
  if (k + 1 < epochs_.size() && t_q > e.x.t_ns) {
    const double w =
        static_cast<double>(t_q - e.x.t_ns) / static_cast<double>(epochs_[k + 1].x.t_ns - e.x.t_ns);
    s.P = (1.0 - w) * P_[k] + w * P_[k + 1];
    if (clock) {
      s.clock.P_xc = (1.0 - w) * clock_P_[k].P_xc + w * clock_P_[k + 1].P_xc;
      s.clock.P_cc = (1.0 - w) * clock_P_[k].P_cc + w * clock_P_[k + 1].P_cc;
    }
  } else {
    s.P = P_[k];
    if (clock) s.clock = clock_P_[k];
  }
  if (clock) covariance_at_gps_time(s, mech.history());
  return s;
}

std::vector<NavState> NavTrajectory::epochs() const {
  std::vector<NavState> out(epochs_.size());
  for (std::size_t k = 0; k < epochs_.size(); ++k) {
    static_cast<InertialState&>(out[k]) = epochs_[k].x;
    out[k].t_ns = epochs_[k].t_gps_ns;
    out[k].P = P_[k];
    if (!clock_P_.empty()) {
      out[k].clock = clock_P_[k];
      covariance_at_gps_time(out[k], epochs_[k].history);
    }
  }
  return out;
}

std::vector<NavSolution> NavTrajectory::solutions() const {
  std::vector<NavSolution> out;
  out.reserve(epochs_.size());
  NavState s;
  for (std::size_t k = 0; k < epochs_.size(); ++k) {
    static_cast<InertialState&>(s) = epochs_[k].x;
    s.t_ns = epochs_[k].t_gps_ns;
    s.P = P_[k];
    if (!clock_P_.empty()) {
      s.clock = clock_P_[k];
      covariance_at_gps_time(s, epochs_[k].history);
    }
    out.push_back(to_solution(s));
  }
  return out;
}

NavSolution to_solution(const NavState& s) {
  NavSolution o;
  o.t_ns = s.t_ns;
  o.position = geodetic_from_ecef(s.p_ecef_m);
  const Matrix3d R_en = R_ecef_ned(o.position.lat_rad, o.position.lon_rad);
  o.v_ned_mps = R_en.transpose() * s.v_ecef_mps;
  const Matrix3d R_nb = R_en.transpose() * s.q_ecef_body.toRotationMatrix();
  o.attitude = ypr_from_rotation(R_nb);
  auto sig = [&](int i) {
    const Matrix3d C = R_en.transpose() * s.P.block<3, 3>(i, i) * R_en;
    return Vector3d(C.diagonal().cwiseMax(0.0).cwiseSqrt());
  };
  o.sigma_pos_ned_m = sig(kErrPos);
  o.sigma_vel_ned_mps = sig(kErrVel);
  const Matrix3d M = euler_to_rotation_jacobian(o.attitude.yaw_rad, o.attitude.pitch_rad);
  const Matrix3d Cn = R_en.transpose() * s.P.block<3, 3>(kErrAtt, kErrAtt) * R_en;
  const Matrix3d Mi = M.inverse();
  o.sigma_ypr_rad = (Mi * Cn * Mi.transpose()).diagonal().cwiseMax(0.0).cwiseSqrt();
  if (s.clock.P_cc(0, 0) > 0) {  // the IMU clock estimated
    o.imu_clock_offset_s = s.imu_clock_offset_s;
    o.imu_clock_drift_s_per_s = s.imu_clock_drift_s_per_s;
    o.sigma_imu_clock_offset_s = std::sqrt(s.clock.P_cc(0, 0));
    o.sigma_imu_clock_drift = std::sqrt(std::max(s.clock.P_cc(1, 1), 0.0));
  }
  return o;
}

}  // namespace augrig::nav
