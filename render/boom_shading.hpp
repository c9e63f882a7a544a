// The CPU rasteriser's boom colour: one boom triangle shaded exactly at a raw pixel's centre, as
// the GL shader of render/backends/gl_raster.cpp shades its samples (Gouraud lighting, bilinear repeating
// texture) and as a UNORM framebuffer stores it (clamped to 0..255). Internal to the raster backends;
// a header of its own so that its edge cases are tested directly.
#pragma once

#include <cstdint>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "render/mesh.hpp"

namespace augrig::detail {

// RGBA as four floats (GCC/Clang vector extensions: SSE here, NEON on ARM).
using F32x4 = float __attribute__((vector_size(16)));

// One boom triangle's colour in one view as functions of the camera-frame ray d = (x, y, 1) (CPU
// rasteriser: the resolve colours each raw pixel at its centre). With e_j = c_j . d the vertices'
// barycentric weights up to a common positive factor (c_j: the edge planes), any vertex attribute
// a_j interpolates perspective-correctly as (sum a_j c_j) . d / (sum c_j) . d. The lighting is
// the GL shader's, evaluated at the vertices and interpolated (Gouraud); the texture coordinates
// are interpolated per pixel.
struct BoomShading {
  // Four planes, one per lane, evaluated together as dx x + dy y + d1: the sum of c_j; the sum of
  // k_j c_j with k_j = SceneLight::on(n_j) at vertex j (the camera look: its SurfaceLight's scale),
  // red channel; the sums of u_j c_j and v_j c_j.
  F32x4 dx, dy, d1;
  // The sums k_j c_j of the green and blue channels (lanes 0 and 1; the others unused).
  F32x4 gx, gy, g1;
  F32x4 base;  // base colour * 255 (the alpha lane is not used)
  // The light's range per channel over the vertices (render/camera_look.hpp's SceneLight: lowest()
  // to highest(); the plain look's fixed light is 0.35 to 1).
  F32x4 light_lo = {0.35f, 0.35f, 0.35f, 0.35f}, light_hi = {1.f, 1.f, 1.f, 1.f};
  // The camera look's specular light that does not take the albedo's colour (render/pbr.hpp:
  // SurfaceLight::add, times 255), R G B lanes: the sums a_j c_j, and its largest vertex value.
  // Only where `specular` (the plain look has none: its pixels stay as they were).
  F32x4 sx = {}, sy = {}, s1 = {};
  F32x4 add_hi = {};
  bool specular = false;
  const Texture* texture = nullptr;
  bool texture_1d = false;  // its rows are all the same: v is not needed
};

// Four RGBA8 samples blended in one vector (GCC/Clang vector extensions: SSE here, NEON on ARM).
inline F32x4 load_rgba(const std::uint8_t* p) {
#if defined(__SSE2__)
  // Widen u8 -> i32 -> f32 in registers (__builtin_convertvector goes lane by lane on SSE2).
  std::int32_t v;
  std::memcpy(&v, p, 4);
  const __m128i zero = _mm_setzero_si128();
  const __m128i w = _mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128(v), zero), zero);
  return reinterpret_cast<F32x4>(_mm_cvtepi32_ps(w));
#else
  return F32x4{static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2]),
               static_cast<float>(p[3])};
#endif
}

