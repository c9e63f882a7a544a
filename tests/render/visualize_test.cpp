// Tests of render/visualize: the paper's colours at chosen pixels, stride handling, and the Bayer
// demosaicing pinned to our PFNC pattern names by a mosaic -> demosaic round trip.
#include "render/visualize.hpp"

#include <array>
#include <cstdlib>
#include <stdexcept>

#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "render/stats.hpp"

namespace augrig {
namespace {

using Rgb = std::array<int, 3>;

Rgb rgb_at(const Image& im, int x, int y) {
  EXPECT_EQ(im.format(), PixelFormat::kRGB8);
  const std::uint8_t* p = im.row(y) + 3 * x;
  return {p[0], p[1], p[2]};
}

// Image whose rows are padded with `pad` bytes of 0xEE (which must never leak into outputs).
Image padded(int w, int h, PixelFormat f, int pad) {
  Image im(w, h, f, static_cast<std::size_t>(w * bytes_per_pixel(f) + pad));
  for (int y = 0; y < h; ++y)
    for (int p = 0; p < pad; ++p) im.row(y)[w * bytes_per_pixel(f) + p] = 0xEE;
  return im;
}

constexpr Rgb kBlack{0, 0, 0}, kRed{255, 0, 0}, kDarkRed{128, 0, 0}, kGreen{0, 255, 0}, kBlue{0, 0, 255},
    kCyan{0, 255, 255}, kMagenta{255, 0, 255}, kWhite{255, 255, 255};

TEST(Visualize, BoomOverlapColours) {
  Image l = padded(4, 2, PixelFormat::kMono8, 3), r = padded(4, 2, PixelFormat::kMono8, 1);
  // Pixel x: 0 neither, 1 left only, 2 right only, 3 both; row 1 adds receiver and high bits,
  // which must not change anything.
  const std::uint8_t lv[4] = {0, 1, 0, 1}, rv[4] = {0, 0, 1, 1};
  for (int x = 0; x < 4; ++x) {
    l.row(0)[x] = lv[x];
    r.row(0)[x] = rv[x];
    l.row(1)[x] = static_cast<std::uint8_t>(lv[x] | kMaskReceiver | 0xF0);
    r.row(1)[x] = static_cast<std::uint8_t>(rv[x] | kMaskReceiver | 0x80);
  }
  const Image v = visualize_boom_overlap(l, r);
  ASSERT_EQ(v.width(), 4);
  ASSERT_EQ(v.height(), 2);
  for (int y = 0; y < 2; ++y) {
    EXPECT_EQ(rgb_at(v, 0, y), kBlack);
    EXPECT_EQ(rgb_at(v, 1, y), kCyan);
    EXPECT_EQ(rgb_at(v, 2, y), kBlue);
    EXPECT_EQ(rgb_at(v, 3, y), kGreen);
  }
  EXPECT_THROW(visualize_boom_overlap(l, Image(3, 2, PixelFormat::kMono8)), std::invalid_argument);
}

TEST(Visualize, ReceiverOcclusionColours) {
  Image m = padded(5, 2, PixelFormat::kMono8, 2);
  m.row(0)[0] = 0x08;                         // no bits of ours
  m.row(0)[1] = kMaskBoom;                    // boom off the receiver
  m.row(0)[2] = kMaskReceiver;                // receiver
  m.row(0)[3] = kMaskBoom | kMaskReceiver;    // boom over receiver
  m.row(0)[4] = kMaskReceiver | kMaskShadow;  // receiver in the boom's shadow
  // Row 1: the same with higher bits, which change nothing.
  for (int x = 0; x < 5; ++x) m.row(1)[x] = static_cast<std::uint8_t>(m.row(0)[x] | 0xF0);
  const Image left = visualize_receiver_occlusion(m, true);
  const Image right = visualize_receiver_occlusion(m, false);
  for (int y = 0; y < 2; ++y) {
    EXPECT_EQ(rgb_at(left, 0, y), kBlack);
    EXPECT_EQ(rgb_at(left, 1, y), kCyan);
    EXPECT_EQ(rgb_at(left, 2, y), kRed);
    EXPECT_EQ(rgb_at(left, 3, y), kWhite);
    EXPECT_EQ(rgb_at(left, 4, y), kDarkRed);
    EXPECT_EQ(rgb_at(right, 0, y), kBlack);
    EXPECT_EQ(rgb_at(right, 1, y), kBlue);
    EXPECT_EQ(rgb_at(right, 2, y), kRed);
    EXPECT_EQ(rgb_at(right, 3, y), kMagenta);
    EXPECT_EQ(rgb_at(right, 4, y), kDarkRed);
  }
}

// The shadow bit never comes without the receiver's or with the boom's; where it does, it is
// ignored: the colours of the other bits, as before the bit existed.
TEST(Visualize, ShadowBitChangesOnlyTheReceiverAlone) {
  for (const bool left_camera : {true, false}) {
    Image with(8, 1, PixelFormat::kMono8), without(8, 1, PixelFormat::kMono8);
    for (int v = 0; v < 8; ++v) {
      with.row(0)[v] = static_cast<std::uint8_t>(v);
      without.row(0)[v] = static_cast<std::uint8_t>(v & ~kMaskShadow);
    }
    const Image a = visualize_receiver_occlusion(with, left_camera);
    const Image b = visualize_receiver_occlusion(without, left_camera);
    for (int v = 0; v < 8; ++v) {
      if (v == (kMaskReceiver | kMaskShadow)) {
        EXPECT_EQ(rgb_at(a, v, 0), kDarkRed);
        EXPECT_NE(rgb_at(b, v, 0), kDarkRed);
      } else {
        EXPECT_EQ(rgb_at(a, v, 0), rgb_at(b, v, 0)) << "mask value " << v;
      }
    }
  }
}

TEST(Visualize, StereoClassColours) {
  const std::vector<std::uint8_t> c = {
      static_cast<std::uint8_t>(StereoClass::kNone),     static_cast<std::uint8_t>(StereoClass::kBoth),
      static_cast<std::uint8_t>(StereoClass::kLeftOnly), static_cast<std::uint8_t>(StereoClass::kRightOnly),
      static_cast<std::uint8_t>(StereoClass::kNeither),  static_cast<std::uint8_t>(StereoClass::kBoth)};
  const Image v = visualize_stereo_classes(c, 3, 2);
  EXPECT_EQ(rgb_at(v, 0, 0), kBlack);
  EXPECT_EQ(rgb_at(v, 1, 0), kRed);
  EXPECT_EQ(rgb_at(v, 2, 0), kCyan);
  EXPECT_EQ(rgb_at(v, 0, 1), kBlue);
  EXPECT_EQ(rgb_at(v, 1, 1), kGreen);
  EXPECT_EQ(rgb_at(v, 2, 1), kRed);
  EXPECT_THROW(visualize_stereo_classes(c, 4, 2), std::invalid_argument);
}

TEST(ToRgb8, MonoRgbRgbaWithPaddedRows) {
  Image mono = padded(3, 2, PixelFormat::kMono8, 5);
  Image rgb = padded(3, 2, PixelFormat::kRGB8, 2);
  Image rgba = padded(3, 2, PixelFormat::kRGBA8, 4);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 3; ++x) {
      const int k = 10 * y + x;
      mono.row(y)[x] = static_cast<std::uint8_t>(k);
      for (int c = 0; c < 3; ++c) rgb.row(y)[3 * x + c] = static_cast<std::uint8_t>(k + 100 * c);
      for (int c = 0; c < 4; ++c) rgba.row(y)[4 * x + c] = static_cast<std::uint8_t>(k + 50 * c);
    }
  const Image m = to_rgb8(mono), r = to_rgb8(rgb), a = to_rgb8(rgba);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 3; ++x) {
      const int k = 10 * y + x;
      EXPECT_EQ(rgb_at(m, x, y), (Rgb{k, k, k}));
      EXPECT_EQ(rgb_at(r, x, y), (Rgb{k, k + 100, k + 200}));
      EXPECT_EQ(rgb_at(a, x, y), (Rgb{k, k + 50, k + 100}));  // alpha (k + 150) dropped
    }
}

