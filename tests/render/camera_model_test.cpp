// CameraModel against OpenCV as the oracle: cv::projectPoints, cv::fisheye::projectPoints and
// cv::undistortPoints (with tight termination criteria), plus round trips over whole images.
#include "render/camera_model.hpp"

#include <cmath>
#include <cstdio>
#include <ctime>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "core/conventions.hpp"

namespace augrig {
namespace {

CameraModel radtan_camera() {
  CameraModel m;
  m.width_px = 1280;
  m.height_px = 960;
  m.fx_px = 1012.3;
  m.fy_px = 1009.7;
  m.cx_px = 655.2;  // deliberately off-centre
  m.cy_px = 471.9;
  m.distortion = DistortionModel::kRadTan;
  m.coeffs = {-0.28, 0.09, 1.2e-3, -7e-4, -0.015};
  return m;
}

// The strong lens from the spec: its fold lies just outside the image corners.
CameraModel strong_radtan_camera() {
  CameraModel m;
  m.width_px = 1280;
  m.height_px = 960;
  m.fx_px = 950.0;
  m.fy_px = 948.0;
  m.cx_px = 650.3;
  m.cy_px = 470.6;
  m.distortion = DistortionModel::kRadTan;
  m.coeffs = {-0.35, 0.15, 1e-3, -5e-4, -0.03};
  return m;
}

CameraModel fisheye_camera() {
  CameraModel m;
  m.width_px = 1280;
  m.height_px = 960;
  m.fx_px = 420.5;
  m.fy_px = 419.8;
  m.cx_px = 644.1;
  m.cy_px = 476.3;
  m.distortion = DistortionModel::kEquidistant;
  m.coeffs = {-0.013, 0.021, -0.009, 0.0017, 0.0};
  return m;
}

cv::Mat cv_K(const CameraModel& m) {
  return (cv::Mat_<double>(3, 3) << m.fx_px, 0, m.cx_px, 0, m.fy_px, m.cy_px, 0, 0, 1);
}
cv::Mat cv_D(const CameraModel& m) {
  const Eigen::VectorXd d = m.distortion_coeffs();
  cv::Mat D(static_cast<int>(d.size()), 1, CV_64F);
  for (int i = 0; i < d.size(); ++i) D.at<double>(i) = d[i];
  return D;
}

// Full-image grid (every `step` px) plus the exact corners and edge midpoints.
std::vector<Eigen::Vector2d> image_grid(const CameraModel& m, int step) {
  std::vector<Eigen::Vector2d> pts;
  for (int v = 0; v < m.height_px; v += step) {
    for (int u = 0; u < m.width_px; u += step) pts.emplace_back(u, v);
  }
  const double W = m.width_px, H = m.height_px;
  for (double u : {-0.5, 0.0, W / 2, W - 1.0, W - 0.5}) {
    for (double v : {-0.5, 0.0, H / 2, H - 1.0, H - 0.5}) pts.emplace_back(u, v);
  }
  return pts;
}

TEST(CameraModel, RadTanProjectMatchesOpenCV) {
  const CameraModel m = radtan_camera();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> xy(-0.9, 0.9), z(0.5, 50.0);
  std::vector<cv::Point3d> obj;
  std::vector<Eigen::Vector3d> pts;
  while (pts.size() < 5000) {
    const double zz = z(rng);
    const Eigen::Vector3d p(xy(rng) * zz, xy(rng) * zz, zz);
    if (!(p.head<2>().norm() / p.z() < m.max_valid_radius())) continue;
    pts.push_back(p);
    obj.emplace_back(p.x(), p.y(), p.z());
  }
  std::vector<cv::Point2d> img;
  cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cv_K(m), cv_D(m), img);
  double max_err = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto uv = m.project(pts[i]);
    ASSERT_TRUE(uv.has_value()) << i;
    max_err = std::max(max_err, (*uv - Eigen::Vector2d(img[i].x, img[i].y)).norm());
  }
  EXPECT_LT(max_err, 1e-6);
}

TEST(CameraModel, NoDistortionProjectMatchesOpenCV) {
  CameraModel m = radtan_camera();
  m.distortion = DistortionModel::kNone;
  m.coeffs = {};
  std::vector<cv::Point3d> obj;
  for (int i = 0; i < 100; ++i) obj.emplace_back(0.03 * i - 1.5, 0.5 - 0.01 * i, 1.0 + 0.1 * i);
  std::vector<cv::Point2d> img;
  cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cv_K(m), cv::noArray(), img);
  for (std::size_t i = 0; i < obj.size(); ++i) {
    const auto uv = m.project({obj[i].x, obj[i].y, obj[i].z});
    ASSERT_TRUE(uv.has_value());
    EXPECT_NEAR(uv->x(), img[i].x, 1e-9);
    EXPECT_NEAR(uv->y(), img[i].y, 1e-9);
  }
  EXPECT_TRUE(std::isinf(m.max_valid_radius()));
}

