// Truth trajectories (sim/flight.hpp, docs/SIMULATION.md "Truth trajectories").
//
// Everything is computed in truncated Taylor arithmetic ("jets"): a Jet<N> holds the value and the
// first N normalised derivatives (f^(k) / k!) of a function of time, and every operation propagates
// them exactly. Evaluating the trajectory with t as a Jet<2> gives position, velocity and
// acceleration, and the rotation matrix with its first two derivatives, to rounding.
//
// The tanker's horizontal path is the solution of the kinematic ODE at constant height h
//   dlat/dt = V cos(psi(t)) / (M(lat) + h),   dlon/dt = V sin(psi(t)) / ((N(lat) + h) cos(lat))
// (M, N: the WGS84 meridian and prime-vertical radii; psi(t): the track, piecewise polynomial), so it
// is exactly level, at exactly speed V along exactly track psi. It is solved once, at creation, by the
// Taylor-series method (order 12, knots at every joint of psi and at most 2 s apart, a tenth of the
// roll-in time in roll-ins and roll-outs), and kept as one polynomial per knot interval (dense
// output): evaluating it is a polynomial evaluation in jets.
#include "sim/flight.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "nav/geodesy.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"

namespace augrig::sim {

namespace {

// WGS84 (as GeographicLib::Constants).
constexpr double kA = 6378137.0;
constexpr double kF = 1.0 / 298.257223563;
constexpr double kE2 = kF * (2.0 - kF);

constexpr int kOdeOrder = 12;          // Taylor order of the dense output
constexpr double kMaxKnotStepS = 2.0;  // knot spacing
constexpr double kMarginS = 60.0;      // the path is solved on [-margin, duration + margin]

// ---- Truncated Taylor arithmetic --------------------------------------------------------------

template <int N>
struct Jet {
  std::array<double, N + 1> c{};  // c[k] = f^(k)(t0) / k!
};

template <int N>
Jet<N> constant(double v) {
  Jet<N> j;
  j.c[0] = v;
  return j;
}

// The independent variable t at t0.
template <int N>
Jet<N> variable(double t0) {
  Jet<N> j;
  j.c[0] = t0;
  if constexpr (N >= 1) j.c[1] = 1.0;
  return j;
}

template <int N>
Jet<N> operator+(Jet<N> a, const Jet<N>& b) {
  for (int k = 0; k <= N; ++k) a.c[k] += b.c[k];
  return a;
}
template <int N>
Jet<N> operator-(Jet<N> a, const Jet<N>& b) {
  for (int k = 0; k <= N; ++k) a.c[k] -= b.c[k];
  return a;
}
template <int N>
Jet<N> operator-(Jet<N> a) {
  for (int k = 0; k <= N; ++k) a.c[k] = -a.c[k];
  return a;
}
template <int N>
Jet<N> operator+(Jet<N> a, double b) {
  a.c[0] += b;
  return a;
}
template <int N>
Jet<N> operator+(double b, Jet<N> a) {
  a.c[0] += b;
  return a;
}
template <int N>
Jet<N> operator-(Jet<N> a, double b) {
  a.c[0] -= b;
  return a;
}
template <int N>
Jet<N> operator-(double b, const Jet<N>& a) {
  return b + (-a);
}
template <int N>
Jet<N> operator*(double s, Jet<N> a) {
  for (int k = 0; k <= N; ++k) a.c[k] *= s;
  return a;
}
template <int N>
Jet<N> operator*(Jet<N> a, double s) {
  return s * a;
}
template <int N>
Jet<N> operator*(const Jet<N>& a, const Jet<N>& b) {
  Jet<N> r;
  for (int k = 0; k <= N; ++k) {
    double s = 0;
    for (int i = 0; i <= k; ++i) s += a.c[i] * b.c[k - i];
    r.c[k] = s;
  }
  return r;
}
template <int N>
Jet<N> operator/(const Jet<N>& a, const Jet<N>& b) {
  Jet<N> q;
  for (int k = 0; k <= N; ++k) {
    double s = a.c[k];
    for (int j = 1; j <= k; ++j) s -= b.c[j] * q.c[k - j];
    q.c[k] = s / b.c[0];
  }
  return q;
}
template <int N>
Jet<N> operator/(Jet<N> a, double s) {
  return (1.0 / s) * a;
}

template <int N>
void sin_cos(const Jet<N>& a, Jet<N>* s, Jet<N>* c) {
  s->c[0] = std::sin(a.c[0]);
  c->c[0] = std::cos(a.c[0]);
  for (int k = 1; k <= N; ++k) {
    double ss = 0, cc = 0;
    for (int j = 1; j <= k; ++j) {
      ss += j * a.c[j] * c->c[k - j];
      cc -= j * a.c[j] * s->c[k - j];
    }
    s->c[k] = ss / k;
    c->c[k] = cc / k;
  }
}

// a^p for a(t0) > 0.
template <int N>
Jet<N> pow(const Jet<N>& a, double p) {
  Jet<N> y;
  y.c[0] = std::pow(a.c[0], p);
  for (int k = 1; k <= N; ++k) {
    double s = 0;
    for (int j = 1; j <= k; ++j) s += ((p + 1.0) * j - k) * a.c[j] * y.c[k - j];
    y.c[k] = s / (k * a.c[0]);
  }
  return y;
}

template <int N>
Jet<N> atan(const Jet<N>& a) {
  Jet<N> y;
  y.c[0] = std::atan(a.c[0]);
  if constexpr (N >= 1) {
    // y' = a' / (1 + a^2), coefficient by coefficient.
    const Jet<N> d = 1.0 + a * a;
    std::array<double, N> q{};
    for (int k = 0; k < N; ++k) {
      double s = (k + 1) * a.c[k + 1];
      for (int j = 1; j <= k; ++j) s -= d.c[j] * q[k - j];
      q[k] = s / d.c[0];
      y.c[k + 1] = q[k] / (k + 1);
    }
  }
  return y;
}

// sum coeffs[i] x^i (Horner).
template <int N, std::size_t M>
Jet<N> polynomial(const std::array<double, M>& coeffs, const Jet<N>& x) {
  Jet<N> r = constant<N>(coeffs[M - 1]);
  for (int i = static_cast<int>(M) - 2; i >= 0; --i) r = r * x + coeffs[i];
  return r;
}

template <int N>
using V3 = std::array<Jet<N>, 3>;
template <int N>
using M3 = std::array<std::array<Jet<N>, 3>, 3>;  // [row][column]

template <int N>
V3<N> operator+(const V3<N>& a, const V3<N>& b) {
  return {a[0] + b[0], a[1] + b[1], a[2] + b[2]};
}
template <int N>
V3<N> operator-(const V3<N>& a, const V3<N>& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
template <int N>
V3<N> operator*(const M3<N>& m, const V3<N>& v) {
  V3<N> r;
  for (int i = 0; i < 3; ++i) r[i] = m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
  return r;
}
template <int N>
M3<N> operator*(const M3<N>& a, const M3<N>& b) {
  M3<N> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
  return r;
}
template <int N>
V3<N> constant3(const Eigen::Vector3d& v) {
  return {constant<N>(v.x()), constant<N>(v.y()), constant<N>(v.z())};
}
template <int N>
Eigen::Vector3d value(const V3<N>& v) {
  return {v[0].c[0], v[1].c[0], v[2].c[0]};
}
template <int N>
Eigen::Matrix3d value(const M3<N>& m, int k = 0) {
  Eigen::Matrix3d r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r(i, j) = m[i][j].c[k];
  return r;
}

template <int N>
M3<N> rot_x(const Jet<N>& a) {
  Jet<N> s, c;
  sin_cos(a, &s, &c);
  const Jet<N> z = constant<N>(0.0), o = constant<N>(1.0);
  return {{{o, z, z}, {z, c, -s}, {z, s, c}}};
}
template <int N>
M3<N> rot_y(const Jet<N>& a) {
  Jet<N> s, c;
  sin_cos(a, &s, &c);
  const Jet<N> z = constant<N>(0.0), o = constant<N>(1.0);
  return {{{c, z, s}, {z, o, z}, {-s, z, c}}};
}
template <int N>
M3<N> rot_z(const Jet<N>& a) {
  Jet<N> s, c;
  sin_cos(a, &s, &c);
  const Jet<N> z = constant<N>(0.0), o = constant<N>(1.0);
  return {{{c, -s, z}, {s, c, z}, {z, z, o}}};
}

// ---- Pieces of the paths ----------------------------------------------------------------------

// Minimum-jerk blend S(u) = 10u^3 - 15u^4 + 6u^5 and its integral P(u) = 2.5u^4 - 3u^5 + u^6.
constexpr std::array<double, 6> kMinJerk = {0, 0, 0, 10, -15, 6};

// One piece of the tanker's track: psi(t) and the turn rate r(t) = psi'(t) as polynomials in
// u = (t - t0) / T.
struct TrackSegment {
  double t0 = 0, t1 = 0, T = 1;
  std::array<double, 7> psi{};
  std::array<double, 6> rate{};
};

TrackSegment straight_segment(double t0, double t1, double psi0) {
  TrackSegment s;
  s.t0 = t0;
  s.t1 = t1;
  s.T = t1 - t0;
  s.psi[0] = psi0;
  return s;
}

// kind: 0 roll-in (rate 0 -> r), 1 constant rate r, 2 roll-out (r -> 0).
TrackSegment turn_segment(int kind, double t0, double T, double psi0, double r) {
  TrackSegment s;
  s.t0 = t0;
  s.t1 = t0 + T;
  s.T = T;
  s.psi[0] = psi0;
  const double rT = r * T;
  if (kind == 0) {
    s.psi[4] = 2.5 * rT;
    s.psi[5] = -3.0 * rT;
    s.psi[6] = rT;
    for (int i = 0; i < 6; ++i) s.rate[i] = r * kMinJerk[i];
  } else if (kind == 1) {
    s.psi[1] = rT;
    s.rate[0] = r;
  } else {
    s.psi[1] = rT;
    s.psi[4] = -2.5 * rT;
    s.psi[5] = 3.0 * rT;
    s.psi[6] = -rT;
    s.rate[0] = r;
    for (int i = 1; i < 6; ++i) s.rate[i] = -r * kMinJerk[i];
  }
  return s;
}

// Dense output of the horizontal path on one knot interval: Taylor polynomials in tau = t - t_ref.
struct PathPiece {
  double t_ref = 0;
  int segment = 0;
  std::array<double, kOdeOrder + 1> lat{}, lon{};
};

double evaluate(const std::array<double, kOdeOrder + 1>& c, double tau) {
  double r = c[kOdeOrder];
  for (int i = kOdeOrder - 1; i >= 0; --i) r = r * tau + c[i];
  return r;
}

template <int N>
void track_jets(const TrackSegment& s, const Jet<N>& t, Jet<N>* psi, Jet<N>* rate) {
  const Jet<N> u = (t - s.t0) * (1.0 / s.T);
  *psi = polynomial(s.psi, u);
  if (rate) *rate = polynomial(s.rate, u);
}

struct Sinusoid {
  double amplitude = 0, omega = 0, phase = 0;
};

// sum a cos(w t + phi) as a Jet in t: the k-th normalised derivative of cos(x) is cos(x + k pi/2) / k!.
template <int N>
Jet<N> sum_of_sinusoids(const std::vector<Sinusoid>& parts, double t) {
  Jet<N> r;
  for (const Sinusoid& p : parts) {
    const double x = p.omega * t + p.phase;
    const double s = std::sin(x), c = std::cos(x);
    const std::array<double, 4> cyc = {c, -s, -c, s};
    double f = p.amplitude;
    for (int k = 0; k <= N; ++k) {
      r.c[k] += f * cyc[k % 4];
      f *= p.omega / (k + 1);
    }
  }
  return r;
}

// One-sided Dryden spectra (temporal angular frequency w, speed V, scale L), up to a constant factor.
double dryden_psd(bool longitudinal, double w, double V, double L) {
  const double x = L * w / V;
  return longitudinal ? 2.0 / (1.0 + x * x) : (1.0 + 3.0 * x * x) / ((1.0 + x * x) * (1.0 + x * x));
}

std::vector<Sinusoid> turbulence_axis(double sigma, bool longitudinal, double speed_mps, double L, int m,
                                      std::uint64_t seed) {
  std::vector<Sinusoid> parts;
  if (!(sigma > 0) || m <= 0) return parts;
  const double V = std::max(speed_mps, 1.0);
  const double wc = V / L;
  const double w_lo = 0.05 * wc;
  double w_hi = std::min(20.0 * wc, 2.0 * kPi * 2.0);  // nothing above 2 Hz: a piloted aircraft
  if (w_hi < 2.0 * w_lo) w_hi = 2.0 * w_lo;
  Rng rng(seed);
  double variance = 0;
  for (int j = 0; j < m; ++j) {
    const double e0 = w_lo * std::pow(w_hi / w_lo, static_cast<double>(j) / m);
    const double e1 = w_lo * std::pow(w_hi / w_lo, static_cast<double>(j + 1) / m);
    Sinusoid p;
    p.omega = e0 + (e1 - e0) * rng.uniform();
    p.phase = 2.0 * kPi * rng.uniform();
    p.amplitude = std::sqrt(2.0 * dryden_psd(longitudinal, p.omega, V, L) * (e1 - e0));
    variance += 0.5 * p.amplitude * p.amplitude;
    parts.push_back(p);
  }
  const double scale = sigma / std::sqrt(variance);
  for (Sinusoid& p : parts) p.amplitude *= scale;
  return parts;
}

Eigen::Vector3d vee(const Eigen::Matrix3d& A) {
  return {A(2, 1), A(0, 2), A(1, 0)};
}

KinematicState to_state(double t, const V3<2>& p, const M3<2>& R) {
  KinematicState s;
  s.t_s = t;
  for (int i = 0; i < 3; ++i) {
    s.p_ecef_m[i] = p[i].c[0];
    s.v_ecef_mps[i] = p[i].c[1];
    s.a_ecef_mps2[i] = 2.0 * p[i].c[2];
  }
  const Eigen::Matrix3d R0 = value(R, 0), R1 = value(R, 1), R2 = 2.0 * value(R, 2);
  s.q_ecef_body = Eigen::Quaterniond(R0).normalized();
  // R' = R [w x]; d/dt (R^T R') = R'^T R' + R^T R'' = [w' x], whose symmetric first term drops out.
  const Eigen::Matrix3d W = R0.transpose() * R1, D = R0.transpose() * R2;
  s.w_eb_body_radps = vee(0.5 * (W - W.transpose()));
  s.dw_eb_body_radps2 = vee(0.5 * (D - D.transpose()));
  return s;
}

}  // namespace

struct Flight::Impl {
  double duration_s = 0;
  // Tanker
  double speed_mps = 0, h_m = 0, g_mps2 = 9.8, aoa_rad = 0, crab_rad = 0, turn_radius_m = 0;
  std::vector<TrackSegment> segments;
  std::vector<double> knots;
  std::vector<PathPiece> pieces;  // pieces[i] covers [knots[i], knots[i + 1]]
  // Receiver
  std::vector<ReceiverPhase> phases;
  std::vector<double> phase_start_s;
  BoomArticulation contact;
  BoomDimensions boom;
  Eigen::Vector3d pivot_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d contact_point_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d receptacle_m = Eigen::Vector3d::Zero();
  std::array<std::vector<Sinusoid>, 6> turbulence;  // x, y, z, yaw, pitch, roll

