// Rig: the stereo camera rig, the boom and the receiver as configured in a rig file (YAML, see
// docs/RIG_FORMAT.md); a rig without a boom section is a capture-only rig (cameras, pairing). Loading never prints: it returns the Rig or an Error naming the file, line
// and key, and what was expected. Rig::paper_default() reproduces the seed paper's rig.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "core/expected.hpp"
#include "core/pose.hpp"
#include "render/camera_look.hpp"
#include "render/camera_model.hpp"

namespace augrig {

struct RigCamera {
  std::string name;  // "left", "right" or as named in the file
  CameraModel model;
  Pose T_body_cam;      // camera (OpenCV frame) in the tanker body frame (FRD)
  // Clipping planes in camera z (metres along the optical axis), as GL's: the augmenter draws the
  // boom and the receiver (pixels, mask bits, depth) only where camera z is in [near_m, far_m].
  double near_m = 1.0;  // no real or virtual object comes nearer than this
  double far_m = 100.0;
  std::string source_uri;  // optional, used by live capture (empty: none)
  // The camera look's parameters (render/camera_look.hpp; `look:` in the rig file): its PSF, tone
  // curve, and noise level function (empty: estimated from its frames during a run).
  CameraLookParams look;
};

// Axis convention of a model file, converted explicitly on load: which model-file axis points
// forward, right and down in the object's FRD frame. Each is one of "+x" "-x" "+y" "-y" "+z" "-z".
struct ModelAxes {
  std::string forward = "+z";  // glTF 2.0: +Z forward (front of the asset)
  std::string right = "-x";    // glTF 2.0: -X right
  std::string down = "-y";     // glTF 2.0: +Y up
  static ModelAxes gltf() { return {}; }
  static ModelAxes frd() { return {"+x", "+y", "+z"}; }
};

struct ModelSource {
  std::string path;  // empty: the built-in procedural model
  ModelAxes axes;
  double scale = 1.0;  // file units -> metres
};

struct BoomLimits {
  double elevation_min_rad = 0, elevation_max_rad = 0;  // below the body x-y plane, positive down
  double azimuth_min_rad = 0, azimuth_max_rad = 0;      // positive towards body +y (starboard)
  double extension_min_m = 0, extension_max_m = 0;      // telescope extension
};

struct BoomConfig {
  // False for a capture-only rig (no `boom` section): its cameras can be recorded, but nothing can
  // be augmented with it; the values below are then the seed paper's, for summaries only.
  bool configured = true;
  Eigen::Vector3d pivot_body_m = Eigen::Vector3d::Zero();
  ModelSource model;  // a model file is in the boom frame (x along the boom), at extension 0
  // `material: {metallic, roughness}`: the built-in boom's finish, and a model file's where the
  // file gives none; absent, the built-in paint (kPaintedBoom). apply_boom_material().
  std::optional<SurfaceFinish> material;
  BoomLimits limits;
};

// A named point on the receiver (a keypoint for pose-estimation labels, render/keypoints.hpp).
struct NamedPoint {
  std::string name;
  Eigen::Vector3d p_m = Eigen::Vector3d::Zero();  // in the receiver body frame (FRD)
  friend bool operator==(const NamedPoint&, const NamedPoint&) = default;
};

struct ReceiverConfig {
  ModelSource model;                                       // receiver body frame (FRD)
  Eigen::Vector3d receptacle_m = Eigen::Vector3d::Zero();  // in the receiver body frame
  // `keypoints: {name: [x, y, z], ...}`, in the order written; empty: the defaults found from the
  // model's geometry (default_receiver_keypoints()).
  std::vector<NamedPoint> keypoints;
};

// How the cameras' frames pair when they come from the cameras' `source` URIs: the parameters of
// a stereo:[..]// source URI (docs/CAPTURE.md), checked on load. What the rig's wiring allows:
// a shared trigger (mode trigger_id), PTP (clock shared), or free-running cameras.
// Largest pairing tolerance, microseconds (10 s: far beyond any frame period; a bound so that it
// converts to nanoseconds without overflow).
inline constexpr double kMaxPairingToleranceUs = 1e7;

struct RigPairing {
  double tolerance_us = 2000.0;    // largest skew that pairs (keep it under half the frame period)
  std::string mode = "timestamp";  // timestamp | trigger_id
  std::string clock = "separate";  // separate (each camera its own clock) | shared (PTP)
  int queue = 8;                   // frames kept per camera while waiting for a partner
  static bool known_mode(std::string_view m) { return m == "timestamp" || m == "trigger_id"; }
  static bool known_clock(std::string_view c) { return c == "separate" || c == "shared"; }
};

struct Rig {
  std::string source;              // file it came from ("<built-in>" for defaults)
  std::vector<RigCamera> cameras;  // [0] left, [1] right
  RigPairing pairing;
  BoomConfig boom;
  ReceiverConfig receiver;

  const RigCamera& left() const { return cameras.at(0); }
  const RigCamera& right() const { return cameras.at(1); }
  // T_right_left: left-camera coordinates -> right-camera coordinates.
  Pose T_right_left() const { return right().T_body_cam.inverse() * left().T_body_cam; }

  // The seed paper's rig: 1280x960, 56 deg horizontal FOV, two cameras 0.5 m apart under the
  // fuselage looking aft 25 deg down, near 1 m, far 100 m; a KC-135-class boom; the built-in receiver.
  static Rig paper_default();
};

// R_body_cam for a camera whose optical axis points along yaw/pitch/roll of a "mount" frame
// (FRD-like, x along the optical axis), e.g. yaw 180 deg, pitch -25 deg: looking aft, 25 deg down.
Eigen::Matrix3d R_body_cam_from_mount_ypr(double yaw_rad, double pitch_rad, double roll_rad);

Expected<Rig> load_rig(const std::string& path);
// Parses rig YAML text; `name` is used in error messages (a path, or "<string>").
Expected<Rig> parse_rig(const std::string& yaml_text, const std::string& name);
// Writes a rig file that load_rig() reads back to an equal Rig.
std::string rig_to_yaml(const Rig& rig);

}  // namespace augrig
