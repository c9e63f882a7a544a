#include "render/calib_import.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <yaml-cpp/yaml.h>

#include "core/file_check.hpp"

namespace augrig {
namespace {

// Thrown inside an importer only; the public functions catch it and return an Error.
struct ImportFailure {
  std::string message;
};

struct Ctx {
  std::string prefix;  // "calib::import_...(): "
  std::string file;
};

std::string num(double v) {
  std::ostringstream o;
  o.precision(10);
  o << v;
  return o.str();
}

[[noreturn]] void fail(const Ctx& c, int line, int col, const std::string& key, const std::string& what) {
  std::string where = c.file;
  if (line > 0) where += ":" + std::to_string(line);
  if (line > 0 && col > 0) where += ":" + std::to_string(col);
  throw ImportFailure{c.prefix + where + ": " + (key.empty() ? "" : "key '" + key + "': ") + what};
}

// Empty on success, else why not: a directory, cannot open, a read error.
std::string read_text(const std::string& path, std::string* text) {
  if (auto d = check_not_directory("", path); !d) return "is a directory, expected a file";
  std::ifstream in(path, std::ios::binary);
  if (!in) return "cannot open the file";
  std::stringstream ss;
  ss << in.rdbuf();
  *text = ss.str();
  return in.bad() ? "cannot read the file (read error)" : "";
}

// Shared checks on what every importer produces, so all formats reject the same nonsense.
void check_camera(const Ctx& c, const CameraModel& m, const std::string& key, int line, int col) {
  if (!(m.fx_px > 0 && m.fy_px > 0)) {
    fail(c, line, col, key,
         "expected positive focal lengths, got fx " + num(m.fx_px) + ", fy " + num(m.fy_px));
  }
  if (!(m.width_px > 0 && m.height_px > 0)) {
    fail(c, line, col, key,
         "expected a positive image size, got " + std::to_string(m.width_px) + "x" +
             std::to_string(m.height_px));
  }
  // Upper bounds too (fx 1e308 or coefficients 1e300 overflow every projection).
  if (const std::string p = camera_model_problem(m); !p.empty()) fail(c, line, col, key, p);
}

// Rotation check shared by all formats: |R^T R - I| small and det +1.
std::string rotation_problem(const Eigen::Matrix3d& R) {
  const double err = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!(err <= 1e-6)) return "expected an orthonormal rotation, got max |R^T R - I| = " + num(err);
  if (R.determinant() < 0) return "expected a rotation (determinant +1), got a reflection";
  return "";
}

// ---------------------------------------------------------------------------------------------
// YAML (ROS, Kalibr): yaml-cpp keeps line/column marks, so messages point at the exact entry.

std::string got(const YAML::Node& n) {
  if (!n.IsDefined() || n.IsNull()) return "got nothing (null)";
  if (n.IsScalar()) return "got '" + n.Scalar() + "'";
  if (n.IsSequence()) return "got a list of " + std::to_string(n.size()) + " element(s)";
  return "got a map";
}

[[noreturn]] void yfail(const Ctx& c, const YAML::Node& n, const std::string& key, const std::string& what) {
  const YAML::Mark m = n.IsDefined() ? n.Mark() : YAML::Mark::null_mark();
  fail(c, m.is_null() ? 0 : m.line + 1, m.is_null() ? 0 : m.column + 1, key, what);
}

YAML::Node yrequire(const Ctx& c, const YAML::Node& map, const std::string& path, const std::string& key,
                    const std::string& what) {
  const YAML::Node n = map[key];
  if (!n.IsDefined()) yfail(c, map, path.empty() ? key : path + "." + key, "missing; expected " + what);
  return n;
}

std::vector<double> ynumbers(const Ctx& c, const YAML::Node& n, const std::string& key,
                             const std::vector<std::size_t>& counts, const std::string& what) {
  if (!n.IsSequence() || std::find(counts.begin(), counts.end(), n.size()) == counts.end()) {
    yfail(c, n, key, "expected " + what + ", " + got(n));
  }
  std::vector<double> v;
  for (std::size_t i = 0; i < n.size(); ++i) {
    double x = 0;
    if (!n[i].IsScalar() || !YAML::convert<double>::decode(n[i], x) || !std::isfinite(x)) {
      yfail(c, n[i], key, "expected " + what + ", " + got(n[i]) + " as element " + std::to_string(i));
    }
    v.push_back(x);
  }
  return v;
}

int yint(const Ctx& c, const YAML::Node& n, const std::string& key, const std::string& what) {
  int v = 0;
  if (!n.IsScalar() || !YAML::convert<int>::decode(n, v) || v <= 0)
    yfail(c, n, key, "expected " + what + ", " + got(n));
  return v;
}

std::string ystring(const Ctx& c, const YAML::Node& n, const std::string& key, const std::string& what) {
  if (!n.IsScalar()) yfail(c, n, key, "expected " + what + ", " + got(n));
  return n.Scalar();
}

YAML::Node yload(const Ctx& c, const std::string& path) {
  std::string text;
  if (const std::string why = read_text(path, &text); !why.empty()) fail(c, 0, 0, "", why);
  try {
    YAML::Node root = YAML::Load(text);
    if (!root.IsMap()) yfail(c, root, "", "expected a YAML map at the top level, " + got(root));
    return root;
  } catch (const YAML::ParserException& e) {
    fail(c, e.mark.line + 1, e.mark.column + 1, "", "YAML syntax error: " + e.msg);
  }
}

// Distortion coefficients for a named model; extra rational/thin-prism terms must be zero.
void set_distortion(const Ctx& c, const YAML::Node& model_node, const std::string& model_key,
                    const std::string& model, const YAML::Node& coeffs_node, const std::string& coeffs_key,
                    CameraModel& cam, bool kalibr) {
  cam.coeffs = {};
  if (model == "plumb_bob" || model == "radtan" || model == "rational_polynomial") {
    cam.distortion = DistortionModel::kRadTan;
    const std::vector<std::size_t> counts =
        kalibr ? std::vector<std::size_t>{4} : std::vector<std::size_t>{4, 5, 8, 12, 14};
    const auto d = ynumbers(c, coeffs_node, coeffs_key, counts,
                            kalibr ? "a list of 4 numbers [k1, k2, p1, p2]"
                                   : "a list of 4, 5, 8, 12 or 14 numbers [k1, k2, p1, p2, k3, ...]");
    for (std::size_t i = 0; i < d.size(); ++i) {
      if (i < 5) {
        cam.coeffs[i] = d[i];
      } else if (d[i] != 0.0) {
        yfail(c, coeffs_node, coeffs_key,
              "rational/thin-prism model not supported: coefficients after k1 k2 p1 p2 k3 must be 0, got " +
                  num(d[i]) + " as element " + std::to_string(i));
      }
    }
  } else if (model == "equidistant" || model == "fisheye") {
    cam.distortion = DistortionModel::kEquidistant;
    const auto d = ynumbers(c, coeffs_node, coeffs_key, {4}, "a list of 4 numbers [k1, k2, k3, k4]");
    std::copy(d.begin(), d.end(), cam.coeffs.begin());
  } else if (model == "none") {
    cam.distortion = DistortionModel::kNone;
    return;
  } else {
    yfail(c, model_node, model_key,
          "unsupported distortion model; expected " +
              std::string(kalibr ? "radtan, equidistant or none"
                                 : "plumb_bob, rational_polynomial, equidistant (fisheye) or none") +
              ", " + got(model_node));
  }
  // Bounded like every camera model (render/camera_model.hpp): 1e300 overflows every projection.
  for (std::size_t i = 0; i < cam.coeffs.size(); ++i) {
    if (!(std::abs(cam.coeffs[i]) <= kMaxDistortionCoefficient)) {
      yfail(c, coeffs_node, coeffs_key,
            "expected distortion coefficients in [-1000, 1000], got " + num(cam.coeffs[i]) + " as element " +
                std::to_string(i));
    }
  }
}

// A ROS matrix entry {rows, cols, data}; also accepts a bare list (CameraInfo message dumps).
std::vector<double> ros_matrix(const Ctx& c, const YAML::Node& n, const std::string& key, std::size_t rows,
                               std::size_t cols) {
  const std::string what = "a " + std::to_string(rows) + "x" + std::to_string(cols) +
                           " matrix: {rows: " + std::to_string(rows) + ", cols: " + std::to_string(cols) +
                           ", data: [" + std::to_string(rows * cols) + " numbers, row-major]}";
  if (n.IsSequence()) return ynumbers(c, n, key, {rows * cols}, what);
  if (!n.IsMap()) yfail(c, n, key, "expected " + what + ", " + got(n));
  for (const auto& [name, expected] : {std::pair<const char*, std::size_t>{"rows", rows}, {"cols", cols}}) {
    if (const YAML::Node d = n[name]; d.IsDefined()) {
      int v = 0;
      if (!d.IsScalar() || !YAML::convert<int>::decode(d, v) || static_cast<std::size_t>(v) != expected) {
        yfail(c, d, key + "." + name, "expected " + std::to_string(expected) + ", " + got(d));
      }
    }
  }
  return ynumbers(c, yrequire(c, n, key, "data", std::to_string(rows * cols) + " numbers"), key + ".data",
                  {rows * cols}, what);
}

struct RosCamera {
  CameraModel model;
  Eigen::Matrix3d R_rect = Eigen::Matrix3d::Identity();  // camera -> rectified camera
  Eigen::Matrix<double, 3, 4> P = Eigen::Matrix<double, 3, 4>::Zero();
};

RosCamera read_ros_camera(const std::string& path) {
  const Ctx c{"calib::import_ros_camera_info(): ", path};
  const YAML::Node root = yload(c, path);
  RosCamera rc;
  CameraModel& m = rc.model;
  // Two spellings: the camera_calibration YAML file, and a dumped sensor_msgs/CameraInfo message.
  const bool msg = !root["camera_matrix"].IsDefined() && root["K"].IsDefined();
  const std::string kK = msg ? "K" : "camera_matrix";
  const std::string kD = msg ? "D" : "distortion_coefficients";
  const std::string kR = msg ? "R" : "rectification_matrix";
  const std::string kP = msg ? "P" : "projection_matrix";
  const std::string kW = msg ? "width" : "image_width";
  const std::string kH = msg ? "height" : "image_height";
  m.width_px = yint(c, yrequire(c, root, "", kW, "the image width in pixels"), kW, "a positive integer");
  m.height_px = yint(c, yrequire(c, root, "", kH, "the image height in pixels"), kH, "a positive integer");
  const YAML::Node kn = yrequire(c, root, "", kK, "the 3x3 camera matrix");
  const auto K = ros_matrix(c, kn, kK, 3, 3);
  m.fx_px = K[0];
  m.cx_px = K[2];
  m.fy_px = K[4];
  m.cy_px = K[5];
  if (std::abs(K[1]) > 1e-9 * std::abs(K[0]))
    yfail(c, kn, kK, "expected zero skew K[0][1], got " + num(K[1]));
  const YAML::Node dm =
      yrequire(c, root, "", "distortion_model", "plumb_bob, rational_polynomial or equidistant");
  const std::string model = ystring(c, dm, "distortion_model", "a distortion model name");
  const YAML::Node dn = yrequire(c, root, "", kD, "the distortion coefficients");
  set_distortion(c, dm, "distortion_model", model, dn.IsMap() ? dn["data"] : dn,
                 dn.IsMap() ? kD + ".data" : kD, m, false);
  check_camera(c, m, kK, kn.Mark().line + 1, kn.Mark().column + 1);
  const YAML::Node rn = yrequire(c, root, "", kR, "the 3x3 rectification matrix");
  const auto R = ros_matrix(c, rn, kR, 3, 3);
  for (int i = 0; i < 9; ++i) rc.R_rect(i / 3, i % 3) = R[i];
  if (const std::string p = rotation_problem(rc.R_rect); !p.empty()) yfail(c, rn, kR, p);
  const YAML::Node pn = yrequire(c, root, "", kP, "the 3x4 projection matrix");
  const auto P = ros_matrix(c, pn, kP, 3, 4);
  for (int i = 0; i < 12; ++i) rc.P(i / 4, i % 4) = P[i];
  if (!(rc.P(0, 0) > 0 && rc.P(1, 1) > 0) || rc.P(2, 2) != 1.0) {
    yfail(c, pn, kP, "expected P = K' [I | t] with positive fx', fy' and P[2][2] = 1");
  }
  return rc;
}

Eigen::Matrix4d kalibr_matrix(const Ctx& c, const YAML::Node& n, const std::string& key) {
  const std::string what = "a 4x4 matrix as 4 rows of 4 numbers";
  std::vector<double> v;
  if (n.IsSequence() && n.size() == 4) {
    for (std::size_t r = 0; r < 4; ++r) {
      const auto row = ynumbers(c, n[r], key, {4}, what + " (row " + std::to_string(r) + ")");
      v.insert(v.end(), row.begin(), row.end());
    }
  } else {
    v = ynumbers(c, n, key, {16}, what);
  }
  Eigen::Matrix4d T;
  for (int i = 0; i < 16; ++i) T(i / 4, i % 4) = v[i];
  if ((T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
    yfail(c, n, key, "expected the last row to be [0, 0, 0, 1]");
  }
  if (const std::string p = rotation_problem(T.topLeftCorner<3, 3>()); !p.empty()) yfail(c, n, key, p);
  return T;
}

CameraModel kalibr_camera(const Ctx& c, const YAML::Node& root, const std::string& cam) {
  const YAML::Node n = yrequire(c, root, "", cam, "the camera's map (camera_model, intrinsics, ...)");
  if (!n.IsMap()) yfail(c, n, cam, "expected a map, " + got(n));
  const YAML::Node cm = yrequire(c, n, cam, "camera_model", "pinhole");
  if (ystring(c, cm, cam + ".camera_model", "pinhole") != "pinhole") {
    yfail(c, cm, cam + ".camera_model", "unsupported camera model; expected pinhole, " + got(cm));
  }
  CameraModel m;
  const YAML::Node in = yrequire(c, n, cam, "intrinsics", "[fu, fv, pu, pv]");
  const auto k = ynumbers(c, in, cam + ".intrinsics", {4}, "a list of 4 numbers [fu, fv, pu, pv]");
  m.fx_px = k[0];
  m.fy_px = k[1];
  m.cx_px = k[2];
  m.cy_px = k[3];
  const YAML::Node res = yrequire(c, n, cam, "resolution", "[width, height]");
  const auto wh = ynumbers(c, res, cam + ".resolution", {2}, "a list of 2 integers [width, height]");
  // Range first: casting 1e10 to int is undefined.
  for (std::size_t i = 0; i < 2; ++i) {
    if (!(wh[i] >= 1 && wh[i] <= kMaxImageSidePx && wh[i] == std::floor(wh[i]))) {
      yfail(c, res[i], cam + ".resolution",
            "expected 2 integers [width, height] in 1.." + std::to_string(kMaxImageSidePx) + ", " +
                got(res[i]) + " as element " + std::to_string(i));
    }
  }
  m.width_px = static_cast<int>(wh[0]);
  m.height_px = static_cast<int>(wh[1]);
  const YAML::Node dm = yrequire(c, n, cam, "distortion_model", "radtan or equidistant");
  const std::string model = ystring(c, dm, cam + ".distortion_model", "radtan or equidistant");
  const YAML::Node dc = n["distortion_coeffs"];
  if (model != "none" && !dc.IsDefined()) {
    yfail(c, n, cam + ".distortion_coeffs", "missing; expected a list of 4 numbers");
  }
  set_distortion(c, dm, cam + ".distortion_model", model, dc, cam + ".distortion_coeffs", m, true);
  check_camera(c, m, cam + ".intrinsics", in.Mark().line + 1, in.Mark().column + 1);
  return m;
}

// ---------------------------------------------------------------------------------------------
// OpenCV FileStorage: cv::FileNode has no line numbers, so the key's line is found in the text.

int opencv_key_line(const std::string& text, const std::string& key) {
  const std::regex yaml_key("^" + key + "[ \t]*:");
  const std::regex xml_key("<" + key + "[ \t>/]");
  std::istringstream in(text);
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    if (std::regex_search(line, yaml_key) || std::regex_search(line, xml_key)) return n;
  }
  return 0;
}

std::string cv_got(const cv::FileNode& n) {
  if (n.isMap()) return "got a map";
  if (n.isSeq()) return "got a list of " + std::to_string(n.size()) + " element(s)";
  if (n.isString()) return "got '" + n.string() + "'";
  if (n.isInt() || n.isReal()) return "got " + num(n.real());
  return "got nothing";
}

// A matrix under `key` (an !!opencv-matrix, or a plain list of numbers) as doubles, row-major.
std::vector<double> cv_numbers(const Ctx& c, const cv::FileStorage& fs, const std::string& text,
                               const std::string& key, const std::string& what, int* rows = nullptr) {
  const cv::FileNode n = fs[key];
  const int line = opencv_key_line(text, key);
  if (n.empty() || n.isNone()) fail(c, line, 0, key, "missing; expected " + what);
  std::vector<double> v;
  try {
    if (n.isSeq()) {
      for (const auto& e : n) {
        if (!e.isInt() && !e.isReal())
          fail(c, line, 0, key, "expected " + what + ", " + cv_got(e) + " in the list");
        v.push_back(e.real());
      }
      if (rows) *rows = 1;
    } else if (n.isMap()) {
      // Checked before OpenCV reads it: cv::read allocates rows x cols as the file says (2e9
      // columns asked for 48 GB). A calibration matrix or vector is small.
      const cv::FileNode rn = n["rows"], cn = n["cols"], dn = n["data"];
      const int r = rn.isInt() ? static_cast<int>(rn) : 0, k = cn.isInt() ? static_cast<int>(cn) : 0;
      if (r < 1 || r > 64 || k < 1 || k > 64 || !dn.isSeq() ||
          dn.size() != static_cast<std::size_t>(r) * static_cast<std::size_t>(k))
        fail(c, line, 0, key,
             "expected " + what +
                 " as an !!opencv-matrix of 1..64 rows and cols with rows x cols numbers in "
                 "'data'");
      cv::Mat m;
      n >> m;
      if (m.empty() || m.channels() != 1) fail(c, line, 0, key, "expected " + what + ", got an empty matrix");
      m.convertTo(m, CV_64F);
      if (rows) *rows = m.rows;
      v.assign(m.begin<double>(), m.end<double>());
    } else {
      fail(c, line, 0, key, "expected " + what + ", " + cv_got(n));
    }
  } catch (const cv::Exception& e) {
    fail(c, line, 0, key, "expected " + what + " (OpenCV: " + e.err + ")");
  }
  for (double x : v) {
    if (!std::isfinite(x)) fail(c, line, 0, key, "expected finite numbers in " + what);
  }
  return v;
}

CameraModel opencv_camera(const Ctx& c, const cv::FileStorage& fs, const std::string& text,
                          const std::string& kname, const std::string& dname, int w, int h) {
  CameraModel m;
  const auto K = cv_numbers(c, fs, text, kname, "a 3x3 camera matrix (!!opencv-matrix)");
  if (K.size() != 9) {
    fail(c, opencv_key_line(text, kname), 0, kname,
         "expected a 3x3 camera matrix, got " + std::to_string(K.size()) + " elements");
  }
  if (std::abs(K[1]) > 1e-9 * std::abs(K[0])) {
    fail(c, opencv_key_line(text, kname), 0, kname, "expected zero skew K[0][1], got " + num(K[1]));
  }
  m.fx_px = K[0];
  m.cx_px = K[2];
  m.fy_px = K[4];
  m.cy_px = K[5];
  m.width_px = w;
  m.height_px = h;
  const auto D = cv_numbers(c, fs, text, dname, "4, 5, 8, 12 or 14 distortion coefficients");
  const int dline = opencv_key_line(text, dname);
  if (D.size() != 4 && D.size() != 5 && D.size() != 8 && D.size() != 12 && D.size() != 14) {
    fail(c, dline, 0, dname,
         "expected 4, 5, 8, 12 or 14 distortion coefficients (k1 k2 p1 p2 [k3 ...]), got " +
             std::to_string(D.size()));
  }
  m.distortion = DistortionModel::kRadTan;
  for (std::size_t i = 0; i < D.size(); ++i) {
    if (i < 5) {
      m.coeffs[i] = D[i];
    } else if (D[i] != 0.0) {
      fail(c, dline, 0, dname,
           "rational/thin-prism model not supported: coefficients after k1 k2 p1 p2 k3 must be 0, got " +
               num(D[i]) + " as element " + std::to_string(i));
    }
  }
  check_camera(c, m, kname, opencv_key_line(text, kname), 0);
  return m;
}

// Image size from the file (several spellings in the wild), 0x0 when absent.
std::pair<int, int> opencv_size(const Ctx& c, const cv::FileStorage& fs, const std::string& text) {
  for (const auto& [kw, kh] :
       {std::pair<const char*, const char*>{"image_width", "image_height"}, {"width", "height"}}) {
    if (!fs[kw].empty() && !fs[kh].empty()) {
      // Compared as doubles: OpenCV reads 1e10 as a real, and a cast to int would be undefined.
      for (const char* k : {kw, kh}) {
        const cv::FileNode n = fs[k];
        const double v = n.isInt() || n.isReal() ? n.real() : 0.0;
        if (!n.isInt() || !(v >= 1 && v <= kMaxImageSidePx)) {
          fail(c, opencv_key_line(text, k), 0, k,
               "expected an integer in 1.." + std::to_string(kMaxImageSidePx) + " (pixels), " + cv_got(n));
        }
      }
      return {static_cast<int>(fs[kw]), static_cast<int>(fs[kh])};
    }
  }
  for (const char* k : {"imageSize", "image_size"}) {
    if (!fs[k].empty()) {
      const auto v = cv_numbers(c, fs, text, k, "[width, height]");
      // Range before the cast to int (1e10 would be undefined behaviour).
      if (v.size() != 2 || !(v[0] >= 1 && v[0] <= kMaxImageSidePx && v[1] >= 1 && v[1] <= kMaxImageSidePx) ||
          v[0] != std::floor(v[0]) || v[1] != std::floor(v[1])) {
        fail(c, opencv_key_line(text, k), 0, k,
             "expected 2 integers [width, height] in 1.." + std::to_string(kMaxImageSidePx) + ", got " +
                 (v.size() == 2 ? "[" + num(v[0]) + ", " + num(v[1]) + "]"
                                : std::to_string(v.size()) + " numbers"));
      }
      return {static_cast<int>(v[0]), static_cast<int>(v[1])};
    }
  }
  return {0, 0};
}

template <typename F>
Expected<StereoCalibration> guarded(F f) {
  try {
    return f();
  } catch (const ImportFailure& e) {
    return Error{e.message};
  } catch (const std::exception& e) {  // YAML or OpenCV surprises: still an Error, never a throw
    return make_error("calib: unexpected error: ", e.what());
  }
}

}  // namespace

