// The CPU synthetic scene renderer (sim/synthetic_scene_cpu.hpp). What does not change per frame
// is computed once: each raw pixel's ray through the lens (VirtualPinhole::ray_xy), a node grid
// every kBlock pixels with each node's ray and angular pixel size, the baked ground tile with its
// mipmaps (once per process), the receiver's textures with their mipmaps. Per view:
//   1. background, per block of kBlock x kBlock raw pixels: the four corner nodes' rays are
//      rotated to NED and shaded exactly (sky colour, or the ground point, its footprint, woods,
//      tint and haze); inside a ground block the ground point is interpolated and the tile sampled
//      bilinearly in fixed point at the block's mip level, four pixels at a time with SSE2
//      (ground_block), eight with AVX2 where the CPU has it (the same bytes); sky blocks
//      interpolate the colour; blocks the horizon or the lens's invalid border cross are shaded
//      per pixel exactly. Bayer pixels compute their own channel only;
//   2. the receiver, rasterised by render/soft_raster at the virtual pinhole's samples (the raw
//      pixels themselves without distortion), lit per vertex, textured per pixel, shaded in runs
//      of one triangle along a row (shade_run) found through a bitmask of covered samples; with
//      the boom drawn (render_with_boom) under a sun above the horizon, receiver samples whose
//      surface point sees the sun through the boom (render/boom_shadow) get the ambient light only;
//   3. sensor noise from a counter-based generator per row, so row bands on several threads give
//      the same bytes as one.
// Cameras with equal intrinsics and orientation (a parallel stereo rig) share one background per
// frame when the ground's disparity between them is below kShareDisparityPx.
#include "sim/synthetic_scene_cpu.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#include <immintrin.h>
#endif

#include "core/conventions.hpp"
#include "render/boom_shadow.hpp"
#include "render/camera_look.hpp"
#include "render/models.hpp"
#include "render/motion_blur.hpp"
#include "render/projection.hpp"
#include "render/soft_raster.hpp"

namespace augrig {

namespace {

constexpr int kTileTexels = 2048;  // 8 m texels, 16.4 km tile, as the OpenGL back end
constexpr int kTileShift = 11;
constexpr int kTileLevels = kTileShift - 1;  // down to 4 x 4 texels (2 km): beyond, haze hides all
constexpr double kTileM = 16384.0;
constexpr double kTexelM = kTileM / kTileTexels;
constexpr int kBlock = 16;                   // background node spacing, raw pixels
constexpr double kShareDisparityPx = 0.25;   // largest ground disparity dropped by sharing a background
constexpr double kMaxGroundRangeM = 3.0e5;   // as the OpenGL shader: the ground plane ends here
constexpr double kHazeRangeM = 30000.0;

// ---- procedural noise: the integer-hashed value noise of the OpenGL shaders ----

inline std::uint32_t hash2(std::int32_t x, std::int32_t y, std::uint32_t seed) {
  std::uint32_t h = static_cast<std::uint32_t>(x) * 0x8da6b343u ^ static_cast<std::uint32_t>(y) * 0xd8163841u ^
                    seed * 0xcb1ab31fu;
  h ^= h >> 13u;
  h *= 0x5bd1e995u;
  h ^= h >> 15u;
  return h;
}
inline double h01(std::int32_t x, std::int32_t y, std::uint32_t seed) {
  return static_cast<double>(hash2(x, y, seed) & 0xffffffu) * (1.0 / 16777215.0);
}
// floor for |v| < 2^31 without a library call.
inline int floor_int(double v) {
  const int i = static_cast<int>(v);
  return i - (v < i);
}
inline int pmod(int a, int n) { return (a % n + n) % n; }

double vnoise(double x, double y, std::uint32_t seed, int period) {
  const int ix = floor_int(x), iy = floor_int(y);
  const double fx = x - ix, fy = y - iy;
  const double ux = fx * fx * (3.0 - 2.0 * fx), uy = fy * fy * (3.0 - 2.0 * fy);
  int x0 = ix, x1 = ix + 1, y0 = iy, y1 = iy + 1;
  if (period > 0) x0 = pmod(x0, period), x1 = pmod(x1, period), y0 = pmod(y0, period), y1 = pmod(y1, period);
  const double a = h01(x0, y0, seed), b = h01(x1, y0, seed), d = h01(x0, y1, seed), e = h01(x1, y1, seed);
  const double top = a + (b - a) * ux, bottom = d + (e - d) * ux;
  return top + (bottom - top) * uy;
}

double fbm(double x, double y, int period, std::uint32_t seed) {
  return (0.5 * vnoise(x, y, seed, period) + 0.25 * vnoise(2 * x, 2 * y, seed + 1, 2 * period) +
          0.125 * vnoise(4 * x, 4 * y, seed + 2, 4 * period)) /
         0.875;
}

// ---- the ground tile: the OpenGL bake shader's farmland, on the CPU ----

std::array<double, 3> field_color(std::uint32_t h) {
  switch (h % 8u) {
    case 0: return {0.33, 0.42, 0.20};  // pasture
    case 1: return {0.45, 0.50, 0.26};  // young crop
    case 2: return {0.55, 0.47, 0.32};  // ploughed
    case 3: return {0.68, 0.62, 0.40};  // stubble
    case 4: return {0.27, 0.36, 0.18};  // meadow
    case 5: return {0.48, 0.40, 0.29};  // bare soil
    case 6: return {0.58, 0.56, 0.33};  // ripe crop
    default: return {0.40, 0.46, 0.24};
  }
}

inline std::uint8_t unorm8(double v) { return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0)); }

// Texel (i, j) of the tile, RGBA8 packed R in the low byte; A is the fine texture under the woods.
std::uint32_t bake_texel(int i, int j) {
  const double n = kTileM;
  const double qx = (i + 0.5) * kTexelM, qy = (j + 0.5) * kTexelM;
  // Field borders warped a little (585 m noise, 28 cells a tile).
  const double wx = qx + 40.0 * (vnoise(qx * 28.0 / n, qy * 28.0 / n, 11u, 28) - 0.5);
  const double wy = qy + 40.0 * (vnoise(qx * 28.0 / n, qy * 28.0 / n, 12u, 28) - 0.5);
  // 64 x 96 fields a tile (256 m x 171 m).
  const double wcx = wx / n * 64.0, wcy = wy / n * 96.0;
  const int cix = floor_int(wcx), ciy = floor_int(wcy);
  const int cwx = pmod(cix, 64), cwy = pmod(ciy, 96);
  std::uint32_t h = hash2(cwx / 2, cwy, 7u);  // neighbouring fields now and then share a crop
  if ((hash2(cwx, cwy, 9u) & 3u) != 0u) h = hash2(cwx, cwy, 7u);
  const std::uint32_t hs = hash2(cwx, cwy, 13u);  // ... and others are split in two crops
  const double cut = 0.3 + 0.4 * static_cast<double>((hs >> 4u) & 255u) / 255.0;
  const double fcx = wcx - cix, fcy = wcy - ciy;
  if (((hs & 3u) == 1u && fcx > cut) || ((hs & 3u) == 2u && fcy > cut)) h = hash2(cwx, cwy, 17u);
  std::array<double, 3> col = field_color(h);
  const double tone = (0.85 + 0.3 * static_cast<double>((h >> 8u) & 255u) / 255.0) *
                      (0.8 + 0.4 * fbm(qx * 1024.0 / n, qy * 1024.0 / n, 1024, 21u)) *
                      (0.9 + 0.2 * vnoise(qx * 128.0 / n, qy * 128.0 / n, 31u, 128));
  // Roads along every 4th column and 3rd row of field borders, 8 m wide, box-filtered over a texel.
  const double sx = n / 16.0, sy = n / 32.0;
  auto coverage = [](double w, double spacing) {
    const double f = w / spacing + 0.5;
    const double d = std::abs(f - std::floor(f) - 0.5) * spacing;
    const double hw = 4.0, fp = kTexelM;
    const double lo = std::max(d - 0.5 * fp, -hw), hi = std::min(d + 0.5 * fp, hw);
    return std::clamp((hi - lo) / fp, 0.0, 1.0);
  };
  const double road = std::max(coverage(wx, sx), coverage(wy, sy));
  std::uint32_t out = 0;
  for (int k = 0; k < 3; ++k) {
    const double c = col[k] * tone;
    out |= static_cast<std::uint32_t>(unorm8(c + (0.46 - c) * road)) << (8 * k);
  }
  return out | static_cast<std::uint32_t>(unorm8(fbm(qx * 512.0 / n, qy * 512.0 / n, 512, 51u))) << 24;
}

// An RGBA8 texel spread into 16-bit lanes (R, B, G, A from the low bits): bilinear filtering then
// runs on all four channels in one 64-bit word (lerp64).
inline std::uint64_t expand(std::uint32_t rgba) {
  return (rgba & 0x00ff00ffu) | (static_cast<std::uint64_t>((rgba >> 8) & 0x00ff00ffu) << 32);
}
constexpr int kLaneShift[4] = {0, 32, 16, 48};  // R, G, B, A in an expanded texel
constexpr std::uint64_t kLaneMask = 0x00ff00ff00ff00ffull, kLaneHalf = 0x0080008000800080ull;
// (a (256 - w) + b w) / 256, rounded, per lane; w in 0..255. No lane exceeds 255 * 256 + 128.
inline std::uint64_t lerp64(std::uint64_t a, std::uint64_t b, std::uint32_t w) {
  return ((a * (256u - w) + b * w + kLaneHalf) >> 8) & kLaneMask;
}
inline int lane(std::uint64_t g, int ch) { return static_cast<int>((g >> kLaneShift[ch]) & 0xffu); }

// 2x2 box average of a packed RGBA8 image (the next mip level), sizes halved down to 1.
std::vector<std::uint32_t> downsample(const std::vector<std::uint32_t>& src, int w, int h, int& w2, int& h2) {
  w2 = std::max(1, w / 2), h2 = std::max(1, h / 2);
  std::vector<std::uint32_t> dst(static_cast<std::size_t>(w2) * h2);
  for (int y = 0; y < h2; ++y)
    for (int x = 0; x < w2; ++x) {
      const int xa = std::min(2 * x, w - 1), xb = std::min(2 * x + 1, w - 1);
      const int ya = std::min(2 * y, h - 1), yb = std::min(2 * y + 1, h - 1);
      const std::uint32_t p[4] = {src[static_cast<std::size_t>(ya) * w + xa], src[static_cast<std::size_t>(ya) * w + xb],
                                  src[static_cast<std::size_t>(yb) * w + xa], src[static_cast<std::size_t>(yb) * w + xb]};
      std::uint32_t out = 0;
      for (int k = 0; k < 4; ++k) {
        std::uint32_t s = 2;
        for (std::uint32_t v : p) s += (v >> (8 * k)) & 0xffu;
        out |= (s / 4) << (8 * k);
      }
      dst[static_cast<std::size_t>(y) * w2 + x] = out;
    }
  return dst;
}

// A receiver texture's mip chain, packed RGBA8 in 4 x 4 texel tiles (one cache line; the width is
// padded to whole tiles): a bilinear footprint is one or two cache lines wherever it lies.
struct Pyramid {
  std::vector<int> width, height;
  std::vector<std::vector<std::uint32_t>> texels;  // tiled per level (pyramid_index)
};
inline std::size_t pyramid_index(int width, int x, int y) {
  return ((static_cast<std::size_t>(y >> 2) * static_cast<std::size_t>((width + 3) >> 2) + (x >> 2)) << 4) |
         static_cast<std::size_t>(((y & 3) << 2) | (x & 3));
}

Pyramid make_pyramid(std::vector<std::uint32_t> level0, int w, int h, int max_levels) {
  Pyramid p;
  for (int l = 0; l < max_levels; ++l) {
    p.width.push_back(w), p.height.push_back(h);
    std::vector<std::uint32_t> tiled(static_cast<std::size_t>((w + 3) >> 2) * ((h + 3) >> 2) * 16, 0u);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) tiled[pyramid_index(w, x, y)] = level0[static_cast<std::size_t>(y) * w + x];
    p.texels.push_back(std::move(tiled));
    if (w == 1 && h == 1) break;
    int w2 = 0, h2 = 0;
    level0 = downsample(level0, w, h, w2, h2);
    w = w2, h = h2;
  }
  return p;
}

// Index of texel (x, y) in a tiled level of side 2^shift (shift >= 2): tiles of 4 rows of 5 texels,
// the 5th a copy of the next tile's first column (wrapping), so that texels (x, y) and (x + 1, y)
// are always adjacent (one 8-byte load).
inline std::size_t tiled_index(int shift, std::uint32_t x, std::uint32_t y) {
  return (((static_cast<std::size_t>(y >> 2) << (shift - 2)) + (x >> 2)) * 20) + (y & 3u) * 5 + (x & 3u);
}

// The ground tile's mip chain, packed RGBA8 (R in the low byte), each level stored in tiles of
// 4 x 4 texels plus a copy of the next tile's first column (tiled_index, 80 bytes): a bilinear
// footprint and its neighbours along any direction stay in a few cache lines, where rows of 8 kB
// would miss on every texel row, and a texel and its right neighbour are one 8-byte load. Packed
// texels (half the bytes of expanded ones) keep more of the chain in cache: level 0 is 20 MB.
struct GroundTile {
  std::vector<std::vector<std::uint32_t>> levels;  // level l: side 2^(kTileShift - l), tiled
};

// The tile is the same for every renderer: baked once per process (about 0.3 s on two cores).
std::shared_ptr<const GroundTile> ground_tile() {
  static std::mutex mutex;
  static std::shared_ptr<const GroundTile> tile;
  std::lock_guard lock(mutex);
  if (tile) return tile;
  std::vector<std::uint32_t> texels(static_cast<std::size_t>(kTileTexels) * kTileTexels);
  auto bake_rows = [&texels](int j0, int j1) {
    for (int j = j0; j < j1; ++j)
      for (int i = 0; i < kTileTexels; ++i) texels[static_cast<std::size_t>(j) * kTileTexels + i] = bake_texel(i, j);
  };
  {
    std::thread other(bake_rows, kTileTexels / 2, kTileTexels);
    bake_rows(0, kTileTexels / 2);
    other.join();
  }
  GroundTile g;
  int side = kTileTexels;
  for (int l = 0; l < kTileLevels; ++l) {
    const int shift = kTileShift - l;
    std::vector<std::uint32_t> tiled(texels.size() / 4 * 5);
    for (int y = 0; y < side; ++y) {
      const std::uint32_t* src = texels.data() + static_cast<std::size_t>(y) * side;
      for (int x = 0; x < side; ++x) tiled[tiled_index(shift, x, y)] = src[x];
      for (int x = 0; x < side; x += 4) tiled[tiled_index(shift, x, y) + 4] = src[(x + 4) & (side - 1)];
    }
    g.levels.push_back(std::move(tiled));
    if (l + 1 < kTileLevels) {
      int w2 = 0, h2 = 0;
      texels = downsample(texels, side, side, w2, h2);
      side = w2;
    }
  }
  tile = std::make_shared<const GroundTile>(std::move(g));
  return tile;
}

