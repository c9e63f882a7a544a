// Ground truth against OpenCV as the oracle: each left receiver pixel undistorted with
// cv::undistortPoints, placed at its depth, moved into the right camera and projected with
// cv::projectPoints must land where right_correspondence() says; and the depth encodings.
#include "render/ground_truth.hpp"

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

namespace augrig {
namespace {

CameraModel radtan_camera(double fx, double fy, double cx, double cy, std::array<double, 5> k) {
  CameraModel c;
  c.width_px = 320;
  c.height_px = 240;
  c.fx_px = fx, c.fy_px = fy, c.cx_px = cx, c.cy_px = cy;
  c.distortion = DistortionModel::kRadTan;
  c.coeffs = k;
  return c;
}

cv::Mat K_of(const CameraModel& c) {
  cv::Mat K;
  cv::eigen2cv(c.K(), K);
  return K;
}
cv::Mat D_of(const CameraModel& c) {
  cv::Mat D;
  const Eigen::VectorXd d = c.distortion_coeffs();
  cv::eigen2cv(d, D);
  return D;
}

// A slanted plane in front of the left camera over part of the image (the rest: no receiver).
DepthImage slanted_plane(const CameraModel& left) {
  DepthImage d{
      left.width_px, left.height_px,
      std::vector<float>(static_cast<std::size_t>(left.width_px) * left.height_px, DepthImage::kNone)};
  for (int y = 30; y < 200; ++y)
    for (int x = 40; x < 300; ++x)
      d.z_m[static_cast<std::size_t>(y) * d.width + x] = 12.0f + 0.01f * x + 0.02f * y;
  return d;
}

TEST(GroundTruth, CorrespondenceAgreesWithOpenCV) {
  // Off-centre principal points, fx != fy, strong distortion in both, a rotated and offset rig.
  const CameraModel left = radtan_camera(410, 395, 150.5, 128.25, {-0.28, 0.09, 0.0012, -0.0007, -0.01});
  const CameraModel right = radtan_camera(402, 407, 166.0, 113.5, {-0.22, 0.05, -0.0009, 0.0011, 0.0});
  const Pose T_right_left = Pose::from((Eigen::AngleAxisd(0.03, Eigen::Vector3d::UnitY()) *
                                        Eigen::AngleAxisd(-0.015, Eigen::Vector3d::UnitX()))
                                           .toRotationMatrix(),
                                       Eigen::Vector3d(-0.6, 0.02, 0.01));
  const DepthImage depth = slanted_plane(left);
  const std::vector<float> uv = right_correspondence(depth, left, right, T_right_left);
  ASSERT_EQ(uv.size(), 2u * 320 * 240);

  // The oracle on every 7th pixel of the plane, and NaN off it.
  std::vector<cv::Point2d> px;
  for (int y = 0; y < 240; y += 7)
    for (int x = 0; x < 320; x += 7) px.emplace_back(x, y);
  std::vector<cv::Point2d> xy;
  cv::undistortPoints(px, xy, K_of(left), D_of(left), cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200, 1e-14));
  std::vector<cv::Point3d> pts;
  std::vector<std::size_t> idx;
  int none = 0;
  for (std::size_t k = 0; k < px.size(); ++k) {
    const std::size_t i = static_cast<std::size_t>(px[k].y) * 320 + static_cast<std::size_t>(px[k].x);
    const float z = depth.z_m[i];
    if (!(z < DepthImage::kNone)) {
      EXPECT_TRUE(std::isnan(uv[2 * i]) && std::isnan(uv[2 * i + 1])) << px[k];
      ++none;
      continue;
    }
    const Eigen::Vector3d p = T_right_left * Eigen::Vector3d(xy[k].x * z, xy[k].y * z, z);
    pts.emplace_back(p.x(), p.y(), p.z());
    idx.push_back(i);
  }
  ASSERT_GT(none, 100);
  ASSERT_GT(pts.size(), 500u);
  std::vector<cv::Point2d> proj;
  cv::projectPoints(pts, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K_of(right), D_of(right), proj);
  double worst = 0;
  for (std::size_t k = 0; k < pts.size(); ++k) {
    const double du = uv[2 * idx[k]] - proj[k].x, dv = uv[2 * idx[k] + 1] - proj[k].y;
    worst = std::max(worst, std::hypot(du, dv));
  }
  // float32 outputs at a few hundred px: ~3e-5 px of rounding; rays from float maps ~1e-4 px.
  EXPECT_LT(worst, 2e-3) << "worst distance to cv::projectPoints, px";
}

TEST(GroundTruth, PointsTheRightCameraCannotSeeAreNaN) {
  CameraModel cam;
  cam.width_px = 64, cam.height_px = 48, cam.fx_px = cam.fy_px = 50, cam.cx_px = 31.5, cam.cy_px = 23.5;
  DepthImage d{64, 48, std::vector<float>(64 * 48, 5.0f)};
  // The right camera 10 m ahead of the left one: every point at 5 m is behind it.
  const Pose ahead = Pose::from(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, -10));
  for (float v : right_correspondence(d, cam, cam, ahead)) EXPECT_TRUE(std::isnan(v));
  // The same camera: every pixel maps to itself.
  const std::vector<float> same = right_correspondence(d, cam, cam, Pose::identity());
  for (int y = 0; y < 48; y += 5)
    for (int x = 0; x < 64; x += 5) {
      const std::size_t i = static_cast<std::size_t>(y) * 64 + x;
      EXPECT_NEAR(same[2 * i], x, 1e-4);
      EXPECT_NEAR(same[2 * i + 1], y, 1e-4);
    }
  // A depth image of another size than the left camera's: nothing (all NaN), no crash.
  DepthImage small{10, 10, std::vector<float>(100, 5.0f)};
  for (float v : right_correspondence(small, cam, cam, Pose::identity())) EXPECT_TRUE(std::isnan(v));
}

TEST(GroundTruth, DepthEncodings) {
  DepthImage d{5, 1, {DepthImage::kNone, 22.1904f, 0.0002f, 65.5349f, 80.0f}};
  const std::vector<float> f = depth_with_nan(d);
  EXPECT_TRUE(std::isnan(f[0]));
  EXPECT_FLOAT_EQ(f[1], 22.1904f);
  EXPECT_FLOAT_EQ(f[4], 80.0f);
  const std::vector<std::uint16_t> mm = depth_mm_u16(d);
  EXPECT_EQ(mm[0], 0) << "no receiver";
  EXPECT_EQ(mm[1], 22190);
  EXPECT_EQ(mm[2], 1) << "a receiver pixel is never 0 (no receiver)";
  EXPECT_EQ(mm[3], 65535);
  EXPECT_EQ(mm[4], 65535) << "saturated";
}

}  // namespace
}  // namespace augrig