Expected<StereoCalibration> import_opencv_stereo(const std::string& path, int width_px, int height_px) {
  return guarded([&]() -> Expected<StereoCalibration> {
    const Ctx c{"calib::import_opencv_stereo(): ", path};
    std::string text;
    if (const std::string why = read_text(path, &text); !why.empty()) fail(c, 0, 0, "", why);
    cv::FileStorage fs;
    try {
      if (!fs.open(path, cv::FileStorage::READ))
        fail(c, 0, 0, "", "cannot open as an OpenCV FileStorage file");
    } catch (const cv::Exception& e) {
      // OpenCV's parser puts "file(line): what" into e.func (a quirk of its error macro): recover
      // the line so the message has our usual file:line shape.
      std::smatch sm;
      if (std::regex_search(e.func, sm, std::regex("\\((\\d+)\\): (.*)$"))) {
        fail(c, std::stoi(sm[1].str()), 0, "", "not a valid OpenCV FileStorage file: " + sm[2].str());
      }
      fail(c, 0, 0, "", "not a valid OpenCV FileStorage YAML/XML file (" + e.err + ")");
    }
    // stereoCalibrate writes M1/M2; other tools write K1/K2.
    const bool m_names = !fs["M1"].empty();
    if (!m_names && fs["K1"].empty())
      fail(c, 0, 0, "M1", "missing; expected M1 D1 M2 D2 R T (or K1 D1 K2 D2 R T)");
    const std::string k1 = m_names ? "M1" : "K1", k2 = m_names ? "M2" : "K2";
    auto [w, h] = opencv_size(c, fs, text);
    if (w == 0) {
      w = width_px;
      h = height_px;
    }
    if (w <= 0 || h <= 0) {
      fail(c, 0, 0, "image_width",
           "missing image size; expected image_width/image_height or imageSize [w, h] in the file, or a "
           "resolution from the caller");
    }
    StereoCalibration out;
    out.format = "opencv";
    out.left = opencv_camera(c, fs, text, k1, "D1", w, h);
    out.right = opencv_camera(c, fs, text, k2, "D2", w, h);
    int rrows = 0;
    const auto R = cv_numbers(c, fs, text, "R", "a 3x3 rotation matrix (or a 3x1 Rodrigues vector)", &rrows);
    Eigen::Matrix3d Rm;
    if (R.size() == 9) {
      for (int i = 0; i < 9; ++i) Rm(i / 3, i % 3) = R[i];
    } else if (R.size() == 3) {
      cv::Mat rm;
      cv::Rodrigues(cv::Vec3d(R[0], R[1], R[2]), rm);
      for (int i = 0; i < 9; ++i) Rm(i / 3, i % 3) = rm.at<double>(i / 3, i % 3);
    } else {
      fail(c, opencv_key_line(text, "R"), 0, "R",
           "expected a 3x3 rotation matrix or a 3x1 Rodrigues vector, got " + std::to_string(R.size()) +
               " elements");
    }
    if (const std::string p = rotation_problem(Rm); !p.empty())
      fail(c, opencv_key_line(text, "R"), 0, "R", p);
    const auto T = cv_numbers(c, fs, text, "T", "a 3x1 translation in metres");
    if (T.size() != 3) {
      fail(c, opencv_key_line(text, "T"), 0, "T",
           "expected a 3x1 translation in metres, got " + std::to_string(T.size()) + " elements");
    }
    // stereoCalibrate's (R, T) maps left-camera coordinates to right-camera ones: T_right_left.
    out.T_right_left = Pose::from(Rm, Eigen::Vector3d(T[0], T[1], T[2]));
    return out;
  });
}

