// WorldView: the display's third-person view of the rig, like the seed paper's Fig. 1, 4 and 6:
// the tanker (a simple procedural airframe), the boom at its articulation, the receiver at its
// pose (and, optionally, a wireframe at the fused pose being validated), each camera's frustum and
// its image quad textured with that camera's current image. Rendered offscreen at a modest
// resolution into a texture the display draws scaled; an orbit camera (drag, scroll) looks at it.
// Everything is in the tanker body frame (FRD); the orbit camera's up is body -z.
// Needs the display's GL context current for every call.
#pragma once

#include <array>
#include <memory>
#include <optional>

#include <Eigen/Core>
#include <epoxy/gl.h>

#include "core/expected.hpp"
#include "core/pose.hpp"
#include "render/augmenter.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"

namespace augrig::app {

// The built-in tanker: a 767/KC-46-sized airframe, body FRD, shaped so the paper rig's cameras
// (x 0, z 2.0) and boom pivot (x -4, z 2.3) sit under the aft fuselage.
Mesh make_tanker_mesh();

struct WorldViewInput {
  const Rig* rig = nullptr;
  SceneState scene;
  std::optional<Pose> validation_T_body_receiver;  // drawn as a wireframe when set
  // Per camera: its image's texture (0: none; the quad is left out) and the frustum's colour.
  std::array<GLuint, 2> image_textures{};
  std::array<Eigen::Vector3f, 2> frustum_rgb{Eigen::Vector3f(0, 1, 1), Eigen::Vector3f(0, 0, 1)};
  double frustum_depth_m = 25.0;  // frusta end here (capped at each camera's far plane); quads at 99 %
};

class WorldView {
 public:
  static Expected<std::unique_ptr<WorldView>> create(std::shared_ptr<const BoomModel> boom,
                                                     std::shared_ptr<const Model> receiver);
  ~WorldView();
  WorldView(const WorldView&) = delete;
  WorldView& operator=(const WorldView&) = delete;

  // Renders into the offscreen target (re-made when the size changes) and returns its RGBA
  // colour texture. Leaves framebuffer 0 bound; the viewport is the caller's to set.
  Expected<GLuint> render(const WorldViewInput& in, int width_px, int height_px);

  // Orbit camera: drag by pixels of the displayed view, zoom by wheel steps (>0: closer).
  void orbit(double dx_px, double dy_px);
  void zoom(double steps);
  void reset_camera();

  // World (body) -> clip transform of the last render, for tests and picking.
  const Eigen::Matrix4f& view_projection() const { return view_projection_; }

 private:
  WorldView() = default;
  struct Gpu;
  std::unique_ptr<Gpu> gpu_;
  double azimuth_rad_ = 0, elevation_rad_ = 0, distance_m_ = 0;
  Eigen::Vector3d target_body_m_ = Eigen::Vector3d::Zero();
  Eigen::Matrix4f view_projection_ = Eigen::Matrix4f::Identity();
};

}  // namespace augrig::app
