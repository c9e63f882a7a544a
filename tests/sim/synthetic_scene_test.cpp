// The synthetic scene renderer against geometry computed independently with the camera model:
// where the horizon must be, where the receiver must be, the stereo disparity, the sensor formats;
// the CPU back end's receiver silhouette against the augmenter's receiver mask, and against the
// OpenGL back end; the physical boom's shadow on the receiver against a ray cast.
#include "sim/synthetic_scene.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/conventions.hpp"
#include "eval/look_compare.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "render/models.hpp"
#include "render/motion_blur.hpp"
#include "render/projection.hpp"
#include "sim/synthetic_scene_cpu.hpp"
#include "tests/support/gl_test.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

Rig distorted_rig() {
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) {
    c.model.distortion = DistortionModel::kRadTan;
    c.model.coeffs = {-0.28, 0.12, 8e-4, -6e-4, -0.02};
    c.model.cx_px += 12.3;
    c.model.cy_px -= 8.7;
  }
  return rig;
}

// Tanker nose down 20 deg and rolled 8 deg: the aft cameras then see the horizon, tilted.
SkyState horizon_sky() {
  SkyState sky;
  sky.R_ned_body = rotation_from_ypr(deg_to_rad(90.0), deg_to_rad(-20.0), deg_to_rad(8.0));
  sky.altitude_m = 6000.0;
  sky.north_east_m = {100.0, 200.0};
  return sky;
}

// Receiver 22 m aft and 8 m below the cameras, level.
Pose receiver_pose() {
  return Pose::from(Eigen::Matrix3d::Identity(), {-22.0, 0.5, 9.0});
}

void write_png(const std::string& path, const Image& img) {
  cv::Mat m;
  if (img.format() == PixelFormat::kRGB8) {
    cv::Mat rgb(img.height(), img.width(), CV_8UC3, const_cast<std::uint8_t*>(img.data()),
                img.stride_bytes());
    cv::cvtColor(rgb, m, cv::COLOR_RGB2BGR);
  } else {
    m = cv::Mat(img.height(), img.width(), CV_8UC1, const_cast<std::uint8_t*>(img.data()), img.stride_bytes())
            .clone();
  }
  cv::imwrite(path, m);
}

const std::uint8_t* px(const Image& img, int u, int v) {
  return img.row(v) + u * bytes_per_pixel(img.format());
}

// Raw-pixel box of the receiver's vertices (projected with the camera model), inclusive.
struct Box {
  double u0 = 1e9, v0 = 1e9, u1 = -1e9, v1 = -1e9;
  int n = 0;
};
Box project_model(const Model& model, const RigCamera& cam, const Pose& T_body_obj) {
  const Pose T_cam_obj = cam.T_body_cam.inverse() * T_body_obj;
  Box b;
  for (const Mesh& m : model.meshes)
    for (const auto& p : m.positions_m) {
      const auto uv = cam.model.project(T_cam_obj * p.cast<double>());
      if (!uv) continue;
      b.u0 = std::min(b.u0, uv->x()), b.u1 = std::max(b.u1, uv->x());
      b.v0 = std::min(b.v0, uv->y()), b.v1 = std::max(b.v1, uv->y());
      ++b.n;
    }
  return b;
}

class SyntheticSceneTest : public test::GlTest {
 protected:
  static std::unique_ptr<SyntheticSceneRenderer> make(const Rig& rig, SceneBackend backend = SceneBackend::kCpu,
                                                      int threads = 2) {
    SceneRendererOptions options;
    options.backend = backend;
    options.threads = threads;
    auto r = SyntheticSceneRenderer::create(rig, nullptr, options);
    EXPECT_TRUE(r) << r.error().message;
    return r ? std::move(*r) : nullptr;
  }
};

TEST_F(SyntheticSceneTest, SizesAndFormats) {
  const Rig rig = Rig::paper_default();
  auto r = make(rig);
  ASSERT_TRUE(r);
  for (PixelFormat f :
       {PixelFormat::kRGB8, PixelFormat::kMono8, PixelFormat::kRGBA8, PixelFormat::kBayerRG8}) {
    SensorOptions s;
    s.format = f;
    Image img;
    ASSERT_TRUE(r->render(1, SkyState{}, receiver_pose(), true, s, img));
    EXPECT_EQ(img.width(), 1280);
    EXPECT_EQ(img.height(), 960);
    EXPECT_EQ(img.format(), f);
  }
  Image img;
  EXPECT_FALSE(r->render(2, SkyState{}, receiver_pose(), true, SensorOptions{}, img));
}

TEST_F(SyntheticSceneTest, BayerAndMonoAreTheRgbRenderSampled) {
  const Rig rig = Rig::paper_default();
  auto r = make(rig);
  ASSERT_TRUE(r);
  Image rgb;
  ASSERT_TRUE(r->render(0, horizon_sky(), receiver_pose(), true, SensorOptions{}, rgb));
  for (PixelFormat f : {PixelFormat::kBayerRG8, PixelFormat::kBayerGR8, PixelFormat::kBayerGB8,
                        PixelFormat::kBayerBG8, PixelFormat::kMono8}) {
    SensorOptions s;
    s.format = f;
    Image out;
    ASSERT_TRUE(r->render(0, horizon_sky(), receiver_pose(), true, s, out));
    long bad = 0;
    for (int y = 0; y < rgb.height(); ++y)
      for (int x = 0; x < rgb.width(); ++x) {
        const std::uint8_t* c = px(rgb, x, y);
        const int got = out.row(y)[x];
        if (is_bayer(f)) {
          bad += got != c[bayer_channel(f, x, y)];
        } else {
          bad += std::abs(got - (0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2])) > 0.51;
        }
      }
    EXPECT_EQ(bad, 0) << to_string(f);
  }
}

// The horizon found by projecting far points of the NED horizontal plane with the camera model:
// bright sky just above it, darker hazy ground just below; blue sky well above, the ground well below.
void check_horizon(const Rig& rig, int camera, const Image& img) {
  const RigCamera& cam = rig.cameras[camera];
  const SkyState sky = horizon_sky();
  const Eigen::Matrix3d R_cam_ned = (sky.R_ned_body * cam.T_body_cam.R()).transpose();
  int checked = 0;
  for (double az = 0; az < 360; az += 0.5) {
    const Eigen::Vector3d d(std::cos(deg_to_rad(az)), std::sin(deg_to_rad(az)), 0.0);
    const auto uv = cam.model.project(R_cam_ned * d * 1e7);
    if (!uv) continue;
    const int u = static_cast<int>(std::lround(uv->x())), v = static_cast<int>(std::lround(uv->y()));
    if (u < 10 || u >= img.width() - 10 || v < 120 || v >= img.height() - 120) continue;
    const std::uint8_t* a = px(img, u, v - 5);
    const std::uint8_t* b = px(img, u, v + 5);
    const int above = a[0] + a[1] + a[2], below = b[0] + b[1] + b[2];
    EXPECT_GT(above, below + 60) << "u " << u << " horizon v " << v;
    const std::uint8_t* high = px(img, u, v - 110);
    EXPECT_GT(high[2], high[0] + 40) << "sky is blue, u " << u;
    const std::uint8_t* low = px(img, u, v + 110);
    EXPECT_LT(low[0] + low[1] + low[2], above - 60) << "ground below, u " << u;
    ++checked;
  }
  EXPECT_GT(checked, 20);
}

TEST_F(SyntheticSceneTest, HorizonWhereTheAttitudePutsIt) {
  for (const SceneBackend backend : {SceneBackend::kCpu, SceneBackend::kOpenGL}) {
    for (const Rig& rig : {Rig::paper_default(), distorted_rig()}) {
      auto r = make(rig, backend);
      ASSERT_TRUE(r);
      for (int c = 0; c < 2; ++c) {
        Image img;
        ASSERT_TRUE(r->render(c, horizon_sky(), receiver_pose(), false, SensorOptions{}, img));
        SCOPED_TRACE(rig.cameras[c].model.distortion_name() + " camera " + std::to_string(c) +
                     (backend == SceneBackend::kCpu ? " cpu" : " opengl"));
        check_horizon(rig, c, img);
      }
    }
  }
}

