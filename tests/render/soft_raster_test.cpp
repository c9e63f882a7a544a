// SoftRaster (render/soft_raster.hpp) against a brute-force oracle written here: for every sample,
// the ray from the camera centre through the sample intersected with the triangle in double
// (Möller–Trumbore; the ray's z is 1, so its t is the camera z). Checked: coverage, 1/z and the
// barycentric weights; the near plane and triangles partly behind the camera; nearest-wins
// whatever the draw order; back-face culling; set-up rejections and the clip box; and that two
// triangles sharing an edge leave no crack. Samples within a tiny band of an edge (or of the near
// plane) may go either way: they are counted and must stay very rare.
#include "render/soft_raster.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace augrig {
namespace {

using Eigen::Vector3d;

constexpr double kEdgeEps = 1e-9;   // barycentric band around the edges where either answer is right
constexpr double kDepthEps = 1e-9;  // relative band around the near plane, likewise

struct Tri {
  Vector3d p[3];
};

SampleGrid test_grid() {
  SampleGrid g;
  g.fx = g.fy = 150, g.cx = 80.3, g.cy = 59.7, g.width = 160, g.height = 120, g.near_m = 0.1;
  return g;
}
SampleBox whole(const SampleGrid& g) {
  return {0, 0, g.width, g.height};
}
Vector3d ray(const SampleGrid& g, int i, int j) {
  return {(i - g.cx) / g.fx, (j - g.cy) / g.fy, 1.0};
}
// The point at camera depth z seen at (possibly fractional) sample position (x, y).
Vector3d at_pixel(const SampleGrid& g, double x, double y, double z) {
  return z * Vector3d((x - g.cx) / g.fx, (y - g.cy) / g.fy, 1.0);
}
bool back_facing(const Tri& t) {
  return ((t.p[1] - t.p[0]).cross(t.p[2] - t.p[0])).dot(t.p[0]) > 0;
}
std::string describe(const Tri& t, int i, int j) {
  std::ostringstream s;
  s.precision(17);
  if (i >= 0) s << "sample (" << i << ", " << j << ") ";
  s << "triangle";
  for (const Vector3d& p : t.p) s << " (" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}

// The oracle: the ray from the origin along d against the triangle; u and v weigh p1 and p2.
struct Hit {
  bool valid = false;
  double t = 0, u = 0, v = 0;
  double margin() const { return std::min({u, v, 1 - u - v}); }
};
Hit intersect(const Vector3d& d, const Tri& tri) {
  const Vector3d e1 = tri.p[1] - tri.p[0], e2 = tri.p[2] - tri.p[0], pv = d.cross(e2);
  const double det = e1.dot(pv);
  Hit h;
  if (det == 0) return h;
  const Vector3d s = -tri.p[0], q = s.cross(e1);
  h.u = s.dot(pv) / det, h.v = d.dot(q) / det, h.t = e2.dot(q) / det;
  h.valid = std::isfinite(h.t);
  return h;
}
enum class Truth { kOut, kIn, kEither };
// Drawn: inside the triangle, at camera z in [near_m, far_m] (GL's clipping planes).
Truth truth(const Hit& h, double near, double far) {
  if (!h.valid) return Truth::kOut;
  const double m = h.margin();
  if (m < -kEdgeEps || h.t < near * (1 - kDepthEps) || h.t > far * (1 + kDepthEps)) return Truth::kOut;
  if (m > kEdgeEps && h.t > near * (1 + kDepthEps) && h.t < far * (1 - kDepthEps)) return Truth::kIn;
  return Truth::kEither;
}

// Draws one triangle on the whole grid (ids[] takes `id` at each write); counts bad write calls.
void draw(const SampleGrid& g, const Tri& t, int id, std::vector<float>& inv_z, std::vector<int>& ids,
          long& bad_writes) {
  RasterTriangle rt;
  if (!rt.setup(g, t.p[0], t.p[1], t.p[2], false, whole(g))) return;
  raster(g, rt, inv_z.data(), [&](std::size_t idx, int i, int j) {
    const bool ok =
        i >= 0 && i < g.width && j >= 0 && j < g.height && idx == static_cast<std::size_t>(j) * g.width + i;
    if (ok) ids[idx] = id;
    bad_writes += !ok;
  });
}

struct Tally {
  long set_up = 0, covered = 0, near_cut = 0, far_cut = 0, behind = 0, either = 0, either_disagree = 0;
  long coverage_errors = 0, depth_errors = 0, weight_errors = 0, write_errors = 0;
  std::string first;  // the first error, described
  void error(long& n, const std::string& what) {
    if (n++ == 0 && first.empty()) first = what;
  }
  void expect_clean() const {
    EXPECT_EQ(coverage_errors, 0) << first;
    EXPECT_EQ(depth_errors, 0) << first;
    EXPECT_EQ(weight_errors, 0) << first;
    EXPECT_EQ(write_errors, 0) << first;
    EXPECT_LE(either_disagree, 2) << "edge-band disagreements out of " << either << " edge-band samples";
  }
};

// Draws `t` alone on a clear grid and compares every sample with the oracle.
void check_triangle(const SampleGrid& g, const Tri& t, bool cull, const SampleBox& clip, Tally& n) {
  const std::size_t count = static_cast<std::size_t>(g.width) * g.height;
  std::vector<float> inv_z(count, 0.0f);
  std::vector<int> ids(count, -1);
  long bad = 0;
  RasterTriangle rt;
  const bool set_up = rt.setup(g, t.p[0], t.p[1], t.p[2], cull, clip);
  if (set_up) {
    ++n.set_up;
    raster(g, rt, inv_z.data(), [&](std::size_t idx, int i, int j) {
      if (i < 0 || i >= g.width || j < 0 || j >= g.height || idx != static_cast<std::size_t>(j) * g.width + i)
        ++bad;
      else
        ++ids[idx];  // -1 + number of writes
    });
  }
  if (bad) n.error(n.write_errors, "write outside the grid or wrong index: " + describe(t, -1, -1));
  const bool culled = cull && back_facing(t);
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const std::size_t idx = static_cast<std::size_t>(j) * g.width + i;
      const Hit h = intersect(ray(g, i, j), t);
      const bool in_clip = i >= clip.x0 && i < clip.x1 && j >= clip.y0 && j < clip.y1;
      Truth want = culled || !in_clip ? Truth::kOut : truth(h, g.near_m, g.far_m);
      const bool covered = ids[idx] >= 0;
      if (ids[idx] > 0) n.error(n.write_errors, "written twice: " + describe(t, i, j));
      if (h.valid && h.margin() > kEdgeEps && h.t > 0 && h.t < g.near_m * (1 - kDepthEps)) ++n.near_cut;
      if (h.valid && h.margin() > kEdgeEps && h.t < 0) ++n.behind;
      if (h.valid && h.margin() > kEdgeEps && h.t > g.far_m * (1 + kDepthEps)) ++n.far_cut;
      n.covered += covered;
      if (want == Truth::kEither) {
        ++n.either;
        n.either_disagree += covered != (h.margin() >= 0 && h.t >= g.near_m && h.t <= g.far_m);
      } else if (covered != (want == Truth::kIn)) {
        n.error(n.coverage_errors,
                (covered ? "drawn but missed by the ray: " : "hit by the ray but not drawn: ") +
                    describe(t, i, j));
      }
      if (!covered || !h.valid || h.t <= 0) continue;
      if (std::abs(inv_z[idx] * h.t - 1) > 1e-6)
        n.error(n.depth_errors, "1/z " + std::to_string(inv_z[idx]) + " vs " + std::to_string(1 / h.t) +
                                    ": " + describe(t, i, j));
      double w1, w2;
      rt.weights(i, j, w1, w2);
      if (std::abs(w1 - h.u) > 1e-6 || std::abs(w2 - h.v) > 1e-6)
        n.error(n.weight_errors, "weights: " + describe(t, i, j));
    }
}

