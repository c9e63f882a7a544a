#include "render/visualize.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

#include <opencv2/imgproc.hpp>

#include "core/conventions.hpp"
#include "render/stats.hpp"

namespace augrig {
namespace {

struct Rgb {
  std::uint8_t r, g, b;
};
constexpr Rgb kBlack{0, 0, 0};
constexpr Rgb kRed{255, 0, 0};
constexpr Rgb kDarkRed{128, 0, 0};  // the receiver in the boom's shadow: red at half intensity
constexpr Rgb kGreen{0, 255, 0};
constexpr Rgb kBlue{0, 0, 255};
constexpr Rgb kCyan{0, 255, 255};
constexpr Rgb kMagenta{255, 0, 255};
constexpr Rgb kWhite{255, 255, 255};

void put(std::uint8_t* p, Rgb c) {
  p[0] = c.r;
  p[1] = c.g;
  p[2] = c.b;
}

void require_mono8(const Image& m, const char* what) {
  if (m.format() != PixelFormat::kMono8)
    throw std::invalid_argument(std::string(what) + ": mask is not Mono8");
}

// OpenCV names a Bayer pattern after the 2x2 cell starting at the second row's second pixel,
// GenICam PFNC (our PixelFormat) after the top-left cell, so every name is shifted by one row and
// one column: PFNC RG (R G / G B) is OpenCV's "BG". tests/render/visualize_test.cpp pins this by
// mosaicing known colours with bayer_channel() and demosaicing them back.
int opencv_bayer_code(PixelFormat f) {
  switch (f) {
    case PixelFormat::kBayerRG8:
      return cv::COLOR_BayerBG2RGB;
    case PixelFormat::kBayerGR8:
      return cv::COLOR_BayerGB2RGB;
    case PixelFormat::kBayerGB8:
      return cv::COLOR_BayerGR2RGB;
    case PixelFormat::kBayerBG8:
      return cv::COLOR_BayerRG2RGB;
    default:
      return -1;
  }
}

// cv::Mat views sharing the Image's buffer, honouring its stride (rows may be padded).
cv::Mat as_mat(const Image& im, int type) {
  return cv::Mat(im.height(), im.width(), type, const_cast<std::uint8_t*>(im.data()), im.stride_bytes());
}

}  // namespace

Image visualize_boom_overlap(const Image& mask_left, const Image& mask_right) {
  require_mono8(mask_left, "visualize_boom_overlap");
  require_mono8(mask_right, "visualize_boom_overlap");
  if (mask_left.width() != mask_right.width() || mask_left.height() != mask_right.height())
    throw std::invalid_argument("visualize_boom_overlap: masks differ in size");
  Image out(mask_left.width(), mask_left.height(), PixelFormat::kRGB8);
  for (int y = 0; y < out.height(); ++y) {
    const std::uint8_t* a = mask_left.row(y);
    const std::uint8_t* b = mask_right.row(y);
    std::uint8_t* o = out.row(y);
    for (int x = 0; x < out.width(); ++x) {
      const bool l = a[x] & kMaskBoom, r = b[x] & kMaskBoom;
      put(o + 3 * x, l && r ? kGreen : l ? kCyan : r ? kBlue : kBlack);
    }
  }
  return out;
}

Image visualize_receiver_occlusion(const Image& mask, bool left_camera) {
  require_mono8(mask, "visualize_receiver_occlusion");
  Image out(mask.width(), mask.height(), PixelFormat::kRGB8);
  // Indexed by (mask & 7): nothing, boom only, receiver only, boom over receiver; then the same
  // with the shadow bit, which only changes the receiver alone (in the boom's shadow: darker red).
  // The augmenter never sets the shadow bit without the receiver's or with the boom's; there it
  // is ignored.
  const Rgb boom = left_camera ? kCyan : kBlue, over = left_camera ? kWhite : kMagenta;
  const Rgb lut[8] = {kBlack, boom, kRed, over, kBlack, boom, kDarkRed, over};
  static_assert((kMaskBoom | kMaskReceiver | kMaskShadow) == 7);
  for (int y = 0; y < out.height(); ++y) {
    const std::uint8_t* m = mask.row(y);
    std::uint8_t* o = out.row(y);
    for (int x = 0; x < out.width(); ++x)
      put(o + 3 * x, lut[m[x] & (kMaskBoom | kMaskReceiver | kMaskShadow)]);
  }
  return out;
}

Image visualize_stereo_classes(const std::vector<std::uint8_t>& classes, int width, int height) {
  if (width < 0 || height < 0 ||
      classes.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height))
    throw std::invalid_argument("visualize_stereo_classes: classes.size() != width * height");
  Image out(width, height, PixelFormat::kRGB8);
  for (int y = 0; y < height; ++y) {
    std::uint8_t* o = out.row(y);
    for (int x = 0; x < width; ++x) {
      Rgb c = kBlack;
      switch (static_cast<StereoClass>(classes[static_cast<std::size_t>(y) * width + x])) {
        case StereoClass::kBoth:
          c = kRed;
          break;
        case StereoClass::kLeftOnly:
          c = kCyan;
          break;
        case StereoClass::kRightOnly:
          c = kBlue;
          break;
        case StereoClass::kNeither:
          c = kGreen;
          break;
        default:
          break;
      }
      put(o + 3 * x, c);
    }
  }
  return out;
}

