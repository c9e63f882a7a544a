// The video sink: an H.264 file that FFmpeg's own ffprobe reads back (codec, size, frame count,
// the pairs' rate) and OpenCV decodes to the colours that went in; the masks' colours option;
// bad arguments named; and `augrig run --sink video:...` end to end.
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/videoio.hpp>

#include "pipeline/report.hpp"
#include "pipeline/sinks/registry.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

namespace fs = std::filesystem;

Rig small_rig() {
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) c.model.width_px = 64, c.model.height_px = 48;
  return rig;
}

Image solid(int w, int h, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  Image im(w, h, PixelFormat::kRGB8);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint8_t* p = im.row(y) + 3 * x;
      p[0] = r, p[1] = g, p[2] = b;
    }
  return im;
}

// `n` pairs at `rate_hz`: left orange, right blue; the left mask marks a receiver block.
Status write_video(const std::string& spec, int n, double rate_hz) {
  const Rig rig = small_rig();
  auto sink = make_sink(spec, {rig});
  if (!sink) return sink.error();
  for (int i = 0; i < n; ++i) {
    StereoFrame raw;
    raw.left.image = solid(64, 48, 220, 120, 30);
    raw.right.image = solid(64, 48, 30, 60, 200);
    raw.t_key_ns = 1'000'000'000 + static_cast<TimestampNs>(i * 1e9 / rate_hz);
    StereoResult r;
    r.left.augmented = Image::copy_of(raw.left.image.cview());
    r.right.augmented = Image::copy_of(raw.right.image.cview());
    r.left.augmented_box = r.right.augmented_box = {0, 0, 64, 48};
    r.left.mask = Image(64, 48, PixelFormat::kMono8);
    r.right.mask = Image(64, 48, PixelFormat::kMono8);
    for (int y = 8; y < 24; ++y) std::fill_n(r.left.mask.row(y) + 8, 16, kMaskReceiver);
    FramePoses poses;
    SceneState scene{};
    PairContext pair{
        .raw = raw, .result = &r, .scene = &scene, .poses = poses, .pair = static_cast<std::uint64_t>(i + 1)};
    if (Status st = (*sink)->consume(pair); !st) return st;
    (*sink)->release(pair);
  }
  PipelineReport report;
  return (*sink)->close(report);
}

std::string ffprobe(const std::string& file) {
  std::string out;
  test::run_command(
      "ffprobe -v error -select_streams v:0 -count_frames -show_entries "
      "stream=codec_name,width,height,nb_read_frames,avg_frame_rate,has_b_frames -of default=nw=1 '" +
          file + "'",
      &out);
  return out;
}

TEST(VideoSink, FfprobeReadsTheStreamAtThePairsRate) {
  const std::string file = test::output_dir("video_sink") + "/pairs.mp4";
  ASSERT_TRUE(write_video("video:" + file, 20, 20.0));
  const std::string probe = ffprobe(file);
  EXPECT_NE(probe.find("codec_name=h264"), std::string::npos) << probe;
  EXPECT_NE(probe.find("width=128"), std::string::npos) << probe;
  EXPECT_NE(probe.find("height=48"), std::string::npos) << probe;
  EXPECT_NE(probe.find("nb_read_frames=20"), std::string::npos) << probe;
  EXPECT_NE(probe.find("avg_frame_rate=20/1"), std::string::npos) << probe;
  EXPECT_NE(probe.find("has_b_frames=0"), std::string::npos) << probe;
}

TEST(VideoSink, DecodesToTheColoursThatWentIn) {
  const std::string dir = test::output_dir("video_sink_colours");
  ASSERT_TRUE(write_video("video:" + dir + "/plain.mp4", 5, 30.0));
  ASSERT_TRUE(write_video("video:" + dir + "/masks.mkv,masks,crf=18", 5, 30.0));
  for (const char* name : {"plain.mp4", "masks.mkv"}) {
    cv::VideoCapture cap(dir + "/" + name);
    ASSERT_TRUE(cap.isOpened()) << name;
    cv::Mat bgr;
    int frames = 0;
    while (cap.read(bgr)) {
      ++frames;
      // Left half orange and right half blue (BGR), away from the mask block and the seam.
      const cv::Vec3b l = bgr.at<cv::Vec3b>(40, 40), r = bgr.at<cv::Vec3b>(24, 100);
      EXPECT_NEAR(l[2], std::string(name) == "masks.mkv" ? 220 * 0.5 : 220, 10)
          << name;  // blend_over darkens
      EXPECT_NEAR(r[0], std::string(name) == "masks.mkv" ? 200 * 0.5 : 200, 10) << name;
      const cv::Vec3b m = bgr.at<cv::Vec3b>(16, 16);  // inside the receiver block
      if (std::string(name) == "plain.mp4")
        EXPECT_NEAR(m[2], 220, 10);
      else
        EXPECT_GT(m[2], m[1] + 60);  // the receiver's red over the darkened orange
    }
    EXPECT_EQ(frames, 5) << name;
  }
}

TEST(VideoSink, BadArgumentsAreNamed) {
  const std::string dir = test::output_dir("video_sink_bad");
  auto expect_error = [&](const std::string& spec, const std::string& part) {
    const Status st = write_video(spec, 1, 30.0);
    ASSERT_FALSE(st) << spec;
    EXPECT_NE(st.error().message.find(part), std::string::npos) << spec << ": " << st.error().message;
  };
  expect_error("video:" + dir + "/a.mp4,crf=99", "crf=99: expected crf=N with N a whole number 0..51");
  expect_error("video:" + dir + "/a.mp4,fast", "fast: unknown option");
  expect_error("video:" + dir + "/a.notacontainer", "a.notacontainer: no container");
  expect_error("video:" + dir + "/no/such/dir/a.mp4", "a.mp4: cannot write");
  expect_error("video:", "expected video:FILE.mp4");
  expect_error("vidoe:a.mp4", "unknown sink (known: video:, tum:, mcap:, euroc:, kitti:, middlebury:, coco:, yolo:)");
}

TEST(VideoSink, RunWritesTheSimulatedFlight) {
  const std::string dir = test::output_dir("video_sink_run");
  std::string out;
  const int rc = test::run_augrig("run --source sim://" + test::data_path("scenarios/short_approach.yaml") +
                                      "?rate=0\\&every=3 --frames 12 --look plain --sink video:" + dir +
                                      "/flight.mp4 --sink tum:" + dir + "/receiver.txt",
                                  &out);
  ASSERT_EQ(rc, 0) << out;
  const std::string probe = ffprobe(dir + "/flight.mp4");
  EXPECT_NE(probe.find("nb_read_frames=12"), std::string::npos) << probe;
  EXPECT_NE(probe.find("codec_name=h264"), std::string::npos) << probe;
  std::ifstream tum(dir + "/receiver.txt");
  int lines = 0;
  for (std::string line; std::getline(tum, line);) lines += !line.empty() && line[0] != '#';
  EXPECT_EQ(lines, 12);
}

}  // namespace
}  // namespace augrig::pipeline
