// The OpenGL synthetic scene renderer (sim/synthetic_scene.hpp, SceneBackend::kOpenGL; the CPU
// back end is sim/synthetic_scene_cpu.cpp). Per view:
//   1. a full-screen pass shades sky and ground per virtual-pinhole pixel from its ray in NED
//      (the world is procedural and fixed in NED metres, so both cameras and all frames agree);
//   2. the receiver is rasterised over it, camera-relative, reversed-Z as in render/augmenter.cpp;
//   3. the RGBA8 image is read back and resampled through each raw pixel's undistorted ray
//      (cv::remap with fixed-point maps built once per camera), or copied for identity pinholes;
//   4. the sensor: RGB8, Mono8 luma or a Bayer mosaic (bayer_channel()), plus Gaussian noise.
#include "sim/synthetic_scene.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/conventions.hpp"
#include "render/gl_util.hpp"
#include "render/models.hpp"
#include "render/projection.hpp"
#include "sim/synthetic_scene_cpu.hpp"

namespace augrig {

namespace {

// A triangle over the whole viewport, from gl_VertexID (no vertex buffer).
constexpr char kFullScreenVertexShader[] = R"(#version 330 core
void main() {
  vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);
  gl_Position = vec4(p, 0.0, 1.0);
}
)";

// Noise shared by the bake and the per-frame pass: integer-hashed value noise. `period` > 0 wraps
// the lattice so the baked tile repeats seamlessly.
#define AUGRIG_SIM_NOISE                                                                                \
  "uint hash2(ivec2 p, uint seed) {\n"                                                                  \
  "  uint h = uint(p.x) * 0x8da6b343u ^ uint(p.y) * 0xd8163841u ^ seed * 0xcb1ab31fu;\n"                \
  "  h ^= h >> 13u; h *= 0x5bd1e995u; h ^= h >> 15u;\n"                                                 \
  "  return h;\n"                                                                                       \
  "}\n"                                                                                                 \
  "float h01(ivec2 p, uint seed) { return float(hash2(p, seed) & 0xffffffu) * (1.0 / 16777215.0); }\n"  \
  "float vnoise(vec2 x, uint seed, int period) {\n"                                                     \
  "  vec2 i = floor(x); vec2 f = x - i; vec2 u = f * f * (3.0 - 2.0 * f);\n"                            \
  "  ivec2 c0 = ivec2(i), c1 = c0 + 1;\n"                                                               \
  "  if (period > 0) { c0 = (c0 % period + period) % period; c1 = (c1 % period + period) % period; }\n" \
  "  float a = h01(c0, seed), b = h01(ivec2(c1.x, c0.y), seed);\n"                                      \
  "  float d = h01(ivec2(c0.x, c1.y), seed), e = h01(c1, seed);\n"                                      \
  "  return mix(mix(a, b, u.x), mix(d, e, u.x), u.y);\n"                                                \
  "}\n"

// The ground tile, baked once: farmland in tile metres [0, kTileM)^2, periodic. RGB: albedo,
// A: fine texture for the woods laid over it per frame.
constexpr char kBakeFragmentShader[] = "#version 330 core\n" AUGRIG_SIM_NOISE R"(
uniform float u_texel_m;
uniform float u_tile_m;
layout(location = 0) out vec4 o_color;

float fbm(vec2 x, int period, uint seed) {  // 3 octaves, period doubles with the frequency
  return (0.5 * vnoise(x, seed, period) + 0.25 * vnoise(2.0 * x, seed + 1u, 2 * period) +
          0.125 * vnoise(4.0 * x, seed + 2u, 4 * period)) / 0.875;
}

vec3 field_color(uint h) {
  uint k = h % 8u;
  if (k == 0u) return vec3(0.33, 0.42, 0.20);   // pasture
  if (k == 1u) return vec3(0.45, 0.50, 0.26);   // young crop
  if (k == 2u) return vec3(0.55, 0.47, 0.32);   // ploughed
  if (k == 3u) return vec3(0.68, 0.62, 0.40);   // stubble
  if (k == 4u) return vec3(0.27, 0.36, 0.18);   // meadow
  if (k == 5u) return vec3(0.48, 0.40, 0.29);   // bare soil
  if (k == 6u) return vec3(0.58, 0.56, 0.33);   // ripe crop
  return vec3(0.40, 0.46, 0.24);
}

