#include "render/rig_check.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "core/conventions.hpp"

namespace augrig {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The angle (degrees) between the rays of two raw pixels; NaN when either has none.
double angle_between(const CameraModel& m, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const auto ra = m.ray(a), rb = m.ray(b);
  if (!ra || !rb) return kNaN;
  return rad_to_deg(std::acos(std::clamp(ra->normalized().dot(rb->normalized()), -1.0, 1.0)));
}

std::string fmt(double v, int decimals) {
  if (std::abs(v) < 0.5 * std::pow(10.0, -decimals)) v = 0;  // no "-0.000"
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}

std::string vec(const Eigen::Vector3d& v, int decimals = 3) {
  return "[" + fmt(v.x(), decimals) + ", " + fmt(v.y(), decimals) + ", " + fmt(v.z(), decimals) + "]";
}

}  // namespace

RigSummary summarize_rig(const Rig& rig, const BoomDimensions& boom, const Eigen::Vector3d& receptacle_m) {
  RigSummary s;
  // The contact checked: the boom at the middle of its limits (azimuth 0 when the limits allow it).
  const BoomLimits& L = rig.boom.limits;
  s.contact.elevation_rad = 0.5 * (L.elevation_min_rad + L.elevation_max_rad);
  s.contact.azimuth_rad = std::clamp(0.0, L.azimuth_min_rad, L.azimuth_max_rad);
  s.contact.extension_m = 0.5 * (L.extension_min_m + L.extension_max_m);
  const Eigen::Vector3d tip_body = boom_pose(rig.boom.pivot_body_m, s.contact) *
                                   Eigen::Vector3d(boom.nozzle_tip_m(s.contact.extension_m), 0, 0);
  s.receptacle_body_m = tip_body;                      // the receptacle sits at the nozzle tip at contact
  s.receiver_origin_body_m = tip_body - receptacle_m;  // the receiver level, as scene_at_contact()

  for (const RigCamera& c : rig.cameras) {
    RigCameraSummary k;
    const CameraModel& m = c.model;
    k.name = c.name;
    k.width_px = m.width_px, k.height_px = m.height_px;
    k.distortion = m.distortion_name();
    k.fx_px = m.fx_px, k.fy_px = m.fy_px, k.cx_px = m.cx_px, k.cy_px = m.cy_px;
    // Outer edges of the edge pixels, through the principal point's row and column.
    const double cx = std::clamp(m.cx_px, 0.0, m.width_px - 1.0),
                 cy = std::clamp(m.cy_px, 0.0, m.height_px - 1.0);
    k.hfov_deg = angle_between(m, {-0.5, cy}, {m.width_px - 0.5, cy});
    k.vfov_deg = angle_between(m, {cx, -0.5}, {cx, m.height_px - 0.5});
    k.position_body_m = c.T_body_cam.translation_m;
    const Eigen::Vector3d axis = c.T_body_cam.R() * Eigen::Vector3d::UnitZ();  // optical axis, body frame
    k.axis_azimuth_deg = rad_to_deg(std::atan2(axis.y(), axis.x()));
    k.axis_depression_deg = rad_to_deg(std::asin(std::clamp(axis.z(), -1.0, 1.0)));
    k.near_m = c.near_m, k.far_m = c.far_m;
    k.source_uri = c.source_uri;
    const Eigen::Vector3d p_cam = c.T_body_cam.inverse() * s.receptacle_body_m;
    k.receptacle_z_m = rig.boom.configured ? p_cam.z() : std::numeric_limits<double>::quiet_NaN();
    if (rig.boom.configured && p_cam.z() > 0) k.receptacle_px = m.project(p_cam);
    s.cameras.push_back(k);
  }

  auto warn = [&s](const std::string& w) { s.warnings.push_back(w); };
  if (rig.cameras.size() == 2) {
    const Pose T_rl = rig.T_right_left();
    s.baseline_left_m = T_rl.inverse().translation_m;
    s.baseline_m = s.baseline_left_m.norm();
    const Eigen::Vector3d a0 = rig.left().T_body_cam.R().col(2), a1 = rig.right().T_body_cam.R().col(2);
    s.axes_angle_deg = rad_to_deg(std::acos(std::clamp(a0.dot(a1), -1.0, 1.0)));
    if (s.baseline_m > 5.0)
      warn("the cameras are " + fmt(s.baseline_m, 3) +
           " m apart: a camera rig's baseline is centimetres to a few " +
           "metres; a translation given in millimetres (or centimetres) instead of metres?");
    else if (s.baseline_m < 0.01)
      warn("the cameras are " + fmt(1000 * s.baseline_m, 2) +
           " mm apart: no usable stereo baseline (the same " + "pose given twice?)");
    if (s.axes_angle_deg > 20.0)
      warn("the cameras' optical axes are " + fmt(s.axes_angle_deg, 1) +
           " degrees apart: a stereo rig's cameras look nearly the same way (a rotation given in the wrong " +
           "convention or units?)");
  }
  // The receiver at contact: below the tanker and aft of the pivot, in front of each camera and in
  // its image. A capture-only rig has no boom to be at contact with.
  if (!rig.boom.configured) return s;
  if (s.receptacle_body_m.z() <= 0 || s.receiver_origin_body_m.z() <= 0)
    warn("at contact (boom at the middle of its limits) the receptacle is " +
         fmt(s.receptacle_body_m.z(), 2) + " m below the tanker's body x-y plane and the receiver's origin " +
         fmt(s.receiver_origin_body_m.z(), 2) + " m: the receiver would be inside or " +
         "above the tanker (boom elevation limits with the wrong sign, or in radians?)");
  if (s.receptacle_body_m.x() >= rig.boom.pivot_body_m.x())
    warn("at contact the receptacle is forward of the boom pivot: the boom points forward, into the tanker " +
         std::string("(azimuth limits around 180 degrees?)"));
  for (const RigCameraSummary& k : s.cameras) {
    if (k.receptacle_z_m <= 0)
      warn("camera '" + k.name + "': the receiver at contact is behind the camera (camera z " +
           fmt(k.receptacle_z_m, 2) + " m): the camera looks away from the boom (its orientation?)");
    else if (!k.receptacle_px || k.receptacle_px->x() < -0.5 || k.receptacle_px->y() < -0.5 ||
             k.receptacle_px->x() > k.width_px - 0.5 || k.receptacle_px->y() > k.height_px - 0.5)
      warn("camera '" + k.name + "': the receptacle at contact is outside the image" +
           (k.receptacle_px
                ? " (pixel " + fmt(k.receptacle_px->x(), 0) + ", " + fmt(k.receptacle_px->y(), 0) + ")"
                : std::string()) +
           ": the camera does not see the refuelling (its orientation or field of view?)");
    else if (k.receptacle_z_m < k.near_m || k.receptacle_z_m > k.far_m)
      warn("camera '" + k.name + "': the receptacle at contact is " + fmt(k.receptacle_z_m, 2) +
           " m along the optical axis, outside near_m..far_m (" + fmt(k.near_m, 2) + ".." + fmt(k.far_m, 2) +
           "): it would not be drawn");
  }
  return s;
}