TEST_F(SyntheticSceneTest, ReceiverInsideItsProjectedBox) {
  for (const Rig& rig : {Rig::paper_default(), distorted_rig()}) {
    auto r = make(rig);
    ASSERT_TRUE(r);
    const Model receiver = make_builtin_receiver();
    for (int c = 0; c < 2; ++c) {
      Image with, without;
      ASSERT_TRUE(r->render(c, SkyState{}, receiver_pose(), true, SensorOptions{}, with));
      ASSERT_TRUE(r->render(c, SkyState{}, receiver_pose(), false, SensorOptions{}, without));
      const Box b = project_model(receiver, rig.cameras[c], receiver_pose());
      ASSERT_GT(b.n, 0);
      ASSERT_GT(b.u0, 0);
      ASSERT_LT(b.u1, 1279);
      long inside = 0, outside = 0;
      for (int y = 0; y < with.height(); ++y)
        for (int x = 0; x < with.width(); ++x) {
          if (std::memcmp(px(with, x, y), px(without, x, y), 3) == 0) continue;
          // Two pixels of slack: bilinear resampling and rasterisation at the silhouette.
          const bool in = x >= b.u0 - 2 && x <= b.u1 + 2 && y >= b.v0 - 2 && y <= b.v1 + 2;
          (in ? inside : outside)++;
        }
      EXPECT_EQ(outside, 0) << rig.cameras[c].model.distortion_name() << " camera " << c;
      const double area = (b.u1 - b.u0) * (b.v1 - b.v0);
      EXPECT_GT(inside, 0.12 * area) << rig.cameras[c].model.distortion_name() << " camera " << c;
    }
  }
}

// Centroid of the pixels the receiver changes.
Eigen::Vector2d receiver_centroid(const Image& with, const Image& without) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  long n = 0;
  for (int y = 0; y < with.height(); ++y)
    for (int x = 0; x < with.width(); ++x)
      if (std::memcmp(px(with, x, y), px(without, x, y), 3) != 0) sum += Eigen::Vector2d(x, y), ++n;
  return n ? Eigen::Vector2d(sum / n) : Eigen::Vector2d::Constant(NAN);
}

TEST_F(SyntheticSceneTest, StereoConsistent) {
  const Rig rig = Rig::paper_default();
  auto r = make(rig);
  ASSERT_TRUE(r);
  Image with[2], without[2];
  for (int c = 0; c < 2; ++c) {
    ASSERT_TRUE(r->render(c, SkyState{}, receiver_pose(), true, SensorOptions{}, with[c]));
    ASSERT_TRUE(r->render(c, SkyState{}, receiver_pose(), false, SensorOptions{}, without[c]));
  }
  // The receiver shifts by the disparity fx * B / z of its depth; rows stay (parallel cameras).
  const Eigen::Vector2d cl = receiver_centroid(with[0], without[0]);
  const Eigen::Vector2d cr = receiver_centroid(with[1], without[1]);
  const Eigen::Vector3d centre_body = receiver_pose() * Eigen::Vector3d(-1.0, 0, 0);  // about mid-body
  const double z = (rig.left().T_body_cam.inverse() * centre_body).z();
  const double baseline = (rig.left().T_body_cam.translation_m - rig.right().T_body_cam.translation_m).norm();
  const double expected = rig.left().model.fx_px * baseline / z;
  EXPECT_NEAR(cl.x() - cr.x(), expected, 0.15 * expected) << "z " << z;
  EXPECT_NEAR(cl.y(), cr.y(), 1.0);
  // The ground is ~14 km away: sub-pixel disparity, the same picture in both cameras.
  double diff = 0;
  for (int y = 0; y < 960; ++y)
    for (int x = 0; x < 1280 * 3; ++x) diff += std::abs(without[0].row(y)[x] - without[1].row(y)[x]);
  EXPECT_LT(diff / (1280.0 * 960 * 3), 2.0);
}

TEST_F(SyntheticSceneTest, NoiseIsDeterministicPerSeed) {
  const Rig rig = Rig::paper_default();
  auto r = make(rig);
  ASSERT_TRUE(r);
  SensorOptions s;
  s.noise_sigma = 3.0;
  s.noise_seed = 7;
  Image a, b, clean, other;
  ASSERT_TRUE(r->render(0, SkyState{}, receiver_pose(), true, s, a));
  ASSERT_TRUE(r->render(0, SkyState{}, receiver_pose(), true, s, b));
  EXPECT_TRUE(pixels_equal(a, b));
  s.noise_seed = 8;
  ASSERT_TRUE(r->render(0, SkyState{}, receiver_pose(), true, s, other));
  EXPECT_FALSE(pixels_equal(a, other));
  ASSERT_TRUE(r->render(0, SkyState{}, receiver_pose(), true, SensorOptions{}, clean));
  // The noise has about the requested sigma and no bias (pixels far from 0 and 255 only).
  double sum = 0, sum2 = 0;
  long n = 0;
  for (int y = 0; y < 960; ++y)
    for (int x = 0; x < 1280 * 3; ++x) {
      const int c = clean.row(y)[x];
      if (c < 20 || c > 235) continue;
      const double d = a.row(y)[x] - c;
      sum += d, sum2 += d * d, ++n;
    }
  ASSERT_GT(n, 100000);
  EXPECT_NEAR(sum / n, 0.0, 0.05);
  EXPECT_NEAR(std::sqrt(sum2 / n), 3.0, 0.1);
}

TEST_F(SyntheticSceneTest, DistortedCameraHasNoHoles) {
  const Rig rig = distorted_rig();
  auto r = make(rig);
  ASSERT_TRUE(r);
  const VirtualPinhole vp = make_virtual_pinhole(rig.left().model).value();
  // Background only: sky and hazy ground are never near black, so a dark pixel is a hole.
  Image img;
  ASSERT_TRUE(r->render(0, horizon_sky(), receiver_pose(), false, SensorOptions{}, img));
  long valid = 0, black = 0, invalid_not_black = 0;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) {
      const std::uint8_t* c = px(img, x, y);
      if (!std::isfinite(vp.ray_xy[static_cast<std::size_t>(y) * img.width() + x].x())) {
        invalid_not_black += c[0] + c[1] + c[2] != 0;
        continue;
      }
      ++valid;
      black += c[0] + c[1] + c[2] < 60;
    }
  EXPECT_GT(valid, 1280L * 960 * 9 / 10);
  EXPECT_EQ(black, 0);
  EXPECT_EQ(invalid_not_black, 0);
  ASSERT_TRUE(r->render(0, horizon_sky(), receiver_pose(), true, SensorOptions{}, img));
  write_png(test::output_dir("sim_distorted") + "/distorted_left.png", img);
}

// Pixels the receiver changes (rendered with and without it, no noise): its silhouette.
std::vector<std::uint8_t> silhouette(const Image& with, const Image& without) {
  std::vector<std::uint8_t> s(static_cast<std::size_t>(with.width()) * with.height());
  for (int y = 0; y < with.height(); ++y)
    for (int x = 0; x < with.width(); ++x)
      s[static_cast<std::size_t>(y) * with.width() + x] = std::memcmp(px(with, x, y), px(without, x, y), 3) != 0;
  return s;
}

// The augmenter decides its receiver mask exactly at every pixel centre's ray (render/augmenter):
// the simulated receiver must cover the same pixels, but for pixels along the silhouette where
// rasterisation rounding differs (the CPU back end rasterises the same triangles at the same
// samples without distortion, and takes each raw pixel's nearest virtual sample with it), and
// receiver pixels that happen to have the background's colour.
TEST_F(SyntheticSceneTest, ReceiverSilhouetteIsTheAugmentersReceiverMask) {
  for (const Rig& rig : {Rig::paper_default(), distorted_rig()}) {
    auto r = make(rig);
    ASSERT_TRUE(r);
    AugmentOptions ao;
    ao.rasterizer = Rasterizer::kCpu;
    auto aug = Augmenter::create(rig, ao);
    ASSERT_TRUE(aug) << aug.error().message;
    SceneState scene;
    scene.T_body_receiver = receiver_pose();
    scene.boom = {deg_to_rad(30.0), 0.0, 1.0};
    for (int c = 0; c < 2; ++c) {
      SCOPED_TRACE(rig.cameras[c].model.distortion_name() + " camera " + std::to_string(c));
      Image with, without;
      ASSERT_TRUE(r->render(c, SkyState{}, receiver_pose(), true, SensorOptions{}, with));
      ASSERT_TRUE(r->render(c, SkyState{}, receiver_pose(), false, SensorOptions{}, without));
      const std::vector<std::uint8_t> sim = silhouette(with, without);
      Frame raw;
      raw.image = with;
      raw.camera = c == 0 ? CameraId::kLeft : CameraId::kRight;
      ViewResult vr;
      ASSERT_TRUE((*aug)->augment_view(c, raw, scene, vr));
      long mask_px = 0, differ = 0;
      for (int y = 0; y < with.height(); ++y)
        for (int x = 0; x < with.width(); ++x) {
          const bool m = (vr.mask.row(y)[x] & kMaskReceiver) != 0;
          mask_px += m;
          differ += m != (sim[static_cast<std::size_t>(y) * with.width() + x] != 0);
        }
      ASSERT_GT(mask_px, 20000);
      std::printf("receiver %ld px, %ld differ from the augmenter's mask (%.2f %%)\n", mask_px, differ,
                  100.0 * differ / mask_px);
      // Measured: 0.03 % without distortion, 0.9 % with it (a raw pixel's ray tested against the
      // triangles of its four virtual samples only, where the augmenter also tries their one-ring).
      const bool distorted = rig.cameras[c].model.distortion != DistortionModel::kNone;
      EXPECT_LT(differ, (distorted ? 0.015 : 0.002) * mask_px);
    }
  }
}

