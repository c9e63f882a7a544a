#include "render/camera_model.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "core/conventions.hpp"

namespace augrig {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// A polynomial c[0] + c[1] s + c[2] s^2 + ... evaluated by Horner's rule.
double poly_eval(const std::vector<double>& c, double s) {
  double v = 0.0;
  for (auto it = c.rbegin(); it != c.rend(); ++it) v = v * s + *it;
  return v;
}

std::vector<double> poly_derivative(const std::vector<double>& c) {
  std::vector<double> d;
  for (std::size_t i = 1; i < c.size(); ++i) d.push_back(static_cast<double>(i) * c[i]);
  return d;
}

// Drops zero leading coefficients so the degree is the true degree.
std::vector<double> poly_trim(std::vector<double> c) {
  while (!c.empty() && c.back() == 0.0) c.pop_back();
  return c;
}

// Bisection on [a, b] where p(a) > 0 >= p(b) (or the reverse): the sign change, to full precision.
double bisect_sign_change(const std::vector<double>& p, double a, double b) {
  const bool a_positive = poly_eval(p, a) > 0.0;
  for (int i = 0; i < 200; ++i) {
    const double m = 0.5 * (a + b);
    if (m <= a || m >= b) break;
    if ((poly_eval(p, m) > 0.0) == a_positive) {
      a = m;
    } else {
      b = m;
    }
  }
  return b;
}

// All real roots of p in (lo, hi), ascending. Why recursive: the roots of p' split [lo, hi] into
// intervals where p is monotonic, so each interval holds at most one root that bisection finds
// reliably; a plain scan could step over a short dip below zero. Degrees here are <= 4.
std::vector<double> poly_roots(const std::vector<double>& p_in, double lo, double hi) {
  const std::vector<double> p = poly_trim(p_in);
  std::vector<double> roots;
  if (p.size() <= 1) return roots;  // constant: no isolated roots
  std::vector<double> knots{lo};
  for (double c : poly_roots(poly_derivative(p), lo, hi)) knots.push_back(c);
  knots.push_back(hi);
  for (std::size_t i = 0; i + 1 < knots.size(); ++i) {
    const double a = knots[i], b = knots[i + 1];
    const double pa = poly_eval(p, a), pb = poly_eval(p, b);
    if (pb == 0.0 && b < hi) {
      roots.push_back(b);
    } else if ((pa > 0.0 && pb < 0.0) || (pa < 0.0 && pb > 0.0)) {
      roots.push_back(bisect_sign_change(p, a, b));
    }
  }
  std::sort(roots.begin(), roots.end());
  roots.erase(std::unique(roots.begin(), roots.end()), roots.end());
  return roots;
}

// Smallest s in (0, hi] with p(s) <= 0, given p(0) > 0; +inf when p stays positive.
double first_nonpositive(const std::vector<double>& p, double hi) {
  const std::vector<double> roots = poly_roots(p, 0.0, hi);
  for (double r : roots) {
    if (r > 0.0) return r;
  }
  if (poly_eval(p, hi) <= 0.0) return hi;
  return kInf;
}

// max_valid_radius() costs a root search; project()/ray() need it per call, so each thread keeps
// the last answer keyed by the distortion parameters (a per-pixel loop hits the cache every time).
double compute_max_valid_radius(DistortionModel model, const std::array<double, 5>& k) {
  switch (model) {
    case DistortionModel::kNone:
      return kInf;
    case DistortionModel::kRadTan: {
      // d/dr [r (1 + k1 r^2 + k2 r^4 + k3 r^6)] = 1 + 3 k1 s + 5 k2 s^2 + 7 k3 s^3 with s = r^2.
      // Tangential terms are ignored (they are small and not radially symmetric).
      const std::vector<double> p = poly_trim({1.0, 3.0 * k[0], 5.0 * k[1], 7.0 * k[4]});
      if (p.size() <= 1) return kInf;
      // Cauchy's bound: every root satisfies |s| <= 1 + max |c_i / c_n|.
      double bound = 0.0;
      for (std::size_t i = 0; i + 1 < p.size(); ++i) bound = std::max(bound, std::abs(p[i] / p.back()));
      const double s = first_nonpositive(p, 1.0 + bound);
      return std::isinf(s) ? kInf : std::sqrt(s);
    }
    case DistortionModel::kEquidistant: {
      // d/dtheta theta_d = 1 + 3 k1 t + 5 k2 t^2 + 7 k3 t^3 + 9 k4 t^4 with t = theta^2, up to pi.
      const std::vector<double> p{1.0, 3.0 * k[0], 5.0 * k[1], 7.0 * k[2], 9.0 * k[3]};
      const double t = first_nonpositive(p, kPi * kPi);
      return std::isinf(t) ? kPi : std::min(kPi, std::sqrt(t));
    }
  }
  return kInf;
}

double cached_max_valid_radius(DistortionModel model, const std::array<double, 5>& k) {
  struct Cache {
    bool valid = false;
    DistortionModel model = DistortionModel::kNone;
    std::array<double, 5> k{};
    double value = kInf;
  };
  thread_local Cache cache;
  if (!cache.valid || cache.model != model || cache.k != k) {
    cache.value = compute_max_valid_radius(model, k);
    cache.model = model;
    cache.k = k;
    cache.valid = true;
  }
  return cache.value;
}

// Radial factor 1 + k1 r^2 + k2 r^4 + k3 r^6 and its derivative with respect to r^2.
inline double radtan_radial(const std::array<double, 5>& k, double r2) {
  return 1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]));
}
inline double radtan_dradial_dr2(const std::array<double, 5>& k, double r2) {
  return k[0] + r2 * (2.0 * k[1] + r2 * 3.0 * k[4]);
}

