// The augmenter (render/augmenter.hpp). Per view:
//   1. everything is moved into the camera frame in double precision (T_cam_body * T_body_obj);
//   2. a raster backend (render/backends/raster_backend.hpp: OpenGL, or the CPU rasteriser where
//      GL is itself software) draws the receiver (ids only), then the boom depth-tested against
//      it (ids, and its colour per sample or per triangle), into the virtual pinhole image, only
//      inside the projected boxes of spatial chunks of each mesh; ids pack the draw id in the
//      top byte and the triangle in the low 24 bits;
//   3. the CPU visits the raw pixels of those boxes: each centre maps into the virtual image
//      (shifted half a sample when anti-aliasing an undistorted lens); where the 2x2 ids around it
//      agree the answer is read off (a triangle covering all four samples covers the centre),
//      elsewhere the centre's exact ray is intersected with the candidate triangles and, when
//      they miss, their one-ring neighbours (silhouette slivers hold no sample). Depth comes from
//      the triangle's plane, exactly at the pixel centre;
//   4. the boom is blended over the raw pixels by its bilinear coverage; pixels it does not touch
//      are never written, so they stay bit-identical.
#include "render/augmenter.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <unordered_map>

#include "core/worker.hpp"
#include "render/backends/raster_backend.hpp"
#include "render/boom_shading.hpp"
#include "render/boom_shadow.hpp"
#include "render/motion_blur.hpp"
#include "render/projection.hpp"

namespace augrig {

namespace {

using detail::F32x4;
using detail::load_rgba;
using detail::shade;
using raster_backends::CamTriangle;
using raster_backends::DrawItem;
using raster_backends::kBlockShift;
using raster_backends::kDrawShift;
using raster_backends::kPrimMask;
using raster_backends::ObjectKind;
using raster_backends::VBox;

// Camera z where the ray d = (x, y, 1) from the camera centre hits `t`, or +inf: inside-ness is
// three signs against the edge planes, and z (the ray parameter, d.z being 1) comes from the plane.
// A hit outside the camera's clipping planes [near_m, far_m] is no hit, as in both rasterisers.
inline double ray_hit_z(const CamTriangle& t, const Eigen::Vector3d& d, double near_m, double far_m) {
  constexpr double kMiss = std::numeric_limits<double>::infinity();
  if (t.edge[0].dot(d) < 0 || t.edge[1].dot(d) < 0 || t.edge[2].dot(d) < 0) return kMiss;
  const double n_dot_d = t.n.dot(d);
  if (n_dot_d == 0) return kMiss;  // seen edge-on
  const double z = t.n_dot_v0 / n_dot_d;
  return z >= near_m && z <= far_m ? z : kMiss;  // near_m > 0: nothing behind the camera either
}

struct MapEntry {
  std::int32_t idx;  // top-left virtual sample of the bilinear 2x2 (j0 * Wv + i0); -1: no ray
  float fx, fy;      // bilinear fractions
};

// One view: what its raster backend sees (raster_backends::RasterView: the camera, the virtual image,
// this frame's triangles and boxes, the id and colour images) and what the resolve adds.
struct ViewState : raster_backends::RasterView {
  std::vector<MapEntry> map;  // per raw pixel
  // A raw row of DepthImage::kNone: copied over depth rows to clear them (a copy is vectorised,
  // std::fill_n of a float pattern is a scalar loop at -O2).
  std::vector<float> no_depth_row;
  // Where the backend marks the blocks it writes (RasterView::occupied): per group of kGroup raw
  // pixels of a row, the blocks their 2x2 sample neighbourhoods lie in.
  struct BlockRange {
    std::uint16_t bi0, bi1, bj0, bj1;  // inclusive; bi0 > bi1 when no pixel of the group has a ray
  };
  std::vector<BlockRange> groups;
  int groups_x = 0;
  // This frame's resolve, set by begin_resolve(): the raw boxes of the rendered boxes, the raw
  // pixels to visit (their union's box) and the part of the raw image the augmented image holds.
  std::vector<VBox> raw_boxes;
  VBox work, copy;
  struct Plane {
    double nx, ny, nz, c;  // n . p = c; depth along the ray (x, y, 1) is c / (n . (x, y, 1))
  };
  std::vector<Plane> planes;  // one per triangle, this frame
  std::vector<Eigen::Vector3d> scratch_vertices;
  // The boom's shadow this frame (camera frame; empty when the sun is down or unknown), the
  // receiver pixels in it with the share of light it takes (the camera look only), the sun and
  // the local vertical in this camera's frame, the receiver's rotation into it.
  BoomShadow shadow;
  std::vector<Eigen::Vector3d> shadow_vertices;
  std::vector<ShadowPixel> shadow_pixels;
  Eigen::Vector3d sun_cam, down_cam;
  Eigen::Matrix3d R_cam_receiver;
  Image spare;  // grow_augmented()'s second buffer
  // The boom's parts in the body frame at the instant this view is drawn at (mid-exposure, or a
  // sub-exposure instant of motion_view()).
  Pose T_body_boom, T_body_telescope;
  // Motion blur: drawing a sub-exposure instant (its shadow is not built, its augmented image is
  // its changed box only), and that instant's result (its pixels and coverage only are used).
  bool sub_instant = false;
  ViewResult instant;
  PixelBox dark;  // finish_shadow(): the pixels the shadow's darkening may reach (empty: none)
};

// What a thread resolving rows (of either view) keeps for itself: rows of one view may be
// resolved by both threads at once.
struct RowScratch {
  std::vector<std::uint32_t> visit_stamp;  // per triangle: last nearest_hit() call that tested it
  std::uint32_t stamp = 0;
  std::vector<std::pair<int, int>> spans;  // the row's spans of raw boxes
};

// One row of one view being resolved by one thread: what its pixels read and write.
struct ResolveRow {
  const ViewState& vs;
  RowScratch& scratch;
  const std::uint32_t *bids, *rids;  // the virtual image's ids
  std::uint8_t* mrow;                // the mask's row
  float* drow;                       // the receiver depth's row
  std::uint8_t* arow;                // the augmented image's row (null outside the changed box)
  std::uint8_t* alrow;               // the camera look's coverage row (null with the plain look)
  PixelFormat fmt;
  int bpp, W, Wv, v;
  int ax0;  // the augmented image's first column: raw pixel u is its byte (u - ax0) * bpp
};

constexpr int kGroup = 32;  // raw pixels per occupancy test

// Whether any sample around the raw pixels of group g of row v may hold an id this frame.
bool group_occupied(const ViewState& vs, int v, int g) {
  if (vs.occupied.empty()) return true;  // the backend marks no blocks: nothing known
  const ViewState::BlockRange& r = vs.groups[static_cast<std::size_t>(v) * vs.groups_x + g];
  for (int bj = r.bj0; bj <= r.bj1; ++bj)
    for (int bi = r.bi0; bi <= r.bi1; ++bi)
      if (vs.occupied[static_cast<std::size_t>(bj) * vs.blocks_x + bi]) return true;
  return false;
}
PixelBox to_pixel_box(const VBox& b) {
  return {b.x0, b.y0, b.x1, b.y1};
}

VBox intersect(VBox a, const VBox& b) {
  a.x0 = std::max(a.x0, b.x0), a.y0 = std::max(a.y0, b.y0);
  a.x1 = std::min(a.x1, b.x1), a.y1 = std::min(a.y1, b.y1);
  return a;
}
VBox unite(const VBox& a, const VBox& b) {
  if (a.empty()) return b;
  if (b.empty()) return a;
  return {std::min(a.x0, b.x0), std::min(a.y0, b.y0), std::max(a.x1, b.x1), std::max(a.y1, b.y1)};
}

// Reorders `mesh`'s triangles into up to `max_chunks` slabs along the longest axis of its bounds
// (by centroid) and returns their ranges. Long parts get several small screen boxes.
std::vector<std::pair<std::uint32_t, std::uint32_t>> split_into_chunks(Mesh& mesh, int max_chunks) {
  const auto n = static_cast<std::uint32_t>(mesh.triangle_count());
  const int k = std::clamp(static_cast<int>(n / 64), 1, max_chunks);
  if (k == 1) return {{0u, n}};
  const auto [lo, hi] = mesh.bounds();
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  std::vector<std::pair<float, std::uint32_t>> order(n);
  for (std::uint32_t t = 0; t < n; ++t) {
    float c = 0;
    for (int j = 0; j < 3; ++j) c += mesh.positions_m[mesh.indices[3 * t + j]][axis];
    order[t] = {c, t};
  }
  std::sort(order.begin(), order.end());
  std::vector<std::uint32_t> indices(mesh.indices.size());
  for (std::uint32_t t = 0; t < n; ++t)
    for (int j = 0; j < 3; ++j) indices[3 * t + j] = mesh.indices[3 * order[t].second + j];
  mesh.indices = std::move(indices);
  std::vector<std::pair<std::uint32_t, std::uint32_t>> chunks;
  for (int c = 0; c < k; ++c) {
    const std::uint32_t a = n * c / k, b = n * (c + 1) / k;
    chunks.emplace_back(a, b - a);
  }
  return chunks;
}

class AugmenterImpl final : public Augmenter {
 public:
  AugmenterImpl(const Rig& rig, const AugmentOptions& options) : rig_(rig), options_(options) {}

  Status init();

  Status augment(const StereoFrame& frame, const SceneState& scene, StereoResult& out) override;
  Status augment_view(int camera, const Frame& raw, const SceneState& scene, ViewResult& out) override;
  Status set_camera_look(int camera, const CameraLookParams& params) override;
  const CameraLookParams& camera_look(int camera) const override { return looks_.at(camera); }
  const AugmentTimings& timings() const override { return timings_; }
  Rasterizer rasterizer() const override { return backend_->kind(); }
  const Rig& rig() const override { return rig_; }
  const BoomModel& boom_model() const override { return boom_; }
  const Model& receiver_model() const override { return receiver_; }