std::string format_rig_summary(const Rig& rig, const RigSummary& s) {
  std::ostringstream o;
  o << "rig " << rig.source << ": " << s.cameras.size() << " camera(s)\n";
  for (const RigCameraSummary& k : s.cameras) {
    o << "  camera '" << k.name << "': " << k.width_px << "x" << k.height_px << ", " << k.distortion
      << ", fx " << fmt(k.fx_px, 2) << " fy " << fmt(k.fy_px, 2) << " cx " << fmt(k.cx_px, 2) << " cy "
      << fmt(k.cy_px, 2) << " px\n"
      << "    field of view " << fmt(k.hfov_deg, 2) << " x " << fmt(k.vfov_deg, 2)
      << " deg (horizontal x vertical)\n"
      << "    centre " << vec(k.position_body_m) << " m (tanker body FRD), looking "
      << fmt(k.axis_azimuth_deg, 2) << " deg azimuth (0 forward, 90 starboard, 180 aft), "
      << fmt(k.axis_depression_deg, 2) << " deg below the body x-y plane\n"
      << "    near " << fmt(k.near_m, 2) << " m, far " << fmt(k.far_m, 2) << " m"
      << (k.source_uri.empty() ? std::string() : ", source " + k.source_uri) << "\n";
    if (rig.boom.configured) {
      o << "    receptacle at contact: " << fmt(k.receptacle_z_m, 3) << " m along the axis";
      if (k.receptacle_px)
        o << ", pixel (" << fmt(k.receptacle_px->x(), 1) << ", " << fmt(k.receptacle_px->y(), 1) << ")";
      o << "\n";
    }
  }
  if (s.cameras.size() == 2)
    o << "  baseline " << fmt(s.baseline_m, 4) << " m (the right camera at " << vec(s.baseline_left_m, 4)
      << " m in the left camera's frame), optical axes " << fmt(s.axes_angle_deg, 2) << " deg apart\n";
  if (!rig.boom.configured) {
    o << "  boom: none: a capture-only rig (its cameras can be recorded; augmenting needs a boom section)\n";
  } else {
    o << "  boom: pivot " << vec(rig.boom.pivot_body_m) << " m, elevation "
      << fmt(rad_to_deg(rig.boom.limits.elevation_min_rad), 1) << ".."
      << fmt(rad_to_deg(rig.boom.limits.elevation_max_rad), 1) << " deg, azimuth "
      << fmt(rad_to_deg(rig.boom.limits.azimuth_min_rad), 1) << ".."
      << fmt(rad_to_deg(rig.boom.limits.azimuth_max_rad), 1) << " deg, extension "
      << fmt(rig.boom.limits.extension_min_m, 2) << ".." << fmt(rig.boom.limits.extension_max_m, 2)
      << " m; model " << (rig.boom.model.path.empty() ? std::string("built-in") : rig.boom.model.path)
      << "\n";
    o << "  receiver: model "
      << (rig.receiver.model.path.empty() ? std::string("built-in") : rig.receiver.model.path)
      << "; at contact (elevation " << fmt(rad_to_deg(s.contact.elevation_rad), 1) << " deg, azimuth "
      << fmt(rad_to_deg(s.contact.azimuth_rad), 1) << " deg, extension " << fmt(s.contact.extension_m, 2)
      << " m) the receptacle is at " << vec(s.receptacle_body_m) << " m, the receiver's origin at "
      << vec(s.receiver_origin_body_m) << " m (body FRD)\n";
  }
  o << "  pairing: " << rig.pairing.mode << ", clock " << rig.pairing.clock << ", tolerance "
    << fmt(rig.pairing.tolerance_us, 0) << " us\n";
  if (s.warnings.empty()) o << "No warnings.\n";
  for (const std::string& w : s.warnings) o << "WARNING: " << w << "\n";
  return o.str();
}

}  // namespace augrig
