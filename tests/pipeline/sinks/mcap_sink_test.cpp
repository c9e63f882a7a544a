// The MCAP sink: a run's pairs written as `export --format mcap` writes the recording of the same
// run, message for message (the export being the oracle: same topics, times and bytes); its file
// plays back through McapSource with the run's rig; its options leave topics out; bad arguments
// and unwritable files are named.
#include <map>

#include <gtest/gtest.h>

#include "pipeline/report.hpp"
#include "pipeline/sinks/registry.hpp"
#include "recorder/mcap_export.hpp"
#include "recorder/mcap_source.hpp"
#include "render/video_codec.hpp"
#include "ros2/messages.hpp"
#include "tests/support/mcap_messages.hpp"
#include "tests/support/pipeline_parts.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

const std::string kScenario = "sim://" + test::data_path("scenarios/short_approach.yaml") + "?every=5&rate=0";

using Message = std::pair<std::string, std::vector<std::uint8_t>>;  // "TOPIC LOG_TIME", bytes
using test::mcap_messages;

std::map<std::string, int> topics_of(const std::vector<Message>& v) {
  std::map<std::string, int> n;
  for (const Message& m : v) ++n[m.first.substr(0, m.first.find(' '))];
  return n;
}

TEST(McapSink, WritesWhatExportWritesFromTheRecordingOfTheSameRun) {
  const std::string out = test::output_dir("mcap_sink_same");
  PipelineParts p = test::pipeline_parts(kScenario);
  p.max_pairs = 4;
  const Rig rig = p.rig;
  auto rec = recorder::Recorder::create(out + "/rec", recorder::RecordingInfo{});
  ASSERT_TRUE(rec) << rec.error().message;
  p.recorder = std::move(*rec);
  auto sink = make_sink("mcap:" + out + "/run.mcap", {p.rig});
  ASSERT_TRUE(sink) << sink.error().message;
  p.sinks.push_back(std::move(*sink));
  Pipeline pipeline(std::move(p));
  std::ostringstream o, e;
  auto report = pipeline.run(o, e);
  ASSERT_TRUE(report) << report.error().message;
  ASSERT_EQ(report->pairs, 4u);
  ASSERT_EQ(report->outputs.size(), 1u);
  EXPECT_NE(report->outputs[0].find("run.mcap: 4 stereo frame(s)"), std::string::npos) << report->outputs[0];
  EXPECT_FALSE(std::filesystem::exists(out + "/run.mcap.part"));

  // The oracle: the recording of the same run, exported.
  auto reader = recorder::RecordingReader::open(out + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  recorder::McapExportOptions eo;
  eo.rig = rig;
  recorder::McapExportReport er;
  ASSERT_TRUE(recorder::export_mcap(**reader, out + "/export.mcap", eo, er));
  const std::vector<Message> run = mcap_messages(out + "/run.mcap"), exported = mcap_messages(out + "/export.mcap");
  ASSERT_EQ(run.size(), exported.size());
  for (std::size_t i = 0; i < run.size(); ++i) {
    EXPECT_EQ(run[i].first, exported[i].first) << "message " << i;
    EXPECT_TRUE(run[i].second == exported[i].second) << run[i].first << ", message " << i;
  }
  const std::map<std::string, int> n = topics_of(run);
  for (const char* t : {"/augrig/frame", "/left/image_augmented", "/right/mask", "/left/receiver_pose", "/tf",
                        "/augrig/occlusion_stats"})
    EXPECT_EQ(n.count(t) ? n.at(t) : 0, 4) << t;

  // It plays back with the run's rig (its metadata) and the recorded scene.
  auto src = recorder::McapSource::open(out + "/run.mcap");
  ASSERT_TRUE(src) << src.error().message;
  EXPECT_EQ((*src)->frame_count(), 4u);
  ASSERT_TRUE((*src)->meta().count("rig_yaml"));
  auto back = parse_rig((*src)->meta().at("rig_yaml"), "mcap meta");
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(back->cameras.size(), 2u);
  EXPECT_EQ(back->cameras[0].model.width_px, rig.cameras[0].model.width_px);
}

// Two pairs of the scenario into the sink "mcap:FILE" + `options`; the file's messages.
std::vector<Message> two_pairs_into(const std::string& file, const std::string& options) {
  PipelineParts p = test::pipeline_parts(kScenario);
  p.max_pairs = 2;
  auto sink = make_sink("mcap:" + file + options, {p.rig});
  EXPECT_TRUE(sink) << sink.error().message;
  if (!sink) return {};
  p.sinks.push_back(std::move(*sink));
  Pipeline pipeline(std::move(p));
  std::ostringstream o, e;
  auto report = pipeline.run(o, e);
  EXPECT_TRUE(report) << report.error().message;
  return mcap_messages(file);
}

TEST(McapSink, OptionsLeaveTopicsOut) {
  const std::string out = test::output_dir("mcap_sink_options");
  const std::map<std::string, int> n = topics_of(two_pairs_into(out + "/raw.mcap", ",no-augmented,no-masks"));
  EXPECT_EQ(n.at("/left/image_raw"), 2);
  EXPECT_EQ(n.at("/augrig/occlusion_stats"), 2);
  EXPECT_EQ(n.count("/left/image_augmented") + n.count("/right/image_augmented"), 0u);
  EXPECT_EQ(n.count("/left/mask") + n.count("/right/mask"), 0u);
}

TEST(McapSink, JpegImagesOnRequest) {
  const std::string out = test::output_dir("mcap_sink_jpeg");
  const auto messages = two_pairs_into(out + "/j.mcap", ",jpeg=70");
  const std::map<std::string, int> n = topics_of(messages);
  EXPECT_EQ(n.count("/left/image_raw"), 0u);
  EXPECT_EQ(n.at("/left/image_raw/compressed"), 2);
  EXPECT_EQ(n.at("/right/image_augmented/compressed"), 2);
  EXPECT_EQ(n.at("/right/mask"), 2);
  for (const auto& [topic_time, data] : messages)
    if (topic_time.substr(0, topic_time.find(' ')) == "/left/image_augmented/compressed") {
      auto c = ros2::decode_compressed_image(data);
      ASSERT_TRUE(c) << c.error().message;
      EXPECT_EQ(c->format, "jpeg");
      EXPECT_EQ(c->frame_id, "left_camera");
      EXPECT_EQ(c->data.at(0), 0xff);
      EXPECT_EQ(c->data.at(1), 0xd8);
    }
}

TEST(McapSink, H264ImagesOnRequestDecodeInOrder) {
  const std::string out = test::output_dir("mcap_sink_h264");
  const auto messages = two_pairs_into(out + "/h.mcap", ",h264=30,gop=1");
  const std::map<std::string, int> n = topics_of(messages);
  EXPECT_EQ(n.count("/left/image_raw"), 0u);
  EXPECT_EQ(n.count("/left/image_raw/compressed"), 0u);
  EXPECT_EQ(n.at("/left/image_raw/h264"), 2);
  EXPECT_EQ(n.at("/right/image_augmented/h264"), 2);
  EXPECT_EQ(n.at("/right/mask"), 2);
  auto dec = H264Decoder::create();
  ASSERT_TRUE(dec);
  int decoded = 0;
  for (const auto& [topic_time, data] : messages)
    if (topic_time.substr(0, topic_time.find(' ')) == "/left/image_augmented/h264") {
      auto c = ros2::decode_compressed_video(data);
      ASSERT_TRUE(c) << c.error().message;
      EXPECT_EQ(c->format, "h264");
      EXPECT_EQ(c->frame_id, "left_camera");
      auto pic = (*dec)->decode(c->data.data(), c->data.size());
      ASSERT_TRUE(pic) << pic.error().message;
      EXPECT_GT(pic->width(), 0);
      ++decoded;
    }
  EXPECT_EQ(decoded, 2);
}

TEST(McapSink, BadArgumentsAndUnwritableFilesAreNamed) {
  const Rig rig = Rig::paper_default();
  auto unknown = make_sink("mcap:x.mcap,png", {rig});
  ASSERT_FALSE(unknown);
  EXPECT_EQ(
      unknown.error().message,
      "mcap sink: png: unknown option (expected no-augmented, no-masks, jpeg[=Q], h264[=CRF] or gop=N)");
  for (const char* q : {"jpeg=0", "jpeg=101", "jpeg=", "jpeg=8x"}) {
    auto bad_q = make_sink(std::string("mcap:x.mcap,") + q, {rig});
    ASSERT_FALSE(bad_q) << q;
    EXPECT_EQ(bad_q.error().message,
              std::string("mcap sink: ") + q + ": expected jpeg or jpeg=N with N a whole number 1..100");
  }
  for (const char* q : {"h264=52", "h264=-1", "gop=0", "gop=x"}) {
    auto bad_q = make_sink(std::string("mcap:x.mcap,") + q, {rig});
    ASSERT_FALSE(bad_q) << q;
    EXPECT_NE(bad_q.error().message.find(std::string("mcap sink: ") + q + ": expected "), std::string::npos)
        << bad_q.error().message;
  }
  auto both = make_sink("mcap:x.mcap,jpeg,h264", {rig});
  ASSERT_FALSE(both);
  EXPECT_EQ(both.error().message, "mcap sink: jpeg or h264, not both");
  auto empty = make_sink("mcap:,no-masks", {rig});
  ASSERT_FALSE(empty);
  EXPECT_EQ(empty.error().message, "mcap sink: expected a file name (mcap:OUT.mcap)");
  auto bad = make_sink("mcap:/nonexistent-dir/x.mcap", {rig});
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("mcap sink: "), std::string::npos) << bad.error().message;
  EXPECT_NE(bad.error().message.find("/nonexistent-dir/x.mcap.part"), std::string::npos) << bad.error().message;
}

}  // namespace
}  // namespace augrig::pipeline
