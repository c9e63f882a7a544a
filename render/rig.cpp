#include "render/rig.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <tuple>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "core/conventions.hpp"
#include "core/file_check.hpp"
#include "core/yaml_reader.hpp"
#include "render/calib_import.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;

using namespace yaml;  // located errors, key checks, numbers (core/yaml_reader.hpp)

struct Ctx : yaml::Context {
  fs::path base_dir;  // relative model/calibration paths are resolved against it
};

// Rounds values within `tol` of an integer to it: a rotation rebuilt from a quaternion carries
// 1e-16 noise (-1.0000000000000004) that would only clutter the file; far below the 1e-12 contract.
double snap(double v, double tol) {
  const double r = std::round(v);
  return std::abs(v - r) <= tol ? r : v;
}

// Degrees for a radian value: the shortest decimal whose conversion back gives the same radians,
// so 15 deg is written as 15 and not as 14.999999999999998.
std::string fmt_deg(double rad) {
  for (int precision = 1; precision <= 17; ++precision) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*g", precision, rad_to_deg(rad));
    const double deg = std::strtod(buf, nullptr);
    if (deg_to_rad(deg) == rad) return fmt(deg);
  }
  return fmt(rad_to_deg(rad));
}

// [min, max] with min <= max; scaled (deg -> rad) after checking.
std::pair<double, double> to_range(const Ctx& c, const YAML::Node& n, const std::string& key,
                                   const std::string& unit) {
  const auto v = to_numbers(c, n, key, 2, "a list of 2 numbers [min, max] in " + unit);
  if (!(v[0] <= v[1])) fail(c, n, key, "expected min <= max, got [" + fmt(v[0]) + ", " + fmt(v[1]) + "]");
  return {v[0], v[1]};
}

std::string resolve_path(const Ctx& c, const std::string& p) {
  const fs::path path(p);
  return (path.is_absolute() ? path : (c.base_dir / path)).lexically_normal().string();
}

// Axis string ("+x" ...) -> unit vector in the model file's coordinates; nullopt when malformed.
std::optional<Eigen::Vector3d> axis_vector(const std::string& s) {
  if (s.size() != 2 || (s[0] != '+' && s[0] != '-')) return std::nullopt;
  const double sign = s[0] == '+' ? 1.0 : -1.0;
  if (s[1] == 'x') return Eigen::Vector3d(sign, 0, 0);
  if (s[1] == 'y') return Eigen::Vector3d(0, sign, 0);
  if (s[1] == 'z') return Eigen::Vector3d(0, 0, sign);
  return std::nullopt;
}

ModelSource parse_model(const Ctx& c, const YAML::Node& n, const std::string& key) {
  ModelSource m;
  if (n.IsScalar() && n.Scalar() == "builtin") return m;
  if (!n.IsMap()) {
    fail(c, n, key, "expected 'builtin' or a map {path, axes: {forward, right, down}, scale}, " + got(n));
  }
  check_keys(c, n, key, {"path", "axes", "scale"});
  const std::string p = to_string_value(c, require(c, n, key, "path", "the model file's path (string)"),
                                        join_key(key, "path"), "the model file's path (string)");
  if (p.empty()) fail(c, n["path"], join_key(key, "path"), "expected a non-empty path, got ''");
  m.path = resolve_path(c, p);
  if (const YAML::Node s = n["scale"]; s.IsDefined()) {
    m.scale = to_number(c, s, join_key(key, "scale"), "a positive number (file units -> metres)");
    if (!(m.scale > 0)) fail(c, s, join_key(key, "scale"), "expected a positive number, got " + fmt(m.scale));
  }
  if (const YAML::Node a = n["axes"]; a.IsDefined()) {
    const std::string akey = join_key(key, "axes");
    expect_map(c, a, akey, "a map {forward, right, down}");
    check_keys(c, a, akey, {"forward", "right", "down"});
    Eigen::Matrix3d R;  // rows: the model axes that become FRD x, y, z
    std::string* fields[3] = {&m.axes.forward, &m.axes.right, &m.axes.down};
    const char* names[3] = {"forward", "right", "down"};
    for (int i = 0; i < 3; ++i) {
      const std::string k = join_key(akey, names[i]);
      const YAML::Node v = require(c, a, akey, names[i], "one of +x -x +y -y +z -z");
      *fields[i] = to_string_value(c, v, k, "one of +x -x +y -y +z -z");
      const auto axis = axis_vector(*fields[i]);
      if (!axis) fail(c, v, k, "expected one of +x -x +y -y +z -z, " + got(v));
      R.row(i) = axis->transpose();
    }
    // The three must form a proper rotation, or the loaded model would be mirrored or degenerate.
    if (std::abs(R.determinant() - 1.0) > 1e-9) {
      fail(c, a, akey,
           "expected forward/right/down to form a right-handed frame (determinant +1), got forward " +
               m.axes.forward + ", right " + m.axes.right + ", down " + m.axes.down +
               (std::abs(R.determinant()) < 0.5 ? " (an axis is repeated)" : " (mirrored, determinant -1)"));
    }
  }
  return m;
}

