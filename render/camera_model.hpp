// CameraModel: one real camera's intrinsics and lens distortion, in OpenCV's conventions
// (core/conventions.hpp: pixel centres at integer coordinates). Projects camera-frame points to
// raw (distorted) pixels and maps raw pixels back to rays. Models: pinhole without distortion,
// OpenCV radial-tangential (k1 k2 p1 p2 [k3]) and Kalibr/OpenCV-fisheye equidistant (k1..k4).
#pragma once

#include <array>
#include <optional>
#include <string>

#include <Eigen/Core>

namespace augrig {

enum class DistortionModel { kNone, kRadTan, kEquidistant };

struct CameraModel {
  int width_px = 0;
  int height_px = 0;
  double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0;
  DistortionModel distortion = DistortionModel::kNone;
  // kRadTan: k1 k2 p1 p2 k3 (OpenCV order).  kEquidistant: k1 k2 k3 k4 (5th unused).
  std::array<double, 5> coeffs{};

  // The paper's camera: W x H with the given horizontal FOV, centred principal point, no distortion.
  static CameraModel pinhole_from_hfov(int width_px, int height_px, double hfov_rad);

  // Normalised undistorted coordinates (X/Z, Y/Z) -> distorted normalised coordinates.
  Eigen::Vector2d distort(const Eigen::Vector2d& xy) const;
  // Camera-frame point -> raw pixel. nullopt when z <= 0 or the point lies outside the region where
  // the distortion model is monotonic (where it would fold back into the image).
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& p_cam) const;
  // The same, with max_valid_radius() looked up by the caller once: for per-pixel loops.
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& p_cam, double max_valid_radius) const;
  // Raw pixel -> unit ray in the camera frame (iterative inversion, |residual| < 1e-9 px).
  // nullopt when the iteration does not converge (pixel outside the model's valid region).
  std::optional<Eigen::Vector3d> ray(const Eigen::Vector2d& uv_px) const;
  // Raw pixel -> undistorted normalised coordinates (x, y) = ray.xy / ray.z; nullopt as for ray(),
  // or when the ray is at or beyond 90 degrees from the optical axis.
  std::optional<Eigen::Vector2d> undistort(const Eigen::Vector2d& uv_px) const;

  // Largest undistorted radius r = |(x, y)| (radtan) or angle theta (equidistant) up to which the
  // distortion is monotonic; project() refuses points beyond it. +inf for kNone.
  double max_valid_radius() const;

  // 3x3 camera matrix K and the coefficient vector as OpenCV takes them (radtan: 5, fisheye: 4).
  Eigen::Matrix3d K() const;
  // kRadTan: k1 k2 p1 p2 k3 (cv::projectPoints), kEquidistant: k1..k4 (cv::fisheye), kNone: 5 zeros.
  Eigen::VectorXd distortion_coeffs() const;
  std::string distortion_name() const;  // "none", "radtan", "equidistant"
};

}  // namespace augrig
