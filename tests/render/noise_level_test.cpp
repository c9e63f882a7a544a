// Tests of render/noise_level: images synthesised with KNOWN Poisson-Gaussian noise
// (sigma^2 = a I + b, drawn with std::mt19937 through a normal approximation, then rounded to
// 8 bits) and the NLF the estimator recovers from them. Truth is the noise before rounding, as
// the NLF reports it. Every image is deterministic (fixed seeds).
#include "render/noise_level.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace augrig {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct Truth {
  double a = 0, b = 0;
  double variance(double level) const { return a * level + b; }
};
using Truths = std::array<Truth, 3>;

// Expected level of pixel (x, y) in NLF channel `ch`.
using Signal = std::function<double(int x, int y, int ch)>;

// An image of `signal` plus noise of `truth` per NLF channel, rounded and clamped to 8 bits.
// RGBA's alpha gets random bytes: the estimator must ignore it.
Image synthesise(int w, int h, PixelFormat f, const Signal& signal, const Truths& truth, unsigned seed) {
  Image img(w, h, f);
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_int_distribution<int> byte(0, 255);
  const int bpp = bytes_per_pixel(f);
  for (int y = 0; y < h; ++y) {
    std::uint8_t* row = img.row(y);
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < bpp; ++c) {
        const int ch = noise_channel(f, x, y, c);
        if (ch < 0) {
          row[x * bpp + c] = static_cast<std::uint8_t>(byte(rng));
          continue;
        }
        const double level = signal(x, y, ch);
        const double sigma = std::sqrt(std::max(truth[static_cast<std::size_t>(ch)].variance(level), 0.0));
        const double v = std::round(level + sigma * normal(rng));
        row[x * bpp + c] = static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0));
      }
    }
  }
  return img;
}

// A smooth scene spanning 20..235 DN: a diagonal ramp with a gentle wave, shifted per channel so
// the channels differ.
Signal smooth_ramp(int w, int h) {
  return [w, h](int x, int y, int ch) {
    const double u = (x + 0.5 * y) / (w - 1 + 0.5 * (h - 1));
    const double level = 20 + 215 * u + 6 * std::sin(2 * kPi * y / 150.0 + ch);
    return std::clamp(level, 20.0, 235.0);
  };
}

// Records one case's recovered sigma at 50, 128 and 200 DN against the truth, within `tol`.
void expect_sigma(const std::string& what, const NoiseFitReport& r, int ch, const Truth& t,
                  double tol = 0.10) {
  const NoiseLevelFunction& n = r.nlf;
  std::printf("  %-26s ch %d: a %.4f b %.3f (true %.3f %.3f)  sigma", what.c_str(), ch, n.a[ch], n.b[ch], t.a,
              t.b);
  for (double level : {50.0, 128.0, 200.0}) {
    const double got = std::sqrt(n.variance(ch, level)), want = std::sqrt(t.variance(level));
    std::printf("  @%3.0f %.3f/%.3f (%+.1f%%)", level, got, want, 100 * (got / want - 1));
    EXPECT_NEAR(got, want, tol * want) << what << " channel " << ch << " at " << level << " DN";
  }
  std::printf("  [bins %d, blocks %llu, ratio %.2f]\n", r.bins_used[ch],
              static_cast<unsigned long long>(r.blocks_used[ch]), r.band_ratio[ch]);
}

const Truths kCases[] = {{{{0, 4}}}, {{{0.1, 1}}}, {{{0.5, 2}}}, {{{0.02, 16}}}};

// ---------------------------------------------------------------------------------------------
// Smooth images: ramps spanning levels populate many bins.