Pose parse_T_body_cam(const Ctx& c, const YAML::Node& n, const std::string& key) {
  expect_map(c, n, key, "a map with 'matrix' or 'translation_m' and 'mount_ypr_deg'");
  check_keys(c, n, key, {"matrix", "translation_m", "mount_ypr_deg"});
  const YAML::Node m = n["matrix"];
  if (m.IsDefined()) {
    if (n["translation_m"].IsDefined() || n["mount_ypr_deg"].IsDefined()) {
      fail(c, n, key, "expected either 'matrix' or 'translation_m' + 'mount_ypr_deg', not both");
    }
    const std::string mk = join_key(key, "matrix");
    const std::string what = "a 4x4 matrix: 16 numbers row-major or 4 rows of 4 numbers";
    std::vector<double> v;
    if (m.IsSequence() && m.size() == 4 && m[0].IsSequence()) {
      for (std::size_t r = 0; r < 4; ++r) {
        const auto row = to_numbers(c, m[r], mk, 4, what + " (row " + std::to_string(r) + ")");
        v.insert(v.end(), row.begin(), row.end());
      }
    } else {
      v = to_numbers(c, m, mk, 16, what);
    }
    Eigen::Matrix4d T;
    for (int i = 0; i < 16; ++i) T(i / 4, i % 4) = v[i];
    if ((T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
      fail(c, m, mk, "expected the last row to be [0, 0, 0, 1]");
    }
    const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
    const double err = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    if (err > 1e-6) {
      fail(c, m, mk, "expected an orthonormal rotation part, got max |R^T R - I| = " + fmt(err));
    }
    if (R.determinant() < 0) fail(c, m, mk, "expected a rotation (determinant +1), got a reflection");
    return Pose::from_matrix(T);
  }
  const Eigen::Vector3d t =
      to_vec3(c, require(c, n, key, "translation_m", "[x, y, z] in metres (or use 'matrix')"),
              join_key(key, "translation_m"), "[x, y, z] in metres");
  const YAML::Node ypr_node = require(c, n, key, "mount_ypr_deg", "[yaw, pitch, roll] in degrees");
  const auto ypr = to_numbers(c, ypr_node, join_key(key, "mount_ypr_deg"), 3,
                              "a list of 3 numbers [yaw, pitch, roll] in degrees");
  return Pose::from(R_body_cam_from_mount_ypr(deg_to_rad(ypr[0]), deg_to_rad(ypr[1]), deg_to_rad(ypr[2])), t);
}

// Resolution [W, H]; both integers in 1..kMaxImageSidePx (larger images do not fit the
// rendering tables in memory).
std::pair<int, int> parse_resolution(const Ctx& c, const YAML::Node& n, const std::string& key) {
  const std::string what =
      "a list of 2 positive integers [width, height] in pixels, at most " + std::to_string(kMaxImageSidePx);
  if (!n.IsSequence() || n.size() != 2) fail(c, n, key, "expected " + what + ", " + got(n));
  int wh[2];
  for (std::size_t i = 0; i < 2; ++i) {
    if (!n[i].IsScalar() || !YAML::convert<int>::decode(n[i], wh[i]) || wh[i] <= 0 ||
        wh[i] > kMaxImageSidePx) {
      fail(c, n[i], key, "expected " + what + ", " + got(n[i]) + " as element " + std::to_string(i));
    }
  }
  return {wh[0], wh[1]};
}

// Huge coefficients overflow every projection to inf/NaN: bounded like every camera model
// (render/camera_model.hpp).
void check_coefficients(const Ctx& c, const YAML::Node& n, const std::string& key,
                        const std::vector<double>& v) {
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!(std::abs(v[i]) <= kMaxDistortionCoefficient)) {
      fail(c, n[i], key,
           "expected distortion coefficients in [-" + fmt(kMaxDistortionCoefficient) + ", " +
               fmt(kMaxDistortionCoefficient) + "], " + got(n[i]) + " as element " + std::to_string(i));
    }
  }
}