// Bilinear, repeating, as GL samples the boom's texture when magnified (no mipmaps here: the
// boom is seen from a few metres, its texture is not minified much). RGBA 0..255.
// `one_row`: all rows are the same (then v is not used).
inline F32x4 sample_texture(const Texture& tex, float u, float v, bool one_row) {
  // Texel coordinates wrapped into [0, n), the texel and its right/lower neighbour (wrapping).
  // Floors by truncation: std::floor is a library call on baseline x86-64.
  auto texel = [](float t, int n, int& i0, int& i1) {
    const float x = t * static_cast<float>(n) - 0.5f;
    int i = static_cast<int>(x);
    i -= x < static_cast<float>(i);
    const float frac = x - static_cast<float>(i);
    if (static_cast<unsigned>(i) >= static_cast<unsigned>(n)) {  // rarely: a division
      i %= n;
      i += i < 0 ? n : 0;
    }
    i0 = i;
    i1 = i0 + 1 == n ? 0 : i0 + 1;
    return frac;
  };
  int x0, x1, y0, y1;
  const float ax = texel(u, tex.width, x0, x1);
  if (one_row) {
    const std::uint8_t* r = tex.rgba.data();
    return (1 - ax) * load_rgba(r + 4 * static_cast<std::size_t>(x0)) +
           ax * load_rgba(r + 4 * static_cast<std::size_t>(x1));
  }
  const float ay = texel(v, tex.height, y0, y1);
  const std::uint8_t* r0 = &tex.rgba[static_cast<std::size_t>(y0) * tex.width * 4];
  const std::uint8_t* r1 = &tex.rgba[static_cast<std::size_t>(y1) * tex.width * 4];
  const std::size_t c0 = 4 * static_cast<std::size_t>(x0), c1 = 4 * static_cast<std::size_t>(x1);
  return (1 - ay) * ((1 - ax) * load_rgba(r0 + c0) + ax * load_rgba(r0 + c1)) +
         ay * ((1 - ax) * load_rgba(r1 + c0) + ax * load_rgba(r1 + c1));
}

// The boom's colour (0..255; alpha lane not set) on the ray (x, y, 1) through triangle `s`:
// the light (sky and ground hemispheres plus direct times the cosine at the vertices, interpolated), times
// base colour and texture, plus (camera look) the specular light that does not take their colour. A pixel
// centre just outside its triangle (an edge pixel whose sample lies inside) extrapolates the attributes: the
// light is held to its range [light_lo, light_hi] and the texture coordinates to a range whose texel index
// fits an int, and the colour is clamped to 0..255 as GL's UNORM framebuffer clamps it (a negative colour
// converted to uint8 is undefined behaviour).
inline F32x4 shade(const BoomShading& s, float x, float y) {
  const F32x4 planes = s.dx * x + s.dy * y + s.d1;
  const float inv = planes[0] > 0 ? 1.f / planes[0] : 0.f;
  const F32x4 q = planes * inv;                         // 1, red light, u, v
  const F32x4 gb = (s.gx * x + s.gy * y + s.g1) * inv;  // green and blue light
  // Written so that NaN goes to the low end too (every comparison with NaN is false).
  auto hold = [](float a, float lo, float hi) { return a > lo ? (a < hi ? a : hi) : lo; };
  const F32x4 light = {hold(q[1], s.light_lo[0], s.light_hi[0]), hold(gb[0], s.light_lo[1], s.light_hi[1]),
                       hold(gb[1], s.light_lo[2], s.light_hi[2]), 0.f};
  F32x4 c = s.base * light;
  if (s.texture) {
    constexpr float kMaxUv = 1e4f;  // the texture repeats: exact far beyond any real coordinate
    c *= sample_texture(*s.texture, hold(q[2], -kMaxUv, kMaxUv), hold(q[3], -kMaxUv, kMaxUv), s.texture_1d) *
         (1.f / 255.f);
  }
  if (s.specular) {  // a sheen or glint added over the albedo's colour, held to the vertices' range
    F32x4 a = (s.sx * x + s.sy * y + s.s1) * inv;
#if defined(__SSE2__)
    // Two instructions for the four lanes (maxps returns its second operand for NaN: 0).
    a = reinterpret_cast<F32x4>(_mm_min_ps(_mm_max_ps(a, _mm_setzero_ps()), s.add_hi));
#else
    for (int i = 0; i < 4; ++i) a[i] = hold(a[i], 0.f, s.add_hi[i]);
#endif
    c += a;  // the alpha lane's planes and range are 0
  }
  for (int i = 0; i < 4; ++i) c[i] = hold(c[i], 0.f, 255.f);
  return c;
}

}  // namespace augrig::detail
