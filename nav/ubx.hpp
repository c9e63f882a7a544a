// ubx: u-blox UBX binary messages from log files and live byte streams (serial, UDP): the frame and
// the two navigation messages a moving-baseline RTK set-up gives (docs/NAV_FORMATS.md, "UBX"):
//
//   frame         0xB5 0x62, class, id, payload length (uint16 little endian), payload, CK_A CK_B:
//                 the 8-bit Fletcher checksum over class, id, length and payload
//   NAV-PVT       class 0x01 id 0x07, 92 bytes: the receiver's absolute fix (WGS-84 position and
//                 NED velocity with accuracies, fix type, carrier solution) with its GPS time of
//                 week and UTC date and time (so GPS - UTC, the leap seconds, can be read off)
//   NAV-RELPOSNED class 0x01 id 0x3C, 40 bytes (version 0, M8P) or 64 (version 1, F9P): the vector
//                 from the base (moving-base) receiver's antenna to this receiver's antenna, NED,
//                 in cm plus 0.1 mm, with 1-sigma accuracies and flags (relPosValid, carrier
//                 solution none/float/fixed, moving base, reference position/observations missed)
//
// UbxStream takes bytes as they arrive, in any chunks, and yields whole frames. Bytes between
// frames, frames whose checksum fails and lengths beyond the limit are counted and skipped by
// searching for the next sync pair after the bad one (a damaged frame never swallows the good frame
// after it); nothing throws. Every count a reader shows adds up: bytes read = bytes in frames +
// bytes skipped + bytes pending at the end.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "core/expected.hpp"
#include "nav/types.hpp"

