// The boom's motion over an exposure: the sub-exposure instants, how many a trail needs, and the
// trail's length in the image against a projection by hand.
#include "render/motion_blur.hpp"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace augrig {
namespace {

TEST(MotionBlur, InstantsSplitTheExposureEvenlyAboutItsMiddle) {
  EXPECT_DOUBLE_EQ(sub_exposure_offset_s(0, 1, 0.01), 0.0);
  for (int n : {2, 5, 16}) {
    double sum = 0;
    for (int k = 0; k < n; ++k) sum += sub_exposure_offset_s(k, n, 0.01);
    EXPECT_NEAR(sum, 0.0, 1e-15) << n;
    EXPECT_NEAR(sub_exposure_offset_s(1, n, 0.01) - sub_exposure_offset_s(0, n, 0.01), 0.01 / n, 1e-15);
    EXPECT_NEAR(sub_exposure_offset_s(0, n, 0.01), -0.005 + 0.005 / n, 1e-15);
  }
}

TEST(MotionBlur, SamplesOnePerHalfPixelOfTrailCappedAndNoneBelowAQuarter) {
  EXPECT_EQ(motion_samples(0.0), 1);
  EXPECT_EQ(motion_samples(0.2499), 1);
  EXPECT_EQ(motion_samples(0.25), 2);
  EXPECT_EQ(motion_samples(1.0), 2);
  EXPECT_EQ(motion_samples(1.01), 3);
  EXPECT_EQ(motion_samples(3.9), 8);
  EXPECT_EQ(motion_samples(100.0), kMaxMotionSamples);
  EXPECT_EQ(motion_samples(std::numeric_limits<double>::quiet_NaN()), 1);
}

TEST(MotionBlur, ArticulationMovesAtItsRate) {
  const BoomArticulation a = articulation_at({0.5, -0.1, 2.0}, {0.2, 0.4, -1.0}, 0.005);
  EXPECT_DOUBLE_EQ(a.elevation_rad, 0.501);
  EXPECT_DOUBLE_EQ(a.azimuth_rad, -0.098);
  EXPECT_DOUBLE_EQ(a.extension_m, 1.995);
  EXPECT_FALSE(moves({}));
  EXPECT_TRUE(moves({0, 0, 1e-9}));
}

// The telescope's extension moving along a pinhole camera's x axis at a known depth: every one of
// its vertices moves f v T / z pixels; the fixed part stays; no rate or no exposure, no trail.
TEST(MotionBlur, TrailIsTheLargestVertexDisplacementInTheImage) {
  Rig rig = Rig::paper_default();
  RigCamera& cam = rig.cameras[0];
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d(-1, 0, 0), R.col(1) = Eigen::Vector3d(0, 0, 1),
  R.col(2) = Eigen::Vector3d(0, 1, 0);
  cam.T_body_cam = Pose::from(R, rig.boom.pivot_body_m + Eigen::Vector3d(-3.5, -6.0, 0));
  BoomModel boom;
  Mesh m;
  m.positions_m = {{2.5f, 0, -1}, {4.5f, 0, -1}, {3.5f, 0, 1}};
  m.indices = {0, 1, 2};
  boom.telescope.meshes.push_back(m);
  boom.fixed.meshes.push_back(m);
  const BoomArticulation mid{0, 0, 0.5}, rate{0, 0, 2.0};
  const double px = boom_motion_px(boom, rig.boom.pivot_body_m, cam, mid, rate, 0.01);
  EXPECT_NEAR(px, cam.model.fx_px * 2.0 * 0.01 / 6.0, 1e-9);
  EXPECT_EQ(boom_motion_px(boom, rig.boom.pivot_body_m, cam, mid, {}, 0.01), 0.0);
  EXPECT_EQ(boom_motion_px(boom, rig.boom.pivot_body_m, cam, mid, rate, 0.0), 0.0);
  // Turning about the pivot (about the optical axis here): the vertex farthest from the pivot,
  // (4.5, 0, -1) m, moves most, its distance times the angle.
  const double turn = boom_motion_px(boom, rig.boom.pivot_body_m, cam, {0, 0, 0}, {0.1, 0, 0}, 0.01);
  EXPECT_NEAR(turn, cam.model.fx_px * std::hypot(4.5, 1.0) * 1e-3 / 6.0, 1e-6 * turn);
}

}  // namespace
}  // namespace augrig