void parse_distortion(const Ctx& c, const YAML::Node& n, const std::string& key, CameraModel& model) {
  expect_map(c, n, key, "a map {model: none|radtan|equidistant, coeffs: [...]}");
  check_keys(c, n, key, {"model", "coeffs"});
  const std::string mk = join_key(key, "model");
  const YAML::Node mn = require(c, n, key, "model", "none, radtan or equidistant");
  const std::string name = to_string_value(c, mn, mk, "one of none, radtan, equidistant");
  const YAML::Node cn = n["coeffs"];
  const std::string ck = join_key(key, "coeffs");
  model.coeffs = {};
  if (name == "none") {
    model.distortion = DistortionModel::kNone;
    if (cn.IsDefined() && !(cn.IsSequence() && cn.size() == 0) && !cn.IsNull()) {
      fail(c, cn, ck, "expected no coefficients for model 'none', " + got(cn));
    }
    return;
  }
  if (name == "radtan") {
    model.distortion = DistortionModel::kRadTan;
    if (!cn.IsDefined()) fail(c, n, ck, "missing; expected a list of 4 or 5 numbers [k1, k2, p1, p2, (k3)]");
    const std::size_t count = cn.IsSequence() && cn.size() == 5 ? 5 : 4;
    const auto v = to_numbers(c, cn, ck, count, "a list of 4 or 5 numbers [k1, k2, p1, p2, (k3)]");
    check_coefficients(c, cn, ck, v);
    std::copy(v.begin(), v.end(), model.coeffs.begin());
    return;
  }
  if (name == "equidistant") {
    model.distortion = DistortionModel::kEquidistant;
    if (!cn.IsDefined()) fail(c, n, ck, "missing; expected a list of 4 numbers [k1, k2, k3, k4]");
    const auto v = to_numbers(c, cn, ck, 4, "a list of 4 numbers [k1, k2, k3, k4]");
    check_coefficients(c, cn, ck, v);
    std::copy(v.begin(), v.end(), model.coeffs.begin());
    return;
  }
  fail(c, mn, mk, "unknown distortion model; expected one of none, radtan, equidistant, " + got(mn));
}

// A number of `key` in [lo, hi].
double number_in(const Ctx& c, const YAML::Node& n, const std::string& key, double lo, double hi,
                 const std::string& what) {
  const double v = to_number(c, n, key, what);
  if (!(v >= lo && v <= hi)) fail(c, n, key, "expected " + what + " in " + fmt(lo) + ".." + fmt(hi) + ", got " + fmt(v));
  return v;
}

// `material: {metallic, roughness}`, each in [0, 1]; one left out keeps the built-in paint's.
SurfaceFinish parse_finish(const Ctx& c, const YAML::Node& n, const std::string& key) {
  expect_map(c, n, key, "a map {metallic, roughness}");
  check_keys(c, n, key, {"metallic", "roughness"});
  SurfaceFinish f = kPaintedBoom;
  if (const YAML::Node v = n["metallic"]; v.IsDefined())
    f.metallic = number_in(c, v, key + ".metallic", 0, 1, "a metallic factor (0 paint, 1 bare metal)");
  if (const YAML::Node v = n["roughness"]; v.IsDefined())
    f.roughness = number_in(c, v, key + ".roughness", 0, 1, "a roughness (0 mirror, 1 matte)");
  return f;
}

// `look: {psf_sigma_px, gamma, noise_a, noise_b, seed, exposure_ms}`: noise_a and noise_b one
// number (every channel) or three (R, G, B), given together.
CameraLookParams parse_look_keys(const Ctx& c, const YAML::Node& n, const std::string& key) {
  expect_map(c, n, key, "a map {psf_sigma_px, gamma, noise_a, noise_b, seed, exposure_ms}");
  check_keys(c, n, key, {"psf_sigma_px", "gamma", "noise_a", "noise_b", "seed", "exposure_ms"});
  CameraLookParams p;
  if (const YAML::Node v = n["psf_sigma_px"]; v.IsDefined())
    p.psf_sigma_px = number_in(c, v, key + ".psf_sigma_px", 0, kMaxPsfSigmaPx, "a PSF 1-sigma in pixels");
  if (const YAML::Node v = n["gamma"]; v.IsDefined())
    p.gamma = number_in(c, v, key + ".gamma", 0.2, 5, "a tone-curve exponent (1: linear)");
  if (const YAML::Node v = n["exposure_ms"]; v.IsDefined())
    p.exposure_ms =
        number_in(c, v, key + ".exposure_ms", 0, kMaxExposureMs, "an exposure time in milliseconds");
  if (const YAML::Node v = n["seed"]; v.IsDefined())
    p.seed = static_cast<std::uint64_t>(number_in(c, v, key + ".seed", 0, 9007199254740992.0, "a whole number"));
  const YAML::Node a = n["noise_a"], b = n["noise_b"];
  if (a.IsDefined() != b.IsDefined())
    fail(c, a.IsDefined() ? a : b, key + (a.IsDefined() ? ".noise_b" : ".noise_a"),
         "missing: noise_a and noise_b (sigma^2 = a I + b, DN) are given together");
  if (!a.IsDefined()) return p;
  auto channels = [&](const YAML::Node& v, const std::string& k, const std::string& what) {
    std::vector<double> x;
    if (v.IsSequence() && v.size() == 3) {
      x = to_numbers(c, v, k, 3, "3 numbers (R, G, B) of " + what);
    } else {
      x = {to_number(c, v, k, "a number (every channel) or 3 (R, G, B) of " + what)};
    }
    for (double e : x)
      if (!(e >= 0 && e < 1e4)) fail(c, v, k, "expected " + what + " >= 0, got " + fmt(e));
    return x;
  };
  const auto va = channels(a, key + ".noise_a", "shot-noise slope (DN)");
  const auto vb = channels(b, key + ".noise_b", "read-noise variance (DN^2)");
  p.noise.channels = va.size() == 3 || vb.size() == 3 ? 3 : 1;
  for (int ch = 0; ch < 3; ++ch) {
    p.noise.a[ch] = va[std::min<std::size_t>(ch, va.size() - 1)];
    p.noise.b[ch] = vb[std::min<std::size_t>(ch, vb.size() - 1)];
  }
  return p;
}