void main() {
  vec2 q = (gl_FragCoord.xy) * u_texel_m;  // metres in the tile
  float n = u_tile_m;
  // Field borders warped a little so they are not ruler-straight (585 m noise, 28 cells a tile).
  vec2 w = q + 40.0 * vec2(vnoise(q * 28.0 / n, 11u, 28) - 0.5, vnoise(q * 28.0 / n, 12u, 28) - 0.5);
  // 64 x 96 fields a tile (256 m x 171 m); wrap the warped coordinate into the tile.
  vec2 cells = vec2(64.0, 96.0);
  vec2 wc = w / n * cells;
  ivec2 ci = ivec2(floor(wc));
  ivec2 cw = (ci % ivec2(cells) + ivec2(cells)) % ivec2(cells);
  // Neighbouring fields now and then share a crop: merge pairs along x.
  uint h = hash2(ivec2(cw.x / 2, cw.y), 7u);
  if ((hash2(cw, 9u) & 3u) != 0u) h = hash2(cw, 7u);
  // ... and others are split in two crops, across or along, so the grid does not read as a checkerboard.
  uint hs = hash2(cw, 13u);
  float cut = 0.3 + 0.4 * float((hs >> 4u) & 255u) / 255.0;
  vec2 fc = wc - vec2(ci);
  if (((hs & 3u) == 1u && fc.x > cut) || ((hs & 3u) == 2u && fc.y > cut)) h = hash2(cw, 17u);
  vec3 col = field_color(h) * (0.85 + 0.3 * float((h >> 8u) & 255u) / 255.0);
  // Texture inside a field (crops, soil), blotches on top.
  col *= 0.8 + 0.4 * fbm(q * 1024.0 / n, 1024, 21u);
  col *= 0.9 + 0.2 * vnoise(q * 128.0 / n, 31u, 128);
  // Roads along every 4th column and 3rd row of field borders, 8 m wide, box-filtered over a texel.
  vec2 spacing = n / (cells / vec2(4.0, 3.0));
  vec2 d = abs(fract(w / spacing + 0.5) - 0.5) * spacing;
  float hw = 4.0, fp = u_texel_m;
  vec2 lo = max(d - 0.5 * fp, -hw), hi = min(d + 0.5 * fp, hw);
  vec2 cov = clamp((hi - lo) / fp, 0.0, 1.0);
  col = mix(col, vec3(0.46, 0.46, 0.46), max(cov.x, cov.y));
  o_color = vec4(clamp(col, 0.0, 1.0), fbm(q * 512.0 / n, 512, 51u));
}
)";

// Sky and ground from the pixel's ray. Everything is in NED metres relative to a world origin,
// so the ground is the same seen from either camera, and moves under a flying tanker.
constexpr char kSkyFragmentShader[] = "#version 330 core\n" AUGRIG_SIM_NOISE R"(
uniform vec4 u_intr;        // virtual pinhole fx, fy, cx, cy
uniform mat3 u_R_ned_cam;
uniform vec3 u_cam_ned;     // camera position: north, east (world metres), down (= -height above ground)
uniform vec3 u_sun_ned;     // unit, towards the sun
uniform float u_tile_m;
uniform sampler2D u_ground;
layout(location = 0) out vec4 o_color;

