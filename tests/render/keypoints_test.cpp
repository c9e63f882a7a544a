// Receiver keypoints: the built-in receiver's defaults where its geometry puts them, and each
// keypoint's class in each camera against the augmenter's own masks (a visible keypoint's deciding
// pixel is receiver-only, a boom-hidden one's shows the boom) and against an independent ray
// caster (tests/support/ray_caster.hpp): the first surface along the ray through the keypoint is
// the boom, the receiver in front of the point, or the point's own surface.
#include "render/keypoints.hpp"

#include <cmath>
#include <map>

#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "render/augmenter.hpp"
#include "render/models.hpp"
#include "tests/support/gl_test.hpp"
#include "tests/support/ray_caster.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

TEST(Keypoints, BuiltInReceiversDefaultsLieWhereItsShapePutsThem) {
  Eigen::Vector3d receptacle;
  const Model receiver = make_builtin_receiver(&receptacle);
  const std::vector<Keypoint> k = default_receiver_keypoints(receiver, receptacle);
  std::map<std::string, Eigen::Vector3d> at;
  for (const Keypoint& p : k) at[p.name] = p.p_receiver_m;
  for (const char* name : {"nose", "tail", "wing_tip_left", "wing_tip_right", "fin_tip", "tailplane_tip_left",
                           "tailplane_tip_right", "nacelle_front_left", "nacelle_front_right", "receptacle"})
    ASSERT_TRUE(at.count(name)) << name;
  EXPECT_EQ(k.size(), 10u);
  const auto [lo, hi] = receiver.bounds();
  EXPECT_NEAR(at["nose"].x(), hi.x(), 0.01);
  EXPECT_NEAR(at["tail"].x(), lo.x(), 0.01);
  EXPECT_NEAR(at["wing_tip_right"].y(), hi.y(), 0.01);
  EXPECT_NEAR(at["wing_tip_left"].y(), lo.y(), 0.01);
  EXPECT_NEAR(at["fin_tip"].z(), lo.z(), 0.01);  // FRD: the top is the least z
  // A symmetric aircraft: the pairs mirror each other; the span ~16.6 m, the length ~13.3 m.
  for (const char* side : {"wing_tip_", "tailplane_tip_", "nacelle_front_"}) {
    const Eigen::Vector3d l = at[std::string(side) + "left"], r = at[std::string(side) + "right"];
    EXPECT_NEAR(l.y(), -r.y(), 1e-3) << side;
    EXPECT_NEAR(l.x(), r.x(), 1e-3) << side;
  }
  EXPECT_NEAR(at["wing_tip_right"].y() - at["wing_tip_left"].y(), 16.6, 0.5);
  EXPECT_NEAR(at["nose"].x() - at["tail"].x(), 13.3, 0.5);
  EXPECT_LT(at["tailplane_tip_right"].y(), at["wing_tip_right"].y());
  EXPECT_GT(at["nacelle_front_right"].x(), at["wing_tip_right"].x() - 3.0);
  EXPECT_EQ(at["receptacle"], receptacle);
  // A model without triangles: the receptacle only.
  EXPECT_EQ(default_receiver_keypoints(Model{}, receptacle).size(), 1u);
}

TEST(Keypoints, TheRigsOwnReplaceTheDefaults) {
  Eigen::Vector3d receptacle;
  const Model receiver = make_builtin_receiver(&receptacle);
  ReceiverConfig config;
  config.receptacle_m = receptacle;
  EXPECT_EQ(receiver_keypoints(config, receiver).size(), 10u);
  config.keypoints = {{"probe", {7, 0, -1}}, {"nose", {6, 0, 0}}};
  const std::vector<Keypoint> k = receiver_keypoints(config, receiver);
  ASSERT_EQ(k.size(), 2u);
  EXPECT_EQ(k[0].name, "probe");
  EXPECT_EQ(k[1].p_receiver_m, Eigen::Vector3d(6, 0, 0));
}