// Bilinear sample of a power-of-two, tiled tile level (side 2^shift) at 16.16 fixed-point texel
// coordinates (texel centres at integers), wrapping: uint32 overflow is a multiple of the period.
// Returns the filtered texel expanded (lerp64's rounding; ground4() below is the same in SIMD).
inline std::uint64_t sample_tile(const std::uint32_t* tex, int shift, std::uint32_t s, std::uint32_t t) {
  const std::uint32_t mask = (1u << shift) - 1u;
  const std::uint32_t x0 = (s >> 16) & mask, y0 = (t >> 16) & mask;
  const std::uint32_t x1 = (x0 + 1u) & mask, y1 = (y0 + 1u) & mask;
  const std::uint32_t wx = (s >> 8) & 0xffu, wy = (t >> 8) & 0xffu;
  return lerp64(lerp64(expand(tex[tiled_index(shift, x0, y0)]), expand(tex[tiled_index(shift, x1, y0)]), wx),
                lerp64(expand(tex[tiled_index(shift, x0, y1)]), expand(tex[tiled_index(shift, x1, y1)]), wx), wy);
}

inline std::int64_t round_to_int64(double v) {  // without a library call
  const double r = v + 0.5;
  const auto i = static_cast<std::int64_t>(r);
  return i - (r < static_cast<double>(i));
}
inline std::uint32_t to_fixed(double texel) { return static_cast<std::uint32_t>(round_to_int64(texel * 65536.0)); }

// ---- shading: the OpenGL sky shader's formulas, in 0..255 units ----

constexpr float kWoodA = static_cast<float>(0.1 / 255.0 / 0.03);  // the fine texture's share of the woods edge
constexpr float kWoodBase[3] = {0.18f * 0.45f * 255.0f, 0.27f * 0.45f * 255.0f, 0.13f * 0.45f * 255.0f};
constexpr float kWoodSlope[3] = {0.18f * 1.1f, 0.27f * 1.1f, 0.13f * 1.1f};
constexpr float kHaze[3] = {0.60f * 255.0f, 0.66f * 255.0f, 0.74f * 255.0f};

inline std::uint8_t to_u8(float v) {  // rounded, clamped; branch-free (minss, maxss)
  return static_cast<std::uint8_t>(static_cast<int>(std::min(std::max(v, 0.0f) + 0.5f, 255.0f)));
}

// One channel of a ground pixel from its filtered texel `g` (expanded), the woods weight `sm`, the
// ground multiplier k1 (tint x sun x (1 - haze)) and the haze fraction h.
inline float ground_channel(std::uint64_t g, int ch, float a, float sm, float k1, float h) {
  const float c = static_cast<float>(lane(g, ch));
  const float wood = kWoodBase[ch] + kWoodSlope[ch] * a;
  return (c + sm * (wood - c)) * k1 + h * kHaze[ch];
}
inline float woods_weight(float wood, float a) {
  const float z = std::clamp(wood + a * kWoodA, 0.0f, 1.0f);
  return z * z * (3.0f - 2.0f * z);
}

struct FrameSky {
  Eigen::Matrix3d R_ned_cam;
  Eigen::Vector3d cam_ned;  // north, east (world metres), down
  Eigen::Vector3d sun;      // unit
  double sun_factor = 1;    // ground brightness from the sun's height
  // The diffuse light on the objects from the sky and the ground hemispheres (0..1 of full scale).
  Eigen::Vector3f ambient_sky{0.36f, 0.40f, 0.46f}, ambient_ground{0.22f, 0.22f, 0.20f};
};

// What a ray sees, exactly: the corner nodes of the background blocks and the pixels of blocks
// that cannot be interpolated.
struct RaySample {
  bool valid = false, ground = false;
  double qs = 0, qt = 0;  // ground point in tile metres (the tile is turned 20 deg off north)
  float lam = 0;          // log2 of the pixel's ground footprint in level-0 texels (the longer axis)
  float wood = 0;         // (woods field - 0.65) / 0.03: the woods edge before the fine texture
  float k1 = 0, h = 0;    // ground multiplier (tint x sun x (1 - haze)) and haze fraction
  std::array<float, 3> sky{};
};

RaySample sample_ray(const Eigen::Vector3d& ray_cam, double ang_px, const FrameSky& f) {
  RaySample r;
  if (!std::isfinite(ray_cam.x()) || !std::isfinite(ray_cam.y())) return r;
  r.valid = true;
  const Eigen::Vector3d d = (f.R_ned_cam * ray_cam).normalized();
  if (d.z() > 0.0) {
    r.ground = true;
    const double t = std::min(-f.cam_ned.z() / std::max(d.z(), 1e-5), kMaxGroundRangeM);
    const double px = f.cam_ned.x() + t * d.x(), py = f.cam_ned.y() + t * d.y();
    r.qs = 0.9397 * px - 0.3420 * py;
    r.qt = 0.3420 * px + 0.9397 * py;
    // Footprint along the range (the longer axis, as OpenGL's isotropic mip selection).
    r.lam = static_cast<float>(std::log2(std::max(t * ang_px / (std::max(d.z(), 1e-5) * kTexelM), 1e-3)));
    const double w = 0.7 * vnoise(r.qs / 2500.0, r.qt / 2500.0, 41u, 0) + 0.3 * vnoise(r.qs / 700.0, r.qt / 700.0, 42u, 0);
    r.wood = static_cast<float>((w - 0.05 - 0.60) / 0.03);
    const double tint = (0.9 + 0.2 * vnoise(r.qs / 9000.0, r.qt / 9000.0, 43u, 0)) * f.sun_factor;
    const double haze = 1.0 - std::exp(-t / kHazeRangeM);
    r.k1 = static_cast<float>(tint * (1.0 - haze));
    r.h = static_cast<float>(haze);
    return r;
  }
  // Sky: pale at the horizon, deeper blue overhead, a soft glow around the sun.
  const double el = std::max(-d.z(), 0.0);
  const double m = std::sqrt(el) * (1.4 - 0.4 * el);
  const double sun = std::max(d.dot(f.sun), 0.0);
  const double glow = 0.5 * std::exp(400.0 * (sun - 1.0)) + 0.18 * std::exp(12.0 * (sun - 1.0));
  const double horizon[3] = {0.80, 0.86, 0.93}, zenith[3] = {0.22, 0.42, 0.78}, glow_col[3] = {1.0, 0.95, 0.85};
  for (int k = 0; k < 3; ++k)
    r.sky[k] = static_cast<float>(
        std::clamp(horizon[k] + (zenith[k] - horizon[k]) * m + glow_col[k] * glow, 0.0, 1.0) * 255.0);
  return r;
}

// The sky's and the ground's radiance as this renderer draws them, averaged over each hemisphere
// with the cosine weight of a surface facing it (stratified cosine-weighted directions): the
// irradiance a surface facing straight up or down receives, over pi. The ground's colour is the
// tile's mean albedo (its coarsest level) with the woods, tint, sun and haze of each direction.
void hemisphere_light(const GroundTile& tile, FrameSky& f) {
  Eigen::Vector3f albedo = Eigen::Vector3f::Zero();
  float alpha = 0;
  for (std::uint32_t y = 0; y < 4; ++y)
    for (std::uint32_t x = 0; x < 4; ++x) {
      const std::uint32_t t = tile.levels.back()[tiled_index(2, x, y)];
      for (int c = 0; c < 3; ++c) albedo[c] += static_cast<float>((t >> (8 * c)) & 0xffu) / 16.0f;
      alpha += static_cast<float>(t >> 24) / 16.0f;
    }
  FrameSky ned = f;
  ned.R_ned_cam = Eigen::Matrix3d::Identity();
  constexpr int kRings = 16, kAzimuths = 32;
  Eigen::Vector3d sky = Eigen::Vector3d::Zero(), ground = Eigen::Vector3d::Zero();
  for (int i = 0; i < kRings; ++i)
    for (int j = 0; j < kAzimuths; ++j) {
      const double u = (i + 0.5) / kRings, phi = 2 * kPi * (j + 0.5) / kAzimuths;
      const double r = std::sqrt(u), up = std::sqrt(1 - u);
      for (int half = 0; half < 2; ++half) {
        const Eigen::Vector3d d(r * std::cos(phi), r * std::sin(phi), half ? up : -up);  // NED: z down
        const RaySample s = sample_ray(d, 0.0, ned);
        if (!s.valid) continue;
        if (!s.ground) {
          for (int c = 0; c < 3; ++c) sky[c] += s.sky[static_cast<std::size_t>(c)] / 255.0;
          continue;
        }
        const float sm = woods_weight(s.wood, alpha);
        for (int c = 0; c < 3; ++c) {
          const float wood = kWoodBase[c] + kWoodSlope[c] * alpha;
          ground[c] += ((albedo[c] + sm * (wood - albedo[c])) * s.k1 + s.h * kHaze[c]) / 255.0;
        }
      }
    }
  f.ambient_sky = (sky / (kRings * kAzimuths)).cast<float>();
  f.ambient_ground = (ground / (kRings * kAzimuths)).cast<float>();
}

inline int mip_level(float lam) { return std::clamp(static_cast<int>(lam + 0.5f), 0, kTileLevels - 1); }

enum Mode { kModeBayer, kModeMono, kModeRgb, kModeRgba };

template <int kMode>
inline void put_rgb(std::uint8_t* row, int x, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  if constexpr (kMode == kModeMono) {
    row[x] = static_cast<std::uint8_t>((299 * r + 587 * g + 114 * b + 500) / 1000);
  } else if constexpr (kMode == kModeRgb) {
    row[3 * x] = r, row[3 * x + 1] = g, row[3 * x + 2] = b;
  } else {
    row[4 * x] = r, row[4 * x + 1] = g, row[4 * x + 2] = b, row[4 * x + 3] = 255;
  }
}

// A ground pixel from its filtered texel: only the Bayer site's channel, or all three.
template <int kMode>
inline void put_ground(std::uint8_t* row, int x, const int* chan, std::uint64_t g, float wood, float k1, float h) {
  const float a = static_cast<float>(g >> 48);
  const float sm = woods_weight(wood, a);
  if constexpr (kMode == kModeBayer) {
    row[x] = to_u8(ground_channel(g, chan[x & 1], a, sm, k1, h));
  } else {
    put_rgb<kMode>(row, x, to_u8(ground_channel(g, 0, a, sm, k1, h)), to_u8(ground_channel(g, 1, a, sm, k1, h)),
                   to_u8(ground_channel(g, 2, a, sm, k1, h)));
  }
}

template <int kMode>
inline void put_sky(std::uint8_t* row, int x, const int* chan, const float* c) {
  if constexpr (kMode == kModeBayer)
    row[x] = to_u8(c[chan[x & 1]]);
  else
    put_rgb<kMode>(row, x, to_u8(c[0]), to_u8(c[1]), to_u8(c[2]));
}

// A ground block: pixels [x0, x0 + n) (x0 even) of rows [y0, y1). Its first row starts at the 16.16
// texel coordinates (s, t), stepped by (ds, dt) per pixel; each next row starts (s_row, t_row)
// further and steps (dds, ddt) more per pixel. The woods, multiplier and haze terms (w, k, h)
// are bilinear over the block the same way. Per pixel exactly put_ground(sample_tile()) of the
// stepped values: with SSE2 four pixels at a time (the texel fetches stay scalar), the filter in
// 16-bit lanes with lerp64's rounding and the shading in float with put_ground's operations in
// its order, so every output format gets the same channel values. kWoods false: the caller knows
// that no pixel of the block is in the woods (woods weight 0), and then c k1 + h haze is exactly
// what the full formula gives.
struct GroundBlock {
  std::uint32_t s = 0, t = 0, ds = 0, dt = 0, s_row = 0, t_row = 0, dds = 0, ddt = 0;
  float w = 0, dw = 0, w_row = 0, ddw = 0, k = 0, dk = 0, k_row = 0, ddk = 0, h = 0, dh = 0, h_row = 0, ddh = 0;
};