// equi_theta_d() (the header) and its derivative.
inline double equi_dtheta_d(const std::array<double, 5>& k, double th) {
  const double t = th * th;
  return 1.0 + t * (3.0 * k[0] + t * (5.0 * k[1] + t * (7.0 * k[2] + t * 9.0 * k[3])));
}

// Solves f(x) = target for x in [0, hi] where f is increasing with f(0) = 0 <= target < f(hi):
// Newton steps, falling back to bisection whenever a step leaves the bracket. Why safeguarded:
// near the fold f' -> 0 and plain Newton would jump past it onto the wrong branch.
// Stops once |f(x) - target| <= tol (0: to full precision).
template <typename F, typename DF>
double solve_monotone(F f, DF df, double target, double hi, double x0, double tol = 0.0) {
  double lo = 0.0;
  double x = std::clamp(x0, lo, hi);
  for (int i = 0; i < 100; ++i) {
    const double fx = f(x) - target;
    if (std::abs(fx) <= tol) return x;
    if (fx > 0.0) {
      hi = x;
    } else {
      lo = x;
    }
    const double d = df(x);
    double next = d > 0.0 ? x - fx / d : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - x) <= 1e-16 * std::max(1.0, std::abs(x))) return next;
    x = next;
  }
  return x;
}

}  // namespace

