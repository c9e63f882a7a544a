// Truth trajectories of a simulated refuelling flight (docs/SIMULATION.md, "Simulated flights"):
// the tanker flies straight and level or a racetrack at constant ellipsoidal height, and the
// receiver flies a scripted path relative to the tanker (observation, pre-contact, contact, ...)
// with smooth Dryden-like turbulence. Everything is an analytic function of time, evaluated with
// exact derivatives (truncated Taylor arithmetic), so velocities, accelerations and body rates are
// the true derivatives of positions and attitudes, to rounding.
//
// Time: t_s, seconds since the scenario start. Frames and units: core/conventions.hpp.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "core/pose.hpp"
#include "render/models.hpp"

namespace augrig::sim {

struct Scenario;

// State of a body origin at time t_s; all derivatives are taken w.r.t. the Earth-fixed frame.
struct KinematicState {
  double t_s = 0;
  Eigen::Vector3d p_ecef_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_ecef_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d a_ecef_mps2 = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_ecef_body = Eigen::Quaterniond::Identity();  // R_ecef_body
  Eigen::Vector3d w_eb_body_radps = Eigen::Vector3d::Zero();        // body rate w.r.t. ECEF, body axes
  Eigen::Vector3d dw_eb_body_radps2 = Eigen::Vector3d::Zero();      // its time derivative, body axes

  Eigen::Matrix3d R_ecef_body() const { return q_ecef_body.toRotationMatrix(); }
  Pose T_ecef_body() const { return {q_ecef_body, p_ecef_m}; }
};

enum class TankerPattern { kStraight, kRacetrack };

// The tanker's flight. No wind: true airspeed = ground speed. Attitude:
//   R_ned_body = Rz(track + crab) * Rx(bank) * Ry(angle_of_attack)
// (the velocity frame banked about the flight path, then nose up by the angle of attack).
struct TankerFlightConfig {
  TankerPattern pattern = TankerPattern::kStraight;
  double heading_rad = deg_to_rad(90.0);  // track of the first leg, from north towards east
  double speed_mps = 160.0;               // >= 0; > 0 for a racetrack
  double bank_rad = deg_to_rad(25.0);     // racetrack turns, coordinated: turn rate g tan(bank) / V
  double leg_length_m = 15000.0;          // racetrack straight legs
  bool turn_right = true;                 // racetrack turn direction
  double roll_in_s = 5.0;                 // racetrack roll-in and roll-out time (turn rate ramps, C2)
  double angle_of_attack_rad = deg_to_rad(3.0);
  double crab_rad = 0.0;  // constant yaw of the nose from the track
  bool operator==(const TankerFlightConfig&) const = default;
};

// One phase of the receiver's path. The receptacle moves by a minimum-jerk (quintic) transition
// from where the previous phase ended (the first phase: its own end point, a hold) to `offset_m`
// at the end of the phase; the relative attitude likewise to `ypr_rad`.
struct ReceiverPhase {
  std::string name;
  double duration_s = 1.0;
  // Receptacle relative to the contact point (the nozzle tip at the contact articulation), tanker
  // body frame FRD, at the end of the phase.
  Eigen::Vector3d offset_m = Eigen::Vector3d::Zero();
  // Receiver attitude relative to the tanker (yaw, pitch, roll; R_tanker_receiver = Rz Ry Rx) at
  // the end of the phase.
  Eigen::Vector3d ypr_rad = Eigen::Vector3d::Zero();
  // The boom is latched: it follows the receptacle (inverse kinematics), turbulence included.
  bool attached = false;
  bool operator==(const ReceiverPhase&) const = default;
};

// Turbulence of the receiver relative to the tanker: per axis a Dryden spectrum at the tanker's
// speed V and length scale L (longitudinal form for x and roll, transverse form for y, z, yaw and
// pitch), realised as a seeded sum of `components` sinusoids per axis (smooth and analytic) whose
// variance is exactly sigma^2. All sigmas zero: no turbulence.
struct TurbulenceConfig {
  Eigen::Vector3d sigma_m = Eigen::Vector3d::Zero();    // receptacle position x, y, z (tanker body)
  Eigen::Vector3d sigma_rad = Eigen::Vector3d::Zero();  // relative yaw, pitch, roll
  double length_scale_m = 500.0;
  int components = 32;
  bool operator==(const TurbulenceConfig&) const = default;
};

struct ReceiverFlightConfig {
  BoomArticulation contact{deg_to_rad(30.0), 0.0, 3.5};  // boom articulation at contact
  std::vector<ReceiverPhase> phases;                     // at least one
  TurbulenceConfig turbulence;
  bool operator==(const ReceiverFlightConfig& o) const {
    return contact.elevation_rad == o.contact.elevation_rad && contact.azimuth_rad == o.contact.azimuth_rad &&
           contact.extension_m == o.contact.extension_m && phases == o.phases && turbulence == o.turbulence;
  }
};

// The truth of one scenario as functions of time. Immutable after create(); cheap to copy (shared
// state); safe to evaluate from several threads. Accurate for t in [-60 s, duration + 60 s]; outside,
// the tanker's path is extrapolated (smooth, increasingly inexact).
class Flight {
 public:
  static Expected<Flight> create(const Scenario& scenario);

  KinematicState tanker(double t_s) const;
  KinematicState receiver(double t_s) const;
  // Receiver body frame in the tanker body frame.
  Pose T_tanker_receiver(double t_s) const;
  // Name of the receiver phase at t (the first phase before 0, the last after the end of all phases).
  const std::string& phase(double t_s) const;
  // Boom articulation: the contact articulation, or, in an attached phase, the one that puts the
  // nozzle tip on the receptacle.
  BoomArticulation boom(double t_s) const;

  // Nozzle tip at the contact articulation, tanker body frame.
  const Eigen::Vector3d& contact_point_body_m() const;
  // The receptacle in the receiver body frame (the built-in receiver's unless the rig names a model).
  const Eigen::Vector3d& receptacle_m() const;
  double duration_s() const;
  // Racetrack: nominal radius of the constant-rate part of the turns, V^2 / (g tan(bank)), with g the
  // normal gravity at the start point; 0 for a straight flight.
  double turn_radius_m() const;
  // The g used for the coordinated turns (normal gravity magnitude at the start point and height).
  double turn_gravity_mps2() const;

  struct Impl;

 private:
  std::shared_ptr<const Impl> impl_;
};

}  // namespace augrig::sim
