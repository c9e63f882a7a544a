// McapSource (recorder/mcap_source.hpp): the fixture's recording exported by export_mcap() plays
// back, frame for frame, as RecordingReader reads the recording (raw images, timestamps, poses,
// boom, presence, statistics); a frame whose messages cannot be used is an Error naming the file and
// the frame, skipped, and the next read() goes on; a damaged file is an Error naming the file; a
// file augrig did not write is named; is_mcap_path(). (The file's content against independent
// readers, and `augrig replay OUT.mcap`: tests/app/cmd_export_mcap_test.)
#include "recorder/mcap_source.hpp"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "recorder/mcap_export.hpp"
#include "recorder/mcap_writer.hpp"
#include "recorder/reader.hpp"
#include "render/cv_image.hpp"
#include "ros2/messages.hpp"
#include "tests/support/recording_fixture.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::recorder {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

struct Exported {
  std::string recording, dir, mcap;
};

// The fixture's recording exported once per test process (CTest runs each test in its own), beside
// the recording in the test's own folder.
const Exported& exported() {
  static const Exported e = [] {
    Exported x;
    x.recording = test::recording_of_this_test("mcap_source_");
    x.dir = fs::path(x.recording).parent_path().string();
    x.mcap = x.dir + "/rec.mcap";
    auto reader = RecordingReader::open(x.recording);
    EXPECT_TRUE(reader) << reader.error().message;
    if (!reader) return x;
    McapExportReport report;
    const Status s = export_mcap(**reader, x.mcap, {}, report);
    EXPECT_TRUE(s) << s.error().message;
    EXPECT_TRUE(report.problems.empty());
    return x;
  }();
  return e;
}

std::vector<char> bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string write_bytes(const std::string& path, const std::vector<char>& b) {
  std::ofstream(path, std::ios::binary).write(b.data(), static_cast<std::streamsize>(b.size()));
  return path;
}

void expect_same_pose(const std::optional<Pose>& got, const std::optional<Pose>& want,
                      const std::string& what) {
  ASSERT_EQ(got.has_value(), want.has_value()) << what;
  if (!want) return;
  EXPECT_EQ(got->translation_m, want->translation_m) << what;
  EXPECT_EQ(got->rotation.coeffs(), want->rotation.coeffs()) << what;
}

// Equal, or both NaN (a sigma the recording does not know).
bool same(double a, double b) {
  return a == b || (std::isnan(a) && std::isnan(b));
}

