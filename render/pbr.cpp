#include "render/pbr.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "render/camera_look.hpp"

namespace augrig {

std::string finish_problem(const SurfaceFinish& f, const char* metallic_name, const char* roughness_name) {
  std::ostringstream o;
  for (const auto& [name, x] : {std::pair{metallic_name, f.metallic}, std::pair{roughness_name, f.roughness}})
    if (!(x >= 0.0 && x <= 1.0)) {
      o << name << " " << x << " is outside [0, 1]";
      return o.str();
    }
  return {};
}

namespace pbr {

SunLobe sun_lobe(const Eigen::Vector3d& n, const Eigen::Vector3d& v, const Eigen::Vector3d& l,
                 double roughness) {
  const double nl = n.dot(l);
  if (!(nl > 0)) return {};
  // A vertex normal may face a little away from the eye on a visible triangle (smooth normals at a
  // silhouette): held just above 0, as real-time renderers do, so the lobe stays continuous there.
  const double nv = std::max(n.dot(v), 1e-4);
  const Eigen::Vector3d h_sum = l + v;
  const double h_len = h_sum.norm();
  if (!(h_len > 1e-12)) return {};  // the sun exactly behind the eye's ray: no half vector
  const Eigen::Vector3d h = h_sum / h_len;
  const double r = std::clamp(roughness, kMinRoughness, 1.0);
  const double a2 = r * r * r * r;  // alpha^2, alpha = roughness^2
  const double nh = std::max(n.dot(h), 0.0);
  const double d = nh * nh * (a2 - 1) + 1;
  const double pi_D = a2 / (d * d);  // GGX: D = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)
  // Smith-GGX height-correlated: Vis = G / (4 (n.l) (n.v)).
  const double vis =
      0.5 / (nl * std::sqrt(nv * nv * (1 - a2) + a2) + nv * std::sqrt(nl * nl * (1 - a2) + a2));
  const double m = 1 - std::clamp(v.dot(h), 0.0, 1.0);
  const double m2 = m * m;
  return {pi_D * vis * nl, m2 * m2 * m};
}

AmbientLobe ambient_lobe(double n_dot_v, double roughness) {
  const double r = std::clamp(roughness, 0.0, 1.0), nv = std::clamp(n_dot_v, 0.0, 1.0);
  // Karis' fit: r4 = roughness * c0 + c1, c0 = (-1, -0.0275, -0.572, 0.022), c1 = (1, 0.0425, 1.04, -0.04).
  const double x = 1 - r, y = 0.0425 - 0.0275 * r, z = 1.04 - 0.572 * r, w = -0.04 + 0.022 * r;
  const double a004 = std::min(x * x, std::exp2(-9.28 * nv)) * x + y;
  // The fit's b dips to -0.0024 at roughness 1: a reflectance is never negative.
  return {-1.04 * a004 + z, std::max(1.04 * a004 + w, 0.0)};
}

}  // namespace pbr

SurfaceLight SceneLight::on(const Eigen::Vector3d& n, const Eigen::Vector3d& v,
                            const Eigen::Vector3d& towards_light, const Eigen::Vector3d& down,
                            const SurfaceFinish& f) const {
  const Eigen::Vector3d lambert = on(n, towards_light, down);
  const double m = std::clamp(f.metallic, 0.0, 1.0), r = std::clamp(f.roughness, 0.0, 1.0);
  const pbr::SunLobe sun = pbr::sun_lobe(n, v, towards_light, r);
  const pbr::AmbientLobe amb = pbr::ambient_lobe(n.dot(v), r);
  // The hemispheres' light as the lobe sees it: along the mirror direction for a smooth surface,
  // along the normal for a matte one (a linear blend; the hemisphere light is linear in it).
  const Eigen::Vector3d mirror = 2 * n.dot(v) * n - v;
  const double alpha = std::max(r, pbr::kMinRoughness) * std::max(r, pbr::kMinRoughness);
  const double q = (n + (1 - alpha) * (mirror - n)).dot(down);
  const double f0 = pbr::kDielectricF0 * (1 - m);  // the dielectric share of F0; the metal's is m * albedo
  SurfaceLight out;
  for (int c = 0; c < 3; ++c) {
    const double hemi = sky[c] * 0.5 * (1 - q) + ground[c] * 0.5 * (1 + q);
    const double sun_spec = direct[c] * sun.s;
    // F = F0 (1 - w) + w with F0 = 0.04 (1 - m) + m albedo: the albedo's part scales, the rest adds.
    out.scale[c] = (1 - m) * lambert[c] + m * ((1 - sun.w) * sun_spec + amb.a * hemi);
    out.add[c] = sun_spec * (f0 * (1 - sun.w) + sun.w) + hemi * (f0 * amb.a + amb.b);
  }
  return out;
}

}  // namespace augrig
