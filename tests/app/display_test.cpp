// The live display against what it is given: a real stereo frame augmented by the Augmenter (on
// its own thread and EGL context, as in a live run) is shown in a real GLFW window; screenshots
// taken through the user's own shortcut are read back from PNG and compared, pixel by pixel at
// mapped sample points, with the augmented images, the masks and render/visualize's colour
// oracles. Keys are injected through the GLFW callbacks the window really has installed.
//
// The window tests need a display: CTest runs them under xvfb-run (tests/CMakeLists.txt); without
// one they skip.
#include "app/display.hpp"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <thread>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "render/visualize.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::app {
namespace {

namespace fs = std::filesystem;

// ---- The augmented frame ---------------------------------------------------------------------------

// A smooth, strongly green image: any grey boom pixel differs from it by >= 35 in some channel,
// and downscaling it for display barely changes it.
Frame smooth_frame(const CameraModel& cm, CameraId id) {
  Frame f;
  f.image = Image(cm.width_px, cm.height_px, PixelFormat::kRGB8);
  for (int y = 0; y < cm.height_px; ++y)
    for (int x = 0; x < cm.width_px; ++x) {
      std::uint8_t* p = f.image.row(y) + 3 * x;
      p[0] = static_cast<std::uint8_t>(40 + 60 * x / cm.width_px);
      p[1] = static_cast<std::uint8_t>(170 + 60 * y / cm.height_px);
      p[2] = static_cast<std::uint8_t>(90 + 40 * x / cm.width_px);
    }
  f.camera = id;
  return f;
}

struct Augmented {
  Rig rig;
  SceneState scene;
  StereoFrame raw;
  StereoResult result;
  std::string error;
};

// Augmented once per process, on a thread with its own EGL context (the display's GLX context
// lives on the test's thread, as the pipeline and the display would in a live run).
const Augmented& augmented() {
  static const Augmented a = [] {
    Augmented a;
    a.rig = Rig::paper_default();
    std::thread worker([&a] {
      auto ctx = create_gl_context(GlBackend::kEglHeadless);
      if (!ctx) {
        a.error = ctx.error().message;
        return;
      }
      auto aug = Augmenter::create(a.rig);
      if (!aug) {
        a.error = aug.error().message;
        return;
      }
      Eigen::Vector3d receptacle;
      make_builtin_receiver(&receptacle);
      a.scene =
          scene_at_contact(a.rig, (*aug)->boom_model().dims, receptacle, BoomArticulation{0.52, 0.03, 3.0});
      a.raw.left = smooth_frame(a.rig.left().model, CameraId::kLeft);
      a.raw.right = smooth_frame(a.rig.right().model, CameraId::kRight);
      if (Status s = (*aug)->augment(a.raw, a.scene, a.result); !s) a.error = s.error().message;
    });
    worker.join();
    return a;
  }();
  return a;
}

DisplayInput input_for(const Augmented& a, std::uint64_t frame_id = 1) {
  DisplayInput in = display_input(a.result, a.rig, a.scene, frame_id);
  in.hud.fps = {30.0, 29.9};
  in.hud.skew_p50_ms = 0.2;
  in.hud.skew_p99_ms = 0.9;
  in.hud.drops = {1, 0, 2, 0, 0};
  in.hud.nav.status = "fused (GPS + IMU)";
  in.hud.nav.fix = nav::FixQuality::kRtkFixed;
  in.hud.nav.age_s = 0.04;
  in.hud.nav.sigma_pos_m = 0.02;
  in.hud.messages = {"left camera lost 0.6 s ago"};
  return in;
}

// ---- Window helpers ----------------------------------------------------------------------------------

#define REQUIRE_DISPLAY()                                                           \
  do {                                                                              \
    if (!std::getenv("DISPLAY"))                                                    \
      GTEST_SKIP() << "no display (DISPLAY unset); CTest runs this under xvfb-run"; \
  } while (0)

std::unique_ptr<Display> open_display(const std::string& out_dir, int w = 1280, int h = 800,
                                      int clip_frames = 150, double hud_refresh_s = 0.25,
                                      double panel_refresh_s = 0.1) {
  DisplayOptions o;
  o.width = w;
  o.height = h;
  o.screenshot_dir = out_dir;
  o.clip_max_frames = clip_frames;
  o.hud_refresh_s = hud_refresh_s;
  o.panel_refresh_s = panel_refresh_s;
  auto d = Display::create(o);
  EXPECT_TRUE(d) << d.error().message;
  return d ? std::move(*d) : nullptr;
}

// Presses (and releases) a key through the key callback GLFW holds for the window: ImGui's
// backend, which chains to the display's own.
void press(Display& d, int key, int mods = 0, int action = GLFW_PRESS) {
  GLFWwindow* w = d.window();
  const GLFWkeyfun cb = glfwSetKeyCallback(w, nullptr);
  glfwSetKeyCallback(w, cb);
  ASSERT_NE(cb, nullptr);
  cb(w, key, glfwGetKeyScancode(key), action, mods);
  if (action == GLFW_PRESS) cb(w, key, glfwGetKeyScancode(key), GLFW_RELEASE, mods);
}

void type_char(Display& d, unsigned int c) {
  GLFWwindow* w = d.window();
  const GLFWcharfun cb = glfwSetCharCallback(w, nullptr);
  glfwSetCharCallback(w, cb);
  ASSERT_NE(cb, nullptr);
  cb(w, c);
}

// Screenshot through the user's key (S), read back as RGB.
cv::Mat screenshot(Display& d, const DisplayInput& in, std::string* path_out = nullptr) {
  press(d, GLFW_KEY_S);
  EXPECT_TRUE(d.frame(in));
  const DisplayCommands c = d.poll_commands();
  EXPECT_EQ(c.screenshots.size(), 1u);
  if (c.screenshots.empty()) return {};
  if (path_out) *path_out = c.screenshots[0];
  const cv::Mat bgra = cv::imread(c.screenshots[0], cv::IMREAD_UNCHANGED);
  EXPECT_FALSE(bgra.empty()) << c.screenshots[0];
  if (bgra.empty()) return {};
  EXPECT_EQ(bgra.channels(), 4);
  cv::Mat rgb;
  cv::cvtColor(bgra, rgb, cv::COLOR_BGRA2RGB);
  return rgb;
}

// ---- Sampling ----------------------------------------------------------------------------------------

// Screenshot pixel showing image pixel (u, v) of a view.
cv::Point on_screen(const PixelRect& r, int W, int H, int u, int v) {
  return {static_cast<int>(r.x + (u + 0.5) * r.w / W), static_cast<int>(r.y + (v + 0.5) * r.h / H)};
}

// Up to ~`max_samples` pixels whose whole (2 radius + 1)^2 neighbourhood satisfies `pred`(mask value),
// so display scaling and filtering cannot mix in anything else.
template <typename Pred>
std::vector<cv::Point> interior(const Image& mask, Pred pred, int radius, int max_samples = 300) {
  cv::Mat in(mask.height(), mask.width(), CV_8UC1);
  for (int y = 0; y < mask.height(); ++y)
    for (int x = 0; x < mask.width(); ++x) in.at<std::uint8_t>(y, x) = pred(mask.row(y)[x]) ? 255 : 0;
  cv::Mat er;
  cv::erode(in, er, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * radius + 1, 2 * radius + 1)),
            {-1, -1}, 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  std::vector<cv::Point> all;
  cv::findNonZero(er, all);
  if (all.size() <= static_cast<std::size_t>(max_samples)) return all;
  std::vector<cv::Point> out;
  const double step = static_cast<double>(all.size()) / max_samples;
  for (int i = 0; i < max_samples; ++i) out.push_back(all[static_cast<std::size_t>(i * step)]);
  return out;
}

