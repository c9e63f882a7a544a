// augrig export --format mcap and augrig replay OUT.mcap through the real binary (docs/MCAP.md), on
// a simulated run's recording: independent readers from npm (@mcap/core's indexed and streaming
// readers, @foxglove/rosmsg2-serialization with @foxglove/rosmsg; tests/support/mcap_check.mjs)
// validate the file and decode every message, and what they decode equals the recording read
// through recorder::RecordingReader; the replay of the MCAP file gives the recorded raw frames and
// poses back bit for bit and reproduces the recorded statistics; damaged files fail clearly.
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "recorder/mcap_source.hpp"
#include "recorder/reader.hpp"
#include "ros2/messages.hpp"
#include "render/rig.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// One simulated run recorded and exported per test process.
struct Exported {
  std::string dir, rec, mcap;
};
const Exported& exported() {
  static const Exported e = [] {
    Exported x;
    x.dir = test::output_dir(std::string("cmd_export_mcap_") +
                             testing::UnitTest::GetInstance()->current_test_info()->name());
    x.rec = x.dir + "/rec";
    x.mcap = x.dir + "/out.mcap";
    std::string log;
    EXPECT_EQ(test::run_augrig("run --source 'sim://demo?every=60&rate=0' --frames 3 --headless --status-every 0 "
                               "--record " + x.rec + " 2>&1",
                               &log),
              0)
        << log;
    EXPECT_EQ(test::run_augrig("export " + x.rec + " --format mcap " + x.mcap + " 2>&1", &log), 0) << log;
    EXPECT_NE(log.find("Exported 3 of 3 stereo frame(s) to " + x.mcap), std::string::npos) << log;
    EXPECT_FALSE(fs::exists(x.mcap + ".part"));
    return x;
  }();
  return e;
}

// FNV-1a 32 of an image's rows packed tight (as mcap_check.mjs hashes a message's data).
std::uint32_t fnv1a(const Image& im) {
  std::uint32_t h = 0x811c9dc5u;
  const std::size_t row = static_cast<std::size_t>(im.width()) * static_cast<std::size_t>(bytes_per_pixel(im.format()));
  for (int y = 0; y < im.height(); ++y)
    for (std::size_t x = 0; x < row; ++x) h = (h ^ im.row(y)[x]) * 0x01000193u;
  return h;
}

// The npm packages, installed once into build/test-output/npm-mcap (kept between runs), with
// mcap_check.mjs copied next to them; "" and `why` set when node or npm cannot provide them.
std::string mcap_checker(std::string* why) {
  return test::npm_script("mcap", {"@mcap/core@2", "@foxglove/rosmsg2-serialization@3", "@foxglove/rosmsg@5", "fzstd@0.1"},
                          "mcap_check.mjs", why);
}