 private:
  Status load_models();
  Status add_draws(ObjectKind kind, Model& model, bool cull);
  Status init_view(std::size_t camera);
  void init_groups(ViewState& vs) const;
  Status check_frame(int camera, const Frame& raw) const;
  void prepare_view(ViewState& vs, const SceneState& scene);
  // The backend clears what it drew last frame, then draws this frame's boxes.
  void rasterise(ViewState& vs, const SceneState& scene);
  void update_boxes(ViewState& vs) const;
  // Whether the camera look applies this frame, and the light the boom is shaded with.
  bool camera_look_on() const {
    return options_.look == Look::kCamera && options_.receiver_draw == ReceiverDraw::kMaskOnly;
  }
  const SceneLight& light_of(const SceneState& scene) const { return camera_look_on() ? scene.light : fixed_light_; }
  // The camera look over one view's changed box (after its rows are resolved).
  void look_view(int camera, const Frame& raw, ViewResult& out, bool motion);
  void shadow_view(ViewState& vs, ViewResult& out, const SceneState& scene) const;
  // After a view's rows are resolved, in two steps: the boom's shadow on the receiver (kMaskShadow;
  // with the camera look, the shares of light it takes; the augmented box grown for its
  // darkening), then the camera look and the shadow's darkening. Between them, motion_view().
  void finish_shadow(int camera, const Frame& raw, ViewResult& out, const SceneState& scene);
  void finish_look(int camera, const Frame& raw, ViewResult& out, bool motion, double& shadow_ms,
                   double& look_ms);
  // Both steps and the motion between them, the views in parallel where they can be.
  void finish_views(const Frame* const raws[2], ViewResult* const outs[2], const SceneState& scene);
  // augment()'s steps: both views drawn and resolved (two threads, or the backend's one), then
  // the statistics.
  void draw_and_resolve_concurrently(const StereoFrame& frame, const SceneState& scene, StereoResult& out);
  void draw_and_resolve_serially(const StereoFrame& frame, const SceneState& scene, StereoResult& out);
  void stereo_stats(const StereoFrame& frame, StereoResult& out);
  // Motion blur: the camera look's layer of one view averaged over sub-exposure instants (its
  // boom redrawn at each, masks and depth left as mid-exposure's); false when the boom moves
  // less than kMotionMinPx over the exposure (or no exposure is known): the mid-exposure layer.
  bool motion_view(int camera, const Frame& raw, ViewResult& out, const SceneState& scene,
                   RowScratch& scratch, int& samples);
  double exposure_s(int camera, const Frame& raw) const {
    const double ms = looks_[camera].exposure_ms;
    return ms >= 0 ? 1e-3 * ms : 1e-9 * static_cast<double>(std::max<std::int64_t>(raw.exposure_ns, 0));
  }
  // Draws every view's boom at `a` from now on (mid-exposure's).
  void set_boom(const BoomArticulation& a) {
    for (ViewState& vs : views_) {
      vs.T_body_boom = boom_pose(rig_.boom.pivot_body_m, a);
      vs.T_body_telescope = vs.T_body_boom * telescope_pose(a);
    }
  }
  Eigen::Vector3d receiver_normal(const ViewState& vs, std::size_t pixel, const Eigen::Vector3d& p_cam) const;
  void grow_augmented(ViewState& vs, const Frame& raw, ViewResult& out, const PixelBox& need) const;
  // The CPU pass per raw pixel (masks, receiver depth, composite) in two steps: begin_resolve()
  // clears what the last frame wrote and copies the raw box; resolve_rows() then takes chunks of
  // rows from `next_row` until none is left, so both threads can share one view's rows.
  void begin_resolve(ViewState& vs, const Frame& raw, ViewResult& out) const;
  void resolve_rows(const ViewState& vs, const Frame& raw, ViewResult& out, std::atomic<int>& next_row,
                    RowScratch& scratch) const;
  // resolve_rows()' parts, compiled per RowFlags and inlined into the row loop.
  template <class Flags>
  void resolve_rows_as(const ViewState& vs, const Frame& raw, ViewResult& out, std::atomic<int>& next_row,
                       RowScratch& scratch) const;
  template <class Flags>
  __attribute__((always_inline)) void resolve_pixel(const ResolveRow& r, int u) const;
  template <class Flags>
  __attribute__((always_inline)) void resolve_edge_pixel(const ResolveRow& row, int u, const MapEntry& e,
                                                         const Eigen::Vector2f& ray, const std::uint32_t b[4],
                                                         const std::uint32_t r[4]) const;
  template <class Flags>
  __attribute__((always_inline)) double centre_depth(const ResolveRow& row, const std::uint32_t* ids,
                                                     bool any, bool all, bool same, double x, double y) const;
  template <class Flags>
  __attribute__((always_inline)) F32x4 boom_colour(const ViewState& vs, std::uint32_t packed, std::size_t s,
                                                   const Eigen::Vector2f& ray) const;
  template <class Flags>
  __attribute__((always_inline)) void put_opaque(const ResolveRow& r, int u, F32x4 c) const;
  __attribute__((always_inline)) static void blend(const ResolveRow& r, int u, float alpha, float cr,
                                                   float cg, float cb);
  // The receiver's (or boom's) depth at a pixel centre's ray from its triangle's plane.
  double plane_depth(const ViewState& vs, std::uint32_t packed, const Eigen::Vector2f& ray) const {
    const ViewState::Plane& pl = vs.planes[global_index(packed)];
    return pl.c / (pl.nx * ray.x() + pl.ny * ray.y() + pl.nz);
  }
  void resolve_view(ViewState& vs, const Frame& raw, ViewResult& out, RowScratch& scratch) const {
    begin_resolve(vs, raw, out);
    std::atomic<int> next_row{0};
    resolve_rows(vs, raw, out, next_row, scratch);
  }
  std::vector<VBox> project_boxes(const ViewState& vs, std::initializer_list<ObjectKind> kinds) const;
  VBox raw_box_of(const ViewState& vs, const VBox& vbox) const;
  double nearest_hit(const ViewState& vs, RowScratch& scratch, const std::uint32_t* cands, int n, double x,
                     double y, bool rings) const;
  double covered_depth(const ViewState& vs, RowScratch& scratch, const std::uint32_t* ids, double x,
                       double y) const;
  enum class Surface { kSmooth, kCreased, kApart };
  Surface surface_of(const ViewState& vs, const std::uint32_t* g, int n) const;
  void build_rings();
  std::uint32_t global_index(std::uint32_t packed) const {
    return first_tri_of_draw_[packed >> kDrawShift] + (packed & kPrimMask);
  }
  const CamTriangle& triangle(const ViewState& vs, std::uint32_t packed) const {
    return vs.tris[global_index(packed)];
  }
  bool is_boom(std::uint32_t packed) const {
    return packed && draws_[(packed >> kDrawShift) - 1].kind != ObjectKind::kReceiver;
  }

  Rig rig_;
  AugmentOptions options_;
  BoomModel boom_;
  Model receiver_;
  std::vector<DrawItem> draws_;
  std::size_t total_tris_ = 0;
  // Triangles sharing a vertex (welded by position) with each triangle, global indices (CSR):
  // silhouette triangles seen edge-on are slivers that no sample lands in, but a sampled neighbour does.
  std::vector<std::uint32_t> ring_offsets_, ring_;
  std::array<std::uint32_t, 256> first_tri_of_draw_{};  // by draw id
  std::vector<ViewState> views_;
  std::array<RowScratch, 2> row_scratch_;  // one per thread resolving rows
  std::vector<CameraLookParams> looks_;     // per camera
  std::vector<LookBuffers> look_buffers_;   // per camera
  const SceneLight fixed_light_ = SceneLight::fixed();
  std::unique_ptr<raster_backends::RasterBackend> backend_;
  AugmentTimings timings_;
  // Runs the left view beside the calling thread's right view; started on first use.
  std::unique_ptr<Worker> worker_;
  Worker& worker() {
    if (!worker_) worker_ = std::make_unique<Worker>("augrig-view");
    return *worker_;
  }