int radius_for(const PixelRect& r, int W) {
  return static_cast<int>(std::ceil(2.0 * W / r.w)) + 2;
}

cv::Vec3i rgb_at(const cv::Mat& shot, cv::Point p) {
  const cv::Vec3b v = shot.at<cv::Vec3b>(p);
  return {v[0], v[1], v[2]};
}
cv::Vec3i rgb_at(const Image& rgb8, cv::Point p) {
  const std::uint8_t* s = rgb8.row(p.y) + 3 * p.x;
  return {s[0], s[1], s[2]};
}
int max_diff(const cv::Vec3i& a, const cv::Vec3i& b) {
  return std::max({std::abs(a[0] - b[0]), std::abs(a[1] - b[1]), std::abs(a[2] - b[2])});
}

// Fraction of `samples` (image coordinates) where the screenshot shows `expected` within `tol`.
double agreement(const cv::Mat& shot, const PixelRect& r, const Image& expected,
                 const std::vector<cv::Point>& samples, int tol) {
  int ok = 0;
  for (const cv::Point& p : samples)
    ok += max_diff(rgb_at(shot, on_screen(r, expected.width(), expected.height(), p.x, p.y)),
                   rgb_at(expected, p)) <= tol;
  return samples.empty() ? 0.0 : static_cast<double>(ok) / samples.size();
}

// Standard deviation of the screenshot inside a rectangle (0 for a flat colour).
double spread(const cv::Mat& shot, const PixelRect& r) {
  cv::Scalar mean, sd;
  cv::meanStdDev(shot(cv::Rect(r.x, r.y, r.w, r.h)), mean, sd);
  return std::max({sd[0], sd[1], sd[2]});
}

void expect_inside(const PixelRect& r, int fbw, int fbh, const char* what) {
  EXPECT_FALSE(r.empty()) << what;
  EXPECT_GE(r.x, 0) << what;
  EXPECT_GE(r.y, 0) << what;
  EXPECT_LE(r.x + r.w, fbw) << what;
  EXPECT_LE(r.y + r.h, fbh) << what;
}

bool overlap(const PixelRect& a, const PixelRect& b) {
  return a.x < b.x + b.w && b.x < a.x + a.w && a.y < b.y + b.h && b.y < a.y + a.h;
}

// ---- Tests ---------------------------------------------------------------------------------------------

TEST(DisplayWindow, ScreenshotShowsBothViewsWithTheBoomWhereTheMasksSay) {
  REQUIRE_DISPLAY();
  const Augmented& a = augmented();
  ASSERT_TRUE(a.error.empty()) << a.error;
  const std::string out = test::output_dir("display_screenshot");
  auto d = open_display(out);
  ASSERT_TRUE(d);
  const DisplayInput in = input_for(a);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(d->frame(in));
  std::string path;
  const cv::Mat shot = screenshot(*d, in, &path);
  ASSERT_FALSE(shot.empty());
  EXPECT_EQ(fs::path(path).parent_path(), fs::path(out));

  // The PNG is the window's framebuffer, whole.
  int fbw = 0, fbh = 0;
  glfwGetFramebufferSize(d->window(), &fbw, &fbh);
  EXPECT_EQ(shot.cols, fbw);
  EXPECT_EQ(shot.rows, fbh);
  const DisplayLayout& L = d->layout();
  EXPECT_EQ(L.framebuffer_w, fbw);
  EXPECT_EQ(L.framebuffer_h, fbh);
  for (const PixelRect* r : {&L.views[0], &L.views[1], &L.world, &L.hud})
    expect_inside(*r, fbw, fbh, "layout");
  EXPECT_FALSE(overlap(L.views[0], L.views[1]));
  EXPECT_FALSE(overlap(L.views[0], L.hud));
  EXPECT_FALSE(overlap(L.views[1], L.world));
  EXPECT_TRUE(L.help.empty());

  const std::array<const ViewResult*, 2> views = {&a.result.left, &a.result.right};
  const std::array<const Frame*, 2> raws = {&a.raw.left, &a.raw.right};
  for (int i = 0; i < 2; ++i) {
    SCOPED_TRACE(i == 0 ? "left view" : "right view");
    const PixelRect& r = L.views[i];
    const Image& aug = views[i]->augmented;
    const Image& mask = views[i]->mask;
    // The aspect of the image is kept.
    EXPECT_NEAR(static_cast<double>(r.w) / r.h, static_cast<double>(aug.width()) / aug.height(), 0.01);
    EXPECT_GT(spread(shot, r), 5.0) << "the view is a flat colour";

    const int rad = radius_for(r, aug.width());
    const auto boom = interior(
        mask, [](std::uint8_t m) { return (m & kMaskBoom) != 0; }, rad);
    const auto clear = interior(
        mask, [](std::uint8_t m) { return m == 0; }, rad);
    ASSERT_GE(boom.size(), 50u) << "the scene must show the boom";
    ASSERT_GE(clear.size(), 50u);
    // Where the mask says boom, the window shows the augmented image's boom, not the raw image.
    EXPECT_GE(agreement(shot, r, aug, boom, 16), 0.95);
    EXPECT_LE(agreement(shot, r, raws[i]->image, boom, 30), 0.05)
        << "the boom is not visible where the mask says";
    // Where the mask says nothing, the raw image.
    EXPECT_GE(agreement(shot, r, raws[i]->image, clear, 12), 0.98);
  }

  // The world view shows something (tanker, boom, receiver, frusta, image quads over a sky).
  EXPECT_GT(spread(shot, L.world), 5.0);
  cv::Mat world = shot(cv::Rect(L.world.x, L.world.y, L.world.w, L.world.h)).clone();
  std::set<int> colours;
  for (int y = 0; y < world.rows; y += 2)
    for (int x = 0; x < world.cols; x += 2) {
      const cv::Vec3b v = world.at<cv::Vec3b>(y, x);
      colours.insert((v[0] >> 3) << 10 | (v[1] >> 3) << 5 | (v[2] >> 3));
    }
  EXPECT_GT(colours.size(), 30u);

  // F1: the help overlay appears over the window and changes what its rectangle shows.
  press(*d, GLFW_KEY_F1);
  EXPECT_TRUE(d->help_visible());
  const cv::Mat with_help = screenshot(*d, in);
  ASSERT_FALSE(with_help.empty());
  const PixelRect h = d->layout().help;
  ASSERT_FALSE(h.empty());
  expect_inside(h, fbw, fbh, "help");
  cv::Mat diff;
  cv::absdiff(shot(cv::Rect(h.x, h.y, h.w, h.h)), with_help(cv::Rect(h.x, h.y, h.w, h.h)), diff);
  cv::Mat grey;
  cv::cvtColor(diff, grey, cv::COLOR_RGB2GRAY);
  EXPECT_GT(cv::countNonZero(grey > 8), h.w * h.h / 3);
  press(*d, GLFW_KEY_ESCAPE);
  EXPECT_FALSE(d->help_visible());
}