TEST(McapSource, PlaysTheExportBackAsTheRecordingReadsIt) {
  const Exported& e = exported();
  auto reader = RecordingReader::open(e.recording);
  ASSERT_TRUE(reader) << reader.error().message;
  const RecordingReader& r = **reader;
  ASSERT_EQ(r.frame_count(), static_cast<std::size_t>(test::kRecordingFrames));

  auto opened = McapSource::open("replay://" + e.mcap);
  ASSERT_TRUE(opened) << opened.error().message;
  McapSource& src = **opened;
  EXPECT_EQ(src.uri(), "replay://" + e.mcap);
  EXPECT_EQ(src.path(), e.mcap);
  EXPECT_TRUE(src.capabilities().finite);
  EXPECT_FALSE(src.capabilities().ranged);
  EXPECT_EQ(src.frame_count(), r.frame_count());
  EXPECT_EQ(src.pair_count(), r.frame_count());
  EXPECT_EQ(src.meta(), r.meta());
  EXPECT_EQ(src.metadata(), r.meta());
  EXPECT_FALSE(src.meta().at("rig_yaml").empty());

  for (std::size_t i = 0; i < r.frame_count(); ++i) {
    auto want = r.read_frame(i, kPartRaw);
    ASSERT_TRUE(want) << want.error().message;
    const RecordedFrame* first = nullptr;
    for (int c = 0; c < 2; ++c) {
      const std::string what = "frame " + std::to_string(i) + " camera " + std::to_string(c);
      Frame f;
      auto st = src.read(f, 0ns);
      ASSERT_TRUE(st) << st.error().message;
      ASSERT_EQ(*st, ReadStatus::kFrame) << what;
      const Frame& w = c == 0 ? want->raw.left : want->raw.right;
      EXPECT_EQ(f.camera, c == 0 ? CameraId::kLeft : CameraId::kRight) << what;
      EXPECT_EQ(f.image.format(), w.image.format()) << what;
      EXPECT_TRUE(pixels_equal(f.image, w.image)) << what;
      EXPECT_EQ(f.t_ns, w.t_ns) << what;
      EXPECT_EQ(f.clock, w.clock) << what;
      EXPECT_EQ(f.t_host_ns, w.t_host_ns) << what;
      EXPECT_EQ(f.sequence, w.sequence) << what;
      EXPECT_EQ(f.exposure_ns, w.exposure_ns) << what;

      const auto* rf = dynamic_cast<const RecordedFrame*>(f.attachment.get());
      ASSERT_NE(rf, nullptr) << what;
      if (c == 0) first = rf;
      EXPECT_EQ(rf, first) << what << ": both Frames of a pair carry one record";
      EXPECT_EQ(rf->index, i);
      const FrameRecord& got = rf->record;
      EXPECT_EQ(got.raw.pair_sequence, want->raw.pair_sequence) << what;
      EXPECT_EQ(got.raw.t_key_ns, want->raw.t_key_ns) << what;
      EXPECT_EQ(got.raw.skew_ns, want->raw.skew_ns) << what;
      EXPECT_EQ(got.raw.left.t_ns, want->raw.left.t_ns) << what;
      EXPECT_EQ(got.raw.right.t_ns, want->raw.right.t_ns) << what;
      for (int k = 0; k < 2; ++k)
        expect_same_pose(got.T_cam_receiver[k], want->T_cam_receiver[k],
                         what + " T_cam_receiver " + std::to_string(k));
      expect_same_pose(got.T_body_receiver, want->T_body_receiver, what + " T_body_receiver");
      EXPECT_EQ(got.receiver_present, want->receiver_present) << what;
      ASSERT_TRUE(got.boom && want->boom) << what;
      EXPECT_EQ(got.boom->elevation_rad, want->boom->elevation_rad) << what;
      EXPECT_EQ(got.boom->azimuth_rad, want->boom->azimuth_rad) << what;
      EXPECT_EQ(got.boom->extension_m, want->boom->extension_m) << what;
      EXPECT_TRUE(same(got.sigma_pos_m, want->sigma_pos_m)) << what;
      EXPECT_TRUE(same(got.sigma_att_deg, want->sigma_att_deg)) << what;
      ASSERT_TRUE(got.stats && want->stats) << what;
      EXPECT_TRUE(*got.stats == *want->stats) << what;
    }
  }
  for (int k = 0; k < 2; ++k) {  // the end stays the end
    Frame f;
    auto end = src.read(f, 0ns);
    ASSERT_TRUE(end) << end.error().message;
    EXPECT_EQ(*end, ReadStatus::kEndOfStream);
  }
  EXPECT_EQ(src.damaged_frames(), 0u);
  EXPECT_EQ(src.frames_dropped(), 0u);
}

