// Built-in models: closed, outward-facing shells, dimensions, triangle budgets, the receptacle on the
// fuselage surface, the livery texture, and boom_pose / telescope_pose by hand-worked cases.
#include "render/models.hpp"

#include <cmath>
#include <map>
#include <optional>
#include <set>
#include <tuple>

#include <gtest/gtest.h>

#include "core/conventions.hpp"

namespace augrig {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;

// Vertices at the same position (within 10 um) are one point for topology: meshes duplicate
// vertices at uv seams and normal creases.
using PointKey = std::tuple<long, long, long>;
PointKey key(const Vector3f& p) {
  return {std::lround(p.x() * 1e5), std::lround(p.y() * 1e5), std::lround(p.z() * 1e5)};
}

struct ShellReport {
  int shells = 0;
  int bad_edges = 0;          // edges not used exactly once in each direction
  int inward_shells = 0;      // signed volume <= 0
  int normal_mismatches = 0;  // vertex normal pointing against its face
  int non_unit_normals = 0;
};

// Checks that a mesh is a union of closed, consistently wound, outward-facing shells.
ShellReport check_shells(const Mesh& m) {
  ShellReport r;
  std::map<PointKey, int> ids;
  std::vector<int> pid(m.positions_m.size());
  for (std::size_t i = 0; i < m.positions_m.size(); ++i) {
    pid[i] = ids.try_emplace(key(m.positions_m[i]), static_cast<int>(ids.size())).first->second;
  }
  // Directed edges: in a closed, consistently oriented surface each appears once, its reverse once.
  std::map<std::pair<int, int>, int> directed;
  for (std::size_t t = 0; t < m.indices.size(); t += 3) {
    for (int k = 0; k < 3; ++k) directed[{pid[m.indices[t + k]], pid[m.indices[t + (k + 1) % 3]]}]++;
  }
  for (const auto& [e, n] : directed) {
    const auto rev = directed.find({e.second, e.first});
    if (n != 1 || rev == directed.end() || rev->second != 1) ++r.bad_edges;
  }
  // Connected components (by shared points) and their signed volumes.
  std::vector<int> parent(ids.size());
  for (std::size_t i = 0; i < parent.size(); ++i) parent[i] = static_cast<int>(i);
  std::function<int(int)> find = [&](int x) { return parent[x] == x ? x : parent[x] = find(parent[x]); };
  for (std::size_t t = 0; t < m.indices.size(); t += 3) {
    parent[find(pid[m.indices[t]])] = find(pid[m.indices[t + 1]]);
    parent[find(pid[m.indices[t]])] = find(pid[m.indices[t + 2]]);
  }
  std::map<int, double> volume;
  for (std::size_t t = 0; t < m.indices.size(); t += 3) {
    const Vector3d a = m.positions_m[m.indices[t]].cast<double>();
    const Vector3d b = m.positions_m[m.indices[t + 1]].cast<double>();
    const Vector3d c = m.positions_m[m.indices[t + 2]].cast<double>();
    volume[find(pid[m.indices[t]])] += a.dot(b.cross(c)) / 6.0;
    const Vector3f fn = (m.positions_m[m.indices[t + 1]] - m.positions_m[m.indices[t]])
                            .cross(m.positions_m[m.indices[t + 2]] - m.positions_m[m.indices[t]]);
    for (int k = 0; k < 3; ++k) {
      if (fn.dot(m.normals[m.indices[t + k]]) <= 0.0f) ++r.normal_mismatches;
    }
  }
  r.shells = static_cast<int>(volume.size());
  for (const auto& [c, v] : volume)
    if (v <= 0) ++r.inward_shells;
  for (const auto& n : m.normals)
    if (std::abs(n.norm() - 1.0f) > 1e-4f) ++r.non_unit_normals;
  return r;
}

void expect_closed_outward(const Model& model, int expected_shells_total) {
  int shells = 0;
  for (const auto& m : model.meshes) {
    SCOPED_TRACE(m.name);
    ASSERT_EQ(m.normals.size(), m.positions_m.size());
    ASSERT_TRUE(m.uvs.empty() || m.uvs.size() == m.positions_m.size());
    for (auto i : m.indices) ASSERT_LT(i, m.positions_m.size());
    const ShellReport r = check_shells(m);
    EXPECT_EQ(r.bad_edges, 0);
    EXPECT_EQ(r.inward_shells, 0);
    EXPECT_EQ(r.normal_mismatches, 0);
    EXPECT_EQ(r.non_unit_normals, 0);
    shells += r.shells;
  }
  EXPECT_EQ(shells, expected_shells_total);
}

const Mesh* find_mesh(const Model& m, const std::string& name) {
  for (const auto& mesh : m.meshes)
    if (mesh.name == name) return &mesh;
  return nullptr;
}

TEST(BuiltinBoom, ClosedOutwardShells) {
  const BoomModel boom = make_builtin_boom();
  // fairing, outer tube, two ruddevators | inner tube, nozzle
  expect_closed_outward(boom.fixed, 4);
  expect_closed_outward(boom.telescope, 2);
}

TEST(BuiltinBoom, DimensionsAndBudget) {
  const BoomDimensions d;
  const BoomModel boom = make_builtin_boom(d);
  const std::size_t tris = boom.fixed.triangle_count() + boom.telescope.triangle_count();
  EXPECT_LE(tris, 1500u);
  RecordProperty("boom_triangles", static_cast<int>(tris));
  std::printf("boom triangles: fixed %zu, telescope %zu\n", boom.fixed.triangle_count(),
              boom.telescope.triangle_count());

  // Telescope tip at nozzle_tip_m(0); it is a body of revolution about the x axis.
  const auto [tlo, thi] = boom.telescope.bounds();
  EXPECT_NEAR(thi.x(), d.nozzle_tip_m(0), 1e-5);
  EXPECT_NEAR(d.nozzle_tip_m(0), 8.5, 1e-12);
  EXPECT_NEAR(thi.y(), -tlo.y(), 1e-5);
  EXPECT_NEAR(thi.z(), -tlo.z(), 1e-5);
  // Inner tube: diameter 0.25, aft end 1 m beyond the outer tube, 7 m long.
  const Mesh* inner = find_mesh(boom.telescope, "inner_tube");
  ASSERT_TRUE(inner);
  EXPECT_NEAR(inner->bounds().second.y(), 0.125, 1e-4);
  EXPECT_NEAR(inner->bounds().second.x(), 8.0, 1e-5);
  EXPECT_NEAR(inner->bounds().second.x() - inner->bounds().first.x(), 7.0, 1e-5);

  const Mesh* outer = find_mesh(boom.fixed, "outer_tube");
  ASSERT_TRUE(outer);
  EXPECT_NEAR(outer->bounds().first.x(), 0.0, 1e-5);
  EXPECT_NEAR(outer->bounds().second.x(), 7.0, 1e-5);
  EXPECT_NEAR(outer->bounds().second.y(), 0.23, 1e-4);
  ASSERT_TRUE(outer->texture);

  const Mesh* fairing = find_mesh(boom.fixed, "fairing");
  ASSERT_TRUE(fairing);
  EXPECT_NEAR(2 * fairing->bounds().second.y(), 0.7, 0.01);
  EXPECT_LT(fairing->bounds().first.x(), 0.0f);  // around the pivot
  EXPECT_LT(fairing->bounds().second.x(), 1.5f);

  // Ruddevators: leading edge at the station, a V rising above the boom (towards -z), symmetric in y,
  // tips 0.23 + 2.1 m out along the 37.5 deg dihedral.
  const Mesh* rud = find_mesh(boom.fixed, "ruddevators");
  ASSERT_TRUE(rud);
  const auto [rlo, rhi] = rud->bounds();
  EXPECT_NEAR(rlo.x(), 5.2, 1e-4);
  EXPECT_LT(rhi.x(), 7.0f);
  EXPECT_NEAR(rhi.y(), -rlo.y(), 1e-4);
  const double reach = 0.23 + 2.1, dih = deg_to_rad(37.5);
  EXPECT_NEAR(rhi.y(), reach * std::cos(dih), 0.05);
  EXPECT_NEAR(rlo.z(), -reach * std::sin(dih), 0.05);
  EXPECT_LT(rhi.z(), 0.2f);  // nothing hangs below the tube
  // Thin: the slab's extent across its own plane is ~8 cm (at the root; the tip keeps t/c).
  const Vector3f thick_dir(0, std::sin(dih), std::cos(dih));
  float tmin = 1e9f, tmax = -1e9f;
  for (const auto& p : rud->positions_m) {
    if (p.y() <= 0.0f) continue;  // right panel
    tmin = std::min(tmin, p.dot(thick_dir));
    tmax = std::max(tmax, p.dot(thick_dir));
  }
  EXPECT_NEAR(tmax - tmin, 0.08, 0.01);
}

// The built-in boom is painted (render/pbr.hpp: kPaintedBoom) until the rig's boom.material says
// otherwise; a model file's own finish stays.
TEST(BuiltinBoom, PaintedUnlessTheRigSaysOtherwise) {
  BoomModel boom = make_builtin_boom();
  for (const Model* part : {&boom.fixed, &boom.telescope})
    for (const Mesh& m : part->meshes) EXPECT_EQ(m.finish, kPaintedBoom) << m.name;
  boom.fixed.meshes[0].finish = SurfaceFinish{1.0, 0.2};
  boom.fixed.meshes[0].finish_from_file = true;
  apply_boom_material(boom, std::nullopt);
  EXPECT_EQ(boom.fixed.meshes[1].finish, kPaintedBoom);
  apply_boom_material(boom, SurfaceFinish{0.5, 0.7});
  EXPECT_EQ(boom.fixed.meshes[0].finish, (SurfaceFinish{1.0, 0.2})) << "the file's";
  for (const Model* part : {&boom.fixed, &boom.telescope})
    for (std::size_t i = part == &boom.fixed ? 1 : 0; i < part->meshes.size(); ++i)
      EXPECT_EQ(part->meshes[i].finish, (SurfaceFinish{0.5, 0.7})) << part->meshes[i].name;
}

TEST(BuiltinBoom, ScalesWithDimensions) {
  BoomDimensions d;
  d.nozzle_length_m = 0.6;
  d.telescope_stick_out_m = 1.5;
  const BoomModel boom = make_builtin_boom(d);
  EXPECT_NEAR(boom.telescope.bounds().second.x(), d.nozzle_tip_m(0), 1e-5);
  expect_closed_outward(boom.telescope, 2);
}

// First intersection of the ray o + t*dir (t > 0) with a mesh.
std::optional<double> ray_hit(const Mesh& m, const Vector3d& o, const Vector3d& dir) {
  std::optional<double> best;
  for (std::size_t t = 0; t < m.indices.size(); t += 3) {
    const Vector3d a = m.positions_m[m.indices[t]].cast<double>();
    const Vector3d b = m.positions_m[m.indices[t + 1]].cast<double>();
    const Vector3d c = m.positions_m[m.indices[t + 2]].cast<double>();
    const Vector3d e1 = b - a, e2 = c - a, p = dir.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-15) continue;
    const Vector3d s = o - a;
    const double u = s.dot(p) / det;
    const Vector3d q = s.cross(e1);
    const double v = dir.dot(q) / det;
    const double dist = e2.dot(q) / det;
    if (u < -1e-9 || v < -1e-9 || u + v > 1 + 1e-9 || dist <= 0) continue;
    if (!best || dist < *best) best = dist;
  }
  return best;
}

