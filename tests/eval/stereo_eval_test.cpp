// Rectification and the true disparity against independent geometry: rectified rows agree and
// disparity = f B / z for points projected by hand through R1, R2; the true disparity of a plane
// seen through strongly distorted cameras against the plane intersected along each rectified ray,
// its raw depth made with cv::undistortPoints.
#include "eval/stereo_eval.hpp"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

namespace augrig::eval {
namespace {

CameraModel radtan(double fx, double fy, double cx, double cy, std::array<double, 5> k) {
  CameraModel c;
  c.width_px = 320, c.height_px = 240;
  c.fx_px = fx, c.fy_px = fy, c.cx_px = cx, c.cy_px = cy;
  c.distortion = DistortionModel::kRadTan;
  c.coeffs = k;
  return c;
}

struct Rig2 {
  CameraModel left = radtan(300, 296, 158.5, 122.0, {-0.25, 0.07, 0.001, -0.0008, 0.0});
  CameraModel right = radtan(304, 301, 163.0, 117.5, {-0.21, 0.05, -0.0006, 0.0009, 0.0});
  Pose T_right_left = Pose::from(
      (Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(-0.01, Eigen::Vector3d::UnitX()))
          .toRotationMatrix(),
      Eigen::Vector3d(-0.5, 0.01, 0.004));
};

// Points projected by hand through R1 and R2: rectified rows agree and disparity = f B / z > 0.
void expect_rows_and_disparity(const Rectification& r, const Pose& T_right_left) {
  EXPECT_NEAR(r.baseline_m, T_right_left.translation_m.norm(), 1e-9);
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(0.3, -0.2, 8.0), Eigen::Vector3d(-1.5, 0.7, 20.0), Eigen::Vector3d(0.0, 0.0, 3.0)}) {
    const Eigen::Vector3d a = r.R_rect_raw[0] * p;
    const Eigen::Vector3d b = r.R_rect_raw[1] * (T_right_left * p);
    const double u1 = r.f_px * a.x() / a.z() + r.cx_px, v1 = r.f_px * a.y() / a.z() + r.cy_px;
    const double u2 = r.f_px * b.x() / b.z() + r.cx_px, v2 = r.f_px * b.y() / b.z() + r.cy_px;
    EXPECT_NEAR(v1, v2, 1e-6) << "rectified rows";
    EXPECT_NEAR(u1 - u2, r.f_px * r.baseline_m / a.z(), 1e-6) << "disparity";
    EXPECT_GT(u1 - u2, 0);
  }
}

TEST(StereoEval, RectifiedRowsAgreeAndDisparityIsFocalTimesBaselineOverDepth) {
  const Rig2 rig;
  auto r = rectify_rig(rig.left, rig.right, rig.T_right_left);
  ASSERT_TRUE(r) << r.error().message;
  expect_rows_and_disparity(*r, rig.T_right_left);
}

TEST(StereoEval, TrueDisparityOfAPlaneThroughDistortedCameras) {
  const Rig2 rig;
  auto r = rectify_rig(rig.left, rig.right, rig.T_right_left);
  ASSERT_TRUE(r) << r.error().message;
  // A slanted plane n . P = c in the left camera frame, over raw pixels [40, 280) x [30, 210).
  const Eigen::Vector3d n = Eigen::Vector3d(0.05, -0.1, 1.0).normalized();
  const double c = 9.0;
  std::vector<cv::Point2d> px;
  for (int y = 0; y < 240; ++y)
    for (int x = 0; x < 320; ++x) px.emplace_back(x, y);
  std::vector<cv::Point2d> xy;
  cv::Mat K, D;
  cv::eigen2cv(rig.left.K(), K);
  cv::eigen2cv(Eigen::VectorXd(rig.left.distortion_coeffs()), D);
  cv::undistortPoints(px, xy, K, D, cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200, 1e-14));
  DepthImage depth{320, 240, std::vector<float>(320 * 240, DepthImage::kNone)};
  for (int y = 30; y < 210; ++y)
    for (int x = 40; x < 280; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * 320 + x;
      const Eigen::Vector3d d(xy[i].x, xy[i].y, 1.0);
      depth.z_m[i] = static_cast<float>(c / n.dot(d));  // z of the ray's hit (d has z = 1)
    }
  const cv::Mat disp = true_disparity(*r, depth);
  ASSERT_EQ(disp.type(), CV_32FC1);
  int checked = 0, nan_outside = 0;
  double worst = 0;
  const Eigen::Matrix3d Rt = r->R_rect_raw[0].transpose();
  for (int v = 0; v < r->height; ++v)
    for (int u = 0; u < r->width; ++u) {
      const float got = disp.at<float>(v, u);
      const double mx = r->map_x[0].at<float>(v, u), my = r->map_y[0].at<float>(v, u);
      // Well inside the plane's raw box: compare; well outside: none.
      if (mx >= 42 && mx <= 277 && my >= 32 && my <= 207) {
        const Eigen::Vector3d d =
            Rt * Eigen::Vector3d((u - r->cx_px) / r->f_px, (v - r->cy_px) / r->f_px, 1.0);
        const double s = c / n.dot(d);  // the rectified ray's hit: z_rect = s
        const double expect = r->f_px * r->baseline_m / s;
        ASSERT_TRUE(std::isfinite(got)) << u << "," << v;
        worst = std::max(worst, std::abs(got - expect));
        ++checked;
      } else if (mx < 38 || mx > 282 || my < 28 || my > 212) {
        nan_outside += std::isnan(got);
        EXPECT_TRUE(std::isnan(got)) << u << "," << v;
      }
    }
  EXPECT_GT(checked, 20000);
  EXPECT_GT(nan_outside, 5000);
  // Bilinear depth between raw pixel centres on a plane: about 1e-4 px of disparity.
  EXPECT_LT(worst, 2e-3) << "worst true-disparity error, px";
}

