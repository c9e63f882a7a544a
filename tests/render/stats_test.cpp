// Tests of render/stats: every number is checked against an oracle written independently here
// (brute-force loops over the masks, hand-derived geometry, ray-rectangle intersection).
#include "render/stats.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/worker.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

CameraModel pinhole(int w, int h, double f = 1000.0) {
  CameraModel c;
  c.width_px = w;
  c.height_px = h;
  c.fx_px = c.fy_px = f;
  c.cx_px = (w - 1) / 2.0;  // pixel centres at integers: the image centre is (W-1)/2
  c.cy_px = (h - 1) / 2.0;
  c.distortion = DistortionModel::kNone;
  return c;
}

DepthImage depth_filled(int w, int h, float z) {
  DepthImage d;
  d.width = w;
  d.height = h;
  d.z_m.assign(static_cast<std::size_t>(w) * h, z);
  return d;
}

// Mono8 mask with `pad` garbage bytes at the end of every row (must never be counted).
Image padded_mask(int w, int h, int pad) {
  Image m(w, h, PixelFormat::kMono8, static_cast<std::size_t>(w + pad));
  for (int y = 0; y < h; ++y)
    for (int p = 0; p < pad; ++p) m.row(y)[w + p] = 0xFF;
  return m;
}

// ---------------------------------------------------------------------------------------------
// Random masks: counts against plain loops.

TEST(OcclusionStats, RandomMasksMatchBruteForceCounts) {
  const int sizes[][3] = {{1, 1, 0}, {7, 5, 3}, {64, 48, 0}, {333, 77, 5}, {640, 480, 16}};
  for (unsigned seed : {1u, 2u, 3u, 42u}) {
    for (const auto& sz : sizes) {
      const int w = sz[0], h = sz[1], pad = sz[2];
      std::mt19937 rng(seed * 7919u + static_cast<unsigned>(w));
      std::uniform_int_distribution<int> byte(0, 255);
      Image ml = padded_mask(w, h, pad), mr = padded_mask(w, h, pad);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          // Full random bytes: the upper bits must be ignored, only bits 0, 1 and 2 count.
          ml.row(y)[x] = static_cast<std::uint8_t>(byte(rng));
          mr.row(y)[x] = static_cast<std::uint8_t>(byte(rng));
        }
      // No receiver depth anywhere: no left receiver pixel can be seen by the right camera.
      const DepthImage dl = depth_filled(w, h, kInf), dr = depth_filled(w, h, kInf);
      std::vector<std::uint8_t> classes;
      const OcclusionStats s = compute_occlusion_stats(123, ml, mr, dl, dr, pinhole(w, h), pinhole(w, h),
                                                       Pose::identity(), {}, &classes);

      std::int64_t rl = 0, rr = 0, bl = 0, br = 0, both_boom = 0, any_boom = 0, ol = 0, orr = 0;
      std::int64_t lonly = 0, neither = 0, sl = 0, sr = 0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const int a = ml.row(y)[x], b = mr.row(y)[x];
          const bool a_boom = a % 2 == 1, a_recv = (a / 2) % 2 == 1;
          const bool b_boom = b % 2 == 1, b_recv = (b / 2) % 2 == 1;
          if (a_recv) ++rl;
          if (b_recv) ++rr;
          if (a_boom) ++bl;
          if (b_boom) ++br;
          if (a_boom && b_boom) ++both_boom;
          if (a_boom || b_boom) ++any_boom;
          if (a_boom && a_recv) ++ol;
          if (b_boom && b_recv) ++orr;
          if ((a / 4) % 2 == 1) ++sl;  // bit 2, whatever the others (a bit test, like the rest)
          if ((b / 4) % 2 == 1) ++sr;
          if (a_recv && !a_boom) ++lonly;
          if (a_recv && a_boom) ++neither;
          const auto c = static_cast<StereoClass>(classes[static_cast<std::size_t>(y) * w + x]);
          const StereoClass want = !a_recv  ? StereoClass::kNone
                                   : a_boom ? StereoClass::kNeither
                                            : StereoClass::kLeftOnly;
          EXPECT_EQ(c, want);
        }
      SCOPED_TRACE("seed " + std::to_string(seed) + " size " + std::to_string(w) + "x" + std::to_string(h));
      EXPECT_EQ(s.t_ns, 123);
      EXPECT_EQ(s.width, w);
      EXPECT_EQ(s.height, h);
      EXPECT_EQ(s.receiver_px_left, rl);
      EXPECT_EQ(s.receiver_px_right, rr);
      EXPECT_EQ(s.boom_px_left, bl);
      EXPECT_EQ(s.boom_px_right, br);
      EXPECT_EQ(s.boom_overlap_px, both_boom);
      EXPECT_EQ(s.occluded_px_left, ol);
      EXPECT_EQ(s.occluded_px_right, orr);
      EXPECT_EQ(s.shadow_px_left, sl);
      EXPECT_EQ(s.shadow_px_right, sr);
      EXPECT_EQ(s.stereo_both_px, 0);
      EXPECT_EQ(s.right_only_px, 0);
      EXPECT_EQ(s.left_only_px, lonly);
      EXPECT_EQ(s.neither_px, neither);
      // Percentages re-derived from the brute-force counts.
      const double area = static_cast<double>(w) * h;
      EXPECT_NEAR(s.receiver_pct_left, 100.0 * rl / area, 1e-9);
      EXPECT_NEAR(s.receiver_pct_right, 100.0 * rr / area, 1e-9);
      EXPECT_NEAR(s.boom_pct_left, 100.0 * bl / area, 1e-9);
      EXPECT_NEAR(s.boom_pct_right, 100.0 * br / area, 1e-9);
      EXPECT_NEAR(s.boom_overlap_pct_union, any_boom ? 100.0 * both_boom / any_boom : 0.0, 1e-9);
      EXPECT_NEAR(s.occluded_pct_left, rl ? 100.0 * ol / rl : 0.0, 1e-9);
      EXPECT_NEAR(s.occluded_pct_right, rr ? 100.0 * orr / rr : 0.0, 1e-9);
      EXPECT_NEAR(s.shadow_pct_left, rl ? 100.0 * sl / rl : 0.0, 1e-9);
      EXPECT_NEAR(s.shadow_pct_right, rr ? 100.0 * sr / rr : 0.0, 1e-9);
    }
  }
}