#if defined(__SSE2__)
// ground_block's SSE2 parts: four pixels at a time, helpers as the AVX2 loop's below.
namespace ground_sse2 {

inline __m128i mul(__m128i v, std::uint32_t d) {  // v * d per 32-bit lane (low 32 bits), SSE2 has no pmulld
  const __m128i dd = _mm_set1_epi32(static_cast<int>(d));
  const __m128i even = _mm_mul_epu32(v, dd), odd = _mm_mul_epu32(_mm_srli_epi64(v, 32), dd);
  return _mm_unpacklo_epi32(_mm_shuffle_epi32(even, 0x08), _mm_shuffle_epi32(odd, 0x08));
}
inline __m128i ilin(std::uint32_t v, std::uint32_t d) {
  return _mm_add_epi32(_mm_set1_epi32(static_cast<int>(v)), mul(_mm_setr_epi32(0, 1, 2, 3), d));
}
inline __m128i i4(std::uint32_t d) {
  return _mm_set1_epi32(static_cast<int>(4u * d));
}
inline __m128 lin(float v, float d) {
  return _mm_add_ps(_mm_set1_ps(v), _mm_mul_ps(_mm_setr_ps(0.0f, 1.0f, 2.0f, 3.0f), _mm_set1_ps(d)));
}
inline __m128 f4(float d) {
  return _mm_set1_ps(4.0f * d);
}

// Row starts of 4 lanes and their per-row steps; per-pixel steps of 4 lanes (4 x the step) and theirs.
struct Lanes {
  __m128i s_start, t_start, ds4, dt4;
  const __m128i s_next, t_next, dds4, ddt4;
  __m128 w_start, k_start, h_start, dw4, dk4, dh4;
  const __m128 w_next, k_next, h_next, ddw4, ddk4, ddh4;
  explicit Lanes(const GroundBlock& g)
      : s_start(ilin(g.s, g.ds)),
        t_start(ilin(g.t, g.dt)),
        ds4(i4(g.ds)),
        dt4(i4(g.dt)),
        s_next(ilin(g.s_row, g.dds)),
        t_next(ilin(g.t_row, g.ddt)),
        dds4(i4(g.dds)),
        ddt4(i4(g.ddt)),
        w_start(lin(g.w, g.dw)),
        k_start(lin(g.k, g.dk)),
        h_start(lin(g.h, g.dh)),
        dw4(f4(g.dw)),
        dk4(f4(g.dk)),
        dh4(f4(g.dh)),
        w_next(lin(g.w_row, g.ddw)),
        k_next(lin(g.k_row, g.ddk)),
        h_next(lin(g.h_row, g.ddh)),
        ddw4(f4(g.ddw)),
        ddk4(f4(g.ddk)),
        ddh4(f4(g.ddh)) {}
  void next_row() {
    s_start = _mm_add_epi32(s_start, s_next), t_start = _mm_add_epi32(t_start, t_next);
    ds4 = _mm_add_epi32(ds4, dds4), dt4 = _mm_add_epi32(dt4, ddt4);
    w_start = _mm_add_ps(w_start, w_next), k_start = _mm_add_ps(k_start, k_next),
    h_start = _mm_add_ps(h_start, h_next);
    dw4 = _mm_add_ps(dw4, ddw4), dk4 = _mm_add_ps(dk4, ddk4), dh4 = _mm_add_ps(dh4, ddh4);
  }
};

// tiled_index(shift, x, y) = row(y) + col(x): 5 (((y / 4) << shift) + y % 4) + 20 (x / 4) + x % 4.
inline __m128i col(__m128i x) {
  const __m128i q = _mm_srli_epi32(x, 2);
  return _mm_add_epi32(_mm_add_epi32(_mm_slli_epi32(q, 4), _mm_slli_epi32(q, 2)),
                       _mm_and_si128(x, _mm_set1_epi32(3)));
}
inline __m128i row_of(__m128i y, __m128i row_shift) {
  const __m128i r =
      _mm_or_si128(_mm_sll_epi32(_mm_srli_epi32(y, 2), row_shift), _mm_and_si128(y, _mm_set1_epi32(3)));
  return _mm_add_epi32(_mm_slli_epi32(r, 2), r);
}
inline __m128i lerp16(__m128i a, __m128i b, __m128i wt) {
  const __m128i w256 = _mm_set1_epi16(256), half = _mm_set1_epi16(128);
  return _mm_srli_epi16(
      _mm_add_epi16(_mm_add_epi16(_mm_mullo_epi16(a, _mm_sub_epi16(w256, wt)), _mm_mullo_epi16(b, wt)), half),
      8);
}
// Weights of 4 pixels (32-bit lanes, 0..255) spread over the 4 channels of pixels 0-1 and 2-3.
inline void spread(__m128i wt, __m128i& lo, __m128i& hi) {
  const __m128i w16 = _mm_packs_epi32(wt, wt);
  const __m128i wd = _mm_unpacklo_epi16(w16, w16);
  lo = _mm_unpacklo_epi32(wd, wd), hi = _mm_unpackhi_epi32(wd, wd);
}
// Texels (x0, y) and (x0 + 1, y) of the 4 pixels, as [left of 0-3] and [right of 0-3].
inline void fetch(const std::uint32_t* tex, const std::uint32_t* ix, __m128i& left, __m128i& right) {
  auto pair = [tex](std::uint32_t i) { return _mm_loadl_epi64(reinterpret_cast<const __m128i*>(tex + i)); };
  const __m128i p01 = _mm_shuffle_epi32(_mm_unpacklo_epi64(pair(ix[0]), pair(ix[1])), 0xd8);
  const __m128i p23 = _mm_shuffle_epi32(_mm_unpacklo_epi64(pair(ix[2]), pair(ix[3])), 0xd8);
  left = _mm_unpacklo_epi64(p01, p23), right = _mm_unpackhi_epi64(p01, p23);
}
// The 4 bilinearly filtered RGBA8 texels at the 16.16 texel coordinates (sv, tv).
inline __m128i filtered(const std::uint32_t* tex, __m128i sv, __m128i tv, __m128i mask, __m128i row_shift) {
  const __m128i ff = _mm_set1_epi32(0xff), zero = _mm_setzero_si128();
  const __m128i x0v = _mm_and_si128(_mm_srli_epi32(sv, 16), mask);
  const __m128i y0v = _mm_and_si128(_mm_srli_epi32(tv, 16), mask);
  const __m128i y1v = _mm_and_si128(_mm_add_epi32(y0v, _mm_set1_epi32(1)), mask);
  alignas(16) std::uint32_t i0[4], i1[4];
  const __m128i c0 = col(x0v);
  _mm_store_si128(reinterpret_cast<__m128i*>(i0), _mm_add_epi32(row_of(y0v, row_shift), c0));
  _mm_store_si128(reinterpret_cast<__m128i*>(i1), _mm_add_epi32(row_of(y1v, row_shift), c0));
  __m128i a, b, c, d;
  fetch(tex, i0, a, b);
  fetch(tex, i1, c, d);
  __m128i wxl, wxh, wyl, wyh;
  spread(_mm_and_si128(_mm_srli_epi32(sv, 8), ff), wxl, wxh);
  spread(_mm_and_si128(_mm_srli_epi32(tv, 8), ff), wyl, wyh);
  const __m128i lo = lerp16(lerp16(_mm_unpacklo_epi8(a, zero), _mm_unpacklo_epi8(b, zero), wxl),
                            lerp16(_mm_unpacklo_epi8(c, zero), _mm_unpacklo_epi8(d, zero), wxl), wyl);
  const __m128i hi = lerp16(lerp16(_mm_unpackhi_epi8(a, zero), _mm_unpackhi_epi8(b, zero), wxh),
                            lerp16(_mm_unpackhi_epi8(c, zero), _mm_unpackhi_epi8(d, zero), wxh), wyh);
  return _mm_packus_epi16(lo, hi);
}
// The woods weight as put_ground's: a from the fine texture (the texels' alpha), sm its smoothstep.
inline void woods(__m128i v, __m128 wv, __m128& av, __m128& sm) {
  const __m128 f0 = _mm_setzero_ps(), f1 = _mm_set1_ps(1.0f), f2 = _mm_set1_ps(2.0f), f3 = _mm_set1_ps(3.0f);
  av = _mm_cvtepi32_ps(_mm_srli_epi32(v, 24));
  const __m128 z = _mm_min_ps(_mm_max_ps(_mm_add_ps(wv, _mm_mul_ps(av, _mm_set1_ps(kWoodA))), f0), f1);
  sm = _mm_mul_ps(_mm_mul_ps(z, z), _mm_sub_ps(f3, _mm_mul_ps(f2, z)));
}

// One channel per lane: ch_even for pixels 0 and 2, ch_odd for 1 and 3.
struct Channel {
  __m128i shift_even, shift_odd;
  __m128 base, slope, haze;
};
inline Channel make_channel(int ch_even, int ch_odd) {
  return Channel{
      _mm_cvtsi32_si128(8 * ch_even), _mm_cvtsi32_si128(8 * ch_odd),
      _mm_setr_ps(kWoodBase[ch_even], kWoodBase[ch_odd], kWoodBase[ch_even], kWoodBase[ch_odd]),
      _mm_setr_ps(kWoodSlope[ch_even], kWoodSlope[ch_odd], kWoodSlope[ch_even], kWoodSlope[ch_odd]),
      _mm_setr_ps(kHaze[ch_even], kHaze[ch_odd], kHaze[ch_even], kHaze[ch_odd])};
}
// One channel of 4 filtered texels, shaded as put_ground: 4 bytes in the low lane.
template <bool kWoods>
inline __m128i channel(__m128i v, __m128 a, __m128 sm, __m128 k1, __m128 hz, const Channel& ch) {
  const __m128i ff = _mm_set1_epi32(0xff), odd = _mm_setr_epi32(0, -1, 0, -1);
  const __m128i ce = _mm_and_si128(_mm_srl_epi32(v, ch.shift_even), ff);
  const __m128i co = _mm_and_si128(_mm_srl_epi32(v, ch.shift_odd), ff);
  const __m128 c = _mm_cvtepi32_ps(_mm_or_si128(_mm_andnot_si128(odd, ce), _mm_and_si128(odd, co)));
  __m128 val;
  if constexpr (kWoods) {
    const __m128 wood = _mm_add_ps(ch.base, _mm_mul_ps(ch.slope, a));
    val = _mm_add_ps(_mm_mul_ps(_mm_add_ps(c, _mm_mul_ps(sm, _mm_sub_ps(wood, c))), k1),
                     _mm_mul_ps(hz, ch.haze));
  } else {
    val = _mm_add_ps(_mm_mul_ps(c, k1), _mm_mul_ps(hz, ch.haze));
  }
  const __m128i q = _mm_cvttps_epi32(
      _mm_min_ps(_mm_add_ps(_mm_max_ps(val, _mm_setzero_ps()), _mm_set1_ps(0.5f)), _mm_set1_ps(255.0f)));
  return _mm_packus_epi16(_mm_packs_epi32(q, q), q);
}

template <int kMode, bool kWoods>
void ground_block(Image& out, PixelFormat fmt, int x0, int n, int y0, int y1, const std::uint32_t* tex, int shift,
                  const GroundBlock& g) {
  const __m128i mask = _mm_set1_epi32((1 << shift) - 1);
  const __m128i row_shift = _mm_cvtsi32_si128(shift);  // (y / 4) tiles of 2^(shift - 2) x 20 texels
  Lanes L(g);
  const __m128 f0 = _mm_setzero_ps();
  const Channel red = make_channel(0, 0), green = make_channel(1, 1), blue = make_channel(2, 2);
  Channel bayer_rows[2] = {red, red};  // by row parity; bayer_channel() is -1 but for Bayer
  if constexpr (kMode == kModeBayer)
    for (int r = 0; r < 2; ++r)
      bayer_rows[r] = make_channel(bayer_channel(fmt, 0, y0 + r), bayer_channel(fmt, 1, y0 + r));
  for (int y = y0; y < y1; ++y) {
    std::uint8_t* const row = out.row(y);
    const Channel& bayer = bayer_rows[(y - y0) & 1];
    __m128i sv = L.s_start, tv = L.t_start;
    __m128 wv = L.w_start, kv = L.k_start, hv = L.h_start;
    for (int i = 0; i < n; i += 4) {
      const __m128i v = filtered(tex, sv, tv, mask, row_shift);
      sv = _mm_add_epi32(sv, L.ds4), tv = _mm_add_epi32(tv, L.dt4);
      // Shading, as put_ground: woods weight from the fine texture, then each channel.
      __m128 av = f0, sm = f0;
      if constexpr (kWoods) woods(v, wv, av, sm);
      const __m128 k1 = kv, hz = hv;
      wv = _mm_add_ps(wv, L.dw4), kv = _mm_add_ps(kv, L.dk4), hv = _mm_add_ps(hv, L.dh4);
      const int m = std::min(4, n - i);
      if constexpr (kMode == kModeBayer) {
        const int bytes = _mm_cvtsi128_si32(channel<kWoods>(v, av, sm, k1, hz, bayer));
        if (m == 4)
          std::memcpy(row + x0 + i, &bytes, 4);
        else
          for (int j = 0; j < m; ++j) row[x0 + i + j] = static_cast<std::uint8_t>(bytes >> (8 * j));
      } else {
        const int r = _mm_cvtsi128_si32(channel<kWoods>(v, av, sm, k1, hz, red));
        const int gr = _mm_cvtsi128_si32(channel<kWoods>(v, av, sm, k1, hz, green));
        const int b = _mm_cvtsi128_si32(channel<kWoods>(v, av, sm, k1, hz, blue));
        for (int j = 0; j < m; ++j)
          put_rgb<kMode>(row, x0 + i + j, static_cast<std::uint8_t>(r >> (8 * j)),
                         static_cast<std::uint8_t>(gr >> (8 * j)), static_cast<std::uint8_t>(b >> (8 * j)));
      }
    }
    L.next_row();
  }
}

}  // namespace ground_sse2
#endif

