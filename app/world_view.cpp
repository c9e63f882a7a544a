#include "app/world_view.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include <Eigen/Geometry>

#include "core/conventions.hpp"
#include "render/gl_util.hpp"

namespace augrig::app {

namespace {

using Eigen::Vector3f;

// ---- The procedural tanker ------------------------------------------------------------------------

struct Section {
  double x_m, radius_m, zc_m;  // a circle in the y-z plane at x, centred on (x, 0, zc)
};

void add_triangle(Mesh& m, const Vector3f& a, const Vector3f& b, const Vector3f& c) {
  const auto base = static_cast<std::uint32_t>(m.positions_m.size());
  m.positions_m.insert(m.positions_m.end(), {a, b, c});
  m.indices.insert(m.indices.end(), {base, base + 1, base + 2});
}

// A body of revolution-like loft through circular sections, shared vertices (smooth normals).
void add_loft(Mesh& m, const std::vector<Section>& sections, double y_offset_m, int segments) {
  const auto base = static_cast<std::uint32_t>(m.positions_m.size());
  for (const Section& s : sections)
    for (int j = 0; j < segments; ++j) {
      const double a = 2 * kPi * j / segments;
      m.positions_m.emplace_back(static_cast<float>(s.x_m),
                                 static_cast<float>(y_offset_m + s.radius_m * std::cos(a)),
                                 static_cast<float>(s.zc_m + s.radius_m * std::sin(a)));
    }
  const auto n = static_cast<std::uint32_t>(segments);
  for (std::uint32_t i = 0; i + 1 < sections.size(); ++i)
    for (std::uint32_t j = 0; j < n; ++j) {
      const std::uint32_t a = base + i * n + j, b = base + i * n + (j + 1) % n;
      const std::uint32_t c = a + n, d = b + n;
      m.indices.insert(m.indices.end(), {a, c, b, b, c, d});
    }
}

// A tapered slab (wing, stabiliser, fin) from a root and a tip chord line; own vertices per face
// (flat normals). `thick` is the direction of the thickness.
void add_slab(Mesh& m, const Vector3f& root_le, float root_chord, const Vector3f& tip_le, float tip_chord,
              const Vector3f& thick, float root_t, float tip_t) {
  const Vector3f aft(-1, 0, 0);
  const Vector3f p[8] = {root_le - thick * root_t / 2,
                         root_le + aft * root_chord - thick * root_t / 2,
                         tip_le + aft * tip_chord - thick * tip_t / 2,
                         tip_le - thick * tip_t / 2,
                         root_le + thick * root_t / 2,
                         root_le + aft * root_chord + thick * root_t / 2,
                         tip_le + aft * tip_chord + thick * tip_t / 2,
                         tip_le + thick * tip_t / 2};
  const int faces[6][4] = {{0, 1, 2, 3}, {4, 7, 6, 5}, {0, 4, 5, 1},
                           {1, 5, 6, 2}, {2, 6, 7, 3}, {3, 7, 4, 0}};
  for (const auto& f : faces) {
    add_triangle(m, p[f[0]], p[f[1]], p[f[2]]);
    add_triangle(m, p[f[0]], p[f[2]], p[f[3]]);
  }
}

// ---- Matrices --------------------------------------------------------------------------------------

Eigen::Matrix4f look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                        const Eigen::Vector3d& up) {
  const Eigen::Vector3d f = (target - eye).normalized();
  const Eigen::Vector3d s = f.cross(up).normalized();
  const Eigen::Vector3d u = s.cross(f);
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<1, 3>(0, 0) = s.transpose();
  m.block<1, 3>(1, 0) = u.transpose();
  m.block<1, 3>(2, 0) = -f.transpose();
  m(0, 3) = -s.dot(eye);
  m(1, 3) = -u.dot(eye);
  m(2, 3) = f.dot(eye);
  return m.cast<float>();
}

Eigen::Matrix4f perspective(double fovy_rad, double aspect, double near_m, double far_m) {
  const double f = 1.0 / std::tan(fovy_rad / 2);
  Eigen::Matrix4d p = Eigen::Matrix4d::Zero();
  p(0, 0) = f / aspect;
  p(1, 1) = f;
  p(2, 2) = (far_m + near_m) / (near_m - far_m);
  p(2, 3) = 2 * far_m * near_m / (near_m - far_m);
  p(3, 2) = -1;
  return p.cast<float>();
}

const char* kVertexSrc = R"(#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec2 a_uv;
uniform mat4 u_mvp;
uniform mat3 u_rot;
out vec3 v_normal;
out vec2 v_uv;
void main() {
  gl_Position = u_mvp * vec4(a_pos, 1.0);
  v_normal = u_rot * a_normal;
  v_uv = a_uv;
}
)";