Expected<StereoCalibration> import_ros_camera_info(const std::string& left_path,
                                                   const std::string& right_path) {
  return guarded([&]() -> Expected<StereoCalibration> {
    const RosCamera l = read_ros_camera(left_path);
    const RosCamera r = read_ros_camera(right_path);
    // Derivation. Each file holds R_i (camera i -> rectified camera i) and P_i = K' [I | t_i] where
    // t_i is the position offset of rectified camera i in the common rectified frame (the left
    // one's): p_rect_i = p_common + t_i, with t_i = K'^-1 P_i[:, 3]. For a horizontal pair
    // P_right[0][3] = Tx = -fx' B, so t_right = (-B, 0, 0): the right camera sits at +B along x.
    // Then p_left = R_l^T (p_common + t_l) and p_right = R_r^T (p_common + t_r), so
    //   p_right = R_r^T R_l p_left + R_r^T (t_r - t_l)   =>   T_right_left = [R_r^T R_l | R_r^T (t_r - t_l)].
    // cv::stereoRectify produces exactly this (R1, R2, P1, P2), which the tests check.
    auto offset = [](const RosCamera& rc) -> Eigen::Vector3d {
      return rc.P.leftCols<3>().inverse() * rc.P.col(3);
    };
    StereoCalibration out;
    out.format = "ros";
    out.left = l.model;
    out.right = r.model;
    out.T_right_left =
        Pose::from(r.R_rect.transpose() * l.R_rect, r.R_rect.transpose() * (offset(r) - offset(l)));
    if (out.T_right_left.translation_m.norm() == 0.0) {
      const Ctx c{"calib::import_ros_camera_info(): ", right_path};
      fail(c, 0, 0, "projection_matrix", "expected a non-zero baseline (P[0][3] = -fx' * B), got 0");
    }
    return out;
  });
}

