#include "render/boom_shadow.hpp"

#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "core/pose.hpp"
#include "render/models.hpp"

namespace augrig {
namespace {

// An axis-aligned box [lo, hi] as 12 triangles (windings mixed on purpose: the shadow ignores them).
std::vector<Eigen::Vector3d> box_triangles(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  auto corner = [&](int i) {
    return Eigen::Vector3d(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
  };
  const int quads[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
  std::vector<Eigen::Vector3d> v;
  for (const auto& q : quads)
    for (const int i : {q[0], q[1], q[2], q[0], q[3], q[2]}) v.push_back(corner(i));
  return v;
}

// Oracle for a box: the slab test of the ray p + t s, t > 0. `margin` receives how far the ray
// passes from deciding otherwise (in t), so that points on the shadow's edge can be skipped.
bool ray_hits_box(const Eigen::Vector3d& p, const Eigen::Vector3d& s, const Eigen::Vector3d& lo,
                  const Eigen::Vector3d& hi, double& margin) {
  double t0 = -1e300, t1 = 1e300;
  for (int a = 0; a < 3; ++a) {
    if (s[a] == 0) {
      if (p[a] < lo[a] || p[a] > hi[a]) {
        margin = std::min(std::abs(p[a] - lo[a]), std::abs(p[a] - hi[a]));
        return false;
      }
      continue;
    }
    double ta = (lo[a] - p[a]) / s[a], tb = (hi[a] - p[a]) / s[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta), t1 = std::min(t1, tb);
  }
  margin = std::min(std::abs(t1 - t0), std::abs(t1));
  return t1 >= t0 && t1 > 0;
}

TEST(BoomShadow, AFlatRodOverAPlaneUnderAHighSunShadowsItsOwnStrip) {
  BoomShadow shadow;
  const Eigen::Vector3d lo(-5, -0.2, -2.2), hi(5, 0.2, -1.8);  // NED: 2 m above the plane z = 0
  shadow.build(box_triangles(lo, hi), Eigen::Vector3d(0, 0, -1));
  EXPECT_EQ(shadow.triangles(), 4u);  // top and bottom: the four faces parallel to the sun shade nothing
  for (double y = -0.5; y <= 0.5; y += 0.01)
    for (double x = -6; x <= 6; x += 0.1) {
      if (std::abs(std::abs(y) - 0.2) < 1e-9 || std::abs(std::abs(x) - 5) < 1e-9) continue;
      EXPECT_EQ(shadow.in_shadow({x, y, 0}), std::abs(y) < 0.2 && std::abs(x) < 5) << x << ", " << y;
    }
  // Above the rod (nearer the sun) nothing is shadowed; inside it the ray still leaves through it.
  EXPECT_FALSE(shadow.in_shadow({0, 0, -3}));
  EXPECT_TRUE(shadow.in_shadow({0, 0, -2}));
}

TEST(BoomShadow, BoxesUnderAnySunAgreeWithTheSlabTest) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  int shaded = 0, compared = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const Eigen::Vector3d c(3 * u(rng), 3 * u(rng), 3 * u(rng));
    const Eigen::Vector3d half(0.1 + std::abs(u(rng)) * 3, 0.1 + std::abs(u(rng)) * 0.5, 0.1 + std::abs(u(rng)));
    const Eigen::Vector3d lo = c - half, hi = c + half;
    Eigen::Vector3d s(u(rng), u(rng), u(rng));
    if (trial % 10 == 0) s = Eigen::Vector3d(0, 0, 1);  // along an axis: faces edge-on
    s.normalize();
    BoomShadow shadow;
    shadow.build(box_triangles(lo, hi), s);
    for (int i = 0; i < 4000; ++i) {
      const Eigen::Vector3d p = c + Eigen::Vector3d(8 * u(rng), 8 * u(rng), 8 * u(rng));
      double margin = 0;
      const bool expected = ray_hits_box(p, s, lo, hi, margin);
      if (margin < 1e-7) continue;
      ++compared, shaded += expected;
      ASSERT_EQ(shadow.in_shadow(p), expected) << "trial " << trial << " point " << p.transpose();
    }
  }
  EXPECT_GT(shaded, 1000);
  EXPECT_GT(compared, 150000);
}

// Brute force: Moeller-Trumbore against every triangle.
bool brute_force(const std::vector<Eigen::Vector3d>& v, const Eigen::Vector3d& p, const Eigen::Vector3d& s) {
  for (std::size_t k = 0; k + 2 < v.size(); k += 3) {
    const Eigen::Vector3d e1 = v[k + 1] - v[k], e2 = v[k + 2] - v[k];
    const Eigen::Vector3d h = s.cross(e2);
    const double a = e1.dot(h);
    if (std::abs(a) < 1e-14) continue;
    const double f = 1 / a;
    const Eigen::Vector3d q = p - v[k];
    const double bu = f * q.dot(h);
    if (bu < 0 || bu > 1) continue;
    const Eigen::Vector3d r = q.cross(e1);
    const double bv = f * s.dot(r);
    if (bv < 0 || bu + bv > 1) continue;
    if (f * e2.dot(r) > 1e-9) return true;
  }
  return false;
}

TEST(BoomShadow, TheBuiltInBoomAgreesWithABruteForceRayCast) {
  const BoomModel boom = make_builtin_boom();
  const BoomArticulation a{deg_to_rad(30), deg_to_rad(2), 4.0};
  const Pose T_body_fixed = boom_pose(Eigen::Vector3d(-5, 0, 1), a), T_body_tele = T_body_fixed * telescope_pose(a);
  std::vector<Eigen::Vector3d> v;
  for (const auto& [model, T] : {std::pair{&boom.fixed, T_body_fixed}, std::pair{&boom.telescope, T_body_tele}})
    for (const Mesh& m : model->meshes)
      for (const std::uint32_t i : m.indices) v.push_back(T * m.positions_m[i].cast<double>());
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  int shaded = 0;
  for (const Eigen::Vector3d& sun : {Eigen::Vector3d(0.2, 0.1, -1), Eigen::Vector3d(-0.5, 0.7, -0.4),
                                    Eigen::Vector3d(0.9, 0, -0.2)}) {
    const Eigen::Vector3d s = sun.normalized();
    BoomShadow shadow;
    shadow.build(v, s);
    // Points below the boom, where its shadow falls: along the boom, pushed away from the sun.
    for (int i = 0; i < 20000; ++i) {
      const Eigen::Vector3d on_boom = v[static_cast<std::size_t>(std::abs(u(rng)) * (v.size() - 1))];
      const Eigen::Vector3d p = on_boom - s * (0.5 + 4 * std::abs(u(rng))) + 0.4 * Eigen::Vector3d(u(rng), u(rng), u(rng));
      const bool expected = brute_force(v, p, s);
      shaded += expected;
      ASSERT_EQ(shadow.in_shadow(p), expected) << "point " << p.transpose();
    }
  }
  EXPECT_GT(shaded, 5000);
}

TEST(BoomShadow, NothingBuiltShadowsNothing) {
  BoomShadow shadow;
  EXPECT_TRUE(shadow.empty());
  EXPECT_FALSE(shadow.in_shadow({0, 0, 0}));
  shadow.build({}, Eigen::Vector3d(0, 0, -1));
  EXPECT_FALSE(shadow.in_shadow({0, 0, 0}));
  // A sun of no direction builds nothing.
  shadow.build(box_triangles({-1, -1, -1}, {1, 1, 1}), Eigen::Vector3d::Zero());
  EXPECT_TRUE(shadow.empty());
  EXPECT_FALSE(shadow.in_shadow({0, 0, 5}));
}

}  // namespace
}  // namespace augrig