// Vertices back-projected from around the grid: large triangles often off the grid, or small ones.
Tri random_front_triangle(const SampleGrid& g, std::mt19937& rng) {
  std::uniform_real_distribution<double> x(-60, g.width + 60), y(-50, g.height + 50), z(0.3, 20), u(-1, 1);
  Tri t;
  if (rng() % 2) {
    for (Vector3d& p : t.p) p = at_pixel(g, x(rng), y(rng), z(rng));
  } else {
    const double x0 = x(rng), y0 = y(rng), z0 = z(rng), r = 2 + 30 * (u(rng) + 1);
    for (Vector3d& p : t.p) p = at_pixel(g, x0 + r * u(rng), y0 + r * u(rng), z0 * (1 + 0.3 * u(rng)));
  }
  return t;
}

TEST(SoftRaster, CoverageDepthAndWeightsMatchRayCasting) {
  const SampleGrid g = test_grid();
  std::mt19937 rng(12345);
  Tally n;
  for (int k = 0; k < 400; ++k) check_triangle(g, random_front_triangle(g, rng), false, whole(g), n);
  n.expect_clean();
  EXPECT_GT(n.covered, 200000);  // the triangles do cover much of the grid
  std::printf("coverage: %ld samples covered, %ld edge-band samples, %ld disagreements\n", n.covered,
              n.either, n.either_disagree);
}

