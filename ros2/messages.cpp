// ros2 messages (messages.hpp): CDR fields, the .msg definitions (ROS 2 Humble's field lists, without
// their comments), and each message written field by field in its definition's order.
#include "ros2/messages.hpp"

#include <cmath>
#include <cstring>
#include <functional>
#include <map>
#include <set>

namespace augrig::ros2 {

// ---- CDR ------------------------------------------------------------------------------------------

void CdrWriter::f64(double v) {
  std::uint64_t bits;
  std::memcpy(&bits, &v, 8);
  le(bits, 8);
}

void CdrWriter::string(const std::string& s) {
  u32(static_cast<std::uint32_t>(s.size() + 1));
  b_.insert(b_.end(), s.begin(), s.end());
  b_.push_back(0);
}

void CdrWriter::bytes(const std::uint8_t* p, std::size_t n) {
  u32(static_cast<std::uint32_t>(n));
  b_.insert(b_.end(), p, p + n);
}

void CdrWriter::f64_array(const double* v, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) f64(v[i]);
}

void CdrWriter::f64_sequence(const std::vector<double>& v) {
  u32(static_cast<std::uint32_t>(v.size()));
  f64_array(v.data(), v.size());
}

CdrReader::CdrReader(const std::uint8_t* p, std::size_t n) : p_(p), n_(n) {
  // 00 01: CDR little endian (00 00 would be big endian, which no ROS 2 writer on our hosts makes).
  ok_ = n >= 4 && p[0] == 0x00 && p[1] == 0x01;
}

std::uint64_t CdrReader::le(int n) {
  const auto k = static_cast<std::size_t>(n);
  const std::size_t aligned = 4 + ((i_ - 4 + k - 1) / k) * k;
  if (!ok_ || aligned > n_ || k > n_ - aligned) {
    ok_ = false;
    return 0;
  }
  i_ = aligned;
  std::uint64_t v = 0;
  for (std::size_t b = 0; b < k; ++b) v |= static_cast<std::uint64_t>(p_[i_ + b]) << (8 * b);
  i_ += k;
  return v;
}

double CdrReader::f64() {
  const std::uint64_t bits = le(8);
  double v;
  std::memcpy(&v, &bits, 8);
  return v;
}

std::string CdrReader::string() {
  const std::uint32_t len = u32();
  if (!ok_ || len == 0 || len > n_ - i_) {
    ok_ = false;
    return {};
  }
  std::string s(reinterpret_cast<const char*>(p_ + i_), len - 1);  // without the NUL
  i_ += len;
  return s;
}

const std::uint8_t* CdrReader::bytes(std::size_t& n) {
  const std::uint32_t len = u32();
  if (!ok_ || len > n_ - i_) {
    ok_ = false;
    n = 0;
    return nullptr;
  }
  const std::uint8_t* p = p_ + i_;
  i_ += len;
  n = len;
  return p;
}

// ---- Schemas --------------------------------------------------------------------------------------