  std::size_t piece_index(double t) const {
    const auto it = std::upper_bound(knots.begin(), knots.end(), t);
    const std::ptrdiff_t i = (it - knots.begin()) - 1;
    return static_cast<std::size_t>(std::clamp<std::ptrdiff_t>(i, 0, std::ssize(pieces) - 1));
  }

  std::size_t phase_index(double t) const {
    const auto it = std::upper_bound(phase_start_s.begin(), phase_start_s.end(), t);
    const std::ptrdiff_t i = (it - phase_start_s.begin()) - 1;
    return static_cast<std::size_t>(std::clamp<std::ptrdiff_t>(i, 0, std::ssize(phases) - 1));
  }

  // Taylor-series solution of the path ODE about t_ref, from (lat0, lon0) at t_ref.
  PathPiece expand(std::size_t segment, double t_ref, double lat0, double lon0) const {
    constexpr int K = kOdeOrder;
    Jet<K> psi;
    track_jets<K>(segments[segment], variable<K>(t_ref), &psi, nullptr);
    Jet<K> sp, cp;
    sin_cos(psi, &sp, &cp);
    const Jet<K> vn = speed_mps * cp, ve = speed_mps * sp;
    Jet<K> lat = constant<K>(lat0), lon = constant<K>(lon0);
    // Pass n fixes coefficient n + 1: coefficient n of the right-hand side depends on those <= n only.
    for (int n = 0; n < K; ++n) {
      Jet<K> sl, cl;
      sin_cos(lat, &sl, &cl);
      const Jet<K> w = 1.0 - kE2 * sl * sl;
      const Jet<K> M = (kA * (1.0 - kE2)) * pow(w, -1.5);
      const Jet<K> Nr = kA * pow(w, -0.5);
      const Jet<K> dlat = vn / (M + h_m);
      const Jet<K> dlon = ve / ((Nr + h_m) * cl);
      lat.c[n + 1] = dlat.c[n] / (n + 1);
      lon.c[n + 1] = dlon.c[n] / (n + 1);
    }
    PathPiece p;
    p.t_ref = t_ref;
    p.segment = static_cast<int>(segment);
    p.lat = lat.c;
    p.lon = lon.c;
    return p;
  }