TEST(SoftRaster, NearPlaneAndBehindTheCameraMatchRayCasting) {
  const SampleGrid g = test_grid();
  std::mt19937 rng(777);
  std::uniform_real_distribution<double> xy(-1.5, 1.5), z(-1.0, 1.5);
  Tally n;
  for (int k = 0; k < 400; ++k) {
    Tri t;
    for (Vector3d& p : t.p) p = {xy(rng), xy(rng), z(rng)};
    check_triangle(g, t, false, whole(g), n);
  }
  n.expect_clean();
  EXPECT_GT(n.covered, 50000);
  EXPECT_GT(n.near_cut, 10000);  // hits nearer than near_m, none drawn (checked per sample)
  EXPECT_GT(n.behind, 10000);    // triangles behind the camera along the ray, none drawn
  std::printf(
      "near/behind: %ld covered, %ld cut by the near plane, %ld behind, %ld edge-band (%ld disagree)\n",
      n.covered, n.near_cut, n.behind, n.either, n.either_disagree);
}

// The far plane clips like GL's: samples whose hit lies beyond far_m are not drawn, whether the
// triangle lies wholly beyond it (set-up rejects it) or straddles it (tested per sample); the
// near plane likewise in the same grid.
TEST(SoftRaster, FarPlaneMatchesRayCasting) {
  SampleGrid g = test_grid();
  g.near_m = 0.5, g.far_m = 2.0;
  std::mt19937 rng(4242);
  std::uniform_real_distribution<double> x(-40, g.width + 40), y(-30, g.height + 30), z(0.2, 4.0);
  Tally n;
  for (int k = 0; k < 400; ++k) {
    Tri t;
    for (Vector3d& p : t.p) p = at_pixel(g, x(rng), y(rng), z(rng));
    check_triangle(g, t, false, whole(g), n);
  }
  // Wholly beyond far_m: nothing drawn.
  RasterTriangle rt;
  EXPECT_FALSE(rt.setup(g, at_pixel(g, 10, 10, 2.5), at_pixel(g, 150, 20, 3), at_pixel(g, 80, 110, 2.1), false,
                        whole(g)));
  n.expect_clean();
  EXPECT_GT(n.covered, 50000);
  EXPECT_GT(n.far_cut, 50000);  // hits beyond far_m, none drawn
  EXPECT_GT(n.near_cut, 5000);
  std::printf("far/near: %ld covered, %ld cut by the far plane, %ld by the near plane, %ld edge-band (%ld disagree)\n",
              n.covered, n.far_cut, n.near_cut, n.either, n.either_disagree);
}

// A vertex a hair in front of the camera plane projects far outside any int range: the triangle
// must still be drawn where it lies beyond the near plane, as it is with that vertex at z = 0.
TEST(SoftRaster, VertexJustInFrontOfTheCameraPlane) {
  const SampleGrid g = test_grid();
  for (double z : {1e-6, 1e-9, 1e-12, 0.0, -1e-9})
    for (double x : {1.0, -1.0}) {
      const Tri t{{{x, 0, z}, {-x, -1, 5}, {-x, 1, 5}}};
      Tally n;
      check_triangle(g, t, false, whole(g), n);
      SCOPED_TRACE(describe(t, -1, -1));
      n.expect_clean();
      EXPECT_GT(n.covered, 5000);
    }
}

