// The light probe against a renderer that lights the receiver with a known light: the simulator's
// CPU back end (sim/synthetic_scene_cpu.cpp) with its fixed ambient, whose sun, sky and ground terms
// per channel are SceneLight's model exactly (Lambert sun of colour 0.75 (1, 0.97, 0.92), sky
// (0.36, 0.40, 0.46) above, ground (0.22, 0.22, 0.20) below). The probe sees only the frames,
// the augmenter's masks and depth, and the receiver's model.
#include "render/light_probe.hpp"

#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "render/models.hpp"
#include "sim/synthetic_scene.hpp"
#include "tests/support/gl_test.hpp"

namespace augrig {
namespace {

const Eigen::Vector3d kDirect = 0.75 * Eigen::Vector3d(1.0, 0.97, 0.92);
const Eigen::Vector3d kSky(0.36, 0.40, 0.46), kGround(0.22, 0.22, 0.20);

class LightProbeTest : public test::GlTest {
 protected:
  // The receiver 20 m aft and 9 m below the cameras, rolled a little: wings' tops, fuselage sides
  // and nacelles in view.
  static Pose receiver_pose() { return Pose::from(rotation_from_ypr(0.1, 0.05, 0.2), {-20.0, 0.5, 9.0}); }
  static SkyState sky_with_sun(const Eigen::Vector3d& sun_ned) {
    SkyState s;
    s.R_ned_body = rotation_from_ypr(deg_to_rad(90.0), 0.0, 0.0);
    s.sun_ned = sun_ned.normalized();
    s.ambient_from_world = false;  // the fixed ambient: the light is known exactly
    return s;
  }
  // Renders both views, augments them for masks and depth, and fits the light seen.
  std::optional<LightFit> measure(const Rig& rig, const SkyState& sky, const SensorOptions& sensor,
                                  std::string* why, std::size_t* samples = nullptr) {
    auto renderer = SyntheticSceneRenderer::create(rig);
    EXPECT_TRUE(renderer);
    AugmentOptions ao;
    ao.rasterizer = Rasterizer::kCpu;
    auto aug = Augmenter::create(rig, ao);
    EXPECT_TRUE(aug);
    SceneState scene;
    scene.T_body_receiver = pose_;
    scene.boom = {deg_to_rad(30.0), 0.0, 1.0};
    LightProbe probe((*aug)->receiver_model());
    EXPECT_GT(probe.points(), 500u);
    for (int c = 0; c < 2; ++c) {
      Frame raw;
      EXPECT_TRUE((*renderer)->render(c, sky, scene.T_body_receiver, true, sensor, raw.image));
      raw.camera = c == 0 ? CameraId::kLeft : CameraId::kRight;
      ViewResult vr;
      EXPECT_TRUE((*aug)->augment_view(c, raw, scene, vr));
      probe.add_view(raw.image, vr.mask, vr.receiver_depth, rig.cameras[static_cast<std::size_t>(c)],
                     scene.T_body_receiver, 1.0);
    }
    if (samples) *samples = probe.samples();
    const Eigen::Matrix3d R_body_ned = sky.R_ned_body.transpose();
    return probe.fit(R_body_ned * sky.sun_ned, R_body_ned * Eigen::Vector3d::UnitZ(), sky.sun_ned.z() < 0,
                     why);
  }
  Pose pose_ = receiver_pose();
};

void expect_light(const LightFit& f, const Eigen::Vector3d& direct, const Eigen::Vector3d& sky,
                  const Eigen::Vector3d& ground, double tol) {
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(f.direct[c], direct[c], tol) << "direct, channel " << c;
    EXPECT_NEAR(f.sky[c], sky[c], tol) << "sky, channel " << c;
    EXPECT_NEAR(f.ground[c], ground[c], tol) << "ground, channel " << c;
  }
}

TEST_F(LightProbeTest, MeasuresSunSkyAndGroundPerChannel) {
  // Suns from the side, from behind and from high above; RGB without, and with noise and a lens
  // (PSF 0.8 px: the background bleeds into the receiver's silhouette, where the surfaces facing
  // sideways and down are; the probe reads away from it). Within 0.015: a boom facing the ground
  // is 1 DN per 0.004 of ground light off.
  for (const Eigen::Vector3d& sun : {Eigen::Vector3d(-0.4, 0.4, -0.82), Eigen::Vector3d(0.7, -0.3, -0.5),
                                     Eigen::Vector3d(0.1, 0.2, -1.0)}) {
    for (double noise : {0.0, 2.0}) {
      SCOPED_TRACE("sun " + std::to_string(sun.x()) + " " + std::to_string(sun.y()) + ", noise " +
                   std::to_string(noise));
      SensorOptions sensor;
      sensor.noise_sigma = noise;
      sensor.psf_sigma_px = noise > 0 ? 0.8 : 0.0;
      std::string why;
      std::size_t samples = 0;
      const auto fit = measure(Rig::paper_default(), sky_with_sun(sun), sensor, &why, &samples);
      ASSERT_TRUE(fit) << why;
      std::printf(
          "%zu samples, %zu used, rms %.4f: direct %.3f %.3f %.3f sky %.3f %.3f %.3f ground %.3f %.3f %.3f\n",
          samples, fit->samples, fit->rms, fit->direct[0], fit->direct[1], fit->direct[2], fit->sky[0],
          fit->sky[1], fit->sky[2], fit->ground[0], fit->ground[1], fit->ground[2]);
      EXPECT_GT(fit->samples, 200u);
      expect_light(*fit, kDirect, kSky, kGround, 0.015);
    }
  }
}

TEST_F(LightProbeTest, BayerAndMonoFrames) {
  SensorOptions sensor;
  sensor.noise_sigma = 1.0;
  std::string why;
  sensor.format = PixelFormat::kBayerRG8;
  const auto bayer = measure(Rig::paper_default(), sky_with_sun({-0.4, 0.4, -0.82}), sensor, &why);
  ASSERT_TRUE(bayer) << why;
  expect_light(*bayer, kDirect, kSky, kGround, 0.02);
  sensor.format = PixelFormat::kMono8;
  const auto mono = measure(Rig::paper_default(), sky_with_sun({-0.4, 0.4, -0.82}), sensor, &why);
  ASSERT_TRUE(mono) << why;
  // A Mono camera knows the luma only: one light for all three channels.
  constexpr double kLuma[3] = {0.299, 0.587, 0.114};
  auto luma = [&](const Eigen::Vector3d& v) { return kLuma[0] * v[0] + kLuma[1] * v[1] + kLuma[2] * v[2]; };
  expect_light(*mono, Eigen::Vector3d::Constant(luma(kDirect)), Eigen::Vector3d::Constant(luma(kSky)),
               Eigen::Vector3d::Constant(luma(kGround)), 0.02);
}

// A far receiver (32 m aft, 13 m below) on a Bayer mosaic: many of its triangles hold a few pixels,
// not always of every colour. Each colour is fitted from the triangles that hold it, so the fit
// has nearly the points a colour camera gives (it had a fifth of them when a triangle needed all
// three) and finds the same light.
TEST_F(LightProbeTest, AFarReceiverOnABayerMosaicIsMeasuredFromEachColoursOwnPoints) {
  pose_ = Pose::from(rotation_from_ypr(0.1, 0.05, 0.2), {-32.0, 0.5, 13.0});
  SensorOptions sensor;
  sensor.noise_sigma = 1.0;
  std::string why;
  const auto rgb = measure(Rig::paper_default(), sky_with_sun({-0.4, 0.4, -0.82}), sensor, &why);
  ASSERT_TRUE(rgb) << why;
  sensor.format = PixelFormat::kBayerRG8;
  const auto bayer = measure(Rig::paper_default(), sky_with_sun({-0.4, 0.4, -0.82}), sensor, &why);
  ASSERT_TRUE(bayer) << why;
  for (const LightFit* f : {&*rgb, &*bayer})
    std::printf("far receiver: %zu points: direct %.3f %.3f %.3f sky %.3f %.3f %.3f ground %.3f %.3f %.3f\n",
                f->samples, f->direct[0], f->direct[1], f->direct[2], f->sky[0], f->sky[1], f->sky[2],
                f->ground[0], f->ground[1], f->ground[2]);
  EXPECT_GT(rgb->samples, 100u);
  EXPECT_GT(bayer->samples, rgb->samples * 3 / 4);
  expect_light(*rgb, kDirect, kSky, kGround, 0.02);
  expect_light(*bayer, kDirect, kSky, kGround, 0.02);
}

TEST_F(LightProbeTest, SunBelowTheHorizonLeavesTheDiffuseLightOnly) {
  std::string why;
  const auto fit = measure(Rig::paper_default(), sky_with_sun({0.3, 0.2, 0.5}), SensorOptions{}, &why);
  ASSERT_TRUE(fit) << why;
  expect_light(*fit, Eigen::Vector3d::Zero(), kSky, kGround, 0.015);
}

TEST_F(LightProbeTest, SaysWhyWhenTheReceiverIsNotInView) {
  // The receiver far off to the side: out of both views.
  auto renderer = SyntheticSceneRenderer::create(Rig::paper_default());
  ASSERT_TRUE(renderer);
  AugmentOptions ao;
  ao.rasterizer = Rasterizer::kCpu;
  auto aug = Augmenter::create(Rig::paper_default(), ao);
  ASSERT_TRUE(aug);
  SceneState scene;
  scene.T_body_receiver = Pose::from(Eigen::Matrix3d::Identity(), {-20.0, 200.0, 9.0});
  LightProbe probe((*aug)->receiver_model());
  Frame raw;
  ASSERT_TRUE((*renderer)->render(0, SkyState{}, scene.T_body_receiver, true, SensorOptions{}, raw.image));
  ViewResult vr;
  ASSERT_TRUE((*aug)->augment_view(0, raw, scene, vr));
  probe.add_view(raw.image, vr.mask, vr.receiver_depth, Rig::paper_default().cameras[0],
                 scene.T_body_receiver, 1.0);
  std::string why;
  EXPECT_FALSE(probe.fit(Eigen::Vector3d(0, 0, -1), Eigen::Vector3d::UnitZ(), true, &why));
  EXPECT_NE(why.find("points of the receiver in view"), std::string::npos) << why;
}

}  // namespace
}  // namespace augrig
