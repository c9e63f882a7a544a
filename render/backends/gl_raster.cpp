// The OpenGL raster backend (render/backends/raster_backend.hpp): the current GL context draws
// each view into an offscreen framebuffer (render/gl_util.hpp) and the augmenter reads ids and
// the boom's shaded colour back, per box. Reversed-Z with float depth (precision at 100 m). Only
// the projected boxes of each mesh's chunks are cleared and read back: a software GL pays per
// pixel for both. The validation overlays (ReceiverDraw::kWireframe, kTranslucent) need it.
#include <chrono>
#include <tuple>

#include "render/backends/raster_backend.hpp"
#include "render/gl_util.hpp"

namespace augrig::raster_backends {

namespace {

constexpr char kVertexShader[] = R"(#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec2 a_uv;
uniform mat4 u_cam_from_obj;  // T_cam_obj, camera-relative so float is precise enough
uniform mat4 u_proj;          // camera frame -> clip (render/projection.hpp)
out vec3 v_normal_cam;
out vec2 v_uv;
void main() {
  vec4 p = u_cam_from_obj * vec4(a_pos, 1.0);
  v_normal_cam = mat3(u_cam_from_obj) * a_normal;
  v_uv = a_uv;
  gl_Position = u_proj * p;
}
)";

// The shaded pass's vertex shader: the camera look's specular light of the mesh's finish per
// vertex (Gouraud, as the CPU rasteriser and the simulator evaluate it), for either face: the
// GLSL twin of render/pbr.cpp's SceneLight::on(n, v, ...), less the diffuse share (1 - metallic)
// times the light the fragment shader computes.
constexpr char kShadedVertexShader[] = R"(#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec2 a_uv;
uniform mat4 u_cam_from_obj;
uniform mat4 u_proj;
uniform int u_specular;  // 0: no specular light (the plain look, the receiver)
uniform float u_metallic;
uniform float u_roughness;
uniform vec3 u_light_cam;
uniform vec3 u_down_cam;
uniform vec3 u_sky;
uniform vec3 u_ground;
uniform vec3 u_direct;
out vec3 v_normal_cam;
out vec2 v_uv;
out vec3 v_scale_front, v_add_front, v_scale_back, v_add_back;
void specular_light(vec3 n, vec3 v, out vec3 scale, out vec3 add) {
  float m = clamp(u_metallic, 0.0, 1.0), r = clamp(u_roughness, 0.0, 1.0), rs = max(r, 0.05);
  float a2 = rs * rs * rs * rs;
  float nl = dot(n, u_light_cam), nv = max(dot(n, v), 1e-4);
  float s = 0.0, w = 0.0;
  vec3 hs = u_light_cam + v;
  if (nl > 0.0 && length(hs) > 1e-6) {
    vec3 h = normalize(hs);
    float nh = max(dot(n, h), 0.0);
    float d = nh * nh * (a2 - 1.0) + 1.0;
    float vis = 0.5 / (nl * sqrt(nv * nv * (1.0 - a2) + a2) + nv * sqrt(nl * nl * (1.0 - a2) + a2));
    float k = 1.0 - clamp(dot(v, h), 0.0, 1.0);
    s = a2 / (d * d) * vis * nl;
    w = k * k * k * k * k;
  }
  float x = 1.0 - r, y = 0.0425 - 0.0275 * r, z = 1.04 - 0.572 * r, c = -0.04 + 0.022 * r;
  float a004 = min(x * x, exp2(-9.28 * clamp(dot(n, v), 0.0, 1.0))) * x + y;
  float A = -1.04 * a004 + z, B = max(1.04 * a004 + c, 0.0);
  vec3 mirror = 2.0 * dot(n, v) * n - v;
  float q = dot(n + (1.0 - rs * rs) * (mirror - n), u_down_cam);
  vec3 hemi = u_sky * 0.5 * (1.0 - q) + u_ground * 0.5 * (1.0 + q);
  vec3 sun = u_direct * s;
  float f0 = 0.04 * (1.0 - m);
  scale = m * ((1.0 - w) * sun + A * hemi);
  add = sun * (f0 * (1.0 - w) + w) + hemi * (f0 * A + B);
}
void main() {
  vec4 p = u_cam_from_obj * vec4(a_pos, 1.0);
  v_normal_cam = mat3(u_cam_from_obj) * a_normal;
  v_uv = a_uv;
  gl_Position = u_proj * p;
  v_scale_front = v_add_front = v_scale_back = v_add_back = vec3(0.0);
  if (u_specular != 0) {
    vec3 n = normalize(v_normal_cam), v = normalize(-p.xyz);
    specular_light(n, v, v_scale_front, v_add_front);
    specular_light(-n, v, v_scale_back, v_add_back);
  }
}
)";