TEST(NoiseLevel, RecoversMonoNoiseOnSmoothRamps) {
  const int w = 640, h = 480;
  unsigned seed = 1;
  for (const Truths& t : kCases) {
    const Image img = synthesise(w, h, PixelFormat::kMono8, smooth_ramp(w, h), t, seed++);
    const Expected<NoiseFitReport> r = estimate_noise_level(img);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->nlf.channels, 1);
    EXPECT_TRUE(r->note.empty()) << r->note;
    EXPECT_GE(r->bins_used[0], 8);
    expect_sigma("mono ramp", *r, 0, t[0]);
  }
}

// Block sides other than the default 8 (the generic, not the unrolled, path).
TEST(NoiseLevel, OtherBlockSizes) {
  const int w = 640, h = 480;
  const Truths t{{{0.1, 1}}};
  const Image img = synthesise(w, h, PixelFormat::kMono8, smooth_ramp(w, h), t, 3);
  for (int block : {6, 12, 16}) {
    NoiseEstimateOptions o;
    o.block_px = block;
    const Expected<NoiseFitReport> r = estimate_noise_level(img, o);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->blocks_seen, static_cast<std::uint64_t>((w / block) * (h / block)));
    expect_sigma("block_px " + std::to_string(block), *r, 0, t[0]);
  }
  // The Bayer green quincunx's block model (its checkerboard taken out) at those sides too.
  const Truths tb{{{0.1, 1}, {0.1, 1}, {0.1, 1}}};
  const Image bayer = synthesise(w, h, PixelFormat::kBayerRG8, smooth_ramp(w, h), tb, 4);
  for (int block : {6, 12, 16}) {
    NoiseEstimateOptions o;
    o.block_px = block;
    const Expected<NoiseFitReport> r = estimate_noise_level(bayer, o);
    ASSERT_TRUE(r) << r.error().message;
    expect_sigma("Bayer G, block_px " + std::to_string(block), *r, 1, tb[1]);
  }
}

// Large white Gaussian noise, no rounding to speak of: the medians' correction to means (a
// three-cumulant shifted chi^2 for v) must leave no bias beyond the sampling error (~0.5 %).
TEST(NoiseLevel, MedianCorrectionIsUnbiased) {
  const int w = 1024, h = 768;
  const Truths t{{{0, 100}}};
  const Signal flat = [](int x, int, int) { return 100.0 + 60.0 * x / 1023.0; };
  const Expected<NoiseFitReport> r = estimate_noise_level(synthesise(w, h, PixelFormat::kMono8, flat, t, 77));
  ASSERT_TRUE(r) << r.error().message;
  expect_sigma("white sigma 10", *r, 0, t[0], 0.02);
  const double var = r->nlf.variance(0, 130);
  std::printf("  variance at 130 DN: %.2f (true 100, %+.2f%%)\n", var, var - 100);
  EXPECT_NEAR(var, 100.0, 3.0);
  // The green quincunx's own model (Q = M less the checkerboard's direction), on twice the
  // frame's area for as many G blocks.
  const Truths tb{{{0, 100}, {0, 100}, {0, 100}}};
  const Expected<NoiseFitReport> g =
      estimate_noise_level(synthesise(2 * w, h, PixelFormat::kBayerRG8, flat, tb, 78));
  ASSERT_TRUE(g) << g.error().message;
  const double var_g = g->nlf.variance(1, 130);
  std::printf("  Bayer G variance at 130 DN: %.2f (true 100, %+.2f%%)\n", var_g, var_g - 100);
  EXPECT_NEAR(var_g, 100.0, 3.0);
}

// ---------------------------------------------------------------------------------------------
// Textured images: flat bands between bands of strong texture whose levels fall in the same bins.

// Texture kinds, each around a level `m` that follows y like the flat bands.
double checkerboard(int x, int y, double m) {
  return ((x / 12 + y / 12) % 2 ? m + 45 : m - 45);
}

double sinusoids(int x, int y, double m) {
  // Several frequencies and orientations, down to a 3 px period, like natural texture.
  return m + 20 * std::sin(0.21 * x + 0.13 * y) + 14 * std::sin(0.63 * x - 0.41 * y + 1) +
         9 * std::sin(1.3 * x + 0.9 * y + 2) + 6 * std::sin(2.1 * x - 1.7 * y + 3) +
         12 * std::sin(0.05 * x * 0.05 * y);
}