void main() {
  vec2 uv = gl_FragCoord.xy - 0.5;  // OpenCV pixel (rows come out top-down, render/projection.hpp)
  vec3 d = normalize(u_R_ned_cam * vec3((uv.x - u_intr.z) / u_intr.x, (uv.y - u_intr.w) / u_intr.y, 1.0));
  float sun = max(dot(d, u_sun_ned), 0.0);

  // Sky: pale at the horizon, deeper blue overhead, a soft glow around the sun.
  float el = max(-d.z, 0.0);
  vec3 sky = mix(vec3(0.80, 0.86, 0.93), vec3(0.22, 0.42, 0.78), sqrt(el) * (1.4 - 0.4 * el));
  sky += vec3(1.0, 0.95, 0.85) * (0.5 * exp(400.0 * (sun - 1.0)) + 0.18 * exp(12.0 * (sun - 1.0)));

  // Ground: where the ray meets the ground plane (computed for every pixel: texture derivatives
  // need the whole 2x2 quad), the tile rotated off the compass, woods and tint from unbaked noise
  // so the tile's repeat does not show.
  float t = min(-u_cam_ned.z / max(d.z, 1e-5), 3.0e5);
  vec2 p = u_cam_ned.xy + t * d.xy;
  vec2 q = vec2(0.9397 * p.x - 0.3420 * p.y, 0.3420 * p.x + 0.9397 * p.y);
  vec4 g = texture(u_ground, q / u_tile_m);
  float wood = 0.7 * vnoise(q / 2500.0, 41u, 0) + 0.3 * vnoise(q / 700.0, 42u, 0) + 0.1 * (g.a - 0.5);
  wood = smoothstep(0.60, 0.63, wood);  // ragged edges from the baked texture
  vec3 ground = mix(g.rgb, vec3(0.18, 0.27, 0.13) * (0.45 + 1.1 * g.a), wood);
  ground *= (0.9 + 0.2 * vnoise(q / 9000.0, 43u, 0)) * (0.75 + 0.35 * max(-u_sun_ned.z, 0.0));
  ground = mix(ground, vec3(0.60, 0.66, 0.74), 1.0 - exp(-t / 30000.0));  // haze

  o_color = vec4(clamp(d.z > 0.0 ? ground : sky, 0.0, 1.0), 1.0);
}
)";

constexpr char kObjectVertexShader[] = R"(#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec2 a_uv;
uniform mat4 u_cam_from_obj;  // camera-relative, so float is precise enough
uniform mat4 u_proj;          // camera frame -> clip (render/projection.hpp)
out vec3 v_normal_cam;
out vec2 v_uv;
void main() {
  v_normal_cam = mat3(u_cam_from_obj) * a_normal;
  v_uv = a_uv;
  gl_Position = u_proj * (u_cam_from_obj * vec4(a_pos, 1.0));
}
)";

constexpr char kObjectFragmentShader[] = R"(#version 330 core
in vec3 v_normal_cam;
in vec2 v_uv;
uniform vec3 u_base_color;
uniform sampler2D u_texture;
uniform int u_has_texture;
uniform vec3 u_sun_cam;   // unit, towards the sun
uniform vec3 u_up_cam;    // unit, NED up: sky light comes from above
layout(location = 0) out vec4 o_color;
void main() {
  vec3 n = normalize(v_normal_cam);
  if (!gl_FrontFacing) n = -n;
  vec3 albedo = u_base_color;
  if (u_has_texture != 0) albedo *= texture(u_texture, v_uv).rgb;
  float diffuse = max(dot(n, u_sun_cam), 0.0);
  float sky = 0.5 + 0.5 * dot(n, u_up_cam);  // hemispherical ambient: bright sky above, ground below
  vec3 ambient = mix(vec3(0.22, 0.22, 0.20), vec3(0.36, 0.40, 0.46), sky);
  vec3 light = vec3(1.0, 0.97, 0.92) * 0.75 * diffuse + ambient;
  o_color = vec4(clamp(albedo * light, 0.0, 1.0), 1.0);
}
)";

// The baked ground tile: 2048^2 texels of 8 m, repeating every 16.4 km (the per-frame noise on top
// hides the repeat). 8 m is about the footprint of a raw pixel on the nearest ground in view.
constexpr int kTileTexels = 2048;
constexpr float kTileM = 16384.0f;

struct DrawMesh {
  gl::GpuMesh gpu;
  Eigen::Vector3f base_color;
  bool cull;
};

struct View {
  VirtualPinhole vp;
  std::array<float, 16> proj{};
  cv::Mat map1, map2;  // raw pixel -> virtual pixel, fixed point (cv::convertMaps); empty for identity
};