namespace {

struct MsgDef {
  std::string text;
  std::vector<std::string> uses;  // the types its fields name ("std_msgs/Header"), in order
};

const std::map<std::string, MsgDef>& definitions() {
  static const std::map<std::string, MsgDef> defs = {
      {"builtin_interfaces/Time", {"int32 sec\nuint32 nanosec\n", {}}},
      {"std_msgs/Header", {"builtin_interfaces/Time stamp\nstring frame_id\n", {"builtin_interfaces/Time"}}},
      {"sensor_msgs/Image",
       {"std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 "
        "step\n"
        "uint8[] data\n",
        {"std_msgs/Header"}}},
      {"sensor_msgs/CompressedImage",
       {"std_msgs/Header header\nstring format\nuint8[] data\n", {"std_msgs/Header"}}},
      {"foxglove_msgs/CompressedVideo",
       {"builtin_interfaces/Time timestamp\nstring frame_id\nuint8[] data\nstring format\n",
        {"builtin_interfaces/Time"}}},
      {"sensor_msgs/RegionOfInterest",
       {"uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n", {}}},
      {"sensor_msgs/CameraInfo",
       {"std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\n"
        "float64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\n"
        "sensor_msgs/RegionOfInterest roi\n",
        {"std_msgs/Header", "sensor_msgs/RegionOfInterest"}}},
      {"geometry_msgs/Vector3", {"float64 x\nfloat64 y\nfloat64 z\n", {}}},
      {"geometry_msgs/Point", {"float64 x\nfloat64 y\nfloat64 z\n", {}}},
      {"geometry_msgs/Quaternion", {"float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n", {}}},
      {"geometry_msgs/Transform",
       {"geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n",
        {"geometry_msgs/Vector3", "geometry_msgs/Quaternion"}}},
      {"geometry_msgs/TransformStamped",
       {"std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n",
        {"std_msgs/Header", "geometry_msgs/Transform"}}},
      {"tf2_msgs/TFMessage",
       {"geometry_msgs/TransformStamped[] transforms\n", {"geometry_msgs/TransformStamped"}}},
      {"geometry_msgs/Pose",
       {"geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
        {"geometry_msgs/Point", "geometry_msgs/Quaternion"}}},
      {"geometry_msgs/PoseWithCovariance",
       {"geometry_msgs/Pose pose\nfloat64[36] covariance\n", {"geometry_msgs/Pose"}}},
      {"geometry_msgs/PoseWithCovarianceStamped",
       {"std_msgs/Header header\ngeometry_msgs/PoseWithCovariance pose\n",
        {"std_msgs/Header", "geometry_msgs/PoseWithCovariance"}}},
      {"sensor_msgs/Imu",
       {"std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
        "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
        "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n",
        {"std_msgs/Header", "geometry_msgs/Quaternion", "geometry_msgs/Vector3"}}},
      {"sensor_msgs/NavSatStatus",
       {"int8 STATUS_NO_FIX = -1\nint8 STATUS_FIX = 0\nint8 STATUS_SBAS_FIX = 1\nint8 STATUS_GBAS_FIX = 2\n"
        "int8 status\nuint16 SERVICE_GPS = 1\nuint16 SERVICE_GLONASS = 2\nuint16 SERVICE_COMPASS = 4\n"
        "uint16 SERVICE_GALILEO = 8\nuint16 service\n",
        {}}},
      {"sensor_msgs/NavSatFix",
       {"std_msgs/Header header\nsensor_msgs/NavSatStatus status\nfloat64 latitude\nfloat64 longitude\n"
        "float64 altitude\nfloat64[9] position_covariance\nuint8 COVARIANCE_TYPE_UNKNOWN = 0\n"
        "uint8 COVARIANCE_TYPE_APPROXIMATED = 1\nuint8 COVARIANCE_TYPE_DIAGONAL_KNOWN = 2\n"
        "uint8 COVARIANCE_TYPE_KNOWN = 3\nuint8 position_covariance_type\n",
        {"std_msgs/Header", "sensor_msgs/NavSatStatus"}}},
      {"diagnostic_msgs/KeyValue", {"string key\nstring value\n", {}}},
      {"diagnostic_msgs/DiagnosticStatus",
       {"byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\nstring name\nstring message\n"
        "string hardware_id\ndiagnostic_msgs/KeyValue[] values\n",
        {"diagnostic_msgs/KeyValue"}}},
      {"diagnostic_msgs/DiagnosticArray",
       {"std_msgs/Header header\ndiagnostic_msgs/DiagnosticStatus[] status\n",
        {"std_msgs/Header", "diagnostic_msgs/DiagnosticStatus"}}},
      {"augrig_msgs/OcclusionStats",
       {"# The occlusion statistics of one stereo frame (augrig render/stats.hpp, docs/STATISTICS.md).\n"
        "std_msgs/Header header\nint64 t_ns\nint64 width\nint64 height\nint64 receiver_px_left\n"
        "int64 receiver_px_right\nint64 boom_px_left\nint64 boom_px_right\nint64 boom_overlap_px\n"
        "float64 boom_overlap_pct_union\nint64 occluded_px_left\nint64 occluded_px_right\n"
        "float64 occluded_pct_left\nfloat64 occluded_pct_right\nint64 stereo_both_px\nint64 left_only_px\n"
        "int64 right_only_px\nint64 neither_px\nfloat64 receiver_pct_left\nfloat64 receiver_pct_right\n"
        "float64 boom_pct_left\nfloat64 boom_pct_right\n"
        "# Appended: the boom's shadow on the receiver (mask bit 2). A message without them reads 0.\n"
        "int64 shadow_px_left\nint64 shadow_px_right\nfloat64 shadow_pct_left\nfloat64 shadow_pct_right\n",
        {"std_msgs/Header"}}},
      {"augrig_msgs/CameraFrameInfo",
       {"# One camera's frame of a stereo frame: its counter, mid-exposure time on its clock, host arrival.\n"
        "uint64 sequence\nint64 t_ns\nstring clock\nint64 t_host_ns\nint64 exposure_ns\nstring pixel_format\n"
        "int32 width\nint32 height\n",
        {}}},
      {"augrig_msgs/StereoFrameInfo",
       {"# A recorded stereo frame (augrig docs/MCAP.md): pairing and the scene the augmentation used.\n"
        "# The poses are on /left/receiver_pose, /right/receiver_pose and /tf.\n"
        "std_msgs/Header header\nuint64 index\nuint64 pair_sequence\nint64 t_key_ns\nint64 skew_ns\n"
        "augrig_msgs/CameraFrameInfo left\naugrig_msgs/CameraFrameInfo right\n"
        "int8 receiver_present\nbool has_boom\nfloat64 boom_elevation_rad\nfloat64 boom_azimuth_rad\n"
        "float64 boom_extension_m\nfloat64 sigma_pos_m\nfloat64 sigma_att_deg\n",
        {"std_msgs/Header", "augrig_msgs/CameraFrameInfo"}}},
  };
  return defs;
}

// "sensor_msgs/msg/Image" -> "sensor_msgs/Image"
std::string short_name(const std::string& type) {
  const auto p = type.find("/msg/");
  return p == std::string::npos ? type : type.substr(0, p) + "/" + type.substr(p + 5);
}

}  // namespace