TEST(StereoEval, LabelsFollowTheirNearestRawPixelAndBadRigsAreErrors) {
  const Rig2 rig;
  auto r = rectify_rig(rig.left, rig.right, rig.T_right_left);
  ASSERT_TRUE(r);
  cv::Mat labels(240, 320, CV_8UC1);
  for (int y = 0; y < 240; ++y)
    for (int x = 0; x < 320; ++x)
      labels.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>((x / 10 + y / 10) % 5);
  const cv::Mat rl = rectify_labels(*r, labels, 9);
  for (int v = 0; v < 240; v += 7)
    for (int u = 0; u < 320; u += 7) {
      const int x = static_cast<int>(std::lround(r->map_x[0].at<float>(v, u)));
      const int y = static_cast<int>(std::lround(r->map_y[0].at<float>(v, u)));
      if (x < 0 || y < 0 || x >= 320 || y >= 240) continue;
      // At an exact .5 the two roundings may differ: skip those.
      if (std::abs(r->map_x[0].at<float>(v, u) - x) > 0.49f ||
          std::abs(r->map_y[0].at<float>(v, u) - y) > 0.49f)
        continue;
      EXPECT_EQ(rl.at<std::uint8_t>(v, u), labels.at<std::uint8_t>(y, x)) << u << "," << v;
    }
  CameraModel other = rig.right;
  other.width_px = 640;
  auto bad = rectify_rig(rig.left, other, rig.T_right_left);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("differ in size"), std::string::npos) << bad.error().message;
  auto same = rectify_rig(rig.left, rig.right, Pose::identity());
  ASSERT_FALSE(same);
  EXPECT_NE(same.error().message.find("no stereo baseline"), std::string::npos);
}

// One radtan and one fisheye camera (a Kalibr rig may mix them): rectified rows agree, disparity
// is f B / z, every rectified pixel sees into both raw images (alpha 0), and each camera's map is
// what OpenCV's own undistort-rectify map for its lens model gives with the same R and P.
TEST(StereoEval, ARadtanAndAFisheyeCameraAreRectifiedTogether) {
  Rig2 rig;
  rig.right.distortion = DistortionModel::kEquidistant;
  rig.right.coeffs = {-0.02, 0.004, -0.001, 0.0002, 0.0};
  for (const bool fisheye_left : {false, true}) {
    SCOPED_TRACE(fisheye_left ? "fisheye left" : "fisheye right");
    const CameraModel left = fisheye_left ? rig.right : rig.left;
    const CameraModel right = fisheye_left ? rig.left : rig.right;
    auto r = rectify_rig(left, right, rig.T_right_left);
    ASSERT_TRUE(r) << r.error().message;
    expect_rows_and_disparity(*r, rig.T_right_left);
    const cv::Mat P = (cv::Mat_<double>(3, 3) << r->f_px, 0, r->cx_px, 0, r->f_px, r->cy_px, 0, 0, 1);
    std::size_t outside = 0;
    double worst = 0;
    for (int i = 0; i < 2; ++i) {
      const CameraModel& cam = i == 0 ? left : right;
      cv::Mat K, D, R, mx, my;
      cv::eigen2cv(cam.K(), K);
      cv::eigen2cv(r->R_rect_raw[i], R);
      if (cam.distortion == DistortionModel::kEquidistant) {
        cv::eigen2cv(Eigen::Vector4d(cam.coeffs[0], cam.coeffs[1], cam.coeffs[2], cam.coeffs[3]), D);
        cv::fisheye::initUndistortRectifyMap(K, D, R, P, cv::Size(320, 240), CV_32FC1, mx, my);
      } else {
        cv::eigen2cv(Eigen::VectorXd(cam.distortion_coeffs()), D);
        cv::initUndistortRectifyMap(K, D, R, P, cv::Size(320, 240), CV_32FC1, mx, my);
      }
      for (int v = 0; v < 240; ++v)
        for (int u = 0; u < 320; ++u) {
          const float x = r->map_x[i].at<float>(v, u), y = r->map_y[i].at<float>(v, u);
          outside += !(x >= -0.5f && x <= 319.5f && y >= -0.5f && y <= 239.5f);
          worst = std::max({worst, std::abs(static_cast<double>(x - mx.at<float>(v, u))),
                            std::abs(static_cast<double>(y - my.at<float>(v, u)))});
        }
    }
    EXPECT_EQ(outside, 0u) << "rectified pixels that see outside a raw image";
    EXPECT_LT(worst, 1e-3) << "px from OpenCV's maps";
    // Not a thin sliver: the view keeps most of the raw images' field.
    EXPECT_GT(r->f_px, 250.0);
    EXPECT_LT(r->f_px, 400.0);
  }
}