// Plays `file` (an export of `r` with compressed images) back against the recording: each frame's
// images within the codec's loss (gray stays gray; colour and Bayer come back as RGB) at the
// recorded size, every other field exact.
void expect_plays_back_within_loss(const RecordingReader& r, const std::string& file, const std::string& what) {
  auto opened = McapSource::open("replay://" + file);
  ASSERT_TRUE(opened) << opened.error().message;
  for (std::size_t i = 0; i < r.frame_count(); ++i) {
    auto want = r.read_frame(i, kPartRaw);
    ASSERT_TRUE(want) << want.error().message;
    for (int c = 0; c < 2; ++c) {
      Frame f;
      auto st = (*opened)->read(f, 0ns);
      ASSERT_TRUE(st && *st == ReadStatus::kFrame) << what << " " << i << ": " << (st ? "" : st.error().message);
      const Frame& w = c == 0 ? want->raw.left : want->raw.right;
      ASSERT_EQ(f.image.format(), w.image.format() == PixelFormat::kMono8 ? PixelFormat::kMono8 : PixelFormat::kRGB8);
      ASSERT_EQ(f.image.width(), w.image.width());
      ASSERT_EQ(f.image.height(), w.image.height());
      EXPECT_GT(cv::PSNR(bgr_of(f.image.cview()), bgr_of(w.image.cview())), 30.0)
          << what << ": frame " << i << " camera " << c;
      EXPECT_EQ(f.t_ns, w.t_ns);
      const auto* rf = dynamic_cast<const RecordedFrame*>(f.attachment.get());
      ASSERT_NE(rf, nullptr);
      ASSERT_TRUE(rf->record.stats && want->stats);
      EXPECT_TRUE(*rf->record.stats == *want->stats);
    }
  }
  EXPECT_EQ((*opened)->damaged_frames(), 0u);
}

// --images jpeg: the images as JPEG on .../compressed (the masks as they are), a fraction of the
// file; played back as the colours decoded (RGB8, a Bayer camera's demosaiced), within JPEG's loss
// of the recording's images, every other field as exact as a raw export's.
TEST(McapSource, PlaysAJpegExportBackAsItsDecodedColours) {
  const Exported& e = exported();
  auto reader = RecordingReader::open(e.recording);
  ASSERT_TRUE(reader) << reader.error().message;
  const RecordingReader& r = **reader;
  const std::string jpeg = e.dir + "/rec_jpeg.mcap";
  McapExportOptions o;
  o.jpeg = true;
  McapExportReport report;
  ASSERT_TRUE(export_mcap(r, jpeg, o, report));
  EXPECT_EQ(report.messages_by_topic.count("/left/image_raw"), 0u);
  EXPECT_EQ(report.messages_by_topic.at("/left/image_raw/compressed"), r.frame_count());
  EXPECT_EQ(report.messages_by_topic.at("/right/image_augmented/compressed"), r.frame_count());
  EXPECT_EQ(report.messages_by_topic.at("/left/mask"), r.frame_count());
  EXPECT_LT(fs::file_size(jpeg), fs::file_size(e.mcap) / 2) << "JPEG and zstd against zstd alone";
  expect_plays_back_within_loss(r, jpeg, "jpeg");
  McapExportOptions bad = o;
  bad.jpeg_quality = 0;
  const Status s = export_mcap(r, e.dir + "/bad.mcap", bad, report);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("JPEG quality 0: expected 1..100"), std::string::npos) << s.error().message;
}

// --images h264: each image topic an H.264 stream on .../h264; played back by decoding each
// camera's stream in order, within the codec's loss of the recording's images (gray as gray), at
// the recorded size; every other field exact. A keyframe every frame and one at the start only
// both play.
TEST(McapSource, PlaysAnH264ExportBackDecodingEachStreamInOrder) {
  const Exported& e = exported();
  auto reader = RecordingReader::open(e.recording);
  ASSERT_TRUE(reader) << reader.error().message;
  const RecordingReader& r = **reader;
  for (int gop : {1, 1000}) {
    const std::string h264 = e.dir + "/rec_h264_" + std::to_string(gop) + ".mcap";
    McapExportOptions o;
    o.h264 = true;
    o.h264_gop_frames = gop;
    o.h264_crf = 18;
    McapExportReport report;
    ASSERT_TRUE(export_mcap(r, h264, o, report));
    EXPECT_EQ(report.messages_by_topic.count("/left/image_raw"), 0u);
    EXPECT_EQ(report.messages_by_topic.at("/left/image_raw/h264"), r.frame_count());
    EXPECT_EQ(report.messages_by_topic.at("/right/image_augmented/h264"), r.frame_count());
    EXPECT_EQ(report.messages_by_topic.at("/left/mask"), r.frame_count());
    // The fixture's frames are fresh noise each (no motion to predict): the gain is the transform's.
    EXPECT_LT(fs::file_size(h264), fs::file_size(e.mcap) * 2 / 3) << "H.264 against zstd alone";
    expect_plays_back_within_loss(r, h264, "gop " + std::to_string(gop));
  }
  McapExportOptions both;
  both.h264 = both.jpeg = true;
  McapExportReport report;
  const Status s = export_mcap(r, e.dir + "/both.mcap", both, report);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("JPEG or as H.264, not both"), std::string::npos) << s.error().message;
}