// Mosaic a four-quadrant colour image with bayer_channel() (the PFNC meaning of our formats),
// demosaic with to_rgb8 and check the quadrant interiors, where bilinear demosaicing is exact.
// Every channel differs in every quadrant, so a pattern shifted by a row or a column (the usual
// OpenCV naming trap) swaps R and B or mixes G in and fails.
TEST(ToRgb8, BayerRoundTripAllPatterns) {
  const Rgb quad[4] = {{200, 100, 30}, {20, 220, 140}, {90, 10, 250}, {160, 60, 110}};
  const int w = 64, h = 48;
  for (PixelFormat f :
       {PixelFormat::kBayerRG8, PixelFormat::kBayerGR8, PixelFormat::kBayerGB8, PixelFormat::kBayerBG8}) {
    SCOPED_TRACE(std::string(to_string(f)));
    for (int pad : {0, 7}) {
      Image bayer = padded(w, h, f, pad);
      auto colour = [&](int x, int y) { return quad[(y >= h / 2) * 2 + (x >= w / 2)]; };
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          bayer.row(y)[x] = static_cast<std::uint8_t>(colour(x, y)[bayer_channel(f, x, y)]);
      const Image out = to_rgb8(bayer);
      ASSERT_EQ(out.format(), PixelFormat::kRGB8);
      int bad = 0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const bool interior = std::abs(2 * x + 1 - w) > 6 && std::abs(2 * y + 1 - h) > 6 && x > 2 &&
                                y > 2 && x < w - 3 && y < h - 3;
          if (!interior) continue;
          const Rgb got = rgb_at(out, x, y), want = colour(x, y);
          for (int c = 0; c < 3; ++c) bad += std::abs(got[c] - want[c]) > 1;
        }
      EXPECT_EQ(bad, 0) << "pad " << pad;
    }
  }
}

TEST(BlendOver, DarkensAndBlendsWhereColoured) {
  Image bg = padded(2, 1, PixelFormat::kMono8, 3);
  bg.row(0)[0] = bg.row(0)[1] = 100;
  Image vis(2, 1, PixelFormat::kRGB8);
  vis.row(0)[0] = 255;  // red at x = 0, black at x = 1
  const Image out = blend_over(bg, vis, 0.6f);
  // x = 0: 0.4 * (0.5 * 100) + 0.6 * (255, 0, 0) = (173, 20, 20); x = 1: darkened only, 50.
  EXPECT_EQ(rgb_at(out, 0, 0), (Rgb{173, 20, 20}));
  EXPECT_EQ(rgb_at(out, 1, 0), (Rgb{50, 50, 50}));
  EXPECT_THROW(blend_over(bg, Image(3, 1, PixelFormat::kRGB8)), std::invalid_argument);
}

TEST(BlendOver, BayerBackground) {
  Image bg(8, 8, PixelFormat::kBayerGR8);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) bg.row(y)[x] = 200;  // grey in any pattern
  const Image vis = visualize_receiver_occlusion(Image(8, 8, PixelFormat::kMono8), true);  // all black
  const Image out = blend_over(bg, vis);
  EXPECT_EQ(rgb_at(out, 4, 4), (Rgb{100, 100, 100}));
}

}  // namespace
}  // namespace augrig