RigCamera parse_camera(const Ctx& c, const YAML::Node& n, int index, const StereoCalibration* calib) {
  const std::string key = "cameras[" + std::to_string(index) + "]";
  expect_map(c, n, key, "a camera map {name, resolution, intrinsics, distortion, T_body_cam, near_m, far_m}");
  check_keys(c, n, key,
             {"name", "resolution", "intrinsics", "hfov_deg", "distortion", "T_body_cam", "near_m", "far_m",
              "source", "look"});
  RigCamera cam;
  cam.name = index == 0 ? "left" : "right";
  if (const YAML::Node v = n["name"]; v.IsDefined())
    cam.name = to_string_value(c, v, key + ".name", "a string");
  if (const YAML::Node v = n["source"]; v.IsDefined()) {
    cam.source_uri = to_string_value(c, v, key + ".source", "a URI string");
  }

  if (calib) {
    // Intrinsics come from the calibration file; giving them here too would be ambiguous.
    for (const char* k : {"intrinsics", "hfov_deg", "distortion"}) {
      if (n[k].IsDefined()) {
        fail(c, n[k], join_key(key, k),
             "not allowed with 'calibration': the camera model comes from the calibration file");
      }
    }
    cam.model = index == 0 ? calib->left : calib->right;
    if (const YAML::Node r = n["resolution"]; r.IsDefined()) {
      const auto [w, h] = parse_resolution(c, r, key + ".resolution");
      if (w != cam.model.width_px || h != cam.model.height_px) {
        fail(c, r, key + ".resolution",
             "expected the calibration's resolution [" + std::to_string(cam.model.width_px) + ", " +
                 std::to_string(cam.model.height_px) + "], got [" + std::to_string(w) + ", " +
                 std::to_string(h) + "]");
      }
    }
  } else {
    const auto [w, h] = parse_resolution(c, require(c, n, key, "resolution", "[width, height] in pixels"),
                                         key + ".resolution");
    const YAML::Node in = n["intrinsics"];
    const YAML::Node hf = n["hfov_deg"];
    if (in.IsDefined() && hf.IsDefined()) {
      fail(c, hf, key + ".hfov_deg", "expected either 'intrinsics' or 'hfov_deg', not both");
    }
    if (in.IsDefined()) {
      const std::string ik = key + ".intrinsics";
      const auto v = to_numbers(c, in, ik, 4, "a list of 4 numbers [fx, fy, cx, cy]");
      // Bounded above too: a focal length of 1e308 overflows every projection.
      if (!(v[0] >= kMinFocalPx && v[0] <= kMaxFocalPx && v[1] >= kMinFocalPx && v[1] <= kMaxFocalPx)) {
        fail(c, in, ik,
             "expected positive focal lengths fx, fy of at least " + fmt(kMinFocalPx) + " and at most " +
                 fmt(kMaxFocalPx) + " pixels, got " + fmt(v[0]) + ", " + fmt(v[1]));
      }
      // Pixel centres are integers, so the image spans [-0.5, W - 0.5] (core/conventions.hpp).
      if (!(v[2] >= -0.5 && v[2] <= w - 0.5 && v[3] >= -0.5 && v[3] <= h - 0.5)) {
        fail(c, in, ik,
             "expected the principal point inside the image [-0.5, " + fmt(w - 0.5) + "] x [-0.5, " +
                 fmt(h - 0.5) + "], got (" + fmt(v[2]) + ", " + fmt(v[3]) + ")");
      }
      cam.model.width_px = w;
      cam.model.height_px = h;
      cam.model.fx_px = v[0];
      cam.model.fy_px = v[1];
      cam.model.cx_px = v[2];
      cam.model.cy_px = v[3];
    } else if (hf.IsDefined()) {
      const double deg = to_number(c, hf, key + ".hfov_deg", "a number of degrees in (0, 180)");
      if (!(deg > 0 && deg < 180)) {
        fail(c, hf, key + ".hfov_deg", "expected a number of degrees in (0, 180), got " + fmt(deg));
      }
      cam.model = CameraModel::pinhole_from_hfov(w, h, deg_to_rad(deg));
    } else {
      fail(c, n, key + ".intrinsics", "missing; expected 'intrinsics: [fx, fy, cx, cy]' or 'hfov_deg'");
    }
    if (const YAML::Node d = n["distortion"]; d.IsDefined())
      parse_distortion(c, d, key + ".distortion", cam.model);
  }
  // What the keys above do not check one by one (an hfov_deg that makes fx too large, a
  // calibration's model): the same bounds as every camera model.
  if (const std::string p = camera_model_problem(cam.model); !p.empty()) fail(c, n, key, p);

  const YAML::Node T = n["T_body_cam"];
  if (calib && index == 1) {
    if (T.IsDefined()) {
      fail(c, T, key + ".T_body_cam",
           "not allowed with 'calibration': the right camera's pose follows from the left camera's "
           "T_body_cam and the calibration's extrinsics");
    }
  } else {
    if (!T.IsDefined()) {
      fail(c, n, key + ".T_body_cam", "missing; expected {matrix: [...]} or {translation_m, mount_ypr_deg}");
    }
    cam.T_body_cam = parse_T_body_cam(c, T, key + ".T_body_cam");
  }

  if (const YAML::Node v = n["near_m"]; v.IsDefined()) {
    cam.near_m = to_number(c, v, key + ".near_m", "a positive number of metres");
    if (!(cam.near_m > 0)) fail(c, v, key + ".near_m", "expected near_m > 0, got " + fmt(cam.near_m));
  }
  if (const YAML::Node v = n["far_m"]; v.IsDefined()) {
    cam.far_m = to_number(c, v, key + ".far_m", "a number of metres greater than near_m");
  }
  if (!(cam.far_m > cam.near_m)) {
    const YAML::Node v = n["far_m"].IsDefined() ? n["far_m"] : n;
    fail(c, v, key + ".far_m", "expected far_m > near_m (" + fmt(cam.near_m) + "), got " + fmt(cam.far_m));
  }
  if (const YAML::Node v = n["look"]; v.IsDefined()) cam.look = parse_look_keys(c, v, key + ".look");
  return cam;
}