// The boom physically in the scene (render_with_boom, issue 33 §3) is where the augmenter puts
// its boom: the pixels it changes are the augmenter's boom mask (the boom front-most at the pixel
// centre), but for silhouette pixels, and it hides the receiver where the augmenter says it does.
TEST_F(SyntheticSceneTest, PhysicalBoomIsWhereTheAugmentersBoomMaskIs) {
  for (const Rig& rig : {Rig::paper_default(), distorted_rig()}) {
    auto r = make(rig);
    ASSERT_TRUE(r);
    AugmentOptions ao;
    ao.rasterizer = Rasterizer::kCpu;
    auto aug = Augmenter::create(rig, ao);
    ASSERT_TRUE(aug) << aug.error().message;
    // Near contact: the boom crosses the receiver's nose in both views.
    SceneState scene;
    scene.boom = {deg_to_rad(30.0), deg_to_rad(2.0), 3.0};
    scene.T_body_receiver = Pose::from(Eigen::Matrix3d::Identity(), {-16.0, 0.3, 11.0});
    for (int c = 0; c < 2; ++c) {
      SCOPED_TRACE(rig.cameras[c].model.distortion_name() + " camera " + std::to_string(c));
      Image with, without;
      ASSERT_TRUE(r->render_with_boom(c, SkyState{}, scene.T_body_receiver, true, scene.boom, SensorOptions{}, with));
      ASSERT_TRUE(r->render(c, SkyState{}, scene.T_body_receiver, true, SensorOptions{}, without));
      const std::vector<std::uint8_t> sim = silhouette(with, without);
      Frame raw;
      raw.image = without;
      raw.camera = c == 0 ? CameraId::kLeft : CameraId::kRight;
      ViewResult vr;
      ASSERT_TRUE((*aug)->augment_view(c, raw, scene, vr));
      long boom_px = 0, differ = 0, over_receiver = 0;
      for (int y = 0; y < with.height(); ++y)
        for (int x = 0; x < with.width(); ++x) {
          const std::uint8_t m = vr.mask.row(y)[x];
          const bool b = (m & kMaskBoom) != 0;
          boom_px += b;
          over_receiver += b && (m & kMaskReceiver);
          differ += b != (sim[static_cast<std::size_t>(y) * with.width() + x] != 0);
        }
      ASSERT_GT(boom_px, 20000);
      ASSERT_GT(over_receiver, 500);
      std::printf("boom %ld px (%ld over the receiver), %ld differ from the augmenter's mask (%.2f %%)\n", boom_px,
                  over_receiver, differ, 100.0 * differ / boom_px);
      const bool distorted = rig.cameras[c].model.distortion != DistortionModel::kNone;
      EXPECT_LT(differ, (distorted ? 0.02 : 0.005) * boom_px);
      if (c == 0 && !distorted) write_png(test::output_dir("sim_physical_boom") + "/left.png", with);
    }
  }
}

// Without the CPU back end's boom, the OpenGL back end says so.
TEST_F(SyntheticSceneTest, OnlyTheCpuBackEndRendersTheBoom) {
  auto r = make(Rig::paper_default(), SceneBackend::kOpenGL);
  ASSERT_TRUE(r);
  Image img;
  const auto s = r->render_with_boom(0, SkyState{}, receiver_pose(), true, BoomArticulation{}, SensorOptions{}, img);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("only the CPU back end"), std::string::npos) << s.error().message;
}

// The CPU and OpenGL back ends render the same world: the same sky and ground to within the
// filtering differences, and the receiver on the same pixels.
TEST_F(SyntheticSceneTest, BackEndsAgree) {
  for (const Rig& rig : {Rig::paper_default(), distorted_rig()}) {
    auto cpu = make(rig, SceneBackend::kCpu);
    auto gl = make(rig, SceneBackend::kOpenGL);
    ASSERT_TRUE(cpu && gl);
    for (const SkyState& sky : {SkyState{}, horizon_sky()}) {
      Image a, b, a0, b0;
      ASSERT_TRUE(cpu->render(0, sky, receiver_pose(), true, SensorOptions{}, a));
      ASSERT_TRUE(gl->render(0, sky, receiver_pose(), true, SensorOptions{}, b));
      ASSERT_TRUE(cpu->render(0, sky, receiver_pose(), false, SensorOptions{}, a0));
      ASSERT_TRUE(gl->render(0, sky, receiver_pose(), false, SensorOptions{}, b0));
      // Background: the mean colour of 32 x 32 pixel cells agrees (the texture's mip levels and the
      // woods noise are sampled differently, so single pixels may not).
      double worst = 0, sum = 0;
      int cells = 0;
      for (int cy = 0; cy + 32 <= 960; cy += 32)
        for (int cx = 0; cx + 32 <= 1280; cx += 32)
          for (int k = 0; k < 3; ++k) {
            double ma = 0, mb = 0;
            for (int y = cy; y < cy + 32; ++y)
              for (int x = cx; x < cx + 32; ++x) ma += px(a0, x, y)[k], mb += px(b0, x, y)[k];
            const double d = std::abs(ma - mb) / 1024.0;
            worst = std::max(worst, d), sum += d, ++cells;
          }
      std::printf("%s: cell means differ by %.2f DN on average, %.1f DN at most\n",
                  rig.left().model.distortion_name().c_str(), sum / cells, worst);
      EXPECT_LT(sum / cells, 3.0);
      EXPECT_LT(worst, 40.0);  // cells the horizon or the woods' edge crosses
      const std::vector<std::uint8_t> sa = silhouette(a, a0), sb = silhouette(b, b0);
      long na = 0, differ = 0;
      for (std::size_t i = 0; i < sa.size(); ++i) na += sa[i], differ += sa[i] != sb[i];
      ASSERT_GT(na, 20000);
      // OpenGL blends the silhouette's pixels under distortion (bilinear resampling of the virtual
      // image), so its silhouette is a pixel wider there (measured 4 %, 0.2 % without distortion).
      const bool distorted = rig.left().model.distortion != DistortionModel::kNone;
      EXPECT_LT(differ, (distorted ? 0.05 : 0.01) * na) << rig.left().model.distortion_name();
    }
  }
}

// A parallel stereo pair sees the ground ~10 km away with ~0.06 px of disparity: the right view
// reuses the left's background. A wide baseline makes the disparity real: then each view has its own.
TEST_F(SyntheticSceneTest, StereoPairSharesTheBackgroundOnlyWhenItsDisparityIsSubpixel) {
  Rig rig = Rig::paper_default();
  auto r = make(rig);
  ASSERT_TRUE(r);
  SensorOptions s;
  s.format = PixelFormat::kBayerRG8;
  Image left, right, right_alone;
  ASSERT_TRUE(r->render(0, horizon_sky(), receiver_pose(), false, s, left));
  ASSERT_TRUE(r->render(1, horizon_sky(), receiver_pose(), false, s, right));
  EXPECT_TRUE(pixels_equal(left, right));
  // The same right view rendered without the left before it: identical (no history).
  auto fresh = make(rig);
  ASSERT_TRUE(fresh->render(1, horizon_sky(), receiver_pose(), false, s, right_alone));
  EXPECT_TRUE(pixels_equal(right, right_alone));

  rig.cameras[1].T_body_cam.translation_m.y() = -2000.0;  // 2 km baseline: ~400 px of ground disparity
  auto wide = make(rig);
  ASSERT_TRUE(wide);
  ASSERT_TRUE(wide->render(0, horizon_sky(), receiver_pose(), false, s, left));
  ASSERT_TRUE(wide->render(1, horizon_sky(), receiver_pose(), false, s, right));
  EXPECT_FALSE(pixels_equal(left, right));
}

TEST_F(SyntheticSceneTest, ThreadsDoNotChangeTheImage) {
  for (const Rig& rig : {Rig::paper_default(), distorted_rig()}) {
    auto one = make(rig, SceneBackend::kCpu, 1);
    auto three = make(rig, SceneBackend::kCpu, 3);
    ASSERT_TRUE(one && three);
    for (PixelFormat f : {PixelFormat::kBayerGB8, PixelFormat::kRGBA8}) {
      SensorOptions s;
      s.format = f;
      s.noise_sigma = 2.0;
      s.noise_seed = 42;
      Image a, b;
      ASSERT_TRUE(one->render(1, horizon_sky(), receiver_pose(), true, s, a));
      ASSERT_TRUE(three->render(1, horizon_sky(), receiver_pose(), true, s, b));
      EXPECT_TRUE(pixels_equal(a, b)) << to_string(f);
      if (f == PixelFormat::kRGBA8) {
        for (int y = 0; y < a.height(); y += 7)
          for (int x = 0; x < a.width(); x += 5) ASSERT_EQ(px(a, x, y)[3], 255);
      }
    }
  }
  SceneRendererOptions bad;
  bad.threads = 0;
  EXPECT_FALSE(SyntheticSceneRenderer::create(Rig::paper_default(), nullptr, bad));
}