  // Per-frame state shared by prepare/render.
  bool receiver_on_ = false;
  bool shadow_on_ = false;  // the receiver drawn and the sun up: the boom's shadow is looked for
};

Status AugmenterImpl::init() {
  if (rig_.cameras.size() != 2)
    return make_error("Augmenter::create(): the rig needs 2 cameras, has ", rig_.cameras.size());
  looks_.assign(rig_.cameras.size(), CameraLookParams{});
  look_buffers_.resize(rig_.cameras.size());
  for (std::size_t c = 0; c < options_.camera_looks.size() && c < looks_.size(); ++c)
    if (auto s = set_camera_look(static_cast<int>(c), options_.camera_looks[c]); !s) return s;
  if (auto s = load_models(); !s) return s;
  auto backend = raster_backends::make_raster_backend(options_);
  if (!backend) return backend.error();
  backend_ = std::move(*backend);

  const bool builtin_boom = rig_.boom.model.path.empty() && !options_.boom_model;
  if (auto s = add_draws(ObjectKind::kBoomFixed, boom_.fixed, builtin_boom); !s) return s;
  if (auto s = add_draws(ObjectKind::kBoomTelescope, boom_.telescope, builtin_boom); !s) return s;
  const bool builtin_receiver = rig_.receiver.model.path.empty() && !options_.receiver_model;
  if (auto s = add_draws(ObjectKind::kReceiver, receiver_, builtin_receiver); !s) return s;
  for (const DrawItem& d : draws_) first_tri_of_draw_[d.draw_id] = static_cast<std::uint32_t>(d.first_tri);
  build_rings();

  views_.resize(rig_.cameras.size());
  std::vector<raster_backends::RasterView*> views;
  for (std::size_t c = 0; c < rig_.cameras.size(); ++c) {
    if (auto s = init_view(c); !s) return s;
    views.push_back(&views_[c]);
  }
  if (auto s = backend_->init(draws_, views); !s) return s;
  for (ViewState& vs : views_) init_groups(vs);
  for (RowScratch& r : row_scratch_) r.visit_stamp.assign(total_tris_, 0);
  return {};
}

// The rig's models, or those the options give.
Status AugmenterImpl::load_models() {
  if (options_.boom_model) {
    boom_ = *options_.boom_model;
  } else if (rig_.boom.model.path.empty()) {
    boom_ = make_builtin_boom();
  } else {
    auto m = load_model(rig_.boom.model);
    if (!m) return m.error();
    boom_.fixed = std::move(*m);  // a user boom is one rigid part (no telescope)
  }
  apply_boom_material(boom_, rig_.boom.material);
  if (options_.receiver_model) {
    receiver_ = *options_.receiver_model;
  } else if (rig_.receiver.model.path.empty()) {
    receiver_ = make_builtin_receiver();
  } else {
    auto m = load_model(rig_.receiver.model);
    if (!m) return m.error();
    receiver_ = std::move(*m);
  }
  return {};
}

// One draw item per mesh; its id (1..255) goes into the id images' top byte.
Status AugmenterImpl::add_draws(ObjectKind kind, Model& model, bool cull) {
  for (Mesh& m : model.meshes) {
    if (draws_.size() >= 255)
      return make_error("Augmenter::create(): models have more than 255 meshes in total; merge them");
    if (m.triangle_count() > kPrimMask)
      return make_error("Augmenter::create(): mesh '", m.name, "' has more than 2^24 triangles");
    auto chunks = split_into_chunks(m, 4);  // before the backend sees it: it reorders the triangles
    draws_.push_back(
        {kind, &m, static_cast<std::uint8_t>(draws_.size() + 1), total_tris_, cull, std::move(chunks)});
    total_tris_ += m.triangle_count();
  }
  return {};
}

// Camera `camera`'s virtual image, its raw pixels' map into it and its (zero) id images.
Status AugmenterImpl::init_view(std::size_t camera) {
  ViewState& vs = views_[camera];
  vs.index = static_cast<int>(camera);
  vs.cam = &rig_.cameras[camera];
  const CameraModel& cm = vs.cam->model;
  // Anti-aliasing samples the virtual image between raw pixel centres (render/projection.hpp).
  auto vp = make_virtual_pinhole(cm, 1.0, options_.antialias, vs.cam->name);
  if (!vp) return vp.error();
  vs.vp = std::move(*vp);
  // Raw pixel centre -> top-left virtual sample of its bilinear neighbourhood.
  vs.map.resize(vs.vp.ray_xy.size());
  for (std::size_t i = 0; i < vs.map.size(); ++i) {
    const Eigen::Vector2f& r = vs.vp.ray_xy[i];
    if (!std::isfinite(r.x())) {
      vs.map[i] = {-1, 0, 0};
      continue;
    }
    if (vs.vp.identity) {
      vs.map[i] = {static_cast<std::int32_t>(i), 0.f, 0.f};
      continue;
    }
    const Eigen::Vector2d p = vs.vp.to_virtual(r.cast<double>());
    const int i0 = std::clamp(static_cast<int>(std::floor(p.x())), 0, vs.vp.width - 2);
    const int j0 = std::clamp(static_cast<int>(std::floor(p.y())), 0, vs.vp.height - 2);
    vs.map[i] = {j0 * vs.vp.width + i0, static_cast<float>(p.x() - i0), static_cast<float>(p.y() - j0)};
  }
  const std::size_t vn = static_cast<std::size_t>(vs.vp.width) * vs.vp.height;
  vs.boom_ids.assign(vn, 0);
  vs.recv_ids.assign(vn, 0);
  vs.tris.resize(total_tris_);
  vs.planes.resize(total_tris_);
  return {};
}

// ViewState::groups, where the backend marks the blocks it writes (RasterView::occupied).
void AugmenterImpl::init_groups(ViewState& vs) const {
  if (vs.occupied.empty()) return;
  const int W = vs.cam->model.width_px, H = vs.cam->model.height_px;
  vs.groups_x = (W + kGroup - 1) / kGroup;
  vs.groups.assign(static_cast<std::size_t>(vs.groups_x) * H, {1, 0, 1, 0});
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      const MapEntry& e = vs.map[static_cast<std::size_t>(v) * W + u];
      if (e.idx < 0) continue;
      const int i0 = e.idx % vs.vp.width, j0 = e.idx / vs.vp.width;
      const auto bi0 = static_cast<std::uint16_t>(i0 >> kBlockShift),
                 bi1 = static_cast<std::uint16_t>((i0 + 1) >> kBlockShift),
                 bj0 = static_cast<std::uint16_t>(j0 >> kBlockShift),
                 bj1 = static_cast<std::uint16_t>((j0 + 1) >> kBlockShift);
      ViewState::BlockRange& r = vs.groups[static_cast<std::size_t>(v) * vs.groups_x + u / kGroup];
      if (r.bi0 > r.bi1)
        r = {bi0, bi1, bj0, bj1};
      else
        r = {std::min(r.bi0, bi0), std::max(r.bi1, bi1), std::min(r.bj0, bj0), std::max(r.bj1, bj1)};
    }
}

Status AugmenterImpl::check_frame(int camera, const Frame& raw) const {
  const CameraModel& cm = rig_.cameras[camera].model;
  if (raw.image.width() != cm.width_px || raw.image.height() != cm.height_px)
    return make_error("Augmenter::augment(): ", rig_.cameras[camera].name, " frame is ", raw.image.width(),
                      "x", raw.image.height(), ", the rig says ", cm.width_px, "x", cm.height_px);
  return {};
}

// Camera-frame triangles of every draw item for this frame (double precision end to end).
void AugmenterImpl::prepare_view(ViewState& vs, const SceneState& scene) {
  const Pose T_cam_body = vs.cam->T_body_cam.inverse();
  for (const DrawItem& d : draws_) {
    if (d.kind == ObjectKind::kReceiver && !receiver_on_) continue;  // nothing will refer to it
    const Pose T_cam_obj = T_cam_body * (d.kind == ObjectKind::kReceiver    ? scene.T_body_receiver
                                         : d.kind == ObjectKind::kBoomFixed ? vs.T_body_boom
                                                                            : vs.T_body_telescope);
    const Eigen::Matrix3d R = T_cam_obj.R();
    const Eigen::Vector3d t = T_cam_obj.translation_m;
    auto& V = vs.scratch_vertices;
    V.resize(d.mesh->positions_m.size());
    for (std::size_t i = 0; i < V.size(); ++i) V[i] = R * d.mesh->positions_m[i].cast<double>() + t;
    const auto& idx = d.mesh->indices;
    for (std::size_t k = 0; k < d.mesh->triangle_count(); ++k) {
      CamTriangle& tri = vs.tris[d.first_tri + k];
      tri.v0 = V[idx[3 * k]];
      tri.e1 = V[idx[3 * k + 1]] - tri.v0;
      tri.e2 = V[idx[3 * k + 2]] - tri.v0;
      tri.n = tri.e1.cross(tri.e2);
      tri.n_dot_v0 = tri.n.dot(tri.v0);
      const Eigen::Vector3d v1 = tri.v0 + tri.e1, v2 = tri.v0 + tri.e2;
      const double sign = tri.n_dot_v0 >= 0 ? 1.0 : -1.0;  // det(v0, v1, v2) = n . v0
      tri.edge[0] = sign * tri.v0.cross(v1), tri.edge[1] = sign * v1.cross(v2),
      tri.edge[2] = sign * v2.cross(tri.v0);
      vs.planes[d.first_tri + k] = {tri.n.x(), tri.n.y(), tri.n.z(), tri.n_dot_v0};
    }
  }
  // The boom's triangles projected along the sun: its shadow, in this camera's frame (mid-exposure's).
  if (vs.sub_instant) return;
  vs.shadow.clear();
  if (!shadow_on_) return;
  const Eigen::Matrix3d R_cam_body = T_cam_body.R();
  vs.sun_cam = R_cam_body * scene.light.towards_light_body.normalized();
  vs.down_cam = R_cam_body * scene.light.down_body.normalized();
  vs.R_cam_receiver = R_cam_body * scene.T_body_receiver.R();
  auto& sv = vs.shadow_vertices;
  sv.clear();
  for (const DrawItem& d : draws_) {
    if (d.kind == ObjectKind::kReceiver) continue;
    for (std::size_t k = 0; k < d.mesh->triangle_count(); ++k) {
      const CamTriangle& t = vs.tris[d.first_tri + k];
      sv.push_back(t.v0), sv.push_back(t.v0 + t.e1), sv.push_back(t.v0 + t.e2);
    }
  }
  vs.shadow.build(sv, vs.sun_cam);
}

// Virtual-image boxes of the draw items of `kinds` seen from this camera: one per chunk, from its
// projected vertices (a mesh's projection lies in the hull of its projected vertices while all are
// in front), then merged where merging costs little area. The whole image if any vertex is nearer
// than the near plane; none for a chunk wholly beyond the far plane.
std::vector<VBox> AugmenterImpl::project_boxes(const ViewState& vs,
                                               std::initializer_list<ObjectKind> kinds) const {
  const VBox full{0, 0, vs.vp.width, vs.vp.height};
  const double near = vs.cam->near_m, far = vs.cam->far_m;
  std::vector<VBox> boxes;
  for (const DrawItem& d : draws_) {
    if (std::find(kinds.begin(), kinds.end(), d.kind) == kinds.end()) continue;
    for (const auto& [first, count] : d.chunks) {
      double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30, z0 = 1e30;
      // The triangles were moved into this camera's frame by prepare_view().
      for (std::uint32_t k = first; k < first + count; ++k) {
        const CamTriangle& t = vs.tris[d.first_tri + k];
        for (const Eigen::Vector3d& p : {t.v0, Eigen::Vector3d(t.v0 + t.e1), Eigen::Vector3d(t.v0 + t.e2)}) {
          if (p.z() < near) return {full};
          z0 = std::min(z0, p.z());
          const double qx = vs.vp.fx * p.x() / p.z() + vs.vp.cx, qy = vs.vp.fy * p.y() / p.z() + vs.vp.cy;
          x0 = std::min(x0, qx), x1 = std::max(x1, qx), y0 = std::min(y0, qy), y1 = std::max(y1, qy);
        }
      }
      if (x1 < -2 || y1 < -2 || x0 > vs.vp.width + 2 || y0 > vs.vp.height + 2) continue;
      if (z0 > far) continue;  // wholly beyond the far plane: nothing of it is drawn
      // Two samples of margin: every bilinear neighbourhood that touches the object is inside.
      const VBox b = intersect({static_cast<int>(std::floor(x0)) - 2, static_cast<int>(std::floor(y0)) - 2,
                                static_cast<int>(std::ceil(x1)) + 3, static_cast<int>(std::ceil(y1)) + 3},
                               full);
      if (!b.empty()) boxes.push_back(b);
    }
  }
  // Merge pairs whose union adds little area: fewer GL clears and readbacks, each with a fixed
  // cost (the CPU rasteriser: fewer box borders to project; its resolve skips empty blocks).
  constexpr std::size_t max_boxes = 6;
  auto area = [](const VBox& b) { return static_cast<double>(b.x1 - b.x0) * (b.y1 - b.y0); };
  for (bool merged = true; merged && boxes.size() > 1;) {
    merged = false;
    double best = 0;
    std::size_t bi = 0, bj = 0;
    for (std::size_t i = 0; i < boxes.size(); ++i)
      for (std::size_t j = i + 1; j < boxes.size(); ++j) {
        const double waste = area(unite(boxes[i], boxes[j])) - area(boxes[i]) - area(boxes[j]);
        // Always merge beyond max_boxes; otherwise only when it wastes under 4096 pixels.
        const double gain = (boxes.size() > max_boxes ? 1e18 : 4096.0) - waste;
        if (gain > best) best = gain, bi = i, bj = j;
      }
    if (best > 0) {
      boxes[bi] = unite(boxes[bi], boxes[bj]);
      boxes.erase(boxes.begin() + static_cast<std::ptrdiff_t>(bj));
      merged = true;
    }
  }
  return boxes;
}

// Raw pixels whose centres map into a virtual box: the lens maps the box's border to the border
// of its image, so the border's projections bound it.
VBox AugmenterImpl::raw_box_of(const ViewState& vs, const VBox& b) const {
  const CameraModel& cm = vs.cam->model;
  const VBox full{0, 0, cm.width_px, cm.height_px};
  if (b.empty()) return {};
  if (vs.vp.identity) return intersect(b, full);
  if (b.x0 <= 0 && b.y0 <= 0 && b.x1 >= vs.vp.width && b.y1 >= vs.vp.height) return full;
  double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30;
  const double max_radius = cm.max_valid_radius();
  auto visit = [&](double i, double j) -> bool {
    const auto uv = cm.project({(i - vs.vp.cx) / vs.vp.fx, (j - vs.vp.cy) / vs.vp.fy, 1.0}, max_radius);
    if (!uv) return false;
    x0 = std::min(x0, uv->x()), x1 = std::max(x1, uv->x()), y0 = std::min(y0, uv->y()),
    y1 = std::max(y1, uv->y());
    return true;
  };
  constexpr double kStep = 2.0;
  for (double i = b.x0; i <= b.x1; i += kStep)
    if (!visit(i, b.y0) || !visit(i, b.y1)) return full;
  for (double j = b.y0; j <= b.y1; j += kStep)
    if (!visit(b.x0, j) || !visit(b.x1, j)) return full;
  if (!visit(b.x1, b.y1)) return full;
  return intersect({static_cast<int>(std::floor(x0)) - 2, static_cast<int>(std::floor(y0)) - 2,
                    static_cast<int>(std::ceil(x1)) + 3, static_cast<int>(std::ceil(y1)) + 3},
                   full);
}

// Has the backend zero what it drew last frame (the id images are zero outside the boxes), and
// finds this frame's boxes.
void AugmenterImpl::update_boxes(ViewState& vs) const {
  backend_->clear(vs);
  vs.boom_vboxes = project_boxes(vs, {ObjectKind::kBoomFixed, ObjectKind::kBoomTelescope});
  vs.recv_vboxes = receiver_on_ ? project_boxes(vs, {ObjectKind::kReceiver}) : std::vector<VBox>{};
}

void AugmenterImpl::rasterise(ViewState& vs, const SceneState& scene) {
  update_boxes(vs);
  const Pose T_cam_body = vs.cam->T_body_cam.inverse();
  raster_backends::RasterFrame f;
  f.T_cam_obj[static_cast<int>(ObjectKind::kBoomFixed)] = T_cam_body * vs.T_body_boom;
  f.T_cam_obj[static_cast<int>(ObjectKind::kBoomTelescope)] = T_cam_body * vs.T_body_telescope;
  f.T_cam_obj[static_cast<int>(ObjectKind::kReceiver)] = T_cam_body * scene.T_body_receiver;
  f.R_cam_body = T_cam_body.R();
  f.light = &light_of(scene);
  f.camera_look = camera_look_on();
  backend_->draw(vs, f, timings_);
}

void AugmenterImpl::build_rings() {
  // Weld vertices by exact position (meshes duplicate them at creases for flat normals).
  std::vector<std::vector<std::uint32_t>> tris_of_vertex;
  std::vector<std::array<std::uint32_t, 3>> tri_vertices(total_tris_);
  for (const DrawItem& d : draws_) {
    std::unordered_map<std::uint64_t, std::uint32_t> welded;
    std::vector<std::uint32_t> id_of(d.mesh->positions_m.size());
    for (std::size_t i = 0; i < id_of.size(); ++i) {
      const Eigen::Vector3f& p = d.mesh->positions_m[i];
      std::uint32_t bits[3];
      std::memcpy(bits, p.data(), sizeof(bits));
      const std::uint64_t key = (static_cast<std::uint64_t>(bits[0]) * 0x9E3779B97F4A7C15ull) ^
                                (static_cast<std::uint64_t>(bits[1]) * 0xC2B2AE3D27D4EB4Full) ^ bits[2];
      // Hash collisions only merge rings (more candidates), never lose one: harmless.
      auto [it, fresh] = welded.emplace(key, static_cast<std::uint32_t>(tris_of_vertex.size()));
      if (fresh) tris_of_vertex.emplace_back();
      id_of[i] = it->second;
    }
    for (std::size_t k = 0; k < d.mesh->triangle_count(); ++k) {
      const auto g = static_cast<std::uint32_t>(d.first_tri + k);
      for (int c = 0; c < 3; ++c) {
        const std::uint32_t v = id_of[d.mesh->indices[3 * k + c]];
        tri_vertices[g][c] = v;
        tris_of_vertex[v].push_back(g);
      }
    }
  }
  ring_offsets_.assign(total_tris_ + 1, 0);
  ring_.clear();
  for (std::size_t g = 0; g < total_tris_; ++g) {
    const std::size_t begin = ring_.size();
    for (std::uint32_t v : tri_vertices[g])
      for (std::uint32_t t : tris_of_vertex[v])
        if (t != g && std::find(ring_.begin() + begin, ring_.end(), t) == ring_.end()) ring_.push_back(t);
    ring_offsets_[g + 1] = static_cast<std::uint32_t>(ring_.size());
  }
}

// Whether two camera-frame triangles share a vertex (the same position up to the rounding of
// v0 + e1, v0 + e2): the one-ring relation, from the triangles themselves, whose cache lines the
// ray tests have just loaded (the CSR rings would cost cache misses on every covered edge pixel).
bool share_a_vertex(const CamTriangle& a, const CamTriangle& b) {
  const Eigen::Vector3d pa[3] = {a.v0, a.v0 + a.e1, a.v0 + a.e2}, pb[3] = {b.v0, b.v0 + b.e1, b.v0 + b.e2};
  for (const Eigen::Vector3d& p : pa)
    for (const Eigen::Vector3d& q : pb)
      if ((p - q).squaredNorm() <= 1e-20 * (1 + p.squaredNorm())) return true;
  return false;
}

// How the distinct triangles g[0..n) of view `vs` lie around a point: kSmooth when each pair is
// nearly parallel (normals within ~8 degrees: a smooth surface, also where its triangles are
// smaller than a sample and the samples' are not neighbours); kCreased when each pair that is not
// shares a vertex; else kApart: parts passing through each other
// (their planes cross between the samples) or one part in front of another, where the triangle
// nearest at the pixel centre may be one that no sample holds.
AugmenterImpl::Surface AugmenterImpl::surface_of(const ViewState& vs, const std::uint32_t* g, int n) const {
  constexpr double kCos2 = 0.98;  // cos^2 of ~8.1 degrees
  Surface s = Surface::kSmooth;
  for (int a = 0; a < n; ++a)
    for (int b = a + 1; b < n; ++b) {
      const Eigen::Vector3d &na = vs.tris[g[a]].n, &nb = vs.tris[g[b]].n;
      const double dot = na.dot(nb);
      if (dot * dot >= kCos2 * na.squaredNorm() * nb.squaredNorm()) continue;  // either facing
      if (!share_a_vertex(vs.tris[g[a]], vs.tris[g[b]])) return Surface::kApart;
      s = Surface::kCreased;
    }
  return s;
}

// Nearest intersection (camera z) of the ray (x, y, 1) with the candidate triangles (packed ids)
// and, when none of them is hit and `rings`, with their one-ring neighbours; +inf if none.
double AugmenterImpl::nearest_hit(const ViewState& vs, RowScratch& scratch, const std::uint32_t* cands, int n,
                                  double x, double y, bool rings) const {
  const Eigen::Vector3d d(x, y, 1.0);
  double best = std::numeric_limits<double>::infinity();
  const double near_m = vs.cam->near_m, far_m = vs.cam->far_m;
  auto test = [&](const CamTriangle& t) { best = std::min(best, ray_hit_z(t, d, near_m, far_m)); };
  // Each triangle is tested once per call: a stamp per triangle, no search.
  if (++scratch.stamp == 0)
    std::fill(scratch.visit_stamp.begin(), scratch.visit_stamp.end(), 0u), scratch.stamp = 1;
  auto first_time = [&](std::uint32_t g) {
    if (scratch.visit_stamp[g] == scratch.stamp) return false;
    scratch.visit_stamp[g] = scratch.stamp;
    return true;
  };
  std::uint32_t direct[4];
  int n_direct = 0;
  for (int k = 0; k < n; ++k) {
    if (!cands[k]) continue;
    const std::uint32_t g = global_index(cands[k]);
    if (first_time(g)) test(vs.tris[g]), direct[n_direct++] = g;
  }
  if (std::isfinite(best) || !rings) return best;
  for (int k = 0; k < n_direct; ++k) {
    const std::uint32_t g = direct[k];
    for (std::uint32_t i = ring_offsets_[g]; i < ring_offsets_[g + 1]; ++i)
      if (first_time(ring_[i])) test(vs.tris[ring_[i]]);
  }
  return best;
}

// Depth at the ray (x, y, 1) where all four samples around it hold one object's triangles (ids
// not all equal): the centre is covered, and its depth is the nearest of those triangles that
// contains the ray, with the few distinct ids told apart directly, or on a smooth surface the
// first sample's plane when a sliver none of them holds does. Where they are apart (parts through
// each other, one in front of another; surface_of()), or creased and none is hit, the nearest hit
// among them and their one-rings, as the triangle nearest at the centre may be one no sample
// holds; the first sample's plane only when that finds nothing either. Out of line, so that the
// per-pixel loop stays small.
__attribute__((noinline)) double AugmenterImpl::covered_depth(const ViewState& vs, RowScratch& scratch,
                                                              const std::uint32_t* ids, double x,
                                                              double y) const {
  const Eigen::Vector3d d(x, y, 1.0);
  double best = std::numeric_limits<double>::infinity();
  std::uint32_t g[4];
  int n = 0;
  for (int k = 0; k < 4; ++k) {
    if ((k > 0 && ids[k] == ids[0]) || (k > 1 && ids[k] == ids[1]) || (k > 2 && ids[k] == ids[2])) continue;
    g[n] = global_index(ids[k]);
    best = std::min(best, ray_hit_z(vs.tris[g[n++]], d, vs.cam->near_m, vs.cam->far_m));
  }
  // One surface: a hit is the nearest; on a smooth one, a sliver between the samples lies on it,
  // and the first sample's plane gives its depth (to within the surface's bend over the sliver).
  const Surface surface = surface_of(vs, g, n);
  if (surface == Surface::kSmooth || (surface == Surface::kCreased && std::isfinite(best))) {
    if (std::isfinite(best)) return best;
    const CamTriangle& t = vs.tris[g[0]];
    return t.n_dot_v0 / t.n.dot(d);
  }
  // Every candidate and its one-ring (whatever the candidates hit: the nearest may be in a ring).
  if (++scratch.stamp == 0)
    std::fill(scratch.visit_stamp.begin(), scratch.visit_stamp.end(), 0u), scratch.stamp = 1;
  for (int k = 0; k < n; ++k) scratch.visit_stamp[g[k]] = scratch.stamp;
  for (int k = 0; k < n; ++k)
    for (std::uint32_t i = ring_offsets_[g[k]]; i < ring_offsets_[g[k] + 1]; ++i) {
      const std::uint32_t t = ring_[i];
      if (scratch.visit_stamp[t] == scratch.stamp) continue;
      scratch.visit_stamp[t] = scratch.stamp;
      best = std::min(best, ray_hit_z(vs.tris[t], d, vs.cam->near_m, vs.cam->far_m));
    }
  if (std::isfinite(best)) return best;
  const CamTriangle& t = triangle(vs, ids[0]);
  return t.n_dot_v0 / t.n.dot(d);
}

void AugmenterImpl::begin_resolve(ViewState& vs, const Frame& raw, ViewResult& out) const {
  const CameraModel& cm = vs.cam->model;
  const int W = cm.width_px, H = cm.height_px;
  const VBox full{0, 0, W, H};

  // Outputs are reused: clear only what the previous frame wrote.
  const bool look = camera_look_on();
  if (out.mask.width() != W || out.mask.height() != H || out.mask.format() != PixelFormat::kMono8 ||
      (look && (out.boom_alpha.width() != W || out.boom_alpha.height() != H))) {
    out.mask = Image(W, H, PixelFormat::kMono8);
    if (look) out.boom_alpha = Image(W, H, PixelFormat::kMono8);
    out.boom_box = out.receiver_box = {};
  }
  if (!look) out.boom_alpha = Image();
  if (out.receiver_depth.width != W || out.receiver_depth.height != H) {
    out.receiver_depth = {W, H, std::vector<float>(static_cast<std::size_t>(W) * H, DepthImage::kNone)};
    out.receiver_box = {};
  }
  for (const PixelBox& b : {out.boom_box, out.receiver_box}) {
    const VBox c = intersect({b.x0, b.y0, b.x1, b.y1}, full);
    for (int y = c.y0; y < c.y1; ++y) std::memset(out.mask.row(y) + c.x0, 0, c.x1 - c.x0);
  }
  if (look) {  // the coverage is written only inside the boom's box
    const VBox c = intersect({out.boom_box.x0, out.boom_box.y0, out.boom_box.x1, out.boom_box.y1}, full);
    for (int y = c.y0; y < c.y1; ++y) std::memset(out.boom_alpha.row(y) + c.x0, 0, c.x1 - c.x0);
  }
  {  // receiver depth is written only where the receiver is, inside its box
    const VBox c =
        intersect({out.receiver_box.x0, out.receiver_box.y0, out.receiver_box.x1, out.receiver_box.y1}, full);
    if (vs.no_depth_row.size() != static_cast<std::size_t>(W)) vs.no_depth_row.assign(W, DepthImage::kNone);
    for (int y = c.y0; y < c.y1; ++y)
      std::memcpy(&out.receiver_depth.z_m[static_cast<std::size_t>(y) * W + c.x0], vs.no_depth_row.data(),
                  sizeof(float) * static_cast<std::size_t>(std::max(c.x1 - c.x0, 0)));
  }
  // Raw pixels to visit: the union of the boxes' raw images, row by row, each pixel once.
  std::vector<VBox>& raw_boxes = vs.raw_boxes;
  raw_boxes.clear();
  VBox boom_raw, recv_raw;
  for (const VBox& b : vs.boom_vboxes)
    raw_boxes.push_back(raw_box_of(vs, b)), boom_raw = unite(boom_raw, raw_boxes.back());
  for (const VBox& b : vs.recv_vboxes)
    raw_boxes.push_back(raw_box_of(vs, b)), recv_raw = unite(recv_raw, raw_boxes.back());
  out.boom_box = to_pixel_box(boom_raw);
  out.receiver_box = to_pixel_box(recv_raw);
  const VBox work = unite(boom_raw, recv_raw);
  vs.work = work;

  // The augmented image starts as the raw image, byte for byte: all of it, or the box where the
  // boom (and a receiver overlay) may change it. Raw pixel (u, v) is its byte (u - ax0) * bpp of
  // row v - ay0.
  const Image& src = raw.image;
  const bool overlay_drawn = !vs.recv_rgba.empty();
  VBox changed = overlay_drawn ? work : boom_raw;
  if (look && !changed.empty()) {  // the camera's PSF spreads the boom a little beyond its pixels
    const int m = psf_margin_px(looks_[vs.cam - rig_.cameras.data()]);
    changed = intersect({changed.x0 - m, changed.y0 - m, changed.x1 + m, changed.y1 + m}, full);
  }
  out.augmented_box = to_pixel_box(changed);
  const bool whole = options_.augmented_output == AugmentedOutput::kWholeImage && !vs.sub_instant;
  const VBox copy = whole ? full : changed;
  vs.copy = copy;
  const int cw = std::max(copy.x1 - copy.x0, 0), ch = std::max(copy.y1 - copy.y0, 0);
  if (out.augmented.width() != cw || out.augmented.height() != ch || out.augmented.format() != src.format())
    out.augmented.reshape(cw, ch, src.format());
  const std::size_t copy_bytes = static_cast<std::size_t>(cw) * bytes_per_pixel(src.format());
  if (whole && src.stride_bytes() == copy_bytes && out.augmented.stride_bytes() == copy_bytes)
    std::memcpy(out.augmented.data(), src.data(), copy_bytes * H);  // one call for the frame
  else
    for (int y = 0; y < ch; ++y)
      std::memcpy(out.augmented.row(y), src.row(copy.y0 + y) + copy.x0 * bytes_per_pixel(src.format()),
                  copy_bytes);
}

// The rows' code is compiled once per combination of these flags, so that the per-pixel code
// carries no tests (nor loads) for what this frame does not have.
template <bool kOverlay, bool kCpu, bool kRecv, bool kIdentity, bool kRgb>
struct RowFlags {
  static constexpr bool overlay = kOverlay;    // a validation overlay's receiver colour (OpenGL)
  static constexpr bool cpu = kCpu;            // the boom's colour per triangle (shades_per_pixel())
  static constexpr bool recv = kRecv;          // the receiver was drawn
  static constexpr bool identity = kIdentity;  // the virtual samples are the raw pixel centres
  static constexpr bool rgb = kRgb;            // RGB8 or RGBA8
};

void AugmenterImpl::resolve_rows(const ViewState& vs, const Frame& raw, ViewResult& out,
                                 std::atomic<int>& next_row, RowScratch& scratch) const {
  const PixelFormat fmt = raw.image.format();
  using T = std::true_type;
  using F = std::false_type;
  auto with = [](bool b, auto f) { return b ? f(T{}) : f(F{}); };
  with(!vs.recv_rgba.empty(), [&](auto o) {
    with(backend_->shades_per_pixel(), [&](auto c) {
      with(!vs.recv_vboxes.empty(), [&](auto r) {
        with(vs.vp.identity, [&](auto i) {
          with(fmt == PixelFormat::kRGB8 || fmt == PixelFormat::kRGBA8, [&](auto rgb) {
            using Flags = RowFlags<decltype(o)::value, decltype(c)::value, decltype(r)::value,
                                   decltype(i)::value, decltype(rgb)::value>;
            if constexpr (!(Flags::overlay && Flags::cpu))  // overlays are drawn by OpenGL only
              resolve_rows_as<Flags>(vs, raw, out, next_row, scratch);
          });
        });
      });
    });
  });
}

template <class Flags>
void AugmenterImpl::resolve_rows_as(const ViewState& vs, const Frame& raw, ViewResult& out,
                                    std::atomic<int>& next_row, RowScratch& scratch) const {
  const CameraModel& cm = vs.cam->model;
  const int W = cm.width_px;
  const VBox work = vs.work, copy = vs.copy;
  std::vector<std::pair<int, int>>& spans = scratch.spans;
  // Chunks of rows, first come first served: a thread the machine delays leaves its rows to the other.
  constexpr int kChunkRows = 8;
  int chunk_end = 0;
  auto take_chunk = [&] {
    const int first = work.y0 + next_row.fetch_add(kChunkRows, std::memory_order_relaxed);
    chunk_end = std::min(first + kChunkRows, work.y1);
    return first;
  };
  for (int v = take_chunk(); v < work.y1; v = v + 1 < chunk_end ? v + 1 : take_chunk()) {
    const ResolveRow row{
        vs, scratch, vs.boom_ids.data(), vs.recv_ids.data(), out.mask.row(v),
        &out.receiver_depth.z_m[static_cast<std::size_t>(v) * W],
        // Null outside the changed box (rows with the receiver alone): nothing is composited there.
        v >= copy.y0 && v < copy.y1 ? out.augmented.row(v - copy.y0) : nullptr,
        // The camera look's coverage row (null with the plain look).
        out.boom_alpha.empty() ? nullptr : out.boom_alpha.row(v), raw.image.format(),
        bytes_per_pixel(raw.image.format()), W, vs.vp.width, v, copy.x0};
    spans.clear();
    for (const VBox& b : vs.raw_boxes)
      if (v >= b.y0 && v < b.y1 && !b.empty()) spans.emplace_back(b.x0, b.x1);
    std::sort(spans.begin(), spans.end());
    std::size_t n_spans = 0;
    for (const auto& sp : spans) {  // merge overlapping spans in place
      if (n_spans && sp.first <= spans[n_spans - 1].second)
        spans[n_spans - 1].second = std::max(spans[n_spans - 1].second, sp.second);
      else
        spans[n_spans++] = sp;
    }
    // Groups of kGroup raw pixels whose virtual samples hold nothing are skipped whole (where the
    // backend marks the blocks it writes).
    for (std::size_t si = 0; si < n_spans; ++si)
      for (int g0 = spans[si].first; g0 < spans[si].second;) {
        const int g1 = std::min(spans[si].second, (g0 / kGroup + 1) * kGroup);
        if (group_occupied(vs, v, g0 / kGroup))
          for (int u = g0; u < g1; ++u) resolve_pixel<Flags>(row, u);
        g0 = g1;
      }
  }
}

// One raw pixel: mask, receiver depth and composite (every pixel at most once per frame).
template <class Flags>
inline __attribute__((always_inline)) void AugmenterImpl::resolve_pixel(const ResolveRow& r, int u) const {
  constexpr bool overlay = Flags::overlay, cpu = Flags::cpu, recv = Flags::recv, identity = Flags::identity;
  const ViewState& vs = r.vs;
  const MapEntry& e = vs.map[static_cast<std::size_t>(r.v) * r.W + u];
  if (e.idx < 0) return;
  // The 2x2 samples' ids, read once (the byte stores below could alias them). One sample when
  // the grids coincide; no receiver loads when none was drawn.
  const std::uint32_t* pb = r.bids + e.idx;
  const std::uint32_t* pr = r.rids + e.idx;
  const std::size_t o1 = identity ? 0 : 1, o2 = identity ? 0 : r.Wv, o3 = identity ? 0 : r.Wv + 1;
  const std::uint32_t b0 = pb[0], b1 = pb[o1], b2 = pb[o2], b3 = pb[o3];
  const std::uint32_t r0 = recv ? pr[0] : 0, r1 = recv ? pr[o1] : 0, r2 = recv ? pr[o2] : 0,
                      r3 = recv ? pr[o3] : 0;
  // Most pixels of a box see nothing: one OR over the samples skips them.
  if (!(b0 | b1 | b2 | b3 | r0 | r1 | r2 | r3)) return;
  const Eigen::Vector2f& ray = vs.vp.ray_xy[static_cast<std::size_t>(r.v) * r.W + u];
  if (identity && !overlay) {
    // The samples ARE the pixel centres: the rasteriser's coverage and depth test are already exact there.
    r.mrow[u] = static_cast<std::uint8_t>((b0 ? kMaskBoom : 0) | (r0 ? kMaskReceiver : 0));
    if (r0) r.drow[u] = static_cast<float>(plane_depth(vs, r0, ray));
    if (b0) put_opaque<Flags>(r, u, boom_colour<Flags>(vs, b0, static_cast<std::size_t>(e.idx), ray));
    return;
  }
  if (!(b0 | b1 | b2 | b3) && r0 == r1 && r0 == r2 && r0 == r3 && !overlay) {
    // Inside one receiver triangle with no boom around: the most common covered pixel.
    r.mrow[u] = kMaskReceiver;
    r.drow[u] = static_cast<float>(plane_depth(vs, r0, ray));
    return;
  }
  if (b0 && b1 && b2 && b3 && !overlay) {
    const bool recv_none = !(r0 | r1 | r2 | r3);
    const bool recv_one = r0 && r0 == r1 && r0 == r2 && r0 == r3;
    if (recv_none || recv_one) {
      // Boom all around, in front of the receiver at every sample (the depth test) and no
      // receiver silhouette nearby: an opaque boom pixel, its colour bilinear.
      r.mrow[u] = static_cast<std::uint8_t>(kMaskBoom | (recv_one ? kMaskReceiver : 0));
      if (recv_one) r.drow[u] = static_cast<float>(plane_depth(vs, r0, ray));
      if (cpu) {
        // Any of the four triangles: the interpolated normal and texture are continuous.
        put_opaque<Flags>(r, u, boom_colour<Flags>(vs, b0, 0, ray));
      } else {
        const std::uint8_t* c0 = &vs.boom_rgba[static_cast<std::size_t>(e.idx) * 4];
        const std::uint8_t* c2 = c0 + static_cast<std::size_t>(r.Wv) * 4;
        const float w0 = (1 - e.fx) * (1 - e.fy), w1 = e.fx * (1 - e.fy), w2 = (1 - e.fx) * e.fy,
                    w3 = e.fx * e.fy;
        put_opaque<Flags>(
            r, u, w0 * load_rgba(c0) + w1 * load_rgba(c0 + 4) + w2 * load_rgba(c2) + w3 * load_rgba(c2 + 4));
      }
      return;
    }
  }
  const std::uint32_t b[4] = {b0, b1, b2, b3}, rr[4] = {r0, r1, r2, r3};
  resolve_edge_pixel<Flags>(r, u, e, ray, b, rr);
}

// A pixel near an edge or a crossing: each object's depth at the centre, the masks, and the
// boom's (and an overlay's) coverage composited over the raw pixel.
template <class Flags>
inline __attribute__((always_inline)) void AugmenterImpl::resolve_edge_pixel(const ResolveRow& row, int u,
                                                                             const MapEntry& e,
                                                                             const Eigen::Vector2f& ray,
                                                                             const std::uint32_t b[4],
                                                                             const std::uint32_t r[4]) const {
  constexpr bool overlay = Flags::overlay, identity = Flags::identity;
  const ViewState& vs = row.vs;
  const bool b_any = (b[0] | b[1] | b[2] | b[3]) != 0, b_all = b[0] && b[1] && b[2] && b[3],
             b_same = b[0] == b[1] && b[0] == b[2] && b[0] == b[3];
  const bool r_any = (r[0] | r[1] | r[2] | r[3]) != 0, r_all = r[0] && r[1] && r[2] && r[3],
             r_same = r[0] == r[1] && r[0] == r[2] && r[0] == r[3];
  const double x = ray.x(), y = ray.y();
  const double z_r = centre_depth<Flags>(row, r, r_any, r_all, r_same, x, y);
  // Boom, front-most where the rasteriser's depth test kept it at the samples.
  const double z_b = centre_depth<Flags>(row, b, b_any, b_all, b_same, x, y);
  const bool has_r = std::isfinite(z_r) && z_r > 0;
  const bool has_b = std::isfinite(z_b) && z_b > 0 && (!has_r || z_b < z_r);
  row.mrow[u] = static_cast<std::uint8_t>((has_b ? kMaskBoom : 0) | (has_r ? kMaskReceiver : 0));
  if (has_r) row.drow[u] = static_cast<float>(z_r);

  // Composite: the boom's bilinear coverage of the centre, anti-aliasing its edges.
  float alpha = 0, cr = 0, cg = 0, cb = 0;
  if (b_any) {
    // The 2x2 samples around the centre (one sample when the grids coincide).
    const int ns = identity ? 1 : 4;
    const std::uint32_t off[4] = {0, 1, static_cast<std::uint32_t>(row.Wv),
                                  static_cast<std::uint32_t>(row.Wv) + 1};
    const float w[4] = {(1 - e.fx) * (1 - e.fy), e.fx * (1 - e.fy), (1 - e.fx) * e.fy, e.fx * e.fy};
    for (int k = 0; k < ns; ++k) {
      if (!b[k]) continue;
      const float wk = identity ? 1.0f : w[k];
      const F32x4 c = boom_colour<Flags>(vs, b[k], static_cast<std::size_t>(e.idx) + off[k], ray);
      alpha += wk, cr += wk * c[0], cg += wk * c[1], cb += wk * c[2];
    }
    if (!options_.antialias) {
      const float s = alpha > 0 ? 1.0f / alpha : 0.f;
      cr *= s, cg *= s, cb *= s;
      alpha = has_b ? 1.f : 0.f;
      cr *= alpha, cg *= alpha, cb *= alpha;
    }
  }
  if (overlay && has_r && !has_b) {
    // Validation overlay: the receiver model drawn translucent (or its wireframe) at its pose.
    const std::uint8_t* c = &vs.recv_rgba[static_cast<std::size_t>(e.idx) * 4];
    const float a = options_.receiver_draw == ReceiverDraw::kTranslucent ? 0.45f : (c[3] > 0 ? 1.0f : 0.0f);
    if (a > 0 && alpha < 1) {
      const float k = a * (1 - alpha);
      cr += k * (0.5f * c[0] + 127.f), cg += k * 0.5f * c[1], cb += k * 0.5f * c[2];
      alpha += k;
    }
  }
  if (alpha <= 0) return;
  if (alpha > 1) alpha = 1;
  blend(row, u, alpha, cr, cg, cb);
}

// An object's depth at the pixel centre (x, y, 1) from its samples' ids: read off when one
// triangle covers all samples (it then covers the centre, triangles being convex), else exact
// ray tests with the candidates. Covered all around, the centre is covered too: only its depth
// is sought, and when the centre's triangle is not among the samples' (a sliver) the first
// sample's plane gives it. At a silhouette the slivers' neighbours are searched as well.
template <class Flags>
inline __attribute__((always_inline)) double AugmenterImpl::centre_depth(const ResolveRow& row,
                                                                         const std::uint32_t* ids, bool any,
                                                                         bool all, bool same, double x,
                                                                         double y) const {
  constexpr bool identity = Flags::identity;
  if (!any) return std::numeric_limits<double>::infinity();
  if (all && !same && !identity) return covered_depth(row.vs, row.scratch, ids, x, y);
  if (!(all && same)) {
    const double z = nearest_hit(row.vs, row.scratch, ids, identity ? 1 : 4, x, y, !all);
    if (std::isfinite(z) || !all) return z;
  }
  const CamTriangle& t = triangle(row.vs, ids[0]);
  return t.n_dot_v0 / t.n.dot(Eigen::Vector3d(x, y, 1.0));
}

// The boom's colour (0..255) here for the triangle virtual sample `s` holds: the backend's shaded
// sample, or (shades_per_pixel()) that triangle shaded exactly at this pixel's centre.
template <class Flags>
inline __attribute__((always_inline)) F32x4 AugmenterImpl::boom_colour(const ViewState& vs,
                                                                       std::uint32_t packed, std::size_t s,
                                                                       const Eigen::Vector2f& ray) const {
  return Flags::cpu ? shade(vs.shading[global_index(packed)], ray.x(), ray.y())
                    : load_rgba(&vs.boom_rgba[s * 4]);
}

// Writes an opaque boom colour (0..255, rounded here) in the raw pixel's format.
template <class Flags>
inline __attribute__((always_inline)) void AugmenterImpl::put_opaque(const ResolveRow& r, int u,
                                                                     F32x4 c) const {
  if (r.alrow) r.alrow[u] = 255;
  c += 0.5f;
  std::uint8_t* px = r.arow + static_cast<std::size_t>(u - r.ax0) * r.bpp;
  if constexpr (Flags::rgb) {
    px[0] = static_cast<std::uint8_t>(c[0]), px[1] = static_cast<std::uint8_t>(c[1]),
    px[2] = static_cast<std::uint8_t>(c[2]);
    return;
  }
  switch (r.fmt) {
    case PixelFormat::kRGB8:
    case PixelFormat::kRGBA8:
      px[0] = static_cast<std::uint8_t>(c[0]), px[1] = static_cast<std::uint8_t>(c[1]),
      px[2] = static_cast<std::uint8_t>(c[2]);
      break;
    case PixelFormat::kMono8:
      px[0] = static_cast<std::uint8_t>(0.299f * c[0] + 0.587f * c[1] + 0.114f * c[2]);
      break;
    default:
      px[0] = static_cast<std::uint8_t>(c[bayer_channel(r.fmt, u, r.v)]);
  }
}

// Blends the premultiplied colour (cr, cg, cb) of coverage `alpha` over the raw pixel u.
inline __attribute__((always_inline)) void AugmenterImpl::blend(const ResolveRow& r, int u, float alpha,
                                                                float cr, float cg, float cb) {
  if (r.alrow) r.alrow[u] = static_cast<std::uint8_t>(alpha * 255.f + 0.5f);
  std::uint8_t* px = r.arow + static_cast<std::size_t>(u - r.ax0) * r.bpp;
  const float ia = 1 - alpha;
  auto mix = [&](std::uint8_t raw_value, float premult) {
    return static_cast<std::uint8_t>(std::clamp(raw_value * ia + premult + 0.5f, 0.f, 255.f));
  };
  switch (r.fmt) {
    case PixelFormat::kRGB8:
    case PixelFormat::kRGBA8:
      px[0] = mix(px[0], cr), px[1] = mix(px[1], cg), px[2] = mix(px[2], cb);
      break;
    case PixelFormat::kMono8:
      px[0] = mix(px[0], 0.299f * cr + 0.587f * cg + 0.114f * cb);
      break;
    default: {  // Bayer: the site's own colour channel
      const int ch = bayer_channel(r.fmt, u, r.v);
      px[0] = mix(px[0], ch == 0 ? cr : ch == 1 ? cg : cb);
    }
  }
}

Status AugmenterImpl::set_camera_look(int camera, const CameraLookParams& params) {
  if (camera < 0 || camera >= static_cast<int>(looks_.size()))
    return make_error("Augmenter::set_camera_look(): no camera ", camera);
  if (!(params.psf_sigma_px >= 0 && params.psf_sigma_px <= kMaxPsfSigmaPx))
    return make_error("Augmenter::set_camera_look(): camera ", camera, ": PSF sigma ", params.psf_sigma_px,
                      " px is outside 0..", kMaxPsfSigmaPx);
  if (!(params.gamma >= 0.2 && params.gamma <= 5))
    return make_error("Augmenter::set_camera_look(): camera ", camera, ": gamma ", params.gamma,
                      " is outside 0.2..5");
  looks_[camera] = params;
  return {};
}

void AugmenterImpl::look_view(int camera, const Frame& raw, ViewResult& out, bool motion) {
  if (!camera_look_on() || out.augmented_box.empty()) return;
  const PixelBox& box = out.augmented_box;
  const bool whole = out.augmented.width() == raw.image.width() && out.augmented.height() == raw.image.height();
  const ImageView aug = whole ? sub_view(out.augmented.view(), box) : out.augmented.view();
  if (motion)  // motion_view() made the layer over the box and put the raw pixels back
    apply_look_layer(raw.image.view(), aug, looks_[camera], static_cast<std::uint64_t>(raw.t_ns), camera,
                     look_buffers_[camera]);
  else
    apply_camera_look(raw.image.view(), out.boom_alpha.cview(), aug, box, looks_[camera],
                      static_cast<std::uint64_t>(raw.t_ns), camera, look_buffers_[camera]);
}

// The receiver's normal at a raw pixel's surface point `p_cam` (camera frame, facing the camera):
// the triangle one of the pixel's four virtual samples holds whose plane passes nearest the
// point (creases), its vertex normals interpolated there (the model's smooth surface).
Eigen::Vector3d AugmenterImpl::receiver_normal(const ViewState& vs, std::size_t pixel,
                                               const Eigen::Vector3d& p_cam) const {
  Eigen::Vector3d n = -p_cam;
  const MapEntry& e = vs.map[pixel];
  std::uint32_t best = 0;
  double best_gap = std::numeric_limits<double>::infinity();
  if (e.idx >= 0) {
    const auto i = static_cast<std::size_t>(e.idx), w = static_cast<std::size_t>(vs.vp.width);
    for (const std::size_t j : {i, i + 1, i + w, i + w + 1}) {
      if (j >= vs.recv_ids.size()) continue;
      const std::uint32_t id = vs.recv_ids[j];
      if (!id || is_boom(id)) continue;
      const CamTriangle& t = triangle(vs, id);
      const double gap = std::abs(t.n.dot(p_cam) - t.n_dot_v0) / std::max(t.n.norm(), 1e-300);
      if (gap < best_gap) best_gap = gap, best = id;
    }
  }
  if (best) {
    const CamTriangle& t = triangle(vs, best);
    n = t.n;
    const DrawItem& d = draws_[(best >> kDrawShift) - 1];
    const std::size_t k = best & kPrimMask;
    if (d.mesh->normals.size() == d.mesh->positions_m.size()) {
      // Barycentric weights of the point in the triangle's plane.
      const double nn = t.n.squaredNorm();
      const Eigen::Vector3d r = p_cam - t.v0;
      const double b1 = r.cross(t.e2).dot(t.n) / nn, b2 = t.e1.cross(r).dot(t.n) / nn;
      const std::uint32_t* vi = &d.mesh->indices[3 * k];
      const Eigen::Vector3d smooth =
          vs.R_cam_receiver * ((1 - b1 - b2) * d.mesh->normals[vi[0]].cast<double>() +
                               b1 * d.mesh->normals[vi[1]].cast<double>() + b2 * d.mesh->normals[vi[2]].cast<double>());
      if (smooth.allFinite() && smooth.squaredNorm() > 1e-12) n = smooth.dot(t.n) >= 0 ? smooth : Eigen::Vector3d(-smooth);
    }
  }
  if (n.dot(p_cam) > 0) n = -n;  // the side the camera sees
  return n.normalized();
}

// Every receiver pixel whose surface point (its centre's ray at the receiver's depth) sees the
// sun through the boom gets kMaskShadow; with the camera look, its share of light the shadow takes.
void AugmenterImpl::shadow_view(ViewState& vs, ViewResult& out, const SceneState& scene) const {
  vs.shadow_pixels.clear();
  if (vs.shadow.empty()) return;
  const int W = vs.cam->model.width_px, H = vs.cam->model.height_px;
  const VBox rb = intersect({out.receiver_box.x0, out.receiver_box.y0, out.receiver_box.x1, out.receiver_box.y1},
                            {0, 0, W, H});
  const Eigen::Matrix3d& R = vs.shadow.R_sun_F();
  const bool look = camera_look_on();
  const SceneLight& sl = scene.light;
  for (int y = rb.y0; y < rb.y1; ++y) {
    std::uint8_t* m = out.mask.row(y);
    const std::size_t row = static_cast<std::size_t>(y) * W;
    const float* z = &out.receiver_depth.z_m[row];
    const Eigen::Vector2f* ray = &vs.vp.ray_xy[row];
    for (int x = rb.x0; x < rb.x1; ++x) {
      if (m[x] != kMaskReceiver) continue;  // the receiver, in front of the boom there
      const double zx = z[x];
      const Eigen::Vector3d q = zx * (R.col(0) * ray[x].x() + R.col(1) * ray[x].y() + R.col(2));
      if (!vs.shadow.may_cover(q.x(), q.y()) || !vs.shadow.in_shadow_sun(q)) continue;
      m[x] |= kMaskShadow;
      if (!look) continue;
      // The direct light's share of what falls on the surface there (SceneLight::on()).
      const Eigen::Vector3d p(ray[x].x() * zx, ray[x].y() * zx, zx);
      const Eigen::Vector3d n = receiver_normal(vs, row + x, p);
      const double facing = std::max(n.dot(vs.sun_cam), 0.0);
      const Eigen::Vector3d all = sl.on(n, vs.sun_cam, vs.down_cam);
      ShadowPixel sp{x, y, {}};
      for (int c = 0; c < 3; ++c) sp.share[c] = all[c] > 0 ? static_cast<float>(sl.direct[c] * facing / all[c]) : 0.f;
      vs.shadow_pixels.push_back(sp);
    }
  }
}

// Widens the augmented image's box to hold `need` as well (the shadow's darkening can reach past
// the boom's box): a whole image only says so; a box image is made anew, the raw image round
// what it held.
void AugmenterImpl::grow_augmented(ViewState& vs, const Frame& raw, ViewResult& out, const PixelBox& need) const {
  const PixelBox& b = out.augmented_box;
  const VBox old{b.x0, b.y0, b.x1, b.y1};
  const VBox u = unite(old, {need.x0, need.y0, need.x1, need.y1});
  if (u.x0 == old.x0 && u.y0 == old.y0 && u.x1 == old.x1 && u.y1 == old.y1) return;
  const Image& src = raw.image;
  const bool whole = out.augmented.width() == src.width() && out.augmented.height() == src.height();
  if (!whole) {
    const std::size_t bpp = bytes_per_pixel(src.format());
    Image& g = vs.spare;
    g.reshape(u.x1 - u.x0, u.y1 - u.y0, src.format());
    for (int y = u.y0; y < u.y1; ++y) {
      std::uint8_t* dst = g.row(y - u.y0);
      if (y >= old.y0 && y < old.y1 && !old.empty()) {
        std::memcpy(dst, src.row(y) + u.x0 * bpp, (old.x0 - u.x0) * bpp);
        std::memcpy(dst + (old.x0 - u.x0) * bpp, out.augmented.row(y - old.y0), (old.x1 - old.x0) * bpp);
        std::memcpy(dst + (old.x1 - u.x0) * bpp, src.row(y) + old.x1 * bpp, (u.x1 - old.x1) * bpp);
      } else {
        std::memcpy(dst, src.row(y) + u.x0 * bpp, (u.x1 - u.x0) * bpp);
      }
    }
    std::swap(out.augmented, g);
  }
  out.augmented_box = to_pixel_box(u);
}

void AugmenterImpl::finish_shadow(int camera, const Frame& raw, ViewResult& out, const SceneState& scene) {
  ViewState& vs = views_[camera];
  shadow_view(vs, out, scene);
  // The darkening spreads by the PSF: the augmented image must hold it before the look runs.
  vs.dark = {};
  if (vs.shadow_pixels.empty()) return;
  VBox sb{raw.image.width(), raw.image.height(), 0, 0};
  for (const ShadowPixel& p : vs.shadow_pixels)
    sb.x0 = std::min(sb.x0, p.u), sb.y0 = std::min(sb.y0, p.v), sb.x1 = std::max(sb.x1, p.u + 1),
    sb.y1 = std::max(sb.y1, p.v + 1);
  const int m = psf_margin_px(looks_[camera]);
  vs.dark = to_pixel_box(
      intersect({sb.x0 - m, sb.y0 - m, sb.x1 + m, sb.y1 + m}, {0, 0, raw.image.width(), raw.image.height()}));
  grow_augmented(vs, raw, out, vs.dark);
}

void AugmenterImpl::finish_look(int camera, const Frame& raw, ViewResult& out, bool motion, double& shadow_ms,
                                double& look_ms) {
  using Clock = std::chrono::steady_clock;
  auto ms = [](Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); };
  const auto a = Clock::now();
  look_view(camera, raw, out, motion);
  const auto b = Clock::now();
  look_ms += ms(b - a);
  const PixelBox& dark = views_[camera].dark;
  if (dark.empty()) return;
  const PixelBox& box = out.augmented_box;
  const bool whole =
      out.augmented.width() == raw.image.width() && out.augmented.height() == raw.image.height();
  const PixelBox at =
      whole ? dark : PixelBox{dark.x0 - box.x0, dark.y0 - box.y0, dark.x1 - box.x0, dark.y1 - box.y0};
  apply_shadow_look(sub_view(out.augmented.view(), at), dark, views_[camera].shadow_pixels, looks_[camera],
                    static_cast<std::uint64_t>(raw.t_ns), camera, look_buffers_[camera]);
  shadow_ms += ms(Clock::now() - b);
}