// Inverse of the standard normal CDF by Newton on erfc (used once, for the noise table).
double normal_quantile(double p) {
  double x = 0.0;
  for (int i = 0; i < 60; ++i) {
    const double cdf = 0.5 * std::erfc(-x / std::sqrt(2.0));
    const double pdf = std::exp(-0.5 * x * x) / std::sqrt(2.0 * kPi);
    const double step = (cdf - p) / std::max(pdf, 1e-300);
    x -= std::clamp(step, -1.0, 1.0);
    if (std::abs(step) < 1e-12) break;
  }
  return x;
}

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

class SyntheticSceneRendererImpl final : public SyntheticSceneRenderer {
 public:
  explicit SyntheticSceneRendererImpl(const Rig& rig) : rig_(rig) {}
  ~SyntheticSceneRendererImpl() override {
    for (auto& m : meshes_) m.gpu.destroy();
    if (fbo_) glDeleteFramebuffers(1, &fbo_);
    const GLuint rbs[2] = {color_rb_, depth_rb_};
    glDeleteRenderbuffers(2, rbs);
    if (empty_vao_) glDeleteVertexArrays(1, &empty_vao_);
    if (sky_program_) glDeleteProgram(sky_program_);
    if (ground_tex_) glDeleteTextures(1, &ground_tex_);
    if (object_program_) glDeleteProgram(object_program_);
  }

  Status init(std::shared_ptr<const Model> receiver);
  Status render(int camera, const SkyState& sky, const Pose& T_body_receiver, bool receiver_present,
                const SensorOptions& sensor, Image& out) override;

 private:
  void draw(const View& view, const RigCamera& cam, const SkyState& sky, const Pose& T_body_receiver,
            bool receiver_present);
  void to_sensor(int camera, const cv::Mat& rgba, const SensorOptions& sensor, Image& out);

  Rig rig_;
  Model receiver_;
  std::vector<DrawMesh> meshes_;
  std::vector<View> views_;
  GLuint fbo_ = 0, color_rb_ = 0, depth_rb_ = 0, empty_vao_ = 0;
  Status bake_ground();

  GLuint sky_program_ = 0, object_program_ = 0, ground_tex_ = 0;
  GLint u_intr_ = -1, u_R_ned_cam_ = -1, u_cam_ned_ = -1, u_sun_ned_ = -1, u_ground_ = -1;
  GLint u_cam_from_obj_ = -1, u_proj_ = -1, u_base_color_ = -1, u_texture_ = -1, u_has_texture_ = -1,
        u_sun_cam_ = -1, u_up_cam_ = -1;
  int fb_width_ = 0, fb_height_ = 0;
  bool zero_to_one_ = false;
  cv::Mat virtual_rgba_, raw_rgba_;
  std::vector<float> gauss_;            // 65536 quantiles of N(0, 1): 16 random bits -> one Gaussian sample
  std::vector<std::int32_t> noise_q8_;  // gauss_ * sigma in 1/256 DN, + 128 for rounding
};