// Random straight edges: the sign of a sum of random half-plane steps.
struct RandomEdges {
  std::vector<std::array<double, 4>> lines;  // nx, ny, offset, contrast
  explicit RandomEdges(unsigned seed, int n, int w, int h) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> angle(0, 2 * kPi), pos(0, 1), contrast(15, 40);
    for (int i = 0; i < n; ++i) {
      const double a = angle(rng);
      const double px = pos(rng) * w, py = pos(rng) * h;
      lines.push_back({std::cos(a), std::sin(a), std::cos(a) * px + std::sin(a) * py, contrast(rng)});
    }
  }
  double operator()(int x, int y, double m) const {
    double v = m;
    for (const auto& l : lines) v += (l[0] * x + l[1] * y > l[2] ? 0.5 : -0.5) * l[3];
    return v;
  }
};

// Bands 48 px wide, cycling through flat, checkerboard, sinusoids, flat, random edges; with
// `flat_bands` 1 the second flat band is textured too (checkerboard), leaving 20 % flat.
Signal textured_scene(int w, int h, int flat_bands = 2) {
  auto edges = std::make_shared<RandomEdges>(99u, 40, w, h);
  return [w, h, edges, flat_bands](int x, int y, int) {
    const double m = 35 + 180.0 * (x * 0.3 + y) / (0.3 * (w - 1) + h - 1);
    double v = m;
    switch ((x / 48) % 5) {
      case 3:
        if (flat_bands == 1) v = checkerboard(x + 6, y + 6, m);
        break;
      case 1:
        v = checkerboard(x, y, m);
        break;
      case 2:
        v = sinusoids(x, y, m);
        break;
      case 4:
        v = (*edges)(x, y, m);
        break;
      default:
        break;
    }
    return std::clamp(v, 12.0, 243.0);
  };
}

TEST(NoiseLevel, TextureDoesNotBiasTheEstimate) {
  const int w = 720, h = 480;
  unsigned seed = 11;
  for (const Truths& t : kCases) {
    const Image img = synthesise(w, h, PixelFormat::kMono8, textured_scene(w, h, 2), t, seed++);
    const Expected<NoiseFitReport> r = estimate_noise_level(img);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_GT(r->blocks_rejected_texture, r->blocks_seen / 5) << "texture was kept";
    std::printf("  blocks seen %llu, texture rejected %llu, clipped %llu\n",
                static_cast<unsigned long long>(r->blocks_seen),
                static_cast<unsigned long long>(r->blocks_rejected_texture),
                static_cast<unsigned long long>(r->blocks_rejected_clipped));
    expect_sigma("mono textured", *r, 0, t[0]);
  }
}

// Fine periodic texture near the pixel scale over 3/4 of the image, 1.5 and 3 noise sigmas in
// amplitude: its blocks are rejected. (Texture of one sigma or less at periods under 3 px passes as
// noise: +18 % in sigma at 1 sigma and a 2.5 px period, +1 % at half a sigma.)
TEST(NoiseLevel, FineTextureAboveTheNoiseIsRejected) {
  const int w = 640, h = 480;
  const Truths t{{{0, 4}}};
  for (double amplitude : {3.0, 6.0}) {
    for (double period : {2.5, 3.0, 4.0, 6.0}) {
      const double k = 2 * kPi / period / std::sqrt(2.0);
      const Signal scene = [&](int x, int y, int) {
        const double m = 30 + 190.0 * y / (h - 1);
        return x < w * 3 / 4 ? m + amplitude * std::sin(k * (x + y)) : m;
      };
      const Expected<NoiseFitReport> r =
          estimate_noise_level(synthesise(w, h, PixelFormat::kMono8, scene, t, 5));
      ASSERT_TRUE(r) << r.error().message;
      EXPECT_GT(r->blocks_rejected_texture, r->blocks_seen * 2 / 3);
      char what[64];
      std::snprintf(what, sizeof what, "fine texture %.0f DN, %.1f px", amplitude, period);
      expect_sigma(what, *r, 0, t[0]);
    }
  }
}