TEST(BuiltinReceiver, ClosedOutwardShellsAndBudget) {
  const Model rx = make_builtin_receiver();
  // fuselage, 2 wings, 2 nacelles, 2 spinners, fin, tailplane
  expect_closed_outward(rx, 9);
  EXPECT_LE(rx.triangle_count(), 6000u);
  std::printf("receiver triangles: %zu in %zu meshes\n", rx.triangle_count(), rx.meshes.size());
}

TEST(BuiltinReceiver, DimensionsWithinFivePercent) {
  const Model rx = make_builtin_receiver();
  const auto [lo, hi] = rx.bounds();
  EXPECT_NEAR(hi.x() - lo.x(), 13.3, 0.05 * 13.3);
  EXPECT_NEAR(hi.y() - lo.y(), 16.6, 0.05 * 16.6);
  EXPECT_NEAR(hi.y(), -lo.y(), 1e-4);  // symmetric
  // Nose forward, origin inside the aircraft's extent, tail above the fuselage (T-tail).
  EXPECT_GT(hi.x(), 4.0f);
  EXPECT_LT(lo.x(), -7.0f);
  EXPECT_LT(lo.z(), -2.5f);
  EXPECT_GT(hi.z(), 0.3f);
  EXPECT_LT(hi.z(), 1.0f);
}

