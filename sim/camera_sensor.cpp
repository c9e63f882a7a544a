#include "sim/camera_sensor.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <thread>
#include <vector>

namespace augrig {
namespace {

constexpr double kMaxPsfSigmaPx = 8.0;

inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// 65536 equal-probability quantiles of N(0, 1), rescaled to unit variance: 16 random bits give one
// Gaussian sample (tails cut at 4.3 sigma, which an 8-bit image cannot tell).
const std::array<float, 65536>& gaussian_table() {
  static const std::array<float, 65536> table = [] {
    std::array<float, 65536> t{};
    double sum2 = 0;
    for (std::size_t i = 0; i < t.size(); ++i) {
      // Inverse normal CDF by bisection on erfc: run once per process, exactness over speed.
      const double p = (static_cast<double>(i) + 0.5) / 65536.0;
      double lo = -10, hi = 10;
      for (int k = 0; k < 60; ++k) {
        const double mid = 0.5 * (lo + hi);
        (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
      }
      t[i] = static_cast<float>(0.5 * (lo + hi));
      sum2 += t[i] * static_cast<double>(t[i]);
    }
    const double scale = 1.0 / std::sqrt(sum2 / static_cast<double>(t.size()));
    for (float& v : t) v = static_cast<float>(v * scale);
    return t;
  }();
  return table;
}

std::vector<float> gaussian_kernel(double sigma) {
  if (!(sigma > 0)) return {1.0f};
  const int r = static_cast<int>(std::ceil(3.0 * sigma));
  std::vector<float> k(static_cast<std::size_t>(2 * r + 1));
  double sum = 0;
  for (int i = -r; i <= r; ++i)
    sum += k[static_cast<std::size_t>(i + r)] = static_cast<float>(std::exp(-0.5 * i * i / (sigma * sigma)));
  for (float& v : k) v = static_cast<float>(v / sum);
  return k;
}

// Runs fn(y0, y1) over `threads` row bands of [0, rows).
template <class Fn>
void in_bands(int rows, int threads, Fn fn) {
  const int n = std::clamp(threads, 1, 8);
  std::vector<std::thread> pool;
  for (int b = 1; b < n; ++b) pool.emplace_back([&, b] { fn(rows * b / n, rows * (b + 1) / n); });
  fn(0, rows / n);
  for (std::thread& t : pool) t.join();
}

}  // namespace

bool needs_camera_model(const CameraResponse& r) {
  return r.psf_sigma_px > 0 || r.noise_a > 0 || r.gain != 1.0 || r.gamma != 1.0;
}

Status check_camera_response(const CameraResponse& r) {
  const char* where = "SyntheticSceneRenderer::render(): ";
  if (!(r.psf_sigma_px >= 0 && r.psf_sigma_px <= kMaxPsfSigmaPx))
    return make_error(where, "psf_sigma_px must be 0 to ", kMaxPsfSigmaPx, " px, got ", r.psf_sigma_px);
  if (!(r.noise_a >= 0 && r.noise_a <= 100))
    return make_error(where, "noise_a must be 0 to 100 DN, got ", r.noise_a);
  if (!(r.noise_sigma >= 0 && r.noise_sigma <= 100))
    return make_error(where, "noise_sigma must be 0 to 100 DN, got ", r.noise_sigma);
  if (!(r.gain > 0 && r.gain <= 100)) return make_error(where, "gain must be > 0 and <= 100, got ", r.gain);
  if (!(r.gamma >= 0.2 && r.gamma <= 5)) return make_error(where, "gamma must be 0.2 to 5, got ", r.gamma);
  return {};
}

void apply_camera_response(const Image& radiance, const CameraResponse& r, PixelFormat format,
                           std::uint64_t seed, int camera, Image& out, int threads) {
  const int W = radiance.width(), H = radiance.height();
  if (out.width() != W || out.height() != H || out.format() != format) out = Image(W, H, format);
  const std::vector<float> k = gaussian_kernel(r.psf_sigma_px);
  const int kr = static_cast<int>(k.size() / 2);
  const std::size_t row_len = static_cast<std::size_t>(W) * 3;

  // 1. The PSF's horizontal pass, radiance to float rows (edges clamped).
  std::vector<float> horiz(row_len * static_cast<std::size_t>(H));
  in_bands(H, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const std::uint8_t* src = radiance.row(y);
      float* dst = horiz.data() + row_len * static_cast<std::size_t>(y);
      for (int x = 0; x < W; ++x)
        for (int c = 0; c < 3; ++c) {
          float s = 0;
          for (int i = -kr; i <= kr; ++i)
            s += k[static_cast<std::size_t>(i + kr)] *
                 static_cast<float>(src[3 * std::clamp(x + i, 0, W - 1) + c]);
          dst[3 * x + c] = s;
        }
    }
  });

