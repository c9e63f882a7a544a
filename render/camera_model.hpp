// CameraModel: one real camera's intrinsics and lens distortion, in OpenCV's conventions
// (core/conventions.hpp: pixel centres at integer coordinates). Projects camera-frame points to
// raw (distorted) pixels and maps raw pixels back to rays. Models: pinhole without distortion,
// OpenCV radial-tangential (k1 k2 p1 p2 [k3]) and Kalibr/OpenCV-fisheye equidistant (k1..k4).
#pragma once

#include <array>
#include <cmath>
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

// What a camera model read from a file must satisfy (docs/RIG_FORMAT.md, "Plausible values"):
// beyond these a projection overflows or the rendering tables no longer fit in memory.
inline constexpr int kMaxImageSidePx = 32768;  // width and height in 1..32768
// fx, fy in [1, 1e7]: below a pixel a whole hemisphere falls on a few pixels (and the augmenter's
// virtual pinhole image would need billions of them), above 1e7 projections overflow.
inline constexpr double kMinFocalPx = 1.0;
inline constexpr double kMaxFocalPx = 1e7;
inline constexpr double kMaxDistortionCoefficient = 1000.0;  // |k|, |p| <= 1000
// Empty when `m` is plausible: image size in 1..kMaxImageSidePx, finite fx, fy in
// [kMinFocalPx, kMaxFocalPx], principal point within one image size of the image (cx in [-W, 2W], cy in
// [-H, 2H]), finite distortion coefficients of magnitude <= kMaxDistortionCoefficient. Else what
// is wrong, with the value and the range expected ("expected fx, fy in [1, 1e7] pixels, got ...").
std::string camera_model_problem(const CameraModel& m);

// The field augrig renders and augments: rays within this angle of the optical axis horizontally
// and vertically (|x|, |y| <= tan of it, in normalised coordinates). Every camera is rendered
// through a virtual pinhole image (render/projection.hpp), which grows as tan(angle) and cannot
// reach 90 degrees; a lens that sees beyond this would have pixels that are never augmented, so
// camera_model_problem() refuses it (docs/RIG_FORMAT.md, "Field of view").
inline constexpr double kMaxFieldAxisDeg = 80.0;

// theta_d(theta) = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8): the equidistant
// model's distorted angle.
inline double equi_theta_d(const std::array<double, 5>& k, double th) {
  const double t = th * th;
  return th * (1.0 + t * (k[0] + t * (k[1] + t * (k[2] + t * k[3]))));
}

// distort() and project() are defined here so that per-pixel loops (the stereo classes project
// every receiver pixel) inline them.
inline Eigen::Vector2d CameraModel::distort(const Eigen::Vector2d& xy) const {
  const double x = xy.x(), y = xy.y();
  switch (distortion) {
    case DistortionModel::kNone:
      return xy;
    case DistortionModel::kRadTan: {
      const double k1 = coeffs[0], k2 = coeffs[1], p1 = coeffs[2], p2 = coeffs[3], k3 = coeffs[4];
      const double r2 = x * x + y * y;
      const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
      return {x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
              y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y};
    }
    case DistortionModel::kEquidistant: {
      // Same small-radius guard as cv::fisheye::projectPoints.
      const double r = std::sqrt(x * x + y * y);
      const double theta = std::atan(r);
      const double scale = r > 1e-8 ? equi_theta_d(coeffs, theta) / r : 1.0;
      return {x * scale, y * scale};
    }
  }
  return xy;
}

inline std::optional<Eigen::Vector2d> CameraModel::project(const Eigen::Vector3d& p_cam,
                                                           double max_radius) const {
  Eigen::Vector2d d;
  if (distortion == DistortionModel::kEquidistant) {
    // Angle from the optical axis via atan2 so points beside or behind the camera work too
    // (a fisheye lens may see beyond 90 degrees).
    const double rxy = std::hypot(p_cam.x(), p_cam.y());
    const double theta = std::atan2(rxy, p_cam.z());
    if (!(theta < max_radius)) return std::nullopt;
    if (p_cam.z() > 0.0 && rxy <= 1e-8 * p_cam.z()) {
      d = distort(p_cam.head<2>() / p_cam.z());  // matches OpenCV's guard on the axis
    } else if (rxy == 0.0) {
      return std::nullopt;  // the zero vector has no direction
    } else {
      const double s = equi_theta_d(coeffs, theta) / rxy;
      d = {p_cam.x() * s, p_cam.y() * s};
    }
  } else {
    if (!(p_cam.z() > 0.0)) return std::nullopt;
    const Eigen::Vector2d xy = p_cam.head<2>() / p_cam.z();
    if (distortion == DistortionModel::kRadTan && !(xy.norm() < max_radius)) return std::nullopt;
    d = distort(xy);
  }
  const Eigen::Vector2d uv(fx_px * d.x() + cx_px, fy_px * d.y() + cy_px);
  // Huge coefficients or focal lengths overflow to inf/NaN: no pixel rather than a non-finite one.
  if (!(std::isfinite(uv.x()) && std::isfinite(uv.y()))) return std::nullopt;
  return uv;
}

}  // namespace augrig
