#include "render/camera_look.hpp"

#include <algorithm>
#include <array>
#include <cmath>

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

SceneLight SceneLight::sun(const Eigen::Vector3d& towards_sun_body, bool sun_above_horizon, LightSource source,
                           const Eigen::Vector3d& down_body) {
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
  return l;
}

int psf_margin_px(const CameraLookParams& p) {
  return p.psf_sigma_px > 0 ? static_cast<int>(std::ceil(3.0 * std::min(p.psf_sigma_px, kMaxPsfSigmaPx))) + 1 : 0;
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
  for (int i = 0; i <= kToneTable; ++i) {
    const double x = static_cast<double>(i) / kToneTable;
    b.decode[i] = static_cast<float>(255.0 * std::pow(x, gamma));
    b.encode[i] = static_cast<float>(255.0 * std::pow(x, 1.0 / gamma));
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
  for (int k = -r; k <= r; ++k) sum += w[k + r] = static_cast<float>(std::exp(-0.5 * std::pow(k * step / sigma, 2)));
  for (float& x : w) x = static_cast<float>(x / sum);
  return w;
}

// A same-colour neighbour index inside [0, n): reflected back by whole steps at the edges.
int inside(int i, int n, int step) {
  while (i < 0) i += step;
  while (i >= n) i -= step;
  return std::clamp(i, 0, n - 1);
}

// Separable blur of a w x h plane of `nc` interleaved channels, in place (tmp: scratch).
void blur(std::vector<float>& p, std::vector<float>& tmp, int w, int h, int nc, int step,
          const std::vector<float>& k) {
  const int r = static_cast<int>(k.size() / 2);
  tmp.resize(p.size());
  for (int y = 0; y < h; ++y) {
    const float* src = &p[static_cast<std::size_t>(y) * w * nc];
    float* dst = &tmp[static_cast<std::size_t>(y) * w * nc];
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < nc; ++c) {
        float s = 0;
        for (int j = -r; j <= r; ++j) s += k[j + r] * src[inside(x + j * step, w, step) * nc + c];
        dst[x * nc + c] = s;
      }
  }
  const std::size_t row = static_cast<std::size_t>(w) * nc;
  for (int y = 0; y < h; ++y) {
    float* dst = &p[y * row];
    std::fill(dst, dst + row, 0.f);
    for (int j = -r; j <= r; ++j) {
      const float* src = &tmp[inside(y + j * step, h, step) * row];
      const float kj = k[j + r];
      for (std::size_t i = 0; i < row; ++i) dst[i] += kj * src[i];
    }
  }
}

}  // namespace

float gaussian_for_key(std::uint64_t key) {
  return gaussian_from_bits(normal_table().data(), static_cast<std::uint32_t>(splitmix64(key) >> 32));
}

void apply_camera_look(ConstImageView raw, ConstImageView alpha, ImageView aug, const PixelBox& box,
                       const CameraLookParams& params, std::uint64_t frame_key, int camera, LookBuffers& buf) {
  if (box.empty()) return;
  const Layout L = layout_of(raw.format);
  const int bw = box.width(), bh = box.height(), nc = L.nc;
  const bool linear = params.gamma == 1.0;
  if (!linear) build_tone_tables(params.gamma, buf);
  auto dec = [&](float e) { return linear ? e : lookup(buf.decode, e); };
  auto enc = [&](float l) { return linear ? l : lookup(buf.encode, l); };

  // 1. The boom's layer from the plain composite A = (1 - a) R + a C: coverage a and the
  //    premultiplied colour a C. C is the rendered radiance, linear already.
  const std::size_t n = static_cast<std::size_t>(bw) * bh;
  buf.layer.assign(n * nc, 0.f);
  buf.alpha.assign(n, 0.f);
  bool any = false;
  for (int y = 0; y < bh; ++y) {
    const std::uint8_t* ar = alpha.row(box.y0 + y) + box.x0;
    const std::uint8_t* rr = raw.row(box.y0 + y) + static_cast<std::size_t>(box.x0) * L.bpp;
    const std::uint8_t* pr = aug.row(y);
    for (int x = 0; x < bw; ++x) {
      if (!ar[x]) continue;
      any = true;
      const float a = ar[x] * (1.f / 255.f);
      const std::size_t i = static_cast<std::size_t>(y) * bw + x;
      buf.alpha[i] = a;
      for (int c = 0; c < nc; ++c) {
        const float A = pr[x * L.bpp + c], R = rr[x * L.bpp + c];
        buf.layer[i * nc + c] = std::clamp(A - (1 - a) * R, 0.f, 255.f * a);
      }
    }
  }
  if (!any) return;

  // 2. Optics: the layer and its coverage through the PSF.
  if (params.psf_sigma_px > 0) {
    const std::vector<float> k = gaussian_kernel(std::min(params.psf_sigma_px, kMaxPsfSigmaPx), L.step);
    blur(buf.layer, buf.tmp, bw, bh, nc, L.step, k);
    blur(buf.alpha, buf.tmp, bw, bh, 1, L.step, k);
  }

  // 3. Composite in linear light, back through the tone curve, and 4. the sensor's noise: the
  //    NLF's variance at the new value less what the raw pixel's noise carries into it.
  const float* gt = normal_table().data();
  const std::uint64_t view_key = splitmix64(params.seed ^ splitmix64(frame_key ^ (0x51ed270b27e4a5c3ULL * (camera + 1))));
  for (int y = 0; y < bh; ++y) {
    const std::uint8_t* rr = raw.row(box.y0 + y) + static_cast<std::size_t>(box.x0) * L.bpp;
    std::uint8_t* pr = aug.row(y);
    const int v = box.y0 + y;
    for (int x = 0; x < bw; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * bw + x;
      const float ab = std::min(buf.alpha[i], 1.f);
      if (ab < 1.f / 1024.f) continue;  // the blur's far tail: the raw pixel stays as it is
      const int u = box.x0 + x;
      const std::uint64_t h = splitmix64(view_key ^ (static_cast<std::uint64_t>(v) << 32 | static_cast<std::uint32_t>(u)));
      for (int c = 0; c < nc; ++c) {
        const float R = rr[x * L.bpp + c];
        float out = enc((1 - ab) * dec(R) + buf.layer[i * nc + c]);
        if (!params.noise.empty()) {
          const int ch = noise_channel(raw.format, u, v, c);
          // d(out)/d(R) = (1 - ab) enc'(.) dec'(R) = (1 - ab) (R / out)^(gamma - 1)
          const float carry = linear ? 1 - ab : (1 - ab) * static_cast<float>(std::pow(std::max(R, 0.5f) / std::max(out, 0.5f), params.gamma - 1));
          const double need = params.noise.variance(ch, out) - carry * carry * params.noise.variance(ch, R);
          if (need > 0) {
            const auto bits = static_cast<std::uint32_t>(c == 0 ? h >> 32 : c == 1 ? h : splitmix64(h) >> 32);
            out += static_cast<float>(std::sqrt(need)) * gaussian_from_bits(gt, bits);
          }
        }
        pr[x * L.bpp + c] = static_cast<std::uint8_t>(std::clamp(out + 0.5f, 0.f, 255.f));
      }
    }
  }
}

}  // namespace augrig
