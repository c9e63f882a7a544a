// RasterBackend: who draws the boom and the receiver into one view's virtual pinhole image (packed
// triangle ids, and the boom's colour) for the augmenter (render/augmenter.cpp), which keeps the
// rest: the camera-frame triangles, the boxes, the masks, the composite, the look, the statistics.
// One backend a file (render/backends/gl_raster.cpp, cpu_raster.cpp), as Dear ImGui's imgui_impl_*:
// a new one (Vulkan, CUDA) is one file, its Rasterizer value and its line in make_raster_backend().
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "core/expected.hpp"
#include "core/pose.hpp"
#include "render/augmenter.hpp"
#include "render/boom_shading.hpp"
#include "render/projection.hpp"

namespace augrig::raster_backends {

enum class ObjectKind : std::uint8_t { kBoomFixed, kBoomTelescope, kReceiver };

// One mesh to draw; its id (1..255) goes into the id images' top byte, the triangle in the low 24 bits.
struct DrawItem {
  ObjectKind kind;
  const Mesh* mesh;
  std::uint8_t draw_id;
  std::size_t first_tri;  // this mesh's first triangle in RasterView::tris
  bool cull;              // built-in, consistently wound meshes only
  // Spatially compact triangle ranges [first, first + count) of the mesh: each gets its own
  // screen box, so a long diagonal part (the boom's tube) costs its footprint, not its bounding box.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> chunks;
};
constexpr std::uint32_t kDrawShift = 24;
constexpr std::uint32_t kPrimMask = (1u << kDrawShift) - 1;

// A triangle in the current view's camera frame, ready for exact ray tests from the origin.
struct CamTriangle {
  // First what the ray test reads (two cache lines rather than three).
  // Planes through the camera centre and each edge, signed so that a ray from the camera passes
  // through the triangle, in front of the camera, iff all three dot products with it are >= 0.
  Eigen::Vector3d edge[3];
  Eigen::Vector3d n;  // n = e1 x e2
  double n_dot_v0;
  Eigen::Vector3d v0, e1, e2;
};

// A box of virtual samples [x0, x1) x [y0, y1).
struct VBox {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool empty() const { return x1 <= x0 || y1 <= y0; }
};

// Blocks of 8 x 8 samples a backend may mark as written (RasterView::occupied's bits).
constexpr int kBlockShift = 3;
constexpr int kBlockSize = 1 << kBlockShift;
constexpr std::uint8_t kReceiverBlock = 1, kBoomBlock = 2;

// One view as a backend sees it: what the augmenter set, and the images the backend writes.
struct RasterView {
  int index = 0;  // the rig camera's
  const RigCamera* cam = nullptr;
  VirtualPinhole vp;
  std::vector<CamTriangle> tris;                   // all draw items' triangles, this frame
  std::vector<VBox> boom_vboxes, recv_vboxes;      // the boxes to draw (the last frame's until clear())
  std::vector<std::uint32_t> boom_ids, recv_ids;   // packed ids; zero outside the boxes
  std::vector<std::uint8_t> boom_rgba, recv_rgba;  // colour per sample (recv: overlays only)
  std::vector<detail::BoomShading> shading;        // or per boom triangle (shades_per_pixel())
  std::vector<std::uint8_t> occupied;              // optional: the blocks written this frame
  int blocks_x = 0;
};

// What one view's draw needs of the frame.
struct RasterFrame {
  std::array<Pose, 3> T_cam_obj;  // by ObjectKind
  Eigen::Matrix3d R_cam_body;
  const SceneLight* light = nullptr;
  bool camera_look = false;  // the boom lit with the camera look's specular light
};

class RasterBackend {
 public:
  virtual ~RasterBackend() = default;
  virtual Rasterizer kind() const = 0;
  // Whether two threads may draw two views at once (OpenGL: one context, its one thread).
  virtual bool concurrent_views() const = 0;
  // Where the boom's colour is: RasterView::shading, shaded at each pixel centre, or (false)
  // RasterView::boom_rgba's samples, interpolated.
  virtual bool shades_per_pixel() const = 0;
  // Once, after the augmenter set each view's cam, vp, tris and id images (all zero); `draws`
  // outlives the backend, which reads it on every draw().
  virtual Status init(const std::vector<DrawItem>& draws, const std::vector<RasterView*>& views) = 0;
  // Zeroes what the last draw() wrote into the id images, before the augmenter sets new boxes.
  virtual void clear(RasterView& v) = 0;
  // The receiver's ids, then the boom's ids and colour where it is in front, inside the view's
  // boxes only (its id images stay zero elsewhere). GL stage times go to `timings`.
  virtual void draw(RasterView& v, const RasterFrame& f, AugmentTimings& timings) = 0;
  virtual Status errors() const = 0;  // the backend's pending errors, after a frame
};

// The backend options.rasterizer names (kAuto: kCpu where GL_RENDERER is a software renderer).
Expected<std::unique_ptr<RasterBackend>> make_raster_backend(const AugmentOptions& options);

// Each backend's factory, in its file under render/backends/.
std::unique_ptr<RasterBackend> make_gl_raster(const AugmentOptions& options);
std::unique_ptr<RasterBackend> make_cpu_raster();

}  // namespace augrig::raster_backends