const char* kFragmentSrc = R"(#version 330 core
in vec3 v_normal;
in vec2 v_uv;
uniform vec4 u_color;
uniform int u_lit;
uniform int u_textured;
uniform sampler2D u_tex;
uniform vec3 u_light;
out vec4 o_color;
void main() {
  vec4 c = u_color;
  if (u_textured == 1) c *= texture(u_tex, v_uv);
  // Two-sided: the sign of a normal depends on a model's winding, the light should not.
  if (u_lit == 1) c.rgb *= 0.35 + 0.65 * abs(dot(normalize(v_normal), u_light));
  o_color = c;
}
)";

using gl::Vertex;

Vertex vtx(const Eigen::Vector3d& p, float u = 0, float v = 0) {
  return {
      {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())}, {0, 0, 1}, {u, v}};
}

// Corner rays of a camera's image (camera frame, z = 1), clockwise from the top-left.
std::array<Eigen::Vector3d, 4> corner_rays(const CameraModel& cm) {
  const double u1 = cm.width_px - 0.5, v1 = cm.height_px - 0.5;
  const Eigen::Vector2d px[4] = {{-0.5, -0.5}, {u1, -0.5}, {u1, v1}, {-0.5, v1}};
  std::array<Eigen::Vector3d, 4> out;
  for (int i = 0; i < 4; ++i) {
    const auto r = cm.ray(px[i]);
    if (r && r->z() > 1e-6) {
      out[i] = *r / r->z();
    } else {  // outside the lens model's valid region: the pinhole corner
      out[i] = Eigen::Vector3d((px[i].x() - cm.cx_px) / cm.fx_px, (px[i].y() - cm.cy_px) / cm.fy_px, 1.0);
    }
  }
  return out;
}

}  // namespace

Mesh make_tanker_mesh() {
  Mesh m;
  m.name = "tanker";
  add_loft(m,
           {{31.0, 0.05, 0.4},
            {30.4, 0.8, 0.3},
            {29.2, 1.45, 0.15},
            {27.0, 1.9, 0.05},
            {-5.0, 1.9, 0.05},
            {-9.0, 1.45, -0.25},
            {-13.0, 0.8, -0.8},
            {-15.5, 0.15, -1.2}},
           0.0, 32);
  for (float side : {1.0f, -1.0f}) {
    // Low swept wing with dihedral (tip higher: -z), an engine nacelle under each.
    add_slab(m, Vector3f(9.0f, side * 1.8f, 0.9f), 7.5f, Vector3f(-3.0f, side * 23.5f, -0.3f), 2.2f,
             Vector3f(0, 0, 1), 0.6f, 0.2f);
    add_loft(m, {{8.5, 0.3, 2.0}, {7.8, 1.25, 2.0}, {3.5, 1.2, 2.0}, {2.5, 0.7, 2.0}}, side * 8.0, 20);
    add_slab(m, Vector3f(-8.5f, side * 0.5f, -0.6f), 4.5f, Vector3f(-13.5f, side * 9.3f, -1.2f), 1.8f,
             Vector3f(0, 0, 1), 0.3f, 0.12f);
  }
  add_slab(m, Vector3f(-6.5f, 0.0f, -1.2f), 6.0f, Vector3f(-12.5f, 0.0f, -9.5f), 2.5f, Vector3f(0, 1, 0),
           0.4f, 0.15f);
  compute_normals(m);
  m.base_color = Vector3f(0.78f, 0.80f, 0.83f);
  return m;
}

