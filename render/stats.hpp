// Occlusion statistics per stereo frame: the seed paper's Table 1, counted in pixels (not in
// channel values as the paper did), plus the per-pixel stereo visibility classes that the
// paper's reference [18] computed with shadow volumes. docs/STATISTICS.md defines every column.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "core/image.hpp"
#include "core/pose.hpp"
#include "render/camera_model.hpp"

namespace augrig {

class Worker;

// Receiver depth per raw pixel centre: z (metres, camera frame, along the optical axis) of the
// nearest receiver surface on the pixel centre's ray, whether or not the boom hides it;
// +infinity where the ray misses the receiver.
struct DepthImage {
  int width = 0;
  int height = 0;
  std::vector<float> z_m;
  float at(int x, int y) const { return z_m[static_cast<std::size_t>(y) * width + x]; }
  static constexpr float kNone = std::numeric_limits<float>::infinity();
};

struct OcclusionStats {
  TimestampNs t_ns = 0;
  std::int64_t width = 0, height = 0;
  std::int64_t receiver_px_left = 0, receiver_px_right = 0;  // mask bit 1
  std::int64_t boom_px_left = 0, boom_px_right = 0;          // mask bit 0
  std::int64_t boom_overlap_px = 0;                          // bit 0 at the same pixel in both images
  double boom_overlap_pct_union = 0;                         // of |boom_left ∪ boom_right| pixels
  std::int64_t occluded_px_left = 0, occluded_px_right = 0;  // bits 0 and 1 (mask value 3)
  double occluded_pct_left = 0, occluded_pct_right = 0;      // of that camera's receiver pixels
  // Stereo classes over the LEFT camera's receiver pixels (they sum to receiver_px_left):
  std::int64_t stereo_both_px = 0;  // the surface point is visible to both cameras
  std::int64_t left_only_px = 0;    // visible to the left camera only
  std::int64_t right_only_px = 0;   // hidden by the boom in the left, visible to the right
  std::int64_t neither_px = 0;      // visible to neither camera
  double receiver_pct_left = 0, receiver_pct_right = 0;  // of W*H
  double boom_pct_left = 0, boom_pct_right = 0;          // of W*H
  // The boom's shadow on the receiver: mask bit 2 (kMaskShadow; the augmenter sets it only with
  // bit 1 and never with bit 0, and only where the sun is known and above the horizon).
  std::int64_t shadow_px_left = 0, shadow_px_right = 0;  // mask bit 2
  double shadow_pct_left = 0, shadow_pct_right = 0;      // of that camera's receiver pixels
  friend bool operator==(const OcclusionStats&, const OcclusionStats&) = default;
};

struct StereoClassOptions {
  // A left receiver point counts as visible to the right camera when the right camera's receiver
  // depth near its projection is within this of the point's own depth (the self-occlusion test).
  double depth_tolerance_m = 0.05;
  double depth_tolerance_rel = 0.005;  // plus this fraction of the depth
  // Optional: undistorted normalised coordinates (x, y) = ray.xy / ray.z of every LEFT raw pixel
  // centre, row-major, width*height entries (NaN where undistort() fails), e.g. from
  // undistorted_xy_map(left). Not owned; must outlive the call. When null, compute_occlusion_stats
  // builds the map once per distinct left CameraModel and keeps it in a small internal cache.
  const std::vector<Eigen::Vector2f>* left_rays_xy = nullptr;
  // false: only the mask counts; the four class counts stay 0, depth images and cameras are not
  // read (may be empty) and classes_out is left empty.
  bool compute_classes = true;
  // Optional: the box [x0, x1) x [y0, y1) outside which both masks are known to be zero (the
  // augmenter's boxes); the passes visit only that. Default: the whole image.
  int content_x0 = 0, content_y0 = 0;
  int content_x1 = std::numeric_limits<int>::max(), content_y1 = std::numeric_limits<int>::max();
  // Optional: a persistent thread (core/worker.hpp, idle during the call) for half of the classes'
  // rows; null: a thread is started for them. Not owned.
  Worker* worker = nullptr;
};

// The map StereoClassOptions::left_rays_xy expects: camera.undistort() of every pixel centre.
std::vector<Eigen::Vector2f> undistorted_xy_map(const CameraModel& camera);
// The same map, made once per distinct camera (the last few are kept) and shared: what
// compute_occlusion_stats() uses when it is given none. Thread-safe.
std::shared_ptr<const std::vector<Eigen::Vector2f>> shared_undistorted_xy_map(const CameraModel& camera);

// Per-pixel class image produced alongside the counts (left camera raw pixels).
enum class StereoClass : std::uint8_t { kNone = 0, kBoth = 1, kLeftOnly = 2, kRightOnly = 3, kNeither = 4 };

// Counts everything from the masks (Mono8, kMaskBoom / kMaskReceiver / kMaskShadow bits) and, for the stereo
// classes, the receiver depth images and the rig geometry. `classes_out` (optional) receives one
// StereoClass per left pixel.
OcclusionStats compute_occlusion_stats(TimestampNs t_ns, const Image& mask_left, const Image& mask_right,
                                       const DepthImage& receiver_depth_left,
                                       const DepthImage& receiver_depth_right, const CameraModel& left,
                                       const CameraModel& right, const Pose& T_right_left,
                                       const StereoClassOptions& options = {},
                                       std::vector<std::uint8_t>* classes_out = nullptr);

// CSV with the exact column names of docs/STATISTICS.md, one row per stereo frame.
void write_stats_csv_header(std::ostream& out);
void write_stats_csv_row(std::ostream& out, const OcclusionStats& s);
// Reads what write_stats_csv_header() and write_stats_csv_row() wrote, rows in file order (width
// and height are not in the file: 0). The header must be exactly the column list, or exactly the
// 19 columns written before the shadow columns were appended (their shadow fields read 0); errors
// name file:line and the column, and what was expected.
Expected<std::vector<OcclusionStats>> read_stats_csv(const std::string& path);
// Table-1-style summary of one frame (or of the mean of several) for stdout.
std::string format_table1(const OcclusionStats& s, const std::string& title);
// Mean, min and max over frames of each column, as a printable table.
std::string format_run_summary(const std::vector<OcclusionStats>& frames);

// The same summary accumulated frame by frame, in constant memory (for live runs of any length).
class RunSummary {
 public:
  RunSummary();
  void add(const OcclusionStats& s);
  std::size_t frames() const { return frames_; }
  std::string format() const;

 private:
  std::size_t frames_ = 0;
  std::vector<double> sum_, lo_, hi_;  // per column of docs/STATISTICS.md
  std::int64_t t_lo_ = 0, t_hi_ = 0;
};

}  // namespace augrig
