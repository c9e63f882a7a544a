// The evaluation of one pair on simulated frames where the answer is known: the simulator renders
// the textured receiver at the pose the augmenter is given, so the augmenter's depth is the raw
// pair's truth. The raw pair must match near the truth; the boom drawn in must spoil the classes it
// occludes, and leaving its pixels out must remove the classes it hides from the left camera.
#include "eval/evaluator.hpp"

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "render/models.hpp"
#include "sim/synthetic_scene.hpp"
#include "tests/support/gl_test.hpp"

namespace augrig::eval {
namespace {

class EvaluatorTest : public test::GlTest {};

struct Pair {
  StereoFrame frame;
  StereoResult result;
};

// The paper's rig at contact with the boom at `a`, the receiver rendered by the simulator (Bayer,
// a little noise), augmented.
Pair contact_pair(const Rig& rig, Augmenter& aug, const BoomArticulation& a, bool receiver_present = true) {
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  SceneState scene = scene_at_contact(rig, aug.boom_model().dims, receptacle, a);
  scene.receiver_present = receiver_present;
  auto renderer = SyntheticSceneRenderer::create(rig);
  EXPECT_TRUE(renderer) << renderer.error().message;
  SensorOptions sensor;
  sensor.format = PixelFormat::kBayerRG8;
  sensor.noise_sigma = 1.5;
  Pair p;
  for (int c = 0; c < 2; ++c) {
    Frame& f = c ? p.frame.right : p.frame.left;
    f.camera = c ? CameraId::kRight : CameraId::kLeft;
    sensor.noise_seed = 7 + c;
    EXPECT_TRUE((*renderer)->render(c, SkyState{}, scene.T_body_receiver, receiver_present, sensor, f.image));
  }
  EXPECT_TRUE(aug.augment(p.frame, scene, p.result));
  return p;
}

TEST_F(EvaluatorTest, RawPairMatchesTheTruthAndTheBoomSpoilsWhatItOccludes) {
  const Rig rig = Rig::paper_default();
  AugmentOptions ao;
  ao.augmented_output = AugmentedOutput::kChangedBox;  // as the pipeline runs it
  auto aug = Augmenter::create(rig, ao);
  ASSERT_TRUE(aug) << aug.error().message;
  const Pair p = contact_pair(rig, **aug, BoomArticulation{0.52, 0.03, 3.0});
  ASSERT_GT(p.result.stats.occluded_px_left, 1000) << "the boom must occlude the receiver here";
  EvaluatorOptions eo;  // StereoSGBM 3-way, 64 disparities (the receiver's reach 43 px here)
  auto ev = StereoEvaluator::create(rig, eo);
  ASSERT_TRUE(ev) << ev.error().message;
  EvaluationImages images;
  auto fe = (*ev)->evaluate(p.frame, p.result, &images);
  ASSERT_TRUE(fe) << fe.error().message;
  ASSERT_GT(fe->receiver_px, 20000);
  EXPECT_LT(fe->matched.height, rig.left().model.height_px) << "only the receiver's rows are matched";

  const auto both = static_cast<int>(StereoClass::kBoth),
             right_only = static_cast<int>(StereoClass::kRightOnly),
             neither = static_cast<int>(StereoClass::kNeither);
  // The raw pair: where both cameras see the receiver, the matcher finds the true disparity.
  const DisparityErrors& raw_both = fe->raw.all[both];
  EXPECT_GT(raw_both.valid_pct(), 80.0);
  EXPECT_LT(std::abs(raw_both.mean_px()), 0.3);
  EXPECT_LT(raw_both.rms_px(), 1.0);
  EXPECT_LT(raw_both.bad3_pct(), 2.0);
  // The augmented pair: where the left camera sees the boom instead of the receiver, the matched
  // disparity is the boom's (nearer: larger), far from the receiver's.
  const DisparityErrors& aug_hidden = fe->augmented.all[right_only];
  ASSERT_GT(aug_hidden.pixels, 500);
  EXPECT_GT(aug_hidden.bad3_pct(), 50.0);
  EXPECT_GT(aug_hidden.mean_px(), 3.0);
  EXPECT_GT(fe->augmented.all[0].bad3_pct(), raw_both.bad3_pct() + 5.0);
  // Classes and mask agree: every pixel the boom hides from the left camera carries its mask bit,
  // so leaving the boom's pixels out leaves none of those classes.
  EXPECT_EQ(fe->augmented.boom_excluded[right_only].pixels, 0);
  EXPECT_EQ(fe->augmented.boom_excluded[neither].pixels, 0);
  EXPECT_EQ(fe->raw.all[0].pixels, fe->receiver_px);
  EXPECT_EQ(fe->raw.all[0].pixels,
            fe->raw.all[1].pixels + fe->raw.all[2].pixels + fe->raw.all[3].pixels + fe->raw.all[4].pixels);
  // Trusting the masks brings the augmented pair back towards the raw one.
  EXPECT_LT(fe->augmented.boom_excluded[0].bad3_pct(), fe->augmented.all[0].bad3_pct());
  // The images handed out are the scored ones (full frame, NaN outside the matched region).
  ASSERT_EQ(images.true_disparity.size(), cv::Size(rig.left().model.width_px, rig.left().model.height_px));
  EXPECT_EQ(cv::countNonZero(images.true_disparity == images.true_disparity), fe->receiver_px);
  EXPECT_TRUE(std::isnan(images.raw_disparity.at<float>(0, 0)));
}

TEST_F(EvaluatorTest, TheCropScoresLikeTheWholeFrame) {
  const Rig rig = Rig::paper_default();
  auto aug = Augmenter::create(rig);
  ASSERT_TRUE(aug) << aug.error().message;
  const Pair p = contact_pair(rig, **aug, BoomArticulation{0.50, -0.04, 2.5});
  EvaluatorOptions crop, whole;
  whole.full_frame = true;
  auto a = StereoEvaluator::create(rig, crop);
  auto b = StereoEvaluator::create(rig, whole);
  ASSERT_TRUE(a && b);
  auto fa = (*a)->evaluate(p.frame, p.result);
  auto fb = (*b)->evaluate(p.frame, p.result);
  ASSERT_TRUE(fa && fb);
  EXPECT_EQ(fb->matched, cv::Rect(0, 0, rig.left().model.width_px, rig.left().model.height_px));
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ(fa->raw.all[k].pixels, fb->raw.all[k].pixels) << k;
    if (fa->raw.all[k].pixels < 200) continue;
    EXPECT_NEAR(fa->raw.all[k].valid_pct(), fb->raw.all[k].valid_pct(), 1.0) << k;
    EXPECT_NEAR(fa->raw.all[k].bad3_pct(), fb->raw.all[k].bad3_pct(), 1.0) << k;
    EXPECT_NEAR(fa->augmented.all[k].valid_pct(), fb->augmented.all[k].valid_pct(), 1.0) << k;
    EXPECT_NEAR(fa->augmented.all[k].bad3_pct(), fb->augmented.all[k].bad3_pct(), 1.0) << k;
  }
}

TEST_F(EvaluatorTest, NoReceiverMeansNothingToScore) {
  const Rig rig = Rig::paper_default();
  auto aug = Augmenter::create(rig);
  ASSERT_TRUE(aug) << aug.error().message;
  const Pair p = contact_pair(rig, **aug, BoomArticulation{0.52, 0.03, 3.0}, false);
  auto ev = StereoEvaluator::create(rig, {});
  ASSERT_TRUE(ev);
  auto fe = (*ev)->evaluate(p.frame, p.result);
  ASSERT_TRUE(fe) << fe.error().message;
  EXPECT_EQ(fe->receiver_px, 0);
  EXPECT_TRUE(fe->matched.empty());
  EXPECT_EQ(fe->raw.all[0].pixels, 0);
  EXPECT_EQ(fe->augmented.all[0].pixels, 0);
}

TEST_F(EvaluatorTest, FramesThatAreNotTheRigsAreRefused) {
  const Rig rig = Rig::paper_default();
  auto aug = Augmenter::create(rig);
  ASSERT_TRUE(aug) << aug.error().message;
  Pair p = contact_pair(rig, **aug, BoomArticulation{0.52, 0.03, 3.0});
  auto ev = StereoEvaluator::create(rig, {});
  ASSERT_TRUE(ev);
  StereoResult no_classes = p.result;
  no_classes.stereo_classes.clear();
  auto e1 = (*ev)->evaluate(p.frame, no_classes);
  ASSERT_FALSE(e1);
  EXPECT_NE(e1.error().message.find("stereo classes"), std::string::npos) << e1.error().message;
  p.frame.right.image = Image(640, 480, PixelFormat::kBayerRG8);
  auto e2 = (*ev)->evaluate(p.frame, p.result);
  ASSERT_FALSE(e2);
  EXPECT_NE(e2.error().message.find("right image is 640x480"), std::string::npos) << e2.error().message;
  Rig one = rig;
  one.cameras.pop_back();
  EXPECT_FALSE(StereoEvaluator::create(one, {}));
}

}  // namespace
}  // namespace augrig::eval