// receiver.keypoints: a map {name: [x, y, z]} in the order written. The names become file
// fields and YOLO's flip pairs (a `left` word swaps with `right`): letters, digits and '_'.
std::vector<NamedPoint> parse_keypoints(const Ctx& c, const YAML::Node& n) {
  const std::string key = "receiver.keypoints";
  expect_map(c, n, key, "a map {name: [x, y, z] in metres (receiver FRD), ...}");
  if (n.size() == 0) fail(c, n, key, "expected at least one keypoint, got an empty map");
  std::vector<NamedPoint> points;
  for (const auto& kv : n) {
    const std::string name = kv.first.as<std::string>();
    const std::string k = join_key(key, name);
    const bool ok = !name.empty() && std::all_of(name.begin(), name.end(), [](char ch) {
      return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_';
    });
    if (!ok) fail(c, kv.first, k, "expected a name of letters, digits and '_', got '" + name + "'");
    for (const NamedPoint& p : points)
      if (p.name == name) fail(c, kv.first, k, "expected each name once, got '" + name + "' twice");
    points.push_back({name, to_vec3(c, kv.second, k, "[x, y, z] in metres (receiver FRD)")});
  }
  return points;
}

Rig parse_root(const Ctx& c, const YAML::Node& root) {
  if (!root.IsMap())
    fail(c, root, "augrig_rig", "expected a rig map starting with 'augrig_rig: 1', " + got(root));
  check_keys(c, root, "", {"augrig_rig", "calibration", "cameras", "pairing", "boom", "receiver"});
  const YAML::Node ver = require(c, root, "", "augrig_rig", "the format version 'augrig_rig: 1'");
  int version = 0;
  if (!ver.IsScalar() || !YAML::convert<int>::decode(ver, version) || version != 1) {
    fail(c, ver, "augrig_rig", "expected format version 1, " + got(ver));
  }

  Rig rig;
  const YAML::Node cams = require(c, root, "", "cameras", "a list of 2 cameras [left, right]");
  if (!cams.IsSequence() || cams.size() != 2) {
    fail(c, cams, "cameras", "expected a list of exactly 2 cameras [left, right], " + got(cams));
  }

  std::optional<StereoCalibration> calib;
  if (const YAML::Node cal = root["calibration"]; cal.IsDefined()) {
    expect_map(c, cal, "calibration", "a map {format: opencv|ros|kalibr, file, file_right}");
    check_keys(c, cal, "calibration", {"format", "file", "file_right"});
    const YAML::Node fmt_node = require(c, cal, "calibration", "format", "opencv, ros or kalibr");
    const std::string format =
        to_string_value(c, fmt_node, "calibration.format", "one of opencv, ros, kalibr");
    if (format != "opencv" && format != "ros" && format != "kalibr") {
      fail(c, fmt_node, "calibration.format", "expected one of opencv, ros, kalibr, " + got(fmt_node));
    }
    const YAML::Node file = require(c, cal, "calibration", "file", "the calibration file's path");
    const std::string path = resolve_path(c, to_string_value(c, file, "calibration.file", "a path"));
    const YAML::Node right = cal["file_right"];
    if (format == "ros" && !right.IsDefined()) {
      fail(c, cal, "calibration.file_right",
           "missing; format 'ros' needs the right camera's camera_info file");
    }
    if (format != "ros" && right.IsDefined()) {
      fail(c, right, "calibration.file_right", "only used with format 'ros'");
    }
    Expected<StereoCalibration> imported = Error{};
    if (format == "opencv") {
      // The OpenCV file may lack the image size; the left camera's resolution supplies it then.
      int w = 0, h = 0;
      if (cams[0].IsMap() && cams[0]["resolution"].IsDefined()) {
        std::tie(w, h) = parse_resolution(c, cams[0]["resolution"], "cameras[0].resolution");
      }
      imported = import_opencv_stereo(path, w, h);
    } else if (format == "ros") {
      const std::string rpath =
          resolve_path(c, to_string_value(c, right, "calibration.file_right", "a path"));
      imported = import_ros_camera_info(path, rpath);
    } else {
      imported = import_kalibr_camchain(path);
    }
    if (!imported) fail(c, file, "calibration.file", imported.error().message);
    calib = std::move(*imported);
  }

  for (int i = 0; i < 2; ++i) rig.cameras.push_back(parse_camera(c, cams[i], i, calib ? &*calib : nullptr));
  if (calib) {
    // T_body_right = T_body_left * T_left_right, and T_left_right = T_right_left^-1.
    rig.cameras[1].T_body_cam = rig.cameras[0].T_body_cam * calib->T_right_left.inverse();
  }

  // No boom section: a capture-only rig (recording its cameras needs no boom); its boom values are
  // the seed paper's, marked as not configured, and augmenting with it is refused.
  const YAML::Node boom = root["boom"];
  if (!boom.IsDefined()) {
    rig.boom = Rig::paper_default().boom;
    rig.boom.configured = false;
  } else {
    expect_map(c, boom, "boom", "a map {pivot_body_m, model, material, limits}");
    check_keys(c, boom, "boom", {"pivot_body_m", "model", "material", "limits"});
    rig.boom.pivot_body_m =
        to_vec3(c, require(c, boom, "boom", "pivot_body_m", "[x, y, z] in metres (body FRD)"),
                "boom.pivot_body_m", "[x, y, z] in metres (body FRD)");
    if (const YAML::Node m = boom["model"]; m.IsDefined()) rig.boom.model = parse_model(c, m, "boom.model");
    if (const YAML::Node m = boom["material"]; m.IsDefined())
      rig.boom.material = parse_finish(c, m, "boom.material");
    const YAML::Node lim =
        require(c, boom, "boom", "limits", "a map {elevation_deg, azimuth_deg, extension_m}");
    expect_map(c, lim, "boom.limits", "a map {elevation_deg, azimuth_deg, extension_m}");
    check_keys(c, lim, "boom.limits", {"elevation_deg", "azimuth_deg", "extension_m"});
    const auto el = to_range(c, require(c, lim, "boom.limits", "elevation_deg", "[min, max] in degrees"),
                             "boom.limits.elevation_deg", "degrees");
    const auto az = to_range(c, require(c, lim, "boom.limits", "azimuth_deg", "[min, max] in degrees"),
                             "boom.limits.azimuth_deg", "degrees");
    const auto ex = to_range(c, require(c, lim, "boom.limits", "extension_m", "[min, max] in metres"),
                             "boom.limits.extension_m", "metres");
    rig.boom.limits = {deg_to_rad(el.first),
                       deg_to_rad(el.second),
                       deg_to_rad(az.first),
                       deg_to_rad(az.second),
                       ex.first,
                       ex.second};
  }

  // The pairing section is optional: free-running cameras, each with its own clock, 2 ms.
  if (const YAML::Node pn = root["pairing"]; pn.IsDefined()) {
    expect_map(c, pn, "pairing", "a map {tolerance_us, mode, clock, queue}");
    check_keys(c, pn, "pairing", {"tolerance_us", "mode", "clock", "queue"});
    RigPairing& p = rig.pairing;
    if (const YAML::Node v = pn["tolerance_us"]; v.IsDefined()) {
      p.tolerance_us = to_number(c, v, "pairing.tolerance_us", "microseconds > 0");
      if (!(p.tolerance_us > 0 && p.tolerance_us <= kMaxPairingToleranceUs))
        fail(c, v, "pairing.tolerance_us", "expected microseconds > 0 and at most 1e7 (10 s), " + got(v));
    }
    if (const YAML::Node v = pn["mode"]; v.IsDefined()) {
      p.mode = to_string_value(c, v, "pairing.mode", "timestamp or trigger_id");
      if (!RigPairing::known_mode(p.mode))
        fail(c, v, "pairing.mode", "expected timestamp or trigger_id, " + got(v));
    }
    if (const YAML::Node v = pn["clock"]; v.IsDefined()) {
      p.clock = to_string_value(c, v, "pairing.clock", "separate or shared");
      if (!RigPairing::known_clock(p.clock))
        fail(c, v, "pairing.clock",
             "expected separate (each camera its own clock) or shared (PTP), " + got(v));
    }
    if (const YAML::Node v = pn["queue"]; v.IsDefined()) {
      const double q = to_number(c, v, "pairing.queue", "an integer >= 1");
      if (!(q >= 1 && q <= 1024 && q == std::floor(q)))
        fail(c, v, "pairing.queue", "expected an integer from 1 to 1024, " + got(v));
      p.queue = static_cast<int>(q);
    }
  }

  // The receiver section is optional: the built-in receiver with its receptacle.
  rig.receiver.receptacle_m = Eigen::Vector3d(4.0, 0.0, -0.9);
  if (const YAML::Node rec = root["receiver"]; rec.IsDefined()) {
    expect_map(c, rec, "receiver", "a map {model, receptacle_m, keypoints}");
    check_keys(c, rec, "receiver", {"model", "receptacle_m", "keypoints"});
    if (const YAML::Node m = rec["model"]; m.IsDefined())
      rig.receiver.model = parse_model(c, m, "receiver.model");
    if (const YAML::Node r = rec["receptacle_m"]; r.IsDefined()) {
      rig.receiver.receptacle_m =
          to_vec3(c, r, "receiver.receptacle_m", "[x, y, z] in metres (receiver FRD)");
    }
    if (const YAML::Node k = rec["keypoints"]; k.IsDefined()) rig.receiver.keypoints = parse_keypoints(c, k);
  }
  return rig;
}