TEST(CameraModel, FisheyeProjectMatchesOpenCV) {
  const CameraModel m = fisheye_camera();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ang(0.0, deg_to_rad(85.0)), phi(-kPi, kPi), dist(0.5, 40.0);
  std::vector<cv::Point3d> obj;
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 5000; ++i) {
    const double th = ang(rng), ph = phi(rng), d = dist(rng);
    const Eigen::Vector3d p(d * std::sin(th) * std::cos(ph), d * std::sin(th) * std::sin(ph),
                            d * std::cos(th));
    pts.push_back(p);
    obj.emplace_back(p.x(), p.y(), p.z());
  }
  obj.emplace_back(0, 0, 3);  // on the optical axis
  pts.emplace_back(0, 0, 3);
  std::vector<cv::Point2d> img;
  cv::fisheye::projectPoints(obj, img, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cv_K(m), cv_D(m));
  double max_err = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto uv = m.project(pts[i]);
    ASSERT_TRUE(uv.has_value()) << i;
    max_err = std::max(max_err, (*uv - Eigen::Vector2d(img[i].x, img[i].y)).norm());
  }
  EXPECT_LT(max_err, 1e-6);
}

TEST(CameraModel, RayRoundTripOverWholeImageStrongRadTan) {
  for (const CameraModel& m : {strong_radtan_camera(), radtan_camera()}) {
    double max_err = 0;
    for (const Eigen::Vector2d& uv : image_grid(m, 4)) {
      const auto r = m.ray(uv);
      ASSERT_TRUE(r.has_value()) << uv.transpose();
      EXPECT_NEAR(r->norm(), 1.0, 1e-12);
      const auto back = m.project(*r);
      ASSERT_TRUE(back.has_value()) << uv.transpose();
      max_err = std::max(max_err, (*back - uv).norm());
    }
    EXPECT_LT(max_err, 1e-6);
  }
}

TEST(CameraModel, RayRoundTripFisheye) {
  const CameraModel m = fisheye_camera();
  double max_err = 0;
  for (const Eigen::Vector2d& uv : image_grid(m, 4)) {
    const auto r = m.ray(uv);
    ASSERT_TRUE(r.has_value()) << uv.transpose();
    const auto back = m.project(*r);
    ASSERT_TRUE(back.has_value()) << uv.transpose();
    max_err = std::max(max_err, (*back - uv).norm());
  }
  EXPECT_LT(max_err, 1e-6);
}

TEST(CameraModel, FisheyeRaysBeyondNinetyDegrees) {
  // A lens with a field of view beyond 180 degrees: the corners of the image look backwards.
  CameraModel m = fisheye_camera();
  m.fx_px = m.fy_px = 250.0;
  m.coeffs = {0.01, -0.002, 0.0003, -0.00002, 0.0};
  EXPECT_DOUBLE_EQ(m.max_valid_radius(), kPi);  // monotonic all the way round
  for (double th_deg : {95.0, 110.0, 130.0}) {
    const double th = deg_to_rad(th_deg);
    const Eigen::Vector3d dir(std::sin(th) * 0.6, std::sin(th) * 0.8, std::cos(th));
    const auto uv = m.project(dir * 5.0);
    ASSERT_TRUE(uv.has_value()) << th_deg;
    const auto r = m.ray(*uv);
    ASSERT_TRUE(r.has_value()) << th_deg;
    EXPECT_LT((*r - dir).norm(), 1e-9) << th_deg;
    EXPECT_FALSE(m.undistort(*uv).has_value()) << "no normalised coordinates behind the camera";
  }
  EXPECT_FALSE(m.project({0, 0, -1}).has_value());  // straight behind: theta = pi
  EXPECT_FALSE(m.project({0, 0, 0}).has_value());
}