// The shadow bit as the augmenter sets it (on receiver pixels not covered by the boom), in masks
// built by hand: its counts against plain loops, at widths that take the 16-pixel SWAR steps alone
// (1280), steps and a scalar tail (37: 2 steps + 5), an 8-pixel word and a tail (13), more steps
// than the 255 a lane can count before it is summed, then a step, a word and a tail (4107 =
// 256 * 16 + 8 + 3), the tail alone (7) and one pixel; and every other count and the classes
// exactly those of the same masks without the bit.
TEST(OcclusionStats, ShadowBitCountedAndChangesNothingElse) {
  for (const int w : {1, 7, 13, 37, 1280, 4107}) {
    for (const bool classes_on : {true, false}) {
      const int h = 9, pad = 5;
      SCOPED_TRACE("width " + std::to_string(w) + (classes_on ? ", classes" : ", masks only"));
      Image ml = padded_mask(w, h, pad), mr = padded_mask(w, h, pad);
      Image ml0 = padded_mask(w, h, pad), mr0 = padded_mask(w, h, pad);  // the same without bit 2
      std::int64_t want_sl = 0, want_sr = 0, want_rl = 0, want_rr = 0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          // Receiver on most of the image; the boom a diagonal band; its shadow another band on
          // the receiver, the whole of row 0 (every lane of every word), none in row 8.
          const bool recv_l = (x + y) % 5 != 0, recv_r = (x + 2 * y) % 7 != 1;
          const bool boom_l = (x - y + 64) % 9 < 2, boom_r = (x - y + 66) % 9 < 2;
          const bool shade_l = y == 0 || (y < 8 && (x + 3 * y) % 4 != 0);
          const bool shade_r = y == 0 || (y < 8 && (2 * x + y) % 3 == 0);
          std::uint8_t l = static_cast<std::uint8_t>((recv_l ? kMaskReceiver : 0) | (boom_l ? kMaskBoom : 0));
          std::uint8_t r = static_cast<std::uint8_t>((recv_r ? kMaskReceiver : 0) | (boom_r ? kMaskBoom : 0));
          ml0.row(y)[x] = l;
          mr0.row(y)[x] = r;
          if (l == kMaskReceiver && shade_l) l |= kMaskShadow, ++want_sl;
          if (r == kMaskReceiver && shade_r) r |= kMaskShadow, ++want_sr;
          want_rl += recv_l;
          want_rr += recv_r;
          ml.row(y)[x] = l;
          mr.row(y)[x] = r;
        }
      const DepthImage d = depth_filled(w, h, 20.f);
      const Pose T_right_left = Pose::from(Eigen::Matrix3d::Identity(), Eigen::Vector3d(-0.3, 0, 0));
      StereoClassOptions o;
      o.compute_classes = classes_on;
      std::vector<std::uint8_t> classes, classes0;
      const OcclusionStats s =
          compute_occlusion_stats(5, ml, mr, d, d, pinhole(w, h), pinhole(w, h), T_right_left, o, &classes);
      const OcclusionStats s0 = compute_occlusion_stats(5, ml0, mr0, d, d, pinhole(w, h), pinhole(w, h),
                                                        T_right_left, o, &classes0);
      EXPECT_GT(want_sl, 0);
      EXPECT_GT(want_sr, 0);
      EXPECT_EQ(s.receiver_px_left, want_rl);
      EXPECT_EQ(s.receiver_px_right, want_rr);
      EXPECT_EQ(s.shadow_px_left, want_sl);
      EXPECT_EQ(s.shadow_px_right, want_sr);
      EXPECT_DOUBLE_EQ(s.shadow_pct_left,
                       100.0 * static_cast<double>(want_sl) / static_cast<double>(want_rl));
      EXPECT_DOUBLE_EQ(s.shadow_pct_right,
                       100.0 * static_cast<double>(want_sr) / static_cast<double>(want_rr));
      EXPECT_EQ(s0.shadow_px_left, 0);
      EXPECT_EQ(s0.shadow_px_right, 0);
      EXPECT_EQ(s0.shadow_pct_left, 0.0);
      // Everything else is as without the bit.
      OcclusionStats without_shadow = s;
      without_shadow.shadow_px_left = without_shadow.shadow_px_right = 0;
      without_shadow.shadow_pct_left = without_shadow.shadow_pct_right = 0;
      EXPECT_EQ(without_shadow, s0);
      EXPECT_EQ(classes, classes0);
      if (classes_on) {
        EXPECT_EQ(s.stereo_both_px + s.left_only_px + s.right_only_px + s.neither_px, s.receiver_px_left);
        EXPECT_TRUE(w <= 15 || s.stereo_both_px > 0);  // the disparity is 15 px
      }
      // A content box around everything counts the same.
      StereoClassOptions boxed = o;
      boxed.content_x0 = 0, boxed.content_y0 = 0, boxed.content_x1 = w, boxed.content_y1 = h;
      EXPECT_EQ(compute_occlusion_stats(5, ml, mr, d, d, pinhole(w, h), pinhole(w, h), T_right_left, boxed),
                s);
    }
  }
}

// A content box (the augmenter's, outside which its masks are zero) changes nothing: random bits
// inside odd-aligned boxes of random masks, counted with and without the box.
TEST(OcclusionStats, ContentBoxGivesTheSameCountsAsTheWholeImage) {
  const int w = 203, h = 61;
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> byte(0, 255);
  for (const auto& box :
       {std::array<int, 4>{0, 0, w, h}, std::array<int, 4>{13, 5, 150, 40}, std::array<int, 4>{3, 0, 11, 61},
        std::array<int, 4>{190, 60, 203, 61}, std::array<int, 4>{50, 20, 50, 30}}) {
    Image ml = padded_mask(w, h, 3), mr = padded_mask(w, h, 3);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const bool in = x >= box[0] && x < box[2] && y >= box[1] && y < box[3];
        ml.row(y)[x] = in ? static_cast<std::uint8_t>(byte(rng)) : 0;
        mr.row(y)[x] = in ? static_cast<std::uint8_t>(byte(rng)) : 0;
      }
    const DepthImage dl = depth_filled(w, h, 20.f), dr = depth_filled(w, h, 20.f);
    std::vector<std::uint8_t> classes_all, classes_box;
    const OcclusionStats all = compute_occlusion_stats(1, ml, mr, dl, dr, pinhole(w, h), pinhole(w, h),
                                                       Pose::identity(), {}, &classes_all);
    StereoClassOptions opt;
    opt.content_x0 = box[0], opt.content_y0 = box[1], opt.content_x1 = box[2], opt.content_y1 = box[3];
    const OcclusionStats boxed = compute_occlusion_stats(1, ml, mr, dl, dr, pinhole(w, h), pinhole(w, h),
                                                         Pose::identity(), opt, &classes_box);
    SCOPED_TRACE("box " + std::to_string(box[0]) + "," + std::to_string(box[1]) + " - " +
                 std::to_string(box[2]) + "," + std::to_string(box[3]));
    EXPECT_EQ(boxed.receiver_px_left, all.receiver_px_left);
    EXPECT_EQ(boxed.receiver_px_right, all.receiver_px_right);
    EXPECT_EQ(boxed.boom_px_left, all.boom_px_left);
    EXPECT_EQ(boxed.boom_px_right, all.boom_px_right);
    EXPECT_EQ(boxed.boom_overlap_px, all.boom_overlap_px);
    EXPECT_EQ(boxed.occluded_px_left, all.occluded_px_left);
    EXPECT_EQ(boxed.occluded_px_right, all.occluded_px_right);
    EXPECT_EQ(boxed.shadow_px_left, all.shadow_px_left);
    EXPECT_EQ(boxed.shadow_px_right, all.shadow_px_right);
    EXPECT_EQ(boxed.stereo_both_px, all.stereo_both_px);
    EXPECT_EQ(boxed.left_only_px, all.left_only_px);
    EXPECT_EQ(boxed.right_only_px, all.right_only_px);
    EXPECT_EQ(boxed.neither_px, all.neither_px);
    EXPECT_EQ(classes_box, classes_all);
  }
}

// Half the classes' rows on a caller's persistent thread: the same counts and classes as on a
// thread of their own, frame after frame.
TEST(OcclusionStats, ClassesOnAWorkerEqualThoseWithout) {
  const int w = 203, h = 61;
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_real_distribution<float> depth(15.f, 25.f);
  Worker worker("augrig-test");
  for (int frame = 0; frame < 5; ++frame) {
    Image ml = padded_mask(w, h, 3), mr = padded_mask(w, h, 3);
    DepthImage dl = depth_filled(w, h, 20.f), dr = depth_filled(w, h, 20.f);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        ml.row(y)[x] = static_cast<std::uint8_t>(byte(rng) & 3);
        mr.row(y)[x] = static_cast<std::uint8_t>(byte(rng) & 3);
        dl.z_m[static_cast<std::size_t>(y) * w + x] = depth(rng);
        dr.z_m[static_cast<std::size_t>(y) * w + x] = depth(rng);
      }
    const Pose T_right_left = Pose::from(Eigen::Matrix3d::Identity(), Eigen::Vector3d(-0.3, 0, 0));
    std::vector<std::uint8_t> classes_thread, classes_worker;
    const OcclusionStats a = compute_occlusion_stats(1, ml, mr, dl, dr, pinhole(w, h), pinhole(w, h),
                                                     T_right_left, {}, &classes_thread);
    StereoClassOptions opt;
    opt.worker = &worker;
    const OcclusionStats b = compute_occlusion_stats(1, ml, mr, dl, dr, pinhole(w, h), pinhole(w, h),
                                                     T_right_left, opt, &classes_worker);
    EXPECT_GT(a.stereo_both_px + a.left_only_px + a.right_only_px + a.neither_px, 0);
    EXPECT_EQ(b.stereo_both_px, a.stereo_both_px);
    EXPECT_EQ(b.left_only_px, a.left_only_px);
    EXPECT_EQ(b.right_only_px, a.right_only_px);
    EXPECT_EQ(b.neither_px, a.neither_px);
    EXPECT_EQ(classes_worker, classes_thread);
  }
}