Expected<Rig> parse_with(const std::string& text, const Ctx& c) {
  return guarded(c, [&] {
    Rig rig = parse_root(c, YAML::Load(text));
    rig.source = c.name;
    return rig;
  });
}

fs::path absolute_dir_of(const std::string& name) {
  std::error_code ec;
  const fs::path p = fs::absolute(fs::path(name), ec);
  return ec ? fs::current_path(ec) : p.parent_path();
}

void write_vec(std::ostream& o, std::initializer_list<double> v) {
  o << '[';
  bool first = true;
  for (double x : v) {
    o << (first ? "" : ", ") << fmt(x);
    first = false;
  }
  o << ']';
}

// Double-quoted YAML scalar so names and paths with ':' '#' or spaces survive.
std::string quote(const std::string& s) {
  std::string q = "\"";
  for (char ch : s) {
    if (ch == '"' || ch == '\\') q += '\\';
    q += ch;
  }
  return q + "\"";
}

void write_model(std::ostream& o, const ModelSource& m) {
  if (m.path.empty()) {
    o << "builtin\n";
    return;
  }
  o << "\n    path: " << quote(m.path) << "\n    axes: {forward: " << quote(m.axes.forward)
    << ", right: " << quote(m.axes.right) << ", down: " << quote(m.axes.down)
    << "}\n    scale: " << fmt(m.scale) << "\n";
}

}  // namespace

