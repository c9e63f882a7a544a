// Importers for the calibration files users already have. Each returns the two cameras' models
// and T_right_left (left-camera coordinates -> right-camera coordinates), or an Error naming
// the file, line or key, and what was expected.
//   OpenCV FileStorage from stereoCalibrate: M1 D1 M2 D2 R T (also K1 K2 spellings), image size
//     from image_width/image_height, imageSize or width/height keys, else passed in.
//   ROS camera_info YAML (one file per camera: camera_matrix, distortion_model plumb_bob /
//     rational_polynomial(first 5) / equidistant, distortion_coefficients, image_width/height);
//     the stereo extrinsic comes from the right camera's projection_matrix (Tx = -fx' * B) and R.
//   Kalibr camchain.yaml: cam0/cam1, camera_model pinhole, intrinsics [fu fv pu pv],
//     distortion_model radtan/equidistant, distortion_coeffs, resolution, cam1.T_cn_cnm1.
#pragma once

#include <string>

#include "core/expected.hpp"
#include "core/pose.hpp"
#include "render/camera_model.hpp"

namespace augrig {

struct StereoCalibration {
  CameraModel left;
  CameraModel right;
  Pose T_right_left;
  std::string format;  // "opencv", "ros", "kalibr"
};

Expected<StereoCalibration> import_opencv_stereo(const std::string& path, int width_px = 0,
                                                 int height_px = 0);
Expected<StereoCalibration> import_ros_camera_info(const std::string& left_path,
                                                   const std::string& right_path);
Expected<StereoCalibration> import_kalibr_camchain(const std::string& path);

// Picks the importer by content ("opencv", "ros", "kalibr" or "auto"); for "ros", `path2` is the
// right camera's file.
Expected<StereoCalibration> import_calibration(const std::string& format, const std::string& path,
                                               const std::string& path2 = "");

}  // namespace augrig
