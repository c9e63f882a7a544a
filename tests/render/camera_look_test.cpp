// Tests of render/camera_look: the noise generator's distribution, and the look over synthetic
// noisy frames with a known boom layer, measured as a researcher would: a robust high-pass sigma
// inside the boom against the noise level function's, edge widths against the PSF's, pixels left
// alone outside the boom's blurred footprint, the same pixels for the same frame.
#include "render/camera_look.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace augrig {
namespace {

// sigma^2 = a I + b per channel.
NoiseLevelFunction nlf(int channels, double a, double b) {
  NoiseLevelFunction f;
  f.channels = channels;
  for (int c = 0; c < 3; ++c) f.a[c] = a * (1 + 0.3 * c), f.b[c] = b * (1 + 0.2 * c);
  return f;
}

int channels_of(PixelFormat f) {
  return f == PixelFormat::kRGB8 || f == PixelFormat::kRGBA8 ? 3 : 1;
}

// A raw frame: `signal(x, y, c)` plus noise drawn from `f` (the channel as noise_channel() names it).
template <typename Signal>
Image noisy_frame(int w, int h, PixelFormat fmt, const NoiseLevelFunction& f, Signal signal, unsigned seed) {
  Image img(w, h, fmt);
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01;
  const int bpp = bytes_per_pixel(fmt), nc = channels_of(fmt);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < bpp; ++c) {
        if (c >= nc) {
          img.row(y)[x * bpp + c] = 255;
          continue;
        }
        const double s = signal(x, y, c);
        const double v = s + std::sqrt(f.variance(noise_channel(fmt, x, y, c), s)) * n01(rng);
        img.row(y)[x * bpp + c] = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
      }
  return img;
}

// The plain composite of a boom of colour `boom(c)` over `raw` with coverage `alpha`.
template <typename Colour>
Image composite(const Image& raw, const Image& alpha, Colour boom) {
  Image out = Image::copy_of(raw.view());
  const int bpp = bytes_per_pixel(raw.format()), nc = channels_of(raw.format());
  for (int y = 0; y < raw.height(); ++y)
    for (int x = 0; x < raw.width(); ++x) {
      const float a = alpha.row(y)[x] / 255.f;
      if (a <= 0) continue;
      for (int c = 0; c < nc; ++c) {
        const int ch = is_bayer(raw.format()) ? bayer_channel(raw.format(), x, y) : c;
        const float v = (1 - a) * raw.row(y)[x * bpp + c] + a * boom(ch);
        out.row(y)[x * bpp + c] = static_cast<std::uint8_t>(std::clamp(v + 0.5f, 0.f, 255.f));
      }
    }
  return out;
}

// Coverage of a disc of radius r at (cx, cy), 4x4 supersampled.
Image disc_alpha(int w, int h, double cx, double cy, double r) {
  Image a(w, h, PixelFormat::kMono8);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      int in = 0;
      for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
          const double dx = x - 0.375 + 0.25 * i - cx, dy = y - 0.375 + 0.25 * j - cy;
          in += dx * dx + dy * dy <= r * r;
        }
      a.row(y)[x] = static_cast<std::uint8_t>(std::lround(in * 255.0 / 16));
    }
  return a;
}

// Robust high-pass sigma of channel c over the pixels where `inside(x, y)`: the residual of the
// same-colour neighbours' [1 -2 1] x [1 -2 1] (step 2 on a Bayer mosaic), normalised to the noise
// sigma (sum of squared weights 36), its median absolute value / 0.6745.
template <typename Inside>
double robust_hp_sigma(const Image& img, int c, Inside inside) {
  const int bpp = bytes_per_pixel(img.format()), s = is_bayer(img.format()) ? 2 : 1;
  std::vector<double> r;
  for (int y = s; y < img.height() - s; ++y)
    for (int x = s; x < img.width() - s; ++x) {
      if (!inside(x, y)) continue;
      auto p = [&](int dx, int dy) {
        return static_cast<double>(img.row(y + dy * s)[(x + dx * s) * bpp + c]);
      };
      const double v = p(-1, -1) - 2 * p(0, -1) + p(1, -1) - 2 * p(-1, 0) + 4 * p(0, 0) - 2 * p(1, 0) +
                       p(-1, 1) - 2 * p(0, 1) + p(1, 1);
      r.push_back(std::abs(v) / 6.0);
    }
  std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
  return r[r.size() / 2] / 0.6745;
}