// A stereo frame whose /augrig/frame does not decode, and one without its images: each an Error
// naming the file and the frame, counted as two dropped Frames; the frames around them play.
TEST(McapSource, UnusableFramesAreSkippedAndTheNextReadGoesOn) {
  const Exported& e = exported();
  auto reader = RecordingReader::open(e.recording);
  ASSERT_TRUE(reader) << reader.error().message;
  const RecordingReader& r = **reader;
  auto rig = parse_rig(r.meta("rig_yaml"), "meta");
  ASSERT_TRUE(rig) << rig.error().message;
  const std::string path = e.dir + "/unusable.mcap";
  McapExportReport report;
  auto w = McapFrameWriter::create(path, {}, r.meta(), *rig, report);
  ASSERT_TRUE(w) << w.error().message;
  std::vector<FrameRecord> frames;
  for (std::size_t i = 0; i < 3; ++i) {
    auto f = r.read_frame(i);
    ASSERT_TRUE(f) << f.error().message;
    frames.push_back(std::move(*f));
  }
  const std::string type = "augrig_msgs/msg/StereoFrameInfo";
  ASSERT_TRUE((*w)->write(mcap_frame_of(frames[0]), 0, "frame 0"));
  ASSERT_TRUE((*w)->write_message("/augrig/frame", type, frames[1].raw.t_key_ns, {1, 2, 3}));
  const std::int64_t t2 = frames[2].raw.t_key_ns;
  ASSERT_TRUE((*w)->write_message("/augrig/frame", type, t2,
                                  ros2::stereo_frame_info(t2, ros2::stereo_frame_info_of(frames[2].raw, 2))));
  ASSERT_TRUE((*w)->write(mcap_frame_of(frames[1]), 1, "frame 1"));
  ASSERT_TRUE((*w)->finish());

  auto src = McapSource::open(path);
  ASSERT_TRUE(src) << src.error().message;
  EXPECT_EQ((*src)->frame_count(), 4u);  // /augrig/frame messages
  std::vector<std::size_t> played;       // the records' indices, per Frame
  std::vector<std::string> errors;
  Frame f;
  for (;;) {
    auto st = (*src)->read(f, 0ns);
    if (!st) {
      errors.push_back(st.error().message);
      continue;
    }
    if (*st == ReadStatus::kEndOfStream) break;
    const auto* rf = dynamic_cast<const RecordedFrame*>(f.attachment.get());
    ASSERT_NE(rf, nullptr);
    played.push_back(rf->index);
  }
  EXPECT_EQ(played, (std::vector<std::size_t>{0, 0, 1, 1}));
  const std::string where = "recorder::McapSource::read(): " + path + ": ";
  ASSERT_EQ(errors.size(), 2u);
  EXPECT_EQ(errors[0].rfind(where + "a stereo frame: ", 0), 0u) << errors[0];
  EXPECT_NE(errors[0].find("; skipped, the next read() goes on"), std::string::npos) << errors[0];
  EXPECT_EQ(errors[1], where + "frame 2: no /left/image_raw message; skipped, the next read() goes on");
  EXPECT_EQ((*src)->damaged_frames(), 2u);
  EXPECT_EQ((*src)->frames_dropped(), 4u);
}