TEST(SoftRaster, NearestWinsWhateverTheDrawOrder) {
  const SampleGrid g = test_grid();
  const std::size_t count = static_cast<std::size_t>(g.width) * g.height;
  std::mt19937 rng(99);
  std::uniform_real_distribution<double> x(40, 120), y(30, 90), off(-90, 90), z(1, 3);
  long checked = 0, overlapped = 0, unsure = 0, unsure_disagree = 0, errors = 0;
  std::string first;
  for (int scene = 0; scene < 20; ++scene) {
    std::vector<Tri> tris(10);
    for (Tri& t : tris) {
      const double x0 = x(rng), y0 = y(rng);
      for (Vector3d& p : t.p) p = at_pixel(g, x0 + off(rng), y0 + off(rng), z(rng));
    }
    std::vector<int> order(tris.size()), first_ids;
    std::iota(order.begin(), order.end(), 0);
    for (int pass = 0; pass < 2; ++pass) {
      std::shuffle(order.begin(), order.end(), rng);
      std::vector<float> inv_z(count, 0.0f);
      std::vector<int> ids(count, -1);
      long bad = 0;
      for (int k : order) draw(g, tris[k], k, inv_z, ids, bad);
      EXPECT_EQ(bad, 0);
      for (int j = 0; j < g.height; ++j)
        for (int i = 0; i < g.width; ++i) {
          const std::size_t idx = static_cast<std::size_t>(j) * g.width + i;
          double best = std::numeric_limits<double>::infinity(), second = best;
          int want = -1, hits = 0;
          bool sure = true;
          for (int k = 0; k < static_cast<int>(tris.size()); ++k) {
            const Hit h = intersect(ray(g, i, j), tris[k]);
            const Truth tr = truth(h, g.near_m, g.far_m);
            sure &= tr != Truth::kEither;
            if (tr != Truth::kIn) continue;
            ++hits;
            if (h.t < best)
              second = best, best = h.t, want = k;
            else
              second = std::min(second, h.t);
          }
          sure &= hits < 2 || second > best * (1 + 1e-6);  // a near tie in depth may go either way
          const bool agree = ids[idx] == want && (pass == 0 || ids[idx] == first_ids[idx]) &&
                             (want < 0 || std::abs(inv_z[idx] * best - 1) < 1e-6);
          if (!sure) {
            unsure += pass == 0, unsure_disagree += !agree;
          } else if (!agree && errors++ == 0) {
            first = "pass " + std::to_string(pass) + " scene " + std::to_string(scene) + " id " +
                    std::to_string(ids[idx]) + " want " + std::to_string(want) + " at " +
                    describe(tris[std::max(want, 0)], i, j);
          }
          checked += pass == 0, overlapped += pass == 0 && hits >= 2;
        }
      if (pass == 0) first_ids = ids;
    }
  }
  EXPECT_EQ(errors, 0) << first;
  EXPECT_LE(unsure_disagree, 4) << "of " << unsure << " samples at an edge or a near depth tie";
  EXPECT_GT(overlapped, checked / 8);  // the depth test is really exercised
  std::printf("nearest: %ld samples, %ld overlapped, %ld unsure (%ld disagree)\n", checked, overlapped,
              unsure, unsure_disagree);
}

TEST(SoftRaster, CullingDropsBackFacesOnly) {
  const SampleGrid g = test_grid();
  // Counter-clockwise seen from the camera (y down): its normal (0, 0, -4) faces the camera.
  const Tri front{{{0, -1, 5}, {-1, 1, 5}, {1, 1, 5}}};
  const Tri back{{front.p[0], front.p[2], front.p[1]}};
  ASSERT_FALSE(back_facing(front));
  ASSERT_TRUE(back_facing(back));
  RasterTriangle rt;
  EXPECT_TRUE(rt.setup(g, front.p[0], front.p[1], front.p[2], true, whole(g)));
  EXPECT_FALSE(rt.setup(g, back.p[0], back.p[1], back.p[2], true, whole(g)));
  EXPECT_TRUE(rt.setup(g, back.p[0], back.p[1], back.p[2], false, whole(g)));
  Tally n;
  for (bool cull : {false, true})
    for (const Tri& t : {front, back}) check_triangle(g, t, cull, whole(g), n);
  EXPECT_EQ(n.set_up, 3);
  EXPECT_GT(n.covered, 3 * 1000);  // each of the three drawn covers ~100 x 60 samples
  // Random triangles either way round: culling keeps exactly the front faces.
  std::mt19937 rng(4242);
  for (int k = 0; k < 200; ++k) {
    const Tri t = random_front_triangle(g, rng);
    const bool set_up = rt.setup(g, t.p[0], t.p[1], t.p[2], true, whole(g));
    EXPECT_TRUE(!back_facing(t) || !set_up) << describe(t, -1, -1);
    check_triangle(g, t, true, whole(g), n);
  }
  n.expect_clean();
}