TEST(CameraLook, GaussianDeviatesAreStandardNormalAndDeterministic) {
  double m1 = 0, m2 = 0, m4 = 0, mx = 0;
  const int n = 400000;
  for (int i = 0; i < n; ++i) {
    const double g = gaussian_for_key(static_cast<std::uint64_t>(i));
    m1 += g, m2 += g * g, m4 += g * g * g * g, mx = std::max(mx, std::abs(g));
  }
  m1 /= n, m2 /= n, m4 /= n;
  EXPECT_NEAR(m1, 0.0, 0.005);
  EXPECT_NEAR(m2, 1.0, 0.01);
  EXPECT_NEAR(m4 / (m2 * m2), 3.0, 0.1);  // Gaussian kurtosis
  EXPECT_GT(mx, 3.0);
  EXPECT_LT(mx, 4.0);
  EXPECT_EQ(gaussian_for_key(12345), gaussian_for_key(12345));
}

TEST(CameraLook, ParsesItsNames) {
  Look l = Look::kPlain;
  EXPECT_TRUE(parse_look("camera", l));
  EXPECT_EQ(l, Look::kCamera);
  EXPECT_TRUE(parse_look("plain", l));
  EXPECT_EQ(l, Look::kPlain);
  EXPECT_FALSE(parse_look("Camera", l));
  EXPECT_STREQ(to_string(Look::kCamera), "camera");
}

struct NoiseCase {
  PixelFormat fmt;
  double a, b;
  bool textured;
};

class CameraLookNoise : public ::testing::TestWithParam<NoiseCase> {};