void AugmenterImpl::finish_views(const Frame* const raws[2], ViewResult* const outs[2],
                                 const SceneState& scene) {
  using Clock = std::chrono::steady_clock;
  auto ms = [](Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); };
  double shadow_ms[2] = {0, 0}, look_ms[2] = {0, 0}, motion_ms[2] = {0, 0};
  int samples[2] = {1, 1};
  bool motion[2] = {false, false};
  auto motion_of = [&](int c) {
    const auto a = Clock::now();
    motion[c] = motion_view(c, *raws[c], *outs[c], scene, row_scratch_[c], samples[c]);
    motion_ms[c] = ms(Clock::now() - a);
  };
  auto shadow_of = [&](int c) {
    const auto a = Clock::now();
    finish_shadow(c, *raws[c], *outs[c], scene);
    shadow_ms[c] += ms(Clock::now() - a);
    if (backend_->concurrent_views()) motion_of(c);  // else it draws on this thread only: below
  };
  {
    worker().start([&] { shadow_of(0); });
    const Worker::Join join{worker()};
    shadow_of(1);
    worker().wait();
  }
  if (!backend_->concurrent_views()) motion_of(0), motion_of(1);
  {
    worker().start([&] { finish_look(0, *raws[0], *outs[0], motion[0], shadow_ms[0], look_ms[0]); });
    const Worker::Join join{worker()};
    finish_look(1, *raws[1], *outs[1], motion[1], shadow_ms[1], look_ms[1]);
    worker().wait();
  }
  timings_.shadow_ms = shadow_ms[0] + shadow_ms[1];
  timings_.motion_ms = motion_ms[0] + motion_ms[1];
  timings_.look_ms = look_ms[0] + look_ms[1] + timings_.motion_ms;
  timings_.motion_samples = std::max(samples[0], samples[1]);
}

