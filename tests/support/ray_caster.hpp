// An independent CPU ray caster, the oracle for the renderer's masks: rays through pixel centres
// undistorted by OpenCV (cv::undistortPoints, tight criteria), intersected in double precision with
// every triangle whose projected bounds contain the ray (a uniform grid over normalised
// coordinates; nothing shared with the renderer's GL path).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "core/image.hpp"
#include "core/pose.hpp"
#include "render/camera_model.hpp"
#include "render/mesh.hpp"

namespace augrig::test {

class RayCaster {
 public:
  // Adds a model's triangles, moved into the camera frame by T_cam_obj.
  void add(const Model& model, const Pose& T_cam_obj);
  // Nearest hit distance along z for the ray (x, y, 1); +inf if none.
  double hit_z(double x, double y) const;

 private:
  void build() const;
  struct Tri {
    Eigen::Vector3d a, b, c;
  };
  std::vector<Tri> tris_;
  // Lazily built grid over normalised coordinates [-kExtent, kExtent]^2.
  mutable bool built_ = false;
  mutable std::vector<std::vector<int>> cells_;
  mutable std::vector<int> everywhere_;  // triangles crossing z <= 0: tested for every ray
};

// Undistorted normalised coordinates of every pixel centre, by OpenCV (row-major W*H).
std::vector<Eigen::Vector2d> opencv_pixel_rays(const CameraModel& camera);

// Mask by ray casting: bit 0 where the boom is nearest, bit 1 where the receiver is hit.
Image ray_cast_mask(const CameraModel& camera, const std::vector<Eigen::Vector2d>& rays,
                    const RayCaster& boom, const RayCaster& receiver);

}  // namespace augrig::test