namespace augrig::nav {

inline constexpr std::uint8_t kUbxSync1 = 0xB5, kUbxSync2 = 0x62;
inline constexpr std::uint8_t kUbxClassNav = 0x01, kUbxIdNavPvt = 0x07, kUbxIdNavRelPosNed = 0x3C;
inline constexpr std::size_t kUbxNavPvtLength = 92, kUbxRelPosNedLengthV0 = 40, kUbxRelPosNedLengthV1 = 64;

struct UbxFrame {
  std::uint8_t cls = 0, id = 0;
  std::vector<std::uint8_t> payload;
  std::uint64_t offset = 0;  // of its first sync byte in the stream
};

// CK_A, CK_B over `n` bytes (class, id, length and payload).
std::pair<std::uint8_t, std::uint8_t> ubx_checksum(const std::uint8_t* p, std::size_t n);
// A whole frame: sync, header, payload, checksum.
std::vector<std::uint8_t> encode_ubx(std::uint8_t cls, std::uint8_t id,
                                     const std::vector<std::uint8_t>& payload);

// UBX-NAV-PVT, in SI units (the message's own scaling undone).
struct UbxNavPvt {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  std::uint32_t itow_ms = 0;  // GPS time of week of the navigation epoch, ms
  int year = 0, month = 0, day = 0, hour = 0, minute = 0, second = 0;  // UTC
  std::int32_t nano_ns = 0;  // fraction of the UTC second, -1e9..1e9 ns
  bool valid_date = false, valid_time = false, fully_resolved = false;
  std::uint32_t time_accuracy_ns = 0;
  int fix_type = 0;  // 0 none, 1 dead reckoning, 2 2D, 3 3D, 4 GNSS + DR, 5 time only
  bool gnss_fix_ok = false, diff_soln = false;
  int carr_soln = 0;  // 0 none, 1 float, 2 fixed
  int satellites = 0;
  double lat_deg = 0, lon_deg = 0, height_m = 0, height_msl_m = 0;  // height: above the ellipsoid
  double h_acc_m = kNaN, v_acc_m = kNaN;                            // 1-sigma
  Eigen::Vector3d vel_ned_mps = Eigen::Vector3d::Zero();
  double speed_acc_mps = kNaN;
  double pdop = 0;
};

// UBX-NAV-RELPOSNED (version 0 or 1), in SI units; the cm and 0.1 mm parts summed.
struct UbxRelPosNed {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  int version = 1;
  int ref_station_id = 0;
  std::uint32_t itow_ms = 0;
  Eigen::Vector3d rel_pos_ned_m = Eigen::Vector3d::Zero();      // base antenna -> this antenna
  double length_m = kNaN, heading_deg = kNaN;                   // version 1 only
  Eigen::Vector3d acc_ned_m = Eigen::Vector3d::Constant(kNaN);  // 1-sigma
  double acc_length_m = kNaN, acc_heading_deg = kNaN;           // version 1 only
  bool gnss_fix_ok = false, diff_soln = false, rel_pos_valid = false;
  int carr_soln = 0;  // 0 none, 1 float, 2 fixed
  bool is_moving = false, ref_pos_miss = false, ref_obs_miss = false;
  bool heading_valid = false, normalized = false;  // version 1 only
};

// Decoding checks the class, id and length (and RELPOSNED's version against its length); errors
// say which and what was expected.
Expected<UbxNavPvt> decode_nav_pvt(const UbxFrame& f);
Expected<UbxRelPosNed> decode_nav_relposned(const UbxFrame& f);
// Whole frames (the simulator's logs, the tests); values out of the message's range are clamped
// to it. A RELPOSNED of version 0 leaves out what only version 1 has.
std::vector<std::uint8_t> encode_nav_pvt(const UbxNavPvt& m);
std::vector<std::uint8_t> encode_nav_relposned(const UbxRelPosNed& m);

struct UbxStreamCounts {
  std::uint64_t bytes = 0;          // pushed
  std::uint64_t frames = 0;         // whole frames with a good checksum
  std::uint64_t frame_bytes = 0;    // their bytes (sync to checksum)
  std::uint64_t skipped_bytes = 0;  // garbage, and the first byte of each bad frame
  std::uint64_t bad_checksums = 0;  // frames whose checksum failed
  std::uint64_t oversized = 0;      // headers announcing more than max_payload bytes
};

class UbxStream {
 public:
  // `name` is used in messages ("tanker.ubx: offset 1234: bad checksum ...").
  explicit UbxStream(std::string name, std::size_t max_payload = 8192);
  void push(const std::uint8_t* data, std::size_t n);
  // The next whole frame, if one has arrived.
  std::optional<UbxFrame> next();
  const UbxStreamCounts& counts() const { return counts_; }
  // Bytes held waiting for the rest of a frame (at the end of a log: a truncated frame).
  std::size_t pending_bytes() const { return buffer_.size() - start_; }
  // What was skipped and why, "NAME: offset N: ..." (the first max_messages; the counts stay exact).
  const std::vector<std::string>& messages() const { return messages_; }

 private:
  void note(std::uint64_t offset, const std::string& what);
  std::string name_;
  std::size_t max_payload_;
  std::vector<std::uint8_t> buffer_;
  std::size_t start_ = 0;            // first unconsumed byte in buffer_
  std::uint64_t buffer_offset_ = 0;  // stream offset of buffer_[0]
  UbxStreamCounts counts_;
  std::vector<std::string> messages_;
};

// A UBX log file: its NAV-PVT and NAV-RELPOSNED messages in file order, the frames of other types
// counted by (class, id), and what was skipped (LogIssues: "FILE: offset N: ..."; malformed =
// bad frames and messages that failed to decode).
struct UbxLog {
  std::vector<UbxNavPvt> pvt;
  std::vector<UbxRelPosNed> relposned;
  std::map<std::pair<int, int>, std::size_t> other_frames;
  UbxStreamCounts counts;
  std::size_t truncated_bytes = 0;  // a frame cut off at the end of the file
  LogIssues issues;
};
// Errors: the file cannot be read; it holds bytes but no UBX frame at all (not a UBX log).
Expected<UbxLog> read_ubx_file(const std::string& path);

}  // namespace augrig::nav
