// The look comparison's measurements against images whose answer is known: differences set by
// hand; Gaussian noise of a known sigma (fixed seeds) on flat and smoothly graded images of every
// format; edges rendered with a known erf profile (point-sampled, pixel-integrated, mosaicked) at
// many angles and round a disc, whose 10-90 % width follows from the profile; patch sets drawn
// from one distribution (AUC near 0.5) and from two clearly different ones (AUC near 1).
#include "eval/look_compare.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <numbers>
#include <random>
#include <string>

#include <gtest/gtest.h>

namespace augrig::eval {
namespace {

// An image whose sample (x, y, channel) is value(x, y, c), rounded and clipped to 8 bits. Bayer
// and Mono8 have one channel: c is the Bayer site's colour (0 for Mono8).
Image make_image(int w, int h, PixelFormat f, const std::function<double(int, int, int)>& value) {
  Image img(w, h, f);
  const int bpp = bytes_per_pixel(f);
  for (int y = 0; y < h; ++y) {
    std::uint8_t* row = img.row(y);
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < bpp; ++c) {
        const int colour = is_bayer(f) ? bayer_channel(f, x, y) : (f == PixelFormat::kMono8 ? 0 : c);
        const double v = (f == PixelFormat::kRGBA8 && c == 3) ? 255.0 : value(x, y, colour);
        row[x * bpp + c] = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
      }
    }
  }
  return img;
}

Image make_mask(int w, int h, const std::function<bool(int, int)>& in) {
  return make_image(w, h, PixelFormat::kMono8, [&](int x, int y, int) { return in(x, y) ? 255.0 : 0.0; });
}

double phi(double z) {
  return 0.5 * std::erfc(-z / std::numbers::sqrt2);
}

// ---- region_difference ---------------------------------------------------------------------------

TEST(RegionDifference, MeanAndRmsOverTheMaskedColourSamples) {
  // a - b = (3, -1, 4) per channel inside the mask, 50 outside (must not count); alpha differs.
  const int w = 40, h = 30;
  const Image mask = make_mask(w, h, [](int x, int y) { return x >= 10 && x < 30 && y >= 5 && y < 25; });
  for (PixelFormat f : {PixelFormat::kRGB8, PixelFormat::kRGBA8}) {
    const Image a = make_image(w, h, f, [](int x, int, int c) { return 100 + c + x; });
    Image b = make_image(w, h, f, [&](int x, int y, int c) {
      const bool in = x >= 10 && x < 30 && y >= 5 && y < 25;
      const double d[3] = {3, -1, 4};
      return 100 + c + x - (in ? d[c] : 50.0);
    });
    if (f == PixelFormat::kRGBA8)
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) b.row(y)[x * 4 + 3] = 7;
    auto r = region_difference(a.view(), b.cview(), mask.view());
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->pixels, 400u);
    EXPECT_DOUBLE_EQ(r->mean_dn, 2.0);
    EXPECT_DOUBLE_EQ(r->rms_dn, std::sqrt(26.0 / 3));
  }
}

TEST(RegionDifference, OneSamplePerPixelForMonoAndBayer) {
  const int w = 32, h = 32;
  const Image mask = make_mask(w, h, [](int x, int) { return x < 16; });
  for (PixelFormat f : {PixelFormat::kMono8, PixelFormat::kBayerGB8}) {
    // a - b = 2 on even rows, -4 on odd rows of the left half.
    const Image a = make_image(w, h, f, [](int x, int y, int c) { return 80 + x + y + 10 * c; });
    const Image b =
        make_image(w, h, f, [](int x, int y, int c) { return 80 + x + y + 10 * c - (y % 2 ? -4 : 2); });
    auto r = region_difference(a.view(), b.cview(), mask.view());
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->pixels, 512u);
    EXPECT_DOUBLE_EQ(r->mean_dn, -1.0);
    EXPECT_DOUBLE_EQ(r->rms_dn, std::sqrt(10.0));
  }
}

