// ros2/messages.hpp, the parts the MCAP tests (mcap_writer_test.cpp, app/cmd_export_mcap_test.cpp)
// do not reach: diagnostic_msgs/msg/DiagnosticArray, the live view's health topic. Its schema is
// ROS 2 Humble's definition with its dependencies; its CDR round-trips field for field; damaged
// messages are errors. augrig_msgs/msg/OcclusionStats with its appended shadow fields, and a message
// written before them read with the shadow 0. A pose covariance from sigmas. tests/net/foxglove_server_test.cpp decodes it with
// @foxglove/rosmsg2-serialization.
#include "ros2/messages.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>

namespace augrig::ros2 {
namespace {

TEST(Ros2Msgs, OcclusionStatsRoundTripsWithTheShadowAppended) {
  const std::string text = schema_text("augrig_msgs/msg/OcclusionStats");
  const std::string tail = "float64 boom_pct_right\n"
                           "# Appended: the boom's shadow on the receiver (mask bit 2). A message without them reads 0.\n"
                           "int64 shadow_px_left\nint64 shadow_px_right\nfloat64 shadow_pct_left\nfloat64 shadow_pct_right\n";
  const std::string own = text.substr(0, text.find(std::string(80, '=')));
  ASSERT_GE(own.size(), tail.size());
  EXPECT_EQ(own.substr(own.size() - tail.size()), tail) << text;

  OcclusionStats s;
  s.t_ns = 1'700'000'000'000'000'123;
  s.width = 1280;
  s.height = 960;
  s.receiver_px_left = 51234;
  s.boom_px_right = 777;
  s.boom_overlap_pct_union = 100.0 / 3.0;
  s.neither_px = 12;
  s.boom_pct_right = 0.625;
  s.shadow_px_left = 4321;
  s.shadow_px_right = 4000;
  s.shadow_pct_left = std::nextafter(8.4, 9.0);
  s.shadow_pct_right = 7.75;
  const std::vector<std::uint8_t> msg = occlusion_stats(s.t_ns, s);
  auto back = decode_occlusion_stats(msg);
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(*back, s);

  // A message written before the shadow fields (32 bytes: two int64, two float64) reads with them 0,
  // padded to 4 bytes or not; any other cut is damage.
  const std::size_t old_size = msg.size() - 32;
  OcclusionStats before = s;
  before.shadow_px_left = before.shadow_px_right = 0;
  before.shadow_pct_left = before.shadow_pct_right = 0;
  for (std::size_t len = 0; len < msg.size(); ++len) {
    auto cut = decode_occlusion_stats(std::vector<std::uint8_t>(msg.begin(), msg.begin() + static_cast<std::ptrdiff_t>(len)));
    if (len >= old_size && len < old_size + 4) {
      ASSERT_TRUE(cut) << len << ": " << cut.error().message;
      EXPECT_EQ(*cut, before) << len;
    } else {
      ASSERT_FALSE(cut) << len;
      EXPECT_EQ(cut.error().message, "augrig_msgs/msg/OcclusionStats: the message is shorter than its fields (damaged)");
    }
  }
}

TEST(Ros2Msgs, DiagnosticArraySchemaNamesItsDependencies) {
  const std::string text = schema_text("diagnostic_msgs/msg/DiagnosticArray");
  ASSERT_FALSE(text.empty());
  EXPECT_EQ(text.rfind("std_msgs/Header header\ndiagnostic_msgs/DiagnosticStatus[] status\n", 0), 0u) << text;
  const std::string sep = std::string(80, '=') + "\nMSG: ";
  for (const char* dep : {"std_msgs/Header", "builtin_interfaces/Time", "diagnostic_msgs/DiagnosticStatus",
                          "diagnostic_msgs/KeyValue"})
    EXPECT_NE(text.find(sep + dep + "\n"), std::string::npos) << dep;
  EXPECT_NE(text.find("byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\n"), std::string::npos);
  const auto& types = known_types();
  EXPECT_NE(std::find(types.begin(), types.end(), "diagnostic_msgs/msg/DiagnosticArray"), types.end());
}

// sensor_msgs/msg/CompressedImage in CDR, byte by byte as ROS 2 lays it out (header, format
// string with its NUL, uint8[] with its count), and back.
TEST(Ros2Msgs, CompressedImageLayoutAndRoundTrip) {
  const std::vector<std::uint8_t> jpeg = {0xff, 0xd8, 0xff, 0xe0, 1, 2, 3};
  const std::vector<std::uint8_t> msg = compressed_image(3'000'000'007, "left_camera", "jpeg", jpeg);
  // Encapsulation (4), sec, nanosec, "left_camera\0" (4 + 12), "jpeg\0" at 4-byte alignment (4 + 5),
  // then the count at the next 4-byte boundary and the bytes.
  ASSERT_EQ(msg.size(), 4u + 8 + 16 + 9 + 3 + 4 + jpeg.size());
  EXPECT_EQ(msg[8], 7);  // nanosec, little endian
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(&msg[32]), 4), "jpeg");
  EXPECT_EQ(msg[40], jpeg.size());
  EXPECT_TRUE(std::equal(jpeg.begin(), jpeg.end(), msg.end() - static_cast<std::ptrdiff_t>(jpeg.size())));
  auto back = decode_compressed_image(msg);
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(back->t_ns, 3'000'000'007);
  EXPECT_EQ(back->frame_id, "left_camera");
  EXPECT_EQ(back->format, "jpeg");
  EXPECT_EQ(back->data, jpeg);
  std::vector<std::uint8_t> cut(msg.begin(), msg.end() - 2);
  auto bad = decode_compressed_image(cut);
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().message, "sensor_msgs/msg/CompressedImage: the message is shorter than its fields (damaged)");
  EXPECT_EQ(schema_text("sensor_msgs/msg/CompressedImage").rfind("std_msgs/Header header\nstring format\nuint8[] data\n", 0),
            0u);
}

// foxglove_msgs/msg/CompressedVideo: timestamp, frame_id, data, then format (Foxglove's field order).
TEST(Ros2Msgs, CompressedVideoLayoutAndRoundTrip) {
  const std::vector<std::uint8_t> unit = {0, 0, 0, 1, 0x67, 9, 9};
  const std::vector<std::uint8_t> msg = compressed_video(5'000'000'011, "right_camera", "h264", unit);
  // Encapsulation (4), sec, nanosec (8), "right_camera\0" (4 + 13), pad to 4 (3), count (4) and the
  // 7 bytes, pad (1), "h264\0" (4 + 5).
  ASSERT_EQ(msg.size(), 4u + 8 + 17 + 3 + 4 + 7 + 1 + 9);
  EXPECT_EQ(msg[8], 11);
  EXPECT_EQ(msg[32], unit.size());
  EXPECT_EQ(msg[36 + 4], 0x67);
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(&msg[48]), 4), "h264");
  auto back = decode_compressed_video(msg);
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(back->t_ns, 5'000'000'011);
  EXPECT_EQ(back->frame_id, "right_camera");
  EXPECT_EQ(back->format, "h264");
  EXPECT_EQ(back->data, unit);
  std::vector<std::uint8_t> cut(msg.begin(), msg.end() - 3);
  auto bad = decode_compressed_video(cut);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("foxglove_msgs/msg/CompressedVideo"), std::string::npos);
  EXPECT_EQ(schema_text("foxglove_msgs/msg/CompressedVideo"),
            "builtin_interfaces/Time timestamp\nstring frame_id\nuint8[] data\nstring format\n" +
                std::string(80, '=') + "\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n");
}

