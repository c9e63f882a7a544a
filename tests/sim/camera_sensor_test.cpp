// The simulated camera's response (sim/camera_sensor.hpp) against what each stage must do:
// noise variance a * signal + b on flat fields (every format), the PSF's 10-90 % edge width
// (2.5631 sigma for a Gaussian), the tone curve, determinism per seed whatever the threads, and
// the checks of its parameters.
#include "sim/camera_sensor.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include <gtest/gtest.h>

namespace augrig {
namespace {

Image flat_rgb(int w, int h, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  Image img(w, h, PixelFormat::kRGB8);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img.row(y)[3 * x] = r, img.row(y)[3 * x + 1] = g, img.row(y)[3 * x + 2] = b;
  return img;
}

// Variance of the samples of channel `c` (Bayer: of the sites whose channel is c).
double variance_of(const Image& img, int c, double& mean) {
  double s = 0, s2 = 0;
  long n = 0;
  const int bpp = bytes_per_pixel(img.format());
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) {
      double v;
      if (is_bayer(img.format())) {
        if (bayer_channel(img.format(), x, y) != c) continue;
        v = img.row(y)[x];
      } else {
        v = img.row(y)[bpp * x + (bpp == 1 ? 0 : c)];
      }
      s += v, s2 += v * v, ++n;
    }
  mean = s / static_cast<double>(n);
  return s2 / static_cast<double>(n) - mean * mean;
}

TEST(CameraSensorTest, NoiseVarianceIsShotPlusReadNoiseInEveryFormat) {
  const Image radiance = flat_rgb(512, 384, 40, 120, 200);
  CameraResponse r;
  r.noise_a = 0.3, r.noise_sigma = 2.0;
  for (PixelFormat f :
       {PixelFormat::kRGB8, PixelFormat::kRGBA8, PixelFormat::kBayerRG8, PixelFormat::kBayerGB8}) {
    Image out;
    apply_camera_response(radiance, r, f, 7, 0, out);
    for (int c = 0; c < 3; ++c) {
      double mean = 0;
      const double var = variance_of(out, c, mean);
      const double signal = c == 0 ? 40 : c == 1 ? 120 : 200;
      const double expected = r.noise_a * signal + r.noise_sigma * r.noise_sigma + 1.0 / 12;  // + rounding
      EXPECT_NEAR(mean, signal, 0.15) << "format " << static_cast<int>(f) << " channel " << c;
      EXPECT_NEAR(var / expected, 1.0, 0.03) << "format " << static_cast<int>(f) << " channel " << c;
    }
  }
  // Mono: the luma's noise.
  Image mono;
  apply_camera_response(flat_rgb(512, 384, 100, 100, 100), r, PixelFormat::kMono8, 7, 0, mono);
  double mean = 0;
  EXPECT_NEAR(variance_of(mono, 0, mean) / (0.3 * 100 + 4 + 1.0 / 12), 1.0, 0.03);
}

TEST(CameraSensorTest, GainScalesTheSignalBeforeTheNoise) {
  CameraResponse r;
  r.gain = 1.5, r.noise_a = 0.5;
  Image out;
  apply_camera_response(flat_rgb(400, 300, 80, 80, 80), r, PixelFormat::kRGB8, 1, 0, out);
  double mean = 0;
  const double var = variance_of(out, 1, mean);
  EXPECT_NEAR(mean, 120, 0.2);
  EXPECT_NEAR(var / (0.5 * 120 + 1.0 / 12), 1.0, 0.03);
}

// A vertical step edge (20 -> 220 DN) blurred by the PSF: each pixel of a row is the step
// convolved with the sampled, normalised Gaussian (computed here in double), within rounding; and
// for a wide PSF the 10-90 % width, found by linear interpolation between pixels, is the
// continuous Gaussian's 2.5631 sigma (narrow ones are too few pixels wide to interpolate).
TEST(CameraSensorTest, PsfIsTheGaussianOnTheEdge) {
  for (double sigma : {0.7, 1.0, 2.0, 3.0}) {
    Image step(64, 8, PixelFormat::kRGB8);
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 64; ++x)
        for (int c = 0; c < 3; ++c) step.row(y)[3 * x + c] = x < 32 ? 20 : 220;
    CameraResponse r;
    r.psf_sigma_px = sigma;
    Image out;
    apply_camera_response(step, r, PixelFormat::kRGB8, 1, 0, out);
    const int radius = static_cast<int>(std::ceil(3 * sigma));
    double norm = 0;
    for (int i = -radius; i <= radius; ++i) norm += std::exp(-0.5 * i * i / (sigma * sigma));
    std::vector<double> p(64);
    for (int x = 0; x < 64; ++x) {
      double expected = 0;
      for (int i = -radius; i <= radius; ++i)
        expected +=
            std::exp(-0.5 * i * i / (sigma * sigma)) / norm * (std::clamp(x + i, 0, 63) < 32 ? 20 : 220);
      EXPECT_NEAR(out.row(4)[3 * x], expected, 0.51) << "sigma " << sigma << " x " << x;
      p[static_cast<std::size_t>(x)] = (out.row(4)[3 * x] - 20.0) / 200.0;
    }
    if (sigma < 2) continue;
    auto crossing = [&](double level) {
      for (int x = 1; x < 64; ++x)
        if (p[static_cast<std::size_t>(x)] >= level)
          return x - 1 +
                 (level - p[static_cast<std::size_t>(x - 1)]) /
                     (p[static_cast<std::size_t>(x)] - p[static_cast<std::size_t>(x - 1)]);
      return 1e9;
    };
    EXPECT_NEAR(crossing(0.9) - crossing(0.1), 2.5631 * sigma, 0.15) << "sigma " << sigma;
  }
}