TEST(DisplayWindow, MaskOverlaysUseThePapersColours) {
  REQUIRE_DISPLAY();
  const Augmented& a = augmented();
  ASSERT_TRUE(a.error.empty()) << a.error;
  auto d = open_display(test::output_dir("display_overlay"));
  ASSERT_TRUE(d);
  const DisplayInput in = input_for(a);
  ASSERT_TRUE(d->frame(in));
  const std::array<const ViewResult*, 2> views = {&a.result.left, &a.result.right};

  // M: Fig. 8 (receiver red, boom cyan / blue, boom over receiver white / magenta) over each view.
  press(*d, GLFW_KEY_M);
  EXPECT_EQ(d->mask_overlay(), MaskOverlay::kOcclusion);
  EXPECT_EQ(d->poll_commands().mask_overlay, MaskOverlay::kOcclusion);
  cv::Mat shot = screenshot(*d, in);
  ASSERT_FALSE(shot.empty());
  for (int i = 0; i < 2; ++i) {
    SCOPED_TRACE(i == 0 ? "left view, Fig. 8" : "right view, Fig. 8");
    const Image& mask = views[i]->mask;
    const Image oracle = blend_over(views[i]->augmented, visualize_receiver_occlusion(mask, i == 0));
    const PixelRect& r = d->layout().views[i];
    int classes = 0;
    for (int c = 0; c < 4; ++c) {
      const auto pts = interior(
          mask, [c](std::uint8_t m) { return (m & 3) == c; }, radius_for(r, mask.width()));
      if (pts.size() < 20) continue;
      ++classes;
      EXPECT_GE(agreement(shot, r, oracle, pts, 16), 0.95) << "mask class " << c;
    }
    EXPECT_GE(classes, 3) << "nothing, boom and receiver must all be sampled";
  }

  // M again: Fig. 7b (boom left cyan, right blue, both green) over both views.
  press(*d, GLFW_KEY_M);
  EXPECT_EQ(d->mask_overlay(), MaskOverlay::kBoomOverlap);
  shot = screenshot(*d, in);
  ASSERT_FALSE(shot.empty());
  const Image vis = visualize_boom_overlap(a.result.left.mask, a.result.right.mask);
  for (int i = 0; i < 2; ++i) {
    SCOPED_TRACE(i == 0 ? "left view, Fig. 7b" : "right view, Fig. 7b");
    const Image oracle = blend_over(views[i]->augmented, vis);
    const PixelRect& r = d->layout().views[i];
    int classes = 0;
    for (int c = 0; c < 4; ++c) {
      auto idx = [&](int x, int y) {
        return (a.result.left.mask.row(y)[x] & kMaskBoom) |
               ((a.result.right.mask.row(y)[x] & kMaskBoom) << 1);
      };
      Image cls(vis.width(), vis.height(), PixelFormat::kMono8);
      for (int y = 0; y < cls.height(); ++y)
        for (int x = 0; x < cls.width(); ++x) cls.row(y)[x] = static_cast<std::uint8_t>(idx(x, y));
      const auto pts = interior(
          cls, [c](std::uint8_t m) { return m == c; }, radius_for(r, cls.width()));
      if (pts.size() < 20) continue;
      ++classes;
      EXPECT_GE(agreement(shot, r, oracle, pts, 16), 0.95) << "overlap class " << c;
    }
    EXPECT_GE(classes, 3) << "none, left-only or right-only, and both must be sampled";
  }

  // M a third time: off, the plain augmented image again.
  press(*d, GLFW_KEY_M);
  EXPECT_EQ(d->mask_overlay(), MaskOverlay::kOff);
  shot = screenshot(*d, in);
  ASSERT_FALSE(shot.empty());
  const PixelRect& r = d->layout().views[0];
  const auto all = interior(
      a.result.left.mask, [](std::uint8_t) { return true; }, radius_for(r, 1280));
  EXPECT_GE(agreement(shot, r, a.result.left.augmented, all, 16), 0.95);
}