Status SyntheticSceneRendererImpl::init(std::shared_ptr<const Model> receiver) {
  if (rig_.cameras.empty()) return make_error("SyntheticSceneRenderer::create(): the rig has no cameras");
  bool builtin = false;
  auto rec = load_scene_receiver(rig_, std::move(receiver), builtin);
  if (!rec) return rec.error();
  receiver_ = std::move(*rec);

  auto sky = gl::make_program("synthetic sky", kFullScreenVertexShader, kSkyFragmentShader);
  if (!sky) return make_error("SyntheticSceneRenderer::create(): ", sky.error().message);
  sky_program_ = *sky;
  auto obj = gl::make_program("synthetic receiver", kObjectVertexShader, kObjectFragmentShader);
  if (!obj) return make_error("SyntheticSceneRenderer::create(): ", obj.error().message);
  object_program_ = *obj;
  u_intr_ = glGetUniformLocation(sky_program_, "u_intr");
  u_R_ned_cam_ = glGetUniformLocation(sky_program_, "u_R_ned_cam");
  u_cam_ned_ = glGetUniformLocation(sky_program_, "u_cam_ned");
  u_sun_ned_ = glGetUniformLocation(sky_program_, "u_sun_ned");
  u_ground_ = glGetUniformLocation(sky_program_, "u_ground");
  glUseProgram(sky_program_);
  glUniform1f(glGetUniformLocation(sky_program_, "u_tile_m"), kTileM);
  u_cam_from_obj_ = glGetUniformLocation(object_program_, "u_cam_from_obj");
  u_proj_ = glGetUniformLocation(object_program_, "u_proj");
  u_base_color_ = glGetUniformLocation(object_program_, "u_base_color");
  u_texture_ = glGetUniformLocation(object_program_, "u_texture");
  u_has_texture_ = glGetUniformLocation(object_program_, "u_has_texture");
  u_sun_cam_ = glGetUniformLocation(object_program_, "u_sun_cam");
  u_up_cam_ = glGetUniformLocation(object_program_, "u_up_cam");
  glGenVertexArrays(1, &empty_vao_);  // core profile: a draw needs a bound VAO
  if (auto st = bake_ground(); !st) return st;

  // Consistently wound built-in meshes can be culled; files may not be.
  for (const Mesh& m : receiver_.meshes) meshes_.push_back({gl::upload(m), m.base_color, builtin});

  zero_to_one_ = gl::has_clip_control();
  if (zero_to_one_) glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);

  views_.resize(rig_.cameras.size());
  for (std::size_t c = 0; c < rig_.cameras.size(); ++c) {
    const RigCamera& cam = rig_.cameras[c];
    const CameraModel& cm = cam.model;
    if (cm.width_px <= 0 || cm.height_px <= 0)
      return make_error("SyntheticSceneRenderer::create(): camera ", c, " has no image size");
    View& v = views_[c];
    auto vp = make_virtual_pinhole(cm, 1.0, false, cam.name);
    if (!vp) return vp.error();
    v.vp = std::move(*vp);
    v.proj = gl_projection(v.vp.fx, v.vp.fy, v.vp.cx, v.vp.cy, v.vp.width, v.vp.height, cam.near_m, cam.far_m,
                           zero_to_one_);
    if (!v.vp.identity) {
      // Pixels without a valid ray map far outside: cv::remap's constant border makes them black.
      cv::Mat map(cm.height_px, cm.width_px, CV_32FC2);
      for (int y = 0; y < cm.height_px; ++y) {
        auto* row = map.ptr<cv::Vec2f>(y);
        for (int x = 0; x < cm.width_px; ++x) {
          const Eigen::Vector2f& r = v.vp.ray_xy[static_cast<std::size_t>(y) * cm.width_px + x];
          if (!std::isfinite(r.x()) || !std::isfinite(r.y())) {
            row[x] = {-1e4f, -1e4f};
            continue;
          }
          const Eigen::Vector2d p = v.vp.to_virtual(r.cast<double>());
          row[x] = {static_cast<float>(p.x()), static_cast<float>(p.y())};
        }
      }
      cv::convertMaps(map, cv::noArray(), v.map1, v.map2, CV_16SC2);
    }
    fb_width_ = std::max(fb_width_, v.vp.width);
    fb_height_ = std::max(fb_height_, v.vp.height);
  }

  // Own framebuffer: one colour attachment (nothing else to clear or write on a CPU rasteriser).
  glGenFramebuffers(1, &fbo_);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glGenRenderbuffers(1, &color_rb_);
  glBindRenderbuffer(GL_RENDERBUFFER, color_rb_);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, fb_width_, fb_height_);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color_rb_);
  glGenRenderbuffers(1, &depth_rb_);
  glBindRenderbuffer(GL_RENDERBUFFER, depth_rb_);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, fb_width_, fb_height_);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_rb_);
  const GLenum buf = GL_COLOR_ATTACHMENT0;
  glDrawBuffers(1, &buf);
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    return make_error("SyntheticSceneRenderer::create(): ", fb_width_, "x", fb_height_,
                      " framebuffer incomplete (status ", static_cast<unsigned>(status), ")");

  gauss_.resize(65536);
  for (std::size_t i = 0; i < gauss_.size(); ++i)
    gauss_[i] = static_cast<float>(normal_quantile((static_cast<double>(i) + 0.5) / 65536.0));

  if (auto e = gl::drain_errors(); !e.empty())
    return make_error("SyntheticSceneRenderer::create(): OpenGL errors:", e);
  return {};
}

