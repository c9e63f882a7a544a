#include "eval/benchmark_layout.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <opencv2/imgproc.hpp>

namespace augrig::eval {
namespace {

// Numbers as KITTI's files write them: %e, space separated.
std::string row(std::initializer_list<double> v) {
  std::string s;
  char buf[32];
  for (double x : v) {
    std::snprintf(buf, sizeof buf, "%s%.12e", s.empty() ? "" : " ", x);
    s += buf;
  }
  return s;
}

std::string matrix_row(const Eigen::Matrix3d& m) {
  return row({m(0, 0), m(0, 1), m(0, 2), m(1, 0), m(1, 1), m(1, 2), m(2, 0), m(2, 1), m(2, 2)});
}

std::string number(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", x);
  return buf;
}

}  // namespace

cv::Mat kitti_disparity(const cv::Mat& disparity_px) {
  CV_Assert(disparity_px.type() == CV_32FC1);
  cv::Mat out(disparity_px.size(), CV_16UC1, cv::Scalar(0));
  for (int y = 0; y < disparity_px.rows; ++y) {
    const float* d = disparity_px.ptr<float>(y);
    std::uint16_t* o = out.ptr<std::uint16_t>(y);
    for (int x = 0; x < disparity_px.cols; ++x)
      if (std::isfinite(d[x]) && d[x] > 0)
        o[x] = static_cast<std::uint16_t>(std::min(65535.0, std::max(1.0, std::round(d[x] * 256.0))));
  }
  return out;
}

Status write_pfm(const std::string& path, const cv::Mat& image) {
  if (image.type() != CV_32FC1) return make_error("eval::write_pfm(): ", path, ": expected a CV_32FC1 image");
  std::ofstream out(path, std::ios::binary);
  if (!out) return make_error("eval::write_pfm(): ", path, ": cannot write the file");
  out << "Pf\n" << image.cols << " " << image.rows << "\n-1\n";
  // Little endian, as the scale's sign says; x86 and ARM hosts store floats so.
  for (int y = image.rows - 1; y >= 0; --y)
    out.write(reinterpret_cast<const char*>(image.ptr<float>(y)),
              static_cast<std::streamsize>(image.cols * sizeof(float)));
  out.close();
  if (!out) return make_error("eval::write_pfm(): ", path, ": write failed");
  return {};
}

std::string kitti_calib_cam_to_cam(const Rectification& r, const CameraModel& left, const CameraModel& right,
                                   const Pose& T_right_left) {
  std::ostringstream s;
  s << "calib_time: augrig rig (cameras 00 and 02: left, 01 and 03: right)\n";
  s << "corner_dist: " << row({0.0}) << "\n";
  const Eigen::Matrix3d R_right_left = T_right_left.rotation.toRotationMatrix();
  for (int k = 0; k < 4; ++k) {
    const int c = k % 2;  // 0 left, 1 right
    const CameraModel& m = c ? right : left;
    char id[4];
    std::snprintf(id, sizeof id, "%02d", k);
    const Eigen::Matrix3d K = m.K();
    Eigen::VectorXd d = m.distortion_coeffs();
    double D[5] = {0, 0, 0, 0, 0};
    for (int i = 0; i < std::min<int>(5, static_cast<int>(d.size())); ++i) D[i] = d[i];
    const Eigen::Matrix3d R = c ? R_right_left : Eigen::Matrix3d::Identity();
    const Eigen::Vector3d T = c ? T_right_left.translation_m : Eigen::Vector3d::Zero();
    // Rectified: both at the left's resolution, the right one -f * baseline along x.
    const double tx = c ? -r.f_px * r.baseline_m : 0.0;
    s << "S_" << id << ": " << row({double(m.width_px), double(m.height_px)}) << "\n"
      << "K_" << id << ": " << matrix_row(K) << "\n"
      << "D_" << id << ": " << row({D[0], D[1], D[2], D[3], D[4]}) << "\n"
      << "R_" << id << ": " << matrix_row(R) << "\n"
      << "T_" << id << ": " << row({T.x(), T.y(), T.z()}) << "\n"
      << "S_rect_" << id << ": " << row({double(r.width), double(r.height)}) << "\n"
      << "R_rect_" << id << ": " << matrix_row(r.R_rect_raw[c]) << "\n"
      << "P_rect_" << id << ": " << row({r.f_px, 0, r.cx_px, tx, 0, r.f_px, r.cy_px, 0, 0, 0, 1, 0}) << "\n";
  }
  return s.str();
}

std::string middlebury_calib(const Rectification& r, double vmin_px, double vmax_px) {
  const bool any = std::isfinite(vmin_px) && std::isfinite(vmax_px) && vmax_px >= vmin_px;
  const int vmin = any ? static_cast<int>(std::floor(vmin_px)) : 0;
  const int vmax = any ? static_cast<int>(std::ceil(vmax_px)) : 0;
  const int ndisp = std::max(16, (vmax / 16 + 1) * 16);
  const std::string cam = "[" + number(r.f_px) + " 0 " + number(r.cx_px) + "; 0 " + number(r.f_px) + " " +
                          number(r.cy_px) + "; 0 0 1]";
  std::ostringstream s;
  s << "cam0=" << cam << "\ncam1=" << cam << "\ndoffs=0\nbaseline=" << number(r.baseline_m * 1e3)
    << "\nwidth=" << r.width << "\nheight=" << r.height << "\nndisp=" << ndisp << "\nisint=0\nvmin=" << vmin
    << "\nvmax=" << vmax << "\ndyavg=0\ndymax=0\n";
  return s.str();
}

}  // namespace augrig::eval
