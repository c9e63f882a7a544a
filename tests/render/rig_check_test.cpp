// The rig summary against independent geometry (the field of view from the intrinsics' closed form,
// the receptacle's pixel from OpenCV's projectPoints), and each warning raised by the mistake it
// names and by nothing else on the paper's rig.
#include "render/rig_check.hpp"

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "core/conventions.hpp"

namespace augrig {
namespace {

bool has_warning(const RigSummary& s, const std::string& text) {
  for (const std::string& w : s.warnings)
    if (w.find(text) != std::string::npos) return true;
  return false;
}

Eigen::Vector3d builtin_receptacle() {
  Eigen::Vector3d r;
  make_builtin_receiver(&r);
  return r;
}

TEST(RigCheck, ThePapersRigInNumbers) {
  const Rig rig = Rig::paper_default();
  const RigSummary s = summarize_rig(rig, BoomDimensions{}, builtin_receptacle());
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
  ASSERT_EQ(s.cameras.size(), 2u);
  EXPECT_NEAR(s.baseline_m, 0.5, 1e-12);
  EXPECT_NEAR(s.axes_angle_deg, 0.0, 1e-6);
  for (const RigCameraSummary& k : s.cameras) {
    SCOPED_TRACE(k.name);
    const CameraModel& m = rig.cameras[&k - s.cameras.data()].model;
    // A pinhole's field through its principal point: atan of each edge's offset over f.
    const double h = rad_to_deg(std::atan((m.cx_px + 0.5) / m.fx_px) + std::atan((m.width_px - 0.5 - m.cx_px) / m.fx_px));
    const double v = rad_to_deg(std::atan((m.cy_px + 0.5) / m.fy_px) + std::atan((m.height_px - 0.5 - m.cy_px) / m.fy_px));
    EXPECT_NEAR(k.hfov_deg, h, 1e-6);
    EXPECT_NEAR(k.hfov_deg, 56.0, 0.01);
    EXPECT_NEAR(k.vfov_deg, v, 1e-6);
    EXPECT_NEAR(std::abs(k.axis_azimuth_deg), 180.0, 1e-6) << "looking aft";
    EXPECT_NEAR(k.axis_depression_deg, 25.0, 1e-6) << "25 degrees down";
    // The receptacle's pixel, projected by OpenCV.
    ASSERT_TRUE(k.receptacle_px);
    const Pose T_cam_body = rig.cameras[&k - s.cameras.data()].T_body_cam.inverse();
    const Eigen::Vector3d p = T_cam_body * s.receptacle_body_m;
    std::vector<cv::Point3d> obj = {{p.x(), p.y(), p.z()}};
    std::vector<cv::Point2d> img;
    cv::Mat K, D;
    cv::eigen2cv(m.K(), K);
    cv::eigen2cv(Eigen::VectorXd(m.distortion_coeffs()), D);
    cv::projectPoints(obj, cv::Mat::zeros(3, 1, CV_64F), cv::Mat::zeros(3, 1, CV_64F), K, D, img);
    EXPECT_NEAR(k.receptacle_px->x(), img[0].x, 1e-6);
    EXPECT_NEAR(k.receptacle_px->y(), img[0].y, 1e-6);
    EXPECT_NEAR(k.receptacle_z_m, p.z(), 1e-12);
  }
  const std::string text = format_rig_summary(rig, s);
  EXPECT_NE(text.find("baseline 0.5000 m"), std::string::npos) << text;
  EXPECT_NE(text.find("No warnings."), std::string::npos) << text;
}

// A capture-only rig (no boom section) has no contact to check: its cameras are summarised and
// warned about, the boom and the receptacle at contact are not (a boom it does not have would put
// the receiver anywhere).
TEST(RigCheck, CaptureOnlyRigHasNoContactChecks) {
  Rig rig = Rig::paper_default();
  rig.boom.configured = false;
  rig.boom.limits.elevation_min_rad = rig.boom.limits.elevation_max_rad = -0.5;  // would be warned about
  const RigSummary s = summarize_rig(rig, BoomDimensions{}, builtin_receptacle());
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
  for (const RigCameraSummary& k : s.cameras) {
    EXPECT_FALSE(k.receptacle_px);
    EXPECT_TRUE(std::isnan(k.receptacle_z_m));
  }
  const std::string text = format_rig_summary(rig, s);
  EXPECT_NE(text.find("boom: none: a capture-only rig"), std::string::npos) << text;
  EXPECT_EQ(text.find("receptacle at contact"), std::string::npos) << text;
  EXPECT_NE(text.find("baseline 0.5000 m"), std::string::npos) << text;
  // The cameras' mistakes are still named.
  rig.cameras[1].T_body_cam.translation_m.y() = -500.0;
  EXPECT_TRUE(has_warning(summarize_rig(rig, BoomDimensions{}, builtin_receptacle()), "millimetres"));
}

TEST(RigCheck, EachMistakeIsNamed) {
  const Eigen::Vector3d rec = builtin_receptacle();
  {  // The right camera's translation in millimetres.
    Rig rig = Rig::paper_default();
    rig.cameras[1].T_body_cam.translation_m *= 1000.0;
    const RigSummary s = summarize_rig(rig, BoomDimensions{}, rec);
    EXPECT_TRUE(has_warning(s, "millimetres")) << format_rig_summary(rig, s);
  }
  {  // Both cameras at one centre.
    Rig rig = Rig::paper_default();
    rig.cameras[1].T_body_cam = rig.cameras[0].T_body_cam;
    const RigSummary s = summarize_rig(rig, BoomDimensions{}, rec);
    EXPECT_TRUE(has_warning(s, "no usable stereo baseline")) << format_rig_summary(rig, s);
  }
  {  // The right camera looking forward: the receiver behind it, the axes far apart.
    Rig rig = Rig::paper_default();
    rig.cameras[1].T_body_cam = Pose::from(R_body_cam_from_mount_ypr(0, deg_to_rad(-25.0), 0),
                                           rig.cameras[1].T_body_cam.translation_m);
    const RigSummary s = summarize_rig(rig, BoomDimensions{}, rec);
    EXPECT_TRUE(has_warning(s, "camera '" + rig.cameras[1].name + "': the receiver at contact is behind"))
        << format_rig_summary(rig, s);
    EXPECT_TRUE(has_warning(s, "optical axes are")) << format_rig_summary(rig, s);
    EXPECT_FALSE(has_warning(s, "camera '" + rig.cameras[0].name + "'")) << format_rig_summary(rig, s);
  }
  {  // Looking aft but level: the receiver below the image.
    Rig rig = Rig::paper_default();
    for (RigCamera& c : rig.cameras)
      c.T_body_cam = Pose::from(R_body_cam_from_mount_ypr(M_PI, deg_to_rad(30.0), 0), c.T_body_cam.translation_m);
    const RigSummary s = summarize_rig(rig, BoomDimensions{}, rec);
    EXPECT_TRUE(has_warning(s, "outside the image")) << format_rig_summary(rig, s);
  }
  {  // Boom elevation limits with the wrong sign: the boom points up into the tanker.
    Rig rig = Rig::paper_default();
    rig.boom.limits.elevation_min_rad = -deg_to_rad(40.0);
    rig.boom.limits.elevation_max_rad = -deg_to_rad(20.0);
    const RigSummary s = summarize_rig(rig, BoomDimensions{}, rec);
    EXPECT_TRUE(has_warning(s, "inside or above the tanker")) << format_rig_summary(rig, s);
  }
  {  // far_m shorter than the receptacle's distance.
    Rig rig = Rig::paper_default();
    rig.cameras[0].far_m = 5.0;
    const RigSummary s = summarize_rig(rig, BoomDimensions{}, rec);
    EXPECT_TRUE(has_warning(s, "outside near_m..far_m")) << format_rig_summary(rig, s);
  }
}

}  // namespace
}  // namespace augrig