template <int kMode, bool kWoods>
void ground_block(Image& out, PixelFormat fmt, int x0, int n, int y0, int y1, const std::uint32_t* tex,
                  int shift, const GroundBlock& g) {
#if defined(__SSE2__)
  ground_sse2::ground_block<kMode, kWoods>(out, fmt, x0, n, y0, y1, tex, shift, g);
#else
  GroundBlock r = g;
  for (int y = y0; y < y1; ++y) {
    const int chan[2] = {bayer_channel(fmt, 0, y), bayer_channel(fmt, 1, y)};
    std::uint32_t s = r.s, t = r.t;
    for (int i = 0; i < n; ++i) {
      const auto fi = static_cast<float>(i);
      put_ground<kMode>(out.row(y), x0 + i, chan, sample_tile(tex, shift, s, t), r.w + fi * r.dw, r.k + fi * r.dk,
                        r.h + fi * r.dh);
      s += r.ds, t += r.dt;
    }
    r.s += r.s_row, r.t += r.t_row, r.ds += r.dds, r.dt += r.ddt;
    r.w += r.w_row, r.k += r.k_row, r.h += r.h_row, r.dw += r.ddw, r.dk += r.ddk, r.dh += r.ddh;
  }
#endif
}

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define AUGRIG_GROUND_AVX2 1
// ground_block with AVX2, chosen at run time where the CPU has it: eight pixels at a time, lanes
// 0-3 and 4-7 each exactly what the SSE2 loop computes for its two 4-pixel steps (the stepped
// float terms of pixels 4-7 are those of 0-3 plus one more 4-pixel step, added as the SSE2 loop
// adds it; no FMA), so every byte is the same. Helpers are functions, not lambdas, so that all of
// them get the target.
#pragma GCC push_options
#pragma GCC target("avx2")
namespace ground_avx2 {

inline __m256i join(__m128i lo, __m128i hi) { return _mm256_inserti128_si256(_mm256_castsi128_si256(lo), hi, 1); }
inline __m256 join(__m128 lo, __m128 hi) { return _mm256_insertf128_ps(_mm256_castps128_ps256(lo), hi, 1); }
// tiled_index(shift, x, y) = row(y) + col(x), as the SSE2 loop.
inline __m256i col(__m256i x) {
  const __m256i q = _mm256_srli_epi32(x, 2);
  return _mm256_add_epi32(_mm256_add_epi32(_mm256_slli_epi32(q, 4), _mm256_slli_epi32(q, 2)),
                          _mm256_and_si256(x, _mm256_set1_epi32(3)));
}
inline __m256i row_of(__m256i y, __m128i row_shift) {
  const __m256i r = _mm256_or_si256(_mm256_sll_epi32(_mm256_srli_epi32(y, 2), row_shift),
                                    _mm256_and_si256(y, _mm256_set1_epi32(3)));
  return _mm256_add_epi32(_mm256_slli_epi32(r, 2), r);
}
inline __m256i lerp16(__m256i a, __m256i b, __m256i wt) {
  const __m256i w256 = _mm256_set1_epi16(256), half = _mm256_set1_epi16(128);
  return _mm256_srli_epi16(
      _mm256_add_epi16(_mm256_add_epi16(_mm256_mullo_epi16(a, _mm256_sub_epi16(w256, wt)), _mm256_mullo_epi16(b, wt)),
                       half),
      8);
}
// Weights of 8 pixels spread over the channels of pixels 0-1, 4-5 (lo) and 2-3, 6-7 (hi).
inline void spread(__m256i wt, __m256i& lo, __m256i& hi) {
  const __m256i w16 = _mm256_packs_epi32(wt, wt);
  const __m256i wd = _mm256_unpacklo_epi16(w16, w16);
  lo = _mm256_unpacklo_epi32(wd, wd), hi = _mm256_unpackhi_epi32(wd, wd);
}
inline __m128i pair(const std::uint32_t* tex, std::uint32_t i) {
  return _mm_loadl_epi64(reinterpret_cast<const __m128i*>(tex + i));
}
// Texels (x0, y) and (x0 + 1, y) of 4 pixels, as [left of 0-3] and [right of 0-3].
inline void fetch4(const std::uint32_t* tex, const std::uint32_t* ix, __m128i& left, __m128i& right) {
  const __m128i p01 = _mm_shuffle_epi32(_mm_unpacklo_epi64(pair(tex, ix[0]), pair(tex, ix[1])), 0xd8);
  const __m128i p23 = _mm_shuffle_epi32(_mm_unpacklo_epi64(pair(tex, ix[2]), pair(tex, ix[3])), 0xd8);
  left = _mm_unpacklo_epi64(p01, p23), right = _mm_unpackhi_epi64(p01, p23);
}
inline __m128i ilin(std::uint32_t v, std::uint32_t d) {
  return _mm_add_epi32(_mm_set1_epi32(static_cast<int>(v)),
                       _mm_mullo_epi32(_mm_setr_epi32(0, 1, 2, 3), _mm_set1_epi32(static_cast<int>(d))));
}
inline __m128i i4(std::uint32_t d) { return _mm_set1_epi32(static_cast<int>(4u * d)); }
inline __m128 lin(float v, float d) {
  return _mm_add_ps(_mm_set1_ps(v), _mm_mul_ps(_mm_setr_ps(0.0f, 1.0f, 2.0f, 3.0f), _mm_set1_ps(d)));
}
inline __m128 f4(float d) { return _mm_set1_ps(4.0f * d); }

struct Channel {
  __m128i shift_even, shift_odd;
  __m256 base, slope, haze;
};
inline Channel make_channel(int ch_even, int ch_odd) {
  const float be = kWoodBase[ch_even], bo = kWoodBase[ch_odd], se = kWoodSlope[ch_even], so = kWoodSlope[ch_odd];
  const float he = kHaze[ch_even], ho = kHaze[ch_odd];
  return Channel{_mm_cvtsi32_si128(8 * ch_even), _mm_cvtsi32_si128(8 * ch_odd), _mm256_setr_ps(be, bo, be, bo, be, bo, be, bo),
                 _mm256_setr_ps(se, so, se, so, se, so, se, so), _mm256_setr_ps(he, ho, he, ho, he, ho, he, ho)};
}
// One channel of 8 filtered texels, shaded as put_ground: 8 bytes in the low half.
template <bool kWoods>
inline __m128i channel(__m256i v, __m256 a, __m256 sm, __m256 k1, __m256 hz, const Channel& ch) {
  const __m256i ff = _mm256_set1_epi32(0xff), odd = _mm256_setr_epi32(0, -1, 0, -1, 0, -1, 0, -1);
  const __m256i ce = _mm256_and_si256(_mm256_srl_epi32(v, ch.shift_even), ff);
  const __m256i co = _mm256_and_si256(_mm256_srl_epi32(v, ch.shift_odd), ff);
  const __m256 c = _mm256_cvtepi32_ps(_mm256_or_si256(_mm256_andnot_si256(odd, ce), _mm256_and_si256(odd, co)));
  __m256 val;
  if constexpr (kWoods) {
    const __m256 wood = _mm256_add_ps(ch.base, _mm256_mul_ps(ch.slope, a));
    val = _mm256_add_ps(_mm256_mul_ps(_mm256_add_ps(c, _mm256_mul_ps(sm, _mm256_sub_ps(wood, c))), k1),
                        _mm256_mul_ps(hz, ch.haze));
  } else {
    val = _mm256_add_ps(_mm256_mul_ps(c, k1), _mm256_mul_ps(hz, ch.haze));
  }
  const __m256i q = _mm256_cvttps_epi32(
      _mm256_min_ps(_mm256_add_ps(_mm256_max_ps(val, _mm256_setzero_ps()), _mm256_set1_ps(0.5f)), _mm256_set1_ps(255.0f)));
  const __m128i q16 = _mm_packs_epi32(_mm256_castsi256_si128(q), _mm256_extracti128_si256(q, 1));
  return _mm_packus_epi16(q16, q16);
}

template <int kMode, bool kWoods>
[[gnu::noinline]] void ground_block(Image& out, PixelFormat fmt, int x0, int n, int y0, int y1, const std::uint32_t* tex,
                                    int shift, const GroundBlock& g) {
  const __m256i mask = _mm256_set1_epi32((1 << shift) - 1), one = _mm256_set1_epi32(1), ff = _mm256_set1_epi32(0xff);
  const __m256i zero = _mm256_setzero_si256();
  const __m128i row_shift = _mm_cvtsi32_si128(shift);
  // The SSE2 loop's 4-lane state, stepped from row to row as it steps it.
  __m128i s_start = ilin(g.s, g.ds), t_start = ilin(g.t, g.dt), ds4 = i4(g.ds), dt4 = i4(g.dt);
  const __m128i s_next = ilin(g.s_row, g.dds), t_next = ilin(g.t_row, g.ddt), dds4 = i4(g.dds), ddt4 = i4(g.ddt);
  __m128 w_start = lin(g.w, g.dw), k_start = lin(g.k, g.dk), h_start = lin(g.h, g.dh);
  __m128 dw4 = f4(g.dw), dk4 = f4(g.dk), dh4 = f4(g.dh);
  const __m128 w_next = lin(g.w_row, g.ddw), k_next = lin(g.k_row, g.ddk), h_next = lin(g.h_row, g.ddh);
  const __m128 ddw4 = f4(g.ddw), ddk4 = f4(g.ddk), ddh4 = f4(g.ddh);
  const __m256 kwa = _mm256_set1_ps(kWoodA), f0 = _mm256_setzero_ps(), f1 = _mm256_set1_ps(1.0f),
               f2 = _mm256_set1_ps(2.0f), f3 = _mm256_set1_ps(3.0f);
  const Channel red = make_channel(0, 0), green = make_channel(1, 1), blue = make_channel(2, 2);
  Channel bayer_rows[2] = {red, red};
  if constexpr (kMode == kModeBayer)
    for (int r = 0; r < 2; ++r) bayer_rows[r] = make_channel(bayer_channel(fmt, 0, y0 + r), bayer_channel(fmt, 1, y0 + r));
  for (int y = y0; y < y1; ++y) {
    std::uint8_t* const row = out.row(y);
    const Channel& bayer = bayer_rows[(y - y0) & 1];
    // Lanes 4-7 start one 4-pixel step on; each iteration takes two such steps.
    __m256i sv = join(s_start, _mm_add_epi32(s_start, ds4)), tv = join(t_start, _mm_add_epi32(t_start, dt4));
    const __m256i ds8 = join(_mm_add_epi32(ds4, ds4), _mm_add_epi32(ds4, ds4));
    const __m256i dt8 = join(_mm_add_epi32(dt4, dt4), _mm_add_epi32(dt4, dt4));
    __m256 wv = join(w_start, _mm_add_ps(w_start, dw4)), kv = join(k_start, _mm_add_ps(k_start, dk4)),
           hv = join(h_start, _mm_add_ps(h_start, dh4));
    const __m256 dw = join(dw4, dw4), dk = join(dk4, dk4), dh = join(dh4, dh4);
    for (int i = 0; i < n; i += 8) {
      const __m256i x0v = _mm256_and_si256(_mm256_srli_epi32(sv, 16), mask);
      const __m256i y0v = _mm256_and_si256(_mm256_srli_epi32(tv, 16), mask);
      const __m256i y1v = _mm256_and_si256(_mm256_add_epi32(y0v, one), mask);
      alignas(32) std::uint32_t i0[8], i1[8];
      const __m256i c0 = col(x0v);
      _mm256_store_si256(reinterpret_cast<__m256i*>(i0), _mm256_add_epi32(row_of(y0v, row_shift), c0));
      _mm256_store_si256(reinterpret_cast<__m256i*>(i1), _mm256_add_epi32(row_of(y1v, row_shift), c0));
      __m128i la, ra, lb, rb, lc, rc, ld, rd;
      fetch4(tex, i0, la, ra);
      fetch4(tex, i0 + 4, lb, rb);
      fetch4(tex, i1, lc, rc);
      fetch4(tex, i1 + 4, ld, rd);
      const __m256i a = join(la, lb), b = join(ra, rb), c = join(lc, ld), d = join(rc, rd);
      __m256i wxl, wxh, wyl, wyh;
      spread(_mm256_and_si256(_mm256_srli_epi32(sv, 8), ff), wxl, wxh);
      spread(_mm256_and_si256(_mm256_srli_epi32(tv, 8), ff), wyl, wyh);
      const __m256i lo = lerp16(lerp16(_mm256_unpacklo_epi8(a, zero), _mm256_unpacklo_epi8(b, zero), wxl),
                                lerp16(_mm256_unpacklo_epi8(c, zero), _mm256_unpacklo_epi8(d, zero), wxl), wyl);
      const __m256i hi = lerp16(lerp16(_mm256_unpackhi_epi8(a, zero), _mm256_unpackhi_epi8(b, zero), wxh),
                                lerp16(_mm256_unpackhi_epi8(c, zero), _mm256_unpackhi_epi8(d, zero), wxh), wyh);
      const __m256i v = _mm256_packus_epi16(lo, hi);  // the 8 filtered RGBA8 texels, in pixel order
      sv = _mm256_add_epi32(sv, ds8), tv = _mm256_add_epi32(tv, dt8);
      __m256 av = f0, sm = f0;
      if constexpr (kWoods) {
        av = _mm256_cvtepi32_ps(_mm256_srli_epi32(v, 24));
        const __m256 z = _mm256_min_ps(_mm256_max_ps(_mm256_add_ps(wv, _mm256_mul_ps(av, kwa)), f0), f1);
        sm = _mm256_mul_ps(_mm256_mul_ps(z, z), _mm256_sub_ps(f3, _mm256_mul_ps(f2, z)));
      }
      const __m256 k1 = kv, hz = hv;
      wv = _mm256_add_ps(_mm256_add_ps(wv, dw), dw), kv = _mm256_add_ps(_mm256_add_ps(kv, dk), dk),
      hv = _mm256_add_ps(_mm256_add_ps(hv, dh), dh);
      const int m = std::min(8, n - i);
      if constexpr (kMode == kModeBayer) {
        const __m128i bytes = channel<kWoods>(v, av, sm, k1, hz, bayer);
        if (m == 8) {
          _mm_storel_epi64(reinterpret_cast<__m128i*>(row + x0 + i), bytes);
        } else {
          alignas(16) std::uint8_t tmp[16];
          _mm_store_si128(reinterpret_cast<__m128i*>(tmp), bytes);
          for (int j = 0; j < m; ++j) row[x0 + i + j] = tmp[j];
        }
      } else {
        alignas(16) std::uint8_t r[16], gg[16], b8[16];
        _mm_store_si128(reinterpret_cast<__m128i*>(r), channel<kWoods>(v, av, sm, k1, hz, red));
        _mm_store_si128(reinterpret_cast<__m128i*>(gg), channel<kWoods>(v, av, sm, k1, hz, green));
        _mm_store_si128(reinterpret_cast<__m128i*>(b8), channel<kWoods>(v, av, sm, k1, hz, blue));
        for (int j = 0; j < m; ++j) put_rgb<kMode>(row, x0 + i + j, r[j], gg[j], b8[j]);
      }
    }
    s_start = _mm_add_epi32(s_start, s_next), t_start = _mm_add_epi32(t_start, t_next);
    ds4 = _mm_add_epi32(ds4, dds4), dt4 = _mm_add_epi32(dt4, ddt4);
    w_start = _mm_add_ps(w_start, w_next), k_start = _mm_add_ps(k_start, k_next), h_start = _mm_add_ps(h_start, h_next);
    dw4 = _mm_add_ps(dw4, ddw4), dk4 = _mm_add_ps(dk4, ddk4), dh4 = _mm_add_ps(dh4, ddh4);
  }
}

}  // namespace ground_avx2
#pragma GCC pop_options

std::atomic<bool> g_avx2_allowed{true};  // set_cpu_scene_avx2_for_testing()
bool cpu_has_avx2() {
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
}
#endif

// ground_block<kMode, kWoods>, with AVX2 where the CPU has it (the same bytes).
template <int kMode, bool kWoods>
void ground_block_any(Image& out, PixelFormat fmt, int x0, int n, int y0, int y1, const std::uint32_t* tex, int shift,
                      const GroundBlock& g) {
#if defined(AUGRIG_GROUND_AVX2)
  if (cpu_has_avx2() && g_avx2_allowed.load(std::memory_order_relaxed))
    return ground_avx2::ground_block<kMode, kWoods>(out, fmt, x0, n, y0, y1, tex, shift, g);
#endif
  ground_block<kMode, kWoods>(out, fmt, x0, n, y0, y1, tex, shift, g);
}

// ---- per camera, fixed ----

struct CameraTables {
  int width = 0, height = 0;
  VirtualPinhole vp;
  double near_m = 0.1;
  std::vector<float> col_x, row_y;  // undistorted: ray (col_x[u], row_y[v], 1)
  int nbx = 0, nby = 0;             // background blocks
  std::vector<int> node_x, node_y;  // node pixel coordinates, nbx + 1 and nby + 1
  std::vector<Eigen::Vector3d> node_ray;
  std::vector<double> node_ang;              // angle between neighbouring pixels at the node, rad
  std::vector<std::uint8_t> block_valid;     // every pixel of the block has a ray
  std::vector<Eigen::Vector2f> virtual_xy;   // distorted: raw pixel's ray in virtual pixels, NaN none
  int group = 0;                             // the lowest camera index with the same lens and orientation

  Eigen::Vector3d ray(int x, int y) const {
    if (vp.identity) return {col_x[x], row_y[y], 1.0};
    const Eigen::Vector2f& r = vp.ray_xy[static_cast<std::size_t>(y) * width + x];
    return {r.x(), r.y(), 1.0};
  }
};

// A texture of the receiver, with mipmaps, REPEAT wrapping (as OpenGL's default).
struct ModelTexture {
  Pyramid levels;
};

// A mesh of the scene's objects: the receiver's, or (render_with_boom) one of the boom's two parts.
enum Part { kReceiverPart, kBoomFixedPart, kBoomTelescopePart, kParts };
struct ReceiverMesh {
  const Mesh* mesh = nullptr;
  int texture = -1;  // index into textures_, -1 none
  bool cull = false;
  Part part = kReceiverPart;
};

// What shading a drawn triangle needs, relative to its first vertex: at a sample with weights b1,
// b2 of p1 and p2, a quantity q is q0 + b1 (q1 - q0) + b2 (q2 - q0).
struct TriShade {
  float lit0[3] = {}, dlit1[3] = {}, dlit2[3] = {};  // per-vertex light (Gouraud)
  // The boom's: the specular light that does not take the albedo's colour, 0..255 (the lit0 ...
  // above are then its SurfaceLight's scale, render/pbr.hpp), per vertex.
  float add0[3] = {}, dadd1[3] = {}, dadd2[3] = {};
  bool specular = false;
  float uv0[2] = {}, duv1[2] = {}, duv2[2] = {};
  float albedo[3] = {};  // base colour, 0..255
  const Pyramid* tex = nullptr;
  int level = 0;  // texture mip level
  int shadow = -1;  // index of its TriShadow (a receiver triangle the boom's shadow may reach), -1 none
  const std::uint32_t* texels = nullptr;  // of that level, tw x th
  int tw = 0, th = 0;
};

// A receiver triangle that the boom's shadow may reach (render_with_boom under a sun above the
// horizon), relative to its first vertex as TriShade: the per-vertex light without the sun's
// diffuse term (what a sample in the shadow gets) and the vertices in the shadow's sun frame.
struct TriShadow {
  float amb0[3] = {}, damb1[3] = {}, damb2[3] = {};
  Eigen::Vector3d q0 = Eigen::Vector3d::Zero(), dq1 = Eigen::Vector3d::Zero(), dq2 = Eigen::Vector3d::Zero();
  const BoomShadow* shadow = nullptr;
};

struct DrawnTriangle {
  RasterTriangle rt;
  TriShade shade;
};

// REPEAT wrapping of a texel coordinate far outside the texture (the rare case).
[[gnu::noinline]] int wrap_far(int i, int size) { return ((i % size) + size) % size; }