// Inside the boom the look's noise matches the NLF at the boom's level (a plain composite has
// none), for flat and textured backgrounds, RGB, Mono and Bayer, several signal-dependent levels.
TEST_P(CameraLookNoise, BoomNoiseMatchesTheNoiseLevelFunction) {
  const NoiseCase& k = GetParam();
  const int w = 240, h = 200;
  const int nc = channels_of(k.fmt);
  const NoiseLevelFunction f = nlf(is_bayer(k.fmt) || nc == 3 ? 3 : 1, k.a, k.b);
  auto signal = [&](int x, int y, int c) {
    const double base = 90 + 10 * c;
    return k.textured
               ? base + 50 * std::sin(x * 0.21) * std::cos(y * 0.17) + (((x / 9) + (y / 7)) % 2 ? 30 : -30)
               : base;
  };
  const Image raw = noisy_frame(w, h, k.fmt, f, signal, 7);
  const Image alpha = disc_alpha(w, h, 120.3, 99.6, 70);
  auto boom = [](int ch) { return 150.f + 20.f * ch; };
  const Image plain = composite(raw, alpha, boom);
  Image look = Image::copy_of(plain.view());
  CameraLookParams p;
  p.noise = f;
  p.psf_sigma_px = 0.8;
  LookBuffers buf;
  const PixelBox box{30, 10, 211, 190};
  apply_camera_look(raw.view(), alpha.view(), sub_view(look.view(), box), box, p, 1000, 0, buf);

  auto deep_inside = [&](int x, int y) { return std::hypot(x - 120.3, y - 99.6) < 62; };
  for (int c = 0; c < nc; ++c) {
    for (int site = 0; site < (is_bayer(k.fmt) ? 4 : 1); ++site) {
      const int sx = site & 1, sy = site >> 1;
      auto in_site = [&](int x, int y) {
        return deep_inside(x, y) && (!is_bayer(k.fmt) || ((x & 1) == sx && (y & 1) == sy));
      };
      const int ch = is_bayer(k.fmt) ? bayer_channel(k.fmt, sx, sy) : c;
      const double want = std::sqrt(f.variance(ch, boom(ch)) + 1.0 / 12);  // + rounding to 8 bits
      const double got = robust_hp_sigma(look, c, in_site);
      SCOPED_TRACE(testing::Message() << to_string(k.fmt) << " c" << c << " site " << site << " a " << k.a
                                      << " b " << k.b << (k.textured ? " textured" : " flat"));
      EXPECT_GT(got / want, 0.9);
      EXPECT_LT(got / want, 1.1);
      EXPECT_LT(robust_hp_sigma(plain, c, in_site), 0.3 * want);  // the plain look: a clean CG object
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Formats, CameraLookNoise,
                         ::testing::Values(NoiseCase{PixelFormat::kRGB8, 0.0, 4.0, false},
                                           NoiseCase{PixelFormat::kRGB8, 0.2, 1.0, true},
                                           NoiseCase{PixelFormat::kRGBA8, 0.05, 0.5, true},
                                           NoiseCase{PixelFormat::kMono8, 0.5, 2.0, false},
                                           NoiseCase{PixelFormat::kMono8, 0.02, 9.0, true},
                                           NoiseCase{PixelFormat::kBayerRG8, 0.3, 1.0, false},
                                           NoiseCase{PixelFormat::kBayerGB8, 0.1, 4.0, true}));

// The edge's 10-90 % width across a vertical boom edge follows the PSF (Gaussian: 2.563 sigma),
// measured on the noise-free look; outside the blurred footprint the raw pixels stay.
TEST(CameraLook, EdgesFollowThePsfAndNothingElseChanges) {
  const int w = 120, h = 40;
  const Image raw = noisy_frame(
      w, h, PixelFormat::kMono8, nlf(1, 0, 0), [](int, int, int) { return 40.0; }, 1);
  Image alpha(w, h, PixelFormat::kMono8);
  const double edge_x = 60.3;  // the boom covers x < edge_x
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      alpha.row(y)[x] =
          static_cast<std::uint8_t>(std::lround(255 * std::clamp(edge_x - (x - 0.5), 0.0, 1.0)));
  const Image plain = composite(raw, alpha, [](int) { return 200.f; });
  for (const double sigma : {0.0, 0.7, 1.5, 3.0}) {
    Image look = Image::copy_of(plain.view());
    CameraLookParams p;
    p.psf_sigma_px = sigma;
    LookBuffers buf;
    const PixelBox box{0, 0, w, h};
    apply_camera_look(raw.view(), alpha.cview(), look.view(), box, p, 1, 0, buf);
    // Sub-pixel crossings of 10 % and 90 % on the middle row (the edge falls with x).
    const std::uint8_t* r = look.row(h / 2);
    auto crossing = [&](double level) {
      for (int x = 1; x < w; ++x)
        if (r[x - 1] >= level && r[x] < level) return x - 1 + (r[x - 1] - level) / double(r[x - 1] - r[x]);
      return -1.0;
    };
    const double width = crossing(40 + 0.1 * 160) - crossing(40 + 0.9 * 160);
    // A 1-pixel box (the pixel's own area) convolved with the Gaussian; with no PSF the sharp
    // plain edge (one mixed pixel: between 1 and 1.5 px read off the samples).
    SCOPED_TRACE(sigma);
    if (sigma > 0)
      EXPECT_NEAR(width, 2.563 * std::sqrt(sigma * sigma + 1.0 / 12), 0.35);
    else
      EXPECT_LE(width, 1.5);
    const int m = psf_margin_px(p);
    for (int y = 0; y < h; ++y)
      for (int x = static_cast<int>(edge_x) + m + 1; x < w; ++x) ASSERT_EQ(look.row(y)[x], raw.row(y)[x]);
  }
}

// The blur, which reads and writes each row only over the boom's span, against OpenCV's separable
// filter over the whole image: a thin diagonal band that leaves the image at two edges, a gap in
// it, and a separate blob; RGB and Mono (replicated borders), Bayer; linear and gamma 2.2.
TEST(CameraLook, BlurOverTheSpansIsOpenCvsOverTheWholeImage) {
  const int w = 160, h = 120;
  Image alpha(w, h, PixelFormat::kMono8);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double d = std::abs((x - 30) - 1.1 * y) / std::hypot(1.0, 1.1);  // distance to the band's axis
      double a = std::clamp(6.5 - d, 0.0, 1.0);
      if (y > 50 && y < 56) a = 0;                  // the gap
      if (std::hypot(x - 40, y - 90) < 7.3) a = 1;  // the blob
      alpha.row(y)[x] = static_cast<std::uint8_t>(std::lround(255 * a));
    }
  for (const PixelFormat fmt : {PixelFormat::kRGB8, PixelFormat::kMono8, PixelFormat::kBayerRG8})
    for (const double gamma : {1.0, 2.2})
      for (const double sigma : {0.6, 1.7}) {
        SCOPED_TRACE(std::string(to_string(fmt)) + ", gamma " + std::to_string(gamma) + ", sigma " +
                     std::to_string(sigma));
        const int nc = channels_of(fmt), bpp = bytes_per_pixel(fmt), step = is_bayer(fmt) ? 2 : 1;
        const Image raw = noisy_frame(
            w, h, fmt, nlf(nc, 0, 0),
            [](int x, int y, int c) { return 60 + 50 * std::sin(0.3 * x + 0.2 * y + c); }, 7);
        const Image plain = composite(raw, alpha, [](int c) { return 150.f + 30 * c; });
        Image look = Image::copy_of(plain.view());
        CameraLookParams p;
        p.psf_sigma_px = sigma;
        p.gamma = gamma;
        LookBuffers buf;
        apply_camera_look(raw.view(), alpha.cview(), look.view(), PixelBox{0, 0, w, h}, p, 1, 0, buf);
        // The reference, blurred by OpenCV with the same sampled Gaussians and composited with exact
        // powers. RGB and Mono: the linear layer and coverage planes per channel. Bayer (the lens
        // blurs before the mosaic): the coverage at full resolution; the colour per site plane as
        // the ratio of the site's blurred layer and coverage (at least 1 px wide), times it.
        auto dec = [&](double e) { return 255 * std::pow(e / 255, gamma); };
        auto enc = [&](double l) { return 255 * std::pow(std::clamp(l, 0.0, 255.0) / 255, 1 / gamma); };
        auto gauss = [](cv::Mat& m, double s) {
          const cv::Mat k = cv::getGaussianKernel(2 * static_cast<int>(std::ceil(3 * s)) + 1, s, CV_32F);
          cv::sepFilter2D(m, m, -1, k, k, {-1, -1}, 0, cv::BORDER_REPLICATE);
        };
        cv::Mat full(h, w, CV_32F);
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) full.at<float>(y, x) = alpha.row(y)[x] / 255.f;
        gauss(full, sigma);
        const double site_sigma = step == 1 ? sigma : std::max(sigma, 1.0) / step;
        int off = 0;
        for (int sy = 0; sy < step; ++sy)
          for (int sx = 0; sx < step; ++sx)
            for (int c = 0; c < nc; ++c) {
              const int pw = w / step, ph = h / step;
              cv::Mat L(ph, pw, CV_32F), A(ph, pw, CV_32F);
              for (int y = 0; y < ph; ++y)
                for (int x = 0; x < pw; ++x) {
                  const int X = x * step + sx, Y = y * step + sy;
                  const float a = alpha.row(Y)[X] / 255.f;
                  const float R = raw.row(Y)[X * bpp + c], P = plain.row(Y)[X * bpp + c];
                  A.at<float>(y, x) = a;
                  L.at<float>(y, x) = a > 0 ? std::clamp(P - (1 - a) * R, 0.f, 255 * a) : 0.f;
                }
              gauss(L, site_sigma);
              gauss(A, site_sigma);
              for (int y = 0; y < ph; ++y)
                for (int x = 0; x < pw; ++x) {
                  const int X = x * step + sx, Y = y * step + sy;
                  double ab = std::min(A.at<float>(y, x), 1.f), layer = L.at<float>(y, x);
                  if (step == 2) {
                    const bool known = A.at<float>(y, x) > 1e-6f;
                    layer = known ? layer / A.at<float>(y, x) * full.at<float>(Y, X) : 0;
                    ab = known ? std::min(full.at<float>(Y, X), 1.f) : 0;
                  }
                  const double R = raw.row(Y)[X * bpp + c];
                  const double want = ab < 1.0 / 1024 ? R : enc((1 - ab) * dec(R) + layer);
                  const int got = look.row(Y)[X * bpp + c];
                  if (std::abs(got - want) > 1.0 && off++ < 5)
                    ADD_FAILURE() << "pixel (" << X << ", " << Y << ") channel " << c << ": " << got
                                  << ", want " << want;
                }
            }
      }
}

