// Display: the live window (GLFW + Dear ImGui) of issue 6. It draws, once per frame() call, the
// left and right augmented views (with an optional mask overlay in the seed paper's colours, and
// the truth-validation overlay: the receiver model drawn at its fused pose), a third-person world
// view like the paper's Fig. 1/4/6 (tanker, receiver, camera frusta with the image quads, the boom)
// and the HUD (rates, skew, drops, nav, occlusion and its recent history, latency, recording,
// messages). It owns its window and GL context and nothing else: user commands (boom mode, nudges,
// recording, pause, quit) are returned by poll_commands() for the pipeline's owner to act on.
// Screenshots and clips are the display's own: it reads back its framebuffer and writes PNGs.
//
// Threads: create() makes the window and its GL context current on the calling thread; every
// later call must come from that thread (GLFW wants it to be the main thread). The display never
// blocks on the pipeline and keeps its cost low: per new frame (DisplayInput::frame_id) one
// composition at about the size shown (with the overlay composed in) and upload per view; a
// redraw (views as textured quads, the world view at a modest resolution and rate, the HUD) only
// when something changed: a new frame, an input event, an overlay, or the HUD's refresh interval.
// docs/DISPLAY.md.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/expected.hpp"
#include "core/image.hpp"
#include "core/pose.hpp"
#include "nav/types.hpp"
#include "pipeline/pipeline.hpp"
#include "pipeline/status.hpp"
#include "recorder/record.hpp"
#include "render/augmenter.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"
#include "render/stats.hpp"

struct GLFWwindow;

namespace augrig::app {

using pipeline::DisplayBoomMode;
using pipeline::to_string;

// What the mask overlay shows over both views.
enum class MaskOverlay {
  kOff,
  kOcclusion,    // Fig. 8: receiver red, boom cyan (left) / blue (right), boom over receiver white / magenta
  kBoomOverlap,  // Fig. 7b: boom in the left image cyan, in the right blue, in both green
};
std::string_view to_string(MaskOverlay m);

using pipeline::kHudUnknown;
using pipeline::LatencyHud;
using pipeline::NavHud;

using pipeline::HudState;

// One call's input. Pointers are not owned and need only live during the frame() call.
struct DisplayInput {
  // Changes whenever the images (and masks) change; the same id again re-draws without uploading.
  std::uint64_t frame_id = 0;
  std::array<const Image*, 2> images{};  // augmented, any PixelFormat; null: no image yet
  std::array<const Image*, 2> masks{};   // Mono8 (kMaskBoom | kMaskReceiver), image-sized; may be null
  const Rig* rig = nullptr;              // null: no world view, no validation overlay
  SceneState scene;                      // boom articulation and the receiver, as augmented
  // The receiver's fused pose (tanker body frame) for the truth-validation overlay; unset: the scene's.
  std::optional<Pose> validation_T_body_receiver;
  HudState hud;
  // A recording's playback position: the HUD shows a timeline (scrub, step, pause) when set.
  std::optional<pipeline::Playback> playback;
};

// Fills images, masks, the scene and the current occlusion from an augmented stereo frame; `result`
// must outlive the frame() call.
DisplayInput display_input(const StereoResult& result, const Rig& rig, const SceneState& scene,
                           std::uint64_t frame_id);

using pipeline::BoomNudge;

// What the user asked for since the last poll_commands(). The owner acts on the first block; the
// second reports what the display did itself.
struct DisplayCommands {
  std::optional<DisplayBoomMode> boom_mode;  // a nudge while not interactive also selects kInteractive
  BoomNudge boom_nudge;
  bool toggle_recording = false;
  bool toggle_pause = false;
  int steps = 0;                          // playback: stereo frames to advance (while paused)
  std::optional<std::size_t> seek_frame;  // playback: the recorded frame to jump to (timeline)
  std::optional<double> rate;             // playback: real rate x (0: as fast as possible)
  bool quit = false;  // the window is closing: frame() returns false from now on