TEST(RegionDifference, EmptyMaskIsNanAndMismatchesAreErrors) {
  const Image a(16, 8, PixelFormat::kRGB8), b(16, 8, PixelFormat::kRGB8);
  const Image none = make_mask(16, 8, [](int, int) { return false; });
  auto r = region_difference(a.view(), b.view(), none.view());
  ASSERT_TRUE(r);
  EXPECT_EQ(r->pixels, 0u);
  EXPECT_TRUE(std::isnan(r->mean_dn) && std::isnan(r->rms_dn));

  const Image other_size(16, 9, PixelFormat::kRGB8), other_format(16, 8, PixelFormat::kBayerRG8);
  const Image rgb_mask(16, 8, PixelFormat::kRGB8), small_mask(8, 8, PixelFormat::kMono8);
  for (const auto& e : {region_difference(a.view(), other_size.view(), none.view()),
                        region_difference(a.view(), other_format.view(), none.view()),
                        region_difference(a.view(), b.view(), rgb_mask.view()),
                        region_difference(a.view(), b.view(), small_mask.view())}) {
    ASSERT_FALSE(e);
    EXPECT_EQ(e.error().message.rfind("eval::region_difference(): ", 0), 0u) << e.error().message;
  }
}

// ---- robust_noise_sigma --------------------------------------------------------------------------

// A smooth image plus white Gaussian noise of `sigma`: flat, or a graded (and slightly curved) level,
// each colour with its own gain; rounded and clipped to 8 bits.
Image noisy_image(int w, int h, PixelFormat f, double sigma, bool graded, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  const double gain[3] = {0.9, 1.0, 0.75};
  return make_image(w, h, f, [&](int x, int y, int c) {
    const double level =
        graded ? 70 + 0.18 * x + 0.12 * y + 0.0004 * (x - w / 2.0) * (y - h / 2.0) + 15 * std::sin(x / 90.0)
               : 128;
    return gain[c] * level + noise(rng);
  });
}

TEST(RobustNoiseSigma, RecoversGaussianNoiseWithin3PercentInEveryFormat) {
  const int w = 512, h = 512;
  // The region: a disc; outside it much stronger noise, which must not count.
  const Image mask = make_mask(w, h, [&](int x, int y) { return std::hypot(x - 250.3, y - 260.8) < 240; });
  unsigned seed = 1;
  for (PixelFormat f : {PixelFormat::kMono8, PixelFormat::kRGB8, PixelFormat::kRGBA8, PixelFormat::kBayerRG8,
                        PixelFormat::kBayerGB8}) {
    for (double sigma : {2.0, 4.0, 8.0}) {
      for (bool graded : {false, true}) {
        Image img = noisy_image(w, h, f, sigma, graded, seed++);
        const Image wild = noisy_image(w, h, f, 40, true, seed++);
        for (int y = 0; y < h; ++y)
          for (std::size_t i = 0; i < static_cast<std::size_t>(w * bytes_per_pixel(f)); ++i)
            if (!mask.row(y)[i / bytes_per_pixel(f)]) img.row(y)[i] = wild.row(y)[i];
        auto s = robust_noise_sigma(img.cview(), mask.view());
        ASSERT_TRUE(s) << s.error().message;
        std::printf("%-8s sigma %.0f %-6s -> %.4f (%+.2f %%)\n", std::string(to_string(f)).c_str(), sigma,
                    graded ? "graded" : "flat", *s, 100 * (*s / sigma - 1));
        EXPECT_NEAR(*s / sigma, 1.0, 0.03)
            << to_string(f) << " sigma " << sigma << (graded ? " graded" : " flat");
      }
    }
  }
}