struct WorldView::Gpu {
  GLuint program = 0;
  GLint u_mvp = -1, u_rot = -1, u_color = -1, u_lit = -1, u_textured = -1, u_tex = -1, u_light = -1;
  struct Part {
    gl::GpuMesh mesh;
    Vector3f color;
  };
  std::vector<Part> tanker, boom_fixed, boom_telescope, receiver;
  GLuint dyn_vao = 0, dyn_vbo = 0;
  GLuint fbo = 0, color = 0, depth = 0;
  int width = 0, height = 0;

  ~Gpu() {
    for (auto* parts : {&tanker, &boom_fixed, &boom_telescope, &receiver})
      for (Part& p : *parts) p.mesh.destroy();
    destroy_target();
    if (dyn_vbo) glDeleteBuffers(1, &dyn_vbo);
    if (dyn_vao) glDeleteVertexArrays(1, &dyn_vao);
    if (program) glDeleteProgram(program);
  }
  void destroy_target() {
    if (fbo) glDeleteFramebuffers(1, &fbo);
    if (color) glDeleteTextures(1, &color);
    if (depth) glDeleteRenderbuffers(1, &depth);
    fbo = color = depth = 0;
    width = height = 0;
  }
  Status make_target(int w, int h) {
    destroy_target();
    color = gl::make_rgba_texture(w, h);
    // BGRA storage (unsized internal format): the window draws it 1:1 as llvmpipe's row copy.
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA, w, h, 0, GL_BGRA, GL_UNSIGNED_BYTE, nullptr);
    glGenRenderbuffers(1, &depth);
    glBindRenderbuffer(GL_RENDERBUFFER, depth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, w, h);
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, color, 0);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
    const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    if (status != GL_FRAMEBUFFER_COMPLETE) {
      destroy_target();
      return make_error("app::WorldView::render(): ", w, "x", h, " offscreen target incomplete (status 0x",
                        static_cast<unsigned>(status), ")");
    }
    width = w, height = h;
    return {};
  }

  static std::vector<Part> upload_parts(const Model& model) {
    std::vector<Part> parts;
    for (const Mesh& mesh : model.meshes) parts.push_back({gl::upload(mesh), mesh.base_color});
    return parts;
  }

  void draw_parts(const std::vector<Part>& parts, const Eigen::Matrix4f& view_proj, const Pose& T_body_obj,
                  float alpha = 1.0f) const {
    const Eigen::Matrix4f mvp = view_proj * T_body_obj.matrix().cast<float>();
    const Eigen::Matrix3f rot = T_body_obj.R().cast<float>();
    glUniformMatrix4fv(u_mvp, 1, GL_FALSE, mvp.data());
    glUniformMatrix3fv(u_rot, 1, GL_FALSE, rot.data());
    for (const Part& p : parts) {
      glUniform4f(u_color, p.color.x(), p.color.y(), p.color.z(), alpha);
      glUniform1i(u_textured, p.mesh.has_texture ? 1 : 0);
      if (p.mesh.has_texture) {
        glActiveTexture(GL_TEXTURE0);
        glBindTexture(GL_TEXTURE_2D, p.mesh.texture);
      }
      p.mesh.draw();
    }
  }
};