// Texture outnumbers flat blocks 4 to 1 in every bin.
TEST(NoiseLevel, MostlyTexturedImages) {
  const int w = 960, h = 720;
  unsigned seed = 15;
  for (const Truths& t : kCases) {
    const Image img = synthesise(w, h, PixelFormat::kMono8, textured_scene(w, h, 1), t, seed++);
    const Expected<NoiseFitReport> r = estimate_noise_level(img);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_GT(r->blocks_rejected_texture, r->blocks_seen * 2 / 5) << "texture was kept";
    expect_sigma("mono 80 % textured", *r, 0, t[0]);
  }
}

// ---------------------------------------------------------------------------------------------
// Colour: per-channel NLFs.

TEST(NoiseLevel, RecoversPerChannelNoiseInRgbAndRgba) {
  const int w = 512, h = 384;
  const Truths t{{{0, 4}, {0.1, 1}, {0.5, 2}}};
  for (PixelFormat f : {PixelFormat::kRGB8, PixelFormat::kRGBA8}) {
    const Image img = synthesise(w, h, f, smooth_ramp(w, h), t, 21);
    const Expected<NoiseFitReport> r = estimate_noise_level(img);
    ASSERT_TRUE(r) << r.error().message;
    ASSERT_EQ(r->nlf.channels, 3);
    for (int c = 0; c < 3; ++c)
      expect_sigma(std::string(to_string(f)), *r, c, t[static_cast<std::size_t>(c)]);
  }
}

TEST(NoiseLevel, RecoversPerColourNoiseInEveryBayerPattern) {
  const int w = 640, h = 480;
  const Truths t{{{0.3, 3}, {0.1, 1}, {0.02, 16}}};
  unsigned seed = 31;
  for (PixelFormat f :
       {PixelFormat::kBayerRG8, PixelFormat::kBayerGR8, PixelFormat::kBayerGB8, PixelFormat::kBayerBG8}) {
    const Image img = synthesise(w, h, f, smooth_ramp(w, h), t, seed++);
    const Expected<NoiseFitReport> r = estimate_noise_level(img);
    ASSERT_TRUE(r) << r.error().message;
    ASSERT_EQ(r->nlf.channels, 3);
    for (int c = 0; c < 3; ++c)
      expect_sigma(std::string(to_string(f)), *r, c, t[static_cast<std::size_t>(c)]);
    // Both green sites feed G's quincunx: twice the blocks of R or B (less the diamonds that
    // cross the image's edge).
    EXPECT_NEAR(static_cast<double>(r->blocks_used[1]) / static_cast<double>(r->blocks_used[0]), 2.0, 0.4);
  }
}

// Reading a Bayer mosaic with the wrong pattern mixes the colours: the estimate must see it.
TEST(NoiseLevel, BayerSitesAreTheFormatsOwn) {
  const int w = 512, h = 384;
  const Truths t{{{0, 36}, {0, 1}, {0, 9}}};
  const Image rg = synthesise(w, h, PixelFormat::kBayerRG8, smooth_ramp(w, h), t, 41);
  const Expected<NoiseFitReport> right = estimate_noise_level(rg);
  ASSERT_TRUE(right) << right.error().message;
  for (int c = 0; c < 3; ++c) expect_sigma("BayerRG8 as RG", *right, c, t[static_cast<std::size_t>(c)]);
  const Image as_bg =
      Image::copy_of(ConstImageView{rg.data(), w, h, rg.stride_bytes(), PixelFormat::kBayerBG8});
  const Expected<NoiseFitReport> wrong = estimate_noise_level(as_bg);
  ASSERT_TRUE(wrong) << wrong.error().message;
  EXPECT_NEAR(wrong->nlf.variance(0, 128), 9.0, 1.5);  // R read at the B sites
  EXPECT_NEAR(wrong->nlf.variance(2, 128), 36.0, 5.0);
}