TEST(RobustNoiseSigma, EdgesMoveItLittleTextureInflatesIt) {
  const int w = 256, h = 256;
  const Image all = make_mask(w, h, [](int, int) { return true; });
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 3.0);
  // A slanted step of 60 DN through the region: its responses are a small minority.
  const Image edged = make_image(w, h, PixelFormat::kMono8, [&](int x, int y, int) {
    return (x * 0.8 + y * 0.6 < 180 ? 90.0 : 150.0) + noise(rng);
  });
  auto e = robust_noise_sigma(edged.view(), all.view());
  ASSERT_TRUE(e);
  EXPECT_NEAR(*e, 3.0, 0.1);
  // Fine texture (period ~5 px, 20 DN) is not cancelled by the operator and reads as noise: the
  // reason to use this on smooth regions, both images alike.
  const Image textured = make_image(w, h, PixelFormat::kMono8, [&](int x, int y, int) {
    return 128 + 20 * std::sin(2 * std::numbers::pi * (x + y) / 5.0) + noise(rng);
  });
  auto t = robust_noise_sigma(textured.view(), all.view());
  ASSERT_TRUE(t);
  std::printf("noise 3 DN: with a step edge %.3f, with fine texture %.3f\n", *e, *t);
  EXPECT_GT(*t, 2 * 3.0);
}

TEST(RobustNoiseSigma, NanBelow50ResponsesAndMaskMismatchIsAnError) {
  const Image img = noisy_image(64, 64, PixelFormat::kMono8, 4, false, 3);
  // A 9 x 9 square: 7 x 7 = 49 full neighbourhoods; 10 x 10: 64.
  const Image m9 = make_mask(64, 64, [](int x, int y) { return x >= 20 && x < 29 && y >= 20 && y < 29; });
  const Image m10 = make_mask(64, 64, [](int x, int y) { return x >= 20 && x < 30 && y >= 20 && y < 30; });
  auto s9 = robust_noise_sigma(img.view(), m9.view());
  auto s10 = robust_noise_sigma(img.view(), m10.view());
  ASSERT_TRUE(s9 && s10);
  EXPECT_TRUE(std::isnan(*s9));
  EXPECT_FALSE(std::isnan(*s10));
  const Image wrong(64, 63, PixelFormat::kMono8);
  auto e = robust_noise_sigma(img.view(), wrong.view());
  ASSERT_FALSE(e);
  EXPECT_EQ(e.error().message.rfind("eval::robust_noise_sigma(): ", 0), 0u) << e.error().message;
}

// ---- edge_width ----------------------------------------------------------------------------------

// The 10-90 % width of a rising profile p(u) (0 at -inf, 1 at +inf), by bisection.
double width_of(const std::function<double(double)>& p) {
  auto at = [&](double level) {
    double lo = -20, hi = 20;
    for (int i = 0; i < 100; ++i) (p(0.5 * (lo + hi)) < level ? lo : hi) = 0.5 * (lo + hi);
    return 0.5 * (lo + hi);
  };
  return at(0.9) - at(0.1);
}

constexpr double kLo = 60, kHi = 190;  // the edge's levels: inside, outside

// A straight edge through (cx, cy) with outward normal at `angle_deg`, its profile erf(d / s)
// point-sampled at pixel centres (supersample > 1: averaged over supersample^2 points of each
// pixel, a pixel-integrating sensor), and its mask (pixel centres inside).
struct EdgeScene {
  Image image, mask;
  double nx, ny;
};
EdgeScene straight_edge(PixelFormat f, double angle_deg, double s, int supersample = 1, bool rising = true) {
  const int w = 160, h = 160;
  const double cx = 80.37, cy = 79.81, a = angle_deg * std::numbers::pi / 180;
  const double nx = std::cos(a), ny = std::sin(a);
  const double gain[3] = {0.85, 1.0, 0.7};
  auto profile = [&](double d) { return rising ? phi(d / s) : 1 - phi(d / s); };
  EdgeScene e;
  e.nx = nx, e.ny = ny;
  e.image = make_image(w, h, f, [&](int x, int y, int c) {
    double v = 0;
    for (int j = 0; j < supersample; ++j)
      for (int i = 0; i < supersample; ++i) {
        const double ox = (i + 0.5) / supersample - 0.5, oy = (j + 0.5) / supersample - 0.5;
        v += profile((x + ox - cx) * nx + (y + oy - cy) * ny);
      }
    return gain[c] * (kLo + (kHi - kLo) * v / (supersample * supersample));
  });
  e.mask = make_mask(w, h, [&](int x, int y) { return (x - cx) * nx + (y - cy) * ny < 0; });
  return e;
}