TEST(DisplayWindow, ValidationOverlayDrawsTheReceiverWhereTheMasksPutIt) {
  REQUIRE_DISPLAY();
  const Augmented& a = augmented();
  ASSERT_TRUE(a.error.empty()) << a.error;
  auto d = open_display(test::output_dir("display_validation"));
  ASSERT_TRUE(d);
  DisplayInput in = input_for(a);
  in.validation_T_body_receiver = a.scene.T_body_receiver;  // the pose the masks were made with
  ASSERT_TRUE(d->frame(in));
  const cv::Mat before = screenshot(*d, in);
  press(*d, GLFW_KEY_V);
  EXPECT_TRUE(d->validation_overlay());
  const cv::Mat after = screenshot(*d, in);
  ASSERT_FALSE(before.empty());
  ASSERT_FALSE(after.empty());
  for (int i = 0; i < 2; ++i) {
    SCOPED_TRACE(i == 0 ? "left view" : "right view");
    const ViewResult& v = i == 0 ? a.result.left : a.result.right;
    const PixelRect& r = d->layout().views[i];
    // The receiver's silhouette, grown by the display's scaling, in image coordinates.
    cv::Mat recv(v.mask.height(), v.mask.width(), CV_8UC1);
    for (int y = 0; y < recv.rows; ++y)
      for (int x = 0; x < recv.cols; ++x)
        recv.at<std::uint8_t>(y, x) = (v.mask.row(y)[x] & kMaskReceiver) ? 255 : 0;
    const int grow = radius_for(r, recv.cols);
    cv::dilate(recv, recv, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * grow + 1, 2 * grow + 1)));
    int changed = 0, on_receiver = 0;
    for (int y = r.y; y < r.y + r.h; ++y)
      for (int x = r.x; x < r.x + r.w; ++x) {
        if (max_diff(rgb_at(before, {x, y}), rgb_at(after, {x, y})) <= 30) continue;
        ++changed;
        const int u = std::clamp(static_cast<int>((x + 0.5 - r.x) * recv.cols / r.w), 0, recv.cols - 1);
        const int vv = std::clamp(static_cast<int>((y + 0.5 - r.y) * recv.rows / r.h), 0, recv.rows - 1);
        on_receiver += recv.at<std::uint8_t>(vv, u) != 0;
      }
    EXPECT_GT(changed, 500) << "the wireframe must be visible";
    EXPECT_GE(on_receiver, changed * 0.98) << "the wireframe lies off the receiver: " << changed - on_receiver
                                           << " of " << changed << " changed pixels";
  }
  // Off again.
  press(*d, GLFW_KEY_V);
  EXPECT_FALSE(d->validation_overlay());
}

TEST(DisplayWindow, KeysProduceCommands) {
  REQUIRE_DISPLAY();
  const std::string out = test::output_dir("display_keys");
  auto d = open_display(out, 1280, 800, /*clip_frames=*/2);
  ASSERT_TRUE(d);
  DisplayInput in;  // no frame yet: the window still runs
  in.hud.boom_mode = DisplayBoomMode::kFixed;
  ASSERT_TRUE(d->frame(in));
  EXPECT_FALSE(d->poll_commands().boom_mode);

  const std::pair<int, DisplayBoomMode> modes[] = {{GLFW_KEY_1, DisplayBoomMode::kFixed},
                                                   {GLFW_KEY_2, DisplayBoomMode::kScripted},
                                                   {GLFW_KEY_3, DisplayBoomMode::kTrackReceptacle},
                                                   {GLFW_KEY_4, DisplayBoomMode::kInteractive}};
  for (const auto& [key, mode] : modes) {
    press(*d, key);
    EXPECT_EQ(d->poll_commands().boom_mode, mode) << to_string(mode);
  }

  // Arrows move the boom as seen in the views; a nudge in a non-interactive mode takes it over.
  press(*d, GLFW_KEY_UP);
  press(*d, GLFW_KEY_DOWN, GLFW_MOD_SHIFT);
  press(*d, GLFW_KEY_DOWN, 0, GLFW_REPEAT);  // held down: repeats
  press(*d, GLFW_KEY_LEFT);
  press(*d, GLFW_KEY_PAGE_UP);
  press(*d, GLFW_KEY_PAGE_UP);
  press(*d, GLFW_KEY_PAGE_DOWN, GLFW_MOD_SHIFT);
  DisplayCommands c = d->poll_commands();
  EXPECT_NEAR(c.boom_nudge.elevation_rad, deg_to_rad(-0.5 + 2.5 + 0.5), 1e-12);
  EXPECT_NEAR(c.boom_nudge.azimuth_rad, deg_to_rad(0.5), 1e-12);
  EXPECT_NEAR(c.boom_nudge.extension_m, 0.1 + 0.1 - 0.5, 1e-12);
  EXPECT_EQ(c.boom_mode, DisplayBoomMode::kInteractive);
  press(*d, GLFW_KEY_RIGHT);
  EXPECT_NEAR(d->poll_commands().boom_nudge.azimuth_rad, deg_to_rad(-0.5), 1e-12);
  // Already interactive: a nudge changes no mode.
  in.hud.boom_mode = DisplayBoomMode::kInteractive;
  ASSERT_TRUE(d->frame(in));
  press(*d, GLFW_KEY_UP);
  c = d->poll_commands();
  EXPECT_TRUE(c.boom_nudge.any());
  EXPECT_FALSE(c.boom_mode);

  // Recording and pause are the owner's: toggles. A held key does not repeat them.
  press(*d, GLFW_KEY_R);
  press(*d, GLFW_KEY_SPACE);
  press(*d, GLFW_KEY_R, 0, GLFW_REPEAT);
  c = d->poll_commands();
  EXPECT_TRUE(c.toggle_recording);
  EXPECT_TRUE(c.toggle_pause);
  EXPECT_FALSE(c.quit);
  EXPECT_FALSE(d->poll_commands().toggle_recording) << "polling clears the commands";

  // Overlays and help are the display's own.
  press(*d, GLFW_KEY_M);
  EXPECT_EQ(d->mask_overlay(), MaskOverlay::kOcclusion);
  press(*d, GLFW_KEY_V);
  EXPECT_TRUE(d->validation_overlay());
  press(*d, GLFW_KEY_F1);
  EXPECT_TRUE(d->help_visible());
  type_char(*d, '?');
  EXPECT_FALSE(d->help_visible());
  press(*d, GLFW_KEY_H);
  EXPECT_TRUE(d->help_visible());
  ASSERT_TRUE(d->frame(in));
  EXPECT_FALSE(d->layout().help.empty());
  press(*d, GLFW_KEY_ESCAPE);
  ASSERT_TRUE(d->frame(in));
  EXPECT_TRUE(d->layout().help.empty());

  // A clip: numbered PNGs of the window, ending by itself after clip_max_frames.
  d->poll_commands();
  press(*d, GLFW_KEY_C);
  c = d->poll_commands();
  ASSERT_TRUE(c.clip_started);
  EXPECT_TRUE(d->clip_recording());
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(d->frame(in));
  c = d->poll_commands();
  ASSERT_TRUE(c.clip_stopped);
  EXPECT_FALSE(d->clip_recording());
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(*c.clip_stopped)) files.push_back(e.path().filename().string());
  std::sort(files.begin(), files.end());
  EXPECT_EQ(files, (std::vector<std::string>{"frame_00000.png", "frame_00001.png"}));
  const cv::Mat f0 = cv::imread(*c.clip_stopped + "/frame_00000.png", cv::IMREAD_UNCHANGED);
  EXPECT_EQ(f0.cols, d->layout().framebuffer_w);
  EXPECT_EQ(f0.rows, d->layout().framebuffer_h);
  // C stops a clip early, too.
  press(*d, GLFW_KEY_C);
  ASSERT_TRUE(d->frame(in));
  press(*d, GLFW_KEY_C);
  c = d->poll_commands();
  ASSERT_TRUE(c.clip_started);
  ASSERT_TRUE(c.clip_stopped);
  EXPECT_EQ(*c.clip_started, *c.clip_stopped);

  // F12 is a screenshot too.
  press(*d, GLFW_KEY_F12);
  ASSERT_TRUE(d->frame(in));
  c = d->poll_commands();
  ASSERT_EQ(c.screenshots.size(), 1u);
  EXPECT_TRUE(fs::exists(c.screenshots[0]));

  // Q quits: a command, and frame() returns false from then on.
  press(*d, GLFW_KEY_Q);
  EXPECT_TRUE(d->poll_commands().quit);
  EXPECT_FALSE(d->frame(in));
  EXPECT_FALSE(d->frame(in));
}