// The AVX2 ground blocks (eight pixels a step) give the bytes of the SSE2 ones, in every output
// format, for ground seen near (finest levels, woods) and far (coarse levels, haze), with a lens.
TEST_F(SyntheticSceneTest, Avx2GroundBlocksAreTheSse2Ones) {
  struct Restore {
    ~Restore() { set_cpu_scene_avx2_for_testing(true); }
  } restore;
  if (!set_cpu_scene_avx2_for_testing(true)) GTEST_SKIP() << "no AVX2 path on this CPU or compiler";
  SkyState down;  // level flight at 7000 m: ground only, woods near and far
  down.altitude_m = 7000.0;
  down.north_east_m = {1234.5, -678.9};
  down.R_ned_body = rotation_from_ypr(deg_to_rad(30.0), deg_to_rad(2.0), deg_to_rad(1.0));
  for (const Rig& rig : {Rig::paper_default(), distorted_rig()}) {
    // Two renderers: one would reuse its own background for a second render of the same frame.
    auto a = make(rig, SceneBackend::kCpu, 1), b = make(rig, SceneBackend::kCpu, 1);
    ASSERT_TRUE(a && b);
    for (const SkyState& sky : {down, horizon_sky()})
      for (PixelFormat f : {PixelFormat::kBayerRG8, PixelFormat::kMono8, PixelFormat::kRGB8, PixelFormat::kRGBA8}) {
        SensorOptions s;
        s.format = f;
        Image avx2, sse2;
        ASSERT_TRUE(set_cpu_scene_avx2_for_testing(true));
        ASSERT_TRUE(a->render(0, sky, receiver_pose(), true, s, avx2));
        ASSERT_FALSE(set_cpu_scene_avx2_for_testing(false));
        ASSERT_TRUE(b->render(0, sky, receiver_pose(), true, s, sse2));
        EXPECT_TRUE(pixels_equal(avx2, sse2))
            << to_string(f) << (rig.cameras[0].model.distortion == DistortionModel::kRadTan ? " radtan" : " none");
      }
  }
}

// The noise of neighbouring rows, of the two cameras and of successive frames is uncorrelated.
TEST_F(SyntheticSceneTest, NoiseIsUncorrelatedBetweenRowsCamerasAndFrames) {
  const Rig rig = Rig::paper_default();
  auto r = make(rig);
  ASSERT_TRUE(r);
  SensorOptions s;
  s.format = PixelFormat::kMono8;
  Image clean[2];
  ASSERT_TRUE(r->render(0, SkyState{}, receiver_pose(), false, s, clean[0]));
  ASSERT_TRUE(r->render(1, SkyState{}, receiver_pose(), false, s, clean[1]));
  s.noise_sigma = 4.0;
  auto noise = [&](int camera, std::uint64_t seed) {
    s.noise_seed = seed;
    Image img;
    EXPECT_TRUE(r->render(camera, SkyState{}, receiver_pose(), false, s, img));
    std::vector<double> n(static_cast<std::size_t>(img.width()) * img.height());
    for (int y = 0; y < img.height(); ++y)
      for (int x = 0; x < img.width(); ++x)
        n[static_cast<std::size_t>(y) * img.width() + x] = img.row(y)[x] - clean[camera].row(y)[x];
    return n;
  };
  auto corr = [](const std::vector<double>& a, const std::vector<double>& b, std::size_t shift) {
    double ab = 0, aa = 0, bb = 0;
    for (std::size_t i = 0; i + shift < a.size(); ++i) ab += a[i] * b[i + shift], aa += a[i] * a[i], bb += b[i] * b[i];
    return ab / std::sqrt(aa * bb);
  };
  const std::vector<double> f0 = noise(0, 1), f1 = noise(0, 2), right = noise(1, 1);
  EXPECT_LT(std::abs(corr(f0, f0, 1280)), 0.01);  // the row below
  EXPECT_LT(std::abs(corr(f0, f0, 1)), 0.01);     // the pixel to the right
  EXPECT_LT(std::abs(corr(f0, f1, 0)), 0.01);     // the next frame
  EXPECT_LT(std::abs(corr(f0, right, 0)), 0.01);  // the other camera
}

TEST_F(SyntheticSceneTest, RenderTimeAndSamples) {
  const Rig rig = Rig::paper_default();
  auto r = make(rig);
  ASSERT_TRUE(r);
  const std::string dir = test::output_dir("sim_scene");
  Image img;
  for (int c = 0; c < 2; ++c) {
    ASSERT_TRUE(r->render(c, horizon_sky(), receiver_pose(), true, SensorOptions{}, img));
    write_png(dir + "/horizon_" + std::to_string(c) + ".png", img);
  }
  SensorOptions bayer;
  bayer.format = PixelFormat::kBayerRG8;
  bayer.noise_sigma = 2.0;
  for (const auto& [name, sensor] : {std::pair{"rgb", SensorOptions{}}, std::pair{"bayer+noise", bayer}}) {
    const int n = 6;
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < n; ++i) ASSERT_TRUE(r->render(i % 2, SkyState{}, receiver_pose(), true, sensor, img));
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / n;
    std::printf("SyntheticSceneRenderer: %s 1280x960 view: %.1f ms\n", name, ms);
    EXPECT_LT(ms, 1000.0);  // generous: shared CI machines; the demo needs a few tens of ms
  }
  ASSERT_TRUE(r->render(0, SkyState{}, receiver_pose(), true, SensorOptions{}, img));
  write_png(dir + "/level_left.png", img);
}

// ---- The boom's shadow on the receiver (render_with_boom) against an independent ray cast ----

// A triangle of the scene in the camera frame, with its vertex normals (camera frame).
struct CamTri {
  Eigen::Vector3d p[3], n[3];
};

// Möller–Trumbore: the ray o + t d (t > t_min) through the triangle; u, v the weights of p[1], p[2].
bool ray_triangle(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const CamTri& tri, double t_min,
                  double& t, double& u, double& v) {
  const Eigen::Vector3d e1 = tri.p[1] - tri.p[0], e2 = tri.p[2] - tri.p[0], h = d.cross(e2);
  const double det = e1.dot(h);
  if (std::abs(det) < 1e-14 * e1.norm() * e2.norm() * d.norm()) return false;
  const double f = 1.0 / det;
  const Eigen::Vector3d s = o - tri.p[0];
  u = f * s.dot(h);
  if (u < 0 || u > 1) return false;
  const Eigen::Vector3d q = s.cross(e1);
  v = f * d.dot(q);
  if (v < 0 || u + v > 1) return false;
  t = f * e2.dot(q);
  return t > t_min;
}

// The triangles binned by the 2D bounding box of their vertices under `proj` (a perspective or a
// parallel projection, under which a triangle's image is the triangle of its vertices' images):
// the candidates for a ray are those of its cell. Triangles `proj` cannot map are always candidates.
class TriBins {
 public:
  TriBins(const std::vector<CamTri>& tris,
          const std::function<std::optional<Eigen::Vector2d>(const Eigen::Vector3d&)>& proj)
      : proj_(proj) {
    std::vector<std::array<Eigen::Vector2d, 2>> boxes(tris.size());
    std::vector<bool> mapped(tris.size(), true);
    for (std::size_t i = 0; i < tris.size(); ++i) {
      boxes[i] = {Eigen::Vector2d::Constant(1e300), Eigen::Vector2d::Constant(-1e300)};
      for (const Eigen::Vector3d& p : tris[i].p) {
        const auto q = proj(p);
        if (!q) {
          mapped[i] = false;
          break;
        }
        boxes[i][0] = boxes[i][0].cwiseMin(*q), boxes[i][1] = boxes[i][1].cwiseMax(*q);
      }
      if (!mapped[i]) {
        always_.push_back(static_cast<int>(i));
        continue;
      }
      lo_ = lo_.cwiseMin(boxes[i][0]), hi_ = hi_.cwiseMax(boxes[i][1]);
    }
    cell_ = std::max((hi_ - lo_).maxCoeff() / kCells, 1e-9);
    cells_.resize(kCells * kCells);
    for (std::size_t i = 0; i < tris.size(); ++i) {
      if (!mapped[i]) continue;
      const auto [i0, j0] = index(boxes[i][0]);
      const auto [i1, j1] = index(boxes[i][1]);
      for (int j = j0; j <= j1; ++j)
        for (int k = i0; k <= i1; ++k)
          cells_[static_cast<std::size_t>(j) * kCells + k].push_back(static_cast<int>(i));
    }
  }
  // fn(triangle index) for the candidates of the ray whose image under proj is that of `p`.
  template <class Fn>
  void candidates(const Eigen::Vector3d& p, Fn&& fn) const {
    for (const int i : always_) fn(i);
    const auto q = proj_(p);
    if (!q || (q->array() < lo_.array()).any() || (q->array() > hi_.array()).any()) return;
    const auto [i, j] = index(*q);
    for (const int t : cells_[static_cast<std::size_t>(j) * kCells + i]) fn(t);
  }