Status SyntheticSceneRendererImpl::bake_ground() {
  auto prog = gl::make_program("synthetic ground bake", kFullScreenVertexShader, kBakeFragmentShader);
  if (!prog) return make_error("SyntheticSceneRenderer::create(): ", prog.error().message);
  glGenTextures(1, &ground_tex_);
  glBindTexture(GL_TEXTURE_2D, ground_tex_);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, kTileTexels, kTileTexels, 0, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
  GLuint fbo = 0;
  glGenFramebuffers(1, &fbo);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, ground_tex_, 0);
  const GLenum buf = GL_COLOR_ATTACHMENT0;
  glDrawBuffers(1, &buf);
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status == GL_FRAMEBUFFER_COMPLETE) {
    glViewport(0, 0, kTileTexels, kTileTexels);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_SCISSOR_TEST);
    glDisable(GL_BLEND);
    glDisable(GL_CULL_FACE);
    glUseProgram(*prog);
    glUniform1f(glGetUniformLocation(*prog, "u_texel_m"), kTileM / kTileTexels);
    glUniform1f(glGetUniformLocation(*prog, "u_tile_m"), kTileM);
    glBindVertexArray(empty_vao_);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glBindVertexArray(0);
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glDeleteFramebuffers(1, &fbo);
  glDeleteProgram(*prog);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    return make_error("SyntheticSceneRenderer::create(): ground tile framebuffer incomplete (status ",
                      static_cast<unsigned>(status), ")");
  // Mipmaps: the far ground averages out instead of shimmering.
  glBindTexture(GL_TEXTURE_2D, ground_tex_);
  glGenerateMipmap(GL_TEXTURE_2D);
  // One mip level per sample: llvmpipe's trilinear costs ~25 % more per frame; haze hides the seams.
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
  glBindTexture(GL_TEXTURE_2D, 0);
  return {};
}

