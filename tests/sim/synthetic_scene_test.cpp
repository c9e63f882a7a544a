// The synthetic scene renderer against geometry computed independently with the camera model:
// where the horizon must be, where the receiver must be, the stereo disparity, the sensor formats;
// the CPU back end's receiver silhouette against the augmenter's receiver mask, and against the
// OpenGL back end.
#include "sim/synthetic_scene.hpp"
#include "sim/synthetic_scene_cpu.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/conventions.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "render/models.hpp"
#include "render/projection.hpp"
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

}  // namespace
}  // namespace augrig