 private:
  static constexpr int kCells = 96;
  std::pair<int, int> index(const Eigen::Vector2d& q) const {
    return {std::clamp(static_cast<int>((q.x() - lo_.x()) / cell_), 0, kCells - 1),
            std::clamp(static_cast<int>((q.y() - lo_.y()) / cell_), 0, kCells - 1)};
  }
  std::function<std::optional<Eigen::Vector2d>(const Eigen::Vector3d&)> proj_;
  Eigen::Vector2d lo_ = Eigen::Vector2d::Constant(1e300), hi_ = Eigen::Vector2d::Constant(-1e300);
  double cell_ = 1;
  std::vector<std::vector<int>> cells_;
  std::vector<int> always_;
};

// A model's triangles placed by T_cam_obj.
void add_triangles(const Model& model, const Pose& T_cam_obj, std::vector<CamTri>& out) {
  for (const Mesh& m : model.meshes)
    for (std::size_t k = 0; k + 2 < m.indices.size(); k += 3) {
      CamTri t;
      for (int j = 0; j < 3; ++j) {
        const std::uint32_t i = m.indices[k + static_cast<std::size_t>(j)];
        t.p[j] = T_cam_obj * m.positions_m[i].cast<double>();
        t.n[j] = i < m.normals.size() ? Eigen::Vector3d(T_cam_obj.R() * m.normals[i].cast<double>())
                                      : Eigen::Vector3d::Zero();
      }
      out.push_back(t);
    }
}

// What a raw pixel's centre ray sees, by ray casting: nothing, the boom, or the receiver lit or
// in the boom's shadow (the ray from its surface point towards the sun crosses a boom triangle).
enum class Seen : std::uint8_t { kNothing, kBoom, kLit, kShade };
struct PixelOracle {
  Seen seen = Seen::kNothing;
  int tri = -1;         // the receiver triangle hit
  double u = 0, v = 0;  // the hit's weights of its vertices 1 and 2
  // kBoom: the boom's surface point faces the sun and sees it through another boom triangle.
  bool boom_self_shade = false;
};

// The oracle of one camera: the receiver and the boom (at `boom`) as the renderer places them,
// and the sky's sun (the shadow's geometry only, above the horizon or not).
class ShadowOracle {
 public:
  ShadowOracle(const Rig& rig, int camera, const SkyState& sky, const Pose& T_body_receiver,
               const BoomArticulation& boom)
      : cam_(rig.cameras[camera]), vp_(make_virtual_pinhole(cam_.model).value()) {
    const Pose T_cam_body = cam_.T_body_cam.inverse();
    add_triangles(make_builtin_receiver(), T_cam_body * T_body_receiver, receiver_);
    const BoomModel bm = make_builtin_boom();
    const Pose T_body_fixed = boom_pose(rig.boom.pivot_body_m, boom);
    add_triangles(bm.fixed, T_cam_body * T_body_fixed, boom_);
    add_triangles(bm.telescope, T_cam_body * T_body_fixed * telescope_pose(boom), boom_);
    const Eigen::Matrix3d R_cam_ned = (sky.R_ned_body * cam_.T_body_cam.R()).transpose();
    sun_cam_ = (R_cam_ned * sky.sun_ned).normalized();
    up_cam_ = R_cam_ned * Eigen::Vector3d(0, 0, -1);
    auto perspective = [](const Eigen::Vector3d& p) -> std::optional<Eigen::Vector2d> {
      if (!(p.z() > 0.05)) return std::nullopt;
      return Eigen::Vector2d(p.x() / p.z(), p.y() / p.z());
    };
    const Eigen::Vector3d e1 = sun_cam_.unitOrthogonal(), e2 = sun_cam_.cross(e1);
    auto along_sun = [e1, e2](const Eigen::Vector3d& p) -> std::optional<Eigen::Vector2d> {
      return Eigen::Vector2d(e1.dot(p), e2.dot(p));
    };
    receiver_bins_ = std::make_unique<TriBins>(receiver_, perspective);
    boom_bins_ = std::make_unique<TriBins>(boom_, perspective);
    shadow_bins_ = std::make_unique<TriBins>(boom_, along_sun);
  }

  PixelOracle at(int x, int y) const {
    PixelOracle o;
    const Eigen::Vector2f& r = vp_.ray_xy[static_cast<std::size_t>(y) * cam_.model.width_px + x];
    if (!std::isfinite(r.x()) || !std::isfinite(r.y())) return o;
    const Eigen::Vector3d d(r.x(), r.y(), 1.0), origin = Eigen::Vector3d::Zero();
    double t_receiver = 1e300, t_boom = 1e300, t, u, v;
    receiver_bins_->candidates(d, [&](int i) {
      if (ray_triangle(origin, d, receiver_[static_cast<std::size_t>(i)], 0.0, t, u, v) && t < t_receiver)
        t_receiver = t, o.tri = i, o.u = u, o.v = v;
    });
    int boom_tri = -1;
    boom_bins_->candidates(d, [&](int i) {
      if (ray_triangle(origin, d, boom_[static_cast<std::size_t>(i)], 0.0, t, u, v) && t < t_boom)
        t_boom = t, boom_tri = i;
    });
    if (t_boom < t_receiver) {
      o.seen = Seen::kBoom;
      const CamTri& tri = boom_[static_cast<std::size_t>(boom_tri)];
      const Eigen::Vector3d p = t_boom * d, n = (tri.p[1] - tri.p[0]).cross(tri.p[2] - tri.p[0]);
      if (n.dot(sun_cam_) * n.dot(d) < 0)  // the side the camera sees faces the sun
        shadow_bins_->candidates(p, [&](int i) {
          o.boom_self_shade =
              o.boom_self_shade ||
              (i != boom_tri && ray_triangle(p, sun_cam_, boom_[static_cast<std::size_t>(i)], 1e-6, t, u, v));
        });
    } else if (o.tri >= 0) {
      const Eigen::Vector3d p = t_receiver * d;
      bool shade = false;
      shadow_bins_->candidates(p, [&](int i) {
        shade = shade || ray_triangle(p, sun_cam_, boom_[static_cast<std::size_t>(i)], 1e-6, t, u, v);
      });
      o.seen = shade ? Seen::kShade : Seen::kLit;
    }
    return o;
  }

  // The renderer's light at a receiver hit (CPU back end, the fixed ambient of SkyState), per
  // channel: the sun's diffuse term and the hemispherical ambient, interpolated from the vertices.
  void light(const PixelOracle& o, Eigen::Vector3d& direct, Eigen::Vector3d& ambient) const {
    const CamTri& tri = receiver_[static_cast<std::size_t>(o.tri)];
    // A back face seen is lit from its other side.
    const double side = tri.p[0].dot(tri.p[1].cross(tri.p[2])) > 0 ? -1.0 : 1.0;
    const Eigen::Vector3d sky(0.36, 0.40, 0.46), ground(0.22, 0.22, 0.20), sun_colour(1.0, 0.97, 0.92);
    const double w[3] = {1 - o.u - o.v, o.u, o.v};
    direct.setZero(), ambient.setZero();
    for (int j = 0; j < 3; ++j) {
      const Eigen::Vector3d n = side * tri.n[j];
      direct += w[j] * 0.75 * std::max(n.dot(sun_cam_), 0.0) * sun_colour;
      ambient += w[j] * (ground + (0.5 + 0.5 * n.dot(up_cam_)) * (sky - ground));
    }
  }

 private:
  const RigCamera& cam_;
  VirtualPinhole vp_;
  std::vector<CamTri> receiver_, boom_;
  Eigen::Vector3d sun_cam_, up_cam_;
  std::unique_ptr<TriBins> receiver_bins_, boom_bins_, shadow_bins_;
};

