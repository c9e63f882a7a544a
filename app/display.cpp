#include "app/display.hpp"

#define GLFW_INCLUDE_NONE  // epoxy provides the GL declarations
#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <deque>
#include <filesystem>
#include <limits>
#include <system_error>
#include <utility>

#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <epoxy/gl.h>
#include <imgui.h>

#include "app/display_hud.hpp"
#include "app/world_view.hpp"
#include "core/conventions.hpp"
#include "render/gl_context.hpp"
#include "render/gl_util.hpp"
#include "render/image_file.hpp"
#include "render/visualize.hpp"

namespace augrig::app {

std::string_view to_string(MaskOverlay m) {
  switch (m) {
    case MaskOverlay::kOff:
      return "off";
    case MaskOverlay::kOcclusion:
      return "occlusion (Fig. 8)";
    case MaskOverlay::kBoomOverlap:
      return "boom overlap (Fig. 7b)";
  }
  return "?";
}

DisplayInput display_input(const StereoResult& result, const Rig& rig, const SceneState& scene,
                           std::uint64_t frame_id) {
  DisplayInput in;
  in.frame_id = frame_id;
  in.images = {&result.left.augmented, &result.right.augmented};
  in.masks = {&result.left.mask, &result.right.mask};
  in.rig = &rig;
  in.scene = scene;
  in.hud.occlusion = result.stats;
  return in;
}

const std::vector<Shortcut>& display_shortcuts() {
  static const std::vector<Shortcut> s = {
      {"F1, H, ?", "show / hide this help"},
      {"Esc", "close this help"},
      {"1 2 3 4", "boom mode: fixed, scripted, track receptacle, interactive"},
      {"Up / Down", "interactive boom up / down (elevation -/+ 0.5 deg)"},
      {"Left / Right", "interactive boom left / right as seen in the views (azimuth +/- 0.5 deg)"},
      {"Page Up / Down", "extend / retract the boom's telescope (0.1 m)"},
      {"Shift + the above", "five times the step"},
      {"Joystick", "left stick: boom elevation and azimuth; right stick up/down: extension"},
      {"R", "start / stop recording"},
      {"Space", "pause / resume the pipeline (a recording: its playback)"},
      {". / ,", "playback of a recording: one stereo frame forward / back (pauses)"},
      {"S, F12", "screenshot of the window to PNG"},
      {"C", "start / stop a clip (numbered PNGs in a folder)"},
      {"M", "mask overlay: off, Fig. 8 occlusion, Fig. 7b boom overlap"},
      {"V", "truth-validation overlay: the receiver model at its fused pose"},
      {"Home", "reset the world view's camera"},
      {"Mouse", "world view: drag to orbit, wheel to zoom"},
      {"Q", "quit"},
  };
  return s;
}

namespace {

using Clock = std::chrono::steady_clock;

// The overlay's look is render/visualize's, not a copy of its colours: blend_over() works per
// channel, so running it once over probe images (every background value 0..255 under every mask
// class) tabulates exactly what it does: lut[class][channel][background] -> output.
// Classes: mask values & 7 (boom, receiver, shadow bits) for Fig. 8; 0..3 for Fig. 7b.
constexpr int kOverlayClasses = 8;
struct OverlayLut {
  std::array<std::array<std::array<std::uint8_t, 256>, 3>, kOverlayClasses> out;
  std::array<Eigen::Vector3f, kOverlayClasses> colour;  // the visualisation's own colour per class, 0..1
};

// `visualize(masks)` receives probe masks (`class_of(i)` gives mask values for class i, one per
// probe image) and returns the visualisation.
template <typename Visualize>
OverlayLut tabulate(Visualize visualize) {
  Image bg(kOverlayClasses * 256, 1, PixelFormat::kRGB8);
  for (int x = 0; x < kOverlayClasses * 256; ++x)
    std::fill_n(bg.row(0) + 3 * x, 3, static_cast<std::uint8_t>(x % 256));
  const Image vis = visualize([](int x) { return x / 256; });
  const Image out = blend_over(bg, vis);
  OverlayLut lut;
  for (int i = 0; i < kOverlayClasses; ++i) {
    for (int c = 0; c < 3; ++c) {
      for (int b = 0; b < 256; ++b) lut.out[i][c][b] = out.row(0)[3 * (256 * i + b) + c];
      lut.colour[i][c] = vis.row(0)[3 * (256 * i) + c] / 255.0f;
    }
  }
  return lut;
}

template <typename ValueOf>
Image probe_mask(ValueOf value_of_x) {
  Image m(kOverlayClasses * 256, 1, PixelFormat::kMono8);
  for (int x = 0; x < kOverlayClasses * 256; ++x) m.row(0)[x] = static_cast<std::uint8_t>(value_of_x(x));
  return m;
}

// The overlays' LUTs, tabulated once (render/visualize needs no GL context).
struct OverlayLuts {
  std::array<OverlayLut, 2> occlusion;  // Fig. 8: left view, right view
  OverlayLut overlap;                   // Fig. 7b
};
const OverlayLuts& overlay_luts() {
  static const OverlayLuts luts = [] {
    OverlayLuts l;
    for (bool left : {true, false})
      l.occlusion[left ? 0 : 1] = tabulate(
          [left](auto class_of) { return visualize_receiver_occlusion(probe_mask(class_of), left); });
    l.overlap = tabulate([](auto class_of) {
      return visualize_boom_overlap(probe_mask([&](int x) { return class_of(x) & 1; }),
                                    probe_mask([&](int x) { return (class_of(x) >> 1) & 1; }));
    });
    return l;
  }();
  return luts;
}

// Block [x0, x1) x [y0, y1) of output texel (ox, oy) at factor f, clamped to `w` x `h`.
struct Block {
  int x0, x1, y0, y1;
};
inline Block block_of(int ox, int oy, int f, int w, int h) {
  return {ox * f, std::min(ox * f + f, w), oy * f, std::min(oy * f + f, h)};
}

// The block means of `im` into `rgba` (ow x oh texels, alpha 255); red goes to byte `r_at` of a
// texel and blue to byte 2 - r_at (0: RGBA, 2: BGRA).
void reduce_colour(const Image& im, int f, int ow, int oh, std::uint8_t* rgba, int r_at) {
  const int w = im.width(), h = im.height();
  const PixelFormat fmt = im.format();
  const int at[3] = {r_at, 1, 2 - r_at};  // byte of channel c
  if (is_bayer(fmt) && f % 2 == 0 && w >= 2 && h >= 2) {
    // Whole 2x2 cells only: each site's colour from bayer_channel(); an odd last column or row
    // (a cell cut in half) takes the last whole cell's colour.
    const int we = w & ~1, he = h & ~1;
    int ch[4], per_cell[3] = {0, 0, 0};
    for (int k = 0; k < 4; ++k) ++per_cell[ch[k] = bayer_channel(fmt, k & 1, k >> 1)];
    int done_w = 0, done_h = 0;  // texels made by the fast path below
    if (f == 2) {
      // One cell a texel (the live window's usual case): sites i_r, i_b and the two greens' of
      // the cell's four (0 1 / 2 3). The same values as the general loop below.
      int ir = 0, ib = 0, ig[2] = {0, 0}, ng = 0;
      for (int k = 0; k < 4; ++k) (ch[k] == 0 ? ir : ch[k] == 2 ? ib : ig[ng++]) = k;
      if (r_at == 2) std::swap(ir, ib);  // BGRA: the blue site's value goes to byte 0
      done_w = we / 2, done_h = he / 2;
      for (int oy = 0; oy < done_h; ++oy) {
        const std::uint8_t* rows[2] = {im.row(2 * oy), im.row(2 * oy + 1)};
        const std::uint8_t* __restrict sr = rows[ir >> 1] + (ir & 1);
        const std::uint8_t* __restrict sb = rows[ib >> 1] + (ib & 1);
        const std::uint8_t* __restrict sg0 = rows[ig[0] >> 1] + (ig[0] & 1);
        const std::uint8_t* __restrict sg1 = rows[ig[1] >> 1] + (ig[1] & 1);
        std::uint8_t* __restrict d = rgba + static_cast<std::size_t>(oy) * ow * 4;
        // One 32-bit store a texel: byte stores made the compiler reload the row pointers after
        // each (they might alias), 3x slower on the window's thread.
        for (int ox = 0; ox < done_w; ++ox) {
          const std::uint32_t r = sr[2 * ox], b = sb[2 * ox];
          const std::uint32_t g = (static_cast<std::uint32_t>(sg0[2 * ox]) + sg1[2 * ox] + 1) >> 1;
          const std::uint32_t texel = std::endian::native == std::endian::little
                                          ? r | g << 8 | b << 16 | 0xFF000000u
                                          : r << 24 | g << 16 | b << 8 | 0xFFu;
          std::memcpy(d + 4 * static_cast<std::size_t>(ox), &texel, 4);
        }
      }
    }
    for (int oy = 0; oy < oh; ++oy) {
      int y0 = oy * f, y1 = std::min(y0 + f, he);
      if (y0 >= he) y0 = he - 2, y1 = he;
      for (int ox = oy < done_h ? done_w : 0; ox < ow; ++ox) {
        std::uint8_t* d = rgba + (static_cast<std::size_t>(oy) * ow + ox) * 4;
        int x0 = ox * f, x1 = std::min(x0 + f, we);
        if (x0 >= we) x0 = we - 2, x1 = we;
        unsigned sum[3] = {0, 0, 0};
        unsigned cells = 0;
        for (int y = y0; y < y1; y += 2) {
          const std::uint8_t* r0 = im.row(y);
          const std::uint8_t* r1 = im.row(y + 1);
          for (int x = x0; x < x1; x += 2, ++cells) {
            sum[ch[0]] += r0[x];
            sum[ch[1]] += r0[x + 1];
            sum[ch[2]] += r1[x];
            sum[ch[3]] += r1[x + 1];
          }
        }
        for (int c = 0; c < 3; ++c) {
          const unsigned n = cells * static_cast<unsigned>(per_cell[c]);
          d[at[c]] = static_cast<std::uint8_t>((sum[c] + n / 2) / n);
        }
        d[3] = 255;
      }
    }
    return;
  }
  // Anything else as RGB (Mono8 replicated; Bayer demosaiced first when not binned by cells).
  Image converted;
  const Image* src = &im;
  if (fmt != PixelFormat::kRGB8 && fmt != PixelFormat::kRGBA8 && fmt != PixelFormat::kMono8) {
    if (w >= 2 && h >= 2) {
      converted = to_rgb8(im);
    } else {  // a Bayer image too small to demosaic: its values as grey
      converted = Image(w, h, PixelFormat::kMono8);
      for (int y = 0; y < h; ++y) std::copy_n(im.row(y), w, converted.row(y));
    }
    src = &converted;
  }
  const int bpp = bytes_per_pixel(src->format());
  const int c1 = bpp >= 3 ? 1 : 0, c2 = bpp >= 3 ? 2 : 0;  // Mono8: one channel, replicated
  if (f == 1) {
    for (int y = 0; y < h; ++y) {
      const std::uint8_t* s = src->row(y);
      std::uint8_t* d = rgba + static_cast<std::size_t>(y) * w * 4;
      for (int x = 0; x < w; ++x, s += bpp, d += 4) {
        d[at[0]] = s[0];
        d[1] = s[c1];
        d[at[2]] = s[c2];
        d[3] = 255;
      }
    }
    return;
  }
  for (int oy = 0; oy < oh; ++oy) {
    std::uint8_t* d = rgba + static_cast<std::size_t>(oy) * ow * 4;
    for (int ox = 0; ox < ow; ++ox, d += 4) {
      const Block b = block_of(ox, oy, f, w, h);
      unsigned sum[3] = {0, 0, 0};
      for (int y = b.y0; y < b.y1; ++y) {
        const std::uint8_t* s = src->row(y) + static_cast<std::size_t>(b.x0) * bpp;
        for (int x = b.x0; x < b.x1; ++x, s += bpp) {
          sum[0] += s[0];
          sum[1] += s[c1];
          sum[2] += s[c2];
        }
      }
      const unsigned n = static_cast<unsigned>((b.x1 - b.x0) * (b.y1 - b.y0));
      for (int c = 0; c < 3; ++c) d[at[c]] = static_cast<std::uint8_t>((sum[c] + n / 2) / n);
      d[3] = 255;
    }
  }
}

// The OR of `m`'s values over each block, ow x oh.
void or_blocks(const Image& m, int f, int ow, int oh, std::vector<std::uint8_t>& out) {
  out.assign(static_cast<std::size_t>(ow) * oh, 0);
  for (int y = 0; y < m.height(); ++y) {
    const std::uint8_t* s = m.row(y);
    std::uint8_t* d = out.data() + static_cast<std::size_t>(y / f) * ow;
    if (f == 1) {
      std::copy_n(s, ow, d);
      continue;
    }
    int ox = 0;
    if (f == 2)
      for (; ox < m.width() / 2; ++ox) d[ox] |= static_cast<std::uint8_t>(s[2 * ox] | s[2 * ox + 1]);
    for (; ox < ow; ++ox) {
      const int x0 = ox * f, x1 = std::min(x0 + f, m.width());
      std::uint8_t v = 0;
      for (int x = x0; x < x1; ++x) v |= s[x];
      d[ox] |= v;
    }
  }
}

const char* kCopyVs = R"(#version 330 core
uniform int u_flip;
uniform vec2 u_uv_max;  // the image's far edges in texture coordinates (a partial last block)
out vec2 v_uv;
void main() {
  // Corners in fan order: llvmpipe takes a 4-vertex fan (not a strip) as one rectangle.
  int i = gl_VertexID;
  vec2 p = vec2((i == 1 || i == 2) ? 1.0 : -1.0, i >= 2 ? 1.0 : -1.0);
  // (0, 0) is the image's top-left; GL-rendered textures (u_flip 1) have row 0 at the bottom.
  v_uv = u_uv_max * vec2(0.5 * (p.x + 1.0), u_flip == 1 ? 0.5 * (p.y + 1.0) : 0.5 * (1.0 - p.y));
  gl_Position = vec4(p, 0.0, 1.0);
}
)";

// A plain textured quad: simple enough for llvmpipe's fast path (about half the cost per pixel of
// a shader that also decides an overlay), so overlays are composed on the CPU once per frame.
const char* kCopyFs = R"(#version 330 core
in vec2 v_uv;
uniform sampler2D u_image;
out vec4 o_color;
void main() { o_color = texture(u_image, v_uv); }
)";

