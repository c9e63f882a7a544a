#include "tests/support/window_shot.hpp"

#include <cstdio>
#include <regex>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/image.hpp"

namespace augrig::test {

std::optional<WindowShot> parse_window_shot(const std::string& log) {
  static const std::regex re(
      R"(screenshot (\S+) \(framebuffer (\d+)x(\d+); left view (\d+),(\d+),(\d+),(\d+); right view (\d+),(\d+),(\d+),(\d+); hud (\d+),(\d+),(\d+),(\d+); pair (\d+)\))");
  std::smatch m;
  if (!std::regex_search(log, m, re)) return std::nullopt;
  WindowShot s;
  s.path = m[1];
  s.width = std::stoi(m[2]);
  s.height = std::stoi(m[3]);
  Rect* rects[3] = {&s.views[0], &s.views[1], &s.hud};
  for (int i = 0; i < 3; ++i)
    *rects[i] = {std::stoi(m[4 + 4 * i]), std::stoi(m[5 + 4 * i]), std::stoi(m[6 + 4 * i]),
                 std::stoi(m[7 + 4 * i])};
  s.pair = std::stoull(m[16]);
  return s;
}

namespace {

// The raw image's colour at (u, v) as the window shows it (RGB; Bayer and mono as gray levels are
// not compared: the caller passes RGB8 frames).
cv::Vec3b raw_rgb(const Image& im, int u, int v) {
  const std::uint8_t* p = im.row(v) + static_cast<std::size_t>(u) * bytes_per_pixel(im.format());
  if (im.format() == PixelFormat::kMono8) return {p[0], p[0], p[0]};
  return {p[0], p[1], p[2]};
}

}  // namespace

void check_window_shot(const WindowShot& shot, const recorder::FrameRecord& frame) {
  const cv::Mat bgr = cv::imread(shot.path, cv::IMREAD_COLOR);
  ASSERT_FALSE(bgr.empty()) << shot.path;
  EXPECT_EQ(bgr.cols, shot.width);
  EXPECT_EQ(bgr.rows, shot.height);
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  for (int c = 0; c < 2; ++c) {
    SCOPED_TRACE(c == 0 ? "left view" : "right view");
    const Image& raw = c == 0 ? frame.raw.left.image : frame.raw.right.image;
    const Image& mask = frame.mask[static_cast<std::size_t>(c)];
    // The recorded augmented pixel (u, v): a whole image, or its changed box over the raw image.
    const Image& augmented = frame.augmented[static_cast<std::size_t>(c)];
    const auto& box = frame.augmented_box[static_cast<std::size_t>(c)];
    const bool aug = augmented.format() == raw.format() &&
                     (box ? augmented.width() == box->width() && augmented.height() == box->height()
                          : augmented.width() == raw.width() && augmented.height() == raw.height());
    auto augmented_rgb = [&](int u, int v) {
      if (!box) return raw_rgb(augmented, u, v);
      if (u < box->x0 || v < box->y0 || u >= box->x1 || v >= box->y1) return raw_rgb(raw, u, v);
      return raw_rgb(augmented, u - box->x0, v - box->y0);
    };
    ASSERT_TRUE(raw.format() == PixelFormat::kRGB8 || raw.format() == PixelFormat::kMono8)
        << "RGB8 or Mono8 frames";
    const Rect& r = shot.views[c];
    ASSERT_GT(r.w, 0);
    // Image pixel (u, v) lies at x + (u + 0.5) w / W in the window. Only pixels whose whole
    // neighbourhood (the scaling's footprint) is of one class are compared.
    const double scale = static_cast<double>(raw.width()) / r.w;
    const int rad = static_cast<int>(std::ceil(scale)) + 1;
    int boom = 0, boom_differs = 0, clear = 0, clear_same = 0;
    const int step = raw.width() >= 640 ? 2 : 1;
    for (int v = rad; v < raw.height() - rad; v += step)
      for (int u = rad; u < raw.width() - rad; u += step) {
        const std::uint8_t m0 = mask.row(v)[u];
        bool uniform = true;
        for (int dv = -rad; dv <= rad && uniform; ++dv)
          for (int du = -rad; du <= rad && uniform; ++du) uniform = mask.row(v + dv)[u + du] == m0;
        if (!uniform || (m0 != 0 && !(m0 & kMaskBoom))) continue;
        const int x = r.x + static_cast<int>((u + 0.5) / scale),
                  y = r.y + static_cast<int>((v + 0.5) / scale);
        const cv::Vec3b got = rgb.at<cv::Vec3b>(y, x), want = raw_rgb(raw, u, v);
        auto distance = [&](const cv::Vec3b& a) {
          int d = 0;
          for (int k = 0; k < 3; ++k) d = std::max(d, std::abs(int(got[k]) - int(a[k])));
          return d;
        };
        const int d = distance(want);
        if (m0 & kMaskBoom) {
          // The boom as recorded where the frame has its augmented image (a lit boom may match
          // the ground behind it in places), else anything but the raw image.
          ++boom;
          boom_differs += aug ? distance(augmented_rgb(u, v)) <= 30 : d > 30;
        } else {
          ++clear;
          clear_same += d <= 20;
        }
      }
    ASSERT_GT(boom, 50) << "the shown frame must show the boom";
    ASSERT_GT(clear, 1000);
    // Where the masks say boom, the window shows the boom, not the raw image; elsewhere the raw image.
    EXPECT_GE(static_cast<double>(boom_differs) / boom, 0.9) << boom_differs << " of " << boom;
    EXPECT_GE(static_cast<double>(clear_same) / clear, 0.97) << clear_same << " of " << clear;
  }
  // The occlusion panel (the right part of the HUD): with a frame, its text and three plots; without,
  // one grey line "no frame yet". Count what differs from the panel's background.
  const Rect& h = shot.hud;
  const int x0 = h.x + h.w * 62 / 100, x1 = h.x + h.w - 4;
  const cv::Vec3b bg = rgb.at<cv::Vec3b>(h.y + h.h - 6, h.x + h.w - 6);
  int ink = 0, all = 0;
  for (int y = h.y + 24; y < h.y + h.h - 4; ++y)
    for (int x = x0; x < x1; ++x) {
      const cv::Vec3b p = rgb.at<cv::Vec3b>(y, x);
      ++all;
      ink += std::abs(int(p[0]) - bg[0]) + std::abs(int(p[1]) - bg[1]) + std::abs(int(p[2]) - bg[2]) > 24;
    }
  EXPECT_GT(static_cast<double>(ink) / all, 0.08)
      << "the occlusion panel is empty (" << ink << " of " << all << ")";
}

}  // namespace augrig::test
