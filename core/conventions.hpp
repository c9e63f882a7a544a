// augrig conventions: the one place that fixes frames, units, rotations and clocks.
// Everything else in augrig states its quantities in these terms and includes this header.
//
// Frames (all right-handed):
//   NED   local navigation frame: x north, y east, z down.
//   ECEF  Earth-centred Earth-fixed (WGS84), metres.
//   body  aircraft body frame FRD: x forward (nose), y right (starboard wing), z down.
//   cam   OpenCV camera frame: x right, y down, z forward along the optical axis.
//         Pixel (u, v): u right, v down; integer (u, v) is the CENTRE of a pixel, (0, 0) is the centre
//         of the top-left pixel, so the image spans [-0.5, W-0.5] x [-0.5, H-0.5].
//   gl    OpenGL eye frame: x right, y up, z backward (the camera looks along -z). Used only by
//         the world view; the augmentation renderer projects straight from `cam` (render/projection.hpp).
//   boom  boom frame: origin at the boom pivot, x along the boom towards the nozzle, y to the right
//         of the boom (seen from the pivot looking along x), z completing the right-handed frame.
//   model mesh frame of a model file, converted to body FRD on load (render/mesh.hpp states how).
//
// Transforms: T_a_b maps coordinates of a point expressed in frame b to frame a:
//   p_a = T_a_b * p_b,  T_a_c = T_a_b * T_b_c,  T_b_a = T_a_b.inverse().
//   R_a_b is its rotation. Translations are in metres.
//
// Euler angles: yaw-pitch-roll, intrinsic Z-Y'-X'' (aerospace 3-2-1):
//   R_ned_body = Rz(yaw) * Ry(pitch) * Rx(roll).
//   yaw: heading of the body x axis from north, positive towards east (clockwise seen from above).
//   pitch: nose up positive.  roll: right wing down positive.  All in radians (`_rad`).
//
// Units: SI unless the name says otherwise: `_m`, `_mps`, `_rad`, `_deg`, `_px`, `_ns`, `_s`.
//
// Time: timestamps are int64 nanoseconds (`_ns`) tagged with the clock domain they were read from.
// Image timestamps are mid-exposure.
#pragma once

#include <cstdint>
#include <numbers>
#include <string_view>

namespace augrig {

// The clock a timestamp was read from. Timestamps of different domains are never compared
// without an explicit, recorded offset.
enum class ClockDomain : std::uint8_t {
  kUnknown = 0,
  kHostMonotonic,  // CLOCK_MONOTONIC of the capturing host
  kHostRealtime,   // CLOCK_REALTIME (UTC, subject to steps) of the capturing host
  kDevice,         // a camera's own tick counter, converted to ns
  kGps,            // GPS time (no leap seconds), ns since the GPS epoch 1980-01-06
  kSim,            // simulated time of a synthetic flight, ns since its start
};

constexpr std::string_view to_string(ClockDomain c) {
  switch (c) {
    case ClockDomain::kHostMonotonic:
      return "host_monotonic";
    case ClockDomain::kHostRealtime:
      return "host_realtime";
    case ClockDomain::kDevice:
      return "device";
    case ClockDomain::kGps:
      return "gps";
    case ClockDomain::kSim:
      return "sim";
    case ClockDomain::kUnknown:
      break;
  }
  return "unknown";
}

using TimestampNs = std::int64_t;

inline constexpr double kPi = std::numbers::pi;
constexpr double deg_to_rad(double deg) {
  return deg * (kPi / 180.0);
}
constexpr double rad_to_deg(double rad) {
  return rad * (180.0 / kPi);
}
constexpr double ns_to_s(TimestampNs t_ns) {
  return static_cast<double>(t_ns) * 1e-9;
}
constexpr TimestampNs s_to_ns(double t_s) {
  return static_cast<TimestampNs>(t_s * 1e9 + (t_s >= 0 ? 0.5 : -0.5));
}

// Mask image bits (render/augmenter.hpp writes them, render/stats.hpp reads them).
inline constexpr std::uint8_t kMaskBoom = 1u << 0;  // the boom is the front-most surface at the pixel centre
inline constexpr std::uint8_t kMaskReceiver = 1u << 1;  // the receiver lies on the pixel centre's ray
// The receiver is the front-most surface at the pixel centre (bit 1 set, bit 0 not) and the ray
// from that surface point towards the sun's centre passes through the boom: the boom's shadow.
// Set only where the sun is known and above the horizon (render/boom_shadow.hpp).
inline constexpr std::uint8_t kMaskShadow = 1u << 2;

}  // namespace augrig