// Bilinear, REPEAT-wrapped sample of a receiver texture level (`texels` tiled as pyramid_index,
// w x h); `u`, `v` in texture units. The position goes to 24.8 fixed point with one conversion
// per axis (texel and weight from it).
[[gnu::always_inline]] inline std::uint64_t sample_texture(const std::uint32_t* texels, int w, int h, float u,
                                                           float v) {
  auto fixed = [](float c) {  // floor(c * 256), without a library call; far coordinates clamped (and NaN)
    const float f = std::min(std::max(-1.0e9f, c * 256.0f), 1.0e9f);
    const int i = static_cast<int>(f);
    return i - (f < static_cast<float>(i));
  };
  const int xf = fixed(u * static_cast<float>(w) - 0.5f), yf = fixed(v * static_cast<float>(h) - 0.5f);
  const auto wx = static_cast<std::uint32_t>(xf & 255), wy = static_cast<std::uint32_t>(yf & 255);
  // REPEAT: coordinates are nearly always within one period of the texture.
  auto wrap = [](int i, int size) {
    if (static_cast<unsigned>(i) < static_cast<unsigned>(size)) return i;
    if (i >= -size && i < 0) return i + size;
    return wrap_far(i, size);
  };
  const int x0 = wrap(xf >> 8, w), y0 = wrap(yf >> 8, h);  // arithmetic shift: floor
  const int x1 = x0 + 1 == w ? 0 : x0 + 1, y1 = y0 + 1 == h ? 0 : y0 + 1;
  const std::size_t row_tiles = static_cast<std::size_t>((w + 3) >> 2) << 4;
  auto row = [row_tiles](int y) { return static_cast<std::size_t>(y >> 2) * row_tiles + static_cast<std::size_t>((y & 3) << 2); };
  auto col = [](int x) { return static_cast<std::size_t>(((x >> 2) << 4) | (x & 3)); };
  const std::size_t r0 = row(y0), r1 = row(y1), c0 = col(x0), c1 = col(x1);
  return lerp64(lerp64(expand(texels[r0 + c0]), expand(texels[r0 + c1]), wx),
                lerp64(expand(texels[r1 + c0]), expand(texels[r1 + c1]), wx), wy);
}

// n covered samples along a row from raw pixel x, whose edge functions are e0, e1, e2 at the
// first and step by d0, d1, d2: only the Bayer site's channel, or all three, each the same
// arithmetic in every format.
// kShadow: `s` is the triangle's TriShadow, and a sample whose surface point the boom shades gets
// its ambient light only.
template <int kMode, bool kShadow>
void shade_run(std::uint8_t* row, int x, int n, const int* chan, const TriShade& t, const TriShadow* s, double e0,
               double e1, double e2, double d0, double d1, double d2) {
  for (int i = 0; i < n; ++i, ++x, e0 += d0, e1 += d1, e2 += d2) {
    const double inv = 1.0 / (e0 + e1 + e2);
    const auto b1 = static_cast<float>(e2 * inv), b2 = static_cast<float>(e0 * inv);
    const float *lit0 = t.lit0, *dlit1 = t.dlit1, *dlit2 = t.dlit2;
    if constexpr (kShadow) {
      const Eigen::Vector3d q = s->q0 + (e2 * inv) * s->dq1 + (e0 * inv) * s->dq2;
      if (s->shadow->may_cover(q.x(), q.y()) && s->shadow->in_shadow_sun(q))
        lit0 = s->amb0, dlit1 = s->damb1, dlit2 = s->damb2;
    } else {
      (void)s;
    }
    std::uint64_t g = 0;
    if (t.tex)
      g = sample_texture(t.texels, t.tw, t.th, t.uv0[0] + b1 * t.duv1[0] + b2 * t.duv2[0],
                         t.uv0[1] + b1 * t.duv1[1] + b2 * t.duv2[1]);
    auto value = [&](int c) {
      const float albedo = t.tex ? t.albedo[c] * (static_cast<float>(lane(g, c)) * (1.0f / 255.0f)) : t.albedo[c];
      const float v = albedo * (lit0[c] + b1 * dlit1[c] + b2 * dlit2[c]);
      return to_u8(t.specular ? v + (t.add0[c] + b1 * t.dadd1[c] + b2 * t.dadd2[c]) : v);
    };
    if constexpr (kMode == kModeBayer)
      row[x] = value(chan[x & 1]);
    else
      put_rgb<kMode>(row, x, value(0), value(1), value(2));
  }
}

class Bands {
 public:
  explicit Bands(int n) : n_(std::clamp(n, 1, 8)) {
    for (int i = 1; i < n_; ++i) workers_.emplace_back([this, i] { loop(i); });
  }
  ~Bands() {
    {
      std::lock_guard lock(m_);
      stop_ = true;
    }
    cv_.notify_all();
    for (auto& t : workers_) t.join();
  }
  int count() const { return n_; }
  // fn(band) for every band, band 0 on the calling thread; returns when all are done.
  void run(const std::function<void(int)>& fn) {
    if (n_ == 1) return fn(0);
    {
      std::lock_guard lock(m_);
      fn_ = &fn;
      pending_ = n_ - 1;
      ++generation_;
    }
    cv_.notify_all();
    fn(0);
    std::unique_lock lock(m_);
    done_cv_.wait(lock, [this] { return pending_ == 0; });
    fn_ = nullptr;
  }

 private:
  void loop(int band) {
    std::uint64_t seen = 0;
    for (;;) {
      const std::function<void(int)>* fn = nullptr;
      {
        std::unique_lock lock(m_);
        cv_.wait(lock, [&] { return stop_ || generation_ != seen; });
        if (stop_) return;
        seen = generation_;
        fn = fn_;
      }
      (*fn)(band);
      std::lock_guard lock(m_);
      if (--pending_ == 0) done_cv_.notify_one();
    }
  }
  int n_;
  std::vector<std::thread> workers_;
  std::mutex m_;
  std::condition_variable cv_, done_cv_;
  const std::function<void(int)>* fn_ = nullptr;
  int pending_ = 0;
  std::uint64_t generation_ = 0;
  bool stop_ = false;
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

// Sensor noise: a field of 2^23 precomputed samples, each row reading it from a random offset.
constexpr std::size_t kNoiseField = std::size_t{1} << 23;
constexpr std::size_t kNoiseTail = 4 * static_cast<std::size_t>(kMaxImageSidePx);  // one RGBA row past the end

// d[i] = clamp(d[i] + noise[i], 0, 255); `skip_alpha`: every 4th byte (RGBA's alpha) stays.
void add_saturated(std::uint8_t* d, const std::int8_t* noise, std::size_t n, bool skip_alpha) {
  std::size_t i = 0;
#if defined(__SSE2__)
  if (!skip_alpha) {
    // 16 bytes at a time: offset to signed, saturating add, back (x ^ 0x80 maps 0..255 to -128..127).
    const __m128i bias = _mm_set1_epi8(static_cast<char>(0x80));
    for (; i + 16 <= n; i += 16) {
      const __m128i v = _mm_xor_si128(_mm_loadu_si128(reinterpret_cast<const __m128i*>(d + i)), bias);
      const __m128i r = _mm_xor_si128(_mm_adds_epi8(v, _mm_loadu_si128(reinterpret_cast<const __m128i*>(noise + i))), bias);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(d + i), r);
    }
  }
#endif
  for (; i < n; ++i) {
    if (skip_alpha && (i & 3) == 3) continue;
    const int v = d[i] + noise[i];
    d[i] = static_cast<std::uint8_t>(v < 0 ? 0 : v > 255 ? 255 : v);
  }
}

inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

bool same_lens(const CameraModel& a, const CameraModel& b) {
  return a.width_px == b.width_px && a.height_px == b.height_px && a.fx_px == b.fx_px && a.fy_px == b.fy_px &&
         a.cx_px == b.cx_px && a.cy_px == b.cy_px && a.distortion == b.distortion && a.coeffs == b.coeffs;
}

}  // namespace

Expected<Model> load_scene_receiver(const Rig& rig, std::shared_ptr<const Model> given, bool& builtin) {
  builtin = false;
  if (given) return Model(*given);
  if (rig.receiver.model.path.empty()) {
    builtin = true;
    return make_builtin_receiver();
  }
  auto m = load_model(rig.receiver.model);
  if (!m) return make_error("SyntheticSceneRenderer::create(): ", m.error().message);
  return std::move(*m);
}

namespace {

class CpuSceneRenderer final : public SyntheticSceneRenderer {
 public:
  CpuSceneRenderer(const Rig& rig, int threads) : rig_(rig), bands_(threads) {}
  Status init(std::shared_ptr<const Model> receiver);
  Status render(int camera, const SkyState& sky, const Pose& T_body_receiver, bool receiver_present,
                const SensorOptions& sensor, Image& out) override {
    return render_view(camera, sky, T_body_receiver, receiver_present, nullptr, {}, sensor, out);
  }
  using SyntheticSceneRenderer::render_with_boom;
  Status render_with_boom(int camera, const SkyState& sky, const Pose& T_body_receiver, bool receiver_present,
                          const BoomArticulation& boom, const BoomArticulation& boom_rate_per_s,
                          const SensorOptions& sensor, Image& out) override {
    return render_view(camera, sky, T_body_receiver, receiver_present, &boom, boom_rate_per_s, sensor, out);
  }

 private:
  template <int kMode>
  void background_rows(const CameraTables& ct, const FrameSky& f, int by0, int by1, PixelFormat fmt, Image& out) const;
  void background(const CameraTables& ct, const FrameSky& f, PixelFormat fmt, Image& out);
  Status render_view(int camera, const SkyState& sky, const Pose& T_body_receiver, bool receiver_present,
                     const BoomArticulation* boom, const BoomArticulation& boom_rate_per_s,
                     const SensorOptions& sensor, Image& out);
  // The clean render averaged over the exposure's sub-exposure instants (motion blur).
  void render_moving(int camera, const SkyState& sky, std::array<std::optional<Pose>, kParts> T_body_part,
                     const BoomArticulation& boom, const BoomArticulation& boom_rate_per_s, double exposure_s,
                     int samples, PixelFormat fmt, Image& out);
  // The clean render (no noise) of a view: background, then the objects placed (a part without
  // a pose is not drawn).
  void render_clean(int camera, const SkyState& sky, const std::array<std::optional<Pose>, kParts>& T_body_part,
                    PixelFormat fmt, Image& out);
  // init()'s parts: the receiver and the boom with their meshes; one camera's tables; its
  // background nodes (rays and angular sizes every kBlock pixels) and the blocks with valid rays.
  Status load_models(std::shared_ptr<const Model> receiver);
  Status init_camera(std::size_t c);
  static void init_background_nodes(CameraTables& ct, const CameraModel& cm);
  void add_mesh(const Mesh& m, bool cull, Part part, std::vector<const Texture*>& seen);
  void draw_objects(const CameraTables& ct, const RigCamera& cam, const FrameSky& f,
                    const std::array<std::optional<Pose>, kParts>& T_body_part, PixelFormat fmt, Image& out);
  // draw_objects' steps: the placed vertices in the camera frame and their light (with `ambient`
  // also the light without the sun's diffuse term); the boom's shadow (false: none cast); the
  // triangles set up and rasterised (returns the box of covered samples); their samples shaded
  // into the raw pixels; the scratch cleared.
  void light_vertices(const RigCamera& cam, const FrameSky& f,
                      const std::array<std::optional<Pose>, kParts>& T_body_part, bool ambient);
  bool build_shadow(const Eigen::Vector3d& sun_cam, const std::array<std::optional<Pose>, kParts>& T_body_part);
  SampleBox raster_objects(const CameraTables& ct, const std::array<std::optional<Pose>, kParts>& T_body_part,
                           bool shadowed);
  void shade_objects(const CameraTables& ct, const RigCamera& cam, const SampleBox& box, PixelFormat fmt, Image& out);
  void clear_samples(const CameraTables& ct, const SampleBox& box);
  void add_noise(int camera, const SensorOptions& sensor, Image& out);

  Rig rig_;
  Bands bands_;
  std::shared_ptr<const GroundTile> tile_;
  Model receiver_;
  BoomModel boom_;  // drawn by render_with_boom only
  std::vector<ReceiverMesh> meshes_;
  Image radiance_;  // the clean render that a camera response turns into the frame
  Image instant_;   // render_moving(): one sub-exposure instant
  std::vector<std::uint32_t> exposure_sum_;  // ... and their sum, per byte
  std::vector<ModelTexture> textures_;
  std::vector<CameraTables> cameras_;
  std::vector<float> gauss_;  // 65536 quantiles of N(0, 1): 16 random bits -> one Gaussian sample
  std::vector<std::int8_t> noise_field_;  // sensor noise in whole DN for noise_sigma_ (add_noise)
  double noise_sigma_ = -1;

  // Receiver scratch, sized to the largest virtual image: 1/z and triangle id + 1 per sample
  // (zero outside the last frame's box).
  std::vector<float> inv_z_;
  std::vector<std::uint32_t> ids_;
  // One bit per sample, set where ids_ is: the scan and the clearing touch the covered samples
  // only (a fraction of the receiver's box, whose id rows are mostly out of cache by then).
  std::vector<std::uint64_t> covered_;
  std::vector<Eigen::Vector3d> verts_cam_;
  std::vector<Eigen::Vector3f> light_front_, light_back_;
  std::vector<Eigen::Vector3f> ambient_front_, ambient_back_;  // without the sun: filled when a shadow is cast
  // The boom's specular light per vertex (SurfaceLight::add times 255; light_* hold its scale), 0
  // for the receiver's vertices.
  std::vector<Eigen::Vector3f> add_front_, add_back_;
  std::vector<std::size_t> vert_offset_;
  std::vector<DrawnTriangle> tris_;
  // The boom's shadow on the receiver (render_with_boom, sun above the horizon), in the camera
  // frame: its triangles, its sun-frame footprint (u, v bounds) and the receiver triangles it may reach.
  BoomShadow shadow_;
  std::vector<Eigen::Vector3d> shadow_tris_;
  Eigen::Vector2d shadow_lo_ = Eigen::Vector2d::Zero(), shadow_hi_ = Eigen::Vector2d::Zero();
  std::vector<TriShadow> tri_shadows_;