TEST(DisplayWindow, ClosedWindowMakesFrameReturnFalse) {
  REQUIRE_DISPLAY();
  auto d = open_display(test::output_dir("display_close"), 640, 480);
  ASSERT_TRUE(d);
  const DisplayInput in;
  ASSERT_TRUE(d->frame(in));
  EXPECT_FALSE(d->poll_commands().quit);
  glfwSetWindowShouldClose(d->window(), GLFW_TRUE);  // what the window manager's close button does
  EXPECT_FALSE(d->frame(in));
  EXPECT_TRUE(d->poll_commands().quit);
}

TEST(DisplayWindow, ResizedWindowReflowsAndScreenshotsFollow) {
  REQUIRE_DISPLAY();
  const Augmented& a = augmented();
  ASSERT_TRUE(a.error.empty()) << a.error;
  auto d = open_display(test::output_dir("display_resize"), 1280, 800);
  ASSERT_TRUE(d);
  const DisplayInput in = input_for(a);
  ASSERT_TRUE(d->frame(in));
  glfwSetWindowSize(d->window(), 960, 720);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(d->frame(in));
  int fbw = 0, fbh = 0;
  glfwGetFramebufferSize(d->window(), &fbw, &fbh);
  const DisplayLayout& L = d->layout();
  EXPECT_EQ(L.framebuffer_w, fbw);
  EXPECT_EQ(L.framebuffer_h, fbh);
  int ww = 0, wh = 0;
  glfwGetWindowSize(d->window(), &ww, &wh);
  EXPECT_EQ(ww, 960);
  EXPECT_EQ(wh, 720);
  for (const PixelRect* r : {&L.views[0], &L.views[1], &L.world, &L.hud})
    expect_inside(*r, fbw, fbh, "layout");
  EXPECT_NEAR(static_cast<double>(L.views[0].w) / L.views[0].h, 4.0 / 3.0, 0.01);
  const cv::Mat shot = screenshot(*d, in);
  ASSERT_FALSE(shot.empty());
  EXPECT_EQ(shot.cols, fbw);
  EXPECT_EQ(shot.rows, fbh);
  EXPECT_GT(spread(shot, L.views[0]), 5.0);
}

// The display redraws only when something changed, and then once per call: a new frame, an
// input, an overlay, a screenshot; the same frame again costs no redraw.
TEST(DisplayWindow, RedrawsOnlyWhenSomethingChanged) {
  REQUIRE_DISPLAY();
  const Augmented& a = augmented();
  ASSERT_TRUE(a.error.empty()) << a.error;
  auto d = open_display(test::output_dir("display_redraw"), 960, 600, 150, /*hud_refresh_s=*/3600.0);
  ASSERT_TRUE(d);
  const DisplayInput first = input_for(a, 1);
  for (int i = 0; i < 8; ++i) ASSERT_TRUE(d->frame(first));  // the start-up frames settle
  const std::uint64_t settled = d->frames_drawn();
  EXPECT_GE(settled, 1u);
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(d->frame(first));
  EXPECT_EQ(d->frames_drawn(), settled) << "the same frame again must not redraw";

  ASSERT_TRUE(d->frame(input_for(a, 2)));
  EXPECT_EQ(d->frames_drawn(), settled + 1) << "a new frame redraws";
  ASSERT_TRUE(d->frame(input_for(a, 2)));
  EXPECT_EQ(d->frames_drawn(), settled + 1);

  d->set_mask_overlay(MaskOverlay::kOcclusion);
  ASSERT_TRUE(d->frame(input_for(a, 2)));
  EXPECT_GT(d->frames_drawn(), settled + 1) << "an overlay change redraws";
  for (int i = 0; i < 8; ++i) ASSERT_TRUE(d->frame(input_for(a, 2)));
  const std::uint64_t n = d->frames_drawn();
  press(*d, GLFW_KEY_S);
  ASSERT_TRUE(d->frame(input_for(a, 2)));
  EXPECT_GT(d->frames_drawn(), n) << "a screenshot draws the window it saves";
  EXPECT_EQ(d->poll_commands().screenshots.size(), 1u);
}