Eigen::Matrix3d R_body_cam_from_mount_ypr(double yaw_rad, double pitch_rad, double roll_rad) {
  // Columns: the OpenCV camera axes in the mount frame (x along the optical axis, y right, z down):
  // cam x (right) -> mount y, cam y (down) -> mount z, cam z (forward) -> mount x.
  Eigen::Matrix3d R_mount_cam;
  R_mount_cam << 0, 0, 1,  //
      1, 0, 0,             //
      0, 1, 0;
  return rotation_from_ypr(yaw_rad, pitch_rad, roll_rad) * R_mount_cam;
}

Rig Rig::paper_default() {
  Rig rig;
  rig.source = "<built-in>";
  const CameraModel model = CameraModel::pinhole_from_hfov(1280, 960, deg_to_rad(56.0));
  const Eigen::Matrix3d R = R_body_cam_from_mount_ypr(kPi, deg_to_rad(-25.0), 0.0);
  // Looking aft, image-right is the port side (-y), so the left camera sits on the starboard side.
  rig.cameras.push_back({"left", model, Pose::from(R, {0.0, 0.25, 2.0}), 1.0, 100.0, "", {}});
  rig.cameras.push_back({"right", model, Pose::from(R, {0.0, -0.25, 2.0}), 1.0, 100.0, "", {}});
  rig.boom.pivot_body_m = {-4.0, 0.0, 2.3};
  rig.boom.limits = {deg_to_rad(20.0), deg_to_rad(40.0), deg_to_rad(-15.0), deg_to_rad(15.0), 0.0, 5.8};
  rig.receiver.receptacle_m = {4.0, 0.0, -0.9};
  return rig;
}

Expected<Rig> load_rig(const std::string& path) {
  Ctx c{{"rig::load(): ", path}, absolute_dir_of(path)};
  auto text = read_text_file(c.prefix, path, "rig file");
  if (!text) return text.error();
  return parse_with(*text, c);
}

Expected<Rig> parse_rig(const std::string& yaml_text, const std::string& name) {
  std::error_code ec;
  // A real path names the directory for relative paths; "<string>" and the like use the cwd.
  const fs::path base = !name.empty() && name[0] != '<' ? absolute_dir_of(name) : fs::current_path(ec);
  return parse_with(yaml_text, Ctx{{"rig::parse(): ", name}, base});
}

