// A small scene for the raster backends' tests: a 64 x 48 pinhole view, a receiver quad 10 m
// away across the whole view and a boom triangle 5 m away in front of its middle, in the camera
// frame (identity poses), set up as the augmenter sets a RasterView.
#pragma once

#include <vector>

#include "render/backends/raster_backend.hpp"

namespace augrig::test {

struct RasterScene {
  RigCamera cam;
  Model boom, receiver;
  std::vector<raster_backends::DrawItem> draws;
  raster_backends::RasterView view;
  SceneLight light = SceneLight::fixed();
  AugmentTimings timings;

  static Mesh mesh(std::vector<Eigen::Vector3f> p, std::vector<std::uint32_t> idx) {
    Mesh m;
    m.positions_m = std::move(p);
    m.normals.assign(m.positions_m.size(), Eigen::Vector3f(0, 0, -1));
    m.indices = std::move(idx);
    return m;
  }

  RasterScene() {
    using raster_backends::ObjectKind;
    cam.name = "test";
    cam.model.width_px = 64, cam.model.height_px = 48;
    cam.model.fx_px = cam.model.fy_px = 50, cam.model.cx_px = 31.5, cam.model.cy_px = 23.5;
    receiver.meshes.push_back(
        mesh({{-20, -20, 10}, {20, -20, 10}, {20, 20, 10}, {-20, 20, 10}}, {0, 1, 2, 0, 2, 3}));
    boom.meshes.push_back(mesh({{-1, -1, 5}, {1, -1, 5}, {0, 1, 5}}, {0, 1, 2}));
    draws.push_back({ObjectKind::kBoomFixed, &boom.meshes[0], 1, 0, false, {{0u, 1u}}});
    draws.push_back({ObjectKind::kReceiver, &receiver.meshes[0], 2, 1, false, {{0u, 2u}}});
    view.cam = &cam;
    view.vp.fx = view.vp.fy = 50, view.vp.cx = 31.5, view.vp.cy = 23.5;
    view.vp.width = 64, view.vp.height = 48, view.vp.identity = true;
    const std::size_t n = 64 * 48;
    view.boom_ids.assign(n, 0), view.recv_ids.assign(n, 0);
    for (const auto& d : draws)
      for (std::size_t k = 0; k < d.mesh->triangle_count(); ++k) {
        const auto& P = d.mesh->positions_m;
        const auto* i = &d.mesh->indices[3 * k];
        raster_backends::CamTriangle t;
        t.v0 = P[i[0]].cast<double>(), t.e1 = P[i[1]].cast<double>() - t.v0,
        t.e2 = P[i[2]].cast<double>() - t.v0;
        t.n = t.e1.cross(t.e2), t.n_dot_v0 = t.n.dot(t.v0);
        const Eigen::Vector3d v1 = t.v0 + t.e1, v2 = t.v0 + t.e2;
        const double sign = t.n_dot_v0 >= 0 ? 1.0 : -1.0;
        t.edge[0] = sign * t.v0.cross(v1), t.edge[1] = sign * v1.cross(v2), t.edge[2] = sign * v2.cross(t.v0);
        view.tris.push_back(t);
      }
  }

  // The frame: identity poses, the plain look's light; the whole view as the boxes.
  raster_backends::RasterFrame frame() {
    view.boom_vboxes = view.recv_vboxes = {{0, 0, 64, 48}};
    raster_backends::RasterFrame f;
    f.R_cam_body = Eigen::Matrix3d::Identity();
    f.light = &light;
    return f;
  }

  std::uint32_t boom_id(int x, int y) const { return view.boom_ids[static_cast<std::size_t>(y) * 64 + x]; }
  std::uint32_t recv_id(int x, int y) const { return view.recv_ids[static_cast<std::size_t>(y) * 64 + x]; }
};

}  // namespace augrig::test