Expected<StereoCalibration> import_kalibr_camchain(const std::string& path) {
  return guarded([&]() -> Expected<StereoCalibration> {
    const Ctx c{"calib::import_kalibr_camchain(): ", path};
    const YAML::Node root = yload(c, path);
    StereoCalibration out;
    out.format = "kalibr";
    out.left = kalibr_camera(c, root, "cam0");
    out.right = kalibr_camera(c, root, "cam1");
    // T_cn_cnm1 maps cam(n-1) coordinates to cam(n): for cam1 that is T_right_left.
    const YAML::Node t = yrequire(c, root["cam1"], "cam1", "T_cn_cnm1", "the 4x4 transform cam0 -> cam1");
    out.T_right_left = Pose::from_matrix(kalibr_matrix(c, t, "cam1.T_cn_cnm1"));
    return out;
  });
}

Expected<StereoCalibration> import_calibration(const std::string& format, const std::string& path,
                                               const std::string& path2) {
  std::string f = format;
  if (f == "auto") {
    // Sniff the content: OpenCV files carry %YAML:1.0 / opencv-matrix / XML, Kalibr has cam0,
    // a ROS camera_info has camera_matrix (or K in a dumped message).
    std::string text;
    if (const std::string why = read_text(path, &text); !why.empty())
      return make_error("calib::import_calibration(): ", path, ": ", why);
    if (text.rfind("%YAML:1.0", 0) == 0 || text.find("opencv-matrix") != std::string::npos ||
        text.find("<opencv_storage>") != std::string::npos) {
      f = "opencv";
    } else if (std::regex_search(text, std::regex("(^|\n)cam0[ \t]*:"))) {
      f = "kalibr";
    } else if (std::regex_search(text, std::regex("(^|\n)(camera_matrix|K)[ \t]*:"))) {
      f = "ros";
    } else {
      return make_error("calib::import_calibration(): ", path,
                        ": cannot tell the format; expected an OpenCV FileStorage file, a ROS camera_info "
                        "or a Kalibr camchain");
    }
  }
  if (f == "opencv") return import_opencv_stereo(path);
  if (f == "kalibr") return import_kalibr_camchain(path);
  if (f == "ros") {
    if (path2.empty()) {
      return make_error("calib::import_calibration(): ", path,
                        ": format 'ros' needs the right camera's camera_info file as the second path");
    }
    return import_ros_camera_info(path, path2);
  }
  return make_error("calib::import_calibration(): ", path, ": unknown format '", format,
                    "'; expected opencv, ros, kalibr or auto");
}

}  // namespace augrig