// Ids only: the mask-only receiver needs no colour (saves texture fetches and lighting per fragment).
constexpr char kIdFragmentShader[] = R"(#version 330 core
uniform uint u_draw_id;
layout(location = 1) out vec4 o_id;
layout(location = 2) out vec4 o_id2;
void main() {
  uint prim = uint(gl_PrimitiveID);
  o_id = vec4(float(prim & 255u), float((prim >> 8) & 255u), float((prim >> 16) & 255u), float(u_draw_id)) / 255.0;
  o_id2 = o_id;
}
)";

constexpr char kFragmentShader[] = R"(#version 330 core
in vec3 v_normal_cam;
in vec2 v_uv;
in vec3 v_scale_front, v_add_front, v_scale_back, v_add_back;
uniform int u_specular;
uniform float u_metallic;
uniform vec3 u_base_color;
uniform sampler2D u_texture;
uniform int u_has_texture;
uniform vec3 u_light_cam;   // unit vector towards the light, camera frame
uniform vec3 u_down_cam;    // SceneLight: sky and ground hemispheres about the local vertical,
uniform vec3 u_sky;         // plus direct * cosine, per colour channel
uniform vec3 u_ground;
uniform vec3 u_direct;
uniform uint u_draw_id;     // 1..255, 0 = nothing
uniform float u_alpha;
layout(location = 0) out vec4 o_color;
layout(location = 1) out vec4 o_id;
layout(location = 2) out vec4 o_id2;     // same id; which target keeps it is chosen by glColorMaski
layout(location = 3) out vec4 o_color2;
void main() {
  vec3 n = normalize(v_normal_cam);
  if (!gl_FrontFacing) n = -n;
  vec3 albedo = u_base_color;
  if (u_has_texture != 0) albedo *= texture(u_texture, v_uv).rgb;
  float diffuse = max(dot(n, u_light_cam), 0.0);
  float nd = dot(n, u_down_cam);
  vec3 hemi = u_sky == u_ground ? u_sky : u_sky * 0.5 * (1.0 - nd) + u_ground * 0.5 * (1.0 + nd);
  if (u_specular != 0) {
    vec3 scale = gl_FrontFacing ? v_scale_front : v_scale_back, add = gl_FrontFacing ? v_add_front : v_add_back;
    o_color = vec4(albedo * ((1.0 - u_metallic) * (hemi + u_direct * diffuse) + scale) + add, u_alpha);
  } else {
    o_color = vec4(albedo * (hemi + u_direct * diffuse), u_alpha);
  }
  // Exact integers through RGBA8: k / 255 is stored as k.
  uint prim = uint(gl_PrimitiveID);
  o_id = vec4(float(prim & 255u), float((prim >> 8) & 255u), float((prim >> 16) & 255u), float(u_draw_id)) / 255.0;
  o_id2 = o_id;
  o_color2 = o_color;
}
)";

struct Program {
  GLuint id = 0;
  GLint cam_from_obj = -1, proj = -1, base_color = -1, has_texture = -1, light = -1, down = -1, sky = -1,
        ground = -1, direct = -1, draw_id = -1, alpha = -1, texture = -1, specular = -1, metallic = -1,
        roughness = -1;
};

class GlRaster final : public RasterBackend {
 public:
  explicit GlRaster(const AugmentOptions& options)
      : receiver_draw_(options.receiver_draw), profile_stages_(options.profile_stages) {}
  ~GlRaster() override {
    for (gl::GpuMesh& m : meshes_) m.destroy();
    fb_.destroy();
    for (Program* p : {&shaded_, &ids_only_})
      if (p->id) glDeleteProgram(p->id);
  }
  Rasterizer kind() const override { return Rasterizer::kOpenGl; }
  bool concurrent_views() const override { return false; }
  bool shades_per_pixel() const override { return false; }
  Status init(const std::vector<DrawItem>& draws, const std::vector<RasterView*>& views) override;
  void clear(RasterView& v) override;
  void draw(RasterView& v, const RasterFrame& f, AugmentTimings& timings) override;
  Status errors() const override {
    if (auto e = gl::drain_errors(); !e.empty()) return make_error("Augmenter::augment(): OpenGL errors:", e);
    return {};
  }

