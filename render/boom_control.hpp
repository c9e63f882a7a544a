// Boom control: where the boom points for each frame. Three modes, as a boom operator flies it:
//   fixed              one articulation for the whole run;
//   scripted           a CSV timeline (t_s, elevation_deg, azimuth_deg, extension_m), interpolated;
//   track receptacle   the nozzle tip aims at the receiver's receptacle (from the fused relative
//                      pose), clamped to the rig's elevation, azimuth and extension limits.
// All articulations obey the rig's limits; a commanded value outside them is clamped and flagged.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"

namespace augrig {

// Nozzle tip in the tanker body frame for an articulation.
Eigen::Vector3d nozzle_tip_body(const Eigen::Vector3d& pivot_body_m, const BoomDimensions& boom,
                                const BoomArticulation& a);

struct BoomCommand {
  BoomArticulation articulation;
  bool clamped = false;  // the wanted articulation lay outside the limits
  // Distance from the nozzle tip to the target (track mode; 0 otherwise), metres.
  double miss_m = 0;
};

// Clamps an articulation to the limits.
BoomCommand clamp_to_limits(const BoomArticulation& a, const BoomLimits& limits);

// The articulation whose nozzle tip lies on `target_body_m` (tanker body frame), or the nearest
// reachable one within the limits.
BoomCommand track_point(const Eigen::Vector3d& target_body_m, const Eigen::Vector3d& pivot_body_m,
                        const BoomDimensions& boom, const BoomLimits& limits);

// A scripted boom timeline. Times are seconds from the source's first frame (a recording's or EuRoC
// folder's first, whatever frame a run starts at; a live source's first frame of the run).
struct BoomScriptPoint {
  double t_s = 0;
  BoomArticulation articulation;
};
struct BoomScript {
  std::vector<BoomScriptPoint> points;  // strictly increasing t_s, at least one
  // Linear interpolation between points; held before the first and after the last.
  BoomArticulation at(double t_s) const;
};
// Reads `t_s,elevation_deg,azimuth_deg,extension_m` CSV (a header line, '#' comments allowed).
// Errors name the file, line and column and what was expected.
Expected<BoomScript> load_boom_script(const std::string& path);
Expected<BoomScript> parse_boom_script(const std::string& text, const std::string& name);

enum class BoomMode { kFixed, kScripted, kTrackReceptacle };
std::string_view to_string(BoomMode m);
Expected<BoomMode> boom_mode_from_string(std::string_view s);

}  // namespace augrig