// The scores against hand-counted ones: classes, the boom left out, bad-pixel rates, range.
TEST(StereoEval, ScoresCountByClassAndLeaveTheBoomOut) {
  cv::Mat t(1, 6, CV_32FC1), e(1, 6, CV_32FC1), cls(1, 6, CV_8UC1), mask(1, 6, CV_8UC1);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float tv[6] = {10, 10, 10, 20, 20, nan}, ev[6] = {10.5f, 14, nan, 18, 20, 5};
  const std::uint8_t cv_[6] = {1, 1, 2, 3, 4, 0}, mv[6] = {2, 3, 2, 2, 3, 0};
  for (int x = 0; x < 6; ++x) {
    t.at<float>(0, x) = tv[x], e.at<float>(0, x) = ev[x];
    cls.at<std::uint8_t>(0, x) = cv_[x], mask.at<std::uint8_t>(0, x) = mv[x];
  }
  const double fb = 100.0;  // f * B: z = 100 / d
  const PairScore s = score_disparity(t, e, cls, mask, fb);
  EXPECT_EQ(s.all[0].pixels, 5);  // the NaN truth is not counted
  EXPECT_EQ(s.all[0].valid, 4);
  EXPECT_DOUBLE_EQ(s.all[0].valid_pct(), 80.0);
  EXPECT_EQ(s.all[1].pixels, 2);
  EXPECT_DOUBLE_EQ(s.all[1].mean_px(), (0.5 + 4.0) / 2);
  EXPECT_DOUBLE_EQ(s.all[1].rms_px(), std::sqrt((0.25 + 16.0) / 2));
  EXPECT_EQ(s.all[1].bad1, 1);
  EXPECT_EQ(s.all[1].bad3, 1);
  EXPECT_DOUBLE_EQ(s.all[1].bad3_pct(), 50.0);
  EXPECT_EQ(s.all[2].valid, 0);
  EXPECT_TRUE(std::isnan(s.all[2].mean_px()));
  EXPECT_DOUBLE_EQ(s.all[3].range_mean_m(), 100.0 / 18 - 100.0 / 20);
  // The boom (bit 0) at x = 1 and 4: left out of boom_excluded.
  EXPECT_EQ(s.boom_excluded[0].pixels, 3);
  EXPECT_EQ(s.boom_excluded[1].pixels, 1);
  EXPECT_DOUBLE_EQ(s.boom_excluded[1].mean_px(), 0.5);
  EXPECT_EQ(s.boom_excluded[4].pixels, 0);
  PairScore twice = s;
  twice.merge(s);
  EXPECT_EQ(twice.all[0].pixels, 10);
  EXPECT_DOUBLE_EQ(twice.all[1].rms_px(), s.all[1].rms_px());
}

}  // namespace
}  // namespace augrig::eval

namespace augrig::eval {
namespace {

// Every rectified pixel whose raw pixel lies in the box is inside rectified_box(), through a
// strongly distorting lens; and the box is not much larger than those pixels' extent.
TEST(StereoEval, RectifiedBoxHoldsEveryRectifiedPixelOfTheRawBox) {
  const Rig2 rig;
  auto r = rectify_rig(rig.left, rig.right, rig.T_right_left);
  ASSERT_TRUE(r) << r.error().message;
  for (const PixelBox& box : {PixelBox{40, 30, 120, 90}, PixelBox{0, 0, 60, 50}, PixelBox{250, 180, 320, 240},
                              PixelBox{150, 100, 151, 101}}) {
    const cv::Rect rect = rectified_box(*r, rig.left, box);
    int x0 = r->width, y0 = r->height, x1 = 0, y1 = 0, inside = 0;
    for (int v = 0; v < r->height; ++v)
      for (int u = 0; u < r->width; ++u) {
        const int x = static_cast<int>(std::lround(r->map_x[0].at<float>(v, u)));
        const int y = static_cast<int>(std::lround(r->map_y[0].at<float>(v, u)));
        if (x < box.x0 || x >= box.x1 || y < box.y0 || y >= box.y1) continue;
        ++inside;
        EXPECT_TRUE(rect.contains(cv::Point(u, v)))
            << "(" << u << ", " << v << ") box " << box.x0 << "," << box.y0;
        x0 = std::min(x0, u), y0 = std::min(y0, v), x1 = std::max(x1, u + 1), y1 = std::max(y1, v + 1);
      }
    if (inside) {
      EXPECT_LE(rect.width, x1 - x0 + 8);
      EXPECT_LE(rect.height, y1 - y0 + 8);
    }
  }
  EXPECT_TRUE(rectified_box(*r, rig.left, PixelBox{}).empty());
}

}  // namespace
}  // namespace augrig::eval