TEST(SoftRaster, SetUpRejectsWhatCannotBeDrawn) {
  const SampleGrid g = test_grid();
  RasterTriangle rt;
  auto set_up = [&](const Tri& t, SampleBox clip) {
    return rt.setup(g, t.p[0], t.p[1], t.p[2], false, clip);
  };
  // Edge-on: the plane y = 0 holds the camera centre.
  EXPECT_FALSE(set_up(Tri{{{1, 0, 2}, {1, 0, 4}, {-1, 0, 3}}}, whole(g)));
  // Entirely nearer than the near plane, entirely behind the camera.
  EXPECT_FALSE(set_up(Tri{{{0, -0.1, 0.05}, {-0.1, 0.1, 0.09}, {0.1, 0.1, 0.099}}}, whole(g)));
  EXPECT_FALSE(set_up(Tri{{{0, -1, -5}, {-1, 1, -5}, {1, 1, -5}}}, whole(g)));
  // Off the grid on each side: rejected, or at least nothing drawn (checked against the oracle).
  Tally n;
  const std::vector<Tri> off = {
      {{at_pixel(g, 170, 10, 2), at_pixel(g, 200, 30, 3), at_pixel(g, 180, 100, 4)}},
      {{at_pixel(g, -90, 10, 2), at_pixel(g, -5, 60, 3), at_pixel(g, -30, 100, 4)}},
      {{at_pixel(g, 10, -40, 2), at_pixel(g, 150, -3, 3), at_pixel(g, 80, -90, 4)}},
      {{at_pixel(g, 10, 125, 2), at_pixel(g, 150, 200, 3), at_pixel(g, 80, 123, 4)}},
      {{{-3, -1, -1}, {-3, 1, -1}, {-2, 0, 1}}},  // partly behind the camera, left of the view
  };
  for (const Tri& t : off) check_triangle(g, t, false, whole(g), n);
  for (int k = 0; k < 4; ++k) EXPECT_FALSE(set_up(off[k], whole(g))) << k;
  EXPECT_EQ(n.covered, 0);
  n.expect_clean();
}

TEST(SoftRaster, ClipBoxRestrictsDrawing) {
  const SampleGrid g = test_grid();
  const Tri big{{at_pixel(g, -100, -100, 2), at_pixel(g, 400, -50, 3), at_pixel(g, 20, 300, 4)}};
  const Tri crossing{{{-2, -2, -0.5}, {3, -1, 2}, {-1, 3, 1}}};  // partly behind the camera
  Tally n;
  for (const Tri& t : {big, crossing})
    for (SampleBox clip : {SampleBox{40, 30, 100, 80}, SampleBox{-20, -10, 30, 500},
                           SampleBox{150, 0, 999, 7}, SampleBox{0, 0, 160, 120}})
      check_triangle(g, t, false, clip, n);  // samples outside the clip box must not be drawn
  EXPECT_GT(n.covered, 15000);
  n.expect_clean();
  RasterTriangle rt;
  EXPECT_FALSE(rt.setup(g, big.p[0], big.p[1], big.p[2], false, SampleBox{50, 50, 50, 90}));  // empty box
  // A clip box away from a small triangle.
  const Tri small{{at_pixel(g, 10, 10, 2), at_pixel(g, 20, 10, 2), at_pixel(g, 10, 20, 2)}};
  EXPECT_FALSE(rt.setup(g, small.p[0], small.p[1], small.p[2], false, SampleBox{100, 60, 160, 120}));
}