TEST(BuiltinReceiver, ReceptacleLiesOnTopOfTheNose) {
  Vector3d receptacle = Vector3d::Constant(99);
  const Model rx = make_builtin_receiver(&receptacle);
  EXPECT_NEAR(receptacle.x(), 4.0, 0.3);
  EXPECT_NEAR(receptacle.y(), 0.0, 1e-9);
  EXPECT_NEAR(receptacle.z(), -0.9, 0.15);
  // Dropping a ray straight down (+z) from above hits the fuselage first, at the receptacle.
  const Mesh* fus = find_mesh(rx, "fuselage");
  ASSERT_TRUE(fus);
  const Vector3d from(receptacle.x(), receptacle.y(), -10.0);
  const auto t = ray_hit(*fus, from, Vector3d::UnitZ());
  ASSERT_TRUE(t);
  EXPECT_NEAR(from.z() + *t, receptacle.z(), 1e-3);
  for (const auto& m : rx.meshes) {
    const auto tm = ray_hit(m, from, Vector3d::UnitZ());
    if (tm) {
      EXPECT_GE(*tm, *t - 1e-4) << m.name << " lies above the receptacle";
    }
  }
}

TEST(BuiltinReceiver, TexturedLiveryWithSpeckle) {
  const Model rx = make_builtin_receiver();
  std::shared_ptr<const Texture> tex;
  for (const auto& m : rx.meshes) {
    SCOPED_TRACE(m.name);
    ASSERT_TRUE(m.texture);
    ASSERT_EQ(m.uvs.size(), m.positions_m.size());
    for (const auto& uv : m.uvs) {
      EXPECT_GE(uv.x(), 0.0f);
      EXPECT_LE(uv.x(), 1.0f);
      EXPECT_GE(uv.y(), 0.0f);
      EXPECT_LE(uv.y(), 1.0f);
    }
    if (tex) {
      EXPECT_EQ(tex, m.texture);  // one shared atlas
    }
    tex = m.texture;
  }
  ASSERT_TRUE(tex);
  EXPECT_EQ(tex->width, 1024);
  EXPECT_EQ(tex->height, 512);
  ASSERT_EQ(tex->rgba.size(), 1024u * 512u * 4u);
  // Texture everywhere: in every 16x16 block the luminance varies.
  int flat_blocks = 0;
  for (int by = 0; by < 512; by += 16) {
    for (int bx = 0; bx < 1024; bx += 16) {
      double s = 0, s2 = 0;
      for (int y = by; y < by + 16; ++y) {
        for (int x = bx; x < bx + 16; ++x) {
          const std::uint8_t* p = tex->rgba.data() + (static_cast<std::size_t>(y) * 1024 + x) * 4;
          const double l = 0.3 * p[0] + 0.59 * p[1] + 0.11 * p[2];
          s += l;
          s2 += l * l;
        }
      }
      const double var = s2 / 256 - (s / 256) * (s / 256);
      if (var < 4.0) ++flat_blocks;
    }
  }
  EXPECT_EQ(flat_blocks, 0);
  // Deterministic: a second build gives the same texture.
  const Model again = make_builtin_receiver();
  EXPECT_EQ(again.meshes[0].texture->rgba, tex->rgba);
}