const char* kLineVs = R"(#version 330 core
layout(location = 0) in vec2 a_px;
uniform vec2 u_size;
void main() {
  gl_Position = vec4(2.0 * (a_px.x + 0.5) / u_size.x - 1.0, 1.0 - 2.0 * (a_px.y + 0.5) / u_size.y, 0.0, 1.0);
}
)";

const char* kLineFs = R"(#version 330 core
uniform vec4 u_color;
out vec4 o_color;
void main() { o_color = u_color; }
)";

// Unique edges of a model's triangles, in the model frame (the validation wireframe).
std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> model_edges(const Model& model) {
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> edges;
  for (const Mesh& m : model.meshes) {
    std::vector<std::pair<std::uint32_t, std::uint32_t>> e;
    for (std::size_t t = 0; t + 2 < m.indices.size(); t += 3)
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = m.indices[t + k], b = m.indices[t + (k + 1) % 3];
        e.emplace_back(std::min(a, b), std::max(a, b));
      }
    std::sort(e.begin(), e.end());
    e.erase(std::unique(e.begin(), e.end()), e.end());
    for (const auto& [a, b] : e)
      edges.emplace_back(m.positions_m[a].cast<double>(), m.positions_m[b].cast<double>());
  }
  return edges;
}

std::string timestamp_name() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  const auto ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  localtime_r(&t, &tm);
  char b[64];
  std::snprintf(b, sizeof b, "%04d%02d%02d_%02d%02d%02d_%03d", tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday,
                tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<int>(ms));
  return b;
}