// The status panel is drawn anew when due, on input and for a screenshot; a new frame alone copies
// its last drawing (what it shows then is checked by the screenshot tests above).
TEST(DisplayWindow, TheStatusPanelIsDrawnAnewOnlyWhenDue) {
  REQUIRE_DISPLAY();
  const Augmented& a = augmented();
  ASSERT_TRUE(a.error.empty()) << a.error;
  auto d = open_display(test::output_dir("display_panel"), 960, 600, 150, /*hud_refresh_s=*/3600.0,
                        /*panel_refresh_s=*/3600.0);
  ASSERT_TRUE(d);
  for (int i = 0; i < 8; ++i) ASSERT_TRUE(d->frame(input_for(a, 1)));  // the start-up frames settle
  const std::uint64_t drawn = d->frames_drawn(), panel = d->panel_draws();
  EXPECT_GE(panel, 1u) << "the first redraw draws the panel";
  for (std::uint64_t id = 2; id < 6; ++id) ASSERT_TRUE(d->frame(input_for(a, id)));
  EXPECT_EQ(d->frames_drawn(), drawn + 4) << "each new frame redraws the window";
  EXPECT_EQ(d->panel_draws(), panel) << "and copies the panel";

  press(*d, GLFW_KEY_LEFT_SHIFT);  // any input
  ASSERT_TRUE(d->frame(input_for(a, 6)));
  EXPECT_EQ(d->panel_draws(), panel + 1) << "input draws the panel at once";

  for (int i = 0; i < 8; ++i) ASSERT_TRUE(d->frame(input_for(a, 6)));  // ImGui settles after input
  const std::uint64_t settled = d->panel_draws();
  d->request_screenshot();
  ASSERT_TRUE(d->frame(input_for(a, 6)));
  EXPECT_EQ(d->panel_draws(), settled + 1) << "a screenshot saves the panel as it is now";
  EXPECT_EQ(d->poll_commands().screenshots.size(), 1u);

  // Due every time: each redraw draws it.
  d.reset();
  auto every =
      open_display(test::output_dir("display_panel"), 960, 600, 150, 3600.0, /*panel_refresh_s=*/0.0);
  ASSERT_TRUE(every);
  for (std::uint64_t id = 1; id < 6; ++id) ASSERT_TRUE(every->frame(input_for(a, id)));
  EXPECT_EQ(every->panel_draws(), every->frames_drawn());
}

// ---- The views' composition at about their size on screen (no window needed) -------------------

// A deterministic, busy image of any format: every site a different-looking value.
Image busy_image(int w, int h, PixelFormat f, int seed) {
  Image im(w, h, f);
  const int bpp = bytes_per_pixel(f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w * bpp; ++x)
      im.row(y)[x] = static_cast<std::uint8_t>((x * 37 + y * 91 + seed * 13 + (x * y) % 29) & 255);
  return im;
}

// Masks with every class, including a boom one pixel wide (column `thin_x`) that a decimation
// must not lose.
Image busy_mask(int w, int h, int seed, int thin_x) {
  Image m(w, h, PixelFormat::kMono8);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint8_t v = ((x + 2 * y + seed) % 11 < 3) ? kMaskBoom : 0;
      if ((x / 5 + y / 4 + seed) % 3 == 0) v |= kMaskReceiver;
      if (x == thin_x) v |= kMaskBoom;
      // The boom's shadow on the receiver where the boom does not hide it (mask value 6).
      if (v == kMaskReceiver && (x / 3 + y / 2 + seed) % 2 == 0) v |= kMaskShadow;
      if (y < 3 && x != thin_x) v = 0;  // the top rows: the thin boom alone
      m.row(y)[x] = v;
    }
  return m;
}

// The straightforward reference: per texel, the block [f ox, f ox + f) x [f oy, f oy + f) cut to
// the image; its colour the mean of each channel's samples (Bayer: sites in whole 2x2 cells, the
// last whole cell for a half one; factor 1 or odd: to_rgb8() first), rounded to nearest; its mask
// class the OR over the block; its overlay colour blend_over() of render/visualize's colour for
// that class over the mean, computed on 1x1 images.
std::vector<std::uint8_t> reference_compose(const Image& im, MaskOverlay overlay, int view,
                                            const std::array<const Image*, 2>& masks, int f) {
  const int w = im.width(), h = im.height();
  const int ow = (w + f - 1) / f, oh = (h + f - 1) / f;
  const bool cells = is_bayer(im.format()) && f % 2 == 0;
  const Image rgb = cells ? Image() : to_rgb8(im);
  std::vector<std::uint8_t> out(static_cast<std::size_t>(ow) * oh * 4);
  for (int oy = 0; oy < oh; ++oy)
    for (int ox = 0; ox < ow; ++ox) {
      double sum[3] = {0, 0, 0};
      int n[3] = {0, 0, 0};
      if (cells) {
        const int we = w / 2 * 2, he = h / 2 * 2;
        int x0 = ox * f, y0 = oy * f;
        int x1 = std::min(x0 + f, we), y1 = std::min(y0 + f, he);
        if (x0 >= we) x0 = we - 2, x1 = we;
        if (y0 >= he) y0 = he - 2, y1 = he;
        for (int y = y0; y < y1; ++y)
          for (int x = x0; x < x1; ++x) {
            const int c = bayer_channel(im.format(), x, y);
            sum[c] += im.row(y)[x];
            ++n[c];
          }
      } else {
        for (int y = oy * f; y < std::min(oy * f + f, h); ++y)
          for (int x = ox * f; x < std::min(ox * f + f, w); ++x)
            for (int c = 0; c < 3; ++c) sum[c] += rgb.row(y)[3 * x + c], ++n[c];
      }
      Image px(1, 1, PixelFormat::kRGB8);
      for (int c = 0; c < 3; ++c) px.row(0)[c] = static_cast<std::uint8_t>(std::floor(sum[c] / n[c] + 0.5));
      std::array<std::uint8_t, 2> ors = {0, 0};
      for (int k = 0; k < 2; ++k)
        if (masks[k])
          for (int y = oy * f; y < std::min(oy * f + f, h); ++y)
            for (int x = ox * f; x < std::min(ox * f + f, w); ++x) ors[k] |= masks[k]->row(y)[x];
      auto one = [](std::uint8_t v) {
        Image m(1, 1, PixelFormat::kMono8);
        m.row(0)[0] = v;
        return m;
      };
      if (overlay == MaskOverlay::kOcclusion)
        px = blend_over(px, visualize_receiver_occlusion(one(ors[view]), view == 0));
      else if (overlay == MaskOverlay::kBoomOverlap)
        px = blend_over(px, visualize_boom_overlap(one(ors[0]), one(ors[1])));
      std::uint8_t* d = out.data() + (static_cast<std::size_t>(oy) * ow + ox) * 4;
      for (int c = 0; c < 3; ++c) d[c] = px.row(0)[c];
      d[3] = 255;
    }
  return out;
}