  // The last background of a camera group, for the other cameras of the group in the same frame.
  struct SharedKey {
    int group = -1;
    PixelFormat format = PixelFormat::kRGB8;
    SkyState sky;
  };
  SharedKey shared_key_;
  std::vector<std::uint8_t> shared_bg_;
};

void CpuSceneRenderer::add_mesh(const Mesh& m, bool cull, Part part, std::vector<const Texture*>& seen) {
  ReceiverMesh rm;
  rm.mesh = &m;
  rm.cull = cull;
  rm.part = part;
  if (m.texture && m.texture->width > 0 && m.texture->height > 0 && !m.uvs.empty()) {
    const auto it = std::find(seen.begin(), seen.end(), m.texture.get());
    if (it != seen.end()) {
      rm.texture = static_cast<int>(it - seen.begin());
    } else {
      const Texture& t = *m.texture;
      std::vector<std::uint32_t> packed(static_cast<std::size_t>(t.width) * t.height);
      for (std::size_t i = 0; i < packed.size(); ++i) std::memcpy(&packed[i], &t.rgba[4 * i], 4);
      textures_.push_back({make_pyramid(std::move(packed), t.width, t.height, 16)});
      seen.push_back(m.texture.get());
      rm.texture = static_cast<int>(textures_.size()) - 1;
    }
  }
  meshes_.push_back(rm);
}

Status CpuSceneRenderer::init(std::shared_ptr<const Model> receiver) {
  if (rig_.cameras.empty()) return make_error("SyntheticSceneRenderer::create(): the rig has no cameras");
  if (auto st = load_models(std::move(receiver)); !st) return st;
  std::size_t max_samples = 0;
  cameras_.resize(rig_.cameras.size());
  for (std::size_t c = 0; c < rig_.cameras.size(); ++c) {
    if (auto st = init_camera(c); !st) return st;
    max_samples =
        std::max(max_samples, static_cast<std::size_t>(cameras_[c].vp.width) * cameras_[c].vp.height);
  }
  inv_z_.assign(max_samples, 0.0f);
  ids_.assign(max_samples, 0u);
  std::size_t max_words = 0;
  for (const CameraTables& ct : cameras_)
    max_words = std::max(max_words, static_cast<std::size_t>(ct.vp.height) * ((ct.vp.width + 63) / 64));
  covered_.assign(max_words, 0u);

  gauss_.resize(65536);
  for (std::size_t i = 0; i < gauss_.size(); ++i)
    gauss_[i] = static_cast<float>(normal_quantile((static_cast<double>(i) + 0.5) / 65536.0));
  tile_ = ground_tile();
  return {};
}

Status CpuSceneRenderer::load_models(std::shared_ptr<const Model> receiver) {
  bool builtin = false;
  auto rec = load_scene_receiver(rig_, std::move(receiver), builtin);
  if (!rec) return rec.error();
  receiver_ = std::move(*rec);
  // The boom as the augmenter has it (render/augmenter.cpp): the rig's model file as one rigid
  // part, or the built-in boom's two parts.
  if (rig_.boom.model.path.empty()) {
    boom_ = make_builtin_boom();
  } else {
    auto m = load_model(rig_.boom.model);
    if (!m) return make_error("SyntheticSceneRenderer::create(): ", m.error().message);
    boom_.fixed = std::move(*m);
  }
  apply_boom_material(boom_, rig_.boom.material);
  // Textures with mipmaps, shared between the meshes that share them. Consistently wound built-in
  // receiver meshes can be culled; files may not be, nor the boom (its ends are open tubes).
  std::vector<const Texture*> seen;
  for (const Mesh& m : receiver_.meshes) add_mesh(m, builtin, kReceiverPart, seen);
  for (const Mesh& m : boom_.fixed.meshes) add_mesh(m, false, kBoomFixedPart, seen);
  for (const Mesh& m : boom_.telescope.meshes) add_mesh(m, false, kBoomTelescopePart, seen);
  return {};
}

Status CpuSceneRenderer::init_camera(std::size_t c) {
  const RigCamera& cam = rig_.cameras[c];
  const CameraModel& cm = cam.model;
  if (cm.width_px <= 0 || cm.height_px <= 0)
    return make_error("SyntheticSceneRenderer::create(): camera ", c, " has no image size");
  CameraTables& ct = cameras_[c];
  ct.width = cm.width_px, ct.height = cm.height_px;
  ct.near_m = cam.near_m;
  auto vp = make_virtual_pinhole(cm, 1.0, false, cam.name);
  if (!vp) return vp.error();
  ct.vp = std::move(*vp);
  const int W = ct.width, H = ct.height;
  if (ct.vp.identity) {
    ct.col_x.resize(W), ct.row_y.resize(H);
    for (int u = 0; u < W; ++u) ct.col_x[u] = static_cast<float>((u - ct.vp.cx) / ct.vp.fx);
    for (int v = 0; v < H; ++v) ct.row_y[v] = static_cast<float>((v - ct.vp.cy) / ct.vp.fy);
  } else {
    ct.virtual_xy.resize(static_cast<std::size_t>(W) * H);
    for (std::size_t i = 0; i < ct.virtual_xy.size(); ++i) {
      const Eigen::Vector2f& r = ct.vp.ray_xy[i];
      ct.virtual_xy[i] = Eigen::Vector2f::Constant(NAN);
      if (std::isfinite(r.x()) && std::isfinite(r.y()))
        ct.virtual_xy[i] = ct.vp.to_virtual(r.cast<double>()).cast<float>();
    }
  }
  init_background_nodes(ct, cm);
  ct.group = static_cast<int>(c);
  for (std::size_t o = 0; o < c; ++o)
    if (same_lens(rig_.cameras[o].model, cm) &&
        (rig_.cameras[o].T_body_cam.R() - cam.T_body_cam.R()).cwiseAbs().maxCoeff() < 1e-12) {
      ct.group = static_cast<int>(o);
      break;
    }
  return {};
}

void CpuSceneRenderer::init_background_nodes(CameraTables& ct, const CameraModel& cm) {
  const int W = ct.width, H = ct.height;
  // Background nodes every kBlock pixels, the last row and column on the image's last pixel.
  ct.nbx = (W + kBlock - 1) / kBlock, ct.nby = (H + kBlock - 1) / kBlock;
  for (int k = 0; k <= ct.nbx; ++k) ct.node_x.push_back(std::min(k * kBlock, W - 1));
  for (int k = 0; k <= ct.nby; ++k) ct.node_y.push_back(std::min(k * kBlock, H - 1));
  const int nnx = ct.nbx + 1;
  ct.node_ray.resize(static_cast<std::size_t>(nnx) * (ct.nby + 1));
  ct.node_ang.resize(ct.node_ray.size());
  auto unit = [&ct](int x, int y) {
    const Eigen::Vector3d r = ct.ray(x, y);
    return std::isfinite(r.x()) && std::isfinite(r.y()) ? Eigen::Vector3d(r.normalized())
                                                        : Eigen::Vector3d::Constant(NAN);
  };
  for (int j = 0; j <= ct.nby; ++j)
    for (int i = 0; i < nnx; ++i) {
      const int x = ct.node_x[i], y = ct.node_y[j];
      const std::size_t n = static_cast<std::size_t>(j) * nnx + i;
      ct.node_ray[n] = ct.ray(x, y);
      // The angle to the neighbouring pixels: the pixel's angular size through the lens.
      const Eigen::Vector3d d = unit(x, y), dx = unit(x > 0 ? x - 1 : x + 1, y),
                            dy = unit(x, y > 0 ? y - 1 : y + 1);
      double ang =
          std::max(std::acos(std::clamp(d.dot(dx), -1.0, 1.0)), std::acos(std::clamp(d.dot(dy), -1.0, 1.0)));
      ct.node_ang[n] = std::isfinite(ang) ? ang : 1.0 / cm.fx_px;
    }
  ct.block_valid.assign(static_cast<std::size_t>(ct.nbx) * ct.nby, 1);
  if (!ct.vp.identity)
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        if (!std::isfinite(ct.vp.ray_xy[static_cast<std::size_t>(y) * W + x].x()))
          ct.block_valid[static_cast<std::size_t>(y / kBlock) * ct.nbx + x / kBlock] = 0;
}

// Background of the block rows [by0, by1).
template <int kMode>
void CpuSceneRenderer::background_rows(const CameraTables& ct, const FrameSky& f, int by0, int by1, PixelFormat fmt,
                                       Image& out) const {
  const int nnx = ct.nbx + 1;
  // The node rows this band needs, shaded exactly.
  std::vector<RaySample> nodes(static_cast<std::size_t>(by1 - by0 + 1) * nnx);
  for (int j = by0; j <= by1; ++j)
    for (int i = 0; i < nnx; ++i) {
      const std::size_t n = static_cast<std::size_t>(j) * nnx + i;
      nodes[static_cast<std::size_t>(j - by0) * nnx + i] = sample_ray(ct.node_ray[n], ct.node_ang[n], f);
    }
  for (int by = by0; by < by1; ++by) {
    const int y0 = by * kBlock, y1 = std::min(y0 + kBlock, ct.height);
    const int ny0 = ct.node_y[by];
    const double span_y = std::max(1, ct.node_y[by + 1] - ny0);
    for (int bx = 0; bx < ct.nbx; ++bx) {
      const int x0 = bx * kBlock, x1 = std::min(x0 + kBlock, ct.width);
      const double span_x = std::max(1, ct.node_x[bx + 1] - ct.node_x[bx]);
      const RaySample* top = &nodes[static_cast<std::size_t>(by - by0) * nnx + bx];
      const RaySample& c00 = top[0];
      const RaySample& c10 = top[1];
      const RaySample& c01 = top[nnx];
      const RaySample& c11 = top[nnx + 1];
      const bool valid = ct.block_valid[static_cast<std::size_t>(by) * ct.nbx + bx] && c00.valid && c10.valid &&
                         c01.valid && c11.valid;
      const int n_ground = c00.ground + c10.ground + c01.ground + c11.ground;
      if (valid && n_ground == 4) {
        // Ground: the tile sampled at the block's coarsest corner level (no aliasing anywhere in
        // it), its coordinates interpolated from the corners (the ground plane's projection is
        // smooth over a block), stepped in 16.16 fixed point along each row.
        const int level = std::max({mip_level(c00.lam), mip_level(c10.lam), mip_level(c01.lam), mip_level(c11.lam)});
        const int shift = kTileShift - level;
        const std::uint32_t* tex = tile_->levels[level].data();
        // The woods weight is 0 at every pixel when the woods field plus the fine texture's most
        // (255 kWoodA) stays below 0 at the corners (the field is interpolated between them).
        const bool woods = std::max({c00.wood, c10.wood, c01.wood, c11.wood}) + 255.0f * kWoodA > -0.01f;
        const double scale = 1.0 / (kTexelM * static_cast<double>(1 << level));
        // Relative to the block's first corner, so that the doubles stay small.
        const double s0 = std::floor(c00.qs * scale), t0 = std::floor(c00.qt * scale);
        auto S = [&](const RaySample& c) { return c.qs * scale - s0 - 0.5; };
        auto T = [&](const RaySample& c) { return c.qt * scale - t0 - 0.5; };
        const double s00 = S(c00), s10 = S(c10), s01 = S(c01), s11 = S(c11);
        const double t00 = T(c00), t10 = T(c10), t01 = T(c01), t11 = T(c11);
        // The wrap offset in whole tiles: s0 modulo the level's side, so fixed point stays in range.
        const double side = static_cast<double>(1 << shift);
        const double s_off = s0 - side * std::floor(s0 / side), t_off = t0 - side * std::floor(t0 / side);
        // Bilinear over the block: the first row's start and step, and their changes per row.
        const double inv_span_y = 1.0 / span_y, fixed_per_x = 65536.0 / span_x;
        const double fy0 = (y0 - ny0) * inv_span_y;
        const double sl = s00 + fy0 * (s01 - s00), sr = s10 + fy0 * (s11 - s10);
        const double tl = t00 + fy0 * (t01 - t00), tr = t10 + fy0 * (t11 - t10);
        auto fixed = [](double v) { return static_cast<std::uint32_t>(round_to_int64(v)); };
        GroundBlock g;
        g.s = to_fixed(sl + s_off), g.t = to_fixed(tl + t_off);
        g.ds = fixed((sr - sl) * fixed_per_x), g.dt = fixed((tr - tl) * fixed_per_x);
        g.s_row = fixed((s01 - s00) * inv_span_y * 65536.0), g.t_row = fixed((t01 - t00) * inv_span_y * 65536.0);
        g.dds = fixed(((s11 - s10) - (s01 - s00)) * inv_span_y * fixed_per_x);
        g.ddt = fixed(((t11 - t10) - (t01 - t00)) * inv_span_y * fixed_per_x);
        const auto fyf = static_cast<float>(fy0), fry = static_cast<float>(inv_span_y);
        const auto inv = static_cast<float>(1.0 / span_x);
        auto terms = [&](float a00, float a10, float a01, float a11, float& v, float& dv, float& v_row, float& ddv) {
          const float l = a00 + fyf * (a01 - a00), r = a10 + fyf * (a11 - a10);
          v = l, dv = (r - l) * inv, v_row = (a01 - a00) * fry, ddv = ((a11 - a10) - (a01 - a00)) * fry * inv;
        };
        terms(c00.wood, c10.wood, c01.wood, c11.wood, g.w, g.dw, g.w_row, g.ddw);
        terms(c00.k1, c10.k1, c01.k1, c11.k1, g.k, g.dk, g.k_row, g.ddk);
        terms(c00.h, c10.h, c01.h, c11.h, g.h, g.dh, g.h_row, g.ddh);
        if (woods)
          ground_block_any<kMode, true>(out, fmt, x0, x1 - x0, y0, y1, tex, shift, g);
        else
          ground_block_any<kMode, false>(out, fmt, x0, x1 - x0, y0, y1, tex, shift, g);
      } else if (valid && n_ground == 0) {
        // Sky: smooth (the sun's glow is several blocks wide); the colour is interpolated.
        for (int y = y0; y < y1; ++y) {
          const auto fy = static_cast<float>((y - ny0) / span_y);
          float l[3], d[3];
          for (int k = 0; k < 3; ++k) {
            l[k] = c00.sky[k] + fy * (c01.sky[k] - c00.sky[k]);
            d[k] = (c10.sky[k] + fy * (c11.sky[k] - c10.sky[k]) - l[k]) / static_cast<float>(span_x);
          }
          std::uint8_t* row = out.row(y);
          const int chan[2] = {bayer_channel(fmt, 0, y), bayer_channel(fmt, 1, y)};
          for (int x = x0; x < x1; ++x) {
            put_sky<kMode>(row, x, chan, l);
            for (int k = 0; k < 3; ++k) l[k] += d[k];
          }
        }
      } else {
        // The horizon or the lens's invalid border crosses the block: every pixel exactly.
        const double ang = ct.node_ang[static_cast<std::size_t>(by) * nnx + bx];
        for (int y = y0; y < y1; ++y) {
          std::uint8_t* row = out.row(y);
          const int chan[2] = {bayer_channel(fmt, 0, y), bayer_channel(fmt, 1, y)};
          for (int x = x0; x < x1; ++x) {
            const RaySample r = sample_ray(ct.ray(x, y), ang, f);
            if (!r.valid) {
              const float black[3] = {0, 0, 0};
              put_sky<kMode>(row, x, chan, black);
            } else if (r.ground) {
              const int level = mip_level(r.lam);
              const double scale = 1.0 / (kTexelM * static_cast<double>(1 << level));
              const int shift = kTileShift - level;
              const double side = static_cast<double>(1 << shift);
              auto wrap = [side](double v) { return v - side * std::floor(v / side); };
              const std::uint64_t g = sample_tile(tile_->levels[level].data(), shift, to_fixed(wrap(r.qs * scale) - 0.5),
                                                  to_fixed(wrap(r.qt * scale) - 0.5));
              put_ground<kMode>(row, x, chan, g, r.wood, r.k1, r.h);
            } else {
              put_sky<kMode>(row, x, chan, r.sky.data());
            }
          }
        }
      }
    }
  }
}

void CpuSceneRenderer::background(const CameraTables& ct, const FrameSky& f, PixelFormat fmt, Image& out) {
  const int bands = bands_.count();
  bands_.run([&](int band) {
    const int by0 = ct.nby * band / bands, by1 = ct.nby * (band + 1) / bands;
    if (by0 >= by1) return;
    if (is_bayer(fmt))
      background_rows<kModeBayer>(ct, f, by0, by1, fmt, out);
    else if (fmt == PixelFormat::kMono8)
      background_rows<kModeMono>(ct, f, by0, by1, fmt, out);
    else if (fmt == PixelFormat::kRGB8)
      background_rows<kModeRgb>(ct, f, by0, by1, fmt, out);
    else
      background_rows<kModeRgba>(ct, f, by0, by1, fmt, out);
  });
}


void CpuSceneRenderer::draw_objects(const CameraTables& ct, const RigCamera& cam, const FrameSky& f,
                                    const std::array<std::optional<Pose>, kParts>& T_body_part, PixelFormat fmt,
                                    Image& out) {
  // The boom shades the receiver only where it is drawn with it under a sun above the horizon.
  const bool boom_drawn = T_body_part[kBoomFixedPart] || T_body_part[kBoomTelescopePart];
  const bool may_shade = boom_drawn && T_body_part[kReceiverPart] && f.sun.z() < 0;
  light_vertices(cam, f, T_body_part, may_shade);
  const bool shadowed = may_shade && build_shadow(f.R_ned_cam.transpose() * f.sun, T_body_part);
  const SampleBox box = raster_objects(ct, T_body_part, shadowed);
  if (box.x0 >= box.x1 || box.y0 >= box.y1) return;
  shade_objects(ct, cam, box, fmt, out);
  clear_samples(ct, box);
}

void CpuSceneRenderer::light_vertices(const RigCamera& cam, const FrameSky& f,
                                      const std::array<std::optional<Pose>, kParts>& T_body_part, bool ambient) {
  const Eigen::Matrix3d R_cam_ned = f.R_ned_cam.transpose();
  const Eigen::Vector3f sun_cam = (R_cam_ned * f.sun).cast<float>();
  const Eigen::Vector3f up_cam = (R_cam_ned * Eigen::Vector3d(0, 0, -1)).cast<float>();
  // Per vertex light (Gouraud): the sun (Lambert) and the hemispherical sky/ground ambient of the
  // OpenGL shader; a back face seen (meshes not culled) is lit from its other side.
  // A sun below the horizon lights nothing directly.
  const float sun_up = f.sun.z() < 0 ? 1.0f : 0.0f;
  auto sky_light = [&](const Eigen::Vector3f& n) {
    const float sky = 0.5f + 0.5f * n.dot(up_cam);
    return Eigen::Vector3f(f.ambient_ground + sky * (f.ambient_sky - f.ambient_ground));
  };
  auto light = [&](const Eigen::Vector3f& n) {
    const float diffuse = sun_up * std::max(n.dot(sun_cam), 0.0f);
    return Eigen::Vector3f(Eigen::Vector3f(1.0f, 0.97f, 0.92f) * 0.75f * diffuse + sky_light(n));
  };
  // The same light as a SceneLight for the boom's finish (render/pbr.hpp): the boom the camera
  // look draws, drawn here physically.
  SceneLight boom_light;
  boom_light.towards_light_body = sun_cam.cast<double>();
  boom_light.down_body = -up_cam.cast<double>();
  boom_light.direct = Eigen::Vector3d(1.0, 0.97, 0.92) * (0.75 * sun_up);
  boom_light.sky = f.ambient_sky.cast<double>(), boom_light.ground = f.ambient_ground.cast<double>();
  verts_cam_.clear(), light_front_.clear(), light_back_.clear(), vert_offset_.clear();
  ambient_front_.clear(), ambient_back_.clear(), add_front_.clear(), add_back_.clear();
  for (const ReceiverMesh& m : meshes_) {
    vert_offset_.push_back(verts_cam_.size());
    if (!T_body_part[m.part]) continue;
    // Camera-relative in double, as the augmenter.
    const Pose T_cam_obj = cam.T_body_cam.inverse() * *T_body_part[m.part];
    const Eigen::Matrix3f R_f = T_cam_obj.R().cast<float>();
    for (std::size_t i = 0; i < m.mesh->positions_m.size(); ++i) {
      verts_cam_.push_back(T_cam_obj * m.mesh->positions_m[i].cast<double>());
      const Eigen::Vector3f n = i < m.mesh->normals.size() ? Eigen::Vector3f(R_f * m.mesh->normals[i]) : Eigen::Vector3f::Zero();
      if (m.part == kReceiverPart) {
        light_front_.push_back(light(n));
        light_back_.push_back(light(-n));
        add_front_.push_back(Eigen::Vector3f::Zero()), add_back_.push_back(Eigen::Vector3f::Zero());
      } else {
        // The boom's finish, seen from the camera at the origin (its normals are unit).
        const Eigen::Vector3d nd = n.cast<double>(), v = -verts_cam_.back().normalized();
        for (const double side : {1.0, -1.0}) {
          const SurfaceLight sl = boom_light.on(side * nd, v, boom_light.towards_light_body,
                                                boom_light.down_body, m.mesh->finish);
          (side > 0 ? light_front_ : light_back_).push_back(sl.scale.cast<float>());
          (side > 0 ? add_front_ : add_back_).push_back((255.0 * sl.add).cast<float>());
        }
      }
      if (ambient) ambient_front_.push_back(sky_light(n)), ambient_back_.push_back(sky_light(-n));
    }
  }
}

bool CpuSceneRenderer::build_shadow(const Eigen::Vector3d& sun_cam,
                                    const std::array<std::optional<Pose>, kParts>& T_body_part) {
  // The boom's triangles as drawn (both parts), in the camera frame.
  shadow_tris_.clear();
  for (std::size_t mi = 0; mi < meshes_.size(); ++mi) {
    const ReceiverMesh& m = meshes_[mi];
    if (m.part == kReceiverPart || !T_body_part[m.part]) continue;
    const std::vector<std::uint32_t>& idx = m.mesh->indices;
    for (std::size_t k = 0; k + 2 < idx.size(); k += 3)
      for (std::size_t j = 0; j < 3; ++j) shadow_tris_.push_back(verts_cam_[vert_offset_[mi] + idx[k + j]]);
  }
  shadow_.build(shadow_tris_, sun_cam);
  if (shadow_.empty()) return false;
  // Its footprint on the plane across the sun: receiver triangles outside it are never shaded.
  shadow_lo_ = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), shadow_hi_ = -shadow_lo_;
  for (const Eigen::Vector3d& p : shadow_tris_) {
    const Eigen::Vector2d uv = (shadow_.R_sun_F() * p).head<2>();
    shadow_lo_ = shadow_lo_.cwiseMin(uv), shadow_hi_ = shadow_hi_.cwiseMax(uv);
  }
  return true;
}