// The oracle every 2 px over the receiver's box; a pixel counts only where the 8 samples around
// it (2 px away) see what it sees: >= 2 px from the boom's and the shadow's edges and the silhouettes.
struct OracleGrid {
  int x0 = 0, y0 = 0, nx = 0, ny = 0;
  std::vector<PixelOracle> at;
  template <class Fn>
  void interior(Fn&& fn) const {
    for (int j = 1; j + 1 < ny; ++j)
      for (int i = 1; i + 1 < nx; ++i) {
        const PixelOracle& o = at[static_cast<std::size_t>(j) * nx + i];
        bool same = true;
        for (int dj = -1; dj <= 1 && same; ++dj)
          for (int di = -1; di <= 1 && same; ++di)
            same = at[static_cast<std::size_t>(j + dj) * nx + i + di].seen == o.seen;
        if (same) fn(x0 + 2 * i, y0 + 2 * j, o);
      }
  }
};
OracleGrid oracle_grid(const ShadowOracle& oracle, const Box& b, int width, int height) {
  OracleGrid g;
  g.x0 = std::max(0, static_cast<int>(b.u0) - 4), g.y0 = std::max(0, static_cast<int>(b.v0) - 4);
  const int x1 = std::min(width, static_cast<int>(b.u1) + 5),
            y1 = std::min(height, static_cast<int>(b.v1) + 5);
  g.nx = (x1 - g.x0 + 1) / 2, g.ny = (y1 - g.y0 + 1) / 2;
  g.at.resize(static_cast<std::size_t>(g.nx) * g.ny);
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i)
      g.at[static_cast<std::size_t>(j) * g.nx + i] = oracle.at(g.x0 + 2 * i, g.y0 + 2 * j);
  return g;
}

// Near contact, the boom over the receiver's nose in both views (as the test above).
const BoomArticulation kShadowBoom{deg_to_rad(30.0), deg_to_rad(2.0), 3.0};
Pose shadow_receiver_pose() {
  return Pose::from(Eigen::Matrix3d::Identity(), {-16.0, 0.3, 11.0});
}

// The sun 60 deg up, ahead of a level tanker (heading north) and a little to the right: the boom's
// shadow falls on the receiver's nose behind the boom, in view of both cameras.
SkyState shadow_sky() {
  SkyState sky;
  sky.sun_ned = Eigen::Vector3d(0.5, 0.1, -0.86).normalized();
  return sky;
}

// With the boom physically in the scene, a receiver pixel whose surface point sees the sun through
// a boom triangle (an independent ray cast: Möller–Trumbore over the boom's and the receiver's
// triangles) is lit by the ambient light alone: the boom-free render's pixel times
// ambient / (ambient + direct) of the renderer's Gouraud light (computed here from the vertex
// normals), and exactly the pixel a render without the sun gives; every other receiver pixel is
// the boom-free render's. Pixels within 2 px of the boom's or the shadow's edge are not judged.
TEST_F(SyntheticSceneTest, PhysicalBoomShadowsTheReceiverWhereARayCastSaysSo) {
  const SkyState sky = shadow_sky();
  SkyState night = sky;  // the same view lit by the sky and the ground alone
  night.sun_ned.z() = -night.sun_ned.z();
  for (const Rig& rig : {Rig::paper_default(), distorted_rig()}) {
    auto r = make(rig);
    ASSERT_TRUE(r);
    for (int c = 0; c < 2; ++c) {
      const bool distorted = rig.cameras[c].model.distortion != DistortionModel::kNone;
      SCOPED_TRACE(rig.cameras[c].model.distortion_name() + " camera " + std::to_string(c));
      Image with, without, ambient, alone;
      ASSERT_TRUE(
          r->render_with_boom(c, sky, shadow_receiver_pose(), true, kShadowBoom, SensorOptions{}, with));
      // The boom without the receiver: no shadow to cast, the boom as it is lit.
      ASSERT_TRUE(
          r->render_with_boom(c, sky, shadow_receiver_pose(), false, kShadowBoom, SensorOptions{}, alone));
      ASSERT_TRUE(r->render(c, sky, shadow_receiver_pose(), true, SensorOptions{}, without));
      ASSERT_TRUE(r->render(c, night, shadow_receiver_pose(), true, SensorOptions{}, ambient));
      const ShadowOracle oracle(rig, c, sky, shadow_receiver_pose(), kShadowBoom);
      const OracleGrid grid =
          oracle_grid(oracle, project_model(make_builtin_receiver(), rig.cameras[c], shadow_receiver_pose()),
                      with.width(), with.height());
      long lit = 0, lit_changed = 0, shade = 0, shade_not_ambient = 0, facing = 0, facing_not_darker = 0;
      long ratio_checked = 0, ratio_off = 0, boom = 0, boom_changed = 0, boom_self_shade = 0;
      double worst = 0;
      grid.interior([&](int x, int y, const PixelOracle& o) {
        const std::uint8_t* w = px(with, x, y);
        const std::uint8_t* b = px(without, x, y);
        if (o.seen == Seen::kBoom) {  // the boom shades the receiver only, not itself
          ++boom, boom_self_shade += o.boom_self_shade;
          boom_changed += std::memcmp(w, px(alone, x, y), 3) != 0;
          return;
        }
        if (o.seen == Seen::kLit) {
          ++lit;
          lit_changed += std::memcmp(w, b, 3) != 0;
          return;
        }
        if (o.seen != Seen::kShade) return;
        ++shade;
        shade_not_ambient += std::memcmp(w, px(ambient, x, y), 3) != 0;
        Eigen::Vector3d direct, amb;
        oracle.light(o, direct, amb);
        bool darker = true;
        for (int k = 0; k < 3; ++k) {
          darker = darker && w[k] < b[k];
          if (b[k] == 255) continue;  // clipped: the light is not known
          // Both renders round: the shadowed value is within 0.5 (1 + ratio) of the ratio's.
          const double err = std::abs(w[k] - b[k] * amb[k] / (amb[k] + direct[k]));
          worst = std::max(worst, err), ++ratio_checked, ratio_off += err > 1.25;
        }
        // Facing the sun enough to lose a quarter of its light, and bright enough to show it.
        if ((direct.array() > 0.25 * (amb + direct).array()).all() && std::min({b[0], b[1], b[2]}) >= 20)
          ++facing, facing_not_darker += !darker;
      });
      std::printf(
          "%s camera %d, every 2nd pixel: receiver %ld lit, %ld in the boom's shadow (%ld facing the sun), "
          "ratio within %.2f DN; boom %ld (%ld facing the sun through the boom)\n",
          rig.cameras[c].model.distortion_name().c_str(), c, lit, shade, facing, worst, boom,
          boom_self_shade);
      // Enough of each (every 2nd pixel in x and y) that the test cannot pass by seeing none.
      ASSERT_GT(lit, 10000);
      ASSERT_GT(shade, 500);
      ASSERT_GT(facing, 300);
      EXPECT_EQ(lit_changed, 0);
      EXPECT_EQ(shade_not_ambient, 0);
      EXPECT_EQ(facing_not_darker, 0);
      EXPECT_GT(ratio_checked, 3 * 500);
      EXPECT_EQ(ratio_off, 0) << "worst " << worst << " DN";
      ASSERT_GT(boom, 2000);
      EXPECT_EQ(boom_changed, 0);
      if (c == 0) {
        // The shading per Bayer site is the RGB render's (the shadow's path for each output format).
        SensorOptions bayer;
        bayer.format = PixelFormat::kBayerGB8;
        Image raw;
        ASSERT_TRUE(r->render_with_boom(c, sky, shadow_receiver_pose(), true, kShadowBoom, bayer, raw));
        long bad = 0;
        for (int y = 0; y < raw.height(); ++y)
          for (int x = 0; x < raw.width(); ++x)
            bad += raw.row(y)[x] != px(with, x, y)[bayer_channel(bayer.format, x, y)];
        EXPECT_EQ(bad, 0);
        if (!distorted) write_png(test::output_dir("sim_boom_shadow") + "/left.png", with);
      }
    }
  }
  // What the shadow costs: the boom rendered under the sun and without it (no shadow to test).
  const Rig rig = Rig::paper_default();
  auto r = make(rig);
  ASSERT_TRUE(r);
  Image img;
  for (const auto& [name, s] : {std::pair{"sun (the shadow)", sky}, std::pair{"no sun (no shadow)", night}}) {
    const int n = 20;
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < n; ++i)
      ASSERT_TRUE(
          r->render_with_boom(i % 2, s, shadow_receiver_pose(), true, kShadowBoom, SensorOptions{}, img));
    std::printf("render_with_boom, %s: %.2f ms a view\n", name,
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / n);
  }
}