  // Tanker position (ECEF) and R_ecef_body as jets in t.
  template <int N>
  void tanker_jets(double t, V3<N>* p, M3<N>* R) const {
    const PathPiece& piece = pieces[piece_index(t)];
    const Jet<N> tau = variable<N>(t - piece.t_ref);
    const Jet<N> lat = polynomial(piece.lat, tau), lon = polynomial(piece.lon, tau);
    Jet<N> sl, cl, so, co;
    sin_cos(lat, &sl, &cl);
    sin_cos(lon, &so, &co);
    const Jet<N> Nr = kA * pow(1.0 - kE2 * sl * sl, -0.5);
    const Jet<N> rc = (Nr + h_m) * cl;
    *p = {rc * co, rc * so, (Nr * (1.0 - kE2) + h_m) * sl};
    // R_ecef_ned: columns north, east, down (nav::R_ecef_ned).
    const Jet<N> z = constant<N>(0.0);
    const M3<N> R_en = {{{-(sl * co), -so, -(cl * co)}, {-(sl * so), co, -(cl * so)}, {cl, z, -sl}}};
    Jet<N> psi, rate;
    track_jets<N>(segments[static_cast<std::size_t>(piece.segment)], variable<N>(t), &psi, &rate);
    const Jet<N> bank = atan(rate * (speed_mps / g_mps2));
    *R = R_en * (rot_z<N>(psi + crab_rad) * (rot_x<N>(bank) * rot_y<N>(constant<N>(aoa_rad))));
  }

