// BoomShadow: which points lie in the boom's shadow, exactly. The boom's triangles are projected
// along the sun's direction onto the plane perpendicular to it and binned in a grid over their
// footprint; a point is in shadow when the ray from it towards the sun's centre crosses one of
// them: a point-in-triangle test in that plane (double precision, no tolerance) and the
// triangle's height along the sun above the point. The augmenter uses it for the mask's
// kMaskShadow bit and the camera look's darkening, the simulator for its physical boom's shadow.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace augrig {

class BoomShadow {
 public:
  // The occluders: triangles as consecutive vertex triples (any frame F); `towards_sun_F` the
  // direction to the sun in F (normalised here). Replaces what was built before; reuses memory.
  void build(const std::vector<Eigen::Vector3d>& triangle_vertices, const Eigen::Vector3d& towards_sun_F);
  void clear();
  bool empty() const { return tris_.empty(); }

  // Whether the ray from `p_F` towards the sun passes through a triangle (one farther along the
  // sun than the point by more than 1e-9 m).
  bool in_shadow(const Eigen::Vector3d& p_F) const { return in_shadow_sun(R_sun_F_ * p_F); }
  // The same for a point already in the sun frame (rows of R_sun_F(): e1, e2, towards the sun).
  bool in_shadow_sun(const Eigen::Vector3d& q) const;
  // Whether any triangle's projection may cover the plane point (u, v): a cheap first test.
  bool may_cover(double u, double v) const {
    const double gx = (u - u0_) * inv_cell_, gy = (v - v0_) * inv_cell_;
    if (!(gx >= 0 && gy >= 0 && gx < nx_ && gy < ny_)) return false;
    const std::size_t c = static_cast<std::size_t>(gy) * static_cast<std::size_t>(nx_) + static_cast<std::size_t>(gx);
    return cell_start_[c] != cell_start_[c + 1];
  }
  const Eigen::Matrix3d& R_sun_F() const { return R_sun_F_; }
  std::size_t triangles() const { return tris_.size(); }

 private:
  // A triangle in the sun frame: edge functions in the plane (inside when all >= 0, or all <= 0
  // for the other winding, made >= 0 by the sign) and its plane's height w(u, v) = a u + b v + c.
  struct Tri {
    double ea[3], eb[3], ec[3];
    double wa, wb, wc;
  };
  Eigen::Matrix3d R_sun_F_ = Eigen::Matrix3d::Identity();
  std::vector<Tri> tris_;
  double u0_ = 0, v0_ = 0, inv_cell_ = 1;
  int nx_ = 0, ny_ = 0;
  std::vector<std::uint32_t> cell_start_, cell_tris_;  // CSR: the triangles overlapping each cell
  std::vector<std::uint32_t> counts_;                   // build scratch
};

}  // namespace augrig