Expected<std::unique_ptr<WorldView>> WorldView::create(std::shared_ptr<const BoomModel> boom,
                                                       std::shared_ptr<const Model> receiver) {
  if (!boom) boom = std::make_shared<BoomModel>(make_builtin_boom());
  if (!receiver) receiver = std::make_shared<Model>(make_builtin_receiver());
  std::unique_ptr<WorldView> w(new WorldView());
  w->gpu_ = std::make_unique<Gpu>();
  Gpu& g = *w->gpu_;
  auto program = gl::make_program("app::WorldView", kVertexSrc, kFragmentSrc);
  if (!program) return program.error();
  g.program = *program;
  g.u_mvp = glGetUniformLocation(g.program, "u_mvp");
  g.u_rot = glGetUniformLocation(g.program, "u_rot");
  g.u_color = glGetUniformLocation(g.program, "u_color");
  g.u_lit = glGetUniformLocation(g.program, "u_lit");
  g.u_textured = glGetUniformLocation(g.program, "u_textured");
  g.u_tex = glGetUniformLocation(g.program, "u_tex");
  g.u_light = glGetUniformLocation(g.program, "u_light");
  Model tanker;
  tanker.meshes.push_back(make_tanker_mesh());
  g.tanker = Gpu::upload_parts(tanker);
  g.boom_fixed = Gpu::upload_parts(boom->fixed);
  g.boom_telescope = Gpu::upload_parts(boom->telescope);
  g.receiver = Gpu::upload_parts(*receiver);

  glGenVertexArrays(1, &g.dyn_vao);
  glBindVertexArray(g.dyn_vao);
  glGenBuffers(1, &g.dyn_vbo);
  glBindBuffer(GL_ARRAY_BUFFER, g.dyn_vbo);
  gl::set_vertex_attributes();
  glBindVertexArray(0);
  if (const std::string e = gl::drain_errors(); !e.empty())
    return make_error("app::WorldView::create(): OpenGL error while uploading the models: ", e);
  w->reset_camera();
  return w;
}

WorldView::~WorldView() = default;

void WorldView::reset_camera() {
  // From the starboard side, somewhat aft and above: tanker tail, boom and receiver in one view.
  target_body_m_ = Eigen::Vector3d(-12.0, 0.0, 6.0);
  azimuth_rad_ = deg_to_rad(50.0);
  elevation_rad_ = deg_to_rad(15.0);
  distance_m_ = 52.0;
}

void WorldView::orbit(double dx_px, double dy_px) {
  azimuth_rad_ += 0.008 * dx_px;
  elevation_rad_ = std::clamp(elevation_rad_ + 0.008 * dy_px, deg_to_rad(-85.0), deg_to_rad(85.0));
}

void WorldView::zoom(double steps) {
  distance_m_ = std::clamp(distance_m_ * std::pow(0.9, steps), 5.0, 400.0);
}