TEST(DisplayCompose, MatchesAStraightforwardReferenceForEveryFormatSizeAndOverlay) {
  struct Case {
    PixelFormat format;
    int w, h, f;
  };
  const std::vector<Case> cases = {
      {PixelFormat::kBayerRG8, 64, 48, 2},  {PixelFormat::kBayerRG8, 37, 23, 2},   // odd sizes: half cells
      {PixelFormat::kBayerBG8, 50, 30, 4},  {PixelFormat::kBayerGR8, 45, 31, 4},   // not multiples of f
      {PixelFormat::kBayerGB8, 38, 26, 6},  {PixelFormat::kBayerRG8, 30, 22, 1},   // factor 1: demosaiced
      {PixelFormat::kBayerRG8, 31, 20, 3},  {PixelFormat::kRGB8, 41, 29, 3},       // odd factor: demosaiced first
      {PixelFormat::kRGB8, 40, 30, 1},      {PixelFormat::kRGBA8, 33, 17, 2},
      {PixelFormat::kMono8, 35, 27, 2},     {PixelFormat::kBayerRG8, 2, 2, 2},
      {PixelFormat::kBayerRG8, 3, 3, 2},    {PixelFormat::kBayerRG8, 7, 5, 8},     // one texel, larger than the image
  };
  for (const Case& c : cases) {
    const Image im = busy_image(c.w, c.h, c.format, c.w);
    const Image ml = busy_mask(c.w, c.h, 0, c.w / 2 | 1), mr = busy_mask(c.w, c.h, 4, c.w / 3);
    const std::array<const Image*, 2> masks = {&ml, &mr};
    for (MaskOverlay ov : {MaskOverlay::kOff, MaskOverlay::kOcclusion, MaskOverlay::kBoomOverlap})
      for (int view : {0, 1}) {
        SCOPED_TRACE(std::string(to_string(c.format)) + " " + std::to_string(c.w) + "x" + std::to_string(c.h) +
                     " / " + std::to_string(c.f) + ", " + std::string(to_string(ov)) + ", view " +
                     std::to_string(view));
        std::vector<std::uint8_t> got;
        int ow = 0, oh = 0;
        compose_view_rgba(im, ov, view, masks, c.f, got, ow, oh);
        EXPECT_EQ(ow, (c.w + c.f - 1) / c.f);
        EXPECT_EQ(oh, (c.h + c.f - 1) / c.f);
        const std::vector<std::uint8_t> want = reference_compose(im, ov, view, masks, c.f);
        ASSERT_EQ(got.size(), want.size());
        std::size_t bad = 0, first = got.size();
        for (std::size_t k = 0; k < got.size(); ++k)
          if (got[k] != want[k]) ++bad, first = std::min(first, k);
        EXPECT_EQ(bad, 0u) << "first at texel " << first / 4 << " (" << (first / 4) % std::max(ow, 1) << ", "
                           << (first / 4) / std::max(ow, 1) << ") channel " << first % 4 << ": "
                           << int(got[first]) << " vs " << int(want[first]);
        // The window's order: the same texels with red and blue swapped, from every path.
        std::vector<std::uint8_t> bgra;
        compose_view_rgba(im, ov, view, masks, c.f, bgra, ow, oh, TexelOrder::kBgra);
        ASSERT_EQ(bgra.size(), got.size());
        std::size_t bad_bgra = 0;
        for (std::size_t k = 0; k < got.size(); k += 4)
          if (bgra[k] != got[k + 2] || bgra[k + 1] != got[k + 1] || bgra[k + 2] != got[k] ||
              bgra[k + 3] != got[k + 3])
            ++bad_bgra;
        EXPECT_EQ(bad_bgra, 0u) << "BGRA texels unlike the RGBA ones swapped";
      }
  }
}

// Factor 1 is the full image as before: Bayer demosaiced by to_rgb8(), the overlay exactly
// blend_over() of the visualisation (what a PNG of it holds).
TEST(DisplayCompose, FactorOneIsBlendOverOfTheFullImage) {
  const Image im = busy_image(64, 48, PixelFormat::kBayerRG8, 3);
  const Image m = busy_mask(64, 48, 1, 9);
  std::vector<std::uint8_t> got;
  int ow = 0, oh = 0;
  compose_view_rgba(im, MaskOverlay::kOcclusion, 1, {&m, &m}, 1, got, ow, oh);
  const Image want = blend_over(im, visualize_receiver_occlusion(m, false));
  ASSERT_EQ(ow, 64);
  ASSERT_EQ(oh, 48);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x)
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(got[(static_cast<std::size_t>(y) * 64 + x) * 4 + c], want.row(y)[3 * x + c]) << x << "," << y;
}