TEST(CameraModel, UndistortMatchesOpenCV) {
  const CameraModel m = radtan_camera();
  std::vector<cv::Point2d> src;
  for (const Eigen::Vector2d& uv : image_grid(m, 16)) src.emplace_back(uv.x(), uv.y());
  std::vector<cv::Point2d> dst;
  cv::undistortPoints(src, dst, cv_K(m), cv_D(m), cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 2000, 1e-13));
  double max_err = 0;
  for (std::size_t i = 0; i < src.size(); ++i) {
    const auto xy = m.undistort({src[i].x, src[i].y});
    ASSERT_TRUE(xy.has_value()) << i;
    // Compare in pixels of the undistorted pinhole image.
    max_err = std::max(max_err, std::hypot((xy->x() - dst[i].x) * m.fx_px, (xy->y() - dst[i].y) * m.fy_px));
  }
  EXPECT_LT(max_err, 1e-6);
}

TEST(CameraModel, FisheyeUndistortMatchesOpenCV) {
  const CameraModel m = fisheye_camera();
  std::vector<cv::Point2d> src;
  // Stay within ~75 degrees: normalised coordinates (tan theta) explode towards 90.
  for (const Eigen::Vector2d& uv : image_grid(m, 16)) {
    const auto r = m.ray(uv);
    if (r && r->z() > std::cos(deg_to_rad(75.0))) src.emplace_back(uv.x(), uv.y());
  }
  ASSERT_GT(src.size(), 1000u);
  std::vector<cv::Point2d> dst;
  cv::fisheye::undistortPoints(src, dst, cv_K(m), cv_D(m), cv::noArray(), cv::noArray(),
                               cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 200, 1e-15));
  double max_err = 0;
  for (std::size_t i = 0; i < src.size(); ++i) {
    const auto xy = m.undistort({src[i].x, src[i].y});
    ASSERT_TRUE(xy.has_value()) << i;
    const double n = std::max(1.0, xy->norm());  // relative far out, where tan theta is large
    max_err = std::max(max_err, (*xy - Eigen::Vector2d(dst[i].x, dst[i].y)).norm() / n);
  }
  EXPECT_LT(max_err, 1e-9);
}

TEST(CameraModel, MaxValidRadiusRadTan) {
  const CameraModel m = strong_radtan_camera();
  const double r = m.max_valid_radius();
  ASSERT_TRUE(std::isfinite(r));
  // The derivative of r * radial(r) vanishes there and is positive just inside.
  const auto& k = m.coeffs;
  auto dfdr = [&](double rr) {
    const double s = rr * rr;
    return 1 + 3 * k[0] * s + 5 * k[1] * s * s + 7 * k[4] * s * s * s;
  };
  EXPECT_NEAR(dfdr(r), 0.0, 1e-9);
  EXPECT_GT(dfdr(0.999 * r), 0.0);
  EXPECT_LT(dfdr(1.001 * r), 0.0);
  // project() refuses beyond it and accepts inside.
  EXPECT_TRUE(m.project({0.99 * r, 0.0, 1.0}).has_value());
  EXPECT_FALSE(m.project({1.01 * r, 0.0, 1.0}).has_value());
  EXPECT_FALSE(m.project({0.0, 1.01 * r * 3.0, 3.0}).has_value());
  // ... and points behind or in the plane of the camera.
  EXPECT_FALSE(m.project({0.1, 0.1, -1.0}).has_value());
  EXPECT_FALSE(m.project({0.1, 0.1, 0.0}).has_value());
  // The overload taking the radius gives the same answers.
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.99 * r, 0.0, 1.0), Eigen::Vector3d(1.01 * r, 0.0, 1.0),
                                   Eigen::Vector3d(0.3, -0.2, 2.0), Eigen::Vector3d(0.1, 0.1, -1.0)}) {
    const auto a = m.project(p), b = m.project(p, r);
    ASSERT_EQ(a.has_value(), b.has_value());
    if (a) {
      EXPECT_EQ(*a, *b);
    }
  }
  // A pixel beyond the fold's image radius has no ray.
  auto f = [&](double rr) {
    return rr * (1 + k[0] * rr * rr + k[1] * std::pow(rr, 4) + k[4] * std::pow(rr, 6));
  };
  EXPECT_FALSE(m.ray({m.cx_px + 1.05 * f(r) * m.fx_px, m.cy_px}).has_value());

  // Barrel-only with k1 > 0 and no higher terms: monotonic everywhere.
  CameraModel mono = m;
  mono.coeffs = {0.1, 0.0, 0.0, 0.0, 0.0};
  EXPECT_TRUE(std::isinf(mono.max_valid_radius()));
  // Pure k1 < 0: fold at r^2 = -1 / (3 k1).
  mono.coeffs = {-0.2, 0.0, 0.0, 0.0, 0.0};
  EXPECT_NEAR(mono.max_valid_radius(), std::sqrt(1.0 / 0.6), 1e-12);
}

