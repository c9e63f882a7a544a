// Built-in procedural models: a KC-135/KC-46-class refuelling boom and a generic light-twin
// receiver with a textured livery (texture gives stereo matching something to match later).
#pragma once

#include <optional>

#include <Eigen/Core>

#include "core/pose.hpp"
#include "render/mesh.hpp"

namespace augrig {

// Boom dimensions in metres (KC-135 class: 8.5 m to 14.3 m from pivot to nozzle tip).
struct BoomDimensions {
  double fixed_tube_length_m = 7.0;  // outer tube, pivot to its aft end
  double fixed_tube_diameter_m = 0.46;
  double telescope_diameter_m = 0.25;
  double telescope_length_m = 7.0;  // inner tube; at extension 0 it sticks out `telescope_stick_out_m`
  double telescope_stick_out_m = 1.0;
  double nozzle_length_m = 0.5;
  double ruddevator_station_m = 5.2;  // along the boom, leading edge of the ruddevators
  double ruddevator_span_m = 2.1;     // each panel, root to tip
  double ruddevator_chord_m = 0.9;
  double ruddevator_dihedral_deg = 37.5;
  double ruddevator_tip_chord_m = 0.6;
  double ruddevator_thickness_m = 0.08;  // at the root; the tip keeps the same thickness/chord ratio
  double fairing_diameter_m = 0.7;       // streamlined root fairing around the pivot
  // Distance from the pivot to the nozzle tip at extension `e`.
  double nozzle_tip_m(double extension_m) const {
    return fixed_tube_length_m + telescope_stick_out_m + extension_m + nozzle_length_m;
  }
};

// The boom as two rigid parts in the boom frame (x along the boom from the pivot):
// `fixed` (fairing, outer tube, ruddevators) and `telescope` (inner tube and nozzle, at
// extension 0; it moves by +extension along x).
struct BoomModel {
  Model fixed;
  Model telescope;
  BoomDimensions dims;
};
BoomModel make_builtin_boom(const BoomDimensions& dims = {});
// The rig's `boom.material` (BoomConfig::material) on every mesh whose finish its model file did
// not give: all of the built-in boom's, a file's meshes without a material. Absent: unchanged (the
// built-in paint, kPaintedBoom, or what a caller set).
void apply_boom_material(BoomModel& boom, const std::optional<SurfaceFinish>& material);

// Generic light twin (~13.3 m long, ~16.6 m span) in its body frame (FRD, origin near the CG),
// textured livery. `receptacle_m` receives the refuelling receptacle's position (top of the nose).
Model make_builtin_receiver(Eigen::Vector3d* receptacle_m = nullptr);

struct BoomArticulation {
  double elevation_rad = 0;  // below the body x-y plane, positive down
  double azimuth_rad = 0;    // positive towards body +y
  double extension_m = 0;
};

// T_body_boom for an articulation: R_body_boom = Rz(pi - azimuth) * Ry(-elevation), origin at the pivot.
Pose boom_pose(const Eigen::Vector3d& pivot_body_m, const BoomArticulation& a);
// T_boom_telescope: the telescope part's pose in the boom frame (a translation along x).
Pose telescope_pose(const BoomArticulation& a);

}  // namespace augrig