Image to_rgb8(const Image& image) {
  const int w = image.width(), h = image.height();
  Image out(w, h, PixelFormat::kRGB8);
  if (image.empty()) return out;
  switch (image.format()) {
    case PixelFormat::kRGB8:
      for (int y = 0; y < h; ++y) std::memcpy(out.row(y), image.row(y), static_cast<std::size_t>(w) * 3);
      break;
    case PixelFormat::kMono8:
      for (int y = 0; y < h; ++y) {
        const std::uint8_t* s = image.row(y);
        std::uint8_t* o = out.row(y);
        for (int x = 0; x < w; ++x) o[3 * x] = o[3 * x + 1] = o[3 * x + 2] = s[x];
      }
      break;
    case PixelFormat::kRGBA8:
      for (int y = 0; y < h; ++y) {
        const std::uint8_t* s = image.row(y);
        std::uint8_t* o = out.row(y);
        for (int x = 0; x < w; ++x) std::memcpy(o + 3 * x, s + 4 * x, 3);
      }
      break;
    default: {
      // Bayer: OpenCV demosaics (bilinear) straight into our buffer.
      if (w < 2 || h < 2) throw std::invalid_argument("to_rgb8: Bayer image smaller than 2x2");
      cv::Mat dst = as_mat(out, CV_8UC3);
      cv::cvtColor(as_mat(image, CV_8UC1), dst, opencv_bayer_code(image.format()));
      if (dst.data != out.data()) throw std::logic_error("to_rgb8: cvtColor reallocated its output");
      break;
    }
  }
  return out;
}

Image blend_over(const Image& background, const Image& visualization, float alpha) {
  if (visualization.format() != PixelFormat::kRGB8)
    throw std::invalid_argument("blend_over: visualisation is not RGB8");
  if (background.width() != visualization.width() || background.height() != visualization.height())
    throw std::invalid_argument("blend_over: background and visualisation differ in size");
  const float a = std::clamp(alpha, 0.0f, 1.0f);
  Image out = to_rgb8(background);
  for (int y = 0; y < out.height(); ++y) {
    std::uint8_t* o = out.row(y);
    const std::uint8_t* v = visualization.row(y);
    for (int i = 0; i < 3 * out.width(); i += 3) {
      // Darken the background so the saturated mask colours stand out; blend only where coloured.
      const bool coloured = v[i] | v[i + 1] | v[i + 2];
      for (int c = 0; c < 3; ++c) {
        const float dark = 0.5f * o[i + c];
        const float val = coloured ? (1.0f - a) * dark + a * v[i + c] : dark;
        o[i + c] = static_cast<std::uint8_t>(std::min(255.0f, val + 0.5f));
      }
    }
  }
  return out;
}

}  // namespace augrig