bool AugmenterImpl::motion_view(int camera, const Frame& raw, ViewResult& out, const SceneState& scene,
                                RowScratch& scratch, int& samples) {
  samples = 1;
  if (!camera_look_on() || out.boom_box.empty()) return false;
  ViewState& vs = views_[camera];
  const double exposure = exposure_s(camera, raw);
  const double motion_px =
      boom_motion_px(boom_, rig_.boom.pivot_body_m, *vs.cam, scene.boom, scene.boom_rate_per_s, exposure);
  samples = motion_samples(motion_px);
  if (samples == 1) return false;
  // The layer's box: the mid-exposure boom's, widened by the half-trail each way and the PSF.
  const int W = raw.image.width(), H = raw.image.height();
  const int m = static_cast<int>(std::ceil(0.5 * motion_px)) + 2 + psf_margin_px(looks_[camera]);
  const PixelBox& bb = out.boom_box;
  grow_augmented(vs, raw, out,
                 to_pixel_box(intersect({bb.x0 - m, bb.y0 - m, bb.x1 + m, bb.y1 + m}, {0, 0, W, H})));
  const PixelBox& box = out.augmented_box;
  LookBuffers& buf = look_buffers_[camera];
  begin_look_layer(box, raw.image.format(), buf);
  // The raw pixels back where the mid-exposure composite changed them: the look composites anew.
  const bool whole = out.augmented.width() == W && out.augmented.height() == H;
  const std::size_t bpp = bytes_per_pixel(raw.image.format());
  const PixelBox ob = to_pixel_box(intersect({bb.x0, bb.y0, bb.x1, bb.y1}, {box.x0, box.y0, box.x1, box.y1}));
  for (int y = ob.y0; y < ob.y1; ++y)
    std::memcpy(out.augmented.row(whole ? y : y - box.y0) + (whole ? ob.x0 : ob.x0 - box.x0) * bpp,
                raw.image.row(y) + ob.x0 * bpp, ob.width() * bpp);
  // Each instant drawn whole (the receiver occludes the boom), only its boom's pixels kept.
  vs.sub_instant = true;
  const float weight = 1.f / static_cast<float>(samples);
  for (int k = 0; k < samples; ++k) {
    const BoomArticulation a =
        articulation_at(scene.boom, scene.boom_rate_per_s, sub_exposure_offset_s(k, samples, exposure));
    vs.T_body_boom = boom_pose(rig_.boom.pivot_body_m, a);
    vs.T_body_telescope = vs.T_body_boom * telescope_pose(a);
    prepare_view(vs, scene);
    rasterise(vs, scene);
    ViewResult& r = vs.instant;
    begin_resolve(vs, raw, r);
    std::atomic<int> next_row{0};
    resolve_rows(vs, raw, r, next_row, scratch);
    const PixelBox part = to_pixel_box(intersect({r.boom_box.x0, r.boom_box.y0, r.boom_box.x1, r.boom_box.y1},
                                                 {box.x0, box.y0, box.x1, box.y1}));
    if (part.empty()) continue;
    // r.augmented holds r.augmented_box, which holds its boom's box.
    const PixelBox at{part.x0 - r.augmented_box.x0, part.y0 - r.augmented_box.y0,
                      part.x1 - r.augmented_box.x0, part.y1 - r.augmented_box.y0};
    add_to_look_layer(raw.image.view(), r.boom_alpha.cview(), sub_view(r.augmented.cview(), at), part, weight,
                      buf);
  }
  vs.sub_instant = false;
  vs.T_body_boom = boom_pose(rig_.boom.pivot_body_m, scene.boom);
  vs.T_body_telescope = vs.T_body_boom * telescope_pose(scene.boom);
  return true;
}

