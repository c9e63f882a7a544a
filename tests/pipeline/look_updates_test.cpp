// pipeline/look_updates: the camera look's updates as recording rows. Estimated noise gives one row
// per camera at each new estimate (the pairs sampled every noise_every_s), with what the augmenter
// was given, the frames it used and the pair's time and clock, and nothing at the pairs between;
// the rig's noise gives one row per camera at the first pair and none after; the plain look none.
// The light measured on the receiver is recorded by a simulated run (pipeline_test).
#include "pipeline/look_updates.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/gl_test.hpp"

namespace augrig::pipeline {
namespace {

class LookUpdatesTest : public test::GlTest {
 protected:
  // A pair of ramps with noise sigma^2 = a I + b, stamped t_ns on the device clock.
  static StereoFrame noisy_pair(const Rig& rig, unsigned seed, TimestampNs t_ns) {
    StereoFrame sf;
    std::mt19937 rng(seed);
    std::normal_distribution<double> n01;
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      const CameraModel& m = rig.cameras[static_cast<std::size_t>(index_of(id))].model;
      Frame& f = sf[id];
      f.camera = id;
      f.t_ns = t_ns;
      f.clock = ClockDomain::kDevice;
      f.image = Image(m.width_px, m.height_px, PixelFormat::kMono8);
      for (int y = 0; y < m.height_px; ++y)
        for (int x = 0; x < m.width_px; ++x) {
          const double s = 30 + 180.0 * x / m.width_px;
          f.image.row(y)[x] =
              static_cast<std::uint8_t>(std::clamp(std::lround(s + std::sqrt(0.3 * s + 2.0) * n01(rng)), 0L, 255L));
        }
    }
    sf.t_key_ns = t_ns;
    return sf;
  }
  static LookConfig config(Look look) {
    LookConfig c;
    c.look = look;
    c.cameras.resize(2);
    c.synchronous = true;
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

constexpr TimestampNs kT0 = 1'000'000'000, kPeriod = 100'000'000;  // 10 pairs a second

TEST_F(LookUpdatesTest, EachNewNoiseEstimateIsOneRowPerCamera) {
  const Rig rig = Rig::paper_default();
  auto aug = augmenter(rig);
  ASSERT_TRUE(aug);
  LookStage stage(config(Look::kCamera));  // a pair every 0.5 s to the estimator
  ASSERT_TRUE(stage.configure(*aug));
  LookUpdates updates;
  std::vector<std::size_t> pairs_with_rows;
  std::size_t rows = 0;
  for (int k = 0; k < 12; ++k) {
    const StereoFrame pair = noisy_pair(rig, static_cast<unsigned>(k), kT0 + k * kPeriod);
    SceneState scene;
    stage.before_augment(pair, scene, *aug);
    const std::vector<recorder::LookRecord> got = updates.take(stage, *aug, pair, scene.light);
    if (got.empty()) continue;
    pairs_with_rows.push_back(static_cast<std::size_t>(k));
    ASSERT_EQ(got.size(), 2u) << "pair " << k;
    for (int c = 0; c < 2; ++c) {
      const recorder::LookRecord& r = got[static_cast<std::size_t>(c)];
      EXPECT_EQ(r.t_ns, pair.t_key_ns);
      EXPECT_EQ(r.clock, ClockDomain::kDevice);
      const auto* n = std::get_if<recorder::LookNoise>(&r.update);
      ASSERT_TRUE(n);
      EXPECT_EQ(n->camera, c);
      EXPECT_FALSE(n->configured);
      EXPECT_EQ(n->nlf, aug->camera_look(c).noise);  // what the augmenter adds from this pair on
      EXPECT_EQ(n->frames, pairs_with_rows.size());  // the estimator keeps every frame of its window
    }
    rows += got.size();
  }
  EXPECT_EQ(pairs_with_rows, (std::vector<std::size_t>{0, 5, 10}));
  EXPECT_EQ(rows, 6u);
}

TEST_F(LookUpdatesTest, TheRigsNoiseIsOneRowPerCameraAtTheFirstPair) {
  const Rig rig = Rig::paper_default();
  auto aug = augmenter(rig);
  ASSERT_TRUE(aug);
  LookConfig c = config(Look::kCamera);
  c.cameras[0].noise = {1, {0.2, 0, 0}, {3, 0, 0}};
  c.cameras[1].noise = {3, {0.1, 0.2, 0.3}, {1, 2, 3}};
  LookStage stage(c);
  ASSERT_TRUE(stage.configure(*aug));
  LookUpdates updates;
  std::vector<recorder::LookRecord> all;
  for (int k = 0; k < 8; ++k) {
    const StereoFrame pair = noisy_pair(rig, static_cast<unsigned>(k), kT0 + k * kPeriod);
    SceneState scene;
    stage.before_augment(pair, scene, *aug);
    for (recorder::LookRecord& r : updates.take(stage, *aug, pair, scene.light)) all.push_back(std::move(r));
  }
  ASSERT_EQ(all.size(), 2u);
  for (int cam = 0; cam < 2; ++cam) {
    const recorder::LookRecord& r = all[static_cast<std::size_t>(cam)];
    EXPECT_EQ(r.t_ns, kT0);
    const auto& n = std::get<recorder::LookNoise>(r.update);
    EXPECT_EQ(n.camera, cam);
    EXPECT_TRUE(n.configured);
    EXPECT_EQ(n.frames, 0u);
    EXPECT_EQ(n.nlf, c.cameras[static_cast<std::size_t>(cam)].noise);
  }
}

TEST_F(LookUpdatesTest, ThePlainLookRecordsNothing) {
  const Rig rig = Rig::paper_default();
  auto aug = augmenter(rig);
  ASSERT_TRUE(aug);
  LookConfig c = config(Look::kPlain);
  c.cameras[0].noise = {1, {0.2, 0, 0}, {3, 0, 0}};
  LookStage stage(c);
  LookUpdates updates;
  for (int k = 0; k < 6; ++k) {
    const StereoFrame pair = noisy_pair(rig, static_cast<unsigned>(k), kT0 + k * kPeriod);
    SceneState scene;
    stage.before_augment(pair, scene, *aug);
    EXPECT_TRUE(updates.take(stage, *aug, pair, scene.light).empty()) << k;
  }
}

}  // namespace
}  // namespace augrig::pipeline