TEST(OcclusionStats, RandomDepthsClassesAlwaysPartitionLeftReceiver) {
  const int w = 97, h = 61;
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> bits(0, 3);
  std::uniform_real_distribution<float> z(5.0f, 30.0f);
  Image ml(w, h, PixelFormat::kMono8), mr(w, h, PixelFormat::kMono8);
  DepthImage dl = depth_filled(w, h, kInf), dr = depth_filled(w, h, kInf);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      ml.row(y)[x] = static_cast<std::uint8_t>(bits(rng));
      mr.row(y)[x] = static_cast<std::uint8_t>(bits(rng));
      dl.z_m[static_cast<std::size_t>(y) * w + x] = (ml.row(y)[x] & kMaskReceiver) ? z(rng) : kInf;
      dr.z_m[static_cast<std::size_t>(y) * w + x] = (mr.row(y)[x] & kMaskReceiver) ? z(rng) : kInf;
    }
  Pose T = Pose::from(rotation_from_ypr(0.01, -0.02, 0.005), Eigen::Vector3d(-0.3, 0.01, 0.02));
  std::vector<std::uint8_t> classes;
  const auto s =
      compute_occlusion_stats(0, ml, mr, dl, dr, pinhole(w, h, 80), pinhole(w, h, 80), T, {}, &classes);
  EXPECT_EQ(s.stereo_both_px + s.left_only_px + s.right_only_px + s.neither_px, s.receiver_px_left);
  std::int64_t counted[5] = {0, 0, 0, 0, 0};
  for (auto c : classes) ++counted[c];
  EXPECT_EQ(counted[1], s.stereo_both_px);
  EXPECT_EQ(counted[2], s.left_only_px);
  EXPECT_EQ(counted[3], s.right_only_px);
  EXPECT_EQ(counted[4], s.neither_px);
  EXPECT_EQ(counted[0], static_cast<std::int64_t>(w) * h - s.receiver_px_left);
}

TEST(OcclusionStats, EmptyMasksGiveZerosNotNaN) {
  Image ml(16, 8, PixelFormat::kMono8), mr(16, 8, PixelFormat::kMono8);
  const auto d = depth_filled(16, 8, kInf);
  const auto s = compute_occlusion_stats(0, ml, mr, d, d, pinhole(16, 8), pinhole(16, 8), Pose::identity());
  EXPECT_EQ(s.boom_overlap_pct_union, 0.0);
  EXPECT_EQ(s.occluded_pct_left, 0.0);
  EXPECT_EQ(s.occluded_pct_right, 0.0);
  EXPECT_EQ(s.receiver_pct_left, 0.0);
}

TEST(OcclusionStats, CountsOnlyWhenClassesAreOff) {
  Image ml(4, 2, PixelFormat::kMono8), mr(4, 2, PixelFormat::kMono8);
  ml.row(0)[0] = kMaskReceiver | kMaskBoom;
  ml.row(1)[3] = kMaskReceiver;
  mr.row(0)[0] = kMaskBoom;
  StereoClassOptions o;
  o.compute_classes = false;
  std::vector<std::uint8_t> classes(5, 9);
  // Empty depth images and default cameras are fine: nothing but the masks is read.
  const auto s = compute_occlusion_stats(0, ml, mr, {}, {}, {}, {}, {}, o, &classes);
  EXPECT_EQ(s.receiver_px_left, 2);
  EXPECT_EQ(s.occluded_px_left, 1);
  EXPECT_EQ(s.boom_overlap_px, 1);
  EXPECT_EQ(s.stereo_both_px + s.left_only_px + s.right_only_px + s.neither_px, 0);
  EXPECT_TRUE(classes.empty());
}