// The same (seed, frame, camera) gives the same pixels; another frame or camera other noise.
TEST(CameraLook, NoiseIsDeterministicPerSeedFrameAndCamera) {
  const int w = 64, h = 64;
  const NoiseLevelFunction f = nlf(3, 0.1, 2);
  const Image raw = noisy_frame(
      w, h, PixelFormat::kRGB8, f, [](int, int, int) { return 80.0; }, 3);
  const Image alpha = disc_alpha(w, h, 32, 32, 20);
  const Image plain = composite(raw, alpha, [](int) { return 160.f; });
  auto run = [&](std::uint64_t seed, std::uint64_t frame, int camera) {
    Image look = Image::copy_of(plain.view());
    CameraLookParams p;
    p.noise = f;
    p.seed = seed;
    LookBuffers buf;
    apply_camera_look(raw.view(), alpha.cview(), look.view(), {0, 0, w, h}, p, frame, camera, buf);
    return look;
  };
  const Image a = run(1, 100, 0);
  EXPECT_TRUE(pixels_equal(a, run(1, 100, 0)));
  EXPECT_FALSE(pixels_equal(a, run(1, 101, 0)));
  EXPECT_FALSE(pixels_equal(a, run(1, 100, 1)));
  EXPECT_FALSE(pixels_equal(a, run(2, 100, 0)));
}

