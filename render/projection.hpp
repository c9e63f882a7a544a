// Projection from real camera intrinsics to OpenGL, and the virtual pinhole camera the renderer
// rasterises in before the lens distortion is applied.
//
// Pixel convention: OpenCV pixel (u, v) has its centre at integer coordinates (core/conventions.hpp);
// GL window coordinates put pixel centres at i + 0.5. The matrix maps camera-frame points straight to
// clip space with window x = u + 0.5 and window y = v + 0.5, so glReadPixels rows come back in
// OpenCV's top-to-bottom order with no flip (front faces then wind clockwise in window space).
// Depth is reversed-Z (near -> 1, far -> 0, test GL_GREATER) with glClipControl(ZERO_TO_ONE) when the
// context has it; on a 3.3 context the same reversed mapping is folded into [-1, 1].
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/expected.hpp"
#include "render/camera_model.hpp"

namespace augrig {

// Column-major 4x4 (as glUniformMatrix4fv takes it) mapping camera-frame points to clip space.
std::array<float, 16> gl_projection(double fx, double fy, double cx, double cy, int width, int height,
                                    double near_m, double far_m, bool zero_to_one_depth);

// A pinhole camera that sees at least everything the real (distorted) camera sees, sampled at
// `scale` times the real focal length. Real pixel centres map into it through `map`.
struct VirtualPinhole {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;
  bool identity = false;  // no distortion, scale 1: virtual pixel (i, j) IS raw pixel (i, j)

  // Per raw pixel (row-major, W*H): undistorted normalised coordinates (x, y) of its centre's ray,
  // (z = 1); NaN where the lens model has no valid ray (those pixels are never augmented).
  std::vector<Eigen::Vector2f> ray_xy;

  Eigen::Vector2d to_virtual(const Eigen::Vector2d& xy) const { return {fx * xy.x() + cx, fy * xy.y() + cy}; }
};

// Builds the virtual pinhole for a camera: undistorts the raw image border to find the field it
// must cover (capped at +-80 deg off axis), keeps a 2-pixel margin so bilinear neighbourhoods stay
// inside, and precomputes ray_xy for every raw pixel. `between_pixels` shifts the virtual grid by
// half a pixel so that, without distortion, each raw pixel centre lies midway between four samples:
// their bilinear coverage anti-aliases edges (otherwise the grids coincide: `identity`).
// An Error "render::make_virtual_pinhole(): camera '<name>': ..." when the camera has no image size,
// when no pixel undistorts to a ray within 80 deg of the axis (distortion coefficients that fold
// the whole image), or when the virtual image would exceed kMaxVirtualSidePx on a side or
// kMaxVirtualPixels in all (focal lengths or distortion far from a real lens).
inline constexpr int kMaxVirtualSidePx = kMaxImageSidePx;
inline constexpr std::int64_t kMaxVirtualPixels = std::int64_t{1} << 28;
Expected<VirtualPinhole> make_virtual_pinhole(const CameraModel& camera, double scale = 1.0,
                                              bool between_pixels = false, const std::string& name = "");

}  // namespace augrig