TEST(Ros2Msgs, DiagnosticArrayRoundTrips) {
  DiagnosticStatus a;
  a.level = DiagnosticStatus::kWarn;
  a.name = "augrig pipeline";
  a.message = "left camera lost 0.6 s ago, reconnecting";
  a.hardware_id = "augrig";
  a.values = {{"drops.capture", "3"}, {"fps", "29.9"}};
  DiagnosticStatus b;
  b.level = DiagnosticStatus::kOk;
  b.name = "x";
  const std::vector<std::uint8_t> msg = diagnostic_array(1'700'000'000'123'456'789, {a, b});
  std::int64_t stamp = 0;
  auto back = decode_diagnostic_array(msg, &stamp);
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(stamp, 1'700'000'000'123'456'789);
  ASSERT_EQ(back->size(), 2u);
  EXPECT_EQ((*back)[0].level, DiagnosticStatus::kWarn);
  EXPECT_EQ((*back)[0].name, a.name);
  EXPECT_EQ((*back)[0].message, a.message);
  EXPECT_EQ((*back)[0].hardware_id, a.hardware_id);
  EXPECT_EQ((*back)[0].values, a.values);
  EXPECT_EQ((*back)[1].name, "x");
  EXPECT_TRUE((*back)[1].values.empty());
  // Every truncation is an error, never a crash or a partial result.
  for (std::size_t len = 0; len < msg.size(); ++len) {
    auto cut = decode_diagnostic_array(
        std::vector<std::uint8_t>(msg.begin(), msg.begin() + static_cast<std::ptrdiff_t>(len)));
    EXPECT_FALSE(cut) << len;
  }
}

TEST(Ros2Msgs, PoseCovarianceFromSigmas) {
  const std::array<double, 36> c = pose_covariance(0.2, 1.5);
  const double att_rad = 1.5 * std::numbers::pi / 180.0;
  for (std::size_t r = 0; r < 6; ++r)
    for (std::size_t k = 0; k < 6; ++k) {
      const double want = r != k ? 0.0 : r < 3 ? 0.2 * 0.2 : att_rad * att_rad;
      EXPECT_NEAR(c[6 * r + k], want, 1e-15) << r << "," << k;
    }
  // Unknown sigmas stay 0 (ROS has no "unknown"), each on its own.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::array<double, 36> u = pose_covariance(nan, 2.0);
  EXPECT_EQ(u[0], 0.0);
  EXPECT_EQ(u[14], 0.0);
  EXPECT_GT(u[21], 0.0);
  EXPECT_EQ(pose_covariance(0.1, nan)[35], 0.0);
  EXPECT_DOUBLE_EQ(pose_covariance(0.1, nan)[7], 0.01);
}

}  // namespace
}  // namespace augrig::ros2