// A sun below the horizon lights nothing directly, so the boom shades nothing: in inverted flight
// (rolled 180 deg) the sun is where it was in the body frame, the shadow's geometry the same as
// above, but below the horizon; every receiver pixel the boom does not cover is the boom-free one.
TEST_F(SyntheticSceneTest, PhysicalBoomCastsNoShadowWithTheSunBelowTheHorizon) {
  const SkyState up = shadow_sky();
  SkyState down = up;
  const Eigen::Matrix3d roll180 = Eigen::Vector3d(1, -1, -1).asDiagonal();
  down.R_ned_body = up.R_ned_body * roll180;
  down.sun_ned = down.R_ned_body * up.R_ned_body.transpose() * up.sun_ned;
  ASSERT_GT(down.sun_ned.z(), 0.4);
  for (const Rig& rig : {Rig::paper_default(), distorted_rig()}) {
    auto r = make(rig);
    ASSERT_TRUE(r);
    for (int c = 0; c < 2; ++c) {
      SCOPED_TRACE(rig.cameras[c].model.distortion_name() + " camera " + std::to_string(c));
      Image with, without;
      ASSERT_TRUE(
          r->render_with_boom(c, down, shadow_receiver_pose(), true, kShadowBoom, SensorOptions{}, with));
      ASSERT_TRUE(r->render(c, down, shadow_receiver_pose(), true, SensorOptions{}, without));
      const ShadowOracle oracle(rig, c, down, shadow_receiver_pose(), kShadowBoom);
      const OracleGrid grid =
          oracle_grid(oracle, project_model(make_builtin_receiver(), rig.cameras[c], shadow_receiver_pose()),
                      with.width(), with.height());
      long lit = 0, shade = 0, changed = 0;
      grid.interior([&](int x, int y, const PixelOracle& o) {
        if (o.seen != Seen::kLit && o.seen != Seen::kShade) return;
        (o.seen == Seen::kLit ? lit : shade)++;
        changed += std::memcmp(px(with, x, y), px(without, x, y), 3) != 0;
      });
      ASSERT_GT(lit, 10000);
      ASSERT_GT(shade, 500);  // the boom would shade these under a sun above the horizon
      EXPECT_EQ(changed, 0);
    }
  }
}

// ---- The boom's finish (render/pbr.hpp): the same glint in the physical and the augmented boom ----

// The outer tube's vertex, about `along_m` from the pivot, that faces camera `c` most, in the body
// frame (position, unit normal), for the boom at `a`.
std::pair<Eigen::Vector3d, Eigen::Vector3d> tube_vertex_facing(const Rig& rig, const BoomArticulation& a,
                                                               int c, double along_m) {
  const BoomModel boom = make_builtin_boom();
  const Pose T_body_boom = boom_pose(rig.boom.pivot_body_m, a);
  const Eigen::Vector3d cam = rig.cameras[c].T_body_cam.translation_m;
  std::pair<Eigen::Vector3d, Eigen::Vector3d> best;
  double best_nv = -2;
  for (const Mesh& m : boom.fixed.meshes) {
    if (m.name != "outer_tube") continue;
    for (std::size_t i = 0; i < m.positions_m.size(); ++i) {
      if (std::abs(m.positions_m[i].x() - along_m) > 0.8) continue;
      const Eigen::Vector3d p = T_body_boom * m.positions_m[i].cast<double>();
      const Eigen::Vector3d n = (T_body_boom.R() * m.normals[i].cast<double>()).normalized();
      if (const double nv = n.dot((cam - p).normalized()); nv > best_nv) best_nv = nv, best = {p, n};
    }
  }
  return best;
}

// The finish is one model in the simulator's physical boom and the augmenter's camera look (per
// vertex, render/pbr.hpp): a glossy boom under a sun that the outer tube mirrors into the left
// camera glints, in both renders, where the mirror geometry says, and the two booms' pixels agree.
// The glint is the glossy boom's excess over a matte twin's (roughness 1).
TEST_F(SyntheticSceneTest, PhysicalAndAugmentedBoomsGlintAtTheSamePlace) {
  const BoomArticulation art{deg_to_rad(30.0), 0.0, 2.0};
  Rig rig = Rig::paper_default();
  const auto [p, n] = tube_vertex_facing(rig, art, 0, 4.0);
  const Eigen::Vector3d v = (rig.cameras[0].T_body_cam.translation_m - p).normalized();
  const Eigen::Vector3d l = 2 * n.dot(v) * n - v;
  // The cameras see the boom's underside: its mirror images of the sky lie below the wings' plane.
  // The tanker inverted (rolled 180 deg) puts that sun above the horizon.
  SkyState sky;
  sky.R_ned_body = Eigen::Vector3d(1, -1, -1).asDiagonal();
  sky.sun_ned = sky.R_ned_body * l;
  ASSERT_LT(sky.sun_ned.z(), -0.2) << "the sun is up";
  // The simulator's light (sim/synthetic_scene_cpu.cpp) as the augmenter's SceneLight.
  SceneState scene;
  scene.boom = art;
  scene.receiver_present = false;
  scene.light = SceneLight::sun(l, true, LightSource::kConfigured,
                                sky.R_ned_body.transpose() * Eigen::Vector3d::UnitZ());
  scene.light.direct = Eigen::Vector3d(1.0, 0.97, 0.92) * 0.75;
  scene.light.sky = Eigen::Vector3d(0.36, 0.40, 0.46), scene.light.ground = Eigen::Vector3d(0.22, 0.22, 0.20);
  AugmentOptions ao;
  ao.rasterizer = Rasterizer::kCpu;
  ao.look = Look::kCamera;
  CameraLookParams lp;
  lp.psf_sigma_px = 0;  // no blur, no noise: the shading alone
  ao.camera_looks = {lp, lp};
  const Pose T_cam_body = rig.cameras[0].T_body_cam.inverse();
  const auto glint_px = rig.cameras[0].model.project(T_cam_body * p);
  ASSERT_TRUE(glint_px);
  // Left view: the simulator's render and the augmented boom-free render, glossy and matte.
  Image phys[2], aug[2], mask;
  for (int k = 0; k < 2; ++k) {
    rig.boom.material = SurfaceFinish{0.0, k == 0 ? 0.3 : 1.0};
    auto r = make(rig);
    ASSERT_TRUE(r);
    Image without;
    ASSERT_TRUE(r->render_with_boom(0, sky, Pose{}, false, art, SensorOptions{}, phys[k]));
    ASSERT_TRUE(r->render(0, sky, Pose{}, false, SensorOptions{}, without));
    auto a = Augmenter::create(rig, ao);
    ASSERT_TRUE(a) << a.error().message;
    Frame raw;
    raw.image = without;
    raw.camera = CameraId::kLeft;
    ViewResult vr;
    ASSERT_TRUE((*a)->augment_view(0, raw, scene, vr));
    aug[k] = vr.augmented;
    mask = vr.mask;
  }
  const std::string dir = test::output_dir("sim_glint");
  write_png(dir + "/physical_glossy.png", phys[0]), write_png(dir + "/physical_matte.png", phys[1]);
  write_png(dir + "/augmented_glossy.png", aug[0]);
  // Over the boom's interior (boom all around: no silhouette pixel): the glint, and the pixels.
  const int W = mask.width(), H = mask.height();
  auto lum = [](const Image& im, int x, int y) {
    const std::uint8_t* q = im.row(y) + 3 * x;
    return (q[0] + q[1] + q[2]) / 3.0;
  };
  // Per render: the largest glint near the mirror vertex's pixel, the mean glint over the interior,
  // and the centroid of where it is above half the physical glint's peak. (The glint is a line along
  // the tube, where its normals mirror the sun into the camera, brightest at grazing angles near the
  // fairing: test-output/sim_glint/.)
  struct Glint {
    double at_vertex = 0, peak = 0, sum = 0, cx = 0, cy = 0, w = 0;
  } g[2];
  std::vector<std::array<double, 2>> glint;
  std::vector<std::pair<int, int>> where;
  double sum_abs = 0, glint_abs = 0;
  for (int y = 1; y + 1 < H; ++y)
    for (int x = 1; x + 1 < W; ++x) {
      bool all_boom = true;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) all_boom &= (mask.row(y + dy)[x + dx] & kMaskBoom) != 0;
      if (!all_boom) continue;
      sum_abs += std::abs(lum(aug[0], x, y) - lum(phys[0], x, y));
      glint.push_back({lum(phys[0], x, y) - lum(phys[1], x, y), lum(aug[0], x, y) - lum(aug[1], x, y)});
      where.emplace_back(x, y);
      glint_abs += std::abs(glint.back()[0] - glint.back()[1]);
      const bool near_vertex = std::abs(x - glint_px->x()) <= 3 && std::abs(y - glint_px->y()) <= 3;
      for (int i = 0; i < 2; ++i) {
        g[i].peak = std::max(g[i].peak, glint.back()[i]), g[i].sum += glint.back()[i];
        if (near_vertex) g[i].at_vertex = std::max(g[i].at_vertex, glint.back()[i]);
      }
    }
  const auto interior = static_cast<double>(std::max<std::size_t>(glint.size(), 1));
  for (std::size_t k = 0; k < glint.size(); ++k)
    for (int i = 0; i < 2; ++i)
      if (glint[k][i] > 0.5 * g[0].peak) g[i].cx += where[k].first, g[i].cy += where[k].second, g[i].w += 1;
  for (int i = 0; i < 2; ++i) g[i].cx /= std::max(g[i].w, 1.0), g[i].cy /= std::max(g[i].w, 1.0);
  std::printf(
      "glint (glossy over matte) near the mirror vertex (%.1f, %.1f): physical %.1f DN, augmented %.1f DN; "
      "peaks %.1f and %.1f DN, their regions above half the physical peak: centroids (%.1f, %.1f) and (%.1f, "
      "%.1f); boom "
      "interior %zu px: mean glint %.2f and %.2f DN, mean |augmented - physical| %.2f DN (glint %.2f DN)\n",
      glint_px->x(), glint_px->y(), g[0].at_vertex, g[1].at_vertex, g[0].peak, g[1].peak, g[0].cx, g[0].cy,
      g[1].cx, g[1].cy, glint.size(), g[0].sum / interior, g[1].sum / interior, sum_abs / interior,
      glint_abs / interior);
  ASSERT_GT(glint.size(), 5000u);
  for (int i = 0; i < 2; ++i) {
    SCOPED_TRACE(i ? "augmented" : "physical");
    EXPECT_GT(g[i].at_vertex, 40.0);
    EXPECT_GT(g[i].at_vertex, 3 * g[i].sum / interior) << "a glint, not a sheen all over";
  }
  EXPECT_NEAR(g[1].at_vertex, g[0].at_vertex, 3.0);
  EXPECT_NEAR(g[1].cx, g[0].cx, 2.0);
  EXPECT_NEAR(g[1].cy, g[0].cy, 2.0);
  EXPECT_LT(glint_abs / interior, 1.0);
  EXPECT_LT(sum_abs / interior, 2.0);
}