// A quad split along its diagonal (a, c): (a, b, c) and (a, c, d). Every sample inside the quad
// is drawn by one of the two, including the samples the shared diagonal passes through.
TEST(SoftRaster, SharedEdgeLeavesNoCracks) {
  const SampleGrid g = test_grid();
  const std::size_t count = static_cast<std::size_t>(g.width) * g.height;
  std::mt19937 rng(2024);
  std::uniform_int_distribution<int> px(20, 60), py(15, 45), len(10, 40), dir(0, 4);
  std::uniform_real_distribution<double> z(0.5, 8), side(5, 60), along(0.1, 0.9), u(-0.5, 0.5);
  const int dirs[5][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}, {2, 1}};
  long inside = 0, on_diagonal = 0, cracks = 0, outside_drawn = 0, bad = 0;
  std::string first;
  for (int q = 0; q < 300; ++q) {
    // Half the diagonals run exactly through sample centres (up to rounding), half anywhere.
    const bool aligned = q % 2 == 0;
    const int* d = dirs[dir(rng)];
    const double i0 = px(rng) + (aligned ? 0 : u(rng)),
                 j0 = py(rng) + 40 * (d[1] < 0) + (aligned ? 0 : u(rng));
    const int l = len(rng);
    const double i1 = i0 + l * d[0] + (aligned ? 0 : u(rng)), j1 = j0 + l * d[1] + (aligned ? 0 : u(rng));
    const double nx = -(j1 - j0), ny = i1 - i0, nl = std::hypot(nx, ny);
    auto beside = [&](double s) {
      const double a = along(rng), dist = s * side(rng);
      return at_pixel(g, i0 + a * (i1 - i0) + dist * nx / nl, j0 + a * (j1 - j0) + dist * ny / nl, z(rng));
    };
    const Vector3d a = at_pixel(g, i0, j0, z(rng)), c = at_pixel(g, i1, j1, z(rng)), b = beside(1),
                   dd = beside(-1);
    const Tri t1{{a, b, c}}, t2{{a, c, dd}};
    std::vector<float> inv_z(count, 0.0f);
    std::vector<int> ids(count, -1);
    draw(g, t1, 1, inv_z, ids, bad);
    draw(g, t2, 2, inv_z, ids, bad);
    for (int j = 0; j < g.height; ++j)
      for (int i = 0; i < g.width; ++i) {
        const Hit h1 = intersect(ray(g, i, j), t1), h2 = intersect(ray(g, i, j), t2);
        // Inside the quad: clear of its four outer edges; the shared edge (weight of b in t1, of
        // d in t2) may be crossed by a rounding error.
        auto in_quad = [&](const Hit& h, double w_outer1, double w_outer2, double w_shared) {
          return h.valid && h.t > g.near_m && w_outer1 > kEdgeEps && w_outer2 > kEdgeEps &&
                 w_shared > -kEdgeEps;
        };
        const bool in = in_quad(h1, 1 - h1.u - h1.v, h1.v, h1.u) || in_quad(h2, 1 - h2.u - h2.v, h2.u, h2.v);
        const bool out = truth(h1, g.near_m, g.far_m) == Truth::kOut && truth(h2, g.near_m, g.far_m) == Truth::kOut;
        const bool drawn = ids[static_cast<std::size_t>(j) * g.width + i] >= 0;
        inside += in, on_diagonal += in && h1.valid && std::abs(h1.u) <= 1e-9;
        if (in && !drawn && cracks++ == 0)
          first = "crack at " + describe(t1, i, j) + " / " + describe(t2, i, j);
        if (out && drawn && outside_drawn++ == 0) first = "outside drawn at " + describe(t1, i, j);
      }
  }
  EXPECT_EQ(bad, 0);
  EXPECT_EQ(cracks, 0) << first;
  EXPECT_EQ(outside_drawn, 0) << first;
  EXPECT_GT(on_diagonal, 1000);  // samples exactly on the shared edge were tested
  std::printf("quads: %ld samples inside, %ld on the shared diagonal\n", inside, on_diagonal);
}

}  // namespace
}  // namespace augrig