TEST(CmdExportMcap, IndependentReadersValidateItAndDecodeTheRecording) {
  const Exported& e = exported();
  std::string why;
  const std::string checker = mcap_checker(&why);
  if (checker.empty()) GTEST_SKIP() << "no independent MCAP readers: " << why;
  std::string out;
  ASSERT_EQ(test::run_command("node " + checker + " " + e.mcap, &out), 0) << out;
  const json j = json::parse(out);
  ASSERT_TRUE(j["ok"].get<bool>()) << j["errors"].dump();
  EXPECT_EQ(j["profile"], "ros2");
  EXPECT_TRUE(j["stream_done"].get<bool>());
  EXPECT_TRUE(j["stream_matches_indexed"].get<bool>());
  EXPECT_EQ(j["chunk_compression"], json::array({"zstd"}));
  EXPECT_GE(j["chunk_indexes"].get<int>(), 2);  // 4 MiB chunks, 1280x960 RGB images
  EXPECT_EQ(j["message_indexed_chunks"], j["chunk_indexes"]);
  EXPECT_EQ(j["summary_offset_opcodes"], json::array({3, 4, 8, 11, 13}));
  EXPECT_GE(j["stream_records"]["MessageIndex"].get<int>(), j["chunk_indexes"].get<int>());
  EXPECT_EQ(j["statistics"]["message_count"], std::to_string(j["stream_records"]["Message"].get<int>()));
  EXPECT_EQ(j["metadata"][0]["name"], recorder::kMcapRecordingMetadata);
  for (const auto& [topic, ch] : j["channels"].items()) {
    EXPECT_EQ(ch["message_encoding"], "cdr") << topic;
    EXPECT_NE(ch["qos"].get<std::string>().find("reliability: 1"), std::string::npos) << topic;
  }
  EXPECT_NE(j["channels"]["/tf_static"]["qos"].get<std::string>().find("durability: 1"), std::string::npos);
  for (const auto& [type, s] : j["schemas"].items()) {
    EXPECT_EQ(s["encoding"], "ros2msg");
    EXPECT_EQ(s["text"], ros2::schema_text(type)) << type;
  }
  EXPECT_EQ(j["channels"]["/augrig/occlusion_stats"]["type"], "augrig_msgs/msg/OcclusionStats");

  auto reader = recorder::RecordingReader::open(e.rec);
  ASSERT_TRUE(reader) << reader.error().message;
  const Rig rig = *parse_rig((*reader)->meta("rig_yaml"), "rig");
  const auto& topics = j["topics"];
  ASSERT_EQ((*reader)->frame_count(), 3u);
  const auto& statics = topics["/tf_static"]["messages"];
  ASSERT_EQ(statics.size(), 1u);
  for (std::size_t i = 0; i < 3; ++i) {
    auto f = (*reader)->read_frame(i);
    ASSERT_TRUE(f) << f.error().message;
    const std::string t_key = std::to_string(f->raw.t_key_ns);
    for (int c = 0; c < 2; ++c) {
      const std::string cam = c == 0 ? "/left" : "/right";
      const Frame& fr = c == 0 ? f->raw.left : f->raw.right;
      const std::string t = std::to_string(fr.t_ns);
      const auto& raw = topics[cam + "/image_raw"]["messages"][i];
      EXPECT_EQ(raw["log_time"], t);
      EXPECT_EQ(raw["stamp_ns"], t);
      EXPECT_EQ(raw["frame_id"], c == 0 ? "left_camera" : "right_camera");
      EXPECT_EQ(raw["encoding"], ros2::image_encoding(fr.image.format()));
      EXPECT_EQ(raw["width"], fr.image.width());
      EXPECT_EQ(raw["fnv1a"].get<std::uint32_t>(), fnv1a(fr.image)) << cam << " frame " << i;
      EXPECT_EQ(topics[cam + "/image_augmented"]["messages"][i]["fnv1a"].get<std::uint32_t>(), fnv1a(f->augmented[c]));
      EXPECT_EQ(topics[cam + "/mask"]["messages"][i]["fnv1a"].get<std::uint32_t>(), fnv1a(f->mask[c]));
      EXPECT_EQ(topics[cam + "/mask"]["messages"][i]["encoding"], "mono8");
      const CameraModel& cm = rig.cameras[static_cast<std::size_t>(c)].model;
      const auto& info = topics[cam + "/camera_info"]["messages"][i];
      EXPECT_EQ(info["stamp_ns"], t);
      EXPECT_EQ(info["distortion_model"], ros2::distortion_model_name(cm.distortion));
      EXPECT_EQ(info["k"], json::array({cm.fx_px, 0.0, cm.cx_px, 0.0, cm.fy_px, cm.cy_px, 0.0, 0.0, 1.0}));
      EXPECT_EQ(info["d"].size(), cm.distortion == DistortionModel::kEquidistant ? 4u : 5u);
      const auto& pose = topics[cam + "/receiver_pose"]["messages"][i];
      ASSERT_TRUE(f->T_cam_receiver[c]);
      const Pose& p = *f->T_cam_receiver[c];
      EXPECT_EQ(pose["stamp_ns"], t_key);
      EXPECT_EQ(pose["t"], json::array({p.translation_m.x(), p.translation_m.y(), p.translation_m.z()}));
      EXPECT_EQ(pose["q"], json::array({p.rotation.x(), p.rotation.y(), p.rotation.z(), p.rotation.w()}));
      const Pose& T = rig.cameras[static_cast<std::size_t>(c)].T_body_cam;
      const auto& st = statics[0]["transforms"][static_cast<std::size_t>(c)];
      EXPECT_EQ(st["parent"], "tanker_body");
      EXPECT_EQ(st["t"], json::array({T.translation_m.x(), T.translation_m.y(), T.translation_m.z()}));
      EXPECT_EQ(st["q"], json::array({T.rotation.x(), T.rotation.y(), T.rotation.z(), T.rotation.w()}));
    }
    const auto& tf = topics["/tf"]["messages"][i]["transforms"][0];
    ASSERT_TRUE(f->T_body_receiver);
    EXPECT_EQ(tf["stamp_ns"], t_key);
    EXPECT_EQ(tf["child"], "receiver_body");
    EXPECT_EQ(tf["t"], json::array({f->T_body_receiver->translation_m.x(), f->T_body_receiver->translation_m.y(),
                                    f->T_body_receiver->translation_m.z()}));
    const auto& stats = topics["/augrig/occlusion_stats"]["messages"][i];
    ASSERT_TRUE(f->stats);
    EXPECT_EQ(stats["receiver_px_left"], std::to_string(f->stats->receiver_px_left));
    EXPECT_EQ(stats["occluded_px_right"], std::to_string(f->stats->occluded_px_right));
    EXPECT_EQ(stats["boom_overlap_pct_union"].get<double>(), f->stats->boom_overlap_pct_union);
    // The shadow fields, appended last, decode by the schema text as well.
    EXPECT_EQ(stats["shadow_px_left"], std::to_string(f->stats->shadow_px_left));
    EXPECT_EQ(stats["shadow_px_right"], std::to_string(f->stats->shadow_px_right));
    EXPECT_EQ(stats["shadow_pct_left"].get<double>(), f->stats->shadow_pct_left);
    EXPECT_EQ(stats["shadow_pct_right"].get<double>(), f->stats->shadow_pct_right);
    const auto& frame = topics["/augrig/frame"]["messages"][i];
    EXPECT_EQ(frame["t_key_ns"], t_key);
    EXPECT_EQ(frame["boom_extension_m"].get<double>(), f->boom->extension_m);
  }
}