 private:
  Status make_programs();
  void set_uniforms(const RasterView& v, const RasterFrame& f) const;
  void clear_boxes(const RasterView& v) const;
  void draw_passes(const RasterView& v, const RasterFrame& f) const;
  void draw_kind(ObjectKind kind, const Pose& T_cam_obj, const Program& p, bool camera_look) const;
  void read_back(RasterView& v) const;

  ReceiverDraw receiver_draw_;
  bool profile_stages_;
  const std::vector<DrawItem>* draws_ = nullptr;
  std::vector<gl::GpuMesh> meshes_;          // by draw item
  std::vector<std::array<float, 16>> proj_;  // by RasterView::index
  gl::Framebuffer fb_;
  Program shaded_, ids_only_;
};

// The shaded pass's and the ids pass's GL programs, and their uniforms' locations.
Status GlRaster::make_programs() {
  for (auto [prog, name, vs, fs] :
       {std::tuple{&shaded_, "augmenter shaded", kShadedVertexShader, kFragmentShader},
        std::tuple{&ids_only_, "augmenter ids", kVertexShader, kIdFragmentShader}}) {
    auto id = gl::make_program(name, vs, fs);
    if (!id) return id.error();
    prog->id = *id;
    prog->cam_from_obj = glGetUniformLocation(*id, "u_cam_from_obj");
    prog->proj = glGetUniformLocation(*id, "u_proj");
    prog->base_color = glGetUniformLocation(*id, "u_base_color");
    prog->has_texture = glGetUniformLocation(*id, "u_has_texture");
    prog->light = glGetUniformLocation(*id, "u_light_cam");
    prog->down = glGetUniformLocation(*id, "u_down_cam");
    prog->sky = glGetUniformLocation(*id, "u_sky");
    prog->ground = glGetUniformLocation(*id, "u_ground");
    prog->direct = glGetUniformLocation(*id, "u_direct");
    prog->draw_id = glGetUniformLocation(*id, "u_draw_id");
    prog->alpha = glGetUniformLocation(*id, "u_alpha");
    prog->texture = glGetUniformLocation(*id, "u_texture");
    prog->specular = glGetUniformLocation(*id, "u_specular");
    prog->metallic = glGetUniformLocation(*id, "u_metallic");
    prog->roughness = glGetUniformLocation(*id, "u_roughness");
  }
  return {};
}

Status GlRaster::init(const std::vector<DrawItem>& draws, const std::vector<RasterView*>& views) {
  draws_ = &draws;
  if (auto s = make_programs(); !s) return s;
  for (const DrawItem& d : draws) meshes_.push_back(gl::upload(*d.mesh));
  const bool zero_to_one = gl::has_clip_control();
  // Reversed-Z: depth 1 at the near plane, 0 at far; float depth keeps precision at 100 m.
  // Context state, set once (changing it per view makes llvmpipe revalidate).
  if (zero_to_one) glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  int fw = 0, fh = 0;
  for (RasterView* v : views) {
    if (v->index >= static_cast<int>(proj_.size())) proj_.resize(v->index + 1);
    proj_[v->index] = gl_projection(v->vp.fx, v->vp.fy, v->vp.cx, v->vp.cy, v->vp.width, v->vp.height,
                                    v->cam->near_m, v->cam->far_m, zero_to_one);
    const std::size_t vn = static_cast<std::size_t>(v->vp.width) * v->vp.height;
    v->boom_rgba.assign(vn * 4, 0);
    if (receiver_draw_ != ReceiverDraw::kMaskOnly) v->recv_rgba.assign(vn * 4, 0);
    fw = std::max(fw, v->vp.width);
    fh = std::max(fh, v->vp.height);
  }
  if (auto s = fb_.create(fw, fh); !s) return s;
  const GLenum targets[4] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2,
                             GL_COLOR_ATTACHMENT3};
  glDrawBuffers(4, targets);  // framebuffer state: set once, passes choose with colour masks
  if (auto e = gl::drain_errors(); !e.empty()) return make_error("Augmenter::create(): OpenGL errors:", e);
  return {};
}

// Ids are read back per box, so only the last frame's boxes hold any.
void GlRaster::clear(RasterView& v) {
  const int Wv = v.vp.width;
  auto zero_boxes = [&](auto& image, const std::vector<VBox>& boxes) {
    for (const VBox& b : boxes)
      for (int y = b.y0; y < b.y1; ++y)
        std::fill_n(&image[static_cast<std::size_t>(y) * Wv + b.x0], b.x1 - b.x0, 0);
  };
  zero_boxes(v.boom_ids, v.boom_vboxes);
  zero_boxes(v.recv_ids, v.recv_vboxes);
}