std::string rig_to_yaml(const Rig& rig) {
  // Canonical form: explicit intrinsics, distortion and the 4x4 matrix, numbers in their shortest
  // exact text, so parse_rig() reads back the same doubles.
  std::ostringstream o;
  o << "# augrig rig file, format: docs/RIG_FORMAT.md. Body frame FRD, camera frame OpenCV, metres.\n";
  o << "augrig_rig: 1\ncameras:\n";
  for (const RigCamera& cam : rig.cameras) {
    const CameraModel& m = cam.model;
    o << "  - name: " << quote(cam.name) << "\n";
    o << "    resolution: [" << m.width_px << ", " << m.height_px << "]\n";
    o << "    intrinsics: ";
    write_vec(o, {m.fx_px, m.fy_px, m.cx_px, m.cy_px});
    o << "\n    distortion: {model: " << m.distortion_name();
    if (m.distortion == DistortionModel::kRadTan) {
      o << ", coeffs: ";
      write_vec(o, {m.coeffs[0], m.coeffs[1], m.coeffs[2], m.coeffs[3], m.coeffs[4]});
    } else if (m.distortion == DistortionModel::kEquidistant) {
      o << ", coeffs: ";
      write_vec(o, {m.coeffs[0], m.coeffs[1], m.coeffs[2], m.coeffs[3]});
    }
    o << "}\n    T_body_cam:\n      matrix:\n";
    const Eigen::Matrix4d T = cam.T_body_cam.matrix();
    for (int r = 0; r < 4; ++r) {
      o << "        - ";
      write_vec(o, {snap(T(r, 0), 2e-15), snap(T(r, 1), 2e-15), snap(T(r, 2), 2e-15), snap(T(r, 3), 2e-15)});
      o << "\n";
    }
    o << "    near_m: " << fmt(cam.near_m) << "\n    far_m: " << fmt(cam.far_m) << "\n";
    if (!cam.source_uri.empty()) o << "    source: " << quote(cam.source_uri) << "\n";
    if (const CameraLookParams& lk = cam.look; !(lk == CameraLookParams{})) {
      o << "    look: {psf_sigma_px: " << fmt(lk.psf_sigma_px) << ", gamma: " << fmt(lk.gamma) << ", seed: " << lk.seed;
      if (lk.exposure_ms >= 0) o << ", exposure_ms: " << fmt(lk.exposure_ms);
      if (lk.noise.channels == 1) {
        o << ", noise_a: " << fmt(lk.noise.a[0]) << ", noise_b: " << fmt(lk.noise.b[0]);
      } else if (lk.noise.channels == 3) {
        o << ", noise_a: ";
        write_vec(o, {lk.noise.a[0], lk.noise.a[1], lk.noise.a[2]});
        o << ", noise_b: ";
        write_vec(o, {lk.noise.b[0], lk.noise.b[1], lk.noise.b[2]});
      }
      o << "}\n";
    }
  }
  const RigPairing& p = rig.pairing;
  o << "pairing: {tolerance_us: " << fmt(p.tolerance_us) << ", mode: " << p.mode << ", clock: " << p.clock
    << ", queue: " << p.queue << "}\n";
  const BoomLimits& l = rig.boom.limits;
  if (rig.boom.configured) {
    o << "boom:\n  pivot_body_m: ";
    write_vec(o, {rig.boom.pivot_body_m.x(), rig.boom.pivot_body_m.y(), rig.boom.pivot_body_m.z()});
    o << "\n  model: ";
    write_model(o, rig.boom.model);
    if (const auto& f = rig.boom.material)
      o << "  material: {metallic: " << fmt(f->metallic) << ", roughness: " << fmt(f->roughness) << "}\n";
    o << "  limits:\n    elevation_deg: [" << fmt_deg(l.elevation_min_rad) << ", "
      << fmt_deg(l.elevation_max_rad) << "]\n    azimuth_deg: [" << fmt_deg(l.azimuth_min_rad) << ", "
      << fmt_deg(l.azimuth_max_rad) << "]";
    o << "\n    extension_m: ";
    write_vec(o, {l.extension_min_m, l.extension_max_m});
    o << "\n";
  }
  o << "receiver:\n  model: ";
  write_model(o, rig.receiver.model);
  o << "  receptacle_m: ";
  write_vec(o, {rig.receiver.receptacle_m.x(), rig.receiver.receptacle_m.y(), rig.receiver.receptacle_m.z()});
  o << "\n";
  if (!rig.receiver.keypoints.empty()) {
    o << "  keypoints:\n";
    for (const NamedPoint& p : rig.receiver.keypoints) {
      o << "    " << p.name << ": ";
      write_vec(o, {p.p_m.x(), p.p_m.y(), p.p_m.z()});
      o << "\n";
    }
  }
  return o.str();
}

}  // namespace augrig