// A boom one pixel thin still shows at half and quarter size: every block it crosses is boom.
TEST(DisplayCompose, AThinBoomSurvivesDecimation) {
  const Image im(64, 48, PixelFormat::kBayerRG8);  // black
  Image m(64, 48, PixelFormat::kMono8);
  for (int y = 0; y < 48; ++y) m.row(y)[13] = kMaskBoom;  // one column
  for (int f : {2, 4}) {
    std::vector<std::uint8_t> got;
    int ow = 0, oh = 0;
    compose_view_rgba(im, MaskOverlay::kOcclusion, 0, {&m, nullptr}, f, got, ow, oh);
    for (int oy = 0; oy < oh; ++oy)
      for (int ox = 0; ox < ow; ++ox) {
        const std::uint8_t* p = got.data() + (static_cast<std::size_t>(oy) * ow + ox) * 4;
        const bool coloured = p[0] || p[1] || p[2];
        EXPECT_EQ(coloured, ox == 13 / f) << "factor " << f << " texel " << ox << "," << oy;
      }
  }
  // Without the masks an overlay cannot be drawn: the plain image.
  std::vector<std::uint8_t> got;
  int ow = 0, oh = 0;
  compose_view_rgba(im, MaskOverlay::kBoomOverlap, 0, {&m, nullptr}, 2, got, ow, oh);
  for (std::size_t k = 0; k < got.size(); ++k) EXPECT_EQ(got[k], k % 4 == 3 ? 255 : 0) << k;
}

TEST(DisplayCompose, DecimationFollowsTheSizeShown) {
  // The live window: 1280x960 Bayer in a 1600x1000 window's 767x575 view: 2x2 cells binned.
  EXPECT_EQ(view_decimation(1280, 960, PixelFormat::kBayerRG8, 767, 575), 2);
  EXPECT_EQ(view_decimation(1280, 960, PixelFormat::kBayerRG8, 599, 449), 2);
  EXPECT_EQ(view_decimation(1280, 960, PixelFormat::kBayerRG8, 400, 300), 4);  // 3 for Bayer: whole cells
  EXPECT_EQ(view_decimation(1280, 960, PixelFormat::kRGB8, 400, 300), 3);
  EXPECT_EQ(view_decimation(1280, 960, PixelFormat::kBayerRG8, 1000, 750), 1);  // near full size: demosaiced
  EXPECT_EQ(view_decimation(1280, 960, PixelFormat::kRGB8, 2400, 1800), 1);
  EXPECT_EQ(view_decimation(1280, 960, PixelFormat::kMono8, 160, 120), 8);
  EXPECT_EQ(view_decimation(1280, 960, PixelFormat::kRGB8, 0, 0), 1);
}

TEST(DisplayCompose, ViewsArePixelExactWhenThatFillsTheCell) {
  // The 1600x1000 window's cell (776x569): 1280x960 Bayer halved, each texel one screen pixel.
  ViewScale s = view_scale(1280, 960, PixelFormat::kBayerRG8, 776, 569);
  EXPECT_TRUE(s.exact);
  EXPECT_EQ(s.factor, 2);
  EXPECT_EQ(s.zoom, 1);
  EXPECT_EQ(s.w, 640);
  EXPECT_EQ(s.h, 480);
  // A small camera zoomed by whole screen pixels: 160x120 in that cell, 4x.
  s = view_scale(160, 120, PixelFormat::kBayerRG8, 776, 569);
  EXPECT_TRUE(s.exact);
  EXPECT_EQ(s.factor, 1);
  EXPECT_EQ(s.zoom, 4);
  EXPECT_EQ(s.w, 640);
  // Full size where it fits (a large monitor), Bayer or not.
  s = view_scale(1280, 960, PixelFormat::kBayerRG8, 1300, 1000);
  EXPECT_TRUE(s.exact);
  EXPECT_EQ(s.factor, 1);
  EXPECT_EQ(s.w, 1280);
  // Bayer needs whole 2x2 cells: 1280x960 in 420x320 is reduced by 4 (not 3), 320x240, too small
  // against the 420-wide fit: shown fitted, bilinear, at view_decimation()'s factor.
  s = view_scale(1280, 960, PixelFormat::kBayerRG8, 420, 320);
  EXPECT_FALSE(s.exact);
  EXPECT_EQ(s.w, 420);
  EXPECT_EQ(s.h, 315);
  EXPECT_EQ(s.factor, view_decimation(1280, 960, PixelFormat::kBayerRG8, 420, 315));
  // The same cell for RGB: reduced by 3 (427x320 does not fit; 4: 320x240) -> fitted too; a
  // 1270-wide cell would show a 1280-wide image at 640: fitted, not halved.
  s = view_scale(1280, 960, PixelFormat::kRGB8, 1270, 1000);
  EXPECT_FALSE(s.exact);
  EXPECT_EQ(s.w, 1270);
  // Odd sizes: the partial last block is a texel of its own.
  s = view_scale(1281, 961, PixelFormat::kMono8, 700, 500);
  EXPECT_TRUE(s.exact);
  EXPECT_EQ(s.factor, 2);
  EXPECT_EQ(s.w, 641);
  EXPECT_EQ(s.h, 481);
  // Nothing to show.
  EXPECT_EQ(view_scale(0, 0, PixelFormat::kMono8, 700, 500).w, 0);
  EXPECT_EQ(view_scale(640, 480, PixelFormat::kMono8, 0, 500).w, 0);
}

// Without a display the window cannot open: a clear error, no crash.
TEST(DisplayHeadless, CreateWithoutADisplayFailsWithAClearMessage) {
  if (std::getenv("DISPLAY") || std::getenv("WAYLAND_DISPLAY")) GTEST_SKIP() << "a display is present";
  auto d = Display::create();
  ASSERT_FALSE(d);
  EXPECT_NE(d.error().message.find("app::Display::create()"), std::string::npos) << d.error().message;
  EXPECT_NE(d.error().message.find("xvfb-run"), std::string::npos) << d.error().message;
}

// docs/DISPLAY.md lists every shortcut the help overlay lists.
TEST(DisplayHeadless, DocsListEveryShortcut) {
  std::ifstream f(test::data_path("../../docs/DISPLAY.md"));
  ASSERT_TRUE(f) << "docs/DISPLAY.md";
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string doc = ss.str();
  for (const Shortcut& s : display_shortcuts()) {
    EXPECT_NE(doc.find(std::string("| ") + s.keys + " |"), std::string::npos) << s.keys;
    EXPECT_NE(doc.find(s.action), std::string::npos) << s.action;
  }
}

}  // namespace
}  // namespace augrig::app