TEST(CameraModel, MaxValidRadiusEquidistant) {
  CameraModel m = fisheye_camera();
  m.coeffs = {-0.3, 0.0, 0.0, 0.0, 0.0};  // theta_d' = 1 - 0.9 theta^2: fold at theta = 1/sqrt(0.9)
  const double th = m.max_valid_radius();
  EXPECT_NEAR(th, 1.0 / std::sqrt(0.9), 1e-12);
  const Eigen::Vector3d inside(std::sin(0.99 * th), 0, std::cos(0.99 * th));
  const Eigen::Vector3d outside(std::sin(1.01 * th), 0, std::cos(1.01 * th));
  EXPECT_TRUE(m.project(inside).has_value());
  EXPECT_FALSE(m.project(outside).has_value());
}

TEST(CameraModel, PinholeFromHfov) {
  const CameraModel m = CameraModel::pinhole_from_hfov(1280, 960, deg_to_rad(56.0));
  EXPECT_NEAR(m.fx_px, 640.0 / std::tan(deg_to_rad(28.0)), 1e-9);
  EXPECT_EQ(m.fx_px, m.fy_px);
  EXPECT_DOUBLE_EQ(m.cx_px, 639.5);
  EXPECT_DOUBLE_EQ(m.cy_px, 479.5);
  EXPECT_EQ(m.distortion, DistortionModel::kNone);
  // The outer edges of the outermost pixels (u = -0.5 and W - 0.5) span exactly 56 degrees.
  const auto a = m.ray({-0.5, m.cy_px});
  const auto b = m.ray({1279.5, m.cy_px});
  ASSERT_TRUE(a && b);
  EXPECT_NEAR(rad_to_deg(std::acos(a->dot(*b))), 56.0, 1e-9);
  EXPECT_EQ(m.distortion_name(), "none");
  EXPECT_EQ(m.K()(0, 2), m.cx_px);
}

TEST(CameraModel, RayPerPixelSpeed) {
  // The per-pixel ray map for 1280x960 is precomputed once per camera (target < 0.3 us per pixel).
  // Process CPU time, not wall time: the machine running the tests may be shared and loaded.
  const CameraModel m = strong_radtan_camera();
  double sink = 0;
  const std::clock_t c0 = std::clock();
  for (int v = 0; v < m.height_px; ++v) {
    for (int u = 0; u < m.width_px; ++u) {
      const auto r = m.ray({u, v});
      sink += r ? r->z() : 0.0;
    }
  }
  const double s = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
  const double us_per_px = s * 1e6 / (m.width_px * m.height_px);
  RecordProperty("ray_us_per_px", std::to_string(us_per_px));
  std::printf("ray(): %.3f us CPU per pixel\n", us_per_px);
  EXPECT_GT(sink, 0.0);
#ifdef NDEBUG
  EXPECT_LT(us_per_px, 1.0);  // margin over the 0.3 target for slower CPUs; unoptimised builds skip it
#endif
}

}  // namespace
}  // namespace augrig

namespace augrig {
namespace {

// Coefficients far beyond camera_model_problem()'s bounds (a rig loader rejects them; a model
// built in code may still carry them): every function answers without a hang and without a
// non-finite ray or pixel.
TEST(CameraModel, ExtremeCoefficientsGiveFiniteAnswersOrNone) {
  for (const double k : {1e300, -1e300, 1e308, -1e308}) {
    for (const DistortionModel d : {DistortionModel::kEquidistant, DistortionModel::kRadTan}) {
      CameraModel m = CameraModel::pinhole_from_hfov(64, 48, deg_to_rad(60));
      m.distortion = d;
      m.coeffs = {k, k, d == DistortionModel::kRadTan ? 0.0 : k, d == DistortionModel::kRadTan ? 0.0 : k,
                  0.0};
      EXPECT_FALSE(std::isnan(m.max_valid_radius())) << k;
      for (int v = 0; v < 48; v += 7) {
        for (int u = 0; u < 64; u += 7) {
          if (const auto r = m.ray({u, v})) {
            EXPECT_TRUE(r->allFinite()) << k << " " << u << "," << v;
          }
          if (const auto xy = m.undistort({u, v})) {
            EXPECT_TRUE(xy->allFinite()) << k;
          }
        }
      }
      for (const Eigen::Vector3d& p :
           {Eigen::Vector3d(0.1, 0.2, 1.0), Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(0, 0, 1)}) {
        if (const auto uv = m.project(p)) {
          EXPECT_TRUE(uv->allFinite()) << k << " " << p.transpose();
        }
      }
    }
  }
}

}  // namespace
}  // namespace augrig