// The layer built instant by instant (motion blur): one instant of weight 1, or two equal halves,
// is apply_camera_look() byte for byte (every format); two discs at different places average to
// a layer between them, composited over the raw pixels (the plain composite's pixels unread).
TEST(CameraLook, LayerAveragedOverInstantsIsTheLookOfTheirMean) {
  const int w = 64, h = 48;
  for (PixelFormat fmt : {PixelFormat::kRGB8, PixelFormat::kBayerRG8, PixelFormat::kMono8}) {
    SCOPED_TRACE(to_string(fmt));
    const NoiseLevelFunction f = nlf(channels_of(fmt), 0.1, 2);
    const Image raw = noisy_frame(
        w, h, fmt, f, [](int, int, int) { return 70.0; }, 5);
    const Image alpha = disc_alpha(w, h, 30, 24, 12), alpha2 = disc_alpha(w, h, 36, 24, 12);
    const Image plain = composite(raw, alpha, [](int c) { return 150.f + 20 * c; });
    const Image plain2 = composite(raw, alpha2, [](int c) { return 150.f + 20 * c; });
    CameraLookParams p;
    p.noise = f;
    p.psf_sigma_px = 0.8;
    const PixelBox box{2, 3, w - 1, h - 2};
    LookBuffers buf;
    Image ref = Image::copy_of(plain.view());
    apply_camera_look(raw.view(), alpha.cview(), sub_view(ref.view(), box), box, p, 7, 1, buf);
    for (int halves : {1, 2}) {
      Image look = Image::copy_of(raw.view());  // the look does not read the composite's pixels
      begin_look_layer(box, fmt, buf);
      for (int k = 0; k < halves; ++k)
        add_to_look_layer(raw.view(), alpha.cview(), sub_view(plain.cview(), box), box, 1.f / halves, buf);
      apply_look_layer(raw.view(), sub_view(look.view(), box), p, 7, 1, buf);
      EXPECT_TRUE(pixels_equal(look, ref)) << halves << " instants";
    }
    // Two instants apart: the pixels covered by one only are between the raw and the boom.
    Image look = Image::copy_of(raw.view());
    CameraLookParams clean = p;
    clean.noise = {};
    begin_look_layer(box, fmt, buf);
    add_to_look_layer(raw.view(), alpha.cview(), sub_view(plain.cview(), box), box, 0.5f, buf);
    const PixelBox part{20, 10, 50, 40};  // an instant's own box, inside the layer's
    add_to_look_layer(raw.view(), alpha2.cview(), sub_view(plain2.cview(), part), part, 0.5f, buf);
    apply_look_layer(raw.view(), sub_view(look.view(), box), clean, 7, 1, buf);
    const int bpp = bytes_per_pixel(fmt);
    const double at_left = look.row(24)[21 * bpp], at_middle = look.row(24)[33 * bpp],
                 at_right = look.row(24)[45 * bpp];
    const double r_left = raw.row(24)[21 * bpp], r_right = raw.row(24)[45 * bpp];
    EXPECT_GT(at_middle, 140);
    EXPECT_GT(at_left, r_left + 20);  // half covered: about halfway
    EXPECT_LT(at_left, at_middle - 20);
    EXPECT_GT(at_right, r_right + 20);
    EXPECT_LT(at_right, at_middle - 20);
  }
}