  // The tone curve as a table over raw DN in steps of 1/16 (linear between entries).
  constexpr int kSteps = 16;
  std::vector<float> encode(256 * kSteps + 2);
  for (std::size_t i = 0; i < encode.size(); ++i) {
    const double raw = std::min(255.0, static_cast<double>(i) / kSteps);
    encode[i] = static_cast<float>(r.gamma == 1.0 ? raw : 255.0 * std::pow(raw / 255.0, 1.0 / r.gamma));
  }
  auto to_u8 = [&](float raw) {
    const float t = std::clamp(raw, 0.0f, 255.0f) * kSteps;
    const auto i = static_cast<std::size_t>(t);
    const float v = encode[i] + (t - static_cast<float>(i)) * (encode[i + 1] - encode[i]);
    return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0f, 255.0f)));
  };

  // 2-6. Vertical pass, gain, colour filter, noise, tone curve, 8 bits.
  const auto& gauss = gaussian_table();
  const std::uint64_t key =
      splitmix64(seed ^ (0x51ed270b27a3e1f1ull * (static_cast<std::uint64_t>(camera) + 1)));
  const double b = r.noise_sigma * r.noise_sigma;
  const bool bayer = is_bayer(format);
  in_bands(H, threads, [&](int y0, int y1) {
    std::vector<float> col(row_len);
    for (int y = y0; y < y1; ++y) {
      std::fill(col.begin(), col.end(), 0.0f);
      for (int i = -kr; i <= kr; ++i) {
        const float* src = horiz.data() + row_len * static_cast<std::size_t>(std::clamp(y + i, 0, H - 1));
        const float w = k[static_cast<std::size_t>(i + kr)];
        for (std::size_t j = 0; j < row_len; ++j) col[j] += w * src[j];
      }
      // Noise for pixel (x, y), channel slot s: 16 bits of the row's counter stream.
      const std::uint64_t row_key = splitmix64(key ^ (static_cast<std::uint64_t>(y) * 0xd6e8feb86659fd93ull));
      std::uint64_t bits = 0;
      int left = 0;
      std::uint64_t counter = 0;
      auto noisy = [&](double raw) {
        if (left == 0) bits = splitmix64(row_key + counter++), left = 4;
        const float z = gauss[bits & 0xffffu];
        bits >>= 16, --left;
        const double var = r.noise_a * std::max(raw, 0.0) + b;
        return static_cast<float>(raw + (var > 0 ? std::sqrt(var) * z : 0.0));
      };
      std::uint8_t* dst = out.row(y);
      for (int x = 0; x < W; ++x) {
        const float* p = &col[3 * static_cast<std::size_t>(x)];
        if (bayer) {
          dst[x] = to_u8(noisy(r.gain * p[bayer_channel(format, x, y)]));
        } else if (format == PixelFormat::kMono8) {
          dst[x] = to_u8(noisy(r.gain * (0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2])));
        } else {
          const int bpp = format == PixelFormat::kRGBA8 ? 4 : 3;
          for (int c = 0; c < 3; ++c) dst[bpp * x + c] = to_u8(noisy(r.gain * p[c]));
          if (bpp == 4) dst[4 * x + 3] = 255;
        }
      }
    }
  });
}

}  // namespace augrig