Status AugmenterImpl::augment_view(int camera, const Frame& raw, const SceneState& scene, ViewResult& out) {
  if (camera < 0 || camera >= static_cast<int>(views_.size()))
    return make_error("Augmenter::augment_view(): no camera ", camera);
  if (auto s = check_frame(camera, raw); !s) return s;
  set_boom(scene.boom);
  receiver_on_ = scene.receiver_present && options_.receiver_proxy;
  shadow_on_ = receiver_on_ && scene.light.sun_up;
  ViewState& vs = views_[camera];
  prepare_view(vs, scene);
  rasterise(vs, scene);
  resolve_view(vs, raw, out, row_scratch_[0]);
  double shadow_ms = 0, look_ms = 0;
  finish_shadow(camera, raw, out, scene);
  int samples = 1;
  const bool motion = motion_view(camera, raw, out, scene, row_scratch_[0], samples);
  finish_look(camera, raw, out, motion, shadow_ms, look_ms);
  return {};
}

Status AugmenterImpl::augment(const StereoFrame& frame, const SceneState& scene, StereoResult& out) {
  using Clock = std::chrono::steady_clock;
  auto ms = [](Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); };
  for (int c = 0; c < 2; ++c)
    if (auto s = check_frame(c, c == 0 ? frame.left : frame.right); !s) return s;
  set_boom(scene.boom);
  receiver_on_ = scene.receiver_present && options_.receiver_proxy;
  shadow_on_ = receiver_on_ && scene.light.sun_up;
  out.receiver_drawn = receiver_on_;

  timings_.gl_clear_ms = timings_.gl_draw_ms = timings_.gl_readback_ms = 0;
  const auto t0 = Clock::now();
  if (backend_->concurrent_views())
    draw_and_resolve_concurrently(frame, scene, out);
  else
    draw_and_resolve_serially(frame, scene, out);

  // The shadow and the look, the views in parallel: neither reads the other's pixels.
  timings_.shadow_ms = timings_.look_ms = timings_.motion_ms = 0;
  timings_.motion_samples = 1;
  if (camera_look_on() || shadow_on_) {
    const Frame* const raws[2] = {&frame.left, &frame.right};
    ViewResult* const outs[2] = {&out.left, &out.right};
    finish_views(raws, outs, scene);
  }

  const auto t4 = Clock::now();
  stereo_stats(frame, out);
  timings_.stats_ms = ms(Clock::now() - t4);
  timings_.total_ms = ms(Clock::now() - t0);
  return backend_->errors();
}