TEST(EdgeWidth, ErfEdgeAtManyAnglesGives2_5631Sigma) {
  for (double s : {0.7, 1.0, 1.5}) {
    for (double angle : {8.0, 23.0, 37.0, 47.0, 61.0, 78.0, 113.0, 152.0, 200.0, 251.0, 305.0, 341.0}) {
      const EdgeScene e = straight_edge(PixelFormat::kMono8, angle, s, 1, angle < 180);
      auto r = edge_width(e.image.view(), e.mask.view());
      ASSERT_TRUE(r) << r.error().message;
      const double expected = 2.5631 * s;
      std::printf("s %.1f angle %5.1f: %3d profiles, width %.4f, expected %.4f (%+.3f px)\n", s, angle,
                  r->profiles, r->width_10_90_px, expected, r->width_10_90_px - expected);
      EXPECT_GT(r->profiles, 50);
      EXPECT_NEAR(r->width_10_90_px, expected, 0.1) << "s " << s << " angle " << angle;
    }
  }
}

TEST(EdgeWidth, PixelIntegrationRgbAndBayerAddWhatTheirSamplingDoes) {
  for (double s : {0.7, 1.0, 1.5}) {
    for (double angle : {17.0, 52.0, 131.0}) {
      // Pixel-integrated: the profile averaged over the pixel's footprint projected on the normal.
      const EdgeScene pi = straight_edge(PixelFormat::kMono8, angle, s, 8);
      const double expected_pi = width_of([&](double u) {
        double v = 0;
        for (int j = 0; j < 8; ++j)
          for (int i = 0; i < 8; ++i)
            v += phi((u + ((i + 0.5) / 8 - 0.5) * pi.nx + ((j + 0.5) / 8 - 0.5) * pi.ny) / s);
        return v / 64;
      });
      // RGB: the mean of the channels, the same profile.
      const EdgeScene rgb = straight_edge(PixelFormat::kRGB8, angle, s);
      // Bayer: the 2 x 2 average adds four samples +-1/2 px apart in x and y.
      const EdgeScene bayer = straight_edge(PixelFormat::kBayerGR8, angle, s);
      const double expected_bayer = width_of([&](double u) {
        double v = 0;
        for (double ox : {-0.5, 0.5})
          for (double oy : {-0.5, 0.5}) v += phi((u + ox * bayer.nx + oy * bayer.ny) / s);
        return v / 4;
      });
      const struct {
        const char* what;
        const EdgeScene& scene;
        double expected;
      } cases[] = {{"pixel-integrated", pi, expected_pi},
                   {"RGB8", rgb, 2.5631 * s},
                   {"BayerGR8", bayer, expected_bayer}};
      for (const auto& c : cases) {
        auto r = edge_width(c.scene.image.view(), c.scene.mask.view());
        ASSERT_TRUE(r) << r.error().message;
        std::printf("%-16s s %.1f angle %5.1f: %3d profiles, width %.4f, expected %.4f (%+.3f px)\n", c.what,
                    s, angle, r->profiles, r->width_10_90_px, c.expected, r->width_10_90_px - c.expected);
        EXPECT_GT(r->profiles, 50);
        EXPECT_NEAR(r->width_10_90_px, c.expected, 0.1) << c.what << " s " << s << " angle " << angle;
      }
    }
  }
}

