// Stereo evaluation (issue 18 §3): what the boom does to stereo matching. The rig's calibration
// rectifies a pair (OpenCV's stereoRectify, fisheye included); the true disparity at every
// rectified left pixel comes from the augmenter's ground truth (the receiver's depth), so a
// matcher's disparity on the raw and on the augmented pair can be scored over the receiver's
// pixels, per stereo class. This file: the rectification and the true disparity. Conventions:
// rectified pixels like raw ones (centres at integers), disparity = u_left - u_right > 0.
#pragma once

#include <array>
#include <cstdint>

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

// The rectification of a rig (left model, right model, T_right_left): OpenCV's stereoRectify
// (alpha 0: every rectified pixel sees into both raw images) and its maps for two radtan (or
// pinhole) cameras or two fisheyes; a pair of one each (a Kalibr rig with a wide and a narrow
// lens) gets OpenCV's rotations and the same alpha-0 image from each camera's own model. Errors
// when the cameras have other sizes, share their centre, do not overlap, or OpenCV fails.
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
// `roi` (when not empty): only its rectified pixels are computed, the others are NaN.
cv::Mat true_disparity(const Rectification& r, const DepthImage& depth_left, const cv::Rect& roi = {});

// The rectified left pixels whose raw pixels may lie in `raw_box` of the left camera `left`: the
// box's border carried through the lens and the rectification, 2 px wider, clipped to the image
// (the whole image when a border pixel has no ray). Empty for an empty box.
cv::Rect rectified_box(const Rectification& r, const CameraModel& left, const PixelBox& raw_box);

// A per-pixel image of the raw left camera (CV_8UC1: masks, stereo classes) carried to the
// rectified left image by its nearest raw pixel; `outside` where that lies outside the image.
cv::Mat rectify_labels(const Rectification& r, const cv::Mat& labels_left, std::uint8_t outside = 0);

// Disparity errors of a matcher over a set of pixels that have a true disparity.
struct DisparityErrors {
  std::int64_t pixels = 0;                  // pixels with a true disparity in the set
  std::int64_t valid = 0;                   // of them, where the matcher gave a disparity
  double sum_error_px = 0, sum_sq_px2 = 0;  // estimated - true, over the valid ones
  std::int64_t bad1 = 0, bad3 = 0;          // valid ones with |error| > 1 px, > 3 px
  // Range from the estimated disparity (f B / d) minus the true range, where the estimate > 0.
  double sum_range_error_m = 0, sum_range_sq_m2 = 0;
  std::int64_t range_n = 0;

  void add(double true_px, double estimated_px, double f_times_b);  // estimated NaN: not valid
  void merge(const DisparityErrors& o);
  double valid_pct() const;  // of `pixels`; 0 when none
  double mean_px() const;    // signed mean error; NaN when no valid pixel
  double rms_px() const;
  double bad1_pct() const;  // of the valid pixels
  double bad3_pct() const;
  double range_mean_m() const;
  double range_rms_m() const;
};

// One pair scored: per stereo class (index = StereoClass: 0 every receiver pixel, 1 both, 2 left
// only, 3 right only, 4 neither), over all of them and with the pixels the left mask marks as
// boom (bit 0) left out, as an evaluation that trusts augrig's masks would.
struct PairScore {
  std::array<DisparityErrors, 5> all, boom_excluded;
  void merge(const PairScore& o);
};
// `true_disp` and `estimated` CV_32FC1 (NaN: none), `classes` and `mask` CV_8UC1 in the rectified
// left frame (rectify_labels()), `f_times_b` = f_px * baseline_m.
PairScore score_disparity(const cv::Mat& true_disp, const cv::Mat& estimated, const cv::Mat& classes,
                          const cv::Mat& mask, double f_times_b);

}  // namespace augrig::eval