TEST(Keypoints, FlipPairsSwapLeftAndRightWords) {
  auto flip = [](std::vector<std::string> names) {
    std::vector<Keypoint> k;
    for (const std::string& n : names) k.push_back({n, Eigen::Vector3d::Zero()});
    return keypoint_flip_index(k);
  };
  EXPECT_EQ(flip({"nose", "wing_tip_left", "wing_tip_right", "tail"}), (std::vector<int>{0, 2, 1, 3}));
  EXPECT_EQ(flip({"right_engine", "left_engine", "left"}), (std::vector<int>{1, 0, 2}));  // "left" has no "right"
  // Words only: "leftover" and "bright" are not sides.
  EXPECT_EQ(flip({"leftover", "rightover", "bright", "bleft"}), (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(flip({"a_left_b", "a_right_b", "a_right_c"}), (std::vector<int>{1, 0, 2}));
  // The built-in receiver's defaults pair as Ultralytics expects (a flip twice is no flip).
  Eigen::Vector3d receptacle;
  const auto d = keypoint_flip_index(default_receiver_keypoints(make_builtin_receiver(&receptacle), receptacle));
  for (std::size_t i = 0; i < d.size(); ++i) EXPECT_EQ(d[static_cast<std::size_t>(d[i])], static_cast<int>(i));
  EXPECT_EQ(d, (std::vector<int>{0, 1, 3, 2, 4, 6, 5, 8, 7, 9}));
}

TEST(Keypoints, ClassesAndCocoFlags) {
  EXPECT_EQ(coco_visibility(KeypointClass::kVisible), 2);
  EXPECT_EQ(coco_visibility(KeypointClass::kHiddenByBoom), 1);
  EXPECT_EQ(coco_visibility(KeypointClass::kHiddenByReceiver), 1);
  EXPECT_EQ(coco_visibility(KeypointClass::kOutside), 0);
  EXPECT_EQ(coco_visibility(KeypointClass::kNotDrawn), 0);
  EXPECT_EQ(to_string(KeypointClass::kHiddenByBoom), "hidden_by_boom");
}

class KeypointsInViews : public test::GlTest {};

// Contact and a boom swung over the receiver, the receiver moved about so that the boom hides some
// points and the far side others; every keypoint in both cameras.
TEST_F(KeypointsInViews, AgreeWithTheMasksAndARayCaster) {
  const Rig rig = Rig::paper_default();
  auto aug = Augmenter::create(rig, {});
  ASSERT_TRUE(aug) << aug.error().message;
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  const std::vector<Keypoint> keypoints = default_receiver_keypoints((*aug)->receiver_model(), receptacle);
  std::map<KeypointClass, int> seen;
  int agree_with_rays = 0, compared = 0;
  const std::vector<std::pair<BoomArticulation, Eigen::Vector3d>> cases = {
      {{0.52, 0.0, 3.0}, {0, 0, 0}},
      {{0.52, 0.03, 3.0}, {-2.0, 0.5, 0.5}},
      {{0.45, -0.15, 2.0}, {-3.0, 1.5, 1.0}},
      {{0.50, 0.2, 1.0}, {1.0, -7.0, 2.0}},
      {{0.40, 0.0, 0.0}, {-6.0, 0.0, 3.0}}};
  for (const auto& [a, offset] : cases) {
    SceneState scene = scene_at_contact(rig, (*aug)->boom_model().dims, receptacle, a);
    scene.T_body_receiver.translation_m += offset;
    StereoFrame sf;
    sf.left = test::gradient_frame(rig.left().model, PixelFormat::kRGB8, CameraId::kLeft);
    sf.right = test::gradient_frame(rig.right().model, PixelFormat::kRGB8, CameraId::kRight);
    StereoResult out;
    ASSERT_TRUE((*aug)->augment(sf, scene, out));
    for (int c = 0; c < 2; ++c) {
      const RigCamera& cam = rig.cameras[static_cast<std::size_t>(c)];
      const ViewResult& view = c ? out.right : out.left;
      const Pose T_cam_body = cam.T_body_cam.inverse();
      const Pose T_body_boom = boom_pose(rig.boom.pivot_body_m, a);
      test::RayCaster boom, receiver;
      boom.add((*aug)->boom_model().fixed, T_cam_body * T_body_boom);
      boom.add((*aug)->boom_model().telescope, T_cam_body * T_body_boom * telescope_pose(a));
      receiver.add((*aug)->receiver_model(), T_cam_body * scene.T_body_receiver);
      for (const Keypoint& k : keypoints) {
        const Eigen::Vector3d p = T_cam_body * (scene.T_body_receiver * k.p_receiver_m);
        const KeypointInView v = locate_keypoint(p, cam.model, view.mask.cview(), view.receiver_depth);
        ++seen[v.cls];
        const std::string what = k.name + " in camera " + std::to_string(c);
        if (v.cls == KeypointClass::kOutside) {
          const auto uv = cam.model.project(p);
          EXPECT_TRUE(!uv || uv->x() < -0.5 || uv->y() < -0.5 || uv->x() >= cam.model.width_px - 0.5 ||
                      uv->y() >= cam.model.height_px - 0.5)
              << what;
          continue;
        }
        ASSERT_GE(v.decided_x, 0) << what;
        EXPECT_LE(std::abs(v.decided_x - v.uv_px.x()), 1.5) << what;
        EXPECT_LE(std::abs(v.decided_y - v.uv_px.y()), 1.5) << what;
        const std::uint8_t m = view.mask.row(v.decided_y)[v.decided_x];
        if (v.cls == KeypointClass::kVisible) {
          EXPECT_EQ(m, kMaskReceiver) << what << ": not receiver-only";
        }
        if (v.cls == KeypointClass::kHiddenByBoom) {
          EXPECT_TRUE(m & kMaskBoom) << what;
        }
        if (v.cls == KeypointClass::kNotDrawn) continue;
        // The ray caster along the keypoint's own ray (x/z, y/z): the nearest boom and receiver hits.
        const double zb = boom.hit_z(p.x() / p.z(), p.y() / p.z());
        const double zr = receiver.hit_z(p.x() / p.z(), p.y() / p.z());
        const double tol = keypoint_depth_tolerance_m(p.z());
        KeypointClass want = KeypointClass::kVisible;
        if (zr < p.z() - tol)
          want = KeypointClass::kHiddenByReceiver;
        else if (zb < p.z() + tol)
          want = KeypointClass::kHiddenByBoom;
        ++compared;
        agree_with_rays += want == v.cls;
      }
    }
  }
  // Each class at work (the first case puts the receptacle under the nozzle).
  EXPECT_GT(seen[KeypointClass::kVisible], 10);
  EXPECT_GT(seen[KeypointClass::kHiddenByBoom], 0);
  EXPECT_GT(seen[KeypointClass::kHiddenByReceiver], 0);
  // The rays differ from the masks only at pixel-centre sampling of edges through the keypoint.
  EXPECT_GE(agree_with_rays, compared * 95 / 100) << agree_with_rays << " of " << compared;
  std::printf(
      "  keypoints: %d visible, %d hidden by the boom, %d by the receiver, %d outside, %d not drawn; "
      "%d of %d as the rays say\n",
      seen[KeypointClass::kVisible], seen[KeypointClass::kHiddenByBoom],
      seen[KeypointClass::kHiddenByReceiver], seen[KeypointClass::kOutside], seen[KeypointClass::kNotDrawn],
      agree_with_rays, compared);
}

}  // namespace
}  // namespace augrig
