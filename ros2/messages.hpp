// ROS 2 messages in CDR for the MCAP export (docs/MCAP.md): the serialisation (XCDR1, little
// endian, the 4-byte encapsulation header 00 01 00 00, each primitive aligned to its size counted
// from the end of that header), the ros2msg schema texts (the type's .msg definition, then each
// type it uses after a line of 80 '=' and "MSG: pkg/Type", as rosbag2 stores them), and the few
// messages augrig writes and reads back: sensor_msgs Image, CameraInfo, Imu, NavSatFix;
// geometry_msgs PoseWithCovarianceStamped; tf2_msgs TFMessage; diagnostic_msgs DiagnosticArray (the
// live view's health, net/foxglove_server.hpp); augrig_msgs StereoFrameInfo and OcclusionStats (our own).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/expected.hpp"
#include "core/frame.hpp"
#include "core/image.hpp"
#include "core/pose.hpp"
#include "render/camera_model.hpp"
#include "render/models.hpp"
#include "render/stats.hpp"

namespace augrig::ros2 {

// Appends CDR fields to a message that starts with the encapsulation header.
class CdrWriter {
 public:
  CdrWriter() : b_{0x00, 0x01, 0x00, 0x00} {}
  void u8(std::uint8_t v) { b_.push_back(v); }
  void i8(std::int8_t v) { b_.push_back(static_cast<std::uint8_t>(v)); }
  void boolean(bool v) { u8(v ? 1 : 0); }
  void u16(std::uint16_t v) { le(v, 2); }
  void u32(std::uint32_t v) { le(v, 4); }
  void i32(std::int32_t v) { le(static_cast<std::uint32_t>(v), 4); }
  void u64(std::uint64_t v) { le(v, 8); }
  void i64(std::int64_t v) { le(static_cast<std::uint64_t>(v), 8); }
  void f64(double v);
  void string(const std::string& s);                 // uint32 length with the NUL, the bytes, NUL
  void bytes(const std::uint8_t* p, std::size_t n);  // uint8[]: uint32 count, the bytes
  void f64_array(const double* v, std::size_t n);    // float64[N]: the values, no count
  void f64_sequence(const std::vector<double>& v);   // float64[]: uint32 count, the values
  std::vector<std::uint8_t>& data() { return b_; }

 private:
  void align(std::size_t n) {
    while ((b_.size() - 4) % n) b_.push_back(0);
  }
  void le(std::uint64_t v, int n) {
    align(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) b_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  std::vector<std::uint8_t> b_;
};

// Reads CDR fields; a read past the end clears ok() and returns zeros.
class CdrReader {
 public:
  // Checks the encapsulation header (CDR little endian); !ok() otherwise.
  CdrReader(const std::uint8_t* p, std::size_t n);
  bool ok() const { return ok_; }
  // Bytes not read yet: a message that ends before fields appended to its type later has none
  // (or, padded to 4 bytes by a ROS 2 writer, fewer than 4).
  std::size_t remaining() const { return i_ < n_ ? n_ - i_ : 0; }
  std::uint8_t u8() { return static_cast<std::uint8_t>(le(1)); }
  std::int8_t i8() { return static_cast<std::int8_t>(le(1)); }
  bool boolean() { return u8() != 0; }
  std::uint32_t u32() { return static_cast<std::uint32_t>(le(4)); }
  std::int32_t i32() { return static_cast<std::int32_t>(static_cast<std::uint32_t>(le(4))); }
  std::uint64_t u64() { return le(8); }
  std::int64_t i64() { return static_cast<std::int64_t>(le(8)); }
  double f64();
  std::string string();
  // uint8[]: the count and a pointer to the bytes inside the message (nullptr when damaged).
  const std::uint8_t* bytes(std::size_t& n);