// Fine texture of one noise sigma over the dark half of a Bayer frame (the simulator's woods, seen
// at the demo flight's distance): four sinusoids at periods of 5 to 6.5 px across the diagonals.
// A site plane samples it every 2 px, where it lands in Immerkaer's pass band and reads as noise
// (R and B: sigma +8 to 9 % at 30 DN); G is measured on the quincunx of both green sites, 1.41 px
// apart, where the same texture mostly falls below the pass band. Truth: the a, b it was drawn with.
TEST(NoiseLevel, FineTextureOnTheGreenQuincunxIsNotNoise) {
  const int w = 1280, h = 960;
  const Truth camera{0.12, 2.25};  // the demo flight's simulated camera
  const Truths t{camera, camera, camera};
  constexpr double kAngle[4] = {0.35, 1.13, 1.92, 2.71}, kPeriod[4] = {5.0, 5.5, 6.0, 6.5};
  const Signal woods = [&](int x, int y, int) {
    const double m = 20 + 215.0 * y / (h - 1);
    if (y >= h / 2) return m;
    double tex = 0;  // variance 4 * 0.7^2 / 2 = 0.98 noise variances
    for (int k = 0; k < 4; ++k) {
      const double f = 2 * kPi / kPeriod[k];
      tex += 0.7 * std::sin(f * (x * std::cos(kAngle[k]) + y * std::sin(kAngle[k])) + k);
    }
    return m + tex * std::sqrt(camera.variance(m));
  };
  const Expected<NoiseFitReport> r =
      estimate_noise_level(synthesise(w, h, PixelFormat::kBayerRG8, woods, t, 57));
  ASSERT_TRUE(r) << r.error().message;
  const NoiseLevelFunction& n = r->nlf;
  for (int c : {0, 2})
    std::printf("  site plane %c: sigma at 30 DN %+.1f %% (fine texture read as noise)\n", c ? 'B' : 'R',
                100 * (std::sqrt(n.variance(c, 30) / camera.variance(30)) - 1));
  expect_sigma("G, textured dark half", *r, 1, camera, 0.03);
  const double got30 = std::sqrt(n.variance(1, 30)), want30 = std::sqrt(camera.variance(30));
  std::printf("  G sigma at 30 DN %.3f / %.3f (%+.1f %%)\n", got30, want30, 100 * (got30 / want30 - 1));
  EXPECT_NEAR(got30, want30, 0.03 * want30);
}

// Real sensors' two green sites differ in gain and offset: the quincunx takes the checkerboard
// this makes out of each block, so G reads the noise alone. Truth: the a, b drawn with.
TEST(NoiseLevel, GreenSiteImbalanceIsRemoved) {
  const int w = 640, h = 480;
  const Truths t{{{0.12, 2.25}, {0.12, 2.25}, {0.12, 2.25}}};
  for (PixelFormat f : {PixelFormat::kBayerRG8, PixelFormat::kBayerGB8}) {
    const Signal ramp = smooth_ramp(w, h);
    const Signal imbalanced = [&](int x, int y, int ch) {
      const bool second_green = ch == 1 && y % 2 == 1;  // the green sites of odd rows
      return second_green ? 1.04 * ramp(x, y, ch) + 1.5 : ramp(x, y, ch);
    };
    const Expected<NoiseFitReport> r = estimate_noise_level(synthesise(w, h, f, imbalanced, t, 61));
    ASSERT_TRUE(r) << r.error().message;
    expect_sigma(std::string(to_string(f)) + " G, sites 4 % apart", *r, 1, t[1], 0.03);
  }
}