// Fits a w:h image into a box, keeping its aspect, centred horizontally and aligned to the top.
PixelRect fit(int bx, int by, int bw, int bh, double aspect) {
  if (bw <= 0 || bh <= 0) return {bx, by, 0, 0};
  int w = bw, h = static_cast<int>(std::lround(bw / aspect));
  if (h > bh) {
    h = bh;
    w = static_cast<int>(std::lround(bh * aspect));
  }
  return {bx + (bw - w) / 2, by, w, h};
}

class GlTexture {
 public:
  ~GlTexture() { reset(); }
  void reset() {
    if (id_) glDeleteTextures(1, &id_);
    id_ = 0;
    w_ = h_ = 0;
  }
  // BGRA8 w x h (TexelOrder::kBgra texels), allocated once per size; then sub-image updates only.
  // The unsized internal format lets Mesa store the texels as given (B8G8R8A8): an upload is a
  // copy, and a NEAREST 1:1 draw of it llvmpipe's row copy (GL_RGBA8 would be R8G8B8A8: its
  // general shader path, about 3 ms a redraw for the two views on 2 cores).
  void upload(int w, int h, const std::uint8_t* bgra) {
    if (!id_ || w != w_ || h != h_) {
      reset();
      id_ = gl::make_rgba_texture(w, h);
      glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA, w, h, 0, GL_BGRA, GL_UNSIGNED_BYTE, nullptr);
      w_ = w, h_ = h;
    }
    glBindTexture(GL_TEXTURE_2D, id_);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w, h, GL_BGRA, GL_UNSIGNED_BYTE, bgra);
  }
  GLuint id() const { return id_; }

 private:
  GLuint id_ = 0;
  int w_ = 0, h_ = 0;
};

struct ViewState {
  GlTexture texture;
  std::vector<std::uint8_t> rgba;
  int image_w = 0, image_h = 0;  // of the last uploaded image (0: none)
  int factor = 0;                // the texture is the image reduced by this (0: none yet)
  bool exact = false;            // the texture is shown pixel-exact (NEAREST)
  ViewScale scale;               // how the layout shows the view (compute_layout)
  std::array<float, 2> uv_max{1.0f, 1.0f};  // texture coordinates of the image's far edges
  bool pending = false;          // a new image or overlay to compose at the next redraw
  std::vector<float> lines_px;   // validation wireframe, image pixels, 2 points per edge
};

class DisplayImpl final : public Display {
 public:
  ~DisplayImpl() override {
    if (!ctx_) return;
    ctx_->make_current();
    if (gl3_backend_) ImGui_ImplOpenGL3_Shutdown();
    if (glfw_backend_) ImGui_ImplGlfw_Shutdown();
    if (imgui_) ImGui::DestroyContext(imgui_);
    world_.reset();
    panel_.destroy();
    for (ViewState& v : views_) v.texture.reset();
    for (GLuint p : {line_program_, copy_program_})
      if (p) glDeleteProgram(p);
    if (empty_vao_) glDeleteVertexArrays(1, &empty_vao_);
    if (line_vbo_) glDeleteBuffers(1, &line_vbo_);
    if (line_vao_) glDeleteVertexArrays(1, &line_vao_);
  }

  Status init(const DisplayOptions& options) {
    opt_ = options;
    GlContextOptions go;
    go.window_width = options.width;
    go.window_height = options.height;
    go.window_title = options.title;
    go.visible = options.visible;
    auto ctx = create_gl_context(GlBackend::kGlfwWindow, go);
    if (!ctx) return make_error("app::Display::create(): ", ctx.error().message);
    ctx_ = std::move(*ctx);
    win_ = ctx_->window();
    glfwSetWindowUserPointer(win_, this);
    // Ours first: ImGui's backend chains to the callbacks installed before it.
    glfwSetKeyCallback(
        win_, [](GLFWwindow* w, int key, int, int action, int mods) { self(w)->on_key(key, action, mods); });
    glfwSetCharCallback(win_, [](GLFWwindow* w, unsigned int c) { self(w)->on_char(c); });
    glfwSetMouseButtonCallback(win_, [](GLFWwindow* w, int, int, int) { self(w)->events_ = true; });
    glfwSetScrollCallback(win_, [](GLFWwindow* w, double, double) { self(w)->events_ = true; });
    glfwSetCursorPosCallback(win_, [](GLFWwindow* w, double, double) { self(w)->events_ = true; });
    glfwSetWindowRefreshCallback(win_, [](GLFWwindow* w) { self(w)->events_ = true; });
    glfwSetFramebufferSizeCallback(win_, [](GLFWwindow* w, int, int) { self(w)->events_ = true; });

    receiver_model_ = options.receiver_model ? options.receiver_model
                                             : std::make_shared<const Model>(make_builtin_receiver());
    edges_ = model_edges(*receiver_model_);
    auto world = WorldView::create(options.boom_model, receiver_model_);
    if (!world) return make_error("app::Display::create(): ", world.error().message);
    world_ = std::move(*world);
    frustum_depth_m_ = options.frustum_depth_m;

    auto lp = gl::make_program("app::Display lines", kLineVs, kLineFs);
    if (!lp) return make_error("app::Display::create(): ", lp.error().message);
    line_program_ = *lp;
    auto cp = gl::make_program("app::Display copy", kCopyVs, kCopyFs);
    if (!cp) return make_error("app::Display::create(): ", cp.error().message);
    copy_program_ = *cp;
    glGenVertexArrays(1, &empty_vao_);
    glGenVertexArrays(1, &line_vao_);
    glBindVertexArray(line_vao_);
    glGenBuffers(1, &line_vbo_);
    glBindBuffer(GL_ARRAY_BUFFER, line_vbo_);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 2 * sizeof(float), nullptr);
    glBindVertexArray(0);

    overlay_luts();  // tabulated now rather than at the first frame