// A run with live nav (--nav sim): each aircraft's IMU increments as sensor_msgs/msg/Imu (mean rates
// at mid-interval, orientation unknown) and its GPS epochs as sensor_msgs/msg/NavSatFix, decoded by
// the independent readers.
TEST(CmdExportMcap, NavInputsAsImuAndNavSatFix) {
  std::string why;
  const std::string checker = mcap_checker(&why);
  if (checker.empty()) GTEST_SKIP() << "no independent MCAP readers: " << why;
  const std::string dir = test::output_dir("cmd_export_mcap_nav");
  std::string log;
  ASSERT_EQ(test::run_augrig("run --source 'sim://demo?every=30' --nav sim --record " + dir +
                                 "/rec --duration 4 --headless --status-every 0 2>&1",
                             &log),
            0)
      << log;
  ASSERT_EQ(test::run_augrig("export " + dir + "/rec --format mcap " + dir + "/nav.mcap 2>&1", &log), 0) << log;
  std::string out;
  ASSERT_EQ(test::run_command("node " + checker + " " + dir + "/nav.mcap", &out), 0) << out;
  const json j = json::parse(out);
  ASSERT_TRUE(j["ok"].get<bool>()) << j["errors"].dump();
  for (const std::string who : {"tanker", "receiver"}) {
    // Each stream's channel and messages are there (a missing key fails here, saying which).
    for (const std::string stream : {"imu", "gps"}) {
      const std::string topic = "/nav/" + who + "/" + stream;
      ASSERT_TRUE(j["channels"].contains(topic) && j["topics"].contains(topic)) << topic << "\n" << log;
    }
    EXPECT_EQ(j["channels"]["/nav/" + who + "/imu"]["type"], "sensor_msgs/msg/Imu");
    EXPECT_EQ(j["channels"]["/nav/" + who + "/gps"]["type"], "sensor_msgs/msg/NavSatFix");
    const auto& imu = j["topics"]["/nav/" + who + "/imu"]["messages"];
    const auto& fix = j["topics"]["/nav/" + who + "/gps"]["messages"];
    ASSERT_GT(imu.size(), 100u) << who;  // 200 Hz
    ASSERT_GT(fix.size(), 5u) << who;    // 10 Hz
    EXPECT_NE(log.find("/nav/" + who + "/imu: " + std::to_string(imu.size()) + "\n"), std::string::npos) << log;
    EXPECT_EQ(imu[0]["frame_id"], who + "_body");
    EXPECT_EQ(imu[0]["orientation_covariance"]["0"].get<double>(), -1.0);
    // Near-level flight in turbulence: specific force roughly -g along body z (FRD, up is -z).
    EXPECT_NEAR(imu[0]["linear_acceleration"]["z"].get<double>(), -9.8, 2.0);
    EXPECT_EQ(fix[0]["frame_id"], who + "_gps");
    EXPECT_NEAR(fix[0]["latitude"].get<double>(), 51.0, 0.1);  // the demo scenario's area
    EXPECT_NEAR(fix[0]["altitude"].get<double>(), 7000.0, 100.0);
  }
}

