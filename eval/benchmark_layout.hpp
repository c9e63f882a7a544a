// benchmark_layout: the stereo benchmarks' own file formats, so that a matcher's disparity on augrig's
// pairs is scored with KITTI's and Middlebury's tools (issue 35 §3). The rectified pairs, the true
// disparity and the calibration as those benchmarks define them:
//   KITTI (stereo 2015)  disparity as a 16-bit PNG of d * 256, 0 = unknown; calib_cam_to_cam.txt
//                        (KITTI raw's keys: S, K, D, R, T, S_rect, R_rect, P_rect per camera);
//   Middlebury (2014, MiddEval3)  disparity as PFM (little-endian float, bottom row first, inf =
//                        unknown); calib.txt (cam0, cam1, doffs, baseline in mm, width, height,
//                        ndisp, isint, vmin, vmax, dyavg, dymax).
// The writers of the folders are pipeline/sinks/stereo_benchmark_sink.cpp (docs/BENCHMARKS.md).
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "core/expected.hpp"
#include "core/image.hpp"
#include "core/pose.hpp"
#include "render/cv_image.hpp"  // bgr_of, for the writers of these layouts
#include "eval/stereo_eval.hpp"
#include "render/camera_model.hpp"

namespace augrig::eval {

// KITTI's disparity image: CV_16UC1, round(d * 256) where d is finite and > 0 (at most 65535),
// 0 elsewhere. `disparity_px` CV_32FC1, NaN or inf where unknown.
cv::Mat kitti_disparity(const cv::Mat& disparity_px);

// Middlebury's PFM: one channel float (CV_32FC1), scale -1 (little endian), rows bottom to top.
Status write_pfm(const std::string& path, const cv::Mat& image);

// KITTI raw's calib_cam_to_cam.txt for a rig rectified by `r`: augrig's two cameras are KITTI's
// left (00 and 02) and right (01 and 03); R_xx, T_xx carry camera 00's coordinates into camera xx's
// (metres); D_xx are OpenCV's five coefficients (radtan; fisheye k1..k4 then 0); P_rect_xx the
// rectified projections, P_rect_01 and _03 with -f * baseline in their fourth column.
std::string kitti_calib_cam_to_cam(const Rectification& r, const CameraModel& left, const CameraModel& right,
                                   const Pose& T_right_left);

// Middlebury's calib.txt for one pair rectified by `r`: the disparity range of the pair's truth
// (vmin, vmax, ndisp a multiple of 16 above vmax; 0 and 16 when it has none).
std::string middlebury_calib(const Rectification& r, double vmin_px, double vmax_px);

}  // namespace augrig::eval
