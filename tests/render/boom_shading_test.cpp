// The CPU rasteriser's per-pixel boom shading (render/boom_shading.hpp): inside a triangle it is
// the interpolated Gouraud light times base colour and texture; at a pixel centre outside the
// triangle (edge pixels) the extrapolated attributes must not leave what GL would store.
#include "render/boom_shading.hpp"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace augrig::detail {
namespace {

// A shading whose planes are linear in x alone: weight sum 1, light = light0 + slope * x, uv = x.
BoomShading linear_in_x(float light0, float slope, const Texture* tex = nullptr) {
  BoomShading s;
  s.dx = F32x4{0.f, slope, 1.f, 1.f};
  s.dy = F32x4{0.f, 0.f, 0.f, 0.f};
  s.d1 = F32x4{1.f, light0, 0.f, 0.f};
  // Green and blue lit as red.
  s.gx = F32x4{slope, slope, 0.f, 0.f};
  s.gy = F32x4{0.f, 0.f, 0.f, 0.f};
  s.g1 = F32x4{light0, light0, 0.f, 0.f};
  s.base = F32x4{200.f, 100.f, 50.f, 255.f};
  s.texture = tex;
  return s;
}

TEST(BoomShading, InsideTheTriangleIsLightTimesBaseColour) {
  const BoomShading s = linear_in_x(0.5f, 0.25f);
  const F32x4 c = shade(s, 1.f, 0.f);  // light 0.75
  EXPECT_FLOAT_EQ(c[0], 150.f);
  EXPECT_FLOAT_EQ(c[1], 75.f);
  EXPECT_FLOAT_EQ(c[2], 37.5f);
}

// Extrapolated far past an edge the light went negative (and the colour with it: -186 was seen,
// which uint8 conversion turns into garbage) or above one: it stays in the vertices' range.
TEST(BoomShading, ExtrapolatedLightStaysInTheVerticesRange) {
  const BoomShading s = linear_in_x(0.5f, 0.25f);
  for (float x : {-1e6f, -100.f, -3.f, 3.f, 100.f, 1e6f}) {
    const F32x4 c = shade(s, x, 0.f);
    for (int i = 0; i < 3; ++i) {
      EXPECT_GE(c[i], 0.35f * s.base[i] - 1e-3f) << "x " << x << " channel " << i;
      EXPECT_LE(c[i], s.base[i] + 1e-3f) << "x " << x << " channel " << i;
    }
  }
}

TEST(BoomShading, ColourIsClampedToWhatAnRgba8FramebufferHolds) {
  BoomShading s = linear_in_x(1.f, 0.f);
  s.base = F32x4{400.f, -20.f, std::numeric_limits<float>::quiet_NaN(), 0.f};
  const F32x4 c = shade(s, 0.f, 0.f);
  EXPECT_EQ(c[0], 255.f);
  EXPECT_EQ(c[1], 0.f);
  EXPECT_EQ(c[2], 0.f) << "NaN goes to 0, not to an undefined uint8";
}

// Texture coordinates extrapolated to huge values still sample a texel (the index would overflow
// an int otherwise) and the result is one of the texture's colours, times the light.
TEST(BoomShading, HugeTextureCoordinatesSampleTheRepeatedTexture) {
  Texture tex;
  tex.width = 4, tex.height = 2;
  tex.rgba.assign(static_cast<std::size_t>(tex.width * tex.height * 4), 255);
  const BoomShading s = linear_in_x(1.f, 0.f, &tex);
  for (float x : {-1e30f, -1e9f, 1e9f, 1e30f}) {
    const F32x4 c = shade(s, x, 0.f);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(c[i], s.base[i], 1e-3f) << "x " << x;
  }
}

TEST(BoomShading, BehindTheEyeTheWeightsGiveNoColourNotNaN) {
  const BoomShading s = linear_in_x(0.5f, 0.f);
  BoomShading behind = s;
  behind.d1[0] = -1.f;  // weight sum <= 0: the ray misses the triangle's plane in front
  const F32x4 c = shade(behind, 0.f, 0.f);
  for (int i = 0; i < 4; ++i) EXPECT_FALSE(std::isnan(c[i]));
}

// The camera look's specular light adds over the albedo's colour (a glint is not tinted by the
// paint), held like the light to its vertices' range when extrapolated; without `specular` its
// planes are not read (the plain look's pixels stay as they were).
TEST(BoomShading, SpecularLightAddsAndStaysInItsVerticesRange) {
  BoomShading s = linear_in_x(0.5f, 0.f);
  s.sx = F32x4{10.f, 10.f, 10.f, 0.f};  // added light 20 + 10 x (0..255)
  s.s1 = F32x4{20.f, 20.f, 20.f, 0.f};
  s.add_hi = F32x4{40.f, 40.f, 40.f, 0.f};
  const F32x4 off = shade(s, 1.f, 0.f);
  s.specular = true;
  const F32x4 on = shade(s, 1.f, 0.f);
  for (int i = 0; i < 3; ++i) {
    EXPECT_FLOAT_EQ(off[i], 0.5f * s.base[i]);
    EXPECT_FLOAT_EQ(on[i], 0.5f * s.base[i] + 30.f);
  }
  for (float x : {-1e6f, -3.f, 3.f, 1e6f}) {
    const F32x4 c = shade(s, x, 0.f);
    for (int i = 0; i < 3; ++i) {
      EXPECT_GE(c[i], 0.5f * s.base[i] - 1e-3f) << "x " << x;
      EXPECT_LE(c[i], 0.5f * s.base[i] + 40.f + 1e-3f) << "x " << x;
    }
  }
}

}  // namespace
}  // namespace augrig::detail