// ---------------------------------------------------------------------------------------------
// Clipping.

TEST(NoiseLevel, ClippedBlocksAreRejected) {
  const int w = 640, h = 480;
  unsigned seed = 51;
  for (const Truths& t : kCases) {
    // Left half saturated (255 and above), a black square, the rest a ramp over 25..225.
    const Signal scene = [w, h](int x, int y, int) {
      if (x < w / 2) return 300.0;
      if (x > w - 120 && y < 120) return 0.0;
      return 25.0 + 200.0 * y / (h - 1);
    };
    const Image img = synthesise(w, h, PixelFormat::kMono8, scene, t, seed++);
    const Expected<NoiseFitReport> r = estimate_noise_level(img);
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_GT(r->blocks_rejected_clipped, r->blocks_seen / 2 + 150);
    expect_sigma("mono half clipped", *r, 0, t[0]);
  }
}

// ---------------------------------------------------------------------------------------------
// Fallbacks and errors.

TEST(NoiseLevel, OneLevelFallsBackToReadNoiseOnly) {
  const Truth t{0.1, 1};
  for (double level : {100.0, 128.0}) {  // 128: on a bin edge, blocks split over two bins
    const Signal flat = [level](int, int, int) { return level; };
    const Image img = synthesise(320, 240, PixelFormat::kMono8, flat, {t, t, t}, 61);
    const Expected<NoiseFitReport> r = estimate_noise_level(img);
    ASSERT_TRUE(r) << r.error().message;
    std::printf("  flat %.0f DN: a %.4f b %.3f (true variance %.3f); note: %s\n", level, r->nlf.a[0],
                r->nlf.b[0], t.variance(level), r->note.c_str());
    EXPECT_NE(r->note.find("channel Mono: too few levels"), std::string::npos) << r->note;
    EXPECT_EQ(r->nlf.a[0], 0.0);
    EXPECT_NEAR(r->nlf.b[0], t.variance(level), 0.05 * t.variance(level));
  }
}

TEST(NoiseLevel, NoiselessTextureIsAnErrorNamingFlatBlocks) {
  const int w = 320, h = 240;
  const RandomEdges edges(7u, 60, w, h);
  const Signal texture = [&edges](int x, int y, int) {
    // Compressed, not clamped, into 18..238: clamping would leave flat (noiseless) patches.
    return 128 +
           110 * std::tanh((edges(x, y, sinusoids(x, y, 128)) + 0.3 * checkerboard(x, y, 0) - 128) / 110);
  };
  const Image img = synthesise(w, h, PixelFormat::kMono8, texture, {}, 71);
  const Expected<NoiseFitReport> r = estimate_noise_level(img);
  ASSERT_FALSE(r) << "fitted a = " << r->nlf.a[0] << ", b = " << r->nlf.b[0];
  std::printf("  %s\n", r.error().message.c_str());
  EXPECT_EQ(r.error().message.rfind("NoiseLevelEstimator::fit(): channel Mono: no level has", 0), 0u);
  EXPECT_NE(r.error().message.find("flat, unclipped"), std::string::npos);
}

TEST(NoiseLevel, SaturatedImageIsAnErrorNamingClipping) {
  for (PixelFormat f : {PixelFormat::kMono8, PixelFormat::kBayerGB8}) {
    const Signal white = [](int, int, int) { return 280.0; };
    const Image img = synthesise(256, 192, f, white, {{{0.1, 4}, {0.1, 4}, {0.1, 4}}}, 81);
    const Expected<NoiseFitReport> r = estimate_noise_level(img);
    ASSERT_FALSE(r);
    std::printf("  %s\n", r.error().message.c_str());
    EXPECT_NE(r.error().message.find("blocks clipped"), std::string::npos);
  }
}

