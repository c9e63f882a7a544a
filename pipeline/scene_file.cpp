#include "pipeline/scene_file.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <set>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "core/file_check.hpp"
#include "core/pose.hpp"
#include "core/yaml_reader.hpp"

namespace augrig {
namespace {

using namespace yaml;  // located errors, key checks, numbers (core/yaml_reader.hpp)
using Ctx = yaml::Context;

// Limits went through deg -> rad -> deg: 9 significant digits hide the rounding.
std::string fmt_limit(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

// A boom angle or extension, checked against the rig's limits in the file's own unit.
double limited(const Ctx& c, const YAML::Node& boom, const std::string& name, double lo, double hi,
               const std::string& unit) {
  const std::string key = "boom." + name;
  const YAML::Node n = require(c, boom, "boom", name, "a number in " + unit);
  const double v = to_number(c, n, key, "a number in " + unit);
  // A hair of slack: limits went through deg -> rad -> deg.
  const double eps = 1e-9 * std::max(1.0, std::max(std::abs(lo), std::abs(hi)));
  if (v < lo - eps || v > hi + eps) {
    fail(c, n, key,
         "expected a value within the rig's limits [" + fmt_limit(lo) + ", " + fmt_limit(hi) + "] " + unit +
             ", got " + fmt(v));
  }
  return v;
}

BoomArticulation parse_boom(const Ctx& c, const YAML::Node& root, const Rig& rig) {
  const std::string what = "a map {elevation_deg, azimuth_deg, extension_m}";
  const YAML::Node boom = require(c, root, "", "boom", what);
  expect_map(c, boom, "boom", what);
  check_keys(c, boom, "boom", {"elevation_deg", "azimuth_deg", "extension_m"});
  const BoomLimits& l = rig.boom.limits;
  BoomArticulation a;
  a.elevation_rad = deg_to_rad(limited(c, boom, "elevation_deg", rad_to_deg(l.elevation_min_rad),
                                       rad_to_deg(l.elevation_max_rad), "degrees"));
  a.azimuth_rad = deg_to_rad(limited(c, boom, "azimuth_deg", rad_to_deg(l.azimuth_min_rad),
                                     rad_to_deg(l.azimuth_max_rad), "degrees"));
  a.extension_m = limited(c, boom, "extension_m", l.extension_min_m, l.extension_max_m, "metres");
  return a;
}

Eigen::Matrix3d parse_ypr(const Ctx& c, const YAML::Node& rec) {
  const YAML::Node n = rec["ypr_deg"];
  if (!n.IsDefined()) return Eigen::Matrix3d::Identity();
  const Eigen::Vector3d ypr = to_vec3(c, n, "receiver.ypr_deg", "[yaw, pitch, roll] in degrees");
  return rotation_from_ypr(deg_to_rad(ypr[0]), deg_to_rad(ypr[1]), deg_to_rad(ypr[2]));
}

// The receiver map: a pose relative to the body or a camera, or "at contact" with the nozzle.
void parse_receiver(const Ctx& c, const YAML::Node& root, const Rig& rig, const BoomDimensions& dims,
                    const Eigen::Vector3d& receptacle_m, SceneState& scene) {
  const std::string what =
      "a map {frame: body|left|right, translation_m, ypr_deg} or {at_contact: true, offset_m, ypr_deg}";
  const YAML::Node rec = require(c, root, "", "receiver", what);
  expect_map(c, rec, "receiver", what);
  check_keys(c, rec, "receiver", {"frame", "translation_m", "ypr_deg", "at_contact", "offset_m", "present"});
  if (const YAML::Node p = rec["present"]; p.IsDefined())
    scene.receiver_present = to_bool(c, p, "receiver.present");

  const YAML::Node contact = rec["at_contact"];
  const bool at_contact = contact.IsDefined() && to_bool(c, contact, "receiver.at_contact");
  if (at_contact) {
    // The two ways of placing the receiver exclude each other; say which key is in the way.
    for (const char* k : {"frame", "translation_m"}) {
      if (rec[k].IsDefined())
        fail(c, rec[k], std::string("receiver.") + k, "not allowed with at_contact: true");
    }
    Eigen::Vector3d offset = Eigen::Vector3d::Zero();
    if (const YAML::Node o = rec["offset_m"]; o.IsDefined()) {
      offset = to_vec3(c, o, "receiver.offset_m", "[dx, dy, dz] in metres (tanker body frame)");
    }
    // Receptacle at the nozzle tip (plus offset): t_body_recv + R * receptacle = tip + offset.
    const Eigen::Matrix3d R = parse_ypr(c, rec);
    const Eigen::Vector3d tip = nozzle_tip_body(rig.boom.pivot_body_m, dims, scene.boom);
    scene.T_body_receiver = Pose::from(R, tip + offset - R * receptacle_m);
    return;
  }

  if (const YAML::Node o = rec["offset_m"]; o.IsDefined()) {
    fail(c, o, "receiver.offset_m", "only allowed with at_contact: true");
  }
  // A receiver that is not there needs no pose.
  if (!scene.receiver_present && !rec["frame"].IsDefined() && !rec["translation_m"].IsDefined()) return;

  const YAML::Node fn =
      require(c, rec, "receiver", "frame", "one of body, left, right (or at_contact: true)");
  if (!fn.IsScalar()) fail(c, fn, "receiver.frame", "expected one of body, left, right, " + got(fn));
  const std::string frame = fn.Scalar();
  Pose T_body_frame;
  if (frame == "body") {
    T_body_frame = Pose::identity();
  } else if (frame == "left" || frame == "right") {
    if (rig.cameras.size() < 2) fail(c, fn, "receiver.frame", "the rig has fewer than 2 cameras");
    T_body_frame = (frame == "left" ? rig.left() : rig.right()).T_body_cam;
  } else {
    fail(c, fn, "receiver.frame", "expected one of body, left, right, " + got(fn));
  }
  const Eigen::Vector3d t =
      to_vec3(c, require(c, rec, "receiver", "translation_m", "[x, y, z] in metres"),
              "receiver.translation_m", "[x, y, z] in metres (in frame '" + frame + "')");
  // T_body_receiver = T_body_frame * T_frame_receiver.
  scene.T_body_receiver = T_body_frame * Pose::from(parse_ypr(c, rec), t);
}

// `sun: {azimuth_deg, elevation_deg, direct, sky, ground}`: the sun in the tanker body frame
// (azimuth from the nose, positive to the right; elevation above the wings' plane) and the light's
// shares (SceneLight::sun()'s clear sky by default; direct 0 for an overcast sky).
SceneLight parse_sun(const Ctx& c, const YAML::Node& sun) {
  const std::string what = "a map {azimuth_deg, elevation_deg, direct, sky, ground}";
  expect_map(c, sun, "sun", what);
  check_keys(c, sun, "sun", {"azimuth_deg", "elevation_deg", "direct", "sky", "ground"});
  const double az = deg_to_rad(to_number(c, require(c, sun, "sun", "azimuth_deg", "degrees from the nose"),
                                         "sun.azimuth_deg", "degrees from the nose, positive right"));
  const YAML::Node el_node = require(c, sun, "sun", "elevation_deg", "degrees above the wings' plane");
  const double el_deg = to_number(c, el_node, "sun.elevation_deg", "degrees above the wings' plane");
  if (el_deg < -90 || el_deg > 90) fail(c, el_node, "sun.elevation_deg", "expected -90..90 degrees, got " + fmt(el_deg));
  const double el = deg_to_rad(el_deg);
  SceneLight l = SceneLight::sun(Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), -std::sin(el)),
                                 true, LightSource::kConfigured);
  for (const auto& [key, value] :
       {std::pair{"direct", &l.direct}, std::pair{"sky", &l.sky}, std::pair{"ground", &l.ground}})
    if (const YAML::Node n = sun[key]; n.IsDefined()) {
      // One share for every channel (a grey light).
      const double v = to_number(c, n, std::string("sun.") + key, "a share of the light, 0..2");
      if (!(v >= 0 && v <= 2)) fail(c, n, std::string("sun.") + key, "expected 0..2, got " + fmt(v));
      *value = Eigen::Vector3d::Constant(v);
    }
  // An overcast sky (no direct light) casts no shadow; a sun below the wings' plane still may.
  l.sun_up = l.direct.maxCoeff() > 0;
  return l;
}

SceneState parse_root(const Ctx& c, const YAML::Node& root, const Rig& rig, const BoomDimensions& dims,
                      const Eigen::Vector3d& receptacle_m, SceneExtras& extras) {
  if (!root.IsMap()) {
    fail(c, root, "", "expected a scene file (a map starting with 'augrig_scene: 1'), " + got(root));
  }
  check_keys(c, root, "", {"augrig_scene", "t_ns", "boom", "receiver", "sun"});
  const YAML::Node version = require(c, root, "", "augrig_scene", "the format version, augrig_scene: 1");
  if (!version.IsScalar() || version.Scalar() != "1") {
    fail(c, version, "augrig_scene", "expected format version 1, " + got(version));
  }
  if (const YAML::Node t = root["t_ns"]; t.IsDefined()) {
    long long v = 0;
    if (!t.IsScalar() || !YAML::convert<long long>::decode(t, v)) {
      fail(c, t, "t_ns", "expected an integer timestamp in nanoseconds, " + got(t));
    }
    extras.t_ns = static_cast<TimestampNs>(v);
  }
  SceneState scene;
  scene.boom = parse_boom(c, root, rig);
  parse_receiver(c, root, rig, dims, receptacle_m, scene);
  if (const YAML::Node sun = root["sun"]; sun.IsDefined()) scene.light = parse_sun(c, sun);
  return scene;
}

Expected<SceneState> parse_with(const std::string& text, const Ctx& c, const Rig& rig,
                                const BoomDimensions& dims, const Eigen::Vector3d& receptacle_m,
                                SceneExtras* extras) {
  return guarded(c, [&] {
    SceneExtras ex;
    SceneState scene = parse_root(c, YAML::Load(text), rig, dims, receptacle_m, ex);
    if (extras) *extras = ex;
    return scene;
  });
}

}  // namespace

Expected<SceneState> load_scene(const std::string& path, const Rig& rig, const BoomDimensions& boom,
                                const Eigen::Vector3d& receptacle_m, SceneExtras* extras) {
  const Ctx c{"scene::load(): ", path};
  // A directory would open and read as an empty document ("got nothing (null)").
  auto text = read_text_file(c.prefix, path, "scene file");
  if (!text) return text.error();
  return parse_with(*text, c, rig, boom, receptacle_m, extras);
}

Expected<SceneState> parse_scene(const std::string& yaml_text, const std::string& name, const Rig& rig,
                                 const BoomDimensions& boom, const Eigen::Vector3d& receptacle_m,
                                 SceneExtras* extras) {
  return parse_with(yaml_text, Ctx{"scene::parse(): ", name}, rig, boom, receptacle_m, extras);
}

}  // namespace augrig