    IMGUI_CHECKVERSION();
    imgui_ = ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini in the working directory
    ImGui::StyleColorsDark();
    base_style_ = ImGui::GetStyle();
    glfw_backend_ = ImGui_ImplGlfw_InitForOpenGL(win_, true);
    if (!glfw_backend_) return make_error("app::Display::create(): the ImGui GLFW backend failed to start");
    gl3_backend_ = ImGui_ImplOpenGL3_Init("#version 330 core");
    if (!gl3_backend_)
      return make_error("app::Display::create(): the ImGui OpenGL 3 backend failed to start");
    update_scale(true);
    if (const std::string e = gl::drain_errors(); !e.empty())
      return make_error("app::Display::create(): OpenGL error during set-up: ", e);
    start_ = last_frame_ = last_draw_ = fps_since_ = Clock::now();
    return {};
  }

  bool frame(const DisplayInput& in) override {
    ctx_->make_current();
    hud_mode_ = in.hud.boom_mode;
    playback_ = in.playback;
    paused_ = in.hud.paused;
    const auto now = Clock::now();
    const double dt_s = std::min(0.25, std::chrono::duration<double>(now - last_frame_).count());
    last_frame_ = now;
    const double t_s = std::chrono::duration<double>(now - start_).count();

    glfwPollEvents();  // runs the callbacks: commands are pending from here on
    poll_joystick(dt_s);
    if (glfwWindowShouldClose(win_)) {
      if (!closed_) pending_.quit = true;
      closed_ = true;
      return false;
    }
    int fbw = 0, fbh = 0, ww = 0, wh = 0;
    glfwGetFramebufferSize(win_, &fbw, &fbh);
    glfwGetWindowSize(win_, &ww, &wh);

    const std::optional<Pose> pose = validation_ ? validation_pose(in) : std::nullopt;
    const bool changed = take_input(in, pose, t_s);
    history_.trim(t_s, opt_.plot_seconds);
    while (!own_messages_.empty() && own_messages_.front().first < t_s - 10.0) own_messages_.pop_front();

    // Redraw only when something changed; the HUD at least every hud_refresh_s. ImGui needs a few
    // frames after an input to settle (hover, clicks).
    if (events_) settle_frames_ = 3;
    const bool input = events_ || settle_frames_ > 0;  // the world view follows input at once
    const bool due = std::chrono::duration<double>(now - last_draw_).count() >= opt_.hud_refresh_s;
    if (!changed && !due && settle_frames_ == 0 && !screenshot_pending_ && !clip_active_) return true;
    if (fbw <= 0 || fbh <= 0 || ww <= 0 || wh <= 0) return true;  // minimised: nothing to draw
    events_ = false;
    settle_frames_ = std::max(0, settle_frames_ - 1);
    last_draw_ = now;
    count_drawn_frame(now);
    update_scale(false);
    const float fb_scale = static_cast<float>(fbw) / static_cast<float>(ww);

    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
    compute_layout(in, fbw, fbh, fb_scale);
    compose_views(in);
    handle_world_mouse(fb_scale);
    // The world view is re-rendered for input (orbit, zoom, toggles) at once, else at most every
    // world_refresh_s: a new frame alone (30 Hz live) shows it again as last rendered.
    const bool world_due = input || !world_tex_ ||
                           std::chrono::duration<double>(now - last_world_).count() >= opt_.world_refresh_s;
    if (layout_.world.empty()) world_tex_ = 0;
    if (!layout_.world.empty() && world_due) render_world(in, pose, now, t_s);

    const std::array<float, 3> clear = {0.09f, 0.09f, 0.10f};
    draw_views(in, fbw, fbh, clear);
    draw_hud(in, fb_scale);
    ImGui::Render();
    // The status panel: its ImGui lists drawn into a texture when due, which every redraw copies;
    // the rest of ImGui (labels, popups, the help window) drawn each time, over it.
    const bool panel_due = input || screenshot_pending_ ||
                           std::chrono::duration<double>(now - last_panel_).count() >= opt_.panel_refresh_s;
    draw_imgui(panel_due, fbw, fbh, fb_scale, clear);
    if (screenshot_pending_) take_screenshot(fbw, fbh, t_s);
    if (clip_active_) write_clip_frame(fbw, fbh, t_s);
    glfwSwapBuffers(win_);
    return true;
  }

  DisplayCommands poll_commands() override { return std::exchange(pending_, DisplayCommands{}); }

  void request_screenshot() override { screenshot_pending_ = true; }

  void toggle_clip() override {
    events_ = true;
    if (clip_active_) {
      stop_clip();
      return;
    }
    const std::string dir =
        (opt_.screenshot_dir.empty() ? "." : opt_.screenshot_dir) + "/clip_" + timestamp_name();
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) {
      const std::string e = "app::Display: clip folder " + dir + ": cannot create it (" + ec.message() + ")";
      pending_.errors.push_back(e);
      note(seconds_now(), e);
      return;
    }
    clip_active_ = true;
    clip_dir_ = dir;
    clip_frames_ = 0;
    pending_.clip_started = dir;
  }

  void set_mask_overlay(MaskOverlay m) override {
    events_ = true;
    if (m == overlay_) return;
    overlay_ = m;
    pending_.mask_overlay = m;
  }
  MaskOverlay mask_overlay() const override { return overlay_; }
  void set_validation_overlay(bool on) override {
    events_ = true;
    validation_ = on;
  }
  bool validation_overlay() const override { return validation_; }
  void set_help_visible(bool on) override {
    events_ = true;
    help_ = on;
  }
  bool help_visible() const override { return help_; }
  bool clip_recording() const override { return clip_active_; }
  std::uint64_t frames_drawn() const override { return frames_drawn_; }
  std::uint64_t panel_draws() const override { return panel_draws_; }
  const DisplayLayout& layout() const override { return layout_; }
  GLFWwindow* window() override { return win_; }

 private:
  // frame()'s parts. A new frame (or overlay, or validation pose) noted: true when the views
  // change.
  bool take_input(const DisplayInput& in, const std::optional<Pose>& pose, double t_s) {
    // New images (or another overlay): one composition and upload per view.
    const bool new_frame = !have_frame_id_ || in.frame_id != frame_id_;
    if (new_frame) {
      frame_id_ = in.frame_id;
      have_frame_id_ = true;
      if (in.hud.occlusion) history_.add(t_s, *in.hud.occlusion);
    }
    bool changed = new_frame;
    if (new_frame || composed_overlay_ != overlay_) {
      // Composed at the next redraw, once the layout says how large each view is shown.
      for (int i = 0; i < 2; ++i) {
        ViewState& v = views_[i];
        v.pending = true;
        const Image* im = in.images[i];
        v.image_w = im ? im->width() : 0;  // the layout's aspect
        v.image_h = im ? im->height() : 0;
      }
      composed_overlay_ = overlay_;
      changed = true;
    }
    if (validation_ && (new_frame || !lines_valid_ || !same_pose(pose, lines_pose_))) {
      for (int i = 0; i < 2; ++i) project_validation(i, in, pose);
      lines_pose_ = pose;
      lines_valid_ = true;
      changed = true;
    }
    if (!validation_) lines_valid_ = false;
    return changed;
  }

  void count_drawn_frame(Clock::time_point now) {
    ++frames_drawn_;
    ++fps_frames_;
    if (const double window_s = std::chrono::duration<double>(now - fps_since_).count(); window_s >= 1.0) {
      display_fps_ = fps_frames_ / window_s;  // frames drawn per second
      fps_frames_ = 0;
      fps_since_ = now;
    }
  }

  // Each view at about its size on screen: recomposed for a new image or overlay, or when a
  // resize changes the factor.
  void compose_views(const DisplayInput& in) {
    for (int i = 0; i < 2; ++i) {
      ViewState& v = views_[i];
      const Image* im = in.images[i];
      const PixelRect& r = layout_.views[i];
      if (!im || im->empty()) {
        if (v.pending) compose_view(i, in, 1);
        continue;
      }
      const int f = r.empty() ? std::max(1, v.factor) : v.scale.factor;
      if (v.pending || f != v.factor || v.scale.exact != v.exact) compose_view(i, in, f);
    }
  }

  void render_world(const DisplayInput& in, const std::optional<Pose>& pose, Clock::time_point now,
                    double t_s) {
    WorldViewInput wi;
    wi.rig = in.rig;
    wi.scene = in.scene;
    wi.validation_T_body_receiver = pose;
    for (int i = 0; i < 2; ++i) wi.image_textures[i] = views_[i].image_w ? views_[i].texture.id() : 0;
    wi.frustum_rgb = {overlay_luts().overlap.colour[1],
                      overlay_luts().overlap.colour[2]};  // left-only cyan, right-only blue
    wi.frustum_depth_m = frustum_depth_m_;
    const double area = static_cast<double>(layout_.world.w) * layout_.world.h;
    const double k = std::min(1.0, std::sqrt(opt_.world_view_max_px / std::max(area, 1.0)));
    // Within the pixel budget, at the view's size, drawn 1:1 (NEAREST: llvmpipe's row copy); else
    // reduced, in steps of 16 px so that a window drag re-makes the target rarely.
    const bool exact = k >= 1.0 && layout_.world.w >= 16 && layout_.world.h >= 16;
    const int w = exact ? layout_.world.w : std::max(16, static_cast<int>(layout_.world.w * k) / 16 * 16);
    const int h = exact ? layout_.world.h : std::max(16, static_cast<int>(layout_.world.h * k) / 16 * 16);
    auto tex = world_->render(wi, w, h);
    last_world_ = now;
    if (tex) {
      world_tex_ = *tex;
      glBindTexture(GL_TEXTURE_2D, world_tex_);
      const GLint filter = exact ? GL_NEAREST : GL_LINEAR;
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, filter);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, filter);
    } else {
      world_tex_ = 0;
      note(t_s, tex.error().message);
    }
  }

  // The window cleared, then the two views, the validation lines and the world view.
  void draw_views(const DisplayInput& in, int fbw, int fbh, const std::array<float, 3>& clear) {
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(0, 0, fbw, fbh);
    glDisable(GL_SCISSOR_TEST);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_BLEND);
    glClearColor(clear[0], clear[1], clear[2], 1.0f);
    // Colour only: nothing here tests depth, and llvmpipe clears a depth-stencil buffer's depth
    // alone pixel by pixel (keeping the stencil bits): 1.6 Mpx a redraw at 1600x1000.
    glClear(GL_COLOR_BUFFER_BIT);
    for (int i = 0; i < 2; ++i)
      if (views_[i].image_w)
        draw_texture(views_[i].texture.id(), layout_.views[i], fbh, false, views_[i].uv_max);
    if (validation_) draw_validation(in, fbh);
    if (world_tex_) draw_texture(world_tex_, layout_.world, fbh, true);
    glBindVertexArray(0);
    glViewport(0, 0, fbw, fbh);
  }

  // ImGui's rendered lists: the status panel's through its texture (redrawn when due), the rest
  // drawn directly.
  void draw_imgui(bool panel_due, int fbw, int fbh, float fb_scale, const std::array<float, 3>& clear) {
    const ImDrawData* imgui = ImGui::GetDrawData();
    std::vector<ImDrawList*> panel_lists, other_lists;
    split_panel_lists(*imgui, fb_scale, panel_lists, other_lists);
    if (const PixelRect& h = layout_.hud; !h.empty()) {
      if (panel_due || panel_.w != h.w || panel_.h != h.h)
        draw_panel(*imgui, panel_lists, h, fb_scale, clear);
      draw_texture(panel_.texture, h, fbh, true);
      glBindVertexArray(0);
      glViewport(0, 0, fbw, fbh);
    }
    render_imgui_lists(*imgui, imgui->DisplayPos, imgui->DisplaySize, other_lists);
  }

  void take_screenshot(int fbw, int fbh, double t_s) {
    screenshot_pending_ = false;
    const std::string dir = opt_.screenshot_dir.empty() ? "." : opt_.screenshot_dir;
    const std::string path = dir + "/augrig_" + timestamp_name() + ".png";
    if (Status s = save_framebuffer(dir, path, fbw, fbh); s) {
      pending_.screenshots.push_back(path);
      last_saved_ = path;
    } else {
      pending_.errors.push_back(s.error().message);
      note(t_s, s.error().message);
    }
  }

  static DisplayImpl* self(GLFWwindow* w) { return static_cast<DisplayImpl*>(glfwGetWindowUserPointer(w)); }

  // ---- Input ------------------------------------------------------------------------------------

  void nudge(double d_el_rad, double d_az_rad, double d_ext_m) {
    pending_.boom_nudge.elevation_rad += d_el_rad;
    pending_.boom_nudge.azimuth_rad += d_az_rad;
    pending_.boom_nudge.extension_m += d_ext_m;
    // Moving the boom by hand takes it over, as a boom operator would.
    const DisplayBoomMode current = pending_.boom_mode.value_or(hud_mode_);
    if (current != DisplayBoomMode::kInteractive) pending_.boom_mode = DisplayBoomMode::kInteractive;
  }

  void on_key(int key, int action, int mods) {
    events_ = true;
    if (action == GLFW_RELEASE) return;
    if (imgui_ && ImGui::GetIO().WantTextInput) return;
    const bool repeat = action == GLFW_REPEAT;
    const double k = (mods & GLFW_MOD_SHIFT) ? 5.0 : 1.0;
    const double step_rad = deg_to_rad(0.5) * k, step_m = 0.1 * k;
    switch (key) {
      case GLFW_KEY_UP:
        return nudge(-step_rad, 0, 0);
      case GLFW_KEY_DOWN:
        return nudge(step_rad, 0, 0);
      case GLFW_KEY_LEFT:  // the views look aft: image-left is starboard, +azimuth
        return nudge(0, step_rad, 0);
      case GLFW_KEY_RIGHT:
        return nudge(0, -step_rad, 0);
      case GLFW_KEY_PAGE_UP:
        return nudge(0, 0, step_m);
      case GLFW_KEY_PAGE_DOWN:
        return nudge(0, 0, -step_m);
      default:
        break;
    }
    if (repeat) return;  // the rest act once per press
    switch (key) {
      case GLFW_KEY_F1:
      case GLFW_KEY_H:
        help_ = !help_;
        break;
      case GLFW_KEY_ESCAPE:
        help_ = false;
        break;
      case GLFW_KEY_1:
        pending_.boom_mode = DisplayBoomMode::kFixed;
        break;
      case GLFW_KEY_2:
        pending_.boom_mode = DisplayBoomMode::kScripted;
        break;
      case GLFW_KEY_3:
        pending_.boom_mode = DisplayBoomMode::kTrackReceptacle;
        break;
      case GLFW_KEY_4:
        pending_.boom_mode = DisplayBoomMode::kInteractive;
        break;
      case GLFW_KEY_R:
        pending_.toggle_recording = !pending_.toggle_recording;
        break;
      case GLFW_KEY_SPACE:
        pending_.toggle_pause = !pending_.toggle_pause;
        break;
      case GLFW_KEY_PERIOD:
      case GLFW_KEY_COMMA:
        // Stepping pauses first; back is a seek to the frame before the one shown.
        if (playback_) {
          if (!paused_) pending_.toggle_pause = !pending_.toggle_pause;
          if (key == GLFW_KEY_PERIOD)
            pending_.steps += 1;
          else if (playback_->frame > 0)
            pending_.seek_frame = playback_->frame - 1;
        }
        break;
      case GLFW_KEY_S:
      case GLFW_KEY_F12:
        request_screenshot();
        break;
      case GLFW_KEY_C:
        toggle_clip();
        break;
      case GLFW_KEY_M:
        set_mask_overlay(static_cast<MaskOverlay>((static_cast<int>(overlay_) + 1) % 3));
        break;
      case GLFW_KEY_V:
        validation_ = !validation_;
        break;
      case GLFW_KEY_HOME:
        world_->reset_camera();
        break;
      case GLFW_KEY_Q:
        glfwSetWindowShouldClose(win_, GLFW_TRUE);
        pending_.quit = true;
        break;
      default:
        break;
    }
  }

  void on_char(unsigned int c) {
    events_ = true;
    if (imgui_ && ImGui::GetIO().WantTextInput) return;
    if (c == '?') help_ = !help_;
  }

  // Stick deflection is a rate: full deflection moves the boom 5 deg/s and extends it 1 m/s.
  void poll_joystick(double dt_s) {
    for (int jid = GLFW_JOYSTICK_1; jid <= GLFW_JOYSTICK_LAST; ++jid) {
      if (!glfwJoystickPresent(jid)) continue;
      float x = 0, y = 0, ext = 0;
      GLFWgamepadstate pad;
      if (glfwJoystickIsGamepad(jid) && glfwGetGamepadState(jid, &pad)) {
        x = pad.axes[GLFW_GAMEPAD_AXIS_LEFT_X];
        y = pad.axes[GLFW_GAMEPAD_AXIS_LEFT_Y];
        ext = pad.axes[GLFW_GAMEPAD_AXIS_RIGHT_Y];
      } else {
        int n = 0;
        const float* axes = glfwGetJoystickAxes(jid, &n);
        if (!axes || n < 2) continue;
        x = axes[0];
        y = axes[1];
        ext = n > 3 ? axes[3] : n > 2 ? axes[2] : 0.0f;
      }
      auto dead = [](float v) { return std::abs(v) < 0.15f ? 0.0 : static_cast<double>(v); };
      const double el = dead(y), az = dead(x), ex = dead(ext);
      // Stick forward (GLFW: -y) lowers the boom (+elevation); stick right moves it right in the
      // views (-azimuth); the right stick forward extends.
      if (el != 0 || az != 0 || ex != 0) {
        nudge(-el * deg_to_rad(5.0) * dt_s, -az * deg_to_rad(5.0) * dt_s, -ex * 1.0 * dt_s);
        events_ = true;
      }
      return;  // the first joystick only
    }
  }

  void handle_world_mouse(float fb_scale) {
    const ImGuiIO& io = ImGui::GetIO();
    const double mx = io.MousePos.x * fb_scale, my = io.MousePos.y * fb_scale;
    if (io.WantCaptureMouse) {
      dragging_ = false;
      return;
    }
    const bool inside = layout_.world.contains(mx, my);
    if (io.MouseClicked[0]) dragging_ = inside;
    if (!io.MouseDown[0]) dragging_ = false;
    if (dragging_ && (io.MouseDelta.x != 0 || io.MouseDelta.y != 0))
      world_->orbit(io.MouseDelta.x / io.DisplaySize.x * 800.0, io.MouseDelta.y / io.DisplaySize.y * 600.0);
    if (inside && io.MouseWheel != 0) world_->zoom(io.MouseWheel);
  }

  // ---- Drawing ----------------------------------------------------------------------------------

  void update_scale(bool force) {
    float sx = 1, sy = 1;
    glfwGetWindowContentScale(win_, &sx, &sy);
    const float cs = std::clamp(std::max(sx, sy), 0.5f, 4.0f);
    if (!force && cs == content_scale_) return;
    content_scale_ = cs;
    int fbw = 0, ww = 0, h = 0;
    glfwGetFramebufferSize(win_, &fbw, &h);
    glfwGetWindowSize(win_, &ww, &h);
    const float fb_scale = ww > 0 && fbw > 0 ? static_cast<float>(fbw) / ww : 1.0f;
    // The font is rasterised at its size in framebuffer pixels and shown at 1/fb_scale of that in
    // ImGui's (window) coordinates: sharp on X11 (scale in pixels) and on Wayland/macOS (scale in
    // the framebuffer) alike.
    ImGuiIO& io = ImGui::GetIO();
    if (!force) ImGui_ImplOpenGL3_DestroyFontsTexture();
    io.Fonts->Clear();
    ImFontConfig cfg;
    cfg.SizePixels = std::round(13.0f * cs);
    io.Fonts->AddFontDefault(&cfg);
    io.FontGlobalScale = 1.0f / fb_scale;
    if (!force) ImGui_ImplOpenGL3_CreateFontsTexture();
    ImGui::GetStyle() = base_style_;
    ImGui::GetStyle().ScaleAllSizes(cs / fb_scale);
  }

  void compute_layout(const DisplayInput& in, int fbw, int fbh, float fb_scale) {
    DisplayLayout L;
    L.framebuffer_w = fbw;
    L.framebuffer_h = fbh;
    L.content_scale = content_scale_;
    const int m = static_cast<int>(std::lround(6 * content_scale_));
    label_h_ = static_cast<int>(std::ceil(ImGui::GetFontSize() * fb_scale)) + m;
    const int top_h = fbh * 3 / 5;
    const int cell_w = fbw / 2;
    for (int i = 0; i < 2; ++i) {
      // The image's size (the camera's until one arrives) decides how it is shown (view_scale()).
      int iw = views_[i].image_w, ih = views_[i].image_h;
      PixelFormat format = in.images[i] ? in.images[i]->format() : PixelFormat::kMono8;
      if (!iw && in.rig && in.rig->cameras.size() > static_cast<std::size_t>(i)) {
        iw = in.rig->cameras[i].model.width_px;
        ih = in.rig->cameras[i].model.height_px;
      }
      const int bx = i * cell_w + m, bw = cell_w - 2 * m, bh = top_h - label_h_ - m;
      if (iw > 0 && ih > 0) {
        views_[i].scale = view_scale(iw, ih, format, bw, bh);
        L.views[i] = {bx + (bw - views_[i].scale.w) / 2, label_h_, views_[i].scale.w, views_[i].scale.h};
        if (bw <= 0 || bh <= 0) L.views[i] = {bx, label_h_, 0, 0};
      } else {
        views_[i].scale = {};
        L.views[i] = fit(bx, label_h_, bw, bh, 4.0 / 3.0);
      }
    }
    const int world_w = fbw * 2 / 5;
    L.world = {m, top_h + label_h_, world_w - 2 * m, fbh - top_h - label_h_ - m};
    if (L.world.w < 16 || L.world.h < 16) L.world = {};
    L.hud = {world_w, top_h, fbw - world_w - m, fbh - top_h - m};
    layout_ = L;
  }

  void set_viewport(const PixelRect& r, int fbh) { glViewport(r.x, fbh - r.y - r.h, r.w, r.h); }

  void draw_texture(GLuint tex, const PixelRect& r, int fbh, bool gl_rendered,
                    std::array<float, 2> uv_max = {1.0f, 1.0f}) {
    if (r.empty()) return;
    set_viewport(r, fbh);
    glUseProgram(copy_program_);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, tex);
    glUniform1i(glGetUniformLocation(copy_program_, "u_image"), 0);
    glUniform1i(glGetUniformLocation(copy_program_, "u_flip"), gl_rendered ? 1 : 0);
    glUniform2f(glGetUniformLocation(copy_program_, "u_uv_max"), uv_max[0], uv_max[1]);
    glBindVertexArray(empty_vao_);
    glDrawArrays(GL_TRIANGLE_FAN, 0, 4);
  }

  // One view's texture at `factor` (view_decimation() of its rectangle), the overlay composed in.
  void compose_view(int i, const DisplayInput& in, int factor) {
    ViewState& v = views_[i];
    v.pending = false;
    const Image* im = in.images[i];
    if (!im || im->empty()) {
      v.image_w = v.image_h = 0;
      return;
    }
    int tw = 0, th = 0;
    compose_view_rgba(*im, overlay_, i, in.masks, factor, v.rgba, tw, th, TexelOrder::kBgra);
    v.texture.upload(tw, th, v.rgba.data());
    // Pixel-exact views copy texels (NEAREST, no blur, cheaper on llvmpipe); fitted ones filter.
    v.exact = v.scale.exact;
    const GLint filter = v.exact ? GL_NEAREST : GL_LINEAR;
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, filter);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, filter);
    v.image_w = im->width();
    v.image_h = im->height();
    v.factor = factor;
    // The texels cover ceil(w / f) * f image pixels: the image is this much of the texture.
    v.uv_max = {static_cast<float>(v.image_w) / (static_cast<float>(tw) * factor),
                static_cast<float>(v.image_h) / (static_cast<float>(th) * factor)};
    if (v.exact) v.uv_max = {1.0f, 1.0f};  // every texel on its own screen pixels, a partial block too
  }

  std::optional<Pose> validation_pose(const DisplayInput& in) const {
    if (in.validation_T_body_receiver) return in.validation_T_body_receiver;
    if (in.scene.receiver_present) return in.scene.T_body_receiver;
    return std::nullopt;
  }

  static bool same_pose(const std::optional<Pose>& a, const std::optional<Pose>& b) {
    if (!a || !b) return !a && !b;
    return a->translation_m == b->translation_m && a->rotation.coeffs() == b->rotation.coeffs();
  }

  // The receiver's edges projected through each camera's own model (distortion included) at the
  // fused pose: where the real receiver is, the lines must lie on it. Redone per new frame or pose.
  void project_validation(int i, const DisplayInput& in, const std::optional<Pose>& T_body_receiver) {
    ViewState& v = views_[i];
    v.lines_px.clear();
    if (!in.rig || !T_body_receiver || static_cast<std::size_t>(i) >= in.rig->cameras.size()) return;
    const RigCamera& cam = in.rig->cameras[i];
    line_size_[i] = {static_cast<float>(cam.model.width_px), static_cast<float>(cam.model.height_px)};
    const Pose T_cam_receiver = cam.T_body_cam.inverse() * *T_body_receiver;
    for (const auto& [a, b] : edges_) {
      const auto pa = cam.model.project(T_cam_receiver * a);
      const auto pb = cam.model.project(T_cam_receiver * b);
      if (!pa || !pb) continue;
      v.lines_px.insert(v.lines_px.end(), {static_cast<float>(pa->x()), static_cast<float>(pa->y()),
                                           static_cast<float>(pb->x()), static_cast<float>(pb->y())});
    }
  }

  void draw_validation(const DisplayInput&, int fbh) {
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glUseProgram(line_program_);
    glBindVertexArray(line_vao_);
    glBindBuffer(GL_ARRAY_BUFFER, line_vbo_);
    for (int i = 0; i < 2; ++i) {
      const ViewState& v = views_[i];
      if (!v.image_w || layout_.views[i].empty() || v.lines_px.empty()) continue;
      glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(v.lines_px.size() * sizeof(float)),
                   v.lines_px.data(), GL_STREAM_DRAW);
      set_viewport(layout_.views[i], fbh);
      glUniform2f(glGetUniformLocation(line_program_, "u_size"), line_size_[i][0], line_size_[i][1]);
      glUniform4f(glGetUniformLocation(line_program_, "u_color"), 1.0f, 0.85f, 0.1f, 0.55f);
      glDrawArrays(GL_LINES, 0, static_cast<GLsizei>(v.lines_px.size() / 2));
    }
    glBindVertexArray(0);
    glDisable(GL_BLEND);
  }

  // ImGui's lists split by where they draw: wholly inside the status panel (its window and child
  // windows, ImGui clips them to it) or anywhere else.
  void split_panel_lists(const ImDrawData& d, float fb_scale, std::vector<ImDrawList*>& panel,
                         std::vector<ImDrawList*>& other) const {
    const float k = 1.0f / fb_scale;
    const PixelRect& h = layout_.hud;
    const ImVec4 r(h.x * k, h.y * k, (h.x + h.w) * k, (h.y + h.h) * k);
    for (int l = 0; l < d.CmdListsCount; ++l) {
      ImDrawList* list = d.CmdLists[l];
      bool inside = !h.empty();
      for (const ImDrawCmd& c : list->CmdBuffer)
        inside = inside && c.ClipRect.x >= r.x && c.ClipRect.y >= r.y && c.ClipRect.z <= r.z &&
                 c.ClipRect.w <= r.w;
      (inside ? panel : other).push_back(list);
    }
  }

  // Renders `lists` with ImGui's OpenGL backend into the bound framebuffer, its origin at `pos`.
  static void render_imgui_lists(const ImDrawData& d, ImVec2 pos, ImVec2 size,
                                 std::vector<ImDrawList*>& lists) {
    ImDrawData part = d;
    part.CmdLists = lists.data();
    part.CmdListsCount = static_cast<int>(lists.size());
    part.TotalIdxCount = part.TotalVtxCount = 0;
    for (const ImDrawList* l : lists)
      part.TotalIdxCount += l->IdxBuffer.Size, part.TotalVtxCount += l->VtxBuffer.Size;
    part.DisplayPos = pos;
    part.DisplaySize = size;
    if (!lists.empty()) ImGui_ImplOpenGL3_RenderDrawData(&part);
  }

  // The status panel into its texture (BGRA, drawn 1:1 NEAREST: llvmpipe's row copy): its
  // background colour, then its ImGui lists. Leaves framebuffer 0 bound.
  void draw_panel(const ImDrawData& d, std::vector<ImDrawList*>& lists, const PixelRect& h, float fb_scale,
                  const std::array<float, 3>& under) {
    if (panel_.w != h.w || panel_.h != h.h) {
      panel_.destroy();
      panel_.texture = gl::make_rgba_texture(h.w, h.h);
      glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA, h.w, h.h, 0, GL_BGRA, GL_UNSIGNED_BYTE, nullptr);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
      glGenFramebuffers(1, &panel_.fbo);
      glBindFramebuffer(GL_FRAMEBUFFER, panel_.fbo);
      glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, panel_.texture, 0);
      panel_.w = h.w, panel_.h = h.h;
    }
    glBindFramebuffer(GL_FRAMEBUFFER, panel_.fbo);
    glViewport(0, 0, h.w, h.h);
    glDisable(GL_SCISSOR_TEST);
    const std::array<float, 3> bg = hud::panel_background(under);
    glClearColor(bg[0], bg[1], bg[2], 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    const float k = 1.0f / fb_scale;
    render_imgui_lists(d, ImVec2(h.x * k, h.y * k), ImVec2(h.w * k, h.h * k), lists);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    last_panel_ = Clock::now();
    ++panel_draws_;
  }

  void draw_hud(const DisplayInput& in, float fb_scale) {
    const float k = 1.0f / fb_scale;  // framebuffer pixels -> ImGui coordinates
    const int m = static_cast<int>(std::lround(6 * content_scale_));
    static const char* kNames[2] = {"left camera, augmented", "right camera, augmented"};
    for (int i = 0; i < 2; ++i) {
      const PixelRect& r = layout_.views[i];
      hud::draw_view_label(kNames[i], in.hud, ImVec2(r.x * k, (r.y - label_h_ + m / 2) * k));
      if (!views_[i].image_w)
        ImGui::GetBackgroundDrawList()->AddText(ImVec2((r.x + m) * k, (r.y + m) * k),
                                                IM_COL32(160, 160, 160, 255), "no image yet");
    }
    if (!layout_.world.empty()) {
      const char* label = "world view (drag: orbit, wheel: zoom, Home: reset)";
      ImGui::GetBackgroundDrawList()->AddText(
          ImVec2(layout_.world.x * k, (layout_.world.y - label_h_ + m / 2) * k), IM_COL32(230, 230, 230, 255),
          label);
    }
    hud::PanelState ps;
    ps.display_fps = display_fps_;
    ps.overlay = overlay_;
    ps.validation = validation_;
    ps.help = help_;
    ps.clip = clip_active_;
    ps.clip_frames = clip_frames_;
    ps.last_screenshot = last_saved_;
    for (const auto& [t, msg] : own_messages_) ps.own_messages.push_back(msg);
    ps.boom = in.scene.boom;
    ps.plot_seconds = opt_.plot_seconds;
    ps.frustum_depth_m = frustum_depth_m_;
    ps.playback = in.playback;
    const PixelRect& h = layout_.hud;
    const hud::PanelActions a =
        hud::draw_status_panel(in.hud, ps, history_, ImVec2(h.x * k, h.y * k), ImVec2(h.w * k, h.h * k));
    if (a.boom_mode) pending_.boom_mode = a.boom_mode;
    if (a.toggle_recording) pending_.toggle_recording = !pending_.toggle_recording;
    if (a.toggle_pause) pending_.toggle_pause = !pending_.toggle_pause;
    if (a.steps) {
      if (!in.hud.paused && !pending_.toggle_pause) pending_.toggle_pause = true;
      pending_.steps += a.steps;
    }
    if (a.seek_frame) pending_.seek_frame = a.seek_frame;
    if (a.rate) pending_.rate = a.rate;
    if (a.screenshot) request_screenshot();
    if (a.clip) toggle_clip();
    if (a.help) help_ = !help_;
    if (a.reset_view) world_->reset_camera();
    if (a.overlay) set_mask_overlay(*a.overlay);
    if (a.validation) validation_ = *a.validation;
    if (a.frustum_depth_m) frustum_depth_m_ = *a.frustum_depth_m;
    layout_.help = {};
    if (help_) {
      bool open = true;
      const auto r = hud::draw_help_overlay(ImGui::GetIO().DisplaySize, &open);
      help_ = open;
      layout_.help = {static_cast<int>(r[0] * fb_scale), static_cast<int>(r[1] * fb_scale),
                      static_cast<int>(r[2] * fb_scale), static_cast<int>(r[3] * fb_scale)};
    }
  }

  // ---- Screenshots and clips ----------------------------------------------------------------------

  Status save_framebuffer(const std::string& dir, const std::string& path, int fbw, int fbh) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec)
      return make_error("app::Display: screenshot folder ", dir, ": cannot create it (", ec.message(), ")");
    Image shot(fbw, fbh, PixelFormat::kRGBA8);
    readback_.resize(static_cast<std::size_t>(fbw) * fbh * 4);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, fbw, fbh, GL_RGBA, GL_UNSIGNED_BYTE, readback_.data());
    for (int y = 0; y < fbh; ++y) {  // GL rows run bottom-up
      const std::uint8_t* s = readback_.data() + static_cast<std::size_t>(fbh - 1 - y) * fbw * 4;
      std::uint8_t* d = shot.row(y);
      std::copy_n(s, 4 * fbw, d);
      for (int x = 0; x < fbw; ++x) d[4 * x + 3] = 255;  // the window is opaque, whatever GL left in alpha
    }
    return write_png_file(path, shot, 1);
  }

  void write_clip_frame(int fbw, int fbh, double t_s) {
    char name[32];
    std::snprintf(name, sizeof name, "/frame_%05d.png", clip_frames_);
    if (Status s = save_framebuffer(clip_dir_, clip_dir_ + name, fbw, fbh); !s) {
      pending_.errors.push_back(s.error().message);
      note(t_s, s.error().message);
      stop_clip();
      return;
    }
    if (++clip_frames_ >= std::max(1, opt_.clip_max_frames)) stop_clip();
  }

  void stop_clip() {
    if (!clip_active_) return;
    clip_active_ = false;
    pending_.clip_stopped = clip_dir_;
    last_saved_ = clip_dir_ + " (" + std::to_string(clip_frames_) + " frames)";
  }

  double seconds_now() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }
  void note(double t_s, std::string msg) {
    own_messages_.emplace_back(t_s, std::move(msg));
    while (own_messages_.size() > 5) own_messages_.pop_front();
  }

  DisplayOptions opt_;
  std::unique_ptr<GlContext> ctx_;
  GLFWwindow* win_ = nullptr;
  ImGuiContext* imgui_ = nullptr;
  bool glfw_backend_ = false, gl3_backend_ = false;
  ImGuiStyle base_style_;
  float content_scale_ = 1.0f;
  int label_h_ = 0;

  std::unique_ptr<WorldView> world_;
  std::shared_ptr<const Model> receiver_model_;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> edges_;
  GLuint line_program_ = 0, copy_program_ = 0;
  GLuint empty_vao_ = 0, line_vao_ = 0, line_vbo_ = 0;
  std::array<ViewState, 2> views_;
  std::array<std::array<float, 2>, 2> line_size_{};
  std::uint64_t frame_id_ = 0;
  bool have_frame_id_ = false;
  MaskOverlay composed_overlay_ = MaskOverlay::kOff;
  bool lines_valid_ = false;
  std::optional<Pose> lines_pose_;

  MaskOverlay overlay_ = MaskOverlay::kOff;
  bool validation_ = false;
  std::optional<pipeline::Playback> playback_;  // the last frame()'s, for the step keys
  bool paused_ = false;
  bool help_ = false;
  bool screenshot_pending_ = false;
  bool clip_active_ = false;
  std::string clip_dir_;
  int clip_frames_ = 0;
  std::string last_saved_;
  std::vector<std::uint8_t> readback_;
  double frustum_depth_m_ = 25.0;
  bool dragging_ = false;
  bool closed_ = false;
  bool events_ = true;  // something happened that needs a redraw
  int settle_frames_ = 0;
  std::uint64_t frames_drawn_ = 0, panel_draws_ = 0;

  DisplayBoomMode hud_mode_ = DisplayBoomMode::kFixed;
  DisplayCommands pending_;
  DisplayLayout layout_;
  hud::OcclusionHistory history_;
  std::deque<std::pair<double, std::string>> own_messages_;
  Clock::time_point start_, last_frame_, last_draw_, fps_since_, last_world_, last_panel_;
  struct Panel {  // the status panel's last drawing
    GLuint fbo = 0, texture = 0;
    int w = 0, h = 0;
    void destroy() {
      if (fbo) glDeleteFramebuffers(1, &fbo);
      if (texture) glDeleteTextures(1, &texture);
      fbo = texture = 0;
      w = h = 0;
    }
  } panel_;
  GLuint world_tex_ = 0;  // the world view's last render (WorldView's target)
  int fps_frames_ = 0;
  double display_fps_ = std::numeric_limits<double>::quiet_NaN();
};

}  // namespace