TEST(EdgeWidth, DiscAndRotatedSquare) {
  const int w = 160, h = 160;
  for (double s : {0.7, 1.0, 1.5}) {
    // A disc of radius 45, bright outside: profiles along the radii.
    const double cx = 80.4, cy = 79.3, radius = 45;
    const Image disc = make_image(w, h, PixelFormat::kMono8, [&](int x, int y, int) {
      return kLo + (kHi - kLo) * phi((std::hypot(x - cx, y - cy) - radius) / s);
    });
    const Image disc_mask =
        make_mask(w, h, [&](int x, int y) { return std::hypot(x - cx, y - cy) < radius; });
    auto d = edge_width(disc.view(), disc_mask.view());
    ASSERT_TRUE(d) << d.error().message;
    // A square rotated by 30 degrees, dark outside: its corners must be left out.
    const double c30 = std::cos(std::numbers::pi / 6), s30 = std::sin(std::numbers::pi / 6);
    auto box_distance = [&](int x,
                            int y) {  // signed distance to the square's outline (2-D erf: near corners only)
      const double u = (x - cx) * c30 + (y - cy) * s30, v = -(x - cx) * s30 + (y - cy) * c30;
      return std::max(std::abs(u), std::abs(v)) - 50;
    };
    const Image square = make_image(w, h, PixelFormat::kMono8, [&](int x, int y, int) {
      return kHi - (kHi - kLo) * phi(box_distance(x, y) / s);
    });
    const Image square_mask = make_mask(w, h, [&](int x, int y) { return box_distance(x, y) < 0; });
    auto q = edge_width(square.view(), square_mask.view());
    ASSERT_TRUE(q) << q.error().message;
    std::printf("s %.1f: disc %d profiles, width %.4f; square %d profiles, width %.4f; expected %.4f\n", s,
                d->profiles, d->width_10_90_px, q->profiles, q->width_10_90_px, 2.5631 * s);
    EXPECT_GT(d->profiles, 100);
    EXPECT_NEAR(d->width_10_90_px, 2.5631 * s, 0.1) << "disc, s " << s;
    EXPECT_GT(q->profiles, 100);
    EXPECT_NEAR(q->width_10_90_px, 2.5631 * s, 0.1) << "square, s " << s;
  }
}

TEST(EdgeWidth, NoiseAveragesOutLowContrastIsSkipped) {
  const EdgeScene clean = straight_edge(PixelFormat::kMono8, 33, 1.0);
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 3.0);
  Image noisy = Image::copy_of(clean.image.view());
  for (int y = 0; y < noisy.height(); ++y)
    for (int x = 0; x < noisy.width(); ++x)
      noisy.row(y)[x] =
          static_cast<std::uint8_t>(std::clamp(std::lround(noisy.row(y)[x] + noise(rng)), 0L, 255L));
  auto a = edge_width(clean.image.view(), clean.mask.view());
  auto b = edge_width(noisy.cview(), clean.mask.view());
  ASSERT_TRUE(a && b);
  std::printf("s 1.0, contrast 130: clean %.4f, noise 3 DN %.4f (%d profiles)\n", a->width_10_90_px,
              b->width_10_90_px, b->profiles);
  EXPECT_NEAR(b->width_10_90_px, a->width_10_90_px, 0.05);
  // Low contrast (30 DN, 10 noise sigmas): one 140 px edge scatters by about 0.1 px (seeds), printed.
  const Image faint = make_image(noisy.width(), noisy.height(), PixelFormat::kMono8, [&](int x, int y, int) {
    return 100 + 30 * phi(((x - 80.37) * clean.nx + (y - 79.81) * clean.ny) / 1.0) + noise(rng);
  });
  auto f = edge_width(faint.view(), clean.mask.view());
  ASSERT_TRUE(f);
  std::printf("s 1.0, contrast 30, noise 3 DN: %.4f (%d profiles)\n", f->width_10_90_px, f->profiles);
  EXPECT_NEAR(f->width_10_90_px, a->width_10_90_px, 0.3);
  // Contrast 130 DN: required 200 skips every profile.
  auto none = edge_width(clean.image.view(), clean.mask.view(), 200);
  ASSERT_TRUE(none);
  EXPECT_EQ(none->profiles, 0);
  EXPECT_TRUE(std::isnan(none->width_10_90_px));
  const Image wrong(10, 10, PixelFormat::kMono8);
  auto e = edge_width(clean.image.view(), wrong.view());
  ASSERT_FALSE(e);
  EXPECT_EQ(e.error().message.rfind("eval::edge_width(): ", 0), 0u) << e.error().message;
}