// Each thread draws one view, begins its resolve and resolves its rows, chunk by chunk; then it
// helps with what is left of the other view's rows, once that view has begun. The views rarely
// cost the same (the receiver fills one more than the other), and a thread the machine delays
// would otherwise hold up the frame.
void AugmenterImpl::draw_and_resolve_concurrently(const StereoFrame& frame, const SceneState& scene,
                                                  StereoResult& out) {
  using Clock = std::chrono::steady_clock;
  auto ms = [](Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); };
  const Frame* raws[2] = {&frame.left, &frame.right};
  ViewResult* results[2] = {&out.left, &out.right};
  enum : int { kNotYet, kBegun, kFailed };
  struct alignas(64) Shared {  // a cache line per view: each thread mostly takes its own rows
    std::atomic<int> next_row{0};
    std::atomic<int> state{kNotYet};  // of the view's resolve
  };
  Shared view_state[2];
  struct Times {
    double raster = 0, resolve = 0;
  };
  auto both = [&](int c, Times& t) {
    try {
      const auto a = Clock::now();
      prepare_view(views_[c], scene);
      rasterise(views_[c], scene);
      const auto b = Clock::now();
      begin_resolve(views_[c], *raws[c], *results[c]);
      t.raster = ms(b - a), t.resolve = ms(Clock::now() - b);
    } catch (...) {
      view_state[c].state.store(kFailed);  // the other thread must not wait for this view, nor resolve it
      view_state[c].state.notify_all();
      throw;
    }
    view_state[c].state.store(kBegun);
    view_state[c].state.notify_all();
    const auto a = Clock::now();
    resolve_rows(views_[c], *raws[c], *results[c], view_state[c].next_row, row_scratch_[c]);
    const int o = 1 - c;
    for (int s = view_state[o].state.load(); s == kNotYet; s = view_state[o].state.load())
      view_state[o].state.wait(s);
    if (view_state[o].state.load() == kBegun)
      resolve_rows(views_[o], *raws[o], *results[o], view_state[o].next_row, row_scratch_[c]);
    t.resolve += ms(Clock::now() - a);
  };
  Times left, right;
  worker().start([&] { both(0, left); });
  const Worker::Join join{worker()};
  both(1, right);
  worker().wait();
  timings_.render_ms = left.raster + right.raster;
  timings_.masks_ms = left.resolve + right.resolve;
}