  std::vector<std::string> screenshots;     // PNGs written
  std::optional<std::string> clip_started;  // folder the clip's numbered PNGs go to
  std::optional<std::string> clip_stopped;  // that folder, when the clip ended (key, or its length)
  std::optional<MaskOverlay> mask_overlay;  // the overlay was changed to this
  std::vector<std::string> errors;          // e.g. a screenshot could not be written
};

struct DisplayOptions {
  int width = 1600;  // window size in screen coordinates (scaled on HiDPI monitors)
  int height = 1000;
  std::string title = "augrig";
  bool visible = true;
  std::string screenshot_dir = ".";   // screenshots and clip folders (created when missing)
  int clip_max_frames = 150;          // a clip stops by itself after this many frames
  int world_view_max_px = 640 * 480;  // pixel budget of the world view's offscreen render
  double plot_seconds = 10.0;         // occlusion history shown
  double frustum_depth_m = 25.0;      // world view: frusta and image quads this far (<= far plane)
  double hud_refresh_s = 0.25;        // redraw at least this often for the HUD, even with no new frame
  // The status panel's pixels are drawn anew at most this often, at once on input or for a
  // screenshot; between, redraws copy them (llvmpipe sets up each of its ~3000 triangles).
  double panel_refresh_s = 0.1;
  double world_refresh_s = 0.1;       // re-render the world view at most this often, except on input
  // Models drawn in the world view (and the validation overlay); null: the built-in ones.
  std::shared_ptr<const BoomModel> boom_model;
  std::shared_ptr<const Model> receiver_model;
};

// Rectangle in framebuffer pixels, origin at the top-left of the window.
struct PixelRect {
  int x = 0, y = 0, w = 0, h = 0;
  bool empty() const { return w <= 0 || h <= 0; }
  bool contains(double px, double py) const { return px >= x && py >= y && px < x + w && py < y + h; }
};

// Where the last frame put things, in framebuffer pixels (what a screenshot holds).
struct DisplayLayout {
  int framebuffer_w = 0, framebuffer_h = 0;
  float content_scale = 1.0f;
  std::array<PixelRect, 2> views;  // the images' rectangles (aspect kept): image pixel (u, v) centre
                                   // lies at x + (u + 0.5) * w / image_width, likewise y
  PixelRect world;                 // the world view
  PixelRect hud;                   // the status panel
  PixelRect help;                  // the help overlay; empty when hidden
};

// ---- How a view's image becomes its texture (exposed for the tests) ----------------------------
//
// Each view is composed on the CPU at about the size it is shown: the image reduced by an integer
// `factor`, each f x f block of image pixels one texel (the last row and column of blocks partial
// when the size is not a multiple of f). A texel's colour is the block's mean (Bayer: the mean of
// each colour's sites in the block, so f = 2 bins each 2x2 cell straight to one RGB texel, with no
// demosaicing); with an overlay, its mask class is the OR of the block's mask bits (so a boom one
// pixel thin still shows) and its colour the overlay LUT's (blend_over()'s) of that class over the
// block's mean. factor 1 is the full image as before (Bayer demosaiced by to_rgb8()).

// The factor for an image shown in a rect_w x rect_h rectangle (framebuffer pixels): the image
// size over the rectangle's, rounded (the texture within about 0.7 to 1.3 times what is shown,
// which the GPU's bilinear filter scales); for Bayer images 1 or even (whole 2x2 cells).
int view_decimation(int image_w, int image_h, PixelFormat format, int rect_w, int rect_h);

// How a view is shown in a cell of cell_w x cell_h framebuffer pixels. Pixel-exact when that fills
// the cell well enough: the image reduced by an integer `factor` (for Bayer 1 or even) and each
// texel drawn as zoom x zoom screen pixels, the largest such view that fits, sampled NEAREST (on
// llvmpipe a texel copied 1:1 costs about 0.75x a bilinear one, and nothing is blurred). When that
// view would be less than kPixelExactMinFill of the aspect-kept fit in width (a 1280-wide image in
// a 1270-wide cell would be shown at 640), the fit is used instead: `exact` false, the texture at
// view_decimation() of it, filtered bilinearly.
struct ViewScale {
  bool exact = false;
  int factor = 1;    // image pixels per texel (each way)
  int zoom = 1;      // screen pixels per texel (each way), exact views only
  int w = 0, h = 0;  // the view's size on screen
};
inline constexpr double kPixelExactMinFill = 0.8;
ViewScale view_scale(int image_w, int image_h, PixelFormat format, int cell_w, int cell_h);

// Byte order of a composed texel. The window's textures are BGRA: llvmpipe draws a BGRA texture
// sampled NEAREST as a row copy, any other format through the general shader path.
enum class TexelOrder : std::uint8_t { kRgba, kBgra };

// `image` composed for view `view` (0 left, 1 right) with `overlay` over it: tightly packed rows
// of 4-byte texels (RGBA or BGRA, alpha 255) of ceil(w / factor) x ceil(h / factor) texels into
// `rgba`, their size into out_w, out_h. The overlay needs Mono8 masks of the image's size
// (kOcclusion: masks[view]; kBoomOverlap: both); without them the plain image is composed.
void compose_view_rgba(const Image& image, MaskOverlay overlay, int view,
                       const std::array<const Image*, 2>& masks, int factor, std::vector<std::uint8_t>& rgba,
                       int& out_w, int& out_h, TexelOrder order = TexelOrder::kRgba);

// Every shortcut, as the help overlay and docs/DISPLAY.md list them: {keys, what}.
struct Shortcut {
  const char* keys;
  const char* action;
};
const std::vector<Shortcut>& display_shortcuts();

class Display {
 public:
  // Opens the window (needs a display: X11 or Wayland; xvfb-run in CI). Errors say what failed.
  static Expected<std::unique_ptr<Display>> create(const DisplayOptions& options = {});
  virtual ~Display() = default;

  // Handles input; when anything changed, draws everything, writes a pending screenshot or clip
  // frame and swaps (else returns at once: the caller paces its loop). Returns false once the
  // window was closed (close button, Q, or glfwSetWindowShouldClose).
  virtual bool frame(const DisplayInput& input) = 0;
  // Returns and clears what the user asked for since the last call.
  virtual DisplayCommands poll_commands() = 0;

  // The actions the shortcuts and the HUD's buttons trigger (exposed for owners and tests).
  virtual void request_screenshot() = 0;  // written by the next frame()
  virtual void toggle_clip() = 0;
  virtual void set_mask_overlay(MaskOverlay m) = 0;
  virtual MaskOverlay mask_overlay() const = 0;
  virtual void set_validation_overlay(bool on) = 0;
  virtual bool validation_overlay() const = 0;
  virtual void set_help_visible(bool on) = 0;
  virtual bool help_visible() const = 0;
  virtual bool clip_recording() const = 0;
  virtual std::uint64_t frames_drawn() const = 0;  // frame() calls that redrew the window
  // Redraws that drew the status panel anew; the others copied its last drawing (panel_refresh_s).
  virtual std::uint64_t panel_draws() const = 0;

  virtual const DisplayLayout& layout() const = 0;
  virtual GLFWwindow* window() = 0;
};

}  // namespace augrig::app