// With a tone curve the composite is made in linear light: a half-covered pixel of a white boom
// over black is encoded as half the linear light, not as half the encoded value.
TEST(CameraLook, CompositesInLinearLight) {
  const int w = 16, h = 16;
  const Image raw = noisy_frame(
      w, h, PixelFormat::kMono8, nlf(1, 0, 0), [](int, int, int) { return 0.0; }, 1);
  Image alpha(w, h, PixelFormat::kMono8);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) alpha.row(y)[x] = x < 8 ? 255 : x == 8 ? 128 : 0;
  const Image plain = composite(raw, alpha, [](int) { return 255.f; });
  Image look = Image::copy_of(plain.view());
  CameraLookParams p;
  p.psf_sigma_px = 0;
  p.gamma = 2.2;
  LookBuffers buf;
  apply_camera_look(raw.view(), alpha.cview(), look.view(), {0, 0, w, h}, p, 1, 0, buf);
  EXPECT_EQ(look.row(4)[3], 255);
  EXPECT_NEAR(look.row(4)[8], 255 * std::pow(128 / 255.0, 1 / 2.2), 1.5);
  EXPECT_EQ(look.row(4)[12], 0);
}

// The shadow's darkening (apply_shadow_look): a disc of shadow taking half the red, a quarter of
// the green and three quarters of the blue light, on flat frames of every format: inside, each
// sample keeps its channel's share (its site's colour on a mosaic, green on Mono) through the tone
// curve; its edge spreads by the PSF and no further; the same pixels for the same frame.
TEST(CameraLook, ShadowDarkensBySharePerChannelWithinThePsfsReach) {
  for (const PixelFormat fmt : {PixelFormat::kRGB8, PixelFormat::kRGBA8, PixelFormat::kMono8, PixelFormat::kBayerRG8,
                                PixelFormat::kBayerGB8}) {
    for (const double gamma : {1.0, 2.2}) {
      SCOPED_TRACE(std::string(to_string(fmt)) + " gamma " + std::to_string(gamma));
      const int W = 160, H = 120, bpp = bytes_per_pixel(fmt), nc = channels_of(fmt);
      Image img(W, H, fmt);
      for (int y = 0; y < H; ++y) std::memset(img.row(y), 200, static_cast<std::size_t>(W) * bpp);
      std::vector<ShadowPixel> shadow;
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
          if ((x - 80) * (x - 80) + (y - 60) * (y - 60) <= 30 * 30) shadow.push_back({x, y, {0.5f, 0.25f, 0.75f}});
      CameraLookParams p;
      p.psf_sigma_px = 1.2;
      p.gamma = gamma;
      const int m = psf_margin_px(p);
      const PixelBox box{80 - 30 - m, 60 - 30 - m, 80 + 31 + m, 60 + 31 + m};
      LookBuffers buf;
      Image out = Image::copy_of(img.cview());
      apply_shadow_look(sub_view(out.view(), box), box, shadow, p, 42, 0, buf);
      const double keep[3] = {0.5, 0.75, 0.25};
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
          const double r = std::hypot(x - 80, y - 60);
          for (int c = 0; c < nc; ++c) {
            const int v = out.row(y)[x * bpp + c];
            if (r > 30 + m + 1) {
              ASSERT_EQ(v, 200) << x << ", " << y;  // beyond the blur's reach
            } else if (r < 30 - m) {
              const int lc = nc == 3 ? c : is_bayer(fmt) ? bayer_channel(fmt, x, y) : 1;
              const double want = 255 * std::pow(keep[lc] * std::pow(200 / 255.0, gamma), 1 / gamma);
              ASSERT_NEAR(v, want, 1.0) << x << ", " << y << " channel " << c;
            }
          }
          if (fmt == PixelFormat::kRGBA8) {
            ASSERT_EQ(out.row(y)[x * 4 + 3], 200);  // alpha is no light
          }
        }
      // The edge is soft: between the inside and the outside along a row through the centre.
      const int lc = nc == 3 ? 0 : is_bayer(fmt) ? bayer_channel(fmt, 110, 60) : 1;
      const int at_edge = out.row(60)[110 * bpp];
      const double inside = 255 * std::pow(keep[lc] * std::pow(200 / 255.0, gamma), 1 / gamma);
      EXPECT_GT(at_edge, inside + 3);
      EXPECT_LT(at_edge, 197);
      // Deterministic, and the same with no noise configured as with none to add.
      Image again = Image::copy_of(img.cview());
      apply_shadow_look(sub_view(again.view(), box), box, shadow, p, 42, 0, buf);
      EXPECT_EQ(0, std::memcmp(again.data(), out.data(), static_cast<std::size_t>(out.stride_bytes()) * H));
    }
  }
}

}  // namespace
}  // namespace augrig
