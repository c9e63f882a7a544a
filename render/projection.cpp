#include "render/projection.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace augrig {

std::array<float, 16> gl_projection(double fx, double fy, double cx, double cy, int width, int height,
                                    double near_m, double far_m, bool zero_to_one_depth) {
  // Rows of the clip-space matrix (see header): x_w = u + 0.5, y_w = v + 0.5, w = Z.
  // Reversed-Z: z_ndc = a + b / Z with z_ndc(near) = 1, z_ndc(far) = 0.
  const double a = -near_m / (far_m - near_m);
  const double b = near_m * far_m / (far_m - near_m);
  double r2_z = a, r2_w = b;
  if (!zero_to_one_depth) {  // fold [0, 1] into [-1, 1]: z' = 2 z - w
    r2_z = 2 * a - 1;
    r2_w = 2 * b;
  }
  const double m[4][4] = {
      {2 * fx / width, 0, (2 * cx + 1) / width - 1, 0},
      {0, 2 * fy / height, (2 * cy + 1) / height - 1, 0},
      {0, 0, r2_z, r2_w},
      {0, 0, 1, 0},
  };
  std::array<float, 16> out{};
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out[c * 4 + r] = static_cast<float>(m[r][c]);
  return out;
}

Expected<VirtualPinhole> make_virtual_pinhole(const CameraModel& cam, double scale, bool between_pixels,
                                              const std::string& name) {
  const std::string where = "render::make_virtual_pinhole(): camera '" + name + "': ";
  VirtualPinhole vp;
  const int W = cam.width_px, H = cam.height_px;
  if (W <= 0 || H <= 0) return make_error(where, "no image size (", W, "x", H, ")");
  vp.ray_xy.assign(static_cast<std::size_t>(W) * H,
                   Eigen::Vector2f::Constant(std::numeric_limits<float>::quiet_NaN()));

  if (cam.distortion == DistortionModel::kNone && scale == 1.0 && !between_pixels) {
    // Same grid as the real camera: rasterisation samples exactly the raw pixel centres.
    vp.fx = cam.fx_px, vp.fy = cam.fy_px, vp.cx = cam.cx_px, vp.cy = cam.cy_px;
    vp.width = W, vp.height = H, vp.identity = true;
    for (int v = 0; v < H; ++v)
      for (int u = 0; u < W; ++u)
        vp.ray_xy[static_cast<std::size_t>(v) * W + u] = {static_cast<float>((u - cam.cx_px) / cam.fx_px),
                                                          static_cast<float>((v - cam.cy_px) / cam.fy_px)};
    return vp;
  }

  // Rays of every raw pixel centre; the field to cover is their bounding box in normalised coords.
  const double max_tan = std::tan(kMaxFieldAxisDeg * 3.14159265358979323846 / 180.0);
  double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
  for (int v = 0; v < H; ++v) {
    for (int u = 0; u < W; ++u) {
      const auto xy = cam.undistort({static_cast<double>(u), static_cast<double>(v)});
      if (!xy || std::abs(xy->x()) > max_tan || std::abs(xy->y()) > max_tan) continue;
      vp.ray_xy[static_cast<std::size_t>(v) * W + u] = xy->cast<float>();
      x0 = std::min(x0, xy->x()), x1 = std::max(x1, xy->x());
      y0 = std::min(y0, xy->y()), y1 = std::max(y1, xy->y());
    }
  }
  // Without a single ray the extents stay at +-1e9 and the size below would be negative or huge.
  if (x0 > x1 || y0 > y1) {
    return make_error(where, "no pixel of the ", W, "x", H,
                      " image undistorts to a ray in front of the camera (within 80 deg of its axis): "
                      "check the distortion coefficients");
  }
  vp.fx = cam.fx_px * scale;
  vp.fy = cam.fy_px * scale;
  // Two virtual pixels of margin on each side keep every 2x2 bilinear neighbourhood inside.
  const int margin = 2;
  const double shift = between_pixels ? 0.5 : 0.0;
  vp.cx = -x0 * vp.fx + margin + shift;
  vp.cy = -y0 * vp.fy + margin + shift;
  // In double first: a size beyond int would make the cast undefined.
  const double w = std::ceil((x1 - x0) * vp.fx) + 2 * margin + 1;
  const double h = std::ceil((y1 - y0) * vp.fy) + 2 * margin + 1;
  if (!(w >= 1 && w <= kMaxVirtualSidePx && h >= 1 && h <= kMaxVirtualSidePx &&
        w * h <= static_cast<double>(kMaxVirtualPixels))) {
    char size[64];
    std::snprintf(size, sizeof size, "%.6g x %.6g", w, h);
    return make_error(where, "the undistorted image would need ", size, " pixels (at most ",
                      kMaxVirtualSidePx,
                      " on a side and 2^28 in all): check the focal lengths and the distortion coefficients");
  }
  vp.width = static_cast<int>(w);
  vp.height = static_cast<int>(h);
  return vp;
}

}  // namespace augrig