 private:
  std::uint64_t le(int n);
  const std::uint8_t* p_;
  std::size_t n_, i_ = 4;
  bool ok_ = true;
};

// The ros2msg schema text of `type` ("sensor_msgs/msg/Image", ...; every type this header writes)
// with its dependencies; empty for a type it does not know.
std::string schema_text(const std::string& type);
// The types this module writes, in the order an export adds them.
const std::vector<std::string>& known_types();

// ROS 2 Image encodings (sensor_msgs/image_encodings.hpp): mono8, rgb8, rgba8, bayer_rggb8, ...
std::string image_encoding(PixelFormat format);
bool parse_image_encoding(const std::string& encoding, PixelFormat& out);
// CameraInfo distortion_model names: plumb_bob (k1 k2 p1 p2 k3), equidistant (k1..k4).
std::string distortion_model_name(DistortionModel d);

// builtin_interfaces/Time from nanoseconds: an Error for t < 0 or past int32 seconds.
Status check_stamp(std::int64_t t_ns);

std::vector<std::uint8_t> image(std::int64_t t_ns, const std::string& frame_id, ConstImageView im);
// sensor_msgs/msg/CompressedImage: `format` as image_transport names it ("jpeg"), `data` the file's bytes.
std::vector<std::uint8_t> compressed_image(std::int64_t t_ns, const std::string& frame_id, const std::string& format,
                                           const std::vector<std::uint8_t>& data);
// foxglove_msgs/msg/CompressedVideo: one frame's access unit (`format` "h264": Annex B, a keyframe
// with its SPS and PPS; render/video_codec.hpp).
std::vector<std::uint8_t> compressed_video(std::int64_t t_ns, const std::string& frame_id, const std::string& format,
                                           const std::vector<std::uint8_t>& data);
std::vector<std::uint8_t> camera_info(std::int64_t t_ns, const std::string& frame_id, const CameraModel& cm);

struct Transform {
  std::int64_t t_ns = 0;
  std::string parent, child;
  Pose T_parent_child;
};
std::vector<std::uint8_t> tf_message(const std::vector<Transform>& transforms);
// covariance: 6x6 row-major over (x, y, z, rotation about x, y, z), m^2 and rad^2.
std::vector<std::uint8_t> pose_with_covariance(std::int64_t t_ns, const std::string& frame_id,
                                               const Pose& pose, const std::array<double, 36>& covariance);
// A pose covariance from the 1-sigmas of position (each axis) and attitude (each rotation), no
// correlations. Unknown sigmas (NaN) give 0: ROS has no "unknown" for a pose covariance.
std::array<double, 36> pose_covariance(double sigma_pos_m, double sigma_att_deg);
// Orientation unknown (covariance[0] = -1, as sensor_msgs/Imu says).
std::vector<std::uint8_t> imu(std::int64_t t_ns, const std::string& frame_id, const Eigen::Vector3d& w_rad_s,
                              const Eigen::Vector3d& a_mps2);
// status: -1 no fix, 0 fix, 1 SBAS, 2 GBAS (RTK); position_covariance diagonal from sigmas when > 0.
std::vector<std::uint8_t> nav_sat_fix(std::int64_t t_ns, const std::string& frame_id, int status,
                                      double lat_deg, double lon_deg, double alt_m,
                                      const Eigen::Vector3d& sigma_enu_m);
std::vector<std::uint8_t> occlusion_stats(std::int64_t stamp_ns, const OcclusionStats& s);

// What augrig_msgs/msg/StereoFrameInfo carries: a recorded stereo frame's pairing and scene.
struct CameraFrameInfo {
  std::uint64_t sequence = 0;
  std::int64_t t_ns = 0, t_host_ns = 0, exposure_ns = 0;
  std::string clock;         // core/conventions.hpp names: device, gps, sim, ...
  std::string pixel_format;  // PFNC: BayerRG8, Mono8, RGB8, RGBA8
  std::int32_t width = 0, height = 0;
};
struct StereoFrameInfo {
  std::uint64_t index = 0, pair_sequence = 0;
  std::int64_t t_key_ns = 0, skew_ns = 0;
  CameraFrameInfo left, right;
  std::int8_t receiver_present = -1;  // 1 yes, 0 no, -1 not recorded
  std::optional<BoomArticulation> boom;
  double sigma_pos_m = 0, sigma_att_deg = 0;  // NaN: unknown
};
std::vector<std::uint8_t> stereo_frame_info(std::int64_t stamp_ns, const StereoFrameInfo& info);
// The pairing part of a stereo frame's info (index, sequences, times, skew, clocks, formats, sizes);
// the caller adds the scene's (presence, boom, sigmas).
StereoFrameInfo stereo_frame_info_of(const StereoFrame& raw, std::uint64_t index);

// diagnostic_msgs/msg/DiagnosticStatus: the health of one part, in plain words. The standard type
// rather than an augrig_msgs one, so that Foxglove's Diagnostics panels and ROS 2's tools
// (rqt_runtime_monitor, the diagnostic aggregator) show it without our schema being built.
struct DiagnosticStatus {
  static constexpr std::uint8_t kOk = 0, kWarn = 1, kError = 2, kStale = 3;
  std::uint8_t level = kOk;
  std::string name, message, hardware_id;
  std::vector<std::pair<std::string, std::string>> values;  // KeyValue[]: key, value
};
std::vector<std::uint8_t> diagnostic_array(std::int64_t t_ns, const std::vector<DiagnosticStatus>& status);

// Decoders of what McapSource reads back; an Error says what is wrong with the message.
Expected<Image> decode_image(const std::vector<std::uint8_t>& msg, std::int64_t* stamp_ns = nullptr);
struct CompressedImage {
  std::int64_t t_ns = 0;
  std::string frame_id, format;
  std::vector<std::uint8_t> data;
};
Expected<CompressedImage> decode_compressed_image(const std::vector<std::uint8_t>& msg);
// foxglove_msgs/msg/CompressedVideo, in the same struct (its timestamp as t_ns).
Expected<CompressedImage> decode_compressed_video(const std::vector<std::uint8_t>& msg);
Expected<Pose> decode_pose_with_covariance(const std::vector<std::uint8_t>& msg);
Expected<std::vector<Transform>> decode_tf_message(const std::vector<std::uint8_t>& msg);
Expected<OcclusionStats> decode_occlusion_stats(const std::vector<std::uint8_t>& msg);
Expected<StereoFrameInfo> decode_stereo_frame_info(const std::vector<std::uint8_t>& msg);
Expected<std::vector<DiagnosticStatus>> decode_diagnostic_array(const std::vector<std::uint8_t>& msg,
                                                                std::int64_t* stamp_ns = nullptr);

}  // namespace augrig::ros2
