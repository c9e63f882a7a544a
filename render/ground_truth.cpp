#include "render/ground_truth.hpp"

#include <cmath>
#include <cstring>
#include <limits>

#include <opencv2/imgcodecs.hpp>

#include "core/npy.hpp"
#include "render/image_file.hpp"

namespace augrig {

std::vector<float> right_correspondence(const DepthImage& depth_left, const CameraModel& left,
                                        const CameraModel& right, const Pose& T_right_left) {
  const int w = depth_left.width, h = depth_left.height;
  const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  std::vector<float> uv(2 * n, std::numeric_limits<float>::quiet_NaN());
  if (n == 0 || left.width_px != w || left.height_px != h) return uv;
  // The left rays: the same cached map the stereo classes use (undistort() once per camera).
  const auto rays = shared_undistorted_xy_map(left);
  const double max_radius = right.max_valid_radius();
  for (std::size_t i = 0; i < n; ++i) {
    const float z = depth_left.z_m[i];
    const Eigen::Vector2f& xy = (*rays)[i];
    if (!(z < DepthImage::kNone) || !(xy.x() == xy.x()) || !(xy.y() == xy.y())) continue;
    // The point on the ray at depth z (left camera frame), then in the right camera's frame.
    const Eigen::Vector3d p_left(static_cast<double>(xy.x()) * z, static_cast<double>(xy.y()) * z, z);
    const auto px = right.project(T_right_left * p_left, max_radius);
    if (!px) continue;
    uv[2 * i] = static_cast<float>(px->x());
    uv[2 * i + 1] = static_cast<float>(px->y());
  }
  return uv;
}

std::vector<float> depth_with_nan(const DepthImage& depth) {
  std::vector<float> out(depth.z_m.size());
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = depth.z_m[i] < DepthImage::kNone ? depth.z_m[i] : std::numeric_limits<float>::quiet_NaN();
  return out;
}

std::vector<std::uint16_t> depth_mm_u16(const DepthImage& depth) {
  std::vector<std::uint16_t> out(depth.z_m.size(), 0);
  for (std::size_t i = 0; i < out.size(); ++i) {
    const float z = depth.z_m[i];
    if (!(z < DepthImage::kNone) || !(z > 0)) continue;
    const double mm = std::round(static_cast<double>(z) * 1000.0);
    out[i] = mm >= 65535.0 ? 65535 : static_cast<std::uint16_t>(std::max(mm, 1.0));
  }
  return out;
}

Status write_depth_npy(const std::string& path, const DepthImage& depth) {
  const std::vector<float> z = depth_with_nan(depth);
  return write_npy_f32(path, {depth.height, depth.width}, z.data());
}

Status write_depth_mm_png(const std::string& path, const DepthImage& depth) {
  std::vector<std::uint16_t> mm = depth_mm_u16(depth);
  const cv::Mat m(depth.height, depth.width, CV_16UC1, mm.data());
  try {
    if (!cv::imwrite(path, m, {cv::IMWRITE_PNG_COMPRESSION, 1})) return make_error(path, ": cannot write the 16-bit PNG");
  } catch (const cv::Exception& e) {
    return make_error(path, ": cannot write the 16-bit PNG (", e.what(), ")");
  }
  return {};
}

Status write_correspondence_npy(const std::string& path, const std::vector<float>& uv, int width, int height) {
  if (uv.size() != 2 * static_cast<std::size_t>(width) * static_cast<std::size_t>(height))
    return make_error(path, ": ", uv.size(), " values for a ", width, "x", height, "x2 correspondence");
  return write_npy_f32(path, {height, width, 2}, uv.data());
}

Status write_stereo_class_png(const std::string& path, const std::vector<std::uint8_t>& classes, int width,
                              int height) {
  if (classes.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height))
    return make_error(path, ": ", classes.size(), " stereo classes for a ", width, "x", height, " image");
  Image cls(width, height, PixelFormat::kMono8);
  for (int y = 0; y < height; ++y)
    std::memcpy(cls.row(y), classes.data() + static_cast<std::size_t>(y) * width, static_cast<std::size_t>(width));
  return write_png_file(path, cls);
}

}  // namespace augrig