std::string camera_model_problem(const CameraModel& m) {
  const auto num = [](double v) {
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, v + 0.0);  // shortest exact text
    return std::string(buf, r.ptr);
  };
  if (m.width_px < 1 || m.width_px > kMaxImageSidePx || m.height_px < 1 || m.height_px > kMaxImageSidePx) {
    return "expected an image size in 1.." + std::to_string(kMaxImageSidePx) + " x 1.." +
           std::to_string(kMaxImageSidePx) + " pixels, got " + std::to_string(m.width_px) + "x" +
           std::to_string(m.height_px);
  }
  if (!(m.fx_px >= kMinFocalPx && m.fx_px <= kMaxFocalPx && m.fy_px >= kMinFocalPx &&
        m.fy_px <= kMaxFocalPx)) {
    return "expected focal lengths fx, fy in [1, 1e7] pixels, got " + num(m.fx_px) + ", " + num(m.fy_px);
  }
  const double w = m.width_px, h = m.height_px;
  if (!(m.cx_px >= -w && m.cx_px <= 2 * w && m.cy_px >= -h && m.cy_px <= 2 * h)) {
    return "expected the principal point within one image size of the image (cx in [" + num(-w) + ", " +
           num(2 * w) + "], cy in [" + num(-h) + ", " + num(2 * h) + "]), got (" + num(m.cx_px) + ", " +
           num(m.cy_px) + ")";
  }
  const std::size_t n = m.distortion == DistortionModel::kNone          ? 0
                        : m.distortion == DistortionModel::kEquidistant ? 4
                                                                        : 5;
  for (std::size_t i = 0; i < n; ++i) {
    if (!(std::abs(m.coeffs[i]) <= kMaxDistortionCoefficient)) {
      return "expected " + m.distortion_name() + " distortion coefficients in [-1000, 1000], got " +
             num(m.coeffs[i]) + " as coefficient " + std::to_string(i);
    }
  }
  // The rendered field (kMaxFieldAxisDeg): the image border holds the most oblique rays of a lens
  // whose distortion is monotonic where it is defined. Pixels that undistort to no ray at all
  // (outside the model's valid region) are left out, as the renderer leaves them.
  // Rays, not normalised coordinates: a fisheye's border may look 90 degrees off axis or more.
  auto beyond = [&](int u, int v) -> std::string {
    const auto r = m.ray({static_cast<double>(u), static_cast<double>(v)});
    if (!r) return {};
    const double deg =
        std::atan2(std::max(std::abs(r->x()), std::abs(r->y())), r->z()) * 180.0 / 3.14159265358979323846;
    if (deg <= kMaxFieldAxisDeg) return {};
    char angle[32];
    std::snprintf(angle, sizeof angle, "%.1f", deg);
    return "the lens sees " + std::string(angle) + " degrees off the optical axis at pixel (" +
           std::to_string(u) + ", " + std::to_string(v) + "); augrig renders and augments within " +
           num(kMaxFieldAxisDeg) +
           " degrees of it, horizontally and vertically (a wider field cannot be "
           "rendered through one pinhole image): crop the image (roi) to that field";
  };
  for (int u = 0; u < m.width_px; ++u)
    for (int v : {0, m.height_px - 1})
      if (std::string p = beyond(u, v); !p.empty()) return p;
  for (int v = 0; v < m.height_px; ++v)
    for (int u : {0, m.width_px - 1})
      if (std::string p = beyond(u, v); !p.empty()) return p;
  return {};
}

CameraModel CameraModel::pinhole_from_hfov(int width_px, int height_px, double hfov_rad) {
  CameraModel m;
  m.width_px = width_px;
  m.height_px = height_px;
  // The image spans [-0.5, W - 0.5] (pixel centres at integers), so its edges are W/2 from the centre.
  m.fx_px = m.fy_px = (0.5 * width_px) / std::tan(0.5 * hfov_rad);
  m.cx_px = 0.5 * (width_px - 1);
  m.cy_px = 0.5 * (height_px - 1);
  return m;
}

std::optional<Eigen::Vector2d> CameraModel::project(const Eigen::Vector3d& p_cam) const {
  return project(p_cam, max_valid_radius());
}