// Motion blur: a boom moving over a 10 ms exposure, rendered physically (the scene at sub-exposure
// instants, the radiance averaged before the camera's PSF) and augmented by the camera look (its
// layer averaged over the same instants, then the PSF) into the boom-free frame, under the
// simulator's own light: they agree over the boom and its trail as the still booms do, within
// bench_look's goals (the mean within 2 DN, the edges within 0.3 px), and what the motion changes
// in one it changes in the other.
TEST_F(SyntheticSceneTest, PhysicalAndAugmentedBoomsBlurAlike) {
  const Rig rig = Rig::paper_default();
  auto r = make(rig);
  ASSERT_TRUE(r);
  const SkyState sky;  // level, the default sun above the horizon
  SceneState scene;
  scene.boom = {deg_to_rad(30.0), deg_to_rad(2.0), 2.0};
  scene.receiver_present = false;
  scene.light = SceneLight::sun(sky.R_ned_body.transpose() * sky.sun_ned, true, LightSource::kConfigured);
  scene.light.direct = Eigen::Vector3d(1.0, 0.97, 0.92) * 0.75;
  scene.light.sky = Eigen::Vector3d(0.36, 0.40, 0.46), scene.light.ground = Eigen::Vector3d(0.22, 0.22, 0.20);
  const BoomArticulation rate{0.3, 0.5, 0.0};  // swinging across the cameras: its long edges blur
  SensorOptions sensor;
  sensor.psf_sigma_px = 0.8;
  sensor.exposure_ms = 10.0;
  AugmentOptions ao;
  ao.rasterizer = Rasterizer::kCpu;
  ao.look = Look::kCamera;
  CameraLookParams lp;
  lp.psf_sigma_px = 0.8;
  lp.exposure_ms = 10.0;
  ao.camera_looks = {lp, lp};
  auto aug = Augmenter::create(rig, ao);
  ASSERT_TRUE(aug) << aug.error().message;
  const int c = 0;
  Image without, phys_still, phys_moving;
  ASSERT_TRUE(r->render(c, sky, Pose{}, false, sensor, without));
  ASSERT_TRUE(r->render_with_boom(c, sky, Pose{}, false, scene.boom, sensor, phys_still));
  ASSERT_TRUE(r->render_with_boom(c, sky, Pose{}, false, scene.boom, rate, sensor, phys_moving));
  EXPECT_FALSE(pixels_equal(phys_still, phys_moving));
  Frame raw;
  raw.image = without;
  raw.camera = CameraId::kLeft;
  ViewResult still, moving;
  ASSERT_TRUE((*aug)->augment_view(c, raw, scene, still));
  SceneState moved = scene;
  moved.boom_rate_per_s = rate;
  ASSERT_TRUE((*aug)->augment_view(c, raw, moved, moving));
  const double trail_px =
      boom_motion_px((*aug)->boom_model(), rig.boom.pivot_body_m, rig.cameras[c], scene.boom, rate, 0.01);
  EXPECT_GT(trail_px, 3.0);
  EXPECT_TRUE(pixels_equal(still.mask, moving.mask));
  // The region: the boom's mask widened by its trail and the PSF's reach.
  const int grow = static_cast<int>(std::ceil(trail_px)) + 4;
  cv::Mat boom_mask(still.mask.height(), still.mask.width(), CV_8U), near;
  for (int y = 0; y < boom_mask.rows; ++y)
    for (int x = 0; x < boom_mask.cols; ++x)
      boom_mask.at<std::uint8_t>(y, x) = (still.mask.row(y)[x] & kMaskBoom) ? 255 : 0;
  cv::dilate(boom_mask, near, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * grow + 1, 2 * grow + 1}));
  Image region(near.cols, near.rows, PixelFormat::kMono8), inside(near.cols, near.rows, PixelFormat::kMono8);
  for (int y = 0; y < near.rows; ++y)
    for (int x = 0; x < near.cols; ++x)
      region.row(y)[x] = near.at<std::uint8_t>(y, x), inside.row(y)[x] = boom_mask.at<std::uint8_t>(y, x);
  const auto d_still = eval::region_difference(still.augmented.cview(), phys_still.cview(), region.cview());
  const auto d_moving =
      eval::region_difference(moving.augmented.cview(), phys_moving.cview(), region.cview());
  // What the motion changes, physically and augmented: (moving - still) in each, and how far apart.
  double signal2 = 0, apart2 = 0, ours2 = 0, cross = 0;
  std::int64_t samples = 0;
  for (int y = 0; y < region.height(); ++y)
    for (int x = 0; x < region.width(); ++x) {
      if (!region.row(y)[x]) continue;
      for (int ch = 0; ch < 3; ++ch) {
        auto v = [&](const Image& im) { return static_cast<double>(im.row(y)[3 * x + ch]); };
        const double phys = v(phys_moving) - v(phys_still), ours = v(moving.augmented) - v(still.augmented);
        signal2 += phys * phys, apart2 += (ours - phys) * (ours - phys), ++samples;
        ours2 += ours * ours, cross += ours * phys;
      }
    }
  const double signal_rms = std::sqrt(signal2 / static_cast<double>(samples)),
               apart_rms = std::sqrt(apart2 / static_cast<double>(samples)),
               correlation = cross / std::sqrt(signal2 * ours2);
  const auto e_phys = eval::edge_width(phys_moving.cview(), inside.cview()),
             e_aug = eval::edge_width(moving.augmented.cview(), inside.cview()),
             e_still = eval::edge_width(phys_still.cview(), inside.cview());
  ASSERT_TRUE(d_still && d_moving && e_phys && e_aug && e_still);
  std::printf(
      "trail %.2f px, %d instants: still booms mean %+.2f RMS %.2f DN, moving booms mean %+.2f RMS %.2f DN; "
      "the motion's change RMS %.2f DN physically, augmented %.2f DN apart from it (correlation %.3f); edges "
      "physical %.3f "
      "(still %.3f), augmented %.3f px\n",
      trail_px, motion_samples(trail_px), d_still->mean_dn, d_still->rms_dn, d_moving->mean_dn,
      d_moving->rms_dn, signal_rms, apart_rms, correlation, e_phys->width_10_90_px, e_still->width_10_90_px,
      e_aug->width_10_90_px);
  EXPECT_LT(std::abs(d_moving->mean_dn), 2.0);
  EXPECT_LT(d_moving->rms_dn, d_still->rms_dn + 1.0);
  // The trail lies at the boom's edges (seen nearly end on, the ruddevators move most), where the
  // still booms already differ by their sub-pixel silhouettes: the changes agree to 0.68, not 1.
  EXPECT_GT(signal_rms, 1.5) << "the trail is there to be matched";
  EXPECT_GT(correlation, 0.6);
  EXPECT_LT(apart_rms, 0.85 * signal_rms);
  EXPECT_GT(e_phys->width_10_90_px, e_still->width_10_90_px + 0.2);
  EXPECT_NEAR(e_aug->width_10_90_px, e_phys->width_10_90_px, 0.3);
}

}  // namespace
}  // namespace augrig