SampleBox CpuSceneRenderer::raster_objects(const CameraTables& ct,
                                           const std::array<std::optional<Pose>, kParts>& T_body_part, bool shadowed) {
  const VirtualPinhole& vp = ct.vp;
  const SampleGrid grid{vp.fx, vp.fy, vp.cx, vp.cy, vp.width, vp.height, ct.near_m};
  const SampleBox all{0, 0, vp.width, vp.height};
  const std::size_t words = (static_cast<std::size_t>(vp.width) + 63) / 64;  // covered_ per row
  tris_.clear(), tri_shadows_.clear();
  SampleBox box{vp.width, vp.height, 0, 0};
  RasterTriangle rt;
  for (std::size_t mi = 0; mi < meshes_.size(); ++mi) {
    const ReceiverMesh& m = meshes_[mi];
    if (!T_body_part[m.part]) continue;
    const std::vector<std::uint32_t>& idx = m.mesh->indices;
    const std::size_t off = vert_offset_[mi];
    for (std::size_t k = 0; k + 2 < idx.size(); k += 3) {
      const Eigen::Vector3d& p0 = verts_cam_[off + idx[k]];
      const Eigen::Vector3d& p1 = verts_cam_[off + idx[k + 1]];
      const Eigen::Vector3d& p2 = verts_cam_[off + idx[k + 2]];
      if (!rt.setup(grid, p0, p1, p2, m.cull, all)) continue;
      DrawnTriangle d;
      d.rt = rt;
      TriShade& ts = d.shade;
      // Counter-clockwise from outside faces the camera (det < 0): a back face is lit from behind.
      const bool back = p0.dot(p1.cross(p2)) > 0;
      {
        const std::vector<Eigen::Vector3f>& L = back ? light_back_ : light_front_;
        const Eigen::Vector3f& l0 = L[off + idx[k]];
        const Eigen::Vector3f& l1 = L[off + idx[k + 1]];
        const Eigen::Vector3f& l2 = L[off + idx[k + 2]];
        for (int c = 0; c < 3; ++c) {
          ts.lit0[c] = l0[c], ts.dlit1[c] = l1[c] - l0[c], ts.dlit2[c] = l2[c] - l0[c];
          ts.albedo[c] = m.mesh->base_color[c] * 255.0f;
        }
        if (m.part != kReceiverPart) {
          const std::vector<Eigen::Vector3f>& A = back ? add_back_ : add_front_;
          const Eigen::Vector3f &a0 = A[off + idx[k]], &a1 = A[off + idx[k + 1]], &a2 = A[off + idx[k + 2]];
          for (int c = 0; c < 3; ++c)
            ts.add0[c] = a0[c], ts.dadd1[c] = a1[c] - a0[c], ts.dadd2[c] = a2[c] - a0[c];
          ts.specular = true;
        }
        if (m.texture >= 0) {
          const Eigen::Vector2f& a = m.mesh->uvs[idx[k]];
          const Eigen::Vector2f& b = m.mesh->uvs[idx[k + 1]];
          const Eigen::Vector2f& c = m.mesh->uvs[idx[k + 2]];
          ts.tex = &textures_[m.texture].levels;
          for (int j = 0; j < 2; ++j) ts.uv0[j] = a[j], ts.duv1[j] = b[j] - a[j], ts.duv2[j] = c[j] - a[j];
        }
      }
      if (shadowed && m.part == kReceiverPart) {
        // A receiver triangle whose sun-frame footprint meets the boom's may be shaded by it.
        const Eigen::Matrix3d& R = shadow_.R_sun_F();
        const Eigen::Vector3d q0 = R * p0, q1 = R * p1, q2 = R * p2;
        const Eigen::Vector2d lo = q0.head<2>().cwiseMin(q1.head<2>()).cwiseMin(q2.head<2>());
        const Eigen::Vector2d hi = q0.head<2>().cwiseMax(q1.head<2>()).cwiseMax(q2.head<2>());
        if ((lo.array() <= shadow_hi_.array()).all() && (hi.array() >= shadow_lo_.array()).all()) {
          TriShadow s;
          const std::vector<Eigen::Vector3f>& A = back ? ambient_back_ : ambient_front_;
          const Eigen::Vector3f& a0 = A[off + idx[k]];
          const Eigen::Vector3f& a1 = A[off + idx[k + 1]];
          const Eigen::Vector3f& a2 = A[off + idx[k + 2]];
          for (int c = 0; c < 3; ++c) s.amb0[c] = a0[c], s.damb1[c] = a1[c] - a0[c], s.damb2[c] = a2[c] - a0[c];
          s.q0 = q0, s.dq1 = q1 - q0, s.dq2 = q2 - q0;
          s.shadow = &shadow_;
          ts.shadow = static_cast<int>(tri_shadows_.size());
          tri_shadows_.push_back(s);
        }
      }
      if (m.texture >= 0 && p0.z() > 0 && p1.z() > 0 && p2.z() > 0) {
        // Footprint-aware texture level: texels per pixel over the triangle.
        const Mesh& mesh = *m.mesh;
        const Pyramid& tex = textures_[m.texture].levels;
        const Eigen::Vector2f& a = mesh.uvs[idx[k]];
        const Eigen::Vector2f& b = mesh.uvs[idx[k + 1]];
        const Eigen::Vector2f& c = mesh.uvs[idx[k + 2]];
        const double uv_area = std::abs(static_cast<double>((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x())) *
                               tex.width[0] * tex.height[0];
        auto proj = [&](const Eigen::Vector3d& p) { return Eigen::Vector2d(vp.fx * p.x() / p.z(), vp.fy * p.y() / p.z()); };
        const Eigen::Vector2d q0 = proj(p0), e1 = proj(p1) - q0, e2 = proj(p2) - q0;
        const double px_area = std::abs(e1.x() * e2.y() - e1.y() * e2.x());
        if (px_area > 0 && uv_area > px_area)
          ts.level = std::clamp(static_cast<int>(0.5 * std::log2(uv_area / px_area) + 0.5), 0,
                               static_cast<int>(tex.width.size()) - 1);
      }
      if (ts.tex) {
        ts.texels = ts.tex->texels[ts.level].data();
        ts.tw = ts.tex->width[ts.level], ts.th = ts.tex->height[ts.level];
      }
      tris_.push_back(d);
      const auto id = static_cast<std::uint32_t>(tris_.size());
      raster(grid, rt, inv_z_.data(), [&](std::size_t i, int x, int y) {
        ids_[i] = id;
        covered_[static_cast<std::size_t>(y) * words + (x >> 6)] |= std::uint64_t{1} << (x & 63);
      });
      box.x0 = std::min(box.x0, rt.bounds.x0), box.y0 = std::min(box.y0, rt.bounds.y0);
      box.x1 = std::max(box.x1, rt.bounds.x1), box.y1 = std::max(box.y1, rt.bounds.y1);
    }
  }
  return box;
}

void CpuSceneRenderer::shade_objects(const CameraTables& ct, const RigCamera& cam, const SampleBox& box,
                                     PixelFormat fmt, Image& out) {
  const VirtualPinhole& vp = ct.vp;
  const std::size_t words = (static_cast<std::size_t>(vp.width) + 63) / 64;  // covered_ per row
  const int bayer_fmt = is_bayer(fmt);
  // A run of samples of one triangle: the shadow's test only for a triangle that it may reach.
  auto run = [&](std::uint8_t* row, int x, int n, int y, const RasterTriangle& rt, const TriShade& ts, double X,
                 double Y) {
    const int chan[2] = {bayer_fmt ? bayer_channel(fmt, 0, y) : 0, bayer_fmt ? bayer_channel(fmt, 1, y) : 0};
    const double e0 = rt.ea[0] * X + rt.eb[0] * Y + rt.ec[0], e1 = rt.ea[1] * X + rt.eb[1] * Y + rt.ec[1],
                 e2 = rt.ea[2] * X + rt.eb[2] * Y + rt.ec[2];
    auto shade = [&]<bool kShadow>(const TriShadow* s) {
      if (bayer_fmt)
        shade_run<kModeBayer, kShadow>(row, x, n, chan, ts, s, e0, e1, e2, rt.ea[0], rt.ea[1], rt.ea[2]);
      else if (fmt == PixelFormat::kMono8)
        shade_run<kModeMono, kShadow>(row, x, n, chan, ts, s, e0, e1, e2, rt.ea[0], rt.ea[1], rt.ea[2]);
      else if (fmt == PixelFormat::kRGB8)
        shade_run<kModeRgb, kShadow>(row, x, n, chan, ts, s, e0, e1, e2, rt.ea[0], rt.ea[1], rt.ea[2]);
      else
        shade_run<kModeRgba, kShadow>(row, x, n, chan, ts, s, e0, e1, e2, rt.ea[0], rt.ea[1], rt.ea[2]);
    };
    if (ts.shadow < 0)
      shade.template operator()<false>(nullptr);
    else
      shade.template operator()<true>(&tri_shadows_[static_cast<std::size_t>(ts.shadow)]);
  };
  if (vp.identity) {
    // Runs of samples of one triangle along each row: edge functions stepped, one division a pixel.
    for (int y = box.y0; y < box.y1; ++y) {
      std::uint8_t* row = out.row(y);
      const std::uint32_t* idr = ids_.data() + static_cast<std::size_t>(y) * vp.width;
      const std::uint64_t* cov = covered_.data() + static_cast<std::size_t>(y) * words;
      int run_x = 0, run_end = -1;
      std::uint32_t run_id = 0;
      for (int w = box.x0 >> 6; w <= (box.x1 - 1) >> 6; ++w)
        for (std::uint64_t bits = cov[w]; bits; bits &= bits - 1) {
          const int x = 64 * w + std::countr_zero(bits);
          if (x == run_end && idr[x] == run_id) {
            ++run_end;
            continue;
          }
          if (run_id) run(row, run_x, run_end - run_x, y, tris_[run_id - 1].rt, tris_[run_id - 1].shade, run_x, y);
          run_x = x, run_end = x + 1, run_id = idr[x];
        }
      if (run_id) run(row, run_x, run_end - run_x, y, tris_[run_id - 1].rt, tris_[run_id - 1].shade, run_x, y);
    }
  } else {
    // Each raw pixel's ray lands between four virtual samples: the triangles they hold are the
    // candidates, tested exactly at the ray (edge functions, nearest 1/z), as the augmenter does.
    // The raw pixels whose ray lands in the box: the lens image of the box's outline.
    double u0 = 1e300, v0 = 1e300, u1 = -1e300, v1 = -1e300;
    bool all_projected = true;
    auto outline = [&](double x, double y) {
      const auto uv = cam.model.project(Eigen::Vector3d((x - vp.cx) / vp.fx, (y - vp.cy) / vp.fy, 1.0));
      if (!uv) {
        all_projected = false;
        return;
      }
      u0 = std::min(u0, uv->x()), u1 = std::max(u1, uv->x()), v0 = std::min(v0, uv->y()), v1 = std::max(v1, uv->y());
    };
    for (int x = box.x0; x <= box.x1; x += 2) outline(x - 0.5, box.y0 - 0.5), outline(x - 0.5, box.y1 + 0.5);
    for (int y = box.y0; y <= box.y1; y += 2) outline(box.x0 - 0.5, y - 0.5), outline(box.x1 + 0.5, y - 0.5);
    int rx0 = 0, ry0 = 0, rx1 = ct.width, ry1 = ct.height;
    if (all_projected) {
      rx0 = std::max(0, static_cast<int>(std::floor(u0)) - 2), ry0 = std::max(0, static_cast<int>(std::floor(v0)) - 2);
      rx1 = std::min(ct.width, static_cast<int>(std::ceil(u1)) + 3);
      ry1 = std::min(ct.height, static_cast<int>(std::ceil(v1)) + 3);
    }
    for (int y = ry0; y < ry1; ++y) {
      std::uint8_t* row = out.row(y);
      for (int x = rx0; x < rx1; ++x) {
        const Eigen::Vector2f& p = ct.virtual_xy[static_cast<std::size_t>(y) * ct.width + x];
        if (!(p.x() >= box.x0 - 1 && p.y() >= box.y0 - 1 && p.x() < box.x1 && p.y() < box.y1)) continue;  // NaN too
        const int sx = std::max(0, static_cast<int>(p.x() + 1.0f) - 1), sy = std::max(0, static_cast<int>(p.y() + 1.0f) - 1);
        const double X = p.x(), Y = p.y();
        std::uint32_t best = 0, nearest = 0;
        double best_w = 0;
        int covered = 0;
        for (int k = 0; k < 4; ++k) {
          const int qx = std::min(sx + (k & 1), vp.width - 1), qy = std::min(sy + (k >> 1), vp.height - 1);
          const std::uint32_t id = ids_[static_cast<std::size_t>(qy) * vp.width + qx];
          covered += id != 0;
          if (qx == std::min(static_cast<int>(X + 0.5), vp.width - 1) && qy == std::min(static_cast<int>(Y + 0.5), vp.height - 1))
            nearest = id;
          if (!id || id == best) continue;
          const RasterTriangle& t = tris_[id - 1].rt;
          const double e0 = t.ea[0] * X + t.eb[0] * Y + t.ec[0], e1 = t.ea[1] * X + t.eb[1] * Y + t.ec[1],
                       e2 = t.ea[2] * X + t.eb[2] * Y + t.ec[2];
          if (e0 < 0 || e1 < 0 || e2 < 0) continue;
          const double w = (e0 + e1 + e2) * t.inv_area;  // 1/z
          if (t.crosses_near && w > 1.0 / ct.near_m) continue;
          if (w > best_w) best = id, best_w = w;
        }
        // Inside the surface (all four samples on it) a small triangle may hold none of them.
        if (!best && covered == 4) best = nearest;
        if (!best) continue;
        const DrawnTriangle& d = tris_[best - 1];
        run(row, x, 1, y, d.rt, d.shade, X, Y);
      }
    }
  }
}

// Leave the scratch clean for the next frame: the covered samples are the written ones.
void CpuSceneRenderer::clear_samples(const CameraTables& ct, const SampleBox& box) {
  const VirtualPinhole& vp = ct.vp;
  const std::size_t words = (static_cast<std::size_t>(vp.width) + 63) / 64;  // covered_ per row
  for (int y = box.y0; y < box.y1; ++y) {
    std::uint64_t* cov = covered_.data() + static_cast<std::size_t>(y) * words;
    for (int w = box.x0 >> 6; w <= (box.x1 - 1) >> 6; ++w) {
      for (std::uint64_t bits = cov[w]; bits; bits &= bits - 1) {
        const std::size_t i = static_cast<std::size_t>(y) * vp.width + 64 * static_cast<std::size_t>(w) +
                              static_cast<std::size_t>(std::countr_zero(bits));
        inv_z_[i] = 0.0f, ids_[i] = 0u;
      }
      cov[w] = 0;
    }
  }
}

void CpuSceneRenderer::add_noise(int camera, const SensorOptions& sensor, Image& out) {
  if (sensor.noise_sigma != noise_sigma_) {
    // The field: kNoiseField samples round(sigma z), z one of 65536 Gaussian quantiles picked by a
    // fixed stream, so the field (and every image) depends on sigma only. Values beyond +-127 DN
    // are clipped (sigma > 29 DN).
    noise_field_.resize(kNoiseField + kNoiseTail);
    std::uint64_t state = 0x6a09e667f3bcc909ull;
    for (std::size_t i = 0; i < noise_field_.size(); i += 4) {
      const std::uint64_t bits = splitmix64(state++);
      for (std::size_t k = 0; k < 4 && i + k < noise_field_.size(); ++k) {
        const long v = std::lround(sensor.noise_sigma * gauss_[(bits >> (16 * k)) & 0xffffu]);
        noise_field_[i + k] = static_cast<std::int8_t>(std::clamp(v, -127L, 127L));
      }
    }
    noise_sigma_ = sensor.noise_sigma;
  }
  // Row y adds the field's samples from an offset that depends on the seed, the camera and y only,
  // so any split of the rows between threads gives the same image. Adding round(sigma z) to an
  // integer is what adding sigma z and rounding gives.
  const std::uint64_t key =
      splitmix64(sensor.noise_seed ^ (0x51ed270b27a3e1f1ull * (static_cast<std::uint64_t>(camera) + 1)));
  const int bpp = bytes_per_pixel(out.format());
  const std::size_t n = static_cast<std::size_t>(out.width()) * bpp;
  const int H = out.height();
  bands_.run([&](int band) {
    const int y0 = H * band / bands_.count(), y1 = H * (band + 1) / bands_.count();
    auto offset = [key](int y) {
      return splitmix64(key ^ (static_cast<std::uint64_t>(y) * 0xd6e8feb86659fd93ull)) & (kNoiseField - 1);
    };
    // The rows' windows are at random places in the 8 MB field, mostly out of cache: the next
    // row's is fetched while this one is added.
    std::size_t next = offset(y0);
    for (int y = y0; y < y1; ++y) {
      const std::size_t here = next;
      if (y + 1 < y1) {
        next = offset(y + 1);
        const std::int8_t* p = noise_field_.data() + next;
        for (std::size_t b = 0; b < n + 64; b += 64) __builtin_prefetch(p + b);
      }
      add_saturated(out.row(y), noise_field_.data() + here, n, bpp == 4);
    }
  });
}

bool same_sky(const SkyState& a, const SkyState& b) {
  return a.R_ned_body == b.R_ned_body && a.altitude_m == b.altitude_m && a.north_east_m == b.north_east_m &&
         a.sun_ned == b.sun_ned;
}

Status CpuSceneRenderer::render_view(int camera, const SkyState& sky, const Pose& T_body_receiver,
                                     bool receiver_present, const BoomArticulation* boom,
                                     const BoomArticulation& boom_rate_per_s, const SensorOptions& sensor,
                                     Image& out) {
  if (camera < 0 || camera >= static_cast<int>(cameras_.size()))
    return make_error("SyntheticSceneRenderer::render(): no camera ", camera, " (the rig has ", cameras_.size(), ")");
  if (!(sky.altitude_m > 0)) return make_error("SyntheticSceneRenderer::render(): altitude must be > 0 m");
  if (!(sensor.noise_sigma >= 0)) return make_error("SyntheticSceneRenderer::render(): noise_sigma must be >= 0");
  const CameraResponse response = sensor.response();
  if (Status s = check_camera_response(response); !s) return s;
  if (!(sensor.exposure_ms >= 0 && sensor.exposure_ms <= kMaxExposureMs))
    return make_error("SyntheticSceneRenderer::render(): exposure_ms must be in 0..", kMaxExposureMs);
  std::array<std::optional<Pose>, kParts> T_body_part;
  if (receiver_present) T_body_part[kReceiverPart] = T_body_receiver;
  if (boom) {
    T_body_part[kBoomFixedPart] = boom_pose(rig_.boom.pivot_body_m, *boom);
    T_body_part[kBoomTelescopePart] = *T_body_part[kBoomFixedPart] * telescope_pose(*boom);
  }
  const double exposure_s = 1e-3 * sensor.exposure_ms;
  const int samples = boom
                          ? motion_samples(boom_motion_px(boom_, rig_.boom.pivot_body_m, rig_.cameras[camera],
                                                          *boom, boom_rate_per_s, exposure_s))
                          : 1;
  auto clean = [&](PixelFormat fmt, Image& img) {
    if (samples == 1)
      render_clean(camera, sky, T_body_part, fmt, img);
    else
      render_moving(camera, sky, T_body_part, *boom, boom_rate_per_s, exposure_s, samples, fmt, img);
  };
  if (!needs_camera_model(response)) {
    // The fast path: the clean render in the frame's format, read noise added to it.
    clean(sensor.format, out);
    if (sensor.noise_sigma > 0) add_noise(camera, sensor, out);
    return {};
  }
  // A camera: the scene's radiance in RGB, then the whole camera's response over it.
  clean(PixelFormat::kRGB8, radiance_);
  apply_camera_response(radiance_, response, sensor.format, sensor.noise_seed, camera, out, bands_.count());
  return {};
}

void CpuSceneRenderer::render_moving(int camera, const SkyState& sky,
                                     std::array<std::optional<Pose>, kParts> T_body_part,
                                     const BoomArticulation& boom, const BoomArticulation& boom_rate_per_s,
                                     double exposure_s, int samples, PixelFormat fmt, Image& out) {
  // A sensor integrates the light over its exposure: the scene at each instant, averaged (in
  // radiance, before the camera's response; rounded once, at the end).
  for (int k = 0; k < samples; ++k) {
    const BoomArticulation a =
        articulation_at(boom, boom_rate_per_s, sub_exposure_offset_s(k, samples, exposure_s));
    T_body_part[kBoomFixedPart] = boom_pose(rig_.boom.pivot_body_m, a);
    T_body_part[kBoomTelescopePart] = *T_body_part[kBoomFixedPart] * telescope_pose(a);
    render_clean(camera, sky, T_body_part, fmt, instant_);
    const std::size_t row = static_cast<std::size_t>(instant_.width()) * bytes_per_pixel(fmt);
    if (k == 0) exposure_sum_.assign(row * instant_.height(), 0);
    for (int y = 0; y < instant_.height(); ++y) {
      const std::uint8_t* src = instant_.row(y);
      std::uint32_t* dst = &exposure_sum_[y * row];
      for (std::size_t i = 0; i < row; ++i) dst[i] += src[i];
    }
  }
  if (out.width() != instant_.width() || out.height() != instant_.height() || out.format() != fmt)
    out = Image(instant_.width(), instant_.height(), fmt);
  const std::size_t row = static_cast<std::size_t>(out.width()) * bytes_per_pixel(fmt);
  const auto n = static_cast<std::uint32_t>(samples);
  for (int y = 0; y < out.height(); ++y) {
    const std::uint32_t* src = &exposure_sum_[y * row];
    std::uint8_t* dst = out.row(y);
    for (std::size_t i = 0; i < row; ++i) dst[i] = static_cast<std::uint8_t>((src[i] + n / 2) / n);
  }
}

void CpuSceneRenderer::render_clean(int camera, const SkyState& sky,
                                    const std::array<std::optional<Pose>, kParts>& T_body_part, PixelFormat fmt,
                                    Image& out) {
  const CameraTables& ct = cameras_[camera];
  const RigCamera& cam = rig_.cameras[camera];
  if (out.width() != ct.width || out.height() != ct.height || out.format() != fmt) out = Image(ct.width, ct.height, fmt);

  // The background is seen from the group's first camera when the ground's disparity between the
  // two (at most f |baseline| / height) is below kShareDisparityPx: then both views of a parallel
  // stereo pair get the same background, and it is rendered once per pair.
  const RigCamera& lead = rig_.cameras[ct.group];
  const double disparity_px = std::max(cam.model.fx_px, cam.model.fy_px) *
                              (cam.T_body_cam.translation_m - lead.T_body_cam.translation_m).norm() / sky.altitude_m;
  const bool shared = ct.group != camera && disparity_px < kShareDisparityPx;
  const int bg_camera = shared ? ct.group : camera;
  const RigCamera& bg_cam = rig_.cameras[bg_camera];

  FrameSky f;
  f.R_ned_cam = sky.R_ned_body * cam.T_body_cam.R();
  // The camera's own offset from the tanker's reference point counts: the ground is in world metres.
  const Eigen::Vector3d cam_offset_ned = sky.R_ned_body * bg_cam.T_body_cam.translation_m;
  f.cam_ned = {sky.north_east_m.x() + cam_offset_ned.x(), sky.north_east_m.y() + cam_offset_ned.y(),
               -sky.altitude_m + cam_offset_ned.z()};
  f.sun = sky.sun_ned.normalized();
  f.sun_factor = 0.75 + 0.35 * std::max(-f.sun.z(), 0.0);
  if (sky.ambient_from_world) hemisphere_light(*tile_, f);

  const bool group_shares = [&] {
    for (const CameraTables& o : cameras_)
      if (&o != &ct && o.group == ct.group) return true;
    return false;
  }();
  const std::size_t bytes = static_cast<std::size_t>(out.stride_bytes()) * out.height();
  if (group_shares && shared_key_.group == ct.group && shared_key_.format == fmt && same_sky(shared_key_.sky, sky) &&
      (shared || bg_camera == ct.group) && shared_bg_.size() == bytes) {
    std::memcpy(out.data(), shared_bg_.data(), bytes);
  } else {
    background(ct, f, fmt, out);
    if (group_shares && bg_camera == ct.group) {
      shared_key_ = {ct.group, fmt, sky};
      shared_bg_.assign(out.data(), out.data() + bytes);
    }
  }
  if (std::any_of(T_body_part.begin(), T_body_part.end(), [](const auto& p) { return p.has_value(); }) &&
      !meshes_.empty())
    draw_objects(ct, cam, f, T_body_part, fmt, out);
}

}  // namespace

bool set_cpu_scene_avx2_for_testing(bool allowed) {
#if defined(AUGRIG_GROUND_AVX2)
  g_avx2_allowed.store(allowed, std::memory_order_relaxed);
  return allowed && cpu_has_avx2();
#else
  (void)allowed;
  return false;
#endif
}

Expected<std::unique_ptr<SyntheticSceneRenderer>> make_cpu_scene_renderer(const Rig& rig,
                                                                          std::shared_ptr<const Model> receiver,
                                                                          const SceneRendererOptions& options) {
  if (options.threads < 1 || options.threads > 8)
    return make_error("SyntheticSceneRenderer::create(): threads must be 1 to 8, got ", options.threads);
  auto r = std::make_unique<CpuSceneRenderer>(rig, options.threads);
  if (auto s = r->init(std::move(receiver)); !s) return s.error();
  return std::unique_ptr<SyntheticSceneRenderer>(std::move(r));
}

}  // namespace augrig