// Damage to the file itself: a copy cut in half does not open, naming the file; a chunk whose CRC
// does not match ends the stream with an Error naming the file and the chunk's offset.
TEST(McapSource, DamagedFileIsAnErrorNamingTheFile) {
  const Exported& e = exported();
  const std::vector<char> good = bytes_of(e.mcap);
  ASSERT_GT(good.size(), 1000u);

  const std::string truncated =
      write_bytes(e.dir + "/truncated.mcap", std::vector<char>(good.begin(), good.begin() + good.size() / 2));
  auto cut = McapSource::open(truncated);
  ASSERT_FALSE(cut);
  EXPECT_NE(cut.error().message.find(truncated + ": offset "), std::string::npos) << cut.error().message;
  EXPECT_NE(cut.error().message.find("the file is truncated or was not closed"), std::string::npos)
      << cut.error().message;

  // The first chunk's CRC field: after the magic, the Header and the Metadata record.
  auto u64 = [&](std::size_t at) {
    std::uint64_t v = 0;
    for (int k = 0; k < 8; ++k)
      v |= static_cast<std::uint64_t>(static_cast<std::uint8_t>(good[at + static_cast<std::size_t>(k)]))
           << (8 * k);
    return v;
  };
  std::size_t at = 8;
  while (good[at] != 0x06) at += 9 + static_cast<std::size_t>(u64(at + 1));
  std::vector<char> b = good;
  b[at + 9 + 24] ^= 0x01;
  const std::string crc = write_bytes(e.dir + "/bad_crc.mcap", b);
  auto src = McapSource::open(crc);
  ASSERT_TRUE(src) << src.error().message;
  Frame f;
  auto st = (*src)->read(f, 0ns);
  ASSERT_FALSE(st);
  EXPECT_EQ(st.error().message.rfind("recorder::McapSource::read(): ", 0), 0u) << st.error().message;
  EXPECT_NE(st.error().message.find(crc + ": offset " + std::to_string(at) + ": Chunk: CRC mismatch"),
            std::string::npos)
      << st.error().message;
  EXPECT_NE(st.error().message.find("; the replay stops here"), std::string::npos) << st.error().message;
  st = (*src)->read(f, 0ns);
  ASSERT_TRUE(st) << st.error().message;
  EXPECT_EQ(*st, ReadStatus::kEndOfStream);
}

// An MCAP file without /augrig/frame (not written by augrig) and a missing file are named.
TEST(McapSource, FilesItCannotPlayAreNamed) {
  const std::string dir = test::output_dir("mcap_source_foreign");
  const std::string path = dir + "/chatter.mcap";
  auto w = McapWriter::create(path, {});
  ASSERT_TRUE(w) << w.error().message;
  const std::uint16_t schema = (*w)->add_schema("std_msgs/msg/String", "ros2msg", "string data");
  const std::uint16_t channel = (*w)->add_channel(schema, "/chatter", "cdr", {});
  ASSERT_TRUE((*w)->write_message(channel, 1000, std::vector<std::uint8_t>{0, 1, 0, 0, 1, 0, 0, 0, 0}));
  ASSERT_TRUE((*w)->close());
  auto foreign = McapSource::open("replay://" + path);
  ASSERT_FALSE(foreign);
  EXPECT_EQ(foreign.error().message,
            "recorder::McapSource::open(): " + path +
                ": no /augrig/frame channel: not an MCAP file written by augrig export "
                "(augrig_msgs/msg/StereoFrameInfo)");
  auto missing = McapSource::open(dir + "/absent.mcap");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find(dir + "/absent.mcap"), std::string::npos) << missing.error().message;
}

// By name (.mcap, whether or not the file exists) or by the MCAP magic at the start.
TEST(McapSource, IsMcapPath) {
  const Exported& e = exported();
  EXPECT_TRUE(is_mcap_path(e.mcap));
  EXPECT_TRUE(is_mcap_path(e.dir + "/absent.mcap"));
  const std::string renamed = write_bytes(e.dir + "/export.bin", bytes_of(e.mcap));
  EXPECT_TRUE(is_mcap_path(renamed));
  EXPECT_FALSE(is_mcap_path(e.recording));
  EXPECT_FALSE(is_mcap_path(e.recording + "/recording.sqlite"));
  EXPECT_FALSE(is_mcap_path(e.dir + "/absent"));
}

}  // namespace
}  // namespace augrig::recorder