std::string schema_text(const std::string& type) {
  const auto& defs = definitions();
  const auto top = defs.find(short_name(type));
  if (top == defs.end()) return {};
  std::string text = top->second.text;
  // Every type used, depth first, each once.
  std::set<std::string> seen{top->first};
  std::function<void(const MsgDef&)> add = [&](const MsgDef& d) {
    for (const std::string& u : d.uses) {
      if (!seen.insert(u).second) continue;
      const MsgDef& dep = defs.at(u);
      text += std::string(80, '=') + "\nMSG: " + u + "\n" + dep.text;
      add(dep);
    }
  };
  add(top->second);
  return text;
}

const std::vector<std::string>& known_types() {
  static const std::vector<std::string> types = {"augrig_msgs/msg/StereoFrameInfo",
                                                 "sensor_msgs/msg/Image",
                                                 "sensor_msgs/msg/CompressedImage",
                                                 "foxglove_msgs/msg/CompressedVideo",
                                                 "sensor_msgs/msg/CameraInfo",
                                                 "tf2_msgs/msg/TFMessage",
                                                 "geometry_msgs/msg/PoseWithCovarianceStamped",
                                                 "augrig_msgs/msg/OcclusionStats",
                                                 "sensor_msgs/msg/Imu",
                                                 "sensor_msgs/msg/NavSatFix",
                                                 "diagnostic_msgs/msg/DiagnosticArray"};
  return types;
}

// ---- Messages -------------------------------------------------------------------------------------

std::string image_encoding(PixelFormat format) {
  switch (format) {
    case PixelFormat::kMono8:
      return "mono8";
    case PixelFormat::kRGB8:
      return "rgb8";
    case PixelFormat::kRGBA8:
      return "rgba8";
    case PixelFormat::kBayerRG8:
      return "bayer_rggb8";
    case PixelFormat::kBayerGR8:
      return "bayer_grbg8";
    case PixelFormat::kBayerGB8:
      return "bayer_gbrg8";
    case PixelFormat::kBayerBG8:
      return "bayer_bggr8";
  }
  return "mono8";
}