// The backend draws on this thread only (OpenGL: its context's); the left view's CPU work
// overlaps the right view's drawing.
void AugmenterImpl::draw_and_resolve_serially(const StereoFrame& frame, const SceneState& scene,
                                              StereoResult& out) {
  using Clock = std::chrono::steady_clock;
  auto ms = [](Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); };
  const auto t0 = Clock::now();
  prepare_view(views_[0], scene);
  rasterise(views_[0], scene);
  const auto t1 = Clock::now();
  double left_cpu_ms = 0;
  worker().start([&] {
    const auto a = Clock::now();
    resolve_view(views_[0], frame.left, out.left, row_scratch_[0]);
    left_cpu_ms = ms(Clock::now() - a);
  });
  const Worker::Join join{worker()};
  prepare_view(views_[1], scene);
  rasterise(views_[1], scene);
  const auto t2 = Clock::now();
  resolve_view(views_[1], frame.right, out.right, row_scratch_[1]);
  const double right_cpu = ms(Clock::now() - t2);
  timings_.render_ms = ms(t1 - t0) + ms(t2 - t1);
  worker().wait();
  timings_.masks_ms = left_cpu_ms + right_cpu;
}

// The occlusion statistics and stereo classes from both views' masks and depth.
void AugmenterImpl::stereo_stats(const StereoFrame& frame, StereoResult& out) {
  // The classes reuse this view's own pixel rays (same undistortion as the masks).
  StereoClassOptions copt = options_.class_options;
  copt.compute_classes = receiver_on_ && options_.stereo_classes;
  copt.left_rays_xy = &views_[0].vp.ray_xy;
  copt.worker = &worker();
  // The masks are zero outside the boxes this frame rendered.
  VBox content;
  for (const PixelBox& b :
       {out.left.boom_box, out.left.receiver_box, out.right.boom_box, out.right.receiver_box})
    content = unite(content, {b.x0, b.y0, b.x1, b.y1});
  copt.content_x0 = content.x0, copt.content_y0 = content.y0;
  copt.content_x1 = content.x1, copt.content_y1 = content.y1;
  out.stats = compute_occlusion_stats(frame.t_key_ns, out.left.mask, out.right.mask, out.left.receiver_depth,
                                      out.right.receiver_depth, rig_.left().model, rig_.right().model,
                                      rig_.T_right_left(), copt,
                                      copt.compute_classes ? &out.stereo_classes : nullptr);
  if (!copt.compute_classes) out.stereo_classes.clear();
}

}  // namespace

SceneState scene_at_contact(const Rig& rig, const BoomDimensions& boom, const Eigen::Vector3d& receptacle_m,
                            const BoomArticulation& a, const Eigen::Vector3d& offset_body_m) {
  SceneState s;
  s.boom = a;
  const Eigen::Vector3d tip_body =
      boom_pose(rig.boom.pivot_body_m, a) * Eigen::Vector3d(boom.nozzle_tip_m(a.extension_m), 0, 0);
  s.T_body_receiver = Pose::from(Eigen::Matrix3d::Identity(), tip_body - receptacle_m + offset_body_m);
  return s;
}

const char* to_string(Rasterizer r) {
  switch (r) {
    case Rasterizer::kAuto:
      return "auto";
    case Rasterizer::kOpenGl:
      return "opengl";
    case Rasterizer::kCpu:
      return "cpu";
  }
  return "?";
}

Expected<std::unique_ptr<Augmenter>> Augmenter::create(const Rig& rig, const AugmentOptions& options) {
  auto a = std::make_unique<AugmenterImpl>(rig, options);
  if (auto s = a->init(); !s) return s.error();
  return std::unique_ptr<Augmenter>(std::move(a));
}

Image whole_augmented(const Image& raw, const ViewResult& r) {
  if (r.augmented.width() == raw.width() && r.augmented.height() == raw.height()) return r.augmented;
  Image out = Image::copy_of(raw.view());
  const PixelBox& b = r.augmented_box;
  const std::size_t n = static_cast<std::size_t>(b.width()) * bytes_per_pixel(raw.format());
  const ImageView inside = sub_view(out.view(), b);
  for (int y = 0; y < b.height(); ++y) std::memcpy(inside.row(y), r.augmented.row(y), n);
  return out;
}

void make_whole_augmented(const Image& raw, ViewResult& r) {
  Image& a = r.augmented;
  const int W = raw.width(), H = raw.height();
  if (a.width() == W && a.height() == H) return;
  const PixelBox b = r.augmented_box;
  const int bw = a.width(), bh = a.height();
  const std::size_t bpp = bytes_per_pixel(raw.format()), box_bytes = static_cast<std::size_t>(bw) * bpp;
  const bool box_fits = bw == b.width() && bh == b.height() && b.x0 >= 0 && b.y0 >= 0 && b.x1 <= W &&
                        b.y1 <= H && a.stride_bytes() == box_bytes;
  if (a.format() != raw.format() || (bw * bh > 0 && !box_fits)) {
    a = whole_augmented(raw, r);
    return;
  }
  // In place, with no allocation once the buffer has grown (a live pipeline's buffers circulate
  // through the window, whole): the box's rows, packed from the start, move to their places last
  // row first (each one's place lies at or after where it is, and after the rows above it), then
  // the raw image fills the rest.
  a.reshape(W, H, raw.format());
  if (bw * bh > 0)
    for (int y = bh - 1; y >= 0; --y)
      std::memmove(a.row(b.y0 + y) + static_cast<std::size_t>(b.x0) * bpp,
                   a.data() + static_cast<std::size_t>(y) * box_bytes, box_bytes);
  const std::size_t row_bytes = static_cast<std::size_t>(W) * bpp;
  const std::size_t left = static_cast<std::size_t>(std::max(b.x0, 0)) * bpp, right = left + box_bytes;
  for (int y = 0; y < H; ++y) {
    if (bw * bh == 0 || y < b.y0 || y >= b.y0 + bh) {
      std::memcpy(a.row(y), raw.row(y), row_bytes);
    } else {
      std::memcpy(a.row(y), raw.row(y), left);
      std::memcpy(a.row(y) + right, raw.row(y) + right, row_bytes - right);
    }
  }
}

}  // namespace augrig
