// Rig check: what a rig resolves to, in the numbers a person compares with the installation's
// drawings (`augrig rig show`), and what in it is implausible. Each camera's pose, field of view
// and optical axis; the baseline; where the receptacle lies in each image when the boom is at the
// middle of its limits (contact). Warnings say what looks wrong and the likely cause: a baseline
// of hundreds of metres (a translation given in millimetres), cameras sharing their centre, the
// receiver behind a camera or out of its image at contact, the receiver inside or above the
// tanker (boom limits pointing up or forward).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "render/models.hpp"
#include "render/rig.hpp"

namespace augrig {

struct RigCameraSummary {
  std::string name;
  int width_px = 0, height_px = 0;
  std::string distortion;  // none | radtan | equidistant
  double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0;
  // Full field of view through the principal point's row and column (from ray() at the image's
  // edges), degrees; NaN where an edge pixel has no ray.
  double hfov_deg = 0, vfov_deg = 0;
  Eigen::Vector3d position_body_m = Eigen::Vector3d::Zero();  // camera centre, tanker body FRD
  // The optical axis in the body frame: azimuth from forward towards starboard, depression below
  // the body x-y plane (positive: looking down), degrees.
  double axis_azimuth_deg = 0, axis_depression_deg = 0;
  double near_m = 0, far_m = 0;
  std::string source_uri;
  // The receptacle at contact in this camera: its depth (camera z, m) and pixel (when in front of
  // the camera and inside the lens model's region).
  double receptacle_z_m = 0;
  std::optional<Eigen::Vector2d> receptacle_px;
};

struct RigSummary {
  std::vector<RigCameraSummary> cameras;
  double baseline_m = 0;                                    // distance between the camera centres
  Eigen::Vector3d baseline_left_m = Eigen::Vector3d::Zero();  // the right camera's centre, left camera frame
  double axes_angle_deg = 0;                                // between the optical axes
  BoomArticulation contact;                                 // the articulation checked (mid-limits)
  Eigen::Vector3d receptacle_body_m = Eigen::Vector3d::Zero();  // the receptacle at contact, body FRD
  Eigen::Vector3d receiver_origin_body_m = Eigen::Vector3d::Zero();  // the receiver's origin then (level)
  std::vector<std::string> warnings;                        // plain sentences; empty: nothing odd
};

// The summary of `rig`, its receptacle at `receptacle_m` (receiver body frame) and the boom of
// `boom` (the rig's models: pipeline's load_rig_models()).
RigSummary summarize_rig(const Rig& rig, const BoomDimensions& boom, const Eigen::Vector3d& receptacle_m);

// The summary as text: one block per camera, the baseline, the boom and receiver, the warnings.
std::string format_rig_summary(const Rig& rig, const RigSummary& s);

}  // namespace augrig
