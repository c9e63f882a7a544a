// pbr: the boom's surface finish (glTF 2.0's metallic-roughness material) and what the camera
// look's light does to it: the sun's specular lobe (GGX / Trowbridge-Reitz microfacets, Smith's
// height-correlated visibility, Schlick's Fresnel) and the sky's and ground's sheen (Karis'
// analytic environment BRDF over the two hemispheres, no prefiltered maps). One implementation
// for the CPU rasteriser, the simulator's physical boom and (mirrored in GLSL) the GL shader, all
// three evaluating it at the vertices (Gouraud). docs/LOOK.md gives the formulas.
#pragma once

#include <string>

#include <Eigen/Core>

namespace augrig {

// glTF 2.0 pbrMetallicRoughness: metallic 0 (a dielectric: paint, plastic) .. 1 (bare metal),
// perceptual roughness 0 (a mirror) .. 1 (matte); the microfacet width is alpha = roughness^2.
struct SurfaceFinish {
  double metallic = 0.0;
  double roughness = 0.5;
  friend bool operator==(const SurfaceFinish&, const SurfaceFinish&) = default;
};

// The built-in boom's finish: weathered semi-gloss paint over metal (metallic 0: paint is a
// dielectric; roughness 0.5: a broad sheen, not a mirror; its highlight, about 18 deg wide in the
// normal's angle, is wider than the built-in tube's 15 deg facets, so vertices resolve it).
inline constexpr SurfaceFinish kPaintedBoom{0.0, 0.5};

// An empty string when `f` is a valid finish (both within [0, 1], not NaN), else what is wrong
// under the caller's names for them ("metallic 1.5 is outside [0, 1]"), for error messages.
std::string finish_problem(const SurfaceFinish& f, const char* metallic_name = "metallic",
                           const char* roughness_name = "roughness");

namespace pbr {

// Fresnel reflectance at normal incidence of a dielectric (index of refraction 1.5).
inline constexpr double kDielectricF0 = 0.04;
// Roughness below this is taken as this: a mirror's lobe is a delta that no vertex samples.
inline constexpr double kMinRoughness = 0.05;

// The sun's specular lobe on a surface of unit normal n seen along unit v (towards the eye) and lit
// along unit l (towards the sun): `s` = pi D(h) Vis(l, v) (n . l), so that the reflected light is
// direct * s * F per unit of the SceneLight's `direct`, and `w` = (1 - v . h)^5, Schlick's Fresnel
// weight (F = F0 + (1 - F0) w). Both 0 where the sun is behind the surface.
struct SunLobe {
  double s = 0, w = 0;
};
SunLobe sun_lobe(const Eigen::Vector3d& n, const Eigen::Vector3d& v, const Eigen::Vector3d& l,
                 double roughness);

// The directional albedo of the specular lobe under an even light (Karis, "Physically Based
// Shading on Mobile", 2014): F0 * a + b, for n . v and the roughness.
struct AmbientLobe {
  double a = 0, b = 0;
};
AmbientLobe ambient_lobe(double n_dot_v, double roughness);

}  // namespace pbr

}  // namespace augrig