TEST(BoomPose, LevelBoomPointsAft) {
  const Pose T = boom_pose(Vector3d(1, 2, 3), BoomArticulation{});
  EXPECT_TRUE(T.translation_m.isApprox(Vector3d(1, 2, 3)));
  // Zero articulation: the boom frame is the body frame rotated 180 deg about z.
  EXPECT_TRUE((T.R() * Vector3d::UnitX()).isApprox(-Vector3d::UnitX(), 1e-12));
  EXPECT_TRUE((T.R() * Vector3d::UnitY()).isApprox(-Vector3d::UnitY(), 1e-12));
  EXPECT_TRUE((T.R() * Vector3d::UnitZ()).isApprox(Vector3d::UnitZ(), 1e-12));
}

TEST(BoomPose, ElevationThirtyDegreesPointsAftAndDown) {
  BoomArticulation a;
  a.elevation_rad = deg_to_rad(30);
  const Vector3d pivot(-2.0, 0.0, 1.0);
  const Pose T = boom_pose(pivot, a);
  const Vector3d dir = T.R() * Vector3d::UnitX();
  EXPECT_TRUE(dir.isApprox(Vector3d(-std::cos(deg_to_rad(30)), 0, std::sin(deg_to_rad(30))), 1e-12))
      << dir.transpose();
  // The nozzle tip of the built-in boom, in the body frame.
  const BoomDimensions d;
  const Vector3d tip = T * Vector3d(d.nozzle_tip_m(0), 0, 0);
  EXPECT_TRUE(tip.isApprox(pivot + 8.5 * dir, 1e-12));
  // Ruddevators rise above the boom: boom -z points up-ish (body -z component) when elevated.
  EXPECT_LT((T.R() * -Vector3d::UnitZ()).z(), 0.0);
}