  // Receptacle point (tanker body) and R_tanker_receiver as jets in t.
  template <int N>
  void relative_jets(double t, V3<N>* receptacle_point, M3<N>* R_tr) const {
    const std::size_t i = phase_index(t);
    const ReceiverPhase& ph = phases[i];
    const ReceiverPhase& prev = phases[i == 0 ? 0 : i - 1];
    Jet<N> s = constant<N>(1.0);  // before 0 and after the last phase: hold
    if (t >= phase_start_s[i] && t <= phase_start_s[i] + ph.duration_s) {
      s = polynomial(kMinJerk, (variable<N>(t) - phase_start_s[i]) * (1.0 / ph.duration_s));
    }
    V3<N> q, ypr;
    for (int k = 0; k < 3; ++k) {
      q[k] = contact_point_m[k] + prev.offset_m[k] + (ph.offset_m[k] - prev.offset_m[k]) * s +
             sum_of_sinusoids<N>(turbulence[k], t);
      ypr[k] =
          prev.ypr_rad[k] + (ph.ypr_rad[k] - prev.ypr_rad[k]) * s + sum_of_sinusoids<N>(turbulence[3 + k], t);
    }
    *receptacle_point = q;
    *R_tr = rot_z<N>(ypr[0]) * (rot_y<N>(ypr[1]) * rot_x<N>(ypr[2]));
  }

