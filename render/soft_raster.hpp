// SoftRaster: the augmenter's rasteriser for machines whose OpenGL is itself software (Mesa
// llvmpipe). It does only what the augmenter needs from GL: at the samples of its virtual pinhole
// image, which camera-frame triangle is nearest (depth test, optional back-face culling), with
// the sample's depth and perspective-correct barycentrics for shading. llvmpipe pays per pixel for
// every attachment cleared and written; this writes one id and one depth per covered sample.
//
// No clipping is needed: each edge function is the plane through the camera centre and one edge
// (homogeneous rasterisation), evaluated on the sample's ray. A triangle crossing the near or far
// plane, or partly behind the camera, is drawn exactly where it lies between them: at samples
// whose camera z is in [near_m, far_m], as GL's clipping planes have it.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

#include <Eigen/Core>

namespace augrig {

// The sample grid: sample (i, j) lies on the ray ((i - cx) / fx, (j - cy) / fy, 1) of the camera
// frame (OpenCV axes, core/conventions.hpp).
struct SampleGrid {
  double fx = 1, fy = 1, cx = 0, cy = 0;
  int width = 0, height = 0;
  double near_m = 0.1;  // nearer samples are not drawn, as with GL's near plane
  double far_m = std::numeric_limits<double>::infinity();  // farther samples are not drawn (GL's far plane)
};

struct SampleBox {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // [x0, x1) x [y0, y1)
};

// One triangle set up for a grid. Edge functions are scaled so that each is >= 0 inside, and at a
// covered sample: 1/z = (e0 + e1 + e2) * inv_area, the weight of p1 is e2 / (e0 + e1 + e2) and the
// weight of p2 is e0 / (e0 + e1 + e2).
struct RasterTriangle {
  double ea[3], eb[3], ec[3];  // e_k(X, Y) = ea[k] X + eb[k] Y + ec[k]
  double inv_ea[3];            // 1 / ea[k] (0 where ea[k] is 0): row spans without divisions
  double inv_area = 0;         // 1 / |det(p0, p1, p2)|
  bool crosses_near = false;   // some vertex nearer than the near plane
  bool crosses_far = false;    // some vertex beyond the far plane
  bool clips_depth = false;    // either: test each sample's depth against [near_m, far_m]
  SampleBox bounds;            // samples the triangle may cover, inside the grid
  // The usual case: one or two edges bound each row's span on the left (ea > 0) and the others
  // on the right (ea < 0). Edge k's bound on row Y is -(eb Y + ec) / ea = m Y + q with
  // m = -eb / ea, q = -ec / ea; the single edge of a side is repeated. A shared edge's two
  // triangles have exactly negated coefficients, so one's left bound is bitwise the other's right
  // bound: no sample between them is lost. 1/z on row Y at X is wy Y + wc + wa X.
  bool two_sided = false;
  double lo_m[2] = {}, lo_q[2] = {}, hi_m[2] = {}, hi_q[2] = {};
  double wy = 0, wc = 0;

  // False when no sample can be covered: edge-on to the camera, culled as a back face (`cull`:
  // triangles wind counter-clockwise seen from outside, render/mesh.hpp), entirely nearer than
  // the near plane or farther than the far plane, or outside `clip`.
  bool setup(const SampleGrid& g, const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
             const Eigen::Vector3d& p2, bool cull, const SampleBox& clip);

  // Weights of p1 and p2 at sample (x, y) (valid where the sample is covered).
  void weights(double x, double y, double& w1, double& w2) const {
    const double e0 = ea[0] * x + eb[0] * y + ec[0], e1 = ea[1] * x + eb[1] * y + ec[1],
                 e2 = ea[2] * x + eb[2] * y + ec[2];
    const double s = 1.0 / (e0 + e1 + e2);
    w1 = e2 * s, w2 = e0 * s;
  }
};

// Draws a set-up triangle: at each sample inside it (edges included), between the near and far
// planes (both included) and nearer than `inv_z[j * width + i]` (1/z, larger is nearer; 0 =
// nothing drawn yet), stores its 1/z and calls write(j * width + i, i, j).
template <class Write>
void raster(const SampleGrid& g, const RasterTriangle& t, float* inv_z, Write&& write) {
  const double max_inv_z = 1.0 / g.near_m, min_inv_z = 1.0 / g.far_m;  // 0 when far_m is infinite
  // 1/z along a row is affine in x: (sum of the edges) * inv_area.
  const double wa = (t.ea[0] + t.ea[1] + t.ea[2]) * t.inv_area;
  for (int y = t.bounds.y0; y < t.bounds.y1; ++y) {
    // The row's span: where all three edge functions are >= 0.
    double lo = t.bounds.x0, hi = t.bounds.x1 - 1;
    bool empty = false;
    double w0;
    if (t.two_sided) {  // no per-edge tests
      const double yd = y;
      lo = std::max({lo, t.lo_m[0] * yd + t.lo_q[0], t.lo_m[1] * yd + t.lo_q[1]});
      hi = std::min({hi, t.hi_m[0] * yd + t.hi_q[0], t.hi_m[1] * yd + t.hi_q[1]});
      w0 = t.wy * yd + t.wc;
    } else {
      double row_c[3];
      for (int k = 0; k < 3; ++k) {
        row_c[k] = t.eb[k] * y + t.ec[k];
        if (t.ea[k] > 0)
          lo = std::max(lo, -row_c[k] * t.inv_ea[k]);
        else if (t.ea[k] < 0)
          hi = std::min(hi, -row_c[k] * t.inv_ea[k]);
        else if (row_c[k] < 0)
          empty = true;
      }
      w0 = (row_c[0] + row_c[1] + row_c[2]) * t.inv_area;
    }
    if (empty || lo > hi) continue;
    // lo and hi lie in the clipped bounds, so are >= 0: truncation is floor (std::ceil and
    // std::floor are library calls on baseline x86-64).
    int xs = static_cast<int>(lo);
    xs += xs < lo;
    const int xe = static_cast<int>(hi);
    const std::size_t row_index = static_cast<std::size_t>(y) * g.width;
    float* row = inv_z + row_index;
    double xd = xs;  // x as a double, counted (exact) rather than converted
    for (int x = xs; x <= xe; ++x, xd += 1.0) {
      const double w = w0 + wa * xd;
      if (!(w > row[x])) continue;  // GL_GREATER on 1/z: nearest wins, ties keep the first
      if (t.clips_depth && (w > max_inv_z || w < min_inv_z)) continue;  // set-up decides for most
      row[x] = static_cast<float>(w);
      write(row_index + x, x, y);
    }
  }
}

}  // namespace augrig
