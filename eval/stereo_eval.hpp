// Stereo evaluation (issue 18 §3): what the boom does to stereo matching. The rig's calibration
// rectifies a pair (OpenCV's stereoRectify, fisheye included); the true disparity at every
// rectified left pixel comes from the augmenter's ground truth (the receiver's depth), so a
// matcher's disparity on the raw and on the augmented pair can be scored over the receiver's
// pixels, per stereo class. This file: the rectification and the true disparity. Conventions:
// rectified pixels like raw ones (centres at integers), disparity = u_left - u_right > 0.
#pragma once

#include <opencv2/core.hpp>

#include "core/expected.hpp"
#include "core/pose.hpp"
#include "render/camera_model.hpp"
#include "render/stats.hpp"

namespace augrig::eval {

// Both cameras rectified to one pinhole pair at the left camera's resolution, the right camera on
// the rectified x axis (same focal length, principal point and rows in both: zero disparity at
// infinity).
struct Rectification {
  int width = 0, height = 0;
  // Rectified pixel -> raw pixel, CV_32FC1 x and y maps for cv::remap, per camera.
  cv::Mat map_x[2], map_y[2];
  // Raw camera frame -> rectified camera frame (OpenCV's R1, R2).
  Eigen::Matrix3d R_rect_raw[2];
  double f_px = 0, cx_px = 0, cy_px = 0;  // the rectified cameras' intrinsics (fx = fy)
  double baseline_m = 0;                  // distance between the camera centres
};

// The rectification of a rig (left model, right model, T_right_left). Errors when the cameras
// have other sizes, share their centre, or OpenCV fails.
Expected<Rectification> rectify_rig(const CameraModel& left, const CameraModel& right,
                                    const Pose& T_right_left);

// The rectified pair of images (`images` raw left and right, any OpenCV type), bilinear.
void rectify_images(const Rectification& r, const cv::Mat& left, const cv::Mat& right, cv::Mat& left_rect,
                    cv::Mat& right_rect);

// The true disparity (rectified px, CV_32FC1) at each rectified left pixel: f * baseline / z of
// the receiver point on that pixel's ray, z in the rectified frame; NaN where the ray does not
// meet the receiver. The point is found from the raw left depth image (+inf where no receiver)
// around the raw pixel the rectified one comes from: bilinear where the four raw neighbours all
// have the receiver, else the nearest raw pixel's (at the receiver's silhouette), nothing when
// the nearest has none.
cv::Mat true_disparity(const Rectification& r, const DepthImage& depth_left);

// A per-pixel image of the raw left camera (CV_8UC1: masks, stereo classes) carried to the
// rectified left image by its nearest raw pixel; `outside` where that lies outside the image.
cv::Mat rectify_labels(const Rectification& r, const cv::Mat& labels_left, std::uint8_t outside = 0);

}  // namespace augrig::eval