TEST(EdgeWidth, RowColumnAndDiagonalEdgesAreTheLimit) {
  // Along a column the mask cannot place the edge inside the pixel, and the pixels' distances from
  // it fall 1 px apart at one phase (on the diagonal 0.71 px apart): the average profile is sampled
  // coarsely and its crossings are interpolated linearly. Printed for the record, held loosely.
  const int w = 120, h = 120;
  const double s = 1.0;
  for (double phase : {0.0, 0.25, 0.5}) {
    const double edge = 60 + phase;
    const Image img = make_image(w, h, PixelFormat::kMono8,
                                 [&](int x, int, int) { return kLo + (kHi - kLo) * phi((x - edge) / s); });
    const Image mask = make_mask(w, h, [&](int x, int) { return x < edge; });
    auto r = edge_width(img.view(), mask.view());
    ASSERT_TRUE(r) << r.error().message;
    std::printf("column edge at pixel phase %.2f: %d profiles, width %.4f, expected %.4f\n", phase,
                r->profiles, r->width_10_90_px, 2.5631 * s);
    EXPECT_NEAR(r->width_10_90_px, 2.5631 * s, 0.4);
  }
  // The diagonal, and edges 1 degree off a column and off the diagonal: the mask places such edges
  // only over long stretches (its staircase steps rarely), and the error follows each profile's
  // sub-pixel phase. 3 degrees or more off these directions the width is good to about 0.05 px.
  for (double angle : {45.0, 1.0, 44.0}) {
    for (double sigma : {0.7, 1.0, 1.5}) {
      const EdgeScene e = straight_edge(PixelFormat::kMono8, angle, sigma);
      auto r = edge_width(e.image.view(), e.mask.view());
      ASSERT_TRUE(r) << r.error().message;
      std::printf("edge at %4.1f degrees, s %.1f: %d profiles, width %.4f, expected %.4f\n", angle, sigma,
                  r->profiles, r->width_10_90_px, 2.5631 * sigma);
      EXPECT_NEAR(r->width_10_90_px, 2.5631 * sigma, 0.3);
    }
  }
}

// ---- patches and classifiers ---------------------------------------------------------------------

TEST(PatchFeatures, ValuesOfFlatAndNoisyPatches) {
  const Image flat = make_image(40, 40, PixelFormat::kRGB8, [](int, int, int c) { return 100 + 10 * c; });
  const std::vector<float> f = patch_features(flat.view(), 4, 4, 32);
  ASSERT_EQ(f.size(), static_cast<std::size_t>(kPatchFeatureCount));
  EXPECT_FLOAT_EQ(f[0], 110);
  for (int i = 1; i < kPatchFeatureCount; ++i) EXPECT_FLOAT_EQ(f[static_cast<std::size_t>(i)], 0) << i;

  for (PixelFormat fmt : {PixelFormat::kMono8, PixelFormat::kBayerBG8}) {
    const Image noisy = noisy_image(64, 64, fmt, 5, false, 21);
    const std::vector<float> g = patch_features(noisy.view(), 0, 0, 64);
    ASSERT_EQ(g.size(), static_cast<std::size_t>(kPatchFeatureCount));
    EXPECT_NEAR(g[8], 5.0, 0.5) << to_string(fmt);  // the raw samples' noise
    EXPECT_NEAR(g[4] + g[5] + g[6] + g[7], 1.0, 1e-4);
    if (fmt == PixelFormat::kMono8) {
      EXPECT_NEAR(g[1], 25, 3);  // variance
      // White noise: the bands hold their share of the coefficients, most at high frequency.
      EXPECT_GT(g[7], g[6]);
      EXPECT_GT(g[6], g[4]);
    }
  }
  EXPECT_TRUE(patch_features(flat.view(), 10, 10, 32).empty());  // leaves the image
  EXPECT_TRUE(patch_features(flat.view(), 0, 0, 6).empty());     // too small
}

TEST(Auc, PerfectReversedIdenticalTiesEmpty) {
  EXPECT_DOUBLE_EQ(auc({1, 2, 3}, {4, 5}), 1.0);
  EXPECT_DOUBLE_EQ(auc({4, 5}, {1, 2, 3}), 0.0);
  EXPECT_DOUBLE_EQ(auc({1, 2, 3}, {1, 2, 3}), 0.5);
  EXPECT_DOUBLE_EQ(auc({7, 7, 7}, {7, 7}), 0.5);
  EXPECT_DOUBLE_EQ(auc({1, 2}, {2, 3}), 3.5 / 4);  // (1,2) (1,3) (2,3) won, (2,2) tied
  EXPECT_TRUE(std::isnan(auc({}, {1.0})));
}