// The light in this camera's frame (the plain look's: above the tanker, a little forward and to
// the right) and the projection, for both programs.
void GlRaster::set_uniforms(const RasterView& v, const RasterFrame& f) const {
  const SceneLight& sl = *f.light;
  const Eigen::Vector3f light = (f.R_cam_body * sl.towards_light_body).cast<float>();
  const Eigen::Vector3f down = (f.R_cam_body * sl.down_body).cast<float>();
  for (const Program* p : {&shaded_, &ids_only_}) {
    glUseProgram(p->id);
    glUniformMatrix4fv(p->proj, 1, GL_FALSE, proj_[v.index].data());
    if (p->texture >= 0) glUniform1i(p->texture, 0);
    if (p->light >= 0) glUniform3f(p->light, light.x(), light.y(), light.z());
    if (p->down >= 0) glUniform3f(p->down, down.x(), down.y(), down.z());
    const Eigen::Vector3f sky = sl.sky.cast<float>(), ground = sl.ground.cast<float>(),
                          direct = sl.direct.cast<float>();
    if (p->sky >= 0) glUniform3f(p->sky, sky.x(), sky.y(), sky.z());
    if (p->ground >= 0) glUniform3f(p->ground, ground.x(), ground.y(), ground.z());
    if (p->direct >= 0) glUniform3f(p->direct, direct.x(), direct.y(), direct.z());
    if (p->alpha >= 0) glUniform1f(p->alpha, 1.0f);
  }
}

void GlRaster::draw_kind(ObjectKind kind, const Pose& T_cam_obj, const Program& p, bool camera_look) const {
  glUseProgram(p.id);
  Eigen::Matrix4f M = T_cam_obj.matrix().cast<float>();
  glUniformMatrix4fv(p.cam_from_obj, 1, GL_FALSE, M.data());  // Eigen is column-major too
  for (std::size_t i = 0; i < draws_->size(); ++i) {
    const DrawItem& d = (*draws_)[i];
    const gl::GpuMesh& gpu = meshes_[i];
    if (d.kind != kind) continue;
    if (d.cull)
      glEnable(GL_CULL_FACE);
    else
      glDisable(GL_CULL_FACE);
    const Eigen::Vector3f& c = d.mesh->base_color;
    glUniform1ui(p.draw_id, d.draw_id);
    if (p.base_color >= 0) glUniform3f(p.base_color, c.x(), c.y(), c.z());
    // The finish's specular light: the boom's, with the camera look's light only.
    if (p.specular >= 0) glUniform1i(p.specular, camera_look && kind != ObjectKind::kReceiver ? 1 : 0);
    if (p.metallic >= 0) glUniform1f(p.metallic, static_cast<float>(d.mesh->finish.metallic));
    if (p.roughness >= 0) glUniform1f(p.roughness, static_cast<float>(d.mesh->finish.roughness));
    if (p.has_texture >= 0) glUniform1i(p.has_texture, gpu.has_texture ? 1 : 0);
    if (gpu.has_texture && p.has_texture >= 0) {
      glActiveTexture(GL_TEXTURE0);
      glBindTexture(GL_TEXTURE_2D, gpu.texture);
    }
    gpu.draw();
  }
}

// The four targets stay bound (set once in init); each pass chooses what it writes with colour
// masks: 0 boom colour, 1 boom ids, 2 receiver ids, 3 receiver colour (overlays only).
void write_only(bool c0, bool c1, bool c2, bool c3) {
  glColorMaski(0, c0, c0, c0, c0);
  glColorMaski(1, c1, c1, c1, c1);
  glColorMaski(2, c2, c2, c2, c2);
  glColorMaski(3, c3, c3, c3, c3);
}

// One scissored clear per box of the id targets and depth (the boom is depth-tested against the
// receiver). Colours are read only where an id is set, so they need no clear: llvmpipe clears
// cost per pixel and per attachment.
void GlRaster::clear_boxes(const RasterView& v) const {
  write_only(false, true, true, false);
  glEnable(GL_SCISSOR_TEST);
  glClearColor(0, 0, 0, 0);
  glClearDepth(0.0);
  for (const auto* list : {&v.recv_vboxes, &v.boom_vboxes})
    for (const VBox& b : *list) {
      glScissor(b.x0, b.y0, b.x1 - b.x0, b.y1 - b.y0);
      glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    }
  glDisable(GL_SCISSOR_TEST);  // every fragment falls inside its chunk's (cleared) box
}

