// The boom's finish under the camera look's light (render/pbr.hpp, SceneLight::on(n, v, ...))
// against an independent evaluation: the textbook forms of GGX (from the half angle's tangent),
// Smith's height-correlated masking (from Lambda), Schlick's Fresnel on F0 = mix(0.04, albedo,
// metallic), and the diffuse light scaled by 1 - metallic; energy and limit cases; the ambient
// lobe against this BRDF's own directional albedo, integrated numerically.
#include "render/pbr.hpp"

#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "render/camera_look.hpp"

namespace augrig {
namespace {

using Eigen::Vector3d;

double alpha_of(double roughness) {
  const double r = std::max(roughness, pbr::kMinRoughness);
  return r * r;
}

// GGX from the half angle: D = alpha^2 / (pi cos^4 (alpha^2 + tan^2)^2).
double ggx_d(double cos_h, double alpha) {
  const double c2 = cos_h * cos_h, t2 = (1 - c2) / c2, a2 = alpha * alpha;
  return a2 / (kPi * c2 * c2 * (a2 + t2) * (a2 + t2));
}

// Smith's Lambda for GGX: (-1 + sqrt(1 + alpha^2 tan^2)) / 2.
double smith_lambda(double cos_t, double alpha) {
  const double c2 = cos_t * cos_t, t2 = (1 - c2) / c2;
  return (-1 + std::sqrt(1 + alpha * alpha * t2)) / 2;
}

// Karis' published fit, as written in "Physically Based Shading on Mobile" (vector form).
Eigen::Vector2d karis(double nv, double roughness) {
  const Eigen::Vector4d c0(-1, -0.0275, -0.572, 0.022), c1(1, 0.0425, 1.04, -0.04);
  const Eigen::Vector4d r = roughness * c0 + c1;
  const double a004 = std::min(r.x() * r.x(), std::exp2(-9.28 * nv)) * r.x() + r.y();
  const Eigen::Vector2d ab = Eigen::Vector2d(-1.04, 1.04) * a004 + Eigen::Vector2d(r.z(), r.w());
  return {ab.x(), std::max(ab.y(), 0.0)};
}

// The colour / 255 of a surface of albedo `rho`, evaluated from the textbook forms.
Vector3d reference(const SceneLight& light, const Vector3d& rho, const Vector3d& n, const Vector3d& v,
                   const SurfaceFinish& f) {
  const Vector3d& l = light.towards_light_body;
  const Vector3d& d = light.down_body;
  const double m = f.metallic, a = alpha_of(f.roughness);
  const Vector3d f0 = Vector3d::Constant(0.04 * (1 - m)) + m * rho;
  const Vector3d lambert = light.on(n, l, d);  // the diffuse light, tested on its own elsewhere
  Vector3d out = (1 - m) * rho.cwiseProduct(lambert);
  const double nl = n.dot(l), nv = std::max(n.dot(v), 1e-4);
  if (nl > 0) {
    const Vector3d h = (l + v).normalized();
    const double g2 = 1 / (1 + smith_lambda(nl, a) + smith_lambda(nv, a));
    const double brdf = ggx_d(n.dot(h), a) * g2 / (4 * nl * nv);  // times F
    const double schlick = std::pow(1 - v.dot(h), 5);
    for (int c = 0; c < 3; ++c) out[c] += kPi * brdf * (f0[c] + (1 - f0[c]) * schlick) * light.direct[c] * nl;
  }
  // The hemispheres along the lobe's dominant direction, times the lobe's directional albedo.
  const Vector3d mirror = 2 * n.dot(v) * n - v;
  const Vector3d dir = (1 - a) * mirror + a * n;
  const Eigen::Vector2d ab = karis(std::clamp(n.dot(v), 0.0, 1.0), f.roughness);
  for (int c = 0; c < 3; ++c) {
    const double hemi = light.sky[c] * (1 - dir.dot(d)) / 2 + light.ground[c] * (1 + dir.dot(d)) / 2;
    out[c] += hemi * (f0[c] * ab.x() + ab.y());
  }
  return out;
}

Vector3d colour(const SurfaceLight& s, const Vector3d& rho) {
  return rho.cwiseProduct(s.scale) + s.add;
}

Vector3d random_unit(std::mt19937& rng) {
  std::normal_distribution<double> g;
  return Vector3d(g(rng), g(rng), g(rng)).normalized();
}

SceneLight tinted_sun(const Vector3d& towards_sun) {
  SceneLight l = SceneLight::sun(towards_sun, true, LightSource::kConfigured);
  l.direct = Vector3d(0.75, 0.72, 0.69), l.sky = Vector3d(0.36, 0.40, 0.46),
  l.ground = Vector3d(0.22, 0.22, 0.20);
  return l;
}

TEST(Pbr, AgreesWithAnIndependentEvaluation) {
  std::mt19937 rng(33);
  std::uniform_real_distribution<double> u01(0, 1);
  int lit = 0;
  for (int i = 0; i < 2000; ++i) {
    const SceneLight light = tinted_sun(random_unit(rng));
    const Vector3d n = random_unit(rng);
    Vector3d v = random_unit(rng);
    if (v.dot(n) < 0) v = -v;  // a surface the eye sees
    const SurfaceFinish f{i % 3 == 0 ? 0.0 : u01(rng), i % 5 == 0 ? 1.0 : u01(rng)};
    const Vector3d rho(u01(rng), u01(rng), u01(rng));
    const SurfaceLight s = light.on(n, v, light.towards_light_body, light.down_body, f);
    const Vector3d want = reference(light, rho, n, v, f), got = colour(s, rho);
    ASSERT_LT((got - want).cwiseAbs().maxCoeff(), 1e-9 * std::max(1.0, want.maxCoeff()))
        << "case " << i << ": got " << got.transpose() << ", want " << want.transpose();
    lit += n.dot(light.towards_light_body) > 0;
  }
  EXPECT_GT(lit, 800);  // both sides of the terminator were tried
}

// No light, no colour: the specular terms scale with the light like the diffuse one.
TEST(Pbr, NoLightGivesNothing) {
  SceneLight dark = tinted_sun(Vector3d(0.3, 0.2, -1).normalized());
  dark.direct.setZero(), dark.sky.setZero(), dark.ground.setZero();
  std::mt19937 rng(1);
  for (int i = 0; i < 200; ++i) {
    const Vector3d n = random_unit(rng), v = random_unit(rng);
    for (const SurfaceFinish f :
         {SurfaceFinish{0, 0}, SurfaceFinish{1, 0.05}, SurfaceFinish{0.5, 1}, kPaintedBoom}) {
      const SurfaceLight s = dark.on(n, v, dark.towards_light_body, dark.down_body, f);
      EXPECT_EQ(s.scale, Vector3d::Zero());
      EXPECT_EQ(s.add, Vector3d::Zero());
    }
  }
}

// Roughness 1, metallic 0: the diffuse light unchanged and a small sheen added (the dielectric's
// 4 % Fresnel over the widest lobe) where the sun and the eye are not grazing.
TEST(Pbr, RoughDielectricIsLambertianPlusALittle) {
  std::mt19937 rng(7);
  double most = 0;
  for (int i = 0; i < 5000; ++i) {
    const SceneLight light = tinted_sun(random_unit(rng));
    const Vector3d n = random_unit(rng), v = random_unit(rng);
    if (n.dot(v) < 0.3 || n.dot(light.towards_light_body) < 0.3) continue;
    const SurfaceLight s = light.on(n, v, light.towards_light_body, light.down_body, SurfaceFinish{0, 1});
    EXPECT_EQ(s.scale, light.on(n, light.towards_light_body, light.down_body));
    for (int c = 0; c < 3; ++c) {
      EXPECT_GE(s.add[c], 0.0);
      most = std::max(most, s.add[c] / (light.direct[c] + light.sky[c]));
    }
  }
  std::printf("largest sheen over (direct + sky): %.4f\n", most);
  EXPECT_LT(most, 0.05);
}

// The glint: with the eye fixed, the sun's specular is largest where the sun lies along the eye's
// mirror direction, and there it is direct pi D(1) Vis F, D(1) = 1 / (pi alpha^2).
TEST(Pbr, TheGlintIsAtTheMirrorDirection) {
  const Vector3d n(0, 0, -1), v = Vector3d(0.6, 0.1, -0.8).normalized();
  const Vector3d mirror = 2 * n.dot(v) * n - v;
  for (const SurfaceFinish f : {SurfaceFinish{0, 0.3}, kPaintedBoom, SurfaceFinish{1, 0.4}}) {
    SCOPED_TRACE(f.metallic);
    double best = -1;
    Vector3d best_l = Vector3d::Zero();
    for (int i = 0; i <= 180; ++i)
      for (int j = 0; j < 360; ++j) {
        const double th = kPi / 2 * i / 180, ph = 2 * kPi * j / 360;
        const Vector3d l(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), -std::cos(th));
        SceneLight light = tinted_sun(l);
        light.sky.setZero(), light.ground.setZero();  // the sun's lobe alone
        const SurfaceLight s = light.on(n, v, l, light.down_body, f);
        const double c = colour(s, Vector3d::Ones())[0] - (1 - f.metallic) * light.direct[0] * n.dot(l);
        if (c > best) best = c, best_l = l;
      }
    EXPECT_LT(std::acos(std::min(1.0, best_l.dot(mirror))), deg_to_rad(1.5)) << best_l.transpose();
    const double a2 = std::pow(alpha_of(f.roughness), 2), nl = n.dot(mirror), nv = n.dot(v);
    const double vis =
        0.5 / (nl * std::sqrt(nv * nv * (1 - a2) + a2) + nv * std::sqrt(nl * nl * (1 - a2) + a2));
    const double f0 = f.metallic > 0 ? 1.0 : 0.04, fresnel = f0 + (1 - f0) * std::pow(1 - v.dot(n), 5);
    EXPECT_NEAR(best, 0.75 * (1 / a2) * vis * nl * fresnel, 0.02 * best);
    // A white metal's glint outshines its diffuse twin; a paint's is a sheen on top.
    EXPECT_GT(best, f.metallic > 0 ? 1.0 : 0.1);
  }
}

// The ambient lobe: Karis' fit against the directional albedo of this BRDF (GGX, Smith
// height-correlated), integrated by importance sampling the half vector. A dielectric's (F0 0.04)
// is held within 0.035; a metal's (F0 1) departs more at high roughness (printed, documented).
TEST(Pbr, AmbientLobeAgainstTheBrdfsDirectionalAlbedo) {
  auto exact = [](double nv, double roughness) {
    const double a = alpha_of(roughness), a2 = a * a;
    const Vector3d v(std::sqrt(1 - nv * nv), 0, nv);
    double A = 0, B = 0;
    constexpr int N = 200;
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j) {
        const double u = (i + 0.5) / N, th = std::atan(a * std::sqrt(u / (1 - u))),
                     ph = 2 * kPi * (j + 0.5) / N;
        const Vector3d h(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th));
        const double vh = v.dot(h);
        const Vector3d l = 2 * vh * h - v;
        if (vh <= 0 || l.z() <= 0) continue;
        const double nl = l.z();
        const double vis =
            0.5 / (nl * std::sqrt(nv * nv * (1 - a2) + a2) + nv * std::sqrt(nl * nl * (1 - a2) + a2));
        const double g = 4 * vis * nl * vh / h.z(), w = std::pow(1 - vh, 5);
        A += g * (1 - w), B += g * w;
      }
    return Eigen::Vector2d(A / (N * N), B / (N * N));
  };
  double worst_dielectric = 0, worst_metal = 0;
  for (const double r : {0.3, 0.5, 0.7, 1.0})
    for (const double nv : {0.2, 0.4, 0.7, 1.0}) {
      const pbr::AmbientLobe fit = pbr::ambient_lobe(nv, r);
      const Eigen::Vector2d k = karis(nv, r), e = exact(nv, r);
      EXPECT_NEAR(fit.a, k.x(), 1e-12);
      EXPECT_NEAR(fit.b, k.y(), 1e-12);
      worst_dielectric = std::max(worst_dielectric, std::abs(0.04 * (fit.a - e.x()) + fit.b - e.y()));
      worst_metal = std::max(worst_metal, std::abs(fit.a + fit.b - e.x() - e.y()));
    }
  std::printf("ambient lobe against the integral: dielectric within %.4f, metal within %.4f\n",
              worst_dielectric, worst_metal);
  EXPECT_LT(worst_dielectric, 0.035);
  EXPECT_LT(worst_metal, 0.22);
  // A smooth mirror facing the eye reflects all of an even light (F0 1) and 4 % as a dielectric.
  const pbr::AmbientLobe mirror = pbr::ambient_lobe(1.0, 0.0);
  EXPECT_NEAR(mirror.a + mirror.b, 1.0, 0.01);
  EXPECT_NEAR(0.04 * mirror.a + mirror.b, 0.04, 0.01);
}

TEST(Pbr, FinishProblemsNameTheValue) {
  EXPECT_EQ(finish_problem(kPaintedBoom), "");
  EXPECT_EQ(finish_problem(SurfaceFinish{1, 0}), "");
  EXPECT_EQ(finish_problem(SurfaceFinish{1.5, 0.5}), "metallic 1.5 is outside [0, 1]");
  EXPECT_EQ(finish_problem(SurfaceFinish{0, -0.25}, "Pm", "Pr"), "Pr -0.25 is outside [0, 1]");
  EXPECT_NE(finish_problem(SurfaceFinish{std::nan(""), 0.5}), "");
}

}  // namespace
}  // namespace augrig
