#include "render/boom_shadow.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

namespace augrig {

namespace {

// Most cells along the footprint's longer side: fine enough that a point far from the boom's
// shadow finds an empty cell, coarse enough that building costs little beside a frame.
constexpr double kCellsLongSide = 96;

// The column range [i0, i1] of cells that the projected triangle `p` touches within the band of
// plane coordinates v in [v_lo, v_hi]: the triangle clipped to the band, its extent in u.
bool band_extent(const Eigen::Vector2d p[3], double v_lo, double v_hi, double& u_min, double& u_max) {
  u_min = std::numeric_limits<double>::infinity(), u_max = -u_min;
  auto take = [&](double u) { u_min = std::min(u_min, u), u_max = std::max(u_max, u); };
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector2d& a = p[i];
    const Eigen::Vector2d& b = p[(i + 1) % 3];
    if (a.y() >= v_lo && a.y() <= v_hi) take(a.x());
    // Where the edge crosses either of the band's lines.
    for (const double line : {v_lo, v_hi})
      if ((a.y() - line) * (b.y() - line) < 0) take(a.x() + (b.x() - a.x()) * (line - a.y()) / (b.y() - a.y()));
  }
  return u_min <= u_max;
}

}  // namespace

void BoomShadow::clear() {
  tris_.clear();
  nx_ = ny_ = 0;
  cell_start_.assign(1, 0);
  cell_tris_.clear();
}

void BoomShadow::build(const std::vector<Eigen::Vector3d>& triangle_vertices, const Eigen::Vector3d& towards_sun_F) {
  clear();
  const Eigen::Vector3d s = towards_sun_F.normalized();
  if (!s.allFinite()) return;
  // Plane axes: any two unit vectors completing the sun's direction to a right-handed frame.
  Eigen::Vector3d helper = Eigen::Vector3d::UnitX();
  if (std::abs(s.x()) > 0.6) helper = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d e1 = s.cross(helper).normalized(), e2 = s.cross(e1);
  R_sun_F_.row(0) = e1, R_sun_F_.row(1) = e2, R_sun_F_.row(2) = s;

  // Each triangle in the sun frame: its edge functions in the plane and its height plane.
  std::vector<std::array<Eigen::Vector2d, 3>> flat;
  const std::size_t n = triangle_vertices.size() / 3;
  double u_lo = std::numeric_limits<double>::infinity(), v_lo = u_lo, u_hi = -u_lo, v_hi = -u_lo;
  for (std::size_t t = 0; t < n; ++t) {
    Eigen::Vector3d q[3];
    for (int i = 0; i < 3; ++i) q[i] = R_sun_F_ * triangle_vertices[3 * t + static_cast<std::size_t>(i)];
    const Eigen::Vector3d nrm = (q[1] - q[0]).cross(q[2] - q[0]);
    // Seen edge-on from the sun, a triangle shades no area (its neighbours do).
    if (!(std::abs(nrm.z()) > 1e-12 * nrm.norm()) || !nrm.allFinite()) continue;
    const double sign = nrm.z() > 0 ? 1.0 : -1.0;
    Tri tri{};
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d& a = q[i];
      const Eigen::Vector3d& b = q[(i + 1) % 3];
      // (b - a) x (p - a) in the plane, positive inside for either winding.
      tri.ea[i] = -sign * (b.y() - a.y());
      tri.eb[i] = sign * (b.x() - a.x());
      tri.ec[i] = sign * ((b.y() - a.y()) * a.x() - (b.x() - a.x()) * a.y());
    }
    tri.wa = -nrm.x() / nrm.z(), tri.wb = -nrm.y() / nrm.z();
    tri.wc = q[0].z() - tri.wa * q[0].x() - tri.wb * q[0].y();
    tris_.push_back(tri);
    flat.push_back({q[0].head<2>(), q[1].head<2>(), q[2].head<2>()});
    for (const Eigen::Vector3d& v : q)
      u_lo = std::min(u_lo, v.x()), u_hi = std::max(u_hi, v.x()), v_lo = std::min(v_lo, v.y()),
      v_hi = std::max(v_hi, v.y());
  }
  if (tris_.empty()) return;

  // The grid over the footprint, cells square.
  const double cell = std::max(std::max(u_hi - u_lo, v_hi - v_lo) / kCellsLongSide, 1e-6);
  u0_ = u_lo, v0_ = v_lo, inv_cell_ = 1.0 / cell;
  nx_ = std::max(1, static_cast<int>(std::ceil((u_hi - u_lo) * inv_cell_)) + 1);
  ny_ = std::max(1, static_cast<int>(std::ceil((v_hi - v_lo) * inv_cell_)) + 1);
  const std::size_t cells = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_);
  // Each triangle into every cell its clipped extent touches: counted, then placed (CSR).
  auto for_each_cell = [&](std::size_t t, auto&& fn) {
    const auto& p = flat[t];
    const double tv_lo = std::min({p[0].y(), p[1].y(), p[2].y()}), tv_hi = std::max({p[0].y(), p[1].y(), p[2].y()});
    const int j0 = std::clamp(static_cast<int>((tv_lo - v0_) * inv_cell_ - 1e-6), 0, ny_ - 1);
    const int j1 = std::clamp(static_cast<int>((tv_hi - v0_) * inv_cell_ + 1e-6), 0, ny_ - 1);
    for (int j = j0; j <= j1; ++j) {
      // The band and the extent a little widened: a point on a cell's border may round either way.
      double a, b;
      if (!band_extent(p.data(), v0_ + (j - 1e-6) * cell, v0_ + (j + 1 + 1e-6) * cell, a, b)) continue;
      const int i0 = std::clamp(static_cast<int>((a - u0_) * inv_cell_ - 1e-6), 0, nx_ - 1);
      const int i1 = std::clamp(static_cast<int>((b - u0_) * inv_cell_ + 1e-6), 0, nx_ - 1);
      for (int i = i0; i <= i1; ++i) fn(static_cast<std::size_t>(j) * static_cast<std::size_t>(nx_) + i);
    }
  };
  counts_.assign(cells, 0);
  for (std::size_t t = 0; t < tris_.size(); ++t) for_each_cell(t, [&](std::size_t c) { ++counts_[c]; });
  cell_start_.assign(cells + 1, 0);
  for (std::size_t c = 0; c < cells; ++c) cell_start_[c + 1] = cell_start_[c] + counts_[c];
  cell_tris_.resize(cell_start_[cells]);
  for (std::size_t c = 0; c < cells; ++c) counts_[c] = cell_start_[c];
  for (std::size_t t = 0; t < tris_.size(); ++t)
    for_each_cell(t, [&](std::size_t c) { cell_tris_[counts_[c]++] = static_cast<std::uint32_t>(t); });
}

bool BoomShadow::in_shadow_sun(const Eigen::Vector3d& q) const {
  const double gx = (q.x() - u0_) * inv_cell_, gy = (q.y() - v0_) * inv_cell_;
  if (!(gx >= 0 && gy >= 0 && gx < nx_ && gy < ny_)) return false;
  const std::size_t c = static_cast<std::size_t>(gy) * static_cast<std::size_t>(nx_) + static_cast<std::size_t>(gx);
  for (std::uint32_t k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
    const Tri& t = tris_[cell_tris_[k]];
    bool inside = true;
    for (int i = 0; i < 3 && inside; ++i) inside = t.ea[i] * q.x() + t.eb[i] * q.y() + t.ec[i] >= 0;
    if (inside && t.wa * q.x() + t.wb * q.y() + t.wc > q.z() + 1e-9) return true;
  }
  return false;
}

}  // namespace augrig