// Features of n patches (16 x 16) of Gaussian noise around `mean`.
std::vector<std::vector<float>> noise_patches(int n, double mean, double sigma, unsigned seed) {
  const int size = 16, cols = 20;
  const int rows = (n + cols - 1) / cols;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(mean, sigma);
  const Image img =
      make_image(cols * size, rows * size, PixelFormat::kMono8, [&](int, int, int) { return noise(rng); });
  std::vector<std::vector<float>> out;
  for (int i = 0; i < n; ++i)
    out.push_back(patch_features(img.view(), (i % cols) * size, (i / cols) * size, size));
  return out;
}

TEST(ClassifyPatches, SameDistributionIsChanceDifferentNoiseIsSeparated) {
  const int n = 400;
  auto same = classify_patches(noise_patches(n, 100, 4, 1), noise_patches(n, 100, 4, 2),
                               noise_patches(n, 100, 4, 3), noise_patches(n, 100, 4, 4));
  ASSERT_TRUE(same) << same.error().message;
  auto noise = classify_patches(noise_patches(n, 100, 2, 5), noise_patches(n, 100, 4, 6),
                                noise_patches(n, 100, 2, 7), noise_patches(n, 100, 4, 8));
  ASSERT_TRUE(noise) << noise.error().message;
  auto level = classify_patches(noise_patches(n, 100, 4, 9), noise_patches(n, 101, 4, 10),
                                noise_patches(n, 100, 4, 11), noise_patches(n, 101, 4, 12));
  ASSERT_TRUE(level) << level.error().message;
  std::printf(
      "AUC (random trees, logistic): same %.3f %.3f; sigma 2 vs 4 %.3f %.3f; mean 100 vs 101 %.3f %.3f\n",
      same->auc_random_trees, same->auc_logistic, noise->auc_random_trees, noise->auc_logistic,
      level->auc_random_trees, level->auc_logistic);
  EXPECT_EQ(same->train, 2u * n);
  EXPECT_EQ(same->test, 2u * n);
  EXPECT_NEAR(same->auc_random_trees, 0.5, 0.08);
  EXPECT_NEAR(same->auc_logistic, 0.5, 0.08);
  EXPECT_GT(noise->auc_random_trees, 0.95);
  EXPECT_GT(noise->auc_logistic, 0.95);
  // Far apart (the logistic regression's weights grow without bound on separable sets).
  auto far = classify_patches(noise_patches(n, 60, 1, 13), noise_patches(n, 200, 9, 14),
                              noise_patches(n, 60, 1, 15), noise_patches(n, 200, 9, 16));
  ASSERT_TRUE(far) << far.error().message;
  EXPECT_EQ(far->auc_random_trees, 1.0);
  EXPECT_EQ(far->auc_logistic, 1.0);
}

TEST(ClassifyPatches, DeterministicAndChecksItsInputs) {
  const auto a = noise_patches(100, 100, 3, 31), b = noise_patches(100, 100, 3.5, 32);
  auto r1 = classify_patches(a, b, b, a);
  auto r2 = classify_patches(a, b, b, a);
  ASSERT_TRUE(r1 && r2);
  EXPECT_EQ(r1->auc_random_trees, r2->auc_random_trees);
  EXPECT_EQ(r1->auc_logistic, r2->auc_logistic);
  // Test sets swapped: a classifier that learned anything scores below 0.5 there.
  EXPECT_LT(r1->auc_logistic, 0.5);

  auto empty = classify_patches(a, {}, a, b);
  ASSERT_FALSE(empty);
  EXPECT_EQ(empty.error().message.rfind("eval::classify_patches(): ", 0), 0u) << empty.error().message;
  auto ragged = a;
  ragged[3].pop_back();
  EXPECT_FALSE(classify_patches(ragged, b, a, b));
  auto nan = a;
  nan[0][0] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(classify_patches(nan, b, a, b));
}

}  // namespace
}  // namespace augrig::eval
