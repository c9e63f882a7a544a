#include "render/camera_look.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Core>

#include "core/conventions.hpp"

namespace augrig {

const char* to_string(Look l) {
  return l == Look::kCamera ? "camera" : "plain";
}

bool parse_look(std::string_view name, Look& out) {
  if (name == "plain") return out = Look::kPlain, true;
  if (name == "camera") return out = Look::kCamera, true;
  return false;
}

const char* to_string(LightSource s) {
  switch (s) {
    case LightSource::kFixed:
      return "fixed";
    case LightSource::kDefaultSun:
      return "default sun";
    case LightSource::kConfigured:
      return "configured";
    case LightSource::kEphemeris:
      return "ephemeris";
  }
  return "?";
}

SceneLight SceneLight::fixed() {
  return {};
}

SceneLight SceneLight::default_sun() {
  // 45 deg above the horizon, 45 deg to the right of the nose (a level tanker's body frame).
  const double c = std::cos(kPi / 4), s = std::sin(kPi / 4);
  return sun(Eigen::Vector3d(c * c, c * s, -s), true, LightSource::kDefaultSun);
}

SceneLight SceneLight::sun(const Eigen::Vector3d& towards_sun_body, bool sun_above_horizon,
                           LightSource source, const Eigen::Vector3d& down_body) {
  // A clear sky: the sun gives about 80 % of the light on a surface facing it, the sky the rest
  // (clear-sky ratios of diffuse to global irradiance are 0.1-0.25); the ground returns about a
  // fifth of what falls on it (a land albedo), until the frames say how bright it is.
  SceneLight l;
  l.towards_light_body = towards_sun_body.normalized();
  l.down_body = down_body.normalized();
  l.direct = Eigen::Vector3d::Constant(sun_above_horizon ? 0.8 : 0.0);
  l.sky = Eigen::Vector3d::Constant(0.2);
  l.ground = Eigen::Vector3d::Constant(0.2);
  l.source = source;
  l.sun_up = sun_above_horizon;
  return l;
}

int psf_margin_px(const CameraLookParams& p) {
  return p.psf_sigma_px > 0 ? static_cast<int>(std::ceil(3.0 * std::min(p.psf_sigma_px, kMaxPsfSigmaPx))) + 1
                            : 0;
}

namespace {

constexpr int kNormalTable = 4096;

// Inverse standard normal CDF at the centres of kNormalTable + 1 equal-probability cells, scaled
// so that the piecewise-linear distribution gaussian_for_key() draws from has unit variance.
const std::array<float, kNormalTable + 1>& normal_table() {
  static const std::array<float, kNormalTable + 1> table = [] {
    std::array<double, kNormalTable + 1> z{};
    for (int j = 0; j <= kNormalTable; ++j) {
      const double u = (j + 0.5) / (kNormalTable + 1);
      double lo = -9, hi = 9;  // bisection on Phi(z) = erfc(-z / sqrt 2) / 2
      for (int it = 0; it < 80; ++it) {
        const double mid = 0.5 * (lo + hi);
        (0.5 * std::erfc(-mid / std::sqrt(2.0)) < u ? lo : hi) = mid;
      }
      z[j] = 0.5 * (lo + hi);
    }
    // Each cell [z_i, z_i+1] is drawn uniformly: its second moment is (a^2 + a b + b^2) / 3.
    double m2 = 0;
    for (int i = 0; i < kNormalTable; ++i) m2 += (z[i] * z[i] + z[i] * z[i + 1] + z[i + 1] * z[i + 1]) / 3.0;
    const double scale = 1.0 / std::sqrt(m2 / kNormalTable);
    std::array<float, kNormalTable + 1> t{};
    for (int j = 0; j <= kNormalTable; ++j) t[j] = static_cast<float>(z[j] * scale);
    return t;
  }();
  return table;
}

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// One deviate from 32 bits of a hash: 12 choose the cell, 20 the place in it.
float gaussian_from_bits(const float* t, std::uint32_t bits) {
  const std::uint32_t i = bits >> 20;
  const float f = static_cast<float>(bits & 0xfffffu) * (1.0f / 1048576.0f);
  return t[i] + (t[i + 1] - t[i]) * f;
}

// The tone curve as tables: decode (encoded DN -> linear DN) and encode, each over 0..255.
constexpr int kToneTable = 4096;
void build_tone_tables(double gamma, LookBuffers& b) {
  if (b.table_gamma == gamma && !b.decode.empty()) return;
  b.decode.resize(kToneTable + 1);
  b.encode.resize(kToneTable + 1);
  b.carry.resize(kToneTable + 1);
  for (int i = 0; i <= kToneTable; ++i) {
    const double x = static_cast<double>(i) / kToneTable;
    b.decode[i] = static_cast<float>(255.0 * std::pow(x, gamma));
    b.encode[i] = static_cast<float>(255.0 * std::pow(x, 1.0 / gamma));
    b.carry[i] = static_cast<float>(std::pow(std::max(255.0 * x, 0.5), gamma - 1));  // the noise's carry
  }
  b.table_gamma = gamma;
}
float lookup(const std::vector<float>& t, float v) {
  const float x = std::clamp(v, 0.f, 255.f) * (static_cast<float>(kToneTable) / 255.f);
  const int i = std::min(static_cast<int>(x), kToneTable - 1);
  return t[i] + (t[i + 1] - t[i]) * (x - static_cast<float>(i));
}

// Channels interleaved in the buffers (1 for Mono8 and Bayer, 3 for RGB8 and RGBA8) and the
// stride between same-colour neighbours (2 on a Bayer mosaic: the blur stays within a site).
struct Layout {
  int nc = 1, step = 1, bpp = 1;
};
Layout layout_of(PixelFormat f) {
  Layout l;
  l.bpp = bytes_per_pixel(f);
  l.nc = f == PixelFormat::kRGB8 || f == PixelFormat::kRGBA8 ? 3 : 1;
  l.step = is_bayer(f) ? 2 : 1;
  return l;
}

std::vector<float> gaussian_kernel(double sigma, int step) {
  const int r = static_cast<int>(std::ceil(3.0 * sigma / step));
  std::vector<float> w(2 * r + 1);
  double sum = 0;
  for (int k = -r; k <= r; ++k)
    sum += w[k + r] = static_cast<float>(std::exp(-0.5 * std::pow(k * step / sigma, 2)));
  for (float& x : w) x = static_cast<float>(x / sum);
  return w;
}

// A same-colour neighbour index inside [0, n): reflected back by whole steps at the edges.
int inside(int i, int n, int step) {
  while (i < 0) i += step;
  while (i >= n) i -= step;
  return std::clamp(i, 0, n - 1);
}

// The columns [lo, hi) of box row y that hold the layer (spans[2y], spans[2y + 1]); lo == hi: none.
struct Span {
  int lo, hi;
  bool empty() const { return lo >= hi; }
};
Span span_of(const int* spans, int y) {
  return {spans[2 * y], spans[2 * y + 1]};
}

// dst[i] += k * src[i] for i in [0, n): the blur's inner loop, vectorised by Eigen (GCC's -O2 leaves
// a loop of unknown length scalar).
void add_scaled(float* dst, const float* src, float k, int n) {
  Eigen::Map<Eigen::ArrayXf>(dst, n) += k * Eigen::Map<const Eigen::ArrayXf>(src, n);
}

// Separable blur of the layer (w x h pixels of `nc` interleaved floats) in place, reading each row
// only over its span and writing each row only over its new span (`spans`, updated), so that a
// thin diagonal boom costs its footprint, not its box. Values outside a row's span are never read.
void blur(float* p, std::vector<float>& tmp, int* spans, int w, int h, int nc, int step,
          const std::vector<float>& k) {
  const int r = static_cast<int>(k.size() / 2), reach = r * step;
  const std::size_t row = static_cast<std::size_t>(w) * nc;
  tmp.resize(row * h);
  // Horizontal: row y's span widened by the kernel's reach, taps past the box's edges reflected.
  std::vector<int> wide(2 * static_cast<std::size_t>(h));
  for (int y = 0; y < h; ++y) {
    const Span s = span_of(spans, y);
    const Span o = s.empty() ? s : Span{std::max(0, s.lo - reach), std::min(w, s.hi + reach)};
    wide[2 * y] = o.lo, wide[2 * y + 1] = o.hi;
    if (o.empty()) continue;
    const float* src = &p[y * row];
    float* dst = &tmp[y * row];
    std::fill(dst + o.lo * nc, dst + o.hi * nc, 0.f);
    for (int j = -r; j <= r; ++j) {
      const int d = j * step;  // output x reads source x + d, where the source is in [s.lo, s.hi)
      const int x0 = std::max(o.lo, s.lo - d), x1 = std::min(o.hi, s.hi - d);
      if (x0 < x1) add_scaled(dst + x0 * nc, src + (x0 + d) * nc, k[j + r], (x1 - x0) * nc);
      // Taps off the box: reflected into it (a box the image's edge cut), read where the span is.
      auto reflected = [&](int from, int to) {
        for (int x = std::max(from, o.lo); x < std::min(to, o.hi); ++x) {
          const int xs = inside(x + d, w, step);
          if (xs >= s.lo && xs < s.hi)
            for (int c = 0; c < nc; ++c) dst[x * nc + c] += k[j + r] * src[xs * nc + c];
        }
      };
      reflected(0, -d);     // x + d < 0
      reflected(w - d, w);  // x + d >= w
    }
  }
  // Vertical: row y's new span is the union of its neighbours' wide spans.
  for (int y = 0; y < h; ++y) {
    Span o{w, 0};
    for (int j = -r; j <= r; ++j) {
      const Span s = span_of(wide.data(), inside(y + j * step, h, step));
      if (!s.empty()) o = {std::min(o.lo, s.lo), std::max(o.hi, s.hi)};
    }
    spans[2 * y] = o.lo, spans[2 * y + 1] = std::max(o.lo, o.hi);
    if (o.empty()) continue;
    float* dst = &p[y * row];
    std::fill(dst + o.lo * nc, dst + o.hi * nc, 0.f);
    for (int j = -r; j <= r; ++j) {
      const int ys = inside(y + j * step, h, step);
      const Span s = span_of(wide.data(), ys);
      const int x0 = std::max(o.lo, s.lo), x1 = std::min(o.hi, s.hi);
      if (x0 < x1) add_scaled(dst + x0 * nc, &tmp[ys * row + x0 * nc], k[j + r], (x1 - x0) * nc);
    }
  }
}

// The PSF on a Bayer mosaic, whose layer holds each pixel's own site's colour (a C) and its
// coverage a (interleaved pairs). A lens blurs before the mosaic, at full resolution: the coverage
// is colour-blind and is blurred so, pixel by pixel. The colour, known at same-site pixels only,
// is taken as locally constant: its unpremultiplied value at each pixel is the ratio of a
// same-site blur of a C and of a (at least 1 px wide, to reach two sites each way), and is
// premultiplied by the full-resolution coverage.
void blur_mosaic(LookBuffers& buf, int w, int h, double sigma) {
  const std::size_t n = static_cast<std::size_t>(w) * h;
  buf.layer.resize(3 * n);  // [a C, a] pairs, then the full-resolution coverage plane
  buf.spans.resize(4 * static_cast<std::size_t>(h));
  float* pairs = buf.layer.data();
  float* cover = pairs + 2 * n;
  int* site_spans = buf.spans.data();
  int* cover_spans = site_spans + 2 * h;
  for (int y = 0; y < h; ++y) {
    const Span s = span_of(site_spans, y);
    cover_spans[2 * y] = s.lo, cover_spans[2 * y + 1] = s.hi;
    for (int x = s.lo; x < s.hi; ++x)
      cover[static_cast<std::size_t>(y) * w + x] = pairs[2 * (static_cast<std::size_t>(y) * w + x) + 1];
  }
  blur(cover, buf.tmp, cover_spans, w, h, 1, 1, gaussian_kernel(sigma, 1));
  blur(pairs, buf.tmp, site_spans, w, h, 2, 2, gaussian_kernel(std::max(sigma, 1.0), 2));
  // Back into the pairs over both spans' union; a pixel no same-site colour reaches keeps none.
  for (int y = 0; y < h; ++y) {
    const Span c = span_of(cover_spans, y), s = span_of(site_spans, y);
    const Span u = c.empty() ? s : s.empty() ? c : Span{std::min(c.lo, s.lo), std::max(c.hi, s.hi)};
    for (int x = u.lo; x < u.hi; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      const float a = x >= c.lo && x < c.hi ? cover[i] : 0.f;
      const bool known = x >= s.lo && x < s.hi && pairs[2 * i + 1] > 1e-6f;
      const float colour = known ? pairs[2 * i] / pairs[2 * i + 1] : 0.f;
      pairs[2 * i] = known ? colour * a : 0.f;
      pairs[2 * i + 1] = known ? a : 0.f;
    }
    site_spans[2 * y] = u.lo, site_spans[2 * y + 1] = std::max(u.lo, u.hi);
  }
}

}  // namespace

float gaussian_for_key(std::uint64_t key) {
  return gaussian_from_bits(normal_table().data(), static_cast<std::uint32_t>(splitmix64(key) >> 32));
}

void begin_look_layer(const PixelBox& box, PixelFormat format, LookBuffers& buf) {
  const int nl = layout_of(format).nc + 1;
  buf.layer_box = box;
  buf.layer.resize(static_cast<std::size_t>(box.width()) * nl * box.height());
  buf.spans.assign(2 * static_cast<std::size_t>(box.height()), 0);
}

void add_to_look_layer(ConstImageView raw, ConstImageView alpha, ConstImageView composite,
                       const PixelBox& part, float weight, LookBuffers& buf) {
  // The boom's layer from the plain composite A = (1 - a) R + a C, per pixel the premultiplied
  // colour a C (C is the rendered radiance, linear already) and the coverage a, interleaved;
  // each row only over the columns its coverage spans.
  const PixelBox& box = buf.layer_box;
  const Layout L = layout_of(raw.format);
  const int bw = box.width(), nc = L.nc, nl = nc + 1;
  const std::size_t row_floats = static_cast<std::size_t>(bw) * nl;
  for (int y = part.y0; y < part.y1; ++y) {
    const std::uint8_t* ar = alpha.row(y) + part.x0;
    int lo = 0, hi = part.width();
    while (lo < hi && !ar[lo]) ++lo;
    while (hi > lo && !ar[hi - 1]) --hi;
    if (lo >= hi) continue;
    const int by = y - box.y0, x0 = part.x0 - box.x0;  // the part's columns in the box
    float* lr = &buf.layer[by * row_floats];
    int& slo = buf.spans[2 * by];
    int& shi = buf.spans[2 * by + 1];
    // Zero the columns the row's span gains.
    if (slo >= shi) {
      std::fill(lr + (x0 + lo) * nl, lr + (x0 + hi) * nl, 0.f), slo = x0 + lo, shi = x0 + hi;
    } else {
      if (x0 + lo < slo) std::fill(lr + (x0 + lo) * nl, lr + slo * nl, 0.f), slo = x0 + lo;
      if (x0 + hi > shi) std::fill(lr + shi * nl, lr + (x0 + hi) * nl, 0.f), shi = x0 + hi;
    }
    const std::uint8_t* rr = raw.row(y) + static_cast<std::size_t>(part.x0) * L.bpp;
    const std::uint8_t* pr = composite.row(y - part.y0);
    for (int x = lo; x < hi; ++x) {
      const float a = ar[x] * (1.f / 255.f);
      if (!(a > 0)) continue;
      float* l = lr + (x0 + x) * nl;
      for (int c = 0; c < nc; ++c) {
        const float A = pr[x * L.bpp + c], R = rr[x * L.bpp + c];
        l[c] += weight * std::clamp(A - (1 - a) * R, 0.f, 255.f * a);
      }
      l[nc] += weight * a;
    }
  }
}

void apply_camera_look(ConstImageView raw, ConstImageView alpha, ImageView aug, const PixelBox& box,
                       const CameraLookParams& params, std::uint64_t frame_key, int camera,
                       LookBuffers& buf) {
  if (box.empty()) return;
  begin_look_layer(box, raw.format, buf);
  add_to_look_layer(raw, alpha, ConstImageView{aug.data, aug.width, aug.height, aug.stride_bytes, aug.format},
                    box, 1.f, buf);
  apply_look_layer(raw, aug, params, frame_key, camera, buf);
}

void apply_look_layer(ConstImageView raw, ImageView aug, const CameraLookParams& params,
                      std::uint64_t frame_key, int camera, LookBuffers& buf) {
  const PixelBox& box = buf.layer_box;
  if (box.empty()) return;
  const Layout L = layout_of(raw.format);
  const int bw = box.width(), bh = box.height(), nc = L.nc;
  const bool linear = params.gamma == 1.0;
  if (!linear) build_tone_tables(params.gamma, buf);
  auto dec = [&](float e) { return linear ? e : lookup(buf.decode, e); };
  auto enc = [&](float l) { return linear ? l : lookup(buf.encode, l); };
  const int nl = nc + 1;
  const std::size_t row_floats = static_cast<std::size_t>(bw) * nl;
  bool any = false;
  for (int y = 0; y < bh && !any; ++y) any = buf.spans[2 * y] < buf.spans[2 * y + 1];
  if (!any) return;

  // 2. Optics: the layer and its coverage through the PSF (the spans widen by its reach).
  if (params.psf_sigma_px > 0) {
    const double sigma = std::min(params.psf_sigma_px, kMaxPsfSigmaPx);
    if (L.step == 1)
      blur(buf.layer.data(), buf.tmp, buf.spans.data(), bw, bh, nl, 1, gaussian_kernel(sigma, 1));
    else
      blur_mosaic(buf, bw, bh, sigma);
  }

  // 3. Composite in linear light, back through the tone curve, and 4. the sensor's noise: the
  //    NLF's variance at the new value less what the raw pixel's noise carries into it.
  const float* gt = normal_table().data();
  const std::uint64_t view_key =
      splitmix64(params.seed ^ splitmix64(frame_key ^ (0x51ed270b27e4a5c3ULL * (camera + 1))));
  const bool noisy = !params.noise.empty();
  for (int y = 0; y < bh; ++y) {
    const std::uint8_t* rr = raw.row(box.y0 + y) + static_cast<std::size_t>(box.x0) * L.bpp;
    std::uint8_t* pr = aug.row(y);
    const float* lr = &buf.layer[y * row_floats];
    const int v = box.y0 + y;
    // The NLF's sigma^2 = a I + b of each channel of the pixels of this row, by column parity
    // (a Bayer row alternates two sites); a channel without noise (RGBA's alpha) has a = b = 0.
    float na[2][3] = {}, nb[2][3] = {};
    for (int px = 0; px < 2 && noisy; ++px)
      for (int c = 0; c < nc; ++c) {
        const int ch = noise_channel(raw.format, box.x0 + px, v, c);
        na[px][c] = static_cast<float>(params.noise.variance(ch, 1.0) - params.noise.variance(ch, 0.0));
        nb[px][c] = static_cast<float>(params.noise.variance(ch, 0.0));
      }
    for (int x = buf.spans[2 * y]; x < buf.spans[2 * y + 1]; ++x) {
      const float* l = lr + x * nl;
      const float ab = std::min(l[nc], 1.f);
      if (ab < 1.f / 1024.f) continue;  // the blur's far tail: the raw pixel stays as it is
      const int u = box.x0 + x;
      const std::uint64_t h =
          noisy ? splitmix64(view_key ^ (static_cast<std::uint64_t>(v) << 32 | static_cast<std::uint32_t>(u)))
                : 0;
      for (int c = 0; c < nc; ++c) {
        const float R = rr[x * L.bpp + c];
        float out = enc((1 - ab) * dec(R) + l[c]);
        if (noisy) {
          // d(out)/d(R) = (1 - ab) enc'(.) dec'(R) = (1 - ab) (R / out)^(gamma - 1)
          const float carry = linear ? 1 - ab : (1 - ab) * lookup(buf.carry, R) / lookup(buf.carry, out);
          const float a = na[x & 1][c], b = nb[x & 1][c];
          const float need = std::max(a * out + b, 0.f) - carry * carry * std::max(a * R + b, 0.f);
          if (need > 0) {
            const auto bits = static_cast<std::uint32_t>(c == 0 ? h >> 32 : c == 1 ? h : splitmix64(h) >> 32);
            out += std::sqrt(need) * gaussian_from_bits(gt, bits);
          }
        }
        pr[x * L.bpp + c] = static_cast<std::uint8_t>(std::clamp(out + 0.5f, 0.f, 255.f));
      }
    }
  }
}

void apply_shadow_look(ImageView aug, const PixelBox& box, const std::vector<ShadowPixel>& shadow,
                       const CameraLookParams& params, std::uint64_t frame_key, int camera, LookBuffers& buf) {
  if (box.empty() || shadow.empty()) return;
  const PixelFormat fmt = aug.format;
  const Layout L = layout_of(fmt);
  const int bw = box.width(), bh = box.height();
  const bool linear = params.gamma == 1.0;
  if (!linear) build_tone_tables(params.gamma, buf);
  auto dec = [&](float e) { return linear ? e : lookup(buf.decode, e); };
  auto enc = [&](float l) { return linear ? l : lookup(buf.encode, l); };

  // 1. The shares as a field over the box, each row over the columns its shadow spans.
  const std::size_t row_floats = static_cast<std::size_t>(bw) * 3;
  buf.shade.resize(row_floats * bh);
  buf.shade_spans.assign(2 * static_cast<std::size_t>(bh), 0);
  for (int y = 0; y < bh; ++y) buf.shade_spans[2 * y] = bw;
  for (const ShadowPixel& p : shadow) {
    const int x = p.u - box.x0, y = p.v - box.y0;
    if (x < 0 || y < 0 || x >= bw || y >= bh) continue;
    int& lo = buf.shade_spans[2 * y];
    int& hi = buf.shade_spans[2 * y + 1];
    // Zero the columns a row's span gains, then place the share.
    float* row = &buf.shade[y * row_floats];
    if (lo >= hi) {
      std::fill(row + 3 * x, row + 3 * x + 3, 0.f), lo = x, hi = x + 1;
    } else if (x < lo) {
      std::fill(row + 3 * x, row + 3 * lo, 0.f), lo = x;
    } else if (x >= hi) {
      std::fill(row + 3 * hi, row + 3 * (x + 1), 0.f), hi = x + 1;
    }
    for (int c = 0; c < 3; ++c) row[3 * x + c] = p.share[c];
  }
  for (int y = 0; y < bh; ++y)
    if (buf.shade_spans[2 * y] > buf.shade_spans[2 * y + 1]) buf.shade_spans[2 * y] = buf.shade_spans[2 * y + 1] = 0;

  // 2. Optics: at full resolution for every format (the light is colour-blind to the mosaic).
  if (params.psf_sigma_px > 0)
    blur(buf.shade.data(), buf.tmp, buf.shade_spans.data(), bw, bh, 3, 1,
         gaussian_kernel(std::min(params.psf_sigma_px, kMaxPsfSigmaPx), 1));

  // 3. Each pixel's linear value scaled, back through the tone curve; 4. the noise topped up, as in
  //    apply_camera_look() but from its own stream (a pixel both looks touch gets two draws).
  const float* gt = normal_table().data();
  const std::uint64_t view_key = splitmix64(
      params.seed ^ splitmix64(frame_key ^ (0x51ed270b27e4a5c3ULL * (camera + 1))) ^ 0x2545f4914f6cdd1dULL);
  const bool noisy = !params.noise.empty();
  const int nc = L.nc;
  for (int y = 0; y < bh; ++y) {
    const int v = box.y0 + y;
    std::uint8_t* pr = aug.row(y);
    const float* sr = &buf.shade[y * row_floats];
    for (int x = buf.shade_spans[2 * y]; x < buf.shade_spans[2 * y + 1]; ++x) {
      const int u = box.x0 + x;
      const std::uint64_t h =
          noisy ? splitmix64(view_key ^ (static_cast<std::uint64_t>(v) << 32 | static_cast<std::uint32_t>(u))) : 0;
      for (int c = 0; c < nc; ++c) {
        // The light's channel of this sample: its own (RGB), its site's (Bayer), green (Mono).
        const int lc = nc == 3 ? c : is_bayer(fmt) ? bayer_channel(fmt, u, v) : 1;
        const float share = std::clamp(sr[3 * x + lc], 0.f, 1.f);
        if (share < 1.f / 1024.f) continue;  // the blur's far tail
        const float g = 1 - share, A = pr[x * L.bpp + c];
        float out = enc(g * dec(A));
        if (noisy) {
          const int ch = noise_channel(fmt, u, v, c);
          const float a = static_cast<float>(params.noise.variance(ch, 1.0) - params.noise.variance(ch, 0.0)),
                      b = static_cast<float>(params.noise.variance(ch, 0.0));
          const float carry = linear ? g : g * lookup(buf.carry, A) / lookup(buf.carry, out);
          const float need = std::max(a * out + b, 0.f) - carry * carry * std::max(a * A + b, 0.f);
          if (need > 0) {
            const auto bits = static_cast<std::uint32_t>(c == 0 ? h >> 32 : c == 1 ? h : splitmix64(h) >> 32);
            out += std::sqrt(need) * gaussian_from_bits(gt, bits);
          }
        }
        pr[x * L.bpp + c] = static_cast<std::uint8_t>(std::clamp(out + 0.5f, 0.f, 255.f));
      }
    }
  }
}

}  // namespace augrig