Expected<GLuint> WorldView::render(const WorldViewInput& in, int width_px, int height_px) {
  Gpu& g = *gpu_;
  width_px = std::max(width_px, 16);
  height_px = std::max(height_px, 16);
  if (g.width != width_px || g.height != height_px) {
    if (Status s = g.make_target(width_px, height_px); !s) return s.error();
  }
  // Orbit camera around the target; azimuth 0 looks from starboard, positive swings aft.
  const Eigen::Vector3d dir = std::cos(elevation_rad_) * (std::cos(azimuth_rad_) * Eigen::Vector3d::UnitY() -
                                                          std::sin(azimuth_rad_) * Eigen::Vector3d::UnitX()) -
                              std::sin(elevation_rad_) * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d eye = target_body_m_ + distance_m_ * dir;
  view_projection_ = perspective(deg_to_rad(40.0), static_cast<double>(width_px) / height_px, 0.5, 2000.0) *
                     look_at(eye, target_body_m_, -Eigen::Vector3d::UnitZ());

  glBindFramebuffer(GL_FRAMEBUFFER, g.fbo);
  glViewport(0, 0, width_px, height_px);
  glDisable(GL_SCISSOR_TEST);
  glClearColor(0.53f, 0.64f, 0.78f, 1.0f);  // sky
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  glUseProgram(g.program);
  glUniform1i(g.u_tex, 0);
  const Eigen::Vector3f light = Eigen::Vector3f(0.3f, 0.4f, -1.0f).normalized();
  glUniform3f(g.u_light, light.x(), light.y(), light.z());
  glUniform1i(g.u_lit, 1);

  g.draw_parts(g.tanker, view_projection_, Pose::identity());
  if (in.rig) {
    const Pose T_body_boom = boom_pose(in.rig->boom.pivot_body_m, in.scene.boom);
    g.draw_parts(g.boom_fixed, view_projection_, T_body_boom);
    g.draw_parts(g.boom_telescope, view_projection_, T_body_boom * telescope_pose(in.scene.boom));
  }
  if (in.scene.receiver_present) g.draw_parts(g.receiver, view_projection_, in.scene.T_body_receiver);

  // Frusta and image quads (Fig. 4): built per frame, a few dozen vertices.
  std::vector<Vertex> quads, lines;
  std::vector<int> quad_camera;
  if (in.rig) {
    for (std::size_t c = 0; c < in.rig->cameras.size() && c < 2; ++c) {
      const RigCamera& cam = in.rig->cameras[c];
      const double depth_m = std::min(in.frustum_depth_m, cam.far_m);
      const auto rays = corner_rays(cam.model);
      const Eigen::Vector3d apex = cam.T_body_cam.translation_m;
      Eigen::Vector3d far[4], quad[4];
      for (int i = 0; i < 4; ++i) {
        far[i] = cam.T_body_cam * (rays[i] * depth_m);
        quad[i] = cam.T_body_cam * (rays[i] * (0.99 * depth_m));
      }
      for (int i = 0; i < 4; ++i) {
        lines.push_back(vtx(apex));
        lines.push_back(vtx(far[i]));
        lines.push_back(vtx(far[i]));
        lines.push_back(vtx(far[(i + 1) % 4]));
      }
      if (in.image_textures[c]) {
        // uv: (0, 0) is the image's top-left (row 0 uploaded first).
        const Vertex q[4] = {vtx(quad[0], 0, 0), vtx(quad[1], 1, 0), vtx(quad[2], 1, 1), vtx(quad[3], 0, 1)};
        quads.insert(quads.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
        quad_camera.push_back(static_cast<int>(c));
      }
    }
  }
  const std::size_t n_quads = quads.size();
  std::vector<Vertex> all = std::move(quads);
  all.insert(all.end(), lines.begin(), lines.end());
  if (!all.empty()) {
    glBindVertexArray(g.dyn_vao);
    glBindBuffer(GL_ARRAY_BUFFER, g.dyn_vbo);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(all.size() * sizeof(Vertex)), all.data(),
                 GL_STREAM_DRAW);
    const Eigen::Matrix3f I = Eigen::Matrix3f::Identity();
    glUniformMatrix4fv(g.u_mvp, 1, GL_FALSE, view_projection_.data());
    glUniformMatrix3fv(g.u_rot, 1, GL_FALSE, I.data());
    glUniform1i(g.u_lit, 0);
    glUniform1i(g.u_textured, 1);
    glUniform4f(g.u_color, 1, 1, 1, 1);
    glActiveTexture(GL_TEXTURE0);
    for (std::size_t q = 0; q < quad_camera.size(); ++q) {
      glBindTexture(GL_TEXTURE_2D, in.image_textures[quad_camera[q]]);
      glDrawArrays(GL_TRIANGLES, static_cast<GLint>(6 * q), 6);
    }
    glUniform1i(g.u_textured, 0);
    for (std::size_t c = 0; c < 2 && c * 16 < lines.size(); ++c) {
      const Eigen::Vector3f& rgb = in.frustum_rgb[c];
      glUniform4f(g.u_color, rgb.x(), rgb.y(), rgb.z(), 1);
      glDrawArrays(GL_LINES, static_cast<GLint>(n_quads + 16 * c), 16);
    }
  }
  // The pose under validation as a wireframe over everything else.
  if (in.validation_T_body_receiver) {
    glUseProgram(g.program);
    glUniform1i(g.u_lit, 0);
    glPolygonMode(GL_FRONT_AND_BACK, GL_LINE);
    glEnable(GL_POLYGON_OFFSET_LINE);
    glPolygonOffset(-1.0f, -1.0f);
    const Eigen::Matrix4f mvp = view_projection_ * in.validation_T_body_receiver->matrix().cast<float>();
    glUniformMatrix4fv(g.u_mvp, 1, GL_FALSE, mvp.data());
    glUniform4f(g.u_color, 1.0f, 0.85f, 0.1f, 1.0f);
    glUniform1i(g.u_textured, 0);
    for (const Gpu::Part& p : g.receiver) p.mesh.draw();
    glDisable(GL_POLYGON_OFFSET_LINE);
    glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
  }
  glBindVertexArray(0);
  glDisable(GL_DEPTH_TEST);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  return g.color;
}

}  // namespace augrig::app