TEST(BoomPose, PositiveAzimuthPointsTheBoomToStarboard) {
  BoomArticulation a;
  a.azimuth_rad = deg_to_rad(10);
  const Vector3d dir = boom_pose(Vector3d::Zero(), a).R() * Vector3d::UnitX();
  EXPECT_GT(dir.y(), 0.0);
  EXPECT_TRUE(dir.isApprox(Vector3d(-std::cos(deg_to_rad(10)), std::sin(deg_to_rad(10)), 0), 1e-12));
  // Both together: direction (-cos e cos a, cos e sin a, sin e).
  a.elevation_rad = deg_to_rad(25);
  const Vector3d d2 = boom_pose(Vector3d::Zero(), a).R() * Vector3d::UnitX();
  const double e = deg_to_rad(25), az = deg_to_rad(10);
  EXPECT_TRUE(
      d2.isApprox(Vector3d(-std::cos(e) * std::cos(az), std::cos(e) * std::sin(az), std::sin(e)), 1e-12));
}

TEST(BoomPose, TelescopeSlidesAlongTheBoom) {
  BoomArticulation a;
  a.elevation_rad = deg_to_rad(30);
  a.extension_m = 3.0;
  const Pose Tt = telescope_pose(a);
  EXPECT_TRUE(Tt.R().isApprox(Eigen::Matrix3d::Identity()));
  EXPECT_TRUE(Tt.translation_m.isApprox(Vector3d(3, 0, 0)));
  const BoomDimensions d;
  const Pose T = boom_pose(Vector3d::Zero(), a) * Tt;
  const Vector3d tip = T * Vector3d(d.nozzle_tip_m(0), 0, 0);
  EXPECT_NEAR(tip.norm(), d.nozzle_tip_m(3.0), 1e-12);
}

}  // namespace
}  // namespace augrig