// export -> replay://OUT.mcap: the same raw frames and scenes; augrig replay OUT.mcap reproduces the
// recorded statistics and writes the same stats.csv as replaying the recording.
TEST(CmdExportMcap, ReplayGivesTheRecordedFramesBackAndReproducesTheStatistics) {
  const Exported& e = exported();
  auto reader = recorder::RecordingReader::open(e.rec);
  ASSERT_TRUE(reader) << reader.error().message;
  auto src = recorder::McapSource::open("replay://" + e.mcap);
  ASSERT_TRUE(src) << src.error().message;
  EXPECT_EQ((*src)->frame_count(), 3u);
  EXPECT_EQ((*src)->meta().at("rig_yaml"), (*reader)->meta("rig_yaml"));
  for (std::size_t i = 0; i < 3; ++i) {
    auto want = (*reader)->read_frame(i, recorder::kPartRaw);
    ASSERT_TRUE(want) << want.error().message;
    for (int c = 0; c < 2; ++c) {
      Frame f;
      auto st = (*src)->read(f, std::chrono::seconds(1));
      ASSERT_TRUE(st && *st == ReadStatus::kFrame) << (st ? "" : st.error().message);
      const Frame& w = c == 0 ? want->raw.left : want->raw.right;
      EXPECT_TRUE(pixels_equal(f.image, w.image)) << i << " " << c;
      EXPECT_EQ(f.t_ns, w.t_ns);
      EXPECT_EQ(f.clock, w.clock);
      EXPECT_EQ(f.sequence, w.sequence);
      const auto* rf = dynamic_cast<const recorder::RecordedFrame*>(f.attachment.get());
      ASSERT_NE(rf, nullptr);
      EXPECT_EQ(rf->record.raw.t_key_ns, want->raw.t_key_ns);
      ASSERT_TRUE(rf->record.T_cam_receiver[c] && want->T_cam_receiver[c]);
      EXPECT_EQ(rf->record.T_cam_receiver[c]->translation_m, want->T_cam_receiver[c]->translation_m);
      EXPECT_EQ(rf->record.T_cam_receiver[c]->rotation.coeffs(), want->T_cam_receiver[c]->rotation.coeffs());
      EXPECT_EQ(rf->record.T_body_receiver->translation_m, want->T_body_receiver->translation_m);
      EXPECT_EQ(rf->record.boom->elevation_rad, want->boom->elevation_rad);
      EXPECT_EQ(rf->record.receiver_present, want->receiver_present);
      EXPECT_EQ(rf->record.stats->receiver_px_left, want->stats->receiver_px_left);
    }
  }
  Frame f;
  auto end = (*src)->read(f, std::chrono::seconds(1));
  ASSERT_TRUE(end);
  EXPECT_EQ(*end, ReadStatus::kEndOfStream);

  std::string log;
  ASSERT_EQ(test::run_augrig("replay " + e.mcap + " --headless --out " + e.dir + "/from_mcap 2>&1", &log), 0) << log;
  EXPECT_NE(log.find("Recorded statistics reproduced exactly (same pixel counts) in 3 of 3 frame(s)"),
            std::string::npos)
      << log;
  ASSERT_EQ(test::run_augrig("replay " + e.rec + " --headless --out " + e.dir + "/from_rec 2>&1", &log), 0) << log;
  auto text = [](const std::string& p) {
    std::ifstream in(p);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  EXPECT_EQ(text(e.dir + "/from_mcap/stats.csv"), text(e.dir + "/from_rec/stats.csv"));
  EXPECT_FALSE(text(e.dir + "/from_mcap/stats.csv").empty());
}

// --images jpeg: the images on .../compressed as JPEG, a fraction of the raw file; `replay` plays it
// (the decoded colours) and reproduces the recorded statistics, which depend on the poses only.
TEST(CmdExportMcap, JpegImagesAFractionOfTheSizeAndReplayed) {
  const Exported& e = exported();
  const std::string jpeg = e.dir + "/jpeg.mcap";
  std::string log;
  ASSERT_EQ(test::run_augrig("export " + e.rec + " --format mcap " + jpeg + " --images jpeg --jpeg-quality 85 2>&1",
                             &log),
            0)
      << log;
  EXPECT_NE(log.find("  /left/image_raw/compressed: 3\n"), std::string::npos) << log;
  EXPECT_NE(log.find("  /right/image_augmented/compressed: 3\n"), std::string::npos) << log;
  EXPECT_EQ(log.find("  /left/image_raw: "), std::string::npos) << log;
  const double ratio = static_cast<double>(fs::file_size(jpeg)) / static_cast<double>(fs::file_size(e.mcap));
  std::printf("  JPEG q85 MCAP: %.1f %% of the raw export's size\n", 100.0 * ratio);
  EXPECT_LT(ratio, 0.5);
  ASSERT_EQ(test::run_augrig("replay " + jpeg + " --headless --out " + e.dir + "/from_jpeg 2>&1", &log), 0) << log;
  EXPECT_NE(log.find("Recorded statistics reproduced exactly (same pixel counts) in 3 of 3 frame(s)"),
            std::string::npos)
      << log;
  EXPECT_EQ(
      test::run_augrig("export " + e.rec + " --format mcap " + e.dir + "/x.mcap --images png 2>&1", &log), 2);
  EXPECT_NE(log.find("--images: expected raw, jpeg or h264, got 'png'"), std::string::npos) << log;
  EXPECT_EQ(test::run_augrig("export " + e.rec + " " + e.dir + "/x --format euroc --images jpeg 2>&1", &log), 2);
  EXPECT_NE(log.find("--images: only for --format mcap"), std::string::npos) << log;
  EXPECT_EQ(test::run_augrig("export " + e.rec + " --format mcap " + e.dir + "/x.mcap --jpeg-quality 50 2>&1", &log),
            2);
  EXPECT_NE(log.find("--jpeg-quality needs --images jpeg"), std::string::npos) << log;
}

// --images h264: each image topic an H.264 stream on .../h264 (foxglove_msgs/msg/CompressedVideo),
// smaller than JPEG; `replay` decodes the streams in order and reproduces the recorded statistics.
TEST(CmdExportMcap, H264ImagesSmallerStillAndReplayed) {
  const Exported& e = exported();
  const std::string h264 = e.dir + "/h264.mcap";
  std::string log;
  ASSERT_EQ(test::run_augrig("export " + e.rec + " --format mcap " + h264 +
                                 " --images h264 --h264-crf 23 --keyframe-interval 2 2>&1",
                             &log),
            0)
      << log;
  EXPECT_NE(log.find("  /left/image_raw/h264: 3\n"), std::string::npos) << log;
  EXPECT_NE(log.find("  /right/image_augmented/h264: 3\n"), std::string::npos) << log;
  EXPECT_EQ(log.find("  /left/image_raw: "), std::string::npos) << log;
  EXPECT_EQ(log.find("/compressed"), std::string::npos) << log;
  const double ratio = static_cast<double>(fs::file_size(h264)) / static_cast<double>(fs::file_size(e.mcap));
  std::printf("  H.264 crf 23 MCAP: %.1f %% of the raw export's size\n", 100.0 * ratio);
  EXPECT_LT(ratio, 0.5);
  ASSERT_EQ(test::run_augrig("replay " + h264 + " --headless --out " + e.dir + "/from_h264 2>&1", &log), 0)
      << log;
  EXPECT_NE(log.find("Recorded statistics reproduced exactly (same pixel counts) in 3 of 3 frame(s)"),
            std::string::npos)
      << log;
  for (const std::string bad : {"--h264-crf 52", "--keyframe-interval 0"}) {
    EXPECT_EQ(
        test::run_augrig(
            "export " + e.rec + " --format mcap " + e.dir + "/x.mcap --images h264 " + bad + " 2>&1", &log),
        2)
        << bad;
    EXPECT_NE(log.find(bad.substr(0, bad.find(' '))), std::string::npos) << log;
  }
  EXPECT_EQ(
      test::run_augrig("export " + e.rec + " --format mcap " + e.dir + "/x.mcap --h264-crf 20 2>&1", &log),
      2);
  EXPECT_NE(log.find("--h264-crf needs --images h264"), std::string::npos) << log;
}

TEST(CmdExportMcap, DamagedFilesFailClearlyWithTheFileAndOffset) {
  const Exported& e = exported();
  std::ifstream in(e.mcap, std::ios::binary);
  const std::vector<char> good((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto write = [&](const std::string& name, const std::vector<char>& b) {
    const std::string p = e.dir + "/" + name;
    std::ofstream(p, std::ios::binary).write(b.data(), static_cast<std::streamsize>(b.size()));
    return p;
  };
  std::string log;
  const std::string truncated = write("truncated.mcap", std::vector<char>(good.begin(), good.begin() + good.size() / 2));
  EXPECT_EQ(test::run_augrig("replay " + truncated + " --headless 2>&1", &log), 1) << log;
  EXPECT_NE(log.find(truncated + ": offset "), std::string::npos) << log;
  EXPECT_NE(log.find("the file is truncated or was not closed"), std::string::npos) << log;

  std::vector<char> b = good;
  b[1] = 'X';
  const std::string magic = write("bad_magic.mcap", b);
  EXPECT_EQ(test::run_augrig("replay " + magic + " --headless 2>&1", &log), 1) << log;
  EXPECT_NE(log.find(magic + ": offset 0: not an MCAP file: bad magic"), std::string::npos) << log;

  // The first chunk's CRC field: after the magic, the Header and the Metadata record.
  auto u64 = [&](std::size_t at) {
    std::uint64_t v = 0;
    for (int k = 0; k < 8; ++k) v |= static_cast<std::uint64_t>(static_cast<std::uint8_t>(good[at + static_cast<std::size_t>(k)])) << (8 * k);
    return v;
  };
  std::size_t at = 8;
  while (good[at] != 0x06) at += 9 + static_cast<std::size_t>(u64(at + 1));
  b = good;
  b[at + 9 + 24] ^= 0x01;
  const std::string crc = write("bad_crc.mcap", b);
  EXPECT_EQ(test::run_augrig("replay " + crc + " --headless 2>&1", &log), 1) << log;
  EXPECT_NE(log.find(crc + ": offset " + std::to_string(at) + ": Chunk: CRC mismatch"), std::string::npos) << log;
}

}  // namespace
}  // namespace augrig