std::optional<Eigen::Vector3d> CameraModel::ray(const Eigen::Vector2d& uv_px) const {
  if (!(fx_px > 0.0 && fy_px > 0.0)) return std::nullopt;
  const Eigen::Vector2d xd((uv_px.x() - cx_px) / fx_px, (uv_px.y() - cy_px) / fy_px);
  if (!xd.allFinite()) return std::nullopt;
  switch (distortion) {
    case DistortionModel::kNone:
      return Eigen::Vector3d(xd.x(), xd.y(), 1.0).normalized();

    case DistortionModel::kEquidistant: {
      // Radially symmetric: only theta is unknown, the direction is that of xd. Solving for theta
      // (not tan theta) keeps rays beyond 90 degrees representable.
      const double rd = xd.norm();
      if (rd == 0.0) return Eigen::Vector3d(0.0, 0.0, 1.0);
      const double th_max = max_valid_radius();
      if (!(rd < equi_theta_d(coeffs, th_max))) return std::nullopt;
      const double th = solve_monotone([&](double t) { return equi_theta_d(coeffs, t); },
                                       [&](double t) { return equi_dtheta_d(coeffs, t); }, rd, th_max, rd);
      if (!(th < th_max)) return std::nullopt;
      const double residual_px = std::abs(equi_theta_d(coeffs, th) - rd) * std::max(fx_px, fy_px);
      if (!(residual_px < 1e-9)) return std::nullopt;
      const double s = std::sin(th) / rd;
      return Eigen::Vector3d(xd.x() * s, xd.y() * s, std::cos(th));
    }

    case DistortionModel::kRadTan: {
      const double r_max = max_valid_radius();
      // Initial guess: invert the radial part alone along xd's direction (a 1-D monotone problem
      // with a guaranteed bracket), then polish with 2-D Newton including the tangential terms.
      // Why: plain Newton from xd overshoots past the fold for strong barrel distortion at corners.
      const double rd = xd.norm();
      Eigen::Vector2d x = xd;
      if (rd > 0.0) {
        auto f = [&](double r) { return r * radtan_radial(coeffs, r * r); };
        auto df = [&](double r) {
          const double r2 = r * r;
          return radtan_radial(coeffs, r2) + 2.0 * r2 * radtan_dradial_dr2(coeffs, r2);
        };
        double hi = r_max;
        if (std::isinf(hi)) {
          hi = std::max(1.0, rd);
          for (int i = 0; i < 200 && f(hi) < rd; ++i) hi *= 2.0;
        }
        // Only a start for Newton below, so a loose tolerance saves iterations; one fixed-point
        // step rd / radial(rd) is a better first guess than rd itself.
        const double r0 = std::min(rd / std::max(radtan_radial(coeffs, rd * rd), 1e-3), hi);
        const double r = rd < f(hi) ? solve_monotone(f, df, rd, hi, r0, 1e-7 * rd) : hi * (1.0 - 1e-9);
        x = xd * (r / rd);
      }
      const double k1 = coeffs[0], k2 = coeffs[1], p1 = coeffs[2], p2 = coeffs[3], k3 = coeffs[4];
      double residual_px = kInf;
      for (int i = 0; i < 20; ++i) {
        const double px = x.x(), py = x.y();
        const double r2 = px * px + py * py;
        const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        const double dR = k1 + r2 * (2.0 * k2 + r2 * 3.0 * k3);
        const double ex = px * radial + 2.0 * p1 * px * py + p2 * (r2 + 2.0 * px * px) - xd.x();
        const double ey = py * radial + p1 * (r2 + 2.0 * py * py) + 2.0 * p2 * px * py - xd.y();
        residual_px = std::max(std::abs(ex * fx_px), std::abs(ey * fy_px));
        if (residual_px < 1e-12) break;
        const double j00 = radial + 2.0 * px * px * dR + 2.0 * p1 * py + 6.0 * p2 * px;
        const double j01 = 2.0 * px * py * dR + 2.0 * p1 * px + 2.0 * p2 * py;
        const double j11 = radial + 2.0 * py * py * dR + 6.0 * p1 * py + 2.0 * p2 * px;
        const double det = j00 * j11 - j01 * j01;  // the Jacobian is symmetric
        if (!(std::abs(det) > 1e-300)) return std::nullopt;
        x.x() -= (j11 * ex - j01 * ey) / det;
        x.y() -= (j00 * ey - j01 * ex) / det;
        if (!x.allFinite()) return std::nullopt;
      }
      if (!(residual_px < 1e-9) || !(x.norm() < r_max)) return std::nullopt;
      return Eigen::Vector3d(x.x(), x.y(), 1.0).normalized();
    }
  }
  return std::nullopt;
}

std::optional<Eigen::Vector2d> CameraModel::undistort(const Eigen::Vector2d& uv_px) const {
  const auto r = ray(uv_px);
  // Normalised coordinates exist only in front of the camera; a tiny z would overflow them.
  if (!r || !(r->z() > 1e-12)) return std::nullopt;
  return Eigen::Vector2d(r->x() / r->z(), r->y() / r->z());
}

double CameraModel::max_valid_radius() const {
  return cached_max_valid_radius(distortion, coeffs);
}

Eigen::Matrix3d CameraModel::K() const {
  Eigen::Matrix3d k;
  k << fx_px, 0.0, cx_px, 0.0, fy_px, cy_px, 0.0, 0.0, 1.0;
  return k;
}

Eigen::VectorXd CameraModel::distortion_coeffs() const {
  switch (distortion) {
    case DistortionModel::kNone:
      return Eigen::VectorXd::Zero(5);
    case DistortionModel::kRadTan:
      return Eigen::Map<const Eigen::VectorXd>(coeffs.data(), 5);
    case DistortionModel::kEquidistant:
      return Eigen::Map<const Eigen::VectorXd>(coeffs.data(), 4);
  }
  return Eigen::VectorXd::Zero(5);
}

std::string CameraModel::distortion_name() const {
  switch (distortion) {
    case DistortionModel::kNone:
      return "none";
    case DistortionModel::kRadTan:
      return "radtan";
    case DistortionModel::kEquidistant:
      return "equidistant";
  }
  return "none";
}

}  // namespace augrig