bool parse_image_encoding(const std::string& encoding, PixelFormat& out) {
  for (PixelFormat f : {PixelFormat::kMono8, PixelFormat::kRGB8, PixelFormat::kRGBA8, PixelFormat::kBayerRG8,
                        PixelFormat::kBayerGR8, PixelFormat::kBayerGB8, PixelFormat::kBayerBG8}) {
    if (image_encoding(f) == encoding) {
      out = f;
      return true;
    }
  }
  return false;
}

std::string distortion_model_name(DistortionModel d) {
  return d == DistortionModel::kEquidistant ? "equidistant" : "plumb_bob";
}

Status check_stamp(std::int64_t t_ns) {
  if (t_ns < 0 || t_ns / 1'000'000'000 > 2147483647)
    return Error{"a timestamp of " + std::to_string(t_ns) +
                 " ns does not fit a ROS 2 builtin_interfaces/Time"};
  return {};
}

namespace {

void header(CdrWriter& w, std::int64_t t_ns, const std::string& frame_id) {
  // Callers check the stamp first (check_stamp()); a negative one is written as 0.
  const std::int64_t t = std::max<std::int64_t>(t_ns, 0);
  w.i32(static_cast<std::int32_t>(t / 1'000'000'000));
  w.u32(static_cast<std::uint32_t>(t % 1'000'000'000));
  w.string(frame_id);
}

std::int64_t read_header(CdrReader& r, std::string* frame_id = nullptr) {
  const std::int64_t sec = r.i32();
  const std::int64_t nsec = r.u32();
  std::string id = r.string();
  if (frame_id) *frame_id = std::move(id);
  return sec * 1'000'000'000 + nsec;
}

void pose_fields(CdrWriter& w, const Pose& p) {
  w.f64(p.translation_m.x());
  w.f64(p.translation_m.y());
  w.f64(p.translation_m.z());
  w.f64(p.rotation.x());
  w.f64(p.rotation.y());
  w.f64(p.rotation.z());
  w.f64(p.rotation.w());
}

Pose read_pose(CdrReader& r) {
  Pose p;
  const double x = r.f64(), y = r.f64(), z = r.f64();
  const double qx = r.f64(), qy = r.f64(), qz = r.f64(), qw = r.f64();
  p.translation_m = Eigen::Vector3d(x, y, z);
  p.rotation = Eigen::Quaterniond(qw, qx, qy, qz);  // as stored: no normalisation, bit-exact
  return p;
}

Error bad(const std::string& type) {
  return Error{type + ": the message is shorter than its fields (damaged)"};
}

}  // namespace

std::vector<std::uint8_t> image(std::int64_t t_ns, const std::string& frame_id, ConstImageView im) {
  CdrWriter w;
  const std::size_t row =
      static_cast<std::size_t>(im.width) * static_cast<std::size_t>(bytes_per_pixel(im.format));
  w.data().reserve(64 + row * static_cast<std::size_t>(im.height));
  header(w, t_ns, frame_id);
  w.u32(static_cast<std::uint32_t>(im.height));
  w.u32(static_cast<std::uint32_t>(im.width));
  w.string(image_encoding(im.format));
  w.u8(0);  // is_bigendian
  w.u32(static_cast<std::uint32_t>(row));
  w.u32(static_cast<std::uint32_t>(row * static_cast<std::size_t>(im.height)));
  auto& b = w.data();
  for (int y = 0; y < im.height; ++y) {
    const std::uint8_t* p = im.data + static_cast<std::size_t>(y) * im.stride_bytes;
    b.insert(b.end(), p, p + row);
  }
  return std::move(w.data());
}

std::vector<std::uint8_t> compressed_image(std::int64_t t_ns, const std::string& frame_id, const std::string& format,
                                           const std::vector<std::uint8_t>& data) {
  CdrWriter w;
  w.data().reserve(64 + data.size());
  header(w, t_ns, frame_id);
  w.string(format);
  w.bytes(data.data(), data.size());
  return std::move(w.data());
}

std::vector<std::uint8_t> compressed_video(std::int64_t t_ns, const std::string& frame_id,
                                           const std::string& format, const std::vector<std::uint8_t>& data) {
  CdrWriter w;
  w.data().reserve(64 + data.size());
  header(w, t_ns, frame_id);  // timestamp, frame_id: the same bytes as a Header's
  w.bytes(data.data(), data.size());
  w.string(format);
  return std::move(w.data());
}

std::vector<std::uint8_t> camera_info(std::int64_t t_ns, const std::string& frame_id, const CameraModel& cm) {
  CdrWriter w;
  header(w, t_ns, frame_id);
  w.u32(static_cast<std::uint32_t>(cm.height_px));
  w.u32(static_cast<std::uint32_t>(cm.width_px));
  w.string(distortion_model_name(cm.distortion));
  std::vector<double> d;
  if (cm.distortion == DistortionModel::kEquidistant)
    d.assign(cm.coeffs.begin(), cm.coeffs.begin() + 4);
  else if (cm.distortion == DistortionModel::kRadTan)
    d.assign(cm.coeffs.begin(), cm.coeffs.end());
  else
    d.assign(5, 0.0);
  w.f64_sequence(d);
  const double k[9] = {cm.fx_px, 0, cm.cx_px, 0, cm.fy_px, cm.cy_px, 0, 0, 1};
  const double r[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const double p[12] = {cm.fx_px, 0, cm.cx_px, 0, 0, cm.fy_px, cm.cy_px, 0, 0, 0, 1, 0};
  w.f64_array(k, 9);
  w.f64_array(r, 9);
  w.f64_array(p, 12);
  w.u32(0);                              // binning_x
  w.u32(0);                              // binning_y
  for (int i = 0; i < 4; ++i) w.u32(0);  // roi: the whole image
  w.boolean(false);
  return std::move(w.data());
}

std::vector<std::uint8_t> tf_message(const std::vector<Transform>& transforms) {
  CdrWriter w;
  w.u32(static_cast<std::uint32_t>(transforms.size()));
  for (const Transform& t : transforms) {
    header(w, t.t_ns, t.parent);
    w.string(t.child);
    pose_fields(w, t.T_parent_child);
  }
  return std::move(w.data());
}

std::array<double, 36> pose_covariance(double sigma_pos_m, double sigma_att_deg) {
  std::array<double, 36> c{};
  const double p = std::isfinite(sigma_pos_m) ? sigma_pos_m * sigma_pos_m : 0.0;
  const double a = std::isfinite(sigma_att_deg) ? std::pow(deg_to_rad(sigma_att_deg), 2) : 0.0;
  for (std::size_t i = 0; i < 3; ++i) {
    c[7 * i] = p;
    c[7 * (i + 3)] = a;
  }
  return c;
}

std::vector<std::uint8_t> pose_with_covariance(std::int64_t t_ns, const std::string& frame_id,
                                               const Pose& pose, const std::array<double, 36>& covariance) {
  CdrWriter w;
  header(w, t_ns, frame_id);
  pose_fields(w, pose);
  w.f64_array(covariance.data(), 36);
  return std::move(w.data());
}

std::vector<std::uint8_t> imu(std::int64_t t_ns, const std::string& frame_id, const Eigen::Vector3d& w_rad_s,
                              const Eigen::Vector3d& a_mps2) {
  CdrWriter w;
  header(w, t_ns, frame_id);
  const double q[4] = {0, 0, 0, 1};
  w.f64_array(q, 4);
  double cov[9] = {-1, 0, 0, 0, 0, 0, 0, 0, 0};  // no orientation estimate
  w.f64_array(cov, 9);
  w.f64_array(w_rad_s.data(), 3);
  cov[0] = 0;  // unknown covariances: all zero
  w.f64_array(cov, 9);
  w.f64_array(a_mps2.data(), 3);
  w.f64_array(cov, 9);
  return std::move(w.data());
}

std::vector<std::uint8_t> nav_sat_fix(std::int64_t t_ns, const std::string& frame_id, int status,
                                      double lat_deg, double lon_deg, double alt_m,
                                      const Eigen::Vector3d& sigma_enu_m) {
  CdrWriter w;
  header(w, t_ns, frame_id);
  w.i8(static_cast<std::int8_t>(status));
  w.u16(1);  // SERVICE_GPS
  w.f64(lat_deg);
  w.f64(lon_deg);
  w.f64(alt_m);
  double cov[9] = {};
  const bool known = sigma_enu_m.minCoeff() > 0 && sigma_enu_m.allFinite();
  if (known)
    for (int i = 0; i < 3; ++i) cov[4 * i] = sigma_enu_m[i] * sigma_enu_m[i];
  w.f64_array(cov, 9);
  w.u8(known ? 2 : 0);  // COVARIANCE_TYPE_DIAGONAL_KNOWN or UNKNOWN
  return std::move(w.data());
}

std::vector<std::uint8_t> occlusion_stats(std::int64_t stamp_ns, const OcclusionStats& s) {
  CdrWriter w;
  header(w, stamp_ns, "");
  w.i64(s.t_ns);
  w.i64(s.width);
  w.i64(s.height);
  w.i64(s.receiver_px_left);
  w.i64(s.receiver_px_right);
  w.i64(s.boom_px_left);
  w.i64(s.boom_px_right);
  w.i64(s.boom_overlap_px);
  w.f64(s.boom_overlap_pct_union);
  w.i64(s.occluded_px_left);
  w.i64(s.occluded_px_right);
  w.f64(s.occluded_pct_left);
  w.f64(s.occluded_pct_right);
  w.i64(s.stereo_both_px);
  w.i64(s.left_only_px);
  w.i64(s.right_only_px);
  w.i64(s.neither_px);
  w.f64(s.receiver_pct_left);
  w.f64(s.receiver_pct_right);
  w.f64(s.boom_pct_left);
  w.f64(s.boom_pct_right);
  w.i64(s.shadow_px_left);
  w.i64(s.shadow_px_right);
  w.f64(s.shadow_pct_left);
  w.f64(s.shadow_pct_right);
  return std::move(w.data());
}

namespace {
void camera_frame_info(CdrWriter& w, const CameraFrameInfo& c) {
  w.u64(c.sequence);
  w.i64(c.t_ns);
  w.string(c.clock);
  w.i64(c.t_host_ns);
  w.i64(c.exposure_ns);
  w.string(c.pixel_format);
  w.i32(c.width);
  w.i32(c.height);
}
CameraFrameInfo read_camera_frame_info(CdrReader& r) {
  CameraFrameInfo c;
  c.sequence = r.u64();
  c.t_ns = r.i64();
  c.clock = r.string();
  c.t_host_ns = r.i64();
  c.exposure_ns = r.i64();
  c.pixel_format = r.string();
  c.width = r.i32();
  c.height = r.i32();
  return c;
}
}  // namespace

StereoFrameInfo stereo_frame_info_of(const StereoFrame& raw, std::uint64_t index) {
  StereoFrameInfo fi;
  fi.index = index;
  fi.pair_sequence = raw.pair_sequence;
  fi.t_key_ns = raw.t_key_ns;
  fi.skew_ns = raw.skew_ns;
  for (int c = 0; c < 2; ++c) {
    const Frame& fr = c == 0 ? raw.left : raw.right;
    CameraFrameInfo& ci = c == 0 ? fi.left : fi.right;
    ci.sequence = fr.sequence;
    ci.t_ns = fr.t_ns;
    ci.clock = std::string(to_string(fr.clock));
    ci.t_host_ns = fr.t_host_ns;
    ci.exposure_ns = fr.exposure_ns;
    ci.pixel_format = std::string(to_string(fr.image.format()));
    ci.width = fr.image.width();
    ci.height = fr.image.height();
  }
  return fi;
}

std::vector<std::uint8_t> stereo_frame_info(std::int64_t stamp_ns, const StereoFrameInfo& info) {
  CdrWriter w;
  header(w, stamp_ns, "tanker_body");
  w.u64(info.index);
  w.u64(info.pair_sequence);
  w.i64(info.t_key_ns);
  w.i64(info.skew_ns);
  camera_frame_info(w, info.left);
  camera_frame_info(w, info.right);
  w.i8(info.receiver_present);
  w.boolean(info.boom.has_value());
  const BoomArticulation b = info.boom.value_or(BoomArticulation{});
  w.f64(b.elevation_rad);
  w.f64(b.azimuth_rad);
  w.f64(b.extension_m);
  w.f64(info.sigma_pos_m);
  w.f64(info.sigma_att_deg);
  return std::move(w.data());
}

std::vector<std::uint8_t> diagnostic_array(std::int64_t t_ns, const std::vector<DiagnosticStatus>& status) {
  CdrWriter w;
  header(w, t_ns, "");
  w.u32(static_cast<std::uint32_t>(status.size()));
  for (const DiagnosticStatus& s : status) {
    w.u8(s.level);
    w.string(s.name);
    w.string(s.message);
    w.string(s.hardware_id);
    w.u32(static_cast<std::uint32_t>(s.values.size()));
    for (const auto& [key, value] : s.values) {
      w.string(key);
      w.string(value);
    }
  }
  return std::move(w.data());
}

Expected<Image> decode_image(const std::vector<std::uint8_t>& msg, std::int64_t* stamp_ns) {
  CdrReader r(msg.data(), msg.size());
  const std::int64_t t = read_header(r);
  const std::uint32_t height = r.u32(), width = r.u32();
  const std::string encoding = r.string();
  r.u8();  // is_bigendian: no 8-bit encoding depends on it
  const std::uint32_t step = r.u32();
  std::size_t n = 0;
  const std::uint8_t* data = r.bytes(n);
  if (!r.ok()) return bad("sensor_msgs/msg/Image");
  PixelFormat f;
  if (!parse_image_encoding(encoding, f))
    return Error{
        "sensor_msgs/msg/Image: encoding '" + encoding +
        "' is not one augrig reads (mono8, rgb8, rgba8, bayer_rggb8, bayer_grbg8, bayer_gbrg8, bayer_bggr8)"};
  const std::size_t row = static_cast<std::size_t>(width) * static_cast<std::size_t>(bytes_per_pixel(f));
  if (width == 0 || height == 0 || width > 32768 || height > 32768 || step < row ||
      n != static_cast<std::size_t>(step) * height)
    return Error{"sensor_msgs/msg/Image: " + std::to_string(width) + "x" + std::to_string(height) + " " +
                 encoding + ", step " + std::to_string(step) + ", holds " + std::to_string(n) +
                 " bytes: sizes disagree"};
  Image im(static_cast<int>(width), static_cast<int>(height), f);
  for (std::uint32_t y = 0; y < height; ++y)
    std::memcpy(im.row(static_cast<int>(y)), data + static_cast<std::size_t>(y) * step, row);
  if (stamp_ns) *stamp_ns = t;
  return im;
}

Expected<CompressedImage> decode_compressed_image(const std::vector<std::uint8_t>& msg) {
  CdrReader r(msg.data(), msg.size());
  CompressedImage c;
  c.t_ns = read_header(r, &c.frame_id);
  c.format = r.string();
  std::size_t n = 0;
  const std::uint8_t* data = r.bytes(n);
  if (!r.ok()) return bad("sensor_msgs/msg/CompressedImage");
  c.data.assign(data, data + n);
  return c;
}

Expected<CompressedImage> decode_compressed_video(const std::vector<std::uint8_t>& msg) {
  CdrReader r(msg.data(), msg.size());
  CompressedImage c;
  c.t_ns = read_header(r, &c.frame_id);
  std::size_t n = 0;
  const std::uint8_t* data = r.bytes(n);
  if (r.ok()) c.data.assign(data, data + n);
  c.format = r.string();
  if (!r.ok()) return bad("foxglove_msgs/msg/CompressedVideo");
  return c;
}

Expected<Pose> decode_pose_with_covariance(const std::vector<std::uint8_t>& msg) {
  CdrReader r(msg.data(), msg.size());
  read_header(r);
  const Pose p = read_pose(r);
  for (int i = 0; i < 36; ++i) r.f64();
  if (!r.ok()) return bad("geometry_msgs/msg/PoseWithCovarianceStamped");
  return p;
}

Expected<std::vector<Transform>> decode_tf_message(const std::vector<std::uint8_t>& msg) {
  CdrReader r(msg.data(), msg.size());
  const std::uint32_t n = r.u32();
  std::vector<Transform> out;
  // Each transform takes at least 70 bytes: a count beyond the message is damage, not a size to reserve.
  if (!r.ok() || n > msg.size() / 70) return bad("tf2_msgs/msg/TFMessage");
  for (std::uint32_t i = 0; i < n && r.ok(); ++i) {
    Transform t;
    t.t_ns = read_header(r, &t.parent);
    t.child = r.string();
    t.T_parent_child = read_pose(r);
    out.push_back(std::move(t));
  }
  if (!r.ok()) return bad("tf2_msgs/msg/TFMessage");
  return out;
}

Expected<OcclusionStats> decode_occlusion_stats(const std::vector<std::uint8_t>& msg) {
  CdrReader r(msg.data(), msg.size());
  read_header(r);
  OcclusionStats s;
  s.t_ns = r.i64();
  s.width = r.i64();
  s.height = r.i64();
  s.receiver_px_left = r.i64();
  s.receiver_px_right = r.i64();
  s.boom_px_left = r.i64();
  s.boom_px_right = r.i64();
  s.boom_overlap_px = r.i64();
  s.boom_overlap_pct_union = r.f64();
  s.occluded_px_left = r.i64();
  s.occluded_px_right = r.i64();
  s.occluded_pct_left = r.f64();
  s.occluded_pct_right = r.f64();
  s.stereo_both_px = r.i64();
  s.left_only_px = r.i64();
  s.right_only_px = r.i64();
  s.neither_px = r.i64();
  s.receiver_pct_left = r.f64();
  s.receiver_pct_right = r.f64();
  s.boom_pct_left = r.f64();
  s.boom_pct_right = r.f64();
  // A message written before the shadow fields were appended ends here (but for padding to 4
  // bytes): its shadow reads 0.
  if (r.ok() && r.remaining() >= 4) {
    s.shadow_px_left = r.i64();
    s.shadow_px_right = r.i64();
    s.shadow_pct_left = r.f64();
    s.shadow_pct_right = r.f64();
  }
  if (!r.ok()) return bad("augrig_msgs/msg/OcclusionStats");
  return s;
}

Expected<StereoFrameInfo> decode_stereo_frame_info(const std::vector<std::uint8_t>& msg) {
  CdrReader r(msg.data(), msg.size());
  read_header(r);
  StereoFrameInfo info;
  info.index = r.u64();
  info.pair_sequence = r.u64();
  info.t_key_ns = r.i64();
  info.skew_ns = r.i64();
  info.left = read_camera_frame_info(r);
  info.right = read_camera_frame_info(r);
  info.receiver_present = r.i8();
  const bool has_boom = r.boolean();
  BoomArticulation b;
  b.elevation_rad = r.f64();
  b.azimuth_rad = r.f64();
  b.extension_m = r.f64();
  if (has_boom) info.boom = b;
  info.sigma_pos_m = r.f64();
  info.sigma_att_deg = r.f64();
  if (!r.ok()) return bad("augrig_msgs/msg/StereoFrameInfo");
  return info;
}

Expected<std::vector<DiagnosticStatus>> decode_diagnostic_array(const std::vector<std::uint8_t>& msg,
                                                                std::int64_t* stamp_ns) {
  CdrReader r(msg.data(), msg.size());
  const std::int64_t t = read_header(r);
  const std::uint32_t n = r.u32();
  // A status takes at least 21 bytes: a count beyond the message is damage, not a size to reserve.
  if (!r.ok() || n > msg.size() / 21) return bad("diagnostic_msgs/msg/DiagnosticArray");
  std::vector<DiagnosticStatus> out;
  for (std::uint32_t i = 0; i < n && r.ok(); ++i) {
    DiagnosticStatus s;
    s.level = r.u8();
    s.name = r.string();
    s.message = r.string();
    s.hardware_id = r.string();
    const std::uint32_t k = r.u32();
    if (k > msg.size() / 10) return bad("diagnostic_msgs/msg/DiagnosticArray");
    for (std::uint32_t j = 0; j < k && r.ok(); ++j) {
      std::string key = r.string();
      s.values.emplace_back(std::move(key), r.string());
    }
    out.push_back(std::move(s));
  }
  if (!r.ok()) return bad("diagnostic_msgs/msg/DiagnosticArray");
  if (stamp_ns) *stamp_ns = t;
  return out;
}

}  // namespace augrig::ros2
