// Triangle set-up for render/soft_raster.hpp.
#include "render/soft_raster.hpp"

#include <Eigen/Geometry>

namespace augrig {

bool RasterTriangle::setup(const SampleGrid& g, const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                           const Eigen::Vector3d& p2, bool cull, const SampleBox& clip) {
  // det(p0, p1, p2) = n . p0 with n = (p1 - p0) x (p2 - p0): negative when the triangle faces the
  // camera (counter-clockwise from outside, camera at the origin), zero when seen edge-on.
  const double det = p0.dot(p1.cross(p2));
  if (det == 0 || !std::isfinite(det)) return false;
  if (cull && det > 0) return false;
  const double z_min = std::min({p0.z(), p1.z(), p2.z()}), z_max = std::max({p0.z(), p1.z(), p2.z()});
  if (z_max < g.near_m || z_min > g.far_m) return false;
  crosses_near = z_min < g.near_m;
  crosses_far = z_max > g.far_m;
  clips_depth = crosses_near || crosses_far;
  // Edge k is the plane through the camera centre and the edge (p_k, p_k+1). On the sample's ray
  // d(X, Y) = ((X - cx) / fx, (Y - cy) / fy, 1) it is affine in X and Y. The sign of det makes
  // every edge non-negative inside, in front of the camera.
  const double s = det > 0 ? 1.0 : -1.0;
  const Eigen::Vector3d c[3] = {s * p0.cross(p1), s * p1.cross(p2), s * p2.cross(p0)};
  for (int k = 0; k < 3; ++k) {
    ea[k] = c[k].x() / g.fx;
    eb[k] = c[k].y() / g.fy;
    ec[k] = c[k].z() - c[k].x() * g.cx / g.fx - c[k].y() * g.cy / g.fy;
    inv_ea[k] = ea[k] != 0 ? 1.0 / ea[k] : 0.0;
  }
  inv_area = 1.0 / std::abs(det);
  int n_lo = 0, n_hi = 0;
  for (int k = 0; k < 3; ++k) {
    const double m = -eb[k] * inv_ea[k], q = -ec[k] * inv_ea[k];
    if (ea[k] > 0) {
      if (n_lo < 2) lo_m[n_lo] = m, lo_q[n_lo] = q;
      ++n_lo;
    } else if (ea[k] < 0) {
      if (n_hi < 2) hi_m[n_hi] = m, hi_q[n_hi] = q;
      ++n_hi;
    }
  }
  two_sided = n_lo >= 1 && n_hi >= 1 && n_lo + n_hi == 3;
  if (n_lo == 1) lo_m[1] = lo_m[0], lo_q[1] = lo_q[0];
  if (n_hi == 1) hi_m[1] = hi_m[0], hi_q[1] = hi_q[0];
  wy = (eb[0] + eb[1] + eb[2]) * inv_area;
  wc = (ec[0] + ec[1] + ec[2]) * inv_area;

  // Bounds: the projected vertices' box when all lie in front of the camera (the projection is
  // then their convex hull), else the whole clip box (rows outside the triangle are empty spans).
  SampleBox b{std::max(clip.x0, 0), std::max(clip.y0, 0), std::min(clip.x1, g.width),
              std::min(clip.y1, g.height)};
  if (z_min > 0) {
    double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
    for (const Eigen::Vector3d* p : {&p0, &p1, &p2}) {
      const double x = g.fx * p->x() / p->z() + g.cx, y = g.fy * p->y() / p->z() + g.cy;
      x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
    }
    // One sample of margin against rounding in the projection; spans decide exactly.
    if (x1 < b.x0 - 1 || y1 < b.y0 - 1 || x0 > b.x1 + 1 || y0 > b.y1 + 1) return false;
    // Clamped as doubles first: a vertex just in front of the camera plane projects beyond int.
    auto clamp_to = [](double v, const int lo, const int hi) {
      return std::clamp(v, static_cast<double>(lo) - 2, static_cast<double>(hi) + 2);
    };
    b.x0 = std::max(b.x0, static_cast<int>(std::floor(clamp_to(x0, b.x0, b.x1))) - 1);
    b.y0 = std::max(b.y0, static_cast<int>(std::floor(clamp_to(y0, b.y0, b.y1))) - 1);
    b.x1 = std::min(b.x1, static_cast<int>(std::ceil(clamp_to(x1, b.x0, b.x1))) + 2);
    b.y1 = std::min(b.y1, static_cast<int>(std::ceil(clamp_to(y1, b.y0, b.y1))) + 2);
  }
  bounds = b;
  return b.x1 > b.x0 && b.y1 > b.y0;
}

}  // namespace augrig