TEST(NoiseLevel, EstimatorErrors) {
  NoiseLevelEstimator e;
  Expected<NoiseFitReport> r = e.fit();
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().message, "NoiseLevelEstimator::fit(): no frames added");
  EXPECT_FALSE(e.add(Image()));
  ASSERT_TRUE(e.add(Image(64, 64, PixelFormat::kMono8)));
  const Status s = e.add(Image(64, 64, PixelFormat::kRGB8));
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message, "NoiseLevelEstimator::add(): a RGB8 frame after Mono8 frames (clear() first)");
  e.clear();
  EXPECT_TRUE(e.add(Image(64, 64, PixelFormat::kRGB8)));

  NoiseEstimateOptions bad;
  bad.block_px = 2;
  NoiseLevelEstimator eb(bad);
  const Status sb = eb.add(Image(64, 64, PixelFormat::kMono8));
  ASSERT_FALSE(sb);
  EXPECT_EQ(sb.error().message, "NoiseLevelEstimator::add(): block_px 2 is not in 6..64");

  // Frames smaller than one block of a Bayer plane (8 plane px = 16 image px).
  NoiseLevelEstimator es;
  ASSERT_TRUE(es.add(Image(12, 12, PixelFormat::kBayerRG8)));
  r = es.fit();
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().message.rfind("NoiseLevelEstimator::fit(): channel R: no blocks", 0), 0u)
      << r.error().message;
}

// ---------------------------------------------------------------------------------------------
// Accumulation over frames.

TEST(NoiseLevel, FramesAccumulateAndClearResets) {
  const int w = 64, h = 48;
  const Truths t{{{0.1, 1}}};
  NoiseLevelEstimator e;
  ASSERT_TRUE(e.add(synthesise(w, h, PixelFormat::kMono8, smooth_ramp(w, h), t, 100)));
  const Expected<NoiseFitReport> one = e.fit();
  EXPECT_FALSE(one) << "one frame of " << w * h / 64 << " blocks fitted";
  if (!one) std::printf("  one frame: %s\n", one.error().message.c_str());
  for (unsigned i = 1; i < 60; ++i)
    ASSERT_TRUE(e.add(synthesise(w, h, PixelFormat::kMono8, smooth_ramp(w, h), t, 100 + i)));
  EXPECT_EQ(e.frames(), 60u);
  const Expected<NoiseFitReport> many = e.fit();
  ASSERT_TRUE(many) << many.error().message;
  expect_sigma("60 frames of 64x48", *many, 0, t[0]);
  e.clear();
  EXPECT_EQ(e.frames(), 0u);
  const Expected<NoiseFitReport> none = e.fit();
  ASSERT_FALSE(none);
  EXPECT_EQ(none.error().message, "NoiseLevelEstimator::fit(): no frames added");
}

// Small reservoirs still fit, and block counts are scaled up to every block added.
TEST(NoiseLevel, ReservoirsBoundTheSamplesButCountEveryBlock) {
  const int w = 320, h = 240;
  const Truths t{{{0.5, 2}}};
  NoiseEstimateOptions o;
  o.max_blocks_per_bin = 64;
  NoiseLevelEstimator small(o), full;
  for (unsigned i = 0; i < 6; ++i) {
    const Image img = synthesise(w, h, PixelFormat::kMono8, smooth_ramp(w, h), t, 200 + i);
    ASSERT_TRUE(small.add(img));
    ASSERT_TRUE(full.add(img));
  }
  const Expected<NoiseFitReport> rs = small.fit(), rf = full.fit();
  ASSERT_TRUE(rs) << rs.error().message;
  ASSERT_TRUE(rf) << rf.error().message;
  expect_sigma("reservoir 64", *rs, 0, t[0], 0.15);
  expect_sigma("reservoir 4096", *rf, 0, t[0]);
  EXPECT_EQ(rs->blocks_seen, 6u * (w / 8) * (h / 8));
  EXPECT_NEAR(static_cast<double>(rs->blocks_used[0]), static_cast<double>(rf->blocks_used[0]),
              0.1 * static_cast<double>(rf->blocks_used[0]));
}

