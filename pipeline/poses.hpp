// Pose providers: where each stereo frame's receiver pose comes from, with a verdict in plain
// words. One interface, one implementation per source of poses:
//   fixed scene      one SceneState for every frame (a scene file);
//   simulation truth the sim:// flight's truth at each frame's true mid-exposure;
//   live nav         the real-time GPS/INS fusion of both aircraft (LiveNav), at mid-exposure;
//   recorded         the poses and boom stored with a replayed recording's frames;
//   poses CSV        `augrig nav`'s camera pose CSV (poses.csv), matched by camera timestamp;
//   offline nav      both aircraft fused from their logs with smoothing (RelativeNav).
// A provider answers for the left camera's frame (the right one is within the pairing tolerance)
// and gives the receiver in the tanker body frame; the pipeline derives each camera's pose from
// the rig. Where a provider knows the boom too (a scene, a recording, the truth), it says so.
#pragma once

#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/frame.hpp"
#include "pipeline/flight_nav.hpp"
#include "pipeline/live_nav.hpp"
#include "pipeline/sources.hpp"
#include "pipeline/status.hpp"
#include "render/augmenter.hpp"
#include "render/rig.hpp"

namespace augrig::pipeline {

class CameraClocks;  // camera_clock_online.hpp

// One frame's poses.
struct FramePoses {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  std::optional<SceneState> scene;    // unset: no pose for this frame (see problems)
  bool boom_given = false;            // scene->boom is the source's own (not a default)
  bool stale = false;                 // a pose, but from data older than the source allows
  std::vector<std::string> problems;  // plain words, e.g. "receiver GPS: no fix for 2.4 s"
  NavHud hud;
  double sigma_pos_m = kNaN, sigma_att_deg = kNaN;  // 1-sigma of the relative pose, where known
  // The pose's time on the nav clock (GPS time) where the provider maps frames onto it (offline
  // nav): the statistics are then stamped with it; else with the pair's key time.
  std::optional<TimestampNs> t_nav_ns;
};

class PoseProvider {
 public:
  virtual ~PoseProvider() = default;
  // "the scene S.yaml", "the live nav (GPS/INS of both aircraft)", ... for banners and recordings.
  virtual std::string describe() const = 0;
  // The poses of `frame`; `mid_host_left_ns` is the left camera's mid-exposure on the host clock
  // (0: unknown), for sources on host time.
  virtual FramePoses at(const StereoFrame& frame, TimestampNs mid_host_left_ns) = 0;
  // True when the poses come from the live nav (the HUD shows its verdicts).
  virtual bool live() const { return false; }
};

std::unique_ptr<PoseProvider> fixed_scene_poses(const SceneState& scene, const std::string& name);
// The truth of a sim:// flight, by (camera, t_ns) of its frames.
std::unique_ptr<PoseProvider> sim_truth_poses(const SimulatedFlight& sim);
// `camera_offset_ns`: the cameras' calibrated offsets to GPS time (the simulation's); empty: frames
// reach the nav clock through the host clock (LiveNav::host_to_nav()). `clocks` (optional): the
// left camera's online clock estimate, used in their place once applied (camera_clock_online.hpp).
std::unique_ptr<PoseProvider> live_nav_poses(const LiveNav& nav, std::vector<TimestampNs> camera_offset_ns,
                                             const CameraClocks* clocks = nullptr);
// The scene recorded with each replayed frame (Frame::attachment, recorder::RecordedFrame);
// `recorded_rig` turns a camera-relative pose into the body frame when only that was recorded.
std::unique_ptr<PoseProvider> recorded_poses(std::optional<Rig> recorded_rig);
// `augrig nav`'s poses.csv: the left camera's row whose t_ns is the frame's within `tolerance_ns`
// (0: exactly). The rows' T_cam_receiver goes into the body frame through `rig`; the boom columns,
// where given, are the boom.
Expected<std::unique_ptr<PoseProvider>> poses_csv(const std::string& path, const Rig& rig,
                                                  TimestampNs tolerance_ns);
// Both aircraft fused from their logs (forward filter and RTS smoother), at each frame's time.
std::unique_ptr<PoseProvider> offline_nav_poses(std::shared_ptr<const RelativeNav> nav, std::string name);

// The sources of poses a command offers, taken in the one order every command uses: a scene file
// (or, for folders of pairs, a folder of scene files), a poses CSV, the live nav, the poses
// recorded with replayed frames, the simulation's truth. Unset fields are not offered.
struct PoseSources {
  std::string scene_path;                     // --scene: a scene file, or a folder if scene_folder_ok
  bool scene_folder_ok = false;               // a folder of scene files, one per pair (augment)
  BoomDimensions boom_dims;                   // the scene files' boom
  std::string poses_csv_path;                 // --poses
  TimestampNs pose_tolerance_ns = 0;          // --pose-tolerance-ms
  const LiveNav* live_nav = nullptr;          // --nav with streams of both aircraft
  std::vector<TimestampNs> camera_offset_ns;  // with live_nav: the cameras' offsets (live_nav_poses)
  const CameraClocks* camera_clocks = nullptr;  // with live_nav: the online camera clocks (or none)
  bool recorded = false;                      // the frames carry their scene (a replayed recording)
  std::optional<Rig> recorded_rig;            // with recorded: the rig the poses were recorded with
  const SimulatedFlight* sim = nullptr;       // a sim:// flight
};
struct ChosenPoses {
  std::unique_ptr<PoseProvider> provider;  // null when none was offered
  // The provider may have no pose for some frames (a CSV's rows, a recording's frames, a folder's
  // files): a command that must not guess skips those frames (PipelineParts::skip_frames_without_pose).
  bool may_miss_frames = false;
  // The scene files' own timestamps, in pair order (a scene file: one; a folder: one per file).
  std::vector<std::optional<TimestampNs>> scene_t_ns;
};
// The first source offered, in PoseSources' order; errors of a scene file or CSV name the file.
// Several of scene, CSV and live nav at once is an error (they are alternatives, not a ladder).
Expected<ChosenPoses> choose_poses(const PoseSources& sources, const Rig& rig,
                                   const Eigen::Vector3d& receptacle_m);

}  // namespace augrig::pipeline
