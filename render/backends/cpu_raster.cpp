// The CPU raster backend (render/backends/raster_backend.hpp): render/soft_raster.hpp writes ids
// and depth straight into the CPU images, the same passes as OpenGL's (receiver ids, then the
// boom's ids depth-tested against it). The boom is not coloured per sample: each boom triangle's
// shading (render/boom_shading.hpp) is set up here and evaluated at each raw pixel centre by the
// augmenter's resolve. Where GL is itself software this is faster: a software GL pays per pixel
// for each attachment it clears, writes and reads back; this writes one id and one depth per
// covered sample, and marks the 8 x 8 blocks it wrote so the resolve skips the empty ones.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "render/backends/raster_backend.hpp"
#include "render/soft_raster.hpp"

namespace augrig::raster_backends {

namespace {

using detail::BoomShading;
using detail::F32x4;

// The camera look's light on the boom per vertex and side, computed once per vertex rather than
// per triangle corner (a vertex is shared by about six triangles): slot 2 i front, 2 i + 1 back,
// holding this frame's where its stamp is `now`.
struct VertexLightCache {
  SurfaceLight* light;
  std::uint32_t* stamp;
  std::uint32_t now;
};

// What the CPU backend keeps per draw item beside DrawItem.
struct CpuDraw {
  bool texture_1d = false;  // a texture whose rows are all the same (bands along u)
  // Per triangle of a texture_1d mesh: the one RGBA colour (packed) of every texel its bilinear
  // samples can reach, or -1 where they differ. Such triangles need no texture sampling.
  std::vector<std::int64_t> flat_texel;
  std::size_t first_vertex = 0;  // this mesh's first vertex in CpuView::vertex_light
  const Texture* texture = nullptr;
};

// What it keeps per view.
struct CpuView {
  std::vector<float> inv_z;  // depth (1/z); zero outside the blocks marked
  std::vector<SurfaceLight> vertex_light;
  std::vector<std::uint32_t> vertex_stamp;
  std::uint32_t light_stamp = 0;
};

// Whether every row of `m`'s texture equals the first: bilinear sampling then needs one row.
bool rows_all_equal(const Mesh& m) {
  if (!m.texture || m.texture->height <= 0) return false;
  const std::size_t row_bytes = static_cast<std::size_t>(m.texture->width) * 4;
  for (int r = 1; r < m.texture->height; ++r)
    if (!std::equal(m.texture->rgba.begin(), m.texture->rgba.begin() + row_bytes,
                    m.texture->rgba.begin() + r * row_bytes))
      return false;
  return true;
}

// CpuDraw::flat_texel of a mesh whose texture's rows are all equal.
std::vector<std::int64_t> flat_texels(const Mesh& m) {
  const Texture& tex = *m.texture;
  auto texel = [&](long i) {  // packed RGBA of row 0, column i wrapped (repeat)
    const long w = tex.width, c = ((i % w) + w) % w;
    std::uint32_t v;
    std::memcpy(&v, &tex.rgba[static_cast<std::size_t>(c) * 4], 4);
    return static_cast<std::int64_t>(v);
  };
  std::vector<std::int64_t> flat(m.triangle_count(), -1);
  for (std::size_t t = 0; t < m.triangle_count(); ++t) {
    double u0 = 1e300, u1 = -1e300;
    for (int j = 0; j < 3; ++j) {
      const double u = m.uvs[m.indices[3 * t + j]].x();
      u0 = std::min(u0, u), u1 = std::max(u1, u);
    }
    // Texels i and i + 1 at x = u w - 0.5, i = floor(x), over [u0, u1]; one more each side for
    // the rounding of the per-pixel u.
    const double x0 = u0 * tex.width - 0.5, x1 = u1 * tex.width - 0.5;
    if (!(x1 - x0 < tex.width)) continue;
    const long i0 = static_cast<long>(std::floor(x0)) - 1, i1 = static_cast<long>(std::floor(x1)) + 2;
    const std::int64_t first = texel(i0);
    bool same = true;
    for (long i = i0 + 1; i <= i1 && same; ++i) same = texel(i) == first;
    if (same) flat[t] = first;
  }
  return flat;
}

// The light planes of one boom triangle (BoomShading's sums over its vertices j of k_j c_j):
// vertex j's attributes weighted by the edge plane through the other two (CamTriangle::edge[j +
// 1]); normals flipped on back faces, as in GL. With `vertex_light` (the camera look): the light
// on the mesh's finish seen from the camera at the origin, its albedo-coloured part in `lit` and
// the rest in `add`; without, the diffuse light alone.
struct LightSums {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero(), u = sum, v = sum;
  Eigen::Matrix3d lit = Eigen::Matrix3d::Zero(), add = lit;  // column ch: the channel's sum of k_j c_j
  Eigen::Vector3d lo, hi, add_hi = Eigen::Vector3d::Zero();
};
LightSums light_sums(const CamTriangle& t, const Mesh& m, std::size_t k, std::size_t first_vertex,
                     const Eigen::Matrix3d& R, const SceneLight& sl, const Eigen::Vector3d& light,
                     const Eigen::Vector3d& down, const VertexLightCache* vertex_light, bool tex) {
  const std::uint32_t* vi = &m.indices[3 * k];
  const double facing = t.n_dot_v0 < 0 ? 1.0 : -1.0;
  const Eigen::Vector3d corner[3] = {t.v0, t.v0 + t.e1, t.v0 + t.e2};
  LightSums s;
  s.lo = sl.lowest(), s.hi = sl.highest();
  for (int j = 0; j < 3; ++j) {
    const Eigen::Vector3d& c = t.edge[(j + 1) % 3];
    const Eigen::Vector3d n_j = facing * (R * m.normals[vi[j]].cast<double>()).normalized();
    s.sum += c;
    if (vertex_light) {
      const std::size_t slot = 2 * (first_vertex + vi[j]) + (facing < 0);
      if (vertex_light->stamp[slot] != vertex_light->now) {
        vertex_light->light[slot] = sl.on(n_j, -corner[j].normalized(), light, down, m.finish);
        vertex_light->stamp[slot] = vertex_light->now;
      }
      const SurfaceLight& l = vertex_light->light[slot];
      for (int ch = 0; ch < 3; ++ch) s.lit.col(ch) += l.scale[ch] * c, s.add.col(ch) += 255.0 * l.add[ch] * c;
      // A glint or a metal's dark side may leave the diffuse light's range: the vertices' own.
      s.lo = s.lo.cwiseMin(l.scale), s.hi = s.hi.cwiseMax(l.scale),
      s.add_hi = s.add_hi.cwiseMax(255.0 * l.add);
    } else {
      const Eigen::Vector3d k_j = sl.on(n_j, light, down);
      for (int ch = 0; ch < 3; ++ch) s.lit.col(ch) += k_j[ch] * c;
    }
    if (tex) s.u += m.uvs[vi[j]].x() * c, s.v += m.uvs[vi[j]].y() * c;
  }
  return s;
}

// Triangle k of boom draw `d` coloured for the augmenter's resolve (render/boom_shading.hpp).
void set_boom_shading(BoomShading& sh, const CamTriangle& t, const DrawItem& d, const CpuDraw& cd,
                      std::size_t k, const Eigen::Matrix3d& R, const SceneLight& sl,
                      const Eigen::Vector3d& light, const Eigen::Vector3d& down,
                      const VertexLightCache* vertex_light) {
  const Mesh& m = *d.mesh;
  const Texture* tex = cd.texture;
  const LightSums s = light_sums(t, m, k, cd.first_vertex, R, sl, light, down, vertex_light, tex != nullptr);
  F32x4* coeff[3] = {&sh.dx, &sh.dy, &sh.d1};
  F32x4* coeff_gb[3] = {&sh.gx, &sh.gy, &sh.g1};
  F32x4* coeff_s[3] = {&sh.sx, &sh.sy, &sh.s1};
  auto f = [](double x) { return static_cast<float>(x); };
  for (int a = 0; a < 3; ++a) {
    *coeff[a] = F32x4{f(s.sum[a]), f(s.lit(a, 0)), f(s.u[a]), f(s.v[a])};
    *coeff_gb[a] = F32x4{f(s.lit(a, 1)), f(s.lit(a, 2)), 0.f, 0.f};
    *coeff_s[a] = F32x4{f(s.add(a, 0)), f(s.add(a, 1)), f(s.add(a, 2)), 0.f};
    sh.base[a] = 255.f * m.base_color[a];
  }
  sh.base[3] = 0;
  sh.light_lo = F32x4{f(s.lo[0]), f(s.lo[1]), f(s.lo[2]), 0.f};
  sh.light_hi = F32x4{f(s.hi[0]), f(s.hi[1]), f(s.hi[2]), 0.f};
  sh.add_hi = F32x4{f(s.add_hi[0]), f(s.add_hi[1]), f(s.add_hi[2]), 0.f};
  sh.specular = vertex_light != nullptr;
  sh.texture = tex;
  sh.texture_1d = cd.texture_1d;
  if (tex && !cd.flat_texel.empty() && cd.flat_texel[k] >= 0) {
    // One texel colour over the whole triangle: folded into the base colour.
    std::uint8_t rgba[4];
    const auto packed = static_cast<std::uint32_t>(cd.flat_texel[k]);
    std::memcpy(rgba, &packed, 4);
    for (int a = 0; a < 3; ++a) sh.base[a] *= rgba[a] * (1.f / 255.f);
    sh.texture = nullptr;
  }
}

// Zeroes the runs of blocks marked with `bits` in `image` (a Wv x Hv virtual image).
template <class T>
void zero_blocks(const RasterView& v, std::vector<T>& image, std::uint8_t bits) {
  const int Wv = v.vp.width, Hv = v.vp.height;
  for (int bj = 0; bj * kBlockSize < Hv; ++bj) {
    const std::uint8_t* marks = &v.occupied[static_cast<std::size_t>(bj) * v.blocks_x];
    const int y0 = bj * kBlockSize, y1 = std::min(y0 + kBlockSize, Hv);
    for (int bi = 0; bi < v.blocks_x;) {
      if (!(marks[bi] & bits)) {
        ++bi;
        continue;
      }
      int be = bi + 1;
      while (be < v.blocks_x && (marks[be] & bits)) ++be;
      const int x0 = bi * kBlockSize, x1 = std::min(be * kBlockSize, Wv);
      for (int y = y0; y < y1; ++y) std::fill_n(&image[static_cast<std::size_t>(y) * Wv + x0], x1 - x0, 0);
      bi = be;
    }
  }
}

class CpuRaster final : public RasterBackend {
 public:
  Rasterizer kind() const override { return Rasterizer::kCpu; }
  bool concurrent_views() const override { return true; }
  bool shades_per_pixel() const override { return true; }
  Status init(const std::vector<DrawItem>& draws, const std::vector<RasterView*>& views) override;
  void clear(RasterView& v) override {
    // Only the blocks marked last frame were written: an oblique boom covers a fraction of its boxes.
    zero_blocks(v, v.boom_ids, kBoomBlock);
    zero_blocks(v, v.recv_ids, kReceiverBlock);
    zero_blocks(v, views_[v.index].inv_z, kBoomBlock | kReceiverBlock);
  }
  void draw(RasterView& v, const RasterFrame& f, AugmentTimings& timings) override;
  Status errors() const override { return {}; }