TEST(CameraSensorTest, ToneCurveEncodesTheRawValue) {
  CameraResponse r;
  r.gamma = 2.2;
  Image out;
  apply_camera_response(flat_rgb(8, 8, 50, 128, 255), r, PixelFormat::kRGB8, 1, 0, out);
  EXPECT_EQ(out.row(3)[0], static_cast<int>(std::lround(255 * std::pow(50 / 255.0, 1 / 2.2))));
  EXPECT_EQ(out.row(3)[1], static_cast<int>(std::lround(255 * std::pow(128 / 255.0, 1 / 2.2))));
  EXPECT_EQ(out.row(3)[2], 255);
}

TEST(CameraSensorTest, DeterministicPerSeedAndCameraWhateverTheThreads) {
  Image radiance(300, 200, PixelFormat::kRGB8);
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 900; ++x) radiance.row(y)[x] = static_cast<std::uint8_t>((x * 7) ^ (y * 13));
  CameraResponse r;
  r.psf_sigma_px = 0.8, r.noise_a = 0.2, r.noise_sigma = 1.5;
  Image a, b, c, d;
  apply_camera_response(radiance, r, PixelFormat::kBayerRG8, 42, 0, a, 1);
  apply_camera_response(radiance, r, PixelFormat::kBayerRG8, 42, 0, b, 3);
  apply_camera_response(radiance, r, PixelFormat::kBayerRG8, 42, 1, c, 2);
  apply_camera_response(radiance, r, PixelFormat::kBayerRG8, 43, 0, d, 2);
  auto same = [](const Image& p, const Image& q) {
    for (int y = 0; y < p.height(); ++y)
      if (std::memcmp(p.row(y), q.row(y), static_cast<std::size_t>(p.width())) != 0) return false;
    return true;
  };
  EXPECT_TRUE(same(a, b));
  EXPECT_FALSE(same(a, c));  // another camera, other noise
  EXPECT_FALSE(same(a, d));  // another seed, other noise
}

TEST(CameraSensorTest, ChecksItsParameters) {
  EXPECT_FALSE(needs_camera_model(CameraResponse{}));
  CameraResponse read_only;
  read_only.noise_sigma = 3;
  EXPECT_FALSE(needs_camera_model(read_only));  // the renderers' own additive noise does this
  struct Bad {
    CameraResponse r;
    const char* field;
  };
  std::vector<Bad> bad(5);
  bad[0].r.psf_sigma_px = 9, bad[0].field = "psf_sigma_px";
  bad[1].r.noise_a = -1, bad[1].field = "noise_a";
  bad[2].r.gain = 0, bad[2].field = "gain";
  bad[3].r.gamma = 0.1, bad[3].field = "gamma";
  bad[4].r.psf_sigma_px = NAN, bad[4].field = "psf_sigma_px";
  for (const Bad& b : bad) {
    const Status s = check_camera_response(b.r);
    ASSERT_FALSE(s) << b.field;
    EXPECT_NE(s.error().message.find(b.field), std::string::npos) << s.error().message;
  }
  EXPECT_TRUE(check_camera_response(CameraResponse{}));
}

}  // namespace
}  // namespace augrig