int view_decimation(int image_w, int image_h, PixelFormat format, int rect_w, int rect_h) {
  if (image_w <= 0 || image_h <= 0 || rect_w <= 0 || rect_h <= 0) return 1;
  const double ratio = std::min(static_cast<double>(image_w) / rect_w, static_cast<double>(image_h) / rect_h);
  const int f = std::max(1, static_cast<int>(std::lround(ratio)));
  if (f == 1 || !is_bayer(format)) return f;
  return 2 * std::max(1, static_cast<int>(std::lround(ratio / 2)));
}

ViewScale view_scale(int image_w, int image_h, PixelFormat format, int cell_w, int cell_h) {
  ViewScale s;
  if (image_w <= 0 || image_h <= 0 || cell_w <= 0 || cell_h <= 0) return s;
  // The aspect-kept fit: the most the cell can show.
  int fit_w = cell_w, fit_h = static_cast<int>(std::lround(static_cast<double>(cell_w) * image_h / image_w));
  if (fit_h > cell_h) {
    fit_h = cell_h;
    fit_w = static_cast<int>(std::lround(static_cast<double>(cell_h) * image_w / image_h));
  }
  // The largest pixel-exact view: zoomed when the image fits, else reduced by the smallest factor
  // that fits (Bayer: whole 2x2 cells, so 1 or even).
  int factor = 1, zoom = 1;
  if (image_w <= cell_w && image_h <= cell_h) {
    zoom = std::max(1, std::min(cell_w / image_w, cell_h / image_h));
  } else {
    auto fits = [&](int f) { return (image_w + f - 1) / f <= cell_w && (image_h + f - 1) / f <= cell_h; };
    factor = 2;
    const int step = is_bayer(format) ? 2 : 1;
    while (!fits(factor) && factor < std::max(image_w, image_h)) factor += step;
  }
  const int exact_w = (image_w + factor - 1) / factor * zoom;
  const int exact_h = (image_h + factor - 1) / factor * zoom;
  if (exact_w <= cell_w && exact_h <= cell_h && exact_w >= kPixelExactMinFill * fit_w) {
    s.exact = true;
    s.factor = factor;
    s.zoom = zoom;
    s.w = exact_w;
    s.h = exact_h;
    return s;
  }
  s.w = fit_w;
  s.h = fit_h;
  s.factor = view_decimation(image_w, image_h, format, fit_w, fit_h);
  return s;
}