void SyntheticSceneRendererImpl::draw(const View& view, const RigCamera& cam, const SkyState& sky,
                                      const Pose& T_body_receiver, bool receiver_present) {
  const Eigen::Matrix3d R_ned_cam = sky.R_ned_body * cam.T_body_cam.R();
  const Eigen::Matrix3d R_cam_ned = R_ned_cam.transpose();
  // The camera's own offset from the tanker's reference point counts: the ground is in world metres.
  const Eigen::Vector3d cam_offset_ned = sky.R_ned_body * cam.T_body_cam.translation_m;
  const Eigen::Vector3d cam_ned(sky.north_east_m.x() + cam_offset_ned.x(),
                                sky.north_east_m.y() + cam_offset_ned.y(),
                                -sky.altitude_m + cam_offset_ned.z());
  const Eigen::Vector3d sun = sky.sun_ned.normalized();

  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glViewport(0, 0, view.vp.width, view.vp.height);
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_BLEND);
  glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  glDepthMask(GL_TRUE);
  glClearDepth(0.0);  // reversed-Z: 0 is the far plane
  glClear(GL_DEPTH_BUFFER_BIT);

  // Background: every pixel, no depth.
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  glUseProgram(sky_program_);
  glUniform4f(u_intr_, static_cast<float>(view.vp.fx), static_cast<float>(view.vp.fy),
              static_cast<float>(view.vp.cx), static_cast<float>(view.vp.cy));
  const Eigen::Matrix3f Rf = R_ned_cam.cast<float>();
  glUniformMatrix3fv(u_R_ned_cam_, 1, GL_FALSE, Rf.data());  // Eigen is column-major, as GL
  glUniform3f(u_cam_ned_, static_cast<float>(cam_ned.x()), static_cast<float>(cam_ned.y()),
              static_cast<float>(cam_ned.z()));
  glUniform3f(u_sun_ned_, static_cast<float>(sun.x()), static_cast<float>(sun.y()),
              static_cast<float>(sun.z()));
  glUniform1i(u_ground_, 0);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, ground_tex_);
  glBindVertexArray(empty_vao_);
  glDrawArrays(GL_TRIANGLES, 0, 3);

  if (receiver_present && !meshes_.empty()) {
    // Camera-relative in double, then float for the GPU.
    const Pose T_cam_receiver = cam.T_body_cam.inverse() * T_body_receiver;
    const Eigen::Matrix4f M = T_cam_receiver.matrix().cast<float>();
    const Eigen::Vector3f sun_cam = (R_cam_ned * sun).cast<float>();
    const Eigen::Vector3f up_cam = (R_cam_ned * Eigen::Vector3d(0, 0, -1)).cast<float>();
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GREATER);
    glFrontFace(GL_CW);  // y-down projection (render/projection.hpp)
    glCullFace(GL_BACK);
    glUseProgram(object_program_);
    glUniformMatrix4fv(u_cam_from_obj_, 1, GL_FALSE, M.data());
    glUniformMatrix4fv(u_proj_, 1, GL_FALSE, view.proj.data());
    glUniform1i(u_texture_, 0);
    glUniform3f(u_sun_cam_, sun_cam.x(), sun_cam.y(), sun_cam.z());
    glUniform3f(u_up_cam_, up_cam.x(), up_cam.y(), up_cam.z());
    glActiveTexture(GL_TEXTURE0);
    for (const DrawMesh& m : meshes_) {
      if (m.cull)
        glEnable(GL_CULL_FACE);
      else
        glDisable(GL_CULL_FACE);
      glUniform3f(u_base_color_, m.base_color.x(), m.base_color.y(), m.base_color.z());
      glUniform1i(u_has_texture_, m.gpu.has_texture ? 1 : 0);
      if (m.gpu.has_texture) glBindTexture(GL_TEXTURE_2D, m.gpu.texture);
      m.gpu.draw();
    }
    glDisable(GL_CULL_FACE);
    glDisable(GL_DEPTH_TEST);
  }
  glBindVertexArray(0);
}

void SyntheticSceneRendererImpl::to_sensor(int camera, const cv::Mat& rgba, const SensorOptions& sensor,
                                           Image& out) {
  const int W = rgba.cols, H = rgba.rows;
  const PixelFormat fmt = sensor.format;
  if (out.width() != W || out.height() != H || out.format() != fmt) out = Image(W, H, fmt);
  for (int y = 0; y < H; ++y) {
    const std::uint8_t* s = rgba.ptr<std::uint8_t>(y);
    std::uint8_t* d = out.row(y);
    switch (fmt) {
      case PixelFormat::kRGB8:
        for (int x = 0; x < W; ++x)
          d[3 * x] = s[4 * x], d[3 * x + 1] = s[4 * x + 1], d[3 * x + 2] = s[4 * x + 2];
        break;
      case PixelFormat::kRGBA8:
        std::memcpy(d, s, static_cast<std::size_t>(W) * 4);
        break;
      case PixelFormat::kMono8:
        for (int x = 0; x < W; ++x) {
          const int l = 299 * s[4 * x] + 587 * s[4 * x + 1] + 114 * s[4 * x + 2];
          d[x] = static_cast<std::uint8_t>((l + 500) / 1000);
        }
        break;
      default:  // Bayer: each site keeps its own colour channel
        for (int x = 0; x < W; ++x) d[x] = s[4 * x + bayer_channel(fmt, x, y)];
    }
  }
  if (sensor.noise_sigma <= 0) return;
  // Deterministic: the stream depends on the seed and the camera only. 16 random bits pick one of
  // 65536 Gaussian quantiles, scaled to 1/256 digital numbers (fixed point keeps it fast).
  std::mt19937_64 rng(
      splitmix64(sensor.noise_seed ^ (0x51ed270b27a3e1f1ull * (static_cast<std::uint64_t>(camera) + 1))));
  noise_q8_.resize(gauss_.size());
  for (std::size_t i = 0; i < gauss_.size(); ++i)
    noise_q8_[i] = static_cast<std::int32_t>(std::lround(sensor.noise_sigma * gauss_[i] * 256.0)) + 128;
  const int bpp = bytes_per_pixel(fmt);
  const std::size_t row_bytes = static_cast<std::size_t>(W) * bpp;
  auto add = [this](std::uint8_t& v, std::uint64_t bits16) {
    const int r = ((static_cast<int>(v) << 8) + noise_q8_[bits16 & 0xffff]) >> 8;  // rounded
    v = static_cast<std::uint8_t>(std::clamp(r, 0, 255));
  };
  for (int y = 0; y < H; ++y) {
    std::uint8_t* d = out.row(y);
    std::size_t i = 0;
    if (bpp == 4) {  // one draw per pixel: R G B, alpha stays opaque
      for (; i + 4 <= row_bytes; i += 4) {
        const std::uint64_t bits = rng();
        add(d[i], bits), add(d[i + 1], bits >> 16), add(d[i + 2], bits >> 32);
      }
      continue;
    }
    for (; i + 4 <= row_bytes; i += 4) {
      const std::uint64_t bits = rng();
      add(d[i], bits), add(d[i + 1], bits >> 16), add(d[i + 2], bits >> 32), add(d[i + 3], bits >> 48);
    }
    for (std::uint64_t bits = rng(); i < row_bytes; ++i, bits >>= 16) add(d[i], bits);
  }
}