TEST(OcclusionStats, RejectsMismatchedInputs) {
  Image m(16, 8, PixelFormat::kMono8), other(15, 8, PixelFormat::kMono8), rgb(16, 8, PixelFormat::kRGB8);
  const auto d = depth_filled(16, 8, kInf), d_small = depth_filled(15, 8, kInf);
  const auto c = pinhole(16, 8);
  EXPECT_THROW(compute_occlusion_stats(0, m, other, d, d, c, c, {}), std::invalid_argument);
  EXPECT_THROW(compute_occlusion_stats(0, rgb, m, d, d, c, c, {}), std::invalid_argument);
  EXPECT_THROW(compute_occlusion_stats(0, m, m, d_small, d, c, c, {}), std::invalid_argument);
  EXPECT_THROW(compute_occlusion_stats(0, m, m, d, d, pinhole(15, 8), c, {}), std::invalid_argument);
  m.row(0)[0] = kMaskReceiver;
  std::vector<Eigen::Vector2f> wrong(3);
  StereoClassOptions o;
  o.left_rays_xy = &wrong;
  EXPECT_THROW(compute_occlusion_stats(0, m, m, d, d, c, c, {}, o), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// The seed paper's Table 1 as a regression of the arithmetic. Its "pixels" are channel values
// (3 per RGB pixel): 1164420 / (3 * 1280 * 960) = 31.59 %. Masks with those counts, as pixels,
// must give count / (W*H) here, and count / (3*W*H) reproduces the paper's whole-image column.
// The other percentages are ratios of counts, where the factor 3 cancels.

TEST(OcclusionStats, SeedPaperTable1Arithmetic) {
  const int W = 1280, H = 960, N = W * H;
  // Pixel index sets built from intervals [a, b), chosen so that every Table 1 count comes out:
  //   left receiver [0, 1164420); left boom [0, 2866) (on receiver) + [1164420, 1202524) (off).
  //   right receiver [63817, N); right boom [0, 39440) (off receiver) + [1199781, 1203051) (on).
  //   boom overlap = [0, 2866) + [1199781, 1202524) = 2866 + 2743 = 5609.
  auto in = [](int i, int a, int b) { return i >= a && i < b; };
  Image ml(W, H, PixelFormat::kMono8), mr(W, H, PixelFormat::kMono8);
  for (int i = 0; i < N; ++i) {
    std::uint8_t l = 0, r = 0;
    if (in(i, 0, 1164420)) l |= kMaskReceiver;
    if (in(i, 0, 2866) || in(i, 1164420, 1202524)) l |= kMaskBoom;
    if (in(i, 63817, N)) r |= kMaskReceiver;
    if (in(i, 0, 39440) || in(i, 1199781, 1203051)) r |= kMaskBoom;
    ml.row(i / W)[i % W] = l;
    mr.row(i / W)[i % W] = r;
  }
  const auto d = depth_filled(W, H, kInf);
  const auto c = pinhole(W, H);
  const auto s = compute_occlusion_stats(0, ml, mr, d, d, c, c, Pose::identity());
  EXPECT_EQ(s.receiver_px_left, 1164420);
  EXPECT_EQ(s.receiver_px_right, 1164983);
  EXPECT_EQ(s.boom_px_left, 40970);
  EXPECT_EQ(s.boom_px_right, 42710);
  EXPECT_EQ(s.boom_overlap_px, 5609);
  EXPECT_EQ(s.occluded_px_left, 2866);
  EXPECT_EQ(s.occluded_px_right, 3270);

  // Ours, of W*H pixels: e.g. 40970 / 1228800 = 3.334 %.
  EXPECT_NEAR(s.receiver_pct_left, 94.7607, 1e-4);
  EXPECT_NEAR(s.receiver_pct_right, 94.8066, 1e-4);
  EXPECT_NEAR(s.boom_pct_left, 3.3342, 1e-4);
  EXPECT_NEAR(s.boom_pct_right, 3.4758, 1e-4);
  // The paper's whole-image percentages are these divided by 3 (channel values over 3*W*H).
  auto paper_round = [](double p) { return std::round(p * 100.0) / 100.0; };
  EXPECT_DOUBLE_EQ(paper_round(s.receiver_pct_left / 3), 31.59);
  EXPECT_DOUBLE_EQ(paper_round(s.receiver_pct_right / 3), 31.60);
  EXPECT_DOUBLE_EQ(paper_round(s.boom_pct_left / 3), 1.11);
  EXPECT_DOUBLE_EQ(paper_round(s.boom_pct_right / 3), 1.16);
  // Ratios of counts: identical to the paper. 5609 / (40970 + 42710 - 5609) = 7.18 %.
  EXPECT_DOUBLE_EQ(paper_round(s.boom_overlap_pct_union), 7.18);
  EXPECT_DOUBLE_EQ(paper_round(s.occluded_pct_left), 0.25);
  EXPECT_DOUBLE_EQ(paper_round(s.occluded_pct_right), 0.28);

  const std::string table = format_table1(s, "Seed paper Table 1 counts");
  EXPECT_NE(table.find("1164420"), std::string::npos);
  EXPECT_NE(table.find("7.18%"), std::string::npos);
  EXPECT_NE(table.find("3.33%"), std::string::npos);
  EXPECT_NE(table.find("channel"), std::string::npos);  // says that ours are pixels, not channels
  EXPECT_NE(table.find("whole image (1228800 px)"), std::string::npos);
  EXPECT_NE(table.find("78071 px"), std::string::npos);  // the overlap's base: |L u R|
}

// ---------------------------------------------------------------------------------------------
// Stereo classes on analytic scenes. Everything is built here by ray casting against
// fronto-parallel rectangles given in the LEFT camera frame; the classes are then derived from
// continuous geometry (segment-rectangle tests), independently of the masks and of stats.cpp.

struct Rect {
  double z, x0, x1, y0, y1;  // plane z = const in the left camera frame, x in [x0,x1], y in [y0,y1]
  bool boom;
};

struct Rig {
  CameraModel cam;
  Pose T_left_right;  // right camera in the left frame
  Pose T_right_left() const { return T_left_right.inverse(); }
};

struct View {
  Image mask;
  DepthImage depth;
};

// Hit of the ray o + s*d (d.z of the camera ray in its own frame is 1, so s is the camera depth).
bool hit(const Rect& r, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& s) {
  if (std::abs(d.z()) < 1e-12) return false;
  s = (r.z - o.z()) / d.z();
  if (s <= 0) return false;
  const Eigen::Vector3d p = o + s * d;
  return p.x() >= r.x0 && p.x() <= r.x1 && p.y() >= r.y0 && p.y() <= r.y1;
}

// Direction (x, y, 1) of a pixel centre's ray: by hand for pinholes; through the lens model's
// ray() (tested with camera_model) when there is distortion.
Eigen::Vector3d pixel_dir(const CameraModel& c, int x, int y) {
  if (c.distortion == DistortionModel::kNone) return {(x - c.cx_px) / c.fx_px, (y - c.cy_px) / c.fy_px, 1.0};
  const auto r = c.ray(Eigen::Vector2d(x, y));
  return r ? Eigen::Vector3d(*r / r->z()) : Eigen::Vector3d(0, 0, 0);
}

View render_view(const std::vector<Rect>& scene, const CameraModel& c, const Pose& T_left_cam) {
  View v{Image(c.width_px, c.height_px, PixelFormat::kMono8), depth_filled(c.width_px, c.height_px, kInf)};
  const Eigen::Matrix3d R = T_left_cam.R();
  const Eigen::Vector3d o = T_left_cam.translation_m;
  for (int y = 0; y < c.height_px; ++y)
    for (int x = 0; x < c.width_px; ++x) {
      const Eigen::Vector3d d = R * pixel_dir(c, x, y);
      double recv = kInf, boom = kInf, s;
      for (const Rect& r : scene)
        if (hit(r, o, d, s)) (r.boom ? boom : recv) = std::min(r.boom ? boom : recv, s);
      std::uint8_t m = 0;
      if (recv < kInf) m |= kMaskReceiver;
      if (boom < recv) m |= kMaskBoom;
      v.mask.row(y)[x] = m;
      v.depth.z_m[static_cast<std::size_t>(y) * c.width_px + x] = static_cast<float>(recv);
    }
  return v;
}

// Class of every left pixel from geometry: the point on the front-most receiver rectangle, seen by
// the right camera when it projects inside the image and no rectangle cuts the segment to it.
std::vector<std::uint8_t> oracle_classes(const std::vector<Rect>& scene, const Rig& rig) {
  const CameraModel& c = rig.cam;
  std::vector<std::uint8_t> out(static_cast<std::size_t>(c.width_px) * c.height_px, 0);
  const Eigen::Vector3d c_right = rig.T_left_right.translation_m;
  const Pose T_rl = rig.T_right_left();
  for (int y = 0; y < c.height_px; ++y)
    for (int x = 0; x < c.width_px; ++x) {
      const Eigen::Vector3d d = pixel_dir(c, x, y);
      double recv = kInf, boom = kInf, s;
      for (const Rect& r : scene)
        if (hit(r, Eigen::Vector3d::Zero(), d, s)) (r.boom ? boom : recv) = std::min(r.boom ? boom : recv, s);
      if (recv == kInf) continue;
      const Eigen::Vector3d p = recv * d;
      const bool vis_left = !(boom < recv);
      bool vis_right = false;
      const Eigen::Vector3d pr = T_rl * p;
      double u = c.cx_px + c.fx_px * pr.x() / pr.z(), v = c.cy_px + c.fy_px * pr.y() / pr.z();
      if (c.distortion != DistortionModel::kNone) {
        const auto uv = c.project(pr);
        u = uv ? uv->x() : -1e9;
        v = uv ? uv->y() : -1e9;
      }
      if (pr.z() > 0 && u >= -0.5 && u < c.width_px - 0.5 && v >= -0.5 && v < c.height_px - 0.5) {
        vis_right = true;
        for (const Rect& r : scene) {
          const double t = (r.z - c_right.z()) / (p.z() - c_right.z());  // segment parameter
          if (t <= 0 || t >= 1 - 1e-9) continue;
          const Eigen::Vector3d q = c_right + t * (p - c_right);
          if (q.x() >= r.x0 && q.x() <= r.x1 && q.y() >= r.y0 && q.y() <= r.y1) vis_right = false;
        }
      }
      const StereoClass k = vis_left && vis_right ? StereoClass::kBoth
                            : vis_left            ? StereoClass::kLeftOnly
                            : vis_right           ? StereoClass::kRightOnly
                                                  : StereoClass::kNeither;
      out[static_cast<std::size_t>(y) * c.width_px + x] = static_cast<std::uint8_t>(k);
    }
  return out;
}

struct SceneResult {
  OcclusionStats stats;
  std::vector<std::uint8_t> classes, oracle;
  std::int64_t mismatches = 0;
};

SceneResult run_scene(const std::vector<Rect>& scene, const Rig& rig, const StereoClassOptions& o = {}) {
  const View l = render_view(scene, rig.cam, Pose::identity());
  const View r = render_view(scene, rig.cam, rig.T_left_right);
  SceneResult res;
  res.stats = compute_occlusion_stats(1, l.mask, r.mask, l.depth, r.depth, rig.cam, rig.cam,
                                      rig.T_right_left(), o, &res.classes);
  res.oracle = oracle_classes(scene, rig);
  for (std::size_t i = 0; i < res.classes.size(); ++i) res.mismatches += res.classes[i] != res.oracle[i];
  return res;
}

std::int64_t count_class(const std::vector<std::uint8_t>& v, StereoClass c) {
  return std::count(v.begin(), v.end(), static_cast<std::uint8_t>(c));
}

// 640x480, fx = fy = 1000, right camera 0.5 m to the right: disparity at z = 20 m is 25 px.
Rig rectified_rig() {
  return {pinhole(640, 480), Pose::from(Eigen::Matrix3d::Identity(), {0.5, 0, 0})};
}

// Receiver plane at 20 m, x in [-2, 2] (columns u - cx = 50 x: 200 columns), y in [-1.5, 1.5]
// (150 rows). Boom bar at 10 m, x in [0, 0.3], all rows.
//   Left:  the bar hides receiver x in [0, 0.6]            (u - cx in [0, 30]: 30 columns).
//   Right: the ray from (0.5, 0, 0) to (x, ., 20) meets the bar when x in [-0.5, 0.1]: 30 columns.
//   Hence neither: x in [0, 0.1] 5 columns; left only: [-0.5, 0) 25; right only: (0.1, 0.6] 25;
//   both: 200 - 55 = 145 columns; everything times 150 rows.
std::vector<Rect> basic_scene() {
  return {{20, -2, 2, -1.5, 1.5, false}, {10, 0, 0.3, -100, 100, true}};
}

TEST(StereoClasses, RectifiedPlaneWithBoomBar) {
  const auto res = run_scene(basic_scene(), rectified_rig());
  const auto& s = res.stats;
  EXPECT_EQ(s.receiver_px_left, 200 * 150);
  EXPECT_EQ(s.receiver_px_right, 200 * 150);
  EXPECT_EQ(s.boom_px_left, 30 * 480);
  EXPECT_EQ(s.boom_px_right, 30 * 480);
  EXPECT_EQ(s.boom_overlap_px, 0);  // bar columns 320..349 (left) vs 270..299 (right)
  EXPECT_EQ(s.occluded_px_left, 30 * 150);
  EXPECT_EQ(s.occluded_px_right, 30 * 150);
  EXPECT_EQ(s.stereo_both_px, 145 * 150);
  EXPECT_EQ(s.left_only_px, 25 * 150);
  EXPECT_EQ(s.right_only_px, 25 * 150);
  EXPECT_EQ(s.neither_px, 5 * 150);
  EXPECT_EQ(res.mismatches, 0);
  // Spot checks, columns from u = cx + 50 x (cx = 319.5) at the centre row 240.
  auto at = [&](int x) { return static_cast<StereoClass>(res.classes[240 * 640 + x]); };
  EXPECT_EQ(at(300), StereoClass::kLeftOnly);   // x = -0.39
  EXPECT_EQ(at(322), StereoClass::kNeither);    // x = 0.05
  EXPECT_EQ(at(340), StereoClass::kRightOnly);  // x = 0.41
  EXPECT_EQ(at(400), StereoClass::kBoth);       // x = 1.61
  EXPECT_EQ(at(100), StereoClass::kNone);       // off the receiver
}

// A nearer receiver part (z = 15 m, x in [1, 1.5], y in [-1, 1]) hides a strip of the far plane
// from the right camera only: far points with x in [1.1667, 1.8333] are behind it for the right
// camera, and the left camera still sees those with x in [1.1667, 1.3333) (u - cx in [58.3, 66.7):
// 9 columns) over |y| <= 1.3333 (134 rows): 1206 more left-only pixels than the basic scene.
TEST(StereoClasses, SelfOcclusionByNearerReceiverPart) {
  auto scene = basic_scene();
  scene.push_back({15, 1, 1.5, -1, 1, false});
  const auto res = run_scene(scene, rectified_rig());
  const auto& s = res.stats;
  EXPECT_EQ(res.mismatches, 0);
  EXPECT_EQ(s.left_only_px, 25 * 150 + 9 * 134);
  EXPECT_EQ(s.stereo_both_px, 145 * 150 - 9 * 134);
  EXPECT_EQ(s.right_only_px, 25 * 150);
  EXPECT_EQ(s.neither_px, 5 * 150);
  EXPECT_EQ(static_cast<StereoClass>(res.classes[240 * 640 + 382]), StereoClass::kLeftOnly);  // x = 1.25
  // With a tolerance larger than the 5 m step the occluder no longer counts as in front.
  StereoClassOptions loose;
  loose.depth_tolerance_m = 6.0;
  EXPECT_EQ(run_scene(scene, rectified_rig(), loose).stats.left_only_px, 25 * 150);
}

// Receiver at x in [-7, -5] (left columns 0..69); the right camera sees it 25 px further left, so
// left columns 0..24 fall outside the right image: 25 * 150 left-only, 45 * 150 both.
TEST(StereoClasses, OutOfRightImage) {
  const auto res = run_scene({{20, -7, -5, -1.5, 1.5, false}}, rectified_rig());
  EXPECT_EQ(res.mismatches, 0);
  EXPECT_EQ(res.stats.receiver_px_left, 70 * 150);
  EXPECT_EQ(res.stats.left_only_px, 25 * 150);
  EXPECT_EQ(res.stats.stereo_both_px, 45 * 150);
  EXPECT_EQ(res.stats.right_only_px + res.stats.neither_px, 0);
}

// Depth disagreement between the views: within tolerance counts as seen, beyond it as hidden.
TEST(StereoClasses, DepthTolerance) {
  const Rig rig = rectified_rig();
  const std::vector<Rect> scene = {{20, -2, 2, -1.5, 1.5, false}};
  View l = render_view(scene, rig.cam, Pose::identity());
  View r = render_view(scene, rig.cam, rig.T_left_right);
  StereoClassOptions o;  // tol = 0.05 + 0.005 * 20 = 0.15 m
  for (float& z : r.depth.z_m) z = std::isfinite(z) ? z - 0.14f : z;
  auto s =
      compute_occlusion_stats(0, l.mask, r.mask, l.depth, r.depth, rig.cam, rig.cam, rig.T_right_left(), o);
  EXPECT_EQ(s.stereo_both_px, 200 * 150);
  for (float& z : r.depth.z_m) z = std::isfinite(z) ? z - 0.02f : z;  // now 0.16 m in front
  s = compute_occlusion_stats(0, l.mask, r.mask, l.depth, r.depth, rig.cam, rig.cam, rig.T_right_left(), o);
  EXPECT_EQ(s.stereo_both_px, 0);
  EXPECT_EQ(s.left_only_px, 200 * 150);
}

// A converging, slightly pitched rig: projections no longer land on pixel centres, so the
// discrete test may differ from the continuous oracle only along boundaries (a few px per row).
TEST(StereoClasses, RotatedRigAgreesWithOracleUpToBoundaryPixels) {
  Rig rig = rectified_rig();
  rig.T_left_right =
      Pose::from(rotation_from_ypr(deg_to_rad(-1.5), deg_to_rad(0.3), deg_to_rad(0.2)), {0.5, 0.02, 0.1});
  auto scene = basic_scene();
  scene.push_back({15, 1, 1.5, -1, 1, false});
  const auto res = run_scene(scene, rig);
  const auto& s = res.stats;
  EXPECT_EQ(s.stereo_both_px + s.left_only_px + s.right_only_px + s.neither_px, s.receiver_px_left);
  const std::int64_t rows = 150;
  EXPECT_LE(res.mismatches, 2 * rows) << "mismatches " << res.mismatches;  // a few boundary columns
  for (auto c : {StereoClass::kBoth, StereoClass::kLeftOnly, StereoClass::kRightOnly, StereoClass::kNeither})
    EXPECT_NEAR(count_class(res.classes, c), count_class(res.oracle, c), rows);
  EXPECT_GT(s.right_only_px, 0);
  EXPECT_GT(s.neither_px, 0);
}

// Barrel distortion on both cameras: the left pixel's point must come from undistort() and the
// right projection from project(); a pinhole shortcut would misplace points by many pixels near
// the corners and turn visible points into "left only".
TEST(StereoClasses, DistortedCamerasAgreeWithOracle) {
  Rig rig = rectified_rig();
  rig.cam.distortion = DistortionModel::kRadTan;
  rig.cam.coeffs = {-0.25, 0.08, 0.0005, -0.0003, 0.0};
  // A receiver wall filling most of the view, and the boom bar.
  const std::vector<Rect> wall = {{20, -6, 6, -4.5, 4.5, false}};
  const auto plain = run_scene(wall, rig);
  EXPECT_EQ(plain.mismatches, 0);
  EXPECT_EQ(plain.stats.right_only_px + plain.stats.neither_px, 0);
  EXPECT_EQ(plain.stats.left_only_px,
            count_class(plain.oracle, StereoClass::kLeftOnly));  // out of the right image
  EXPECT_GT(plain.stats.stereo_both_px, plain.stats.receiver_px_left * 9 / 10);
  // Bars in the centre and near the right edge, where barrel distortion moves pixels by ~5 px.
  auto scene = wall;
  scene.push_back({10, 0, 0.3, -100, 100, true});
  scene.push_back({10, 2.5, 2.8, -100, 100, true});
  const auto res = run_scene(scene, rig);
  EXPECT_LE(res.mismatches, 2 * 480) << "mismatches " << res.mismatches;  // boundary pixels only
  EXPECT_GT(res.stats.right_only_px, 0);
  EXPECT_GT(res.stats.neither_px, 0);
  // The same wall with pinhole rays passed in (distortion ignored on the left): wrong points, and
  // the test notices.
  std::vector<Eigen::Vector2f> pinhole_rays(640 * 480);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x)
      pinhole_rays[y * 640 + x] = Eigen::Vector2f((x - 319.5f) / 1000.f, (y - 239.5f) / 1000.f);
  StereoClassOptions wrong;
  wrong.left_rays_xy = &pinhole_rays;
  const auto bad = run_scene(scene, rig, wrong);
  EXPECT_GT(bad.mismatches, 4 * res.mismatches) << bad.mismatches << " vs " << res.mismatches;
  std::cout << "distorted rig: " << res.mismatches << " boundary mismatches; with pinhole rays "
            << bad.mismatches << "\n";
}

// Equidistant (fisheye) cameras: the right projection goes through CameraModel::project() one
// point at a time (the classes project two at a time only for pinhole and radial-tangential
// lenses). The same oracle.
TEST(StereoClasses, FisheyeCamerasAgreeWithOracle) {
  Rig rig = rectified_rig();
  rig.cam.distortion = DistortionModel::kEquidistant;
  rig.cam.coeffs = {-0.02, 0.004, -0.001, 0.0002, 0.0};
  const std::vector<Rect> scene = {
      {20, -6, 6, -4.5, 4.5, false}, {10, 0, 0.3, -100, 100, true}, {10, 2.5, 2.8, -100, 100, true}};
  const auto res = run_scene(scene, rig);
  EXPECT_LE(res.mismatches, 2 * 480) << "mismatches " << res.mismatches;  // boundary pixels only
  EXPECT_GT(res.stats.right_only_px, 0);
  EXPECT_GT(res.stats.neither_px, 0);
  EXPECT_GT(res.stats.left_only_px, 0);
  EXPECT_GT(res.stats.stereo_both_px, res.stats.receiver_px_left / 2);
}

TEST(StereoClasses, CallerRaysEqualCachedRays) {
  const Rig rig = rectified_rig();
  const View l = render_view(basic_scene(), rig.cam, Pose::identity());
  const View r = render_view(basic_scene(), rig.cam, rig.T_left_right);
  const std::vector<Eigen::Vector2f> rays = undistorted_xy_map(rig.cam);
  ASSERT_EQ(rays.size(), 640u * 480u);
  EXPECT_NEAR(rays[240 * 640 + 400].x(), (400 - 319.5) / 1000.0, 1e-6);
  EXPECT_NEAR(rays[240 * 640 + 400].y(), (240 - 239.5) / 1000.0, 1e-6);
  StereoClassOptions o;
  o.left_rays_xy = &rays;
  std::vector<std::uint8_t> a, b;
  const auto sa = compute_occlusion_stats(0, l.mask, r.mask, l.depth, r.depth, rig.cam, rig.cam,
                                          rig.T_right_left(), o, &a);
  const auto sb = compute_occlusion_stats(0, l.mask, r.mask, l.depth, r.depth, rig.cam, rig.cam,
                                          rig.T_right_left(), {}, &b);
  EXPECT_EQ(a, b);
  EXPECT_EQ(sa.stereo_both_px, sb.stereo_both_px);
}

// 1280x960 with a receiver over ~30 % of the image and a boom bar: how long one frame takes.
TEST(StereoClasses, TimingFullResolution) {
  Rig rig{pinhole(1280, 960), Pose::from(Eigen::Matrix3d::Identity(), {0.5, 0, 0})};
  // 780 x 480 px of receiver (30.5 %): x in [-7.8, 7.8] m and y in [-4.8, 4.8] m at 20 m.
  const std::vector<Rect> scene = {{20, -7.8, 7.8, -4.8, 4.8, false}, {10, 0, 0.5, -100, 100, true}};
  const View l = render_view(scene, rig.cam, Pose::identity());
  const View r = render_view(scene, rig.cam, rig.T_left_right);
  const auto rays = undistorted_xy_map(rig.cam);
  StereoClassOptions o;
  o.left_rays_xy = &rays;
  std::vector<std::uint8_t> classes;
  OcclusionStats s;
  double best_ms = 1e9;
  for (int i = 0; i < 5; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    s = compute_occlusion_stats(0, l.mask, r.mask, l.depth, r.depth, rig.cam, rig.cam, rig.T_right_left(), o,
                                &classes);
    best_ms = std::min(
        best_ms, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::cout << "compute_occlusion_stats 1280x960, receiver " << s.receiver_pct_left << " %: " << best_ms
            << " ms\n";
  EXPECT_NEAR(s.receiver_pct_left, 100.0 * 780 * 480 / (1280 * 960), 1e-9);
  EXPECT_EQ(s.stereo_both_px + s.left_only_px + s.right_only_px + s.neither_px, s.receiver_px_left);
  EXPECT_LT(best_ms, 1000.0);  // only catches pathologies; the number above is what matters
}

// ---------------------------------------------------------------------------------------------
// Output formats.

TEST(StatsCsv, HeaderIsExact) {
  std::ostringstream o;
  write_stats_csv_header(o);
  EXPECT_EQ(o.str(),
            "t_ns,receiver_px_left,receiver_px_right,boom_px_left,boom_px_right,boom_overlap_px,"
            "boom_overlap_pct_union,occluded_px_left,occluded_px_right,occluded_pct_left,occluded_pct_right,"
            "stereo_both_px,left_only_px,right_only_px,neither_px,receiver_pct_left,receiver_pct_right,"
            "boom_pct_left,boom_pct_right,shadow_px_left,shadow_px_right,shadow_pct_left,shadow_pct_right\n");
}

OcclusionStats sample_stats() {
  OcclusionStats s;
  s.t_ns = 1234567890123456789LL;  // needs all 64 bits: must not pass through a double
  s.width = 1280;
  s.height = 960;
  s.receiver_px_left = 1;
  s.receiver_px_right = 2;
  s.boom_px_left = 3;
  s.boom_px_right = 4;
  s.boom_overlap_px = 5;
  s.boom_overlap_pct_union = 7.18449;
  s.occluded_px_left = 6;
  s.occluded_px_right = 7;
  s.occluded_pct_left = 0.24613;
  s.occluded_pct_right = 100;
  s.stereo_both_px = 8;
  s.left_only_px = 9;
  s.right_only_px = 10;
  s.neither_px = 11;
  s.receiver_pct_left = 0;
  s.receiver_pct_right = 1.0 / 3.0;
  s.boom_pct_left = 3.33416;
  s.boom_pct_right = 99.99996;
  s.shadow_px_left = 12;
  s.shadow_px_right = 13;
  s.shadow_pct_left = 2.5;
  s.shadow_pct_right = 0.123456;
  return s;
}

TEST(StatsCsv, RowFormat) {
  std::ostringstream o;
  write_stats_csv_row(o, sample_stats());
  EXPECT_EQ(o.str(),
            "1234567890123456789,1,2,3,4,5,7.1845,6,7,0.2461,100.0000,8,9,10,11,0.0000,0.3333,3.3342,"
            "100.0000,12,13,2.5000,0.1235\n");
}

// What write_stats_csv_header() and write_stats_csv_row() wrote, as a file.
std::string write_stats_file(const std::string& path, const std::vector<OcclusionStats>& rows) {
  std::ostringstream o;
  write_stats_csv_header(o);
  for (const OcclusionStats& s : rows) write_stats_csv_row(o, s);
  std::ofstream(path, std::ios::binary) << o.str();
  return o.str();
}

TEST(StatsCsv, ReadBackAndWrittenAgainIsTheSameText) {
  const std::string dir = test::output_dir("stats_csv_read");
  OcclusionStats a = sample_stats(), b = sample_stats(), c;
  a.t_ns = -5;  // a clock before its epoch is still a time
  b.t_ns = std::numeric_limits<std::int64_t>::max();
  b.receiver_px_left = 1234567890123;
  b.occluded_pct_left = 12.34565;  // rounded to 4 decimals when written: read back as written
  c.t_ns = 1;
  const std::string text = write_stats_file(dir + "/stats.csv", {a, b, c});
  auto rows = read_stats_csv(dir + "/stats.csv");
  ASSERT_TRUE(rows) << rows.error().message;
  ASSERT_EQ(rows->size(), 3u);
  EXPECT_EQ((*rows)[0].t_ns, -5);
  EXPECT_EQ((*rows)[1].t_ns, std::numeric_limits<std::int64_t>::max());  // all 64 bits, not through a double
  EXPECT_EQ((*rows)[1].receiver_px_left, 1234567890123);
  EXPECT_EQ((*rows)[0].neither_px, 11);
  EXPECT_EQ((*rows)[0].boom_pct_right, 100.0);  // 99.99996 as written: 100.0000
  EXPECT_EQ((*rows)[0].shadow_px_left, 12);
  EXPECT_EQ((*rows)[0].shadow_px_right, 13);
  EXPECT_EQ((*rows)[0].shadow_pct_left, 2.5);
  EXPECT_EQ((*rows)[0].shadow_pct_right, 0.1235);
  EXPECT_EQ((*rows)[2].shadow_px_left, 0);
  EXPECT_EQ((*rows)[0].width, 0);  // not in the file
  EXPECT_EQ((*rows)[0].height, 0);
  std::ostringstream again;
  write_stats_csv_header(again);
  for (const OcclusionStats& s : *rows) write_stats_csv_row(again, s);
  EXPECT_EQ(again.str(), text);
  // The run's summary of the rows read is that of the rows written, up to the file's rounding.
  const std::string summary = format_run_summary(*rows);
  EXPECT_NE(summary.find("Run summary over 3 stereo frame(s)"), std::string::npos) << summary;
  char t_line[128];
  std::snprintf(t_line, sizeof t_line, "%-24s %16s %16lld %16lld\n", "t_ns", "-", -5LL,
                static_cast<long long>(std::numeric_limits<std::int64_t>::max()));
  EXPECT_NE(summary.find(t_line), std::string::npos) << summary;
  EXPECT_NE(summary.find(" 1234567890123\n"), std::string::npos) << "receiver_px_left's max\n" << summary;
  // A file with Windows line ends and no last line end reads the same.
  std::string crlf;
  for (char ch : text) crlf += ch == '\n' ? std::string("\r\n") : std::string(1, ch);
  crlf.resize(crlf.size() - 2);
  std::ofstream(dir + "/crlf.csv", std::ios::binary) << crlf;
  auto r2 = read_stats_csv(dir + "/crlf.csv");
  ASSERT_TRUE(r2) << r2.error().message;
  std::ostringstream o2;
  write_stats_csv_header(o2);
  for (const OcclusionStats& s : *r2) write_stats_csv_row(o2, s);
  EXPECT_EQ(o2.str(), text);
}

TEST(StatsCsv, ABadFileIsAnErrorNamingFileLineAndColumn) {
  const std::string dir = test::output_dir("stats_csv_read_bad");
  const std::string text = write_stats_file(dir + "/good.csv", {sample_stats(), sample_stats()});
  const std::string header = text.substr(0, text.find('\n'));
  const std::string row =
      text.substr(header.size() + 1, text.find('\n', header.size() + 1) - header.size() - 1);
  auto error_of = [&](const std::string& name, const std::string& content) {
    std::ofstream(dir + "/" + name, std::ios::binary) << content;
    auto r = read_stats_csv(dir + "/" + name);
    EXPECT_FALSE(r) << name;
    return r ? std::string() : r.error().message;
  };
  auto replace = [](std::string s, const std::string& from, const std::string& to) {
    s.replace(s.find(from), from.size(), to);
    return s;
  };
  // The header: a column renamed, one missing, one too many.
  std::string m = error_of("renamed.csv", replace(header, "neither_px", "none_px") + "\n" + row + "\n");
  EXPECT_NE(m.find(dir + "/renamed.csv:1:"), std::string::npos) << m;
  EXPECT_NE(m.find("column 15 is 'none_px', expected 'neither_px'"), std::string::npos) << m;
  m = error_of("fewer.csv", header.substr(0, header.rfind(',')) + "\n");
  EXPECT_NE(m.find("fewer.csv:1:"), std::string::npos) << m;
  EXPECT_NE(m.find("column 23 is '(none)', expected 'shadow_pct_right'"), std::string::npos) << m;
  m = error_of("more.csv", header + ",frame\n");
  EXPECT_NE(m.find("column 24 is 'frame', expected '(none)'"), std::string::npos) << m;
  // A row: a field missing, a count that is not an integer, a percentage that is not a number.
  m = error_of("short.csv", header + "\n" + row + "\n" + row.substr(0, row.rfind(',')) + "\n");
  EXPECT_NE(m.find("short.csv:3: 22 fields, expected 23"), std::string::npos) << m;
  m = error_of("count.csv", header + "\n" + replace(row, ",8,9,", ",8.5,9,") + "\n");
  EXPECT_NE(m.find("count.csv:2:stereo_both_px: expected an integer, got '8.5'"), std::string::npos) << m;
  m = error_of("pct.csv", header + "\n" + replace(row, ",7.1845,", ",7.18x,") + "\n");
  EXPECT_NE(m.find("pct.csv:2:boom_overlap_pct_union: expected a number, got '7.18x'"), std::string::npos)
      << m;
  m = error_of("t.csv", header + "\n" + replace(row, "1234567890123456789,", ",") + "\n");
  EXPECT_NE(m.find("t.csv:2:t_ns: expected an integer, got ''"), std::string::npos) << m;
  m = error_of("empty.csv", "");
  EXPECT_NE(m.find("empty.csv: empty"), std::string::npos) << m;
  auto none = read_stats_csv(dir + "/none.csv");
  ASSERT_FALSE(none);
  EXPECT_NE(none.error().message.find("render::read_stats_csv(): " + dir + "/none.csv: cannot read"),
            std::string::npos)
      << none.error().message;
}

// The first n cells of every line of `text`.
std::string first_cells(const std::string& text, int n) {
  std::istringstream in(text);
  std::string out;
  for (std::string line; std::getline(in, line);) {
    std::size_t end = 0;
    for (int k = 0; k < n && end != std::string::npos; ++k) end = line.find(',', end ? end + 1 : 0);
    out += line.substr(0, end) + "\n";
  }
  return out;
}

// A file written before the four shadow columns were appended: exactly the 19 columns up to
// boom_pct_right. It still reads, every other field as written and the shadow fields 0.
TEST(StatsCsv, AFileWithTheColumnsBeforeTheShadowColumnsStillReads) {
  const std::string dir = test::output_dir("stats_csv_read_old");
  OcclusionStats a = sample_stats(), b = sample_stats();
  b.t_ns = 7;
  b.neither_px = 99;
  const std::string text = write_stats_file(dir + "/new.csv", {a, b});
  const std::string old = first_cells(text, 19);
  ASSERT_EQ(old.substr(0, old.find('\n')),
            "t_ns,receiver_px_left,receiver_px_right,boom_px_left,boom_px_right,boom_overlap_px,"
            "boom_overlap_pct_union,occluded_px_left,occluded_px_right,occluded_pct_left,occluded_pct_right,"
            "stereo_both_px,left_only_px,right_only_px,neither_px,receiver_pct_left,receiver_pct_right,"
            "boom_pct_left,boom_pct_right");
  std::ofstream(dir + "/old.csv", std::ios::binary) << old;
  auto rows = read_stats_csv(dir + "/old.csv");
  ASSERT_TRUE(rows) << rows.error().message;
  auto now = read_stats_csv(dir + "/new.csv");
  ASSERT_TRUE(now) << now.error().message;
  ASSERT_EQ(rows->size(), 2u);
  ASSERT_EQ(now->size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    OcclusionStats want = (*now)[i];
    EXPECT_NE(want.shadow_px_left, 0);
    want.shadow_px_left = want.shadow_px_right = 0;
    want.shadow_pct_left = want.shadow_pct_right = 0;
    EXPECT_EQ((*rows)[i], want) << i;
  }
  EXPECT_EQ((*rows)[1].neither_px, 99);
  // Written again, it has the whole header and zeros in the shadow columns.
  std::ostringstream again;
  write_stats_csv_header(again);
  for (const OcclusionStats& s : *rows) write_stats_csv_row(again, s);
  EXPECT_EQ(first_cells(again.str(), 19), old);
  EXPECT_NE(again.str().find(",100.0000,0,0,0.0000,0.0000\n"), std::string::npos) << again.str();
  // Its summary has the shadow columns, at 0.
  const std::string summary = format_run_summary(*rows);
  EXPECT_NE(summary.find("shadow_px_left "), std::string::npos) << summary;
}

// Any header other than the whole column list or the older 19 columns is refused, naming the file,
// line 1 and what was expected; so is an older file whose rows have the newer columns.
TEST(StatsCsv, OtherHeadersAreRefused) {
  const std::string dir = test::output_dir("stats_csv_read_headers");
  const std::string text = write_stats_file(dir + "/good.csv", {sample_stats()});
  const std::string header = text.substr(0, text.find('\n'));
  const std::string row = text.substr(header.size() + 1);
  const std::string old_header = first_cells(header, 19);  // ends in '\n'
  auto error_of = [&](const std::string& name, const std::string& content) {
    std::ofstream(dir + "/" + name, std::ios::binary) << content;
    auto r = read_stats_csv(dir + "/" + name);
    EXPECT_FALSE(r) << name;
    return r ? std::string() : r.error().message;
  };
  // The older header less its last column, or with one more than it.
  std::string m = error_of("old_fewer.csv", first_cells(header, 18));
  EXPECT_NE(m.find(dir + "/old_fewer.csv:1: not a stats.csv header"), std::string::npos) << m;
  EXPECT_NE(m.find("column 19 is '(none)', expected 'boom_pct_right'"), std::string::npos) << m;
  m = error_of("old_more.csv", first_cells(header, 20));
  EXPECT_NE(m.find("old_more.csv:1:"), std::string::npos) << m;
  EXPECT_NE(m.find("column 21 is '(none)', expected 'shadow_px_right'"), std::string::npos) << m;
  // The older header with a column renamed, or its columns in another order.
  std::string renamed = old_header;
  renamed.replace(renamed.find("boom_pct_right"), 14, "boom_pct_rite");
  m = error_of("old_renamed.csv", renamed);
  EXPECT_NE(m.find("old_renamed.csv:1:"), std::string::npos) << m;
  EXPECT_NE(m.find("column 19 is 'boom_pct_rite', expected 'boom_pct_right'"), std::string::npos) << m;
  // The shadow columns in another order.
  std::string swapped = header;
  swapped.replace(swapped.find("shadow_px_left,shadow_px_right"), 30, "shadow_px_right,shadow_px_left");
  m = error_of("swapped.csv", swapped + "\n");
  EXPECT_NE(m.find("swapped.csv:1:"), std::string::npos) << m;
  EXPECT_NE(m.find("column 20 is 'shadow_px_right', expected 'shadow_px_left'"), std::string::npos) << m;
  // The shadow columns without the older ones before them.
  m = error_of("shadow_only.csv", "t_ns,shadow_px_left,shadow_px_right,shadow_pct_left,shadow_pct_right\n");
  EXPECT_NE(m.find("column 2 is 'shadow_px_left', expected 'receiver_px_left'"), std::string::npos) << m;
  // The older header over rows of the newer kind.
  m = error_of("old_header_new_rows.csv", old_header + row);
  EXPECT_NE(m.find("old_header_new_rows.csv:2: 23 fields, expected 19"), std::string::npos) << m;
}

TEST(StatsTable1, ShadowRowsAfterTheOcclusionRows) {
  OcclusionStats s = sample_stats();
  s.receiver_px_left = 1000, s.receiver_px_right = 800;
  s.shadow_px_left = 125, s.shadow_px_right = 20;
  s.shadow_pct_left = 12.5, s.shadow_pct_right = 2.5;
  const std::string t = format_table1(s, "Shadow");
  const auto occl = t.find("Boom occlusion right");
  const auto left = t.find("Boom shadow on receiver left");
  const auto right = t.find("Boom shadow on receiver right");
  const auto stereo = t.find("Stereo: visible to both");
  ASSERT_NE(occl, std::string::npos) << t;
  ASSERT_NE(left, std::string::npos) << t;
  ASSERT_NE(right, std::string::npos) << t;
  EXPECT_LT(occl, left);
  EXPECT_LT(left, right);
  EXPECT_LT(right, stereo);
  auto line_at = [&](std::size_t p) { return t.substr(p, t.find('\n', p) - p); };
  char want[256];
  std::snprintf(want, sizeof want, "%-36s %12lld %9.2f%%  %s", "Boom shadow on receiver left", 125LL, 12.5,
                "receiver pixels left (1000 px)");
  EXPECT_EQ(line_at(left), want);
  std::snprintf(want, sizeof want, "%-36s %12lld %9.2f%%  %s", "Boom shadow on receiver right", 20LL, 2.5,
                "receiver pixels right (800 px)");
  EXPECT_EQ(line_at(right), want);
}

TEST(StatsSummary, MeanMinMaxPerColumn) {
  OcclusionStats a = sample_stats(), b = sample_stats();
  a.t_ns = 100;
  b.t_ns = 300;
  a.receiver_px_left = 10;
  b.receiver_px_left = 31;
  a.occluded_pct_left = 1.0;
  b.occluded_pct_left = 2.5;
  const std::string t = format_run_summary({a, b});
  auto line_of = [&](const std::string& col) {
    const auto p = t.find("\n" + col + " ");
    EXPECT_NE(p, std::string::npos) << col;
    return p == std::string::npos ? std::string() : t.substr(p + 1, t.find('\n', p + 1) - p - 1);
  };
  std::istringstream r(line_of("receiver_px_left"));
  std::string name;
  double mean, lo, hi;
  r >> name >> mean >> lo >> hi;
  EXPECT_DOUBLE_EQ(mean, 20.5);
  EXPECT_DOUBLE_EQ(lo, 10);
  EXPECT_DOUBLE_EQ(hi, 31);
  std::istringstream p(line_of("occluded_pct_left"));
  p >> name >> mean >> lo >> hi;
  EXPECT_DOUBLE_EQ(mean, 1.75);
  EXPECT_DOUBLE_EQ(lo, 1.0);
  EXPECT_DOUBLE_EQ(hi, 2.5);
  EXPECT_NE(t.find("2 stereo frame"), std::string::npos);
  EXPECT_NE(format_run_summary({}).find("0 stereo frame"), std::string::npos);
}

}  // namespace
}  // namespace augrig