// ---------------------------------------------------------------------------------------------
// The NLF's small functions.

TEST(NoiseLevel, NoiseChannelPerFormat) {
  EXPECT_EQ(noise_channel(PixelFormat::kMono8, 5, 7, 0), 0);
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(noise_channel(PixelFormat::kRGB8, 3, 4, c), c);
    EXPECT_EQ(noise_channel(PixelFormat::kRGBA8, 3, 4, c), c);
  }
  EXPECT_EQ(noise_channel(PixelFormat::kRGBA8, 3, 4, 3), -1);  // alpha: no noise
  // Site colours of the top-left 2x2 cell in reading order, written out per pattern.
  const struct {
    PixelFormat f;
    int cell[4];
  } patterns[] = {{PixelFormat::kBayerRG8, {0, 1, 1, 2}},
                  {PixelFormat::kBayerGR8, {1, 0, 2, 1}},
                  {PixelFormat::kBayerGB8, {1, 2, 0, 1}},
                  {PixelFormat::kBayerBG8, {2, 1, 1, 0}}};
  for (const auto& p : patterns)
    for (int y = 0; y < 6; ++y)
      for (int x = 0; x < 6; ++x)
        EXPECT_EQ(noise_channel(p.f, x, y, 0), p.cell[(y % 2) * 2 + x % 2])
            << to_string(p.f) << " " << x << "," << y;
}

TEST(NoiseLevel, VarianceIsNeverNegative) {
  NoiseLevelFunction n;
  EXPECT_EQ(n.variance(0, 100), 0.0);  // empty
  n.channels = 3;
  n.a = {0.1, 0.0, 0.5};
  n.b = {1.0, -2.0, 0.0};
  EXPECT_DOUBLE_EQ(n.variance(0, 100), 11.0);
  EXPECT_EQ(n.variance(1, 100), 0.0);
  EXPECT_EQ(n.variance(2, -10), 0.0);
  EXPECT_EQ(n.variance(0, -50), 0.0);
  EXPECT_EQ(n.variance(-1, 100), 0.0);
  EXPECT_EQ(n.variance(3, 100), 0.0);
  n.channels = 1;
  EXPECT_EQ(n.variance(1, 100), 0.0);
  n.a[0] = std::nan("");
  EXPECT_EQ(n.variance(0, 100), 0.0);
  for (double level = -300; level <= 300; level += 0.5)
    for (int c = -1; c < 4; ++c) EXPECT_GE(n.variance(c, level), 0.0);
}

// ---------------------------------------------------------------------------------------------
// Cost on a 1280 x 960 frame (printed, not asserted).

TEST(NoiseLevel, TimingOnA1280x960Frame) {
  const int w = 1280, h = 960;
  const Truths t{{{0.1, 1}, {0.2, 2}, {0.3, 3}}};
  for (PixelFormat f : {PixelFormat::kMono8, PixelFormat::kBayerRG8, PixelFormat::kRGB8}) {
    const Image img = synthesise(w, h, f, smooth_ramp(w, h), t, 300);
    NoiseLevelEstimator e;
    using Clock = std::chrono::steady_clock;
    double add_ms = 1e9;
    for (int i = 0; i < 5; ++i) {
      const auto t0 = Clock::now();
      ASSERT_TRUE(e.add(img));
      add_ms = std::min(add_ms, std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    }
    const auto t0 = Clock::now();
    const Expected<NoiseFitReport> r = e.fit();
    const double fit_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    ASSERT_TRUE(r) << r.error().message;
    std::printf("  %-9s 1280x960: add() %.2f ms (best of 5), fit() %.2f ms after 5 frames (%llu blocks)\n",
                std::string(to_string(f)).c_str(), add_ms, fit_ms,
                static_cast<unsigned long long>(r->blocks_seen));
  }
}

}  // namespace
}  // namespace augrig