Status SyntheticSceneRendererImpl::render(int camera, const SkyState& sky, const Pose& T_body_receiver,
                                          bool receiver_present, const SensorOptions& sensor, Image& out) {
  if (camera < 0 || camera >= static_cast<int>(views_.size()))
    return make_error("SyntheticSceneRenderer::render(): no camera ", camera, " (the rig has ", views_.size(),
                      ")");
  if (!(sky.altitude_m > 0)) return make_error("SyntheticSceneRenderer::render(): altitude must be > 0 m");
  if (!(sensor.noise_sigma >= 0))
    return make_error("SyntheticSceneRenderer::render(): noise_sigma must be >= 0");
  const View& view = views_[camera];
  const RigCamera& cam = rig_.cameras[camera];
  draw(view, cam, sky, T_body_receiver, receiver_present);

  // Read back RGBA (the fast path on llvmpipe); rows come out in OpenCV order.
  const int W = cam.model.width_px, H = cam.model.height_px;
  virtual_rgba_.create(view.vp.height, view.vp.width, CV_8UC4);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glPixelStorei(GL_PACK_ROW_LENGTH, 0);
  glReadPixels(0, 0, view.vp.width, view.vp.height, GL_RGBA, GL_UNSIGNED_BYTE, virtual_rgba_.data);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  if (auto e = gl::drain_errors(); !e.empty())
    return make_error("SyntheticSceneRenderer::render(): OpenGL errors:", e);

  const cv::Mat* raw = &virtual_rgba_;
  if (!view.vp.identity) {
    // The lens: each raw pixel samples the virtual image where its undistorted ray lands.
    cv::remap(virtual_rgba_, raw_rgba_, view.map1, view.map2, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
              cv::Scalar(0, 0, 0, 255));
    raw = &raw_rgba_;
  }
  if (raw->cols != W || raw->rows != H)
    return make_error("SyntheticSceneRenderer::render(): internal size mismatch ", raw->cols, "x", raw->rows);
  to_sensor(camera, *raw, sensor, out);
  return {};
}

}  // namespace

Expected<std::unique_ptr<SyntheticSceneRenderer>> SyntheticSceneRenderer::create(
    const Rig& rig, std::shared_ptr<const Model> receiver, const SceneRendererOptions& options) {
  if (options.backend == SceneBackend::kCpu) return make_cpu_scene_renderer(rig, std::move(receiver), options);
  auto r = std::make_unique<SyntheticSceneRendererImpl>(rig);
  if (auto s = r->init(std::move(receiver)); !s) return s.error();
  return std::unique_ptr<SyntheticSceneRenderer>(std::move(r));
}

}  // namespace augrig