 private:
  const std::vector<DrawItem>* draws_ = nullptr;
  std::vector<CpuDraw> cpu_draws_;
  std::vector<CpuView> views_;  // by RasterView::index
};

Status CpuRaster::init(const std::vector<DrawItem>& draws, const std::vector<RasterView*>& views) {
  draws_ = &draws;
  std::size_t total_tris = 0, total_verts = 0;
  for (const DrawItem& d : draws) {
    const Mesh& m = *d.mesh;
    CpuDraw cd;
    cd.texture_1d = rows_all_equal(m);
    if (cd.texture_1d && !m.uvs.empty()) cd.flat_texel = flat_texels(m);
    cd.first_vertex = total_verts;
    cd.texture = m.texture && m.texture->width > 0 && !m.uvs.empty() ? m.texture.get() : nullptr;
    cpu_draws_.push_back(std::move(cd));
    total_tris += m.triangle_count();
    total_verts += m.positions_m.size();
  }
  for (RasterView* v : views) {
    if (v->index >= static_cast<int>(views_.size())) views_.resize(v->index + 1);
    CpuView& cv = views_[v->index];
    const std::size_t vn = static_cast<std::size_t>(v->vp.width) * v->vp.height;
    cv.inv_z.assign(vn, 0.f);
    cv.vertex_light.resize(2 * total_verts);
    cv.vertex_stamp.assign(2 * total_verts, 0);
    v->shading.resize(total_tris);
    v->blocks_x = (v->vp.width >> kBlockShift) + 1;
    v->occupied.assign(static_cast<std::size_t>(v->blocks_x) * ((v->vp.height >> kBlockShift) + 1), 0);
  }
  return {};
}

// Every sample a triangle covers lies in its chunk's box, so the images stay zero outside this
// frame's boxes.
void CpuRaster::draw(RasterView& v, const RasterFrame& f, AugmentTimings&) {
  CpuView& cv = views_[v.index];
  const SampleGrid grid{v.vp.fx,    v.vp.fy,     v.vp.cx,       v.vp.cy,
                        v.vp.width, v.vp.height, v.cam->near_m, v.cam->far_m};
  const SampleBox all{0, 0, v.vp.width, v.vp.height};
  std::fill(v.occupied.begin(), v.occupied.end(), 0);
  std::uint8_t* occupied = v.occupied.data();
  const int blocks_x = v.blocks_x;
  const SceneLight& sl = *f.light;
  const Eigen::Vector3d light = f.R_cam_body * sl.towards_light_body, down = f.R_cam_body * sl.down_body;
  if (++cv.light_stamp == 0) {  // wrapped round: every slot is stale again
    std::fill(cv.vertex_stamp.begin(), cv.vertex_stamp.end(), 0);
    cv.light_stamp = 1;
  }
  const VertexLightCache vertex_cache{cv.vertex_light.data(), cv.vertex_stamp.data(), cv.light_stamp};
  const VertexLightCache* cache = f.camera_look ? &vertex_cache : nullptr;
  RasterTriangle rt;
  for (const ObjectKind kind : {ObjectKind::kReceiver, ObjectKind::kBoomFixed, ObjectKind::kBoomTelescope}) {
    const bool boom = kind != ObjectKind::kReceiver;
    if (boom ? v.boom_vboxes.empty() : v.recv_vboxes.empty()) continue;
    const std::uint8_t block_bit = boom ? kBoomBlock : kReceiverBlock;
    const Eigen::Matrix3d R = f.T_cam_obj[static_cast<int>(kind)].R();
    std::uint32_t* ids = boom ? v.boom_ids.data() : v.recv_ids.data();
    for (std::size_t di = 0; di < draws_->size(); ++di) {
      const DrawItem& d = (*draws_)[di];
      if (d.kind != kind) continue;
      const std::uint32_t tag = static_cast<std::uint32_t>(d.draw_id) << kDrawShift;
      for (std::size_t k = 0; k < d.mesh->triangle_count(); ++k) {
        const CamTriangle& t = v.tris[d.first_tri + k];
        if (!rt.setup(grid, t.v0, t.v0 + t.e1, t.v0 + t.e2, d.cull, all)) continue;
        const std::uint32_t id = tag | static_cast<std::uint32_t>(k);
        raster(grid, rt, cv.inv_z.data(), [&](std::size_t i, int x, int y) {
          ids[i] = id;
          occupied[(y >> kBlockShift) * blocks_x + (x >> kBlockShift)] |= block_bit;
        });
        if (boom)
          set_boom_shading(v.shading[d.first_tri + k], t, d, cpu_draws_[di], k, R, sl, light, down, cache);
      }
    }
  }
}

}  // namespace

std::unique_ptr<RasterBackend> make_cpu_raster() {
  return std::make_unique<CpuRaster>();
}

}  // namespace augrig::raster_backends