// The receiver's ids into target 2 (its colour into 3 for the validation overlays), then the
// boom's colour and ids where it is in front of the receiver.
void GlRaster::draw_passes(const RasterView& v, const RasterFrame& f) const {
  const Pose& T_cam_recv = f.T_cam_obj[static_cast<int>(ObjectKind::kReceiver)];
  const bool look = f.camera_look;
  if (!v.recv_vboxes.empty()) {
    if (receiver_draw_ == ReceiverDraw::kWireframe) {
      // Ids from filled triangles; the wireframe colour is drawn after, without touching ids or depth.
      write_only(false, false, true, false);
      draw_kind(ObjectKind::kReceiver, T_cam_recv, ids_only_, look);
      write_only(false, false, false, true);
      glDepthMask(GL_FALSE);
      glDepthFunc(GL_GEQUAL);
      glPolygonMode(GL_FRONT_AND_BACK, GL_LINE);
      draw_kind(ObjectKind::kReceiver, T_cam_recv, shaded_, look);
      glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
      glDepthFunc(GL_GREATER);
      glDepthMask(GL_TRUE);
    } else if (receiver_draw_ == ReceiverDraw::kTranslucent) {
      write_only(false, false, true, !v.recv_rgba.empty());
      draw_kind(ObjectKind::kReceiver, T_cam_recv, shaded_, look);
    } else {
      write_only(false, false, true, false);
      draw_kind(ObjectKind::kReceiver, T_cam_recv, ids_only_, look);  // mask-only proxy: ids and depth
    }
  }
  if (!v.boom_vboxes.empty()) {
    write_only(true, true, false, false);
    draw_kind(ObjectKind::kBoomFixed, f.T_cam_obj[static_cast<int>(ObjectKind::kBoomFixed)], shaded_, look);
    draw_kind(ObjectKind::kBoomTelescope, f.T_cam_obj[static_cast<int>(ObjectKind::kBoomTelescope)], shaded_,
              look);
  }
  write_only(true, true, true, true);
}

void GlRaster::read_back(RasterView& v) const {
  for (const VBox& b : v.recv_vboxes) {
    gl::read_rgba_box(GL_COLOR_ATTACHMENT2, b.x0, b.y0, b.x1, b.y1,
                      reinterpret_cast<std::uint8_t*>(v.recv_ids.data()), v.vp.width);
    if (!v.recv_rgba.empty())
      gl::read_rgba_box(GL_COLOR_ATTACHMENT3, b.x0, b.y0, b.x1, b.y1, v.recv_rgba.data(), v.vp.width);
  }
  for (const VBox& b : v.boom_vboxes) {
    gl::read_rgba_box(GL_COLOR_ATTACHMENT1, b.x0, b.y0, b.x1, b.y1,
                      reinterpret_cast<std::uint8_t*>(v.boom_ids.data()), v.vp.width);
    gl::read_rgba_box(GL_COLOR_ATTACHMENT0, b.x0, b.y0, b.x1, b.y1, v.boom_rgba.data(), v.vp.width);
  }
}

void GlRaster::draw(RasterView& v, const RasterFrame& f, AugmentTimings& timings) {
  glBindFramebuffer(GL_FRAMEBUFFER, fb_.fbo);
  glViewport(0, 0, v.vp.width, v.vp.height);
  set_uniforms(v, f);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_GREATER);  // reversed-Z
  glFrontFace(GL_CW);       // y-down projection (render/projection.hpp)
  glDisable(GL_BLEND);
  // Optional stage profile (bench/): wait for the GL to finish each stage.
  auto last = std::chrono::steady_clock::now();
  auto stage = [&](double& acc) {
    if (!profile_stages_) return;
    glFinish();
    const auto now = std::chrono::steady_clock::now();
    acc += std::chrono::duration<double, std::milli>(now - last).count();
    last = now;
  };
  clear_boxes(v);
  stage(timings.gl_clear_ms);
  draw_passes(v, f);
  stage(timings.gl_draw_ms);
  read_back(v);
  stage(timings.gl_readback_ms);
}

}  // namespace

std::unique_ptr<RasterBackend> make_gl_raster(const AugmentOptions& options) {
  return std::make_unique<GlRaster>(options);
}

}  // namespace augrig::raster_backends
