// pipeline/look_stage: the sun on the boom from nav (against nav/solar_position's own NED vector
// turned into the body frame here by hand), the default sun said once, the ground's light from
// the frames, each camera's noise estimated from noisy frames of a known noise level function
// and handed to the augmenter (synchronously: repeatable; on its thread: in time), and a note
// where no estimate can be made.
#include "pipeline/look_stage.hpp"

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "nav/geodesy.hpp"
#include "nav/gps_time.hpp"
#include "nav/solar_position.hpp"
#include "tests/support/gl_test.hpp"

namespace augrig::pipeline {
namespace {

// A tanker at `where` flying level on `heading_rad`, as T_ecef_body.
Pose tanker_at(const nav::Geodetic& where, double heading_rad) {
  const Eigen::Matrix3d R_ned_body = Eigen::AngleAxisd(heading_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return Pose::from(nav::R_ecef_ned(where.lat_rad, where.lon_rad) * R_ned_body, nav::ecef_from_geodetic(where));
}

TimestampNs gps_ns(int y, int mo, int d, int h, int mi) {
  const std::int64_t utc_s = nav::days_from_civil(y, mo, d) * 86400 + h * 3600 + mi * 60;
  const std::int64_t gps_epoch_s = nav::days_from_civil(1980, 1, 6) * 86400;
  return (utc_s - gps_epoch_s + nav::kDefaultLeapSeconds) * nav::kNsPerSecond;
}

TEST(SunLight, IsTheEphemerisSunInTheTankersBodyFrame) {
  const nav::Geodetic where{deg_to_rad(34.9), deg_to_rad(-117.9), 7000};  // Edwards AFB, at altitude
  const TimestampNs t = gps_ns(2026, 6, 1, 19, 0);                       // local noon-ish
  const nav::SolarPosition sun = nav::solar_position(t, where);
  for (const double heading_deg : {0.0, 90.0, 217.0}) {
    const SceneLight l = sun_light(t, tanker_at(where, deg_to_rad(heading_deg)));
    // Level flight: body = NED turned by the heading about down.
    const Eigen::Vector3d want =
        Eigen::AngleAxisd(-deg_to_rad(heading_deg), Eigen::Vector3d::UnitZ()).toRotationMatrix() * sun.sun_ned;
    EXPECT_LT((l.towards_light_body - want).norm(), 1e-9) << heading_deg;
    EXPECT_LT((l.down_body - Eigen::Vector3d::UnitZ()).norm(), 1e-9);
    EXPECT_EQ(l.source, LightSource::kEphemeris);
    EXPECT_GT(l.direct.minCoeff(), 0);
  }
}

TEST(SunLight, AnAircraftAtAltitudeSeesTheSunAfterItSetsOnTheGround) {
  // Find a time when the sun is 1 deg below the level horizon at Edwards: at 10 km the horizon
  // dips 3.2 deg, so the tanker is still sunlit; at sea level it is not; 1 h later neither is.
  nav::Geodetic where{deg_to_rad(34.9), deg_to_rad(-117.9), 10000};
  TimestampNs t = gps_ns(2026, 6, 2, 2, 0);  // evening local time
  for (int i = 0; i < 2000; ++i, t += 10 * nav::kNsPerSecond)
    if (nav::solar_position(t, where).zenith_rad > deg_to_rad(91.0)) break;
  EXPECT_GT(sun_light(t, tanker_at(where, 0)).direct.minCoeff(), 0);
  nav::Geodetic ground = where;
  ground.h_m = 0;
  EXPECT_EQ(sun_light(t, tanker_at(ground, 0)).direct.maxCoeff(), 0);
  EXPECT_EQ(sun_light(t + 3600 * nav::kNsPerSecond, tanker_at(where, 0)).direct.maxCoeff(), 0);
}

class LookStageTest : public test::GlTest {
 protected:
  // A pair of flat-ish frames (a ramp) with noise sigma^2 = a I + b.
  static StereoFrame noisy_pair(const Rig& rig, double a, double b, unsigned seed, TimestampNs t_ns) {
    StereoFrame sf;
    std::mt19937 rng(seed);
    std::normal_distribution<double> n01;
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      const CameraModel& m = rig.cameras[static_cast<std::size_t>(index_of(id))].model;
      Frame& f = sf[id];
      f.camera = id;
      f.t_ns = t_ns;
      f.image = Image(m.width_px, m.height_px, PixelFormat::kMono8);
      for (int y = 0; y < m.height_px; ++y)
        for (int x = 0; x < m.width_px; ++x) {
          const double s = 30 + 180.0 * x / m.width_px;
          f.image.row(y)[x] = static_cast<std::uint8_t>(std::clamp(std::lround(s + std::sqrt(a * s + b) * n01(rng)), 0L, 255L));
        }
    }
    sf.t_key_ns = t_ns;
    return sf;
  }
  static LookConfig camera_look(bool synchronous) {
    LookConfig c;
    c.look = Look::kCamera;
    c.cameras.resize(2);
    c.synchronous = synchronous;
    return c;
  }
  std::unique_ptr<Augmenter> augmenter(const Rig& rig) {
    AugmentOptions o;
    o.look = Look::kCamera;
    auto a = Augmenter::create(rig, o);
    EXPECT_TRUE(a) << a.error().message;
    return a ? std::move(*a) : nullptr;
  }
};

// sigma at level I from an NLF, against the truth.
double sigma_ratio(const NoiseLevelFunction& f, double a, double b, double level) {
  return std::sqrt(f.variance(0, level)) / std::sqrt(a * level + b);
}

TEST_F(LookStageTest, EstimatesEachCamerasNoiseAndGivesItToTheAugmenter) {
  const Rig rig = Rig::paper_default();
  auto aug = augmenter(rig);
  ASSERT_TRUE(aug);
  LookStage stage(camera_look(true));
  ASSERT_TRUE(stage.configure(*aug));
  SceneState scene;  // no light from the pose source: the default sun, said once
  const StereoFrame pair = noisy_pair(rig, 0.3, 2.0, 1, 1'000'000'000);
  std::vector<std::string> notes = stage.before_augment(pair, scene, *aug);
  EXPECT_EQ(scene.light.source, LightSource::kDefaultSun);
  int sun_notes = 0, noise_notes = 0;
  for (const std::string& n : notes) {
    sun_notes += n.find("default sun") != std::string::npos;
    noise_notes += n.find("noise estimated") != std::string::npos;
  }
  EXPECT_EQ(sun_notes, 1);
  EXPECT_EQ(noise_notes, 2);
  for (int c = 0; c < 2; ++c) {
    const NoiseLevelFunction& f = aug->camera_look(c).noise;
    ASSERT_FALSE(f.empty()) << c;
    for (double level : {60.0, 120.0, 190.0}) EXPECT_NEAR(sigma_ratio(f, 0.3, 2.0, level), 1.0, 0.1) << level;
  }
  // The ground's light: the frames' mean linear level (the ramp's mean, 120 DN).
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(scene.light.ground[c], 120.0 / 255, 0.01) << c;
  // Said once only.
  SceneState again;
  for (const std::string& n : stage.before_augment(noisy_pair(rig, 0.3, 2.0, 2, 1'100'000'000), again, *aug))
    EXPECT_EQ(n.find("default sun"), std::string::npos) << n;
  EXPECT_NE(stage.status().find("look camera: sun default sun"), std::string::npos) << stage.status();
}

// The same frames give the same estimates (the batch commands' repeatability).
TEST_F(LookStageTest, SynchronousEstimatesAreRepeatable) {
  const Rig rig = Rig::paper_default();
  std::vector<NoiseLevelFunction> got[2];
  for (int run = 0; run < 2; ++run) {
    auto aug = augmenter(rig);
    ASSERT_TRUE(aug);
    LookStage stage(camera_look(true));
    for (int k = 0; k < 4; ++k) {
      SceneState scene;
      stage.before_augment(noisy_pair(rig, 0.1, 4.0, 10 + k, (k + 1) * 600'000'000LL), scene, *aug);
    }
    got[run] = {aug->camera_look(0).noise, aug->camera_look(1).noise};
    EXPECT_EQ(stage.noise()[0].fits, 4u);
  }
  EXPECT_EQ(got[0], got[1]);
}

// Live runs: the estimate is made on the stage's thread and reaches the augmenter at a later pair.
TEST_F(LookStageTest, LiveEstimatesArriveFromTheirThread) {
  const Rig rig = Rig::paper_default();
  auto aug = augmenter(rig);
  ASSERT_TRUE(aug);
  LookStage stage(camera_look(false));
  SceneState scene;
  stage.before_augment(noisy_pair(rig, 0.5, 1.0, 3, 1'000'000'000), scene, *aug);
  stage.flush();
  SceneState next;
  stage.before_augment(noisy_pair(rig, 0.5, 1.0, 4, 1'010'000'000), next, *aug);
  ASSERT_FALSE(aug->camera_look(0).noise.empty());
  EXPECT_NEAR(sigma_ratio(aug->camera_look(0).noise, 0.5, 1.0, 128), 1.0, 0.1);
}

// Frames that show no noise to measure (saturated): no estimate, said once per camera, and
// nothing added; a noise-free rendering's (only 8-bit steps) gives a negligible one.
TEST_F(LookStageTest, FramesWithoutMeasurableNoiseAreSaidAndLeftAlone) {
  const Rig rig = Rig::paper_default();
  auto aug = augmenter(rig);
  ASSERT_TRUE(aug);
  LookStage stage(camera_look(true));
  int said = 0;
  for (int k = 0; k < 3; ++k) {
    StereoFrame white = noisy_pair(rig, 0, 0, 5, (k + 1) * 600'000'000LL);
    for (CameraId id : {CameraId::kLeft, CameraId::kRight})
      std::fill(white[id].image.data(), white[id].image.data() + white[id].image.size_bytes(), 255);
    SceneState scene;
    for (const std::string& n : stage.before_augment(white, scene, *aug))
      said += n.find("cannot be estimated") != std::string::npos;
  }
  EXPECT_EQ(said, 2);  // once per camera
  EXPECT_TRUE(aug->camera_look(0).noise.empty());

  LookStage clean_stage(camera_look(true));
  SceneState scene;
  clean_stage.before_augment(noisy_pair(rig, 0, 0, 5, 1), scene, *aug);
  for (int c = 0; c < 2; ++c) EXPECT_LT(aug->camera_look(c).noise.variance(0, 128), 0.1) << c;
}

// The rig's noise is used as it is, not estimated; the plain look does nothing.
TEST_F(LookStageTest, ConfiguredNoiseAndThePlainLookAreLeftAsTheyAre) {
  const Rig rig = Rig::paper_default();
  auto aug = augmenter(rig);
  ASSERT_TRUE(aug);
  LookConfig c = camera_look(true);
  for (CameraLookParams& p : c.cameras) p.noise = {1, {0.2, 0, 0}, {3, 0, 0}};
  LookStage stage(c);
  ASSERT_TRUE(stage.configure(*aug));
  SceneState scene;
  stage.before_augment(noisy_pair(rig, 0.9, 9.0, 6, 1'000'000'000), scene, *aug);
  EXPECT_EQ(aug->camera_look(1).noise, c.cameras[1].noise);
  EXPECT_TRUE(stage.noise()[0].configured);

  LookConfig plain;
  plain.cameras.resize(2);
  LookStage off(plain);
  // The plain look measures nothing; it takes the default sun (for the boom's shadow, a mask bit
  // in either look), says so once, and leaves a known sun as it is.
  SceneState untouched;
  const auto notes = off.before_augment(noisy_pair(rig, 0.1, 1.0, 7, 1), untouched, *aug);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("default sun"), std::string::npos) << notes[0];
  EXPECT_EQ(untouched.light.source, LightSource::kDefaultSun);
  EXPECT_TRUE(untouched.light.sun_up);
  EXPECT_EQ(untouched.light.direct, SceneLight::default_sun().direct);
  SceneState again;
  EXPECT_TRUE(off.before_augment(noisy_pair(rig, 0.1, 1.0, 7, 2), again, *aug).empty());
  SceneState known;
  known.light = SceneLight::sun(Eigen::Vector3d(0, 0, -1), false, LightSource::kEphemeris);
  EXPECT_TRUE(off.before_augment(noisy_pair(rig, 0.1, 1.0, 7, 3), known, *aug).empty());
  EXPECT_EQ(known.light.source, LightSource::kEphemeris);
  EXPECT_FALSE(known.light.sun_up);
  EXPECT_EQ(off.status(), "look plain");
}

// Where the exposure (the camera look's motion blur) comes from, said once per run: the rig's key,
// the frames' own, or nowhere (no motion blur).
TEST_F(LookStageTest, SaysOnceWhereEachCamerasExposureComesFrom) {
  const Rig rig = Rig::paper_default();
  auto aug = augmenter(rig);
  ASSERT_TRUE(aug);
  auto first_note = [&](LookConfig c, std::int64_t right_exposure_ns) {
    c.cameras[0].noise = c.cameras[1].noise = NoiseLevelFunction{1, {0.1, 0.1, 0.1}, {1, 1, 1}};
    LookStage stage(c);
    EXPECT_TRUE(stage.configure(*aug));
    StereoFrame pair = noisy_pair(rig, 0.1, 1.0, 3, 1'000'000'000);
    pair.right.exposure_ns = right_exposure_ns;
    SceneState scene;
    std::string said;
    for (const std::string& n : stage.before_augment(pair, scene, *aug))
      if (n.find("exposure") != std::string::npos) said += n;
    for (const std::string& n : stage.before_augment(pair, scene, *aug))
      EXPECT_EQ(n.find("exposure"), std::string::npos) << "said again: " << n;
    return said;
  };
  LookConfig c = camera_look(true);
  EXPECT_EQ(
      first_note(c, 0),
      "look: exposure left unknown; right unknown: the boom is drawn without motion blur (give the rig's "
      "look.exposure_ms; docs/LOOK.md)");
  c.cameras[0].exposure_ms = 4;
  EXPECT_EQ(
      first_note(c, 2'500'000),
      "look: exposure left 4 ms (the rig's look.exposure_ms); right 2.5 ms (its frames'): a moving boom is "
      "blurred over it, a camera without one is not");
}

}  // namespace
}  // namespace augrig::pipeline