void compose_view_rgba(const Image& image, MaskOverlay overlay, int view,
                       const std::array<const Image*, 2>& masks, int factor, std::vector<std::uint8_t>& rgba,
                       int& out_w, int& out_h, TexelOrder order) {
  const int f = std::max(1, factor);
  const int w = image.width(), h = image.height();
  out_w = (w + f - 1) / f;
  out_h = (h + f - 1) / f;
  rgba.resize(static_cast<std::size_t>(out_w) * out_h * 4);
  if (image.empty()) return;
  const int r_at = order == TexelOrder::kBgra ? 2 : 0;
  reduce_colour(image, f, out_w, out_h, rgba.data(), r_at);

  auto fits = [&](const Image* m) {
    return m && m->format() == PixelFormat::kMono8 && m->width() == w && m->height() == h;
  };
  const OverlayLut* lut = nullptr;
  thread_local std::vector<std::uint8_t> cls, other;
  const int own = view == 0 ? 0 : 1;
  if (overlay == MaskOverlay::kOcclusion && fits(masks[own])) {
    lut = &overlay_luts().occlusion[own];
    or_blocks(*masks[own], f, out_w, out_h, cls);
    for (std::uint8_t& c : cls) c &= kMaskBoom | kMaskReceiver | kMaskShadow;
  } else if (overlay == MaskOverlay::kBoomOverlap && fits(masks[0]) && fits(masks[1])) {
    lut = &overlay_luts().overlap;
    or_blocks(*masks[0], f, out_w, out_h, cls);
    or_blocks(*masks[1], f, out_w, out_h, other);
    for (std::size_t k = 0; k < cls.size(); ++k)
      cls[k] = static_cast<std::uint8_t>((cls[k] & kMaskBoom) | ((other[k] & kMaskBoom) << 1));
  }
  if (!lut) return;
  std::uint8_t* d = rgba.data();
  for (std::size_t k = 0; k < cls.size(); ++k, d += 4) {
    const auto& row = lut->out[cls[k]];
    d[r_at] = row[0][d[r_at]];
    d[1] = row[1][d[1]];
    d[2 - r_at] = row[2][d[2 - r_at]];
  }
}

Expected<std::unique_ptr<Display>> Display::create(const DisplayOptions& options) {
  auto d = std::make_unique<DisplayImpl>();
  if (Status s = d->init(options); !s) return s.error();
  return std::unique_ptr<Display>(std::move(d));
}

}  // namespace augrig::app
