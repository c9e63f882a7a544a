// Ground truth for stereo research, per augmented stereo frame (docs/GROUND_TRUTH.md): the
// receiver's depth in each camera, and for every left receiver pixel where the same surface point
// lies in the right image (the true correspondence; with the stereo class image it says whether
// the right camera actually sees it). Exact to the masks' geometry: the depth is the augmenter's
// (the receiver's nearest surface on each pixel centre's ray), the correspondence that point
// projected through the right camera's own model, distortion included.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/expected.hpp"
#include "core/pose.hpp"
#include "render/camera_model.hpp"
#include "render/stats.hpp"

namespace augrig {

// (u, v) in the right image of the receiver point on each left pixel centre's ray, two floats per
// left pixel, row-major (width x height x 2). NaN where the left pixel has no receiver, its ray is
// undefined, or the point does not project into the right camera (behind it, or outside its lens
// model's domain). Points outside the right image keep their coordinates (the stereo class says
// who sees what). `depth_left` is the left camera's receiver depth (+inf where none).
std::vector<float> right_correspondence(const DepthImage& depth_left, const CameraModel& left,
                                        const CameraModel& right, const Pose& T_right_left);

// The depth as float32 metres with NaN where there is no receiver (DepthImage has +inf there).
std::vector<float> depth_with_nan(const DepthImage& depth);

// The depth in whole millimetres for 16-bit images: round(z * 1000), 0 where there is no
// receiver, 65535 for 65.535 m or more (saturated).
std::vector<std::uint16_t> depth_mm_u16(const DepthImage& depth);

// The files of docs/GROUND_TRUTH.md, one per call, for every writer of them (pipeline's
// write_ground_truth beside a frame's images, the EuRoC export of a recording). The folder must
// exist; errors name the file.
//   write_depth_npy           float32 H x W, metres along z, NaN where no receiver (depth_with_nan)
//   write_depth_mm_png        16-bit PNG H x W, whole mm, 0 where no receiver (depth_mm_u16)
//   write_correspondence_npy  float32 H x W x 2: right_correspondence()'s (u, v) per left pixel
//   write_stereo_class_png    8-bit PNG H x W of StereoClass values (0..4)
Status write_depth_npy(const std::string& path, const DepthImage& depth);
Status write_depth_mm_png(const std::string& path, const DepthImage& depth);
Status write_correspondence_npy(const std::string& path, const std::vector<float>& uv, int width, int height);
Status write_stereo_class_png(const std::string& path, const std::vector<std::uint8_t>& classes, int width,
                              int height);

}  // namespace augrig