  // Receiver body origin (tanker body) and R_tanker_receiver.
  template <int N>
  void receiver_relative_jets(double t, V3<N>* r, M3<N>* R_tr) const {
    V3<N> q;
    relative_jets<N>(t, &q, R_tr);
    *r = q - (*R_tr) * constant3<N>(receptacle_m);
  }
};

Expected<Flight> Flight::create(const Scenario& sc) {
  const std::string where = "Flight::create(): scenario '" + sc.name + "': ";
  const TankerFlightConfig& tk = sc.tanker;
  if (!(sc.duration_s > 0)) return make_error(where, "duration_s must be > 0");
  if (!(std::abs(sc.start.lat_rad) < deg_to_rad(85.0)))
    return make_error(where, "the start latitude must be within +-85 deg (no polar flights)");
  if (!(tk.speed_mps >= 0)) return make_error(where, "the tanker's speed must be >= 0");
  if (sc.receiver.phases.empty()) return make_error(where, "the receiver needs at least one phase");
  for (const ReceiverPhase& p : sc.receiver.phases) {
    if (!(p.duration_s > 0)) return make_error(where, "phase '", p.name, "': duration_s must be > 0");
  }
  const TurbulenceConfig& tb = sc.receiver.turbulence;
  if (!(tb.length_scale_m > 0)) return make_error(where, "turbulence length_scale_m must be > 0");

  auto impl = std::make_shared<Impl>();
  Impl& m = *impl;
  m.duration_s = sc.duration_s;
  m.speed_mps = tk.speed_mps;
  m.h_m = sc.start.h_m;
  m.g_mps2 = nav::gravity_ecef(nav::ecef_from_geodetic(sc.start)).norm();
  m.aoa_rad = tk.angle_of_attack_rad;
  m.crab_rad = tk.crab_rad;

  // Track schedule.
  const double t_begin = -kMarginS, t_end = sc.duration_s + kMarginS;
  if (tk.pattern == TankerPattern::kStraight || tk.speed_mps == 0) {
    m.segments.push_back(straight_segment(t_begin, t_end, tk.heading_rad));
  } else {
    if (!(tk.bank_rad > 0 && tk.bank_rad <= deg_to_rad(60.0)))
      return make_error(where, "racetrack bank must be in (0, 60] deg");
    if (!(tk.leg_length_m > 0)) return make_error(where, "racetrack leg_length_m must be > 0");
    if (!(tk.roll_in_s > 0)) return make_error(where, "racetrack roll_in_s must be > 0");
    const double r_abs = m.g_mps2 * std::tan(tk.bank_rad) / tk.speed_mps;
    const double r = tk.turn_right ? r_abs : -r_abs;
    const double T = tk.roll_in_s;
    const double Tc = kPi / r_abs - T;
    if (Tc < 0)
      return make_error(where, "racetrack roll_in_s (", tk.roll_in_s,
                        " s) is too long for a 180 deg turn at this bank and speed (at most ", kPi / r_abs,
                        " s)");
    m.turn_radius_m = tk.speed_mps / r_abs;
    const double leg_s = tk.leg_length_m / tk.speed_mps;
    double t = leg_s, psi = tk.heading_rad;
    m.segments.push_back(straight_segment(t_begin, t, psi));
    while (t < t_end) {
      m.segments.push_back(turn_segment(0, t, T, psi, r));
      t += T;
      psi += 0.5 * r * T;
      if (Tc > 0) {
        m.segments.push_back(turn_segment(1, t, Tc, psi, r));
        t += Tc;
        psi += r * Tc;
      }
      m.segments.push_back(turn_segment(2, t, T, psi, r));
      t += T;
      psi += 0.5 * r * T;
      m.segments.push_back(straight_segment(t, t + leg_s, psi));
      t += leg_s;
    }
  }

  // Knots: every segment joint, t = 0, and at most kMaxKnotStepS apart.
  std::vector<int> knot_segment;
  for (std::size_t s = 0; s < m.segments.size(); ++s) {
    const TrackSegment& seg = m.segments[s];
    std::vector<double> breaks = {seg.t0};
    if (seg.t0 < 0 && seg.t1 > 0) breaks.push_back(0.0);
    breaks.push_back(seg.t1);
    for (std::size_t b = 0; b + 1 < breaks.size(); ++b) {
      const double a = breaks[b], e = breaks[b + 1];
      // Roll-in/out: psi is a degree-6 polynomial in (t - t0) / T, whose Taylor series about a point
      // converges quickly only well within T of it.
      const bool roll = seg.psi[6] != 0;
      const double step = roll ? std::min(kMaxKnotStepS, seg.T / 10.0) : kMaxKnotStepS;
      const int n = std::max(1, static_cast<int>(std::ceil((e - a) / step - 1e-9)));
      for (int i = 0; i < n; ++i) {
        m.knots.push_back(i == 0 ? a : a + (e - a) * i / n);
        knot_segment.push_back(static_cast<int>(s));
      }
    }
  }
  m.knots.push_back(m.segments.back().t1);

  // Integrate the path from the start point forwards and backwards.
  const std::size_t n_pieces = m.knots.size() - 1;
  m.pieces.resize(n_pieces);
  const std::size_t i0 =
      static_cast<std::size_t>(std::find(m.knots.begin(), m.knots.end(), 0.0) - m.knots.begin());
  double lat = sc.start.lat_rad, lon = sc.start.lon_rad;
  for (std::size_t i = i0; i < n_pieces; ++i) {
    m.pieces[i] = m.expand(static_cast<std::size_t>(knot_segment[i]), m.knots[i], lat, lon);
    const double h = m.knots[i + 1] - m.knots[i];
    lat = evaluate(m.pieces[i].lat, h);
    lon = evaluate(m.pieces[i].lon, h);
  }
  lat = sc.start.lat_rad;
  lon = sc.start.lon_rad;
  for (std::size_t i = i0; i-- > 0;) {
    m.pieces[i] = m.expand(static_cast<std::size_t>(knot_segment[i]), m.knots[i + 1], lat, lon);
    const double h = m.knots[i] - m.knots[i + 1];
    lat = evaluate(m.pieces[i].lat, h);
    lon = evaluate(m.pieces[i].lon, h);
  }

  // Receiver.
  m.phases = sc.receiver.phases;
  double t = 0;
  for (const ReceiverPhase& p : m.phases) {
    m.phase_start_s.push_back(t);
    t += p.duration_s;
  }
  m.contact = sc.receiver.contact;
  m.boom = sc.boom;
  m.pivot_m = sc.rig.boom.pivot_body_m;
  m.contact_point_m =
      boom_pose(m.pivot_m, m.contact) * Eigen::Vector3d(m.boom.nozzle_tip_m(m.contact.extension_m), 0, 0);
  if (sc.rig.receiver.model.path.empty()) {
    make_builtin_receiver(&m.receptacle_m);  // the model the renderer draws
  } else {
    m.receptacle_m = sc.rig.receiver.receptacle_m;
  }
  const std::array<const char*, 6> axis_names = {"x", "y", "z", "yaw", "pitch", "roll"};
  for (int k = 0; k < 6; ++k) {
    const double sigma = k < 3 ? tb.sigma_m[k] : tb.sigma_rad[k - 3];
    const bool longitudinal = k == 0 || k == 5;
    m.turbulence[static_cast<std::size_t>(k)] = turbulence_axis(
        sigma, longitudinal, tk.speed_mps, tb.length_scale_m, tb.components,
        derive_seed(sc.seed, std::string("turbulence/") + axis_names[static_cast<std::size_t>(k)]));
  }

  Flight f;
  f.impl_ = std::move(impl);
  return f;
}

KinematicState Flight::tanker(double t_s) const {
  V3<2> p;
  M3<2> R;
  impl_->tanker_jets<2>(t_s, &p, &R);
  return to_state(t_s, p, R);
}

KinematicState Flight::receiver(double t_s) const {
  V3<2> p, r;
  M3<2> R, R_tr;
  impl_->tanker_jets<2>(t_s, &p, &R);
  impl_->receiver_relative_jets<2>(t_s, &r, &R_tr);
  return to_state(t_s, p + R * r, R * R_tr);
}

Pose Flight::T_tanker_receiver(double t_s) const {
  V3<0> r;
  M3<0> R_tr;
  impl_->receiver_relative_jets<0>(t_s, &r, &R_tr);
  return Pose::from(value(R_tr), value(r));
}

const std::string& Flight::phase(double t_s) const {
  return impl_->phases[impl_->phase_index(t_s)].name;
}

BoomArticulation Flight::boom(double t_s) const {
  const Impl& m = *impl_;
  if (!m.phases[m.phase_index(t_s)].attached) return m.contact;
  V3<0> q;
  M3<0> R_tr;
  m.relative_jets<0>(t_s, &q, &R_tr);
  // Inverse of boom_pose: the boom's x axis in the body is (-cos az cos el, sin az cos el, sin el).
  const Eigen::Vector3d d = value(q) - m.pivot_m;
  const double L = d.norm();
  BoomArticulation a;
  a.elevation_rad = std::asin(std::clamp(d.z() / L, -1.0, 1.0));
  a.azimuth_rad = std::atan2(d.y(), -d.x());
  a.extension_m = L - m.boom.nozzle_tip_m(0.0);
  return a;
}

const Eigen::Vector3d& Flight::contact_point_body_m() const {
  return impl_->contact_point_m;
}
const Eigen::Vector3d& Flight::receptacle_m() const {
  return impl_->receptacle_m;
}
double Flight::duration_s() const {
  return impl_->duration_s;
}
double Flight::turn_radius_m() const {
  return impl_->turn_radius_m;
}
double Flight::turn_gravity_mps2() const {
  return impl_->g_mps2;
}

}  // namespace augrig::sim
