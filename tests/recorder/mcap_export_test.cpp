// recorder/mcap_export: the writer shared by export_mcap() and the mcap sink, and merge_mcap().
// A recording written in two shards by McapFrameWriter and joined by merge_mcap() is, message for
// message, export_mcap()'s file of the whole recording (the oracle), its nav inputs included;
// bad inputs are named. (The files' content against independent readers: tests/app/cmd_export_mcap_test.)
#include "recorder/mcap_export.hpp"

#include <filesystem>

#include <gtest/gtest.h>

#include "recorder/mcap_reader.hpp"
#include "recorder/recorder.hpp"
#include "tests/support/mcap_messages.hpp"
#include "tests/support/recording_fixture.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::recorder {
namespace {

using test::mcap_messages;

// The fixture's recording copied with an IMU stream added (as `augrig run --nav` records one).
std::string recording_with_nav(const std::string& dir) {
  auto from = RecordingReader::open(test::recording_of_this_test("mcap_export_"));
  EXPECT_TRUE(from) << from.error().message;
  RecordingInfo info;
  info.rig_yaml = (*from)->meta("rig_yaml");
  auto rec = Recorder::create(dir + "/rec", info);
  EXPECT_TRUE(rec) << rec.error().message;
  for (std::size_t i = 0; i < (*from)->frame_count(); ++i) {
    auto f = (*from)->read_frame(i);
    EXPECT_TRUE(f) << f.error().message;
    (*rec)->push(std::move(*f));
  }
  for (int k = 0; k < 50; ++k) {
    nav::ImuSample s;
    s.t_ns = test::kRecordingT0 + k * 5'000'000;
    s.dt_s = 0.005;
    s.dtheta_rad = {1e-4 * k, -2e-4, 3e-5};
    s.dv_mps = {0.01, 0.0, -0.049};
    (*rec)->push(imu_input(s, "tanker.imu"));
  }
  EXPECT_TRUE((*rec)->close());
  return dir + "/rec";
}

TEST(McapExport, ShardsJoinedAreTheWholeRecordingsFile) {
  const std::string dir = test::output_dir("mcap_export_merge");
  auto reader = RecordingReader::open(recording_with_nav(dir));
  ASSERT_TRUE(reader) << reader.error().message;
  const RecordingReader& r = **reader;
  McapExportOptions o;
  McapExportReport whole_report;
  ASSERT_TRUE(export_mcap(r, dir + "/whole.mcap", o, whole_report));

  // Two shards, frames [0, 3) and [3, 8), each written as the mcap sink writes a replay's pairs.
  auto rig = parse_rig(r.meta("rig_yaml"), "meta");
  ASSERT_TRUE(rig) << rig.error().message;
  McapExportOptions so;
  so.nav = false;
  std::vector<std::string> shards;
  for (auto [from, to] : {std::pair<std::size_t, std::size_t>{0, 3}, {3, r.frame_count()}}) {
    shards.push_back(dir + "/shard" + std::to_string(from) + ".mcap");
    McapExportReport rep;
    auto w = McapFrameWriter::create(shards.back(), so, r.meta(), *rig, rep);
    ASSERT_TRUE(w) << w.error().message;
    for (std::size_t i = from; i < to; ++i) {
      auto f = r.read_frame(i, kPartRaw | kPartAugmented | kPartMasks);
      ASSERT_TRUE(f) << f.error().message;
      ASSERT_TRUE((*w)->write(mcap_frame_of(*f), i, "frame " + std::to_string(i)));
    }
    ASSERT_TRUE((*w)->finish());
    EXPECT_EQ(rep.frames_written, to - from);
  }
  McapExportReport merged_report;
  ASSERT_TRUE(merge_mcap(shards, dir + "/merged.mcap", &r, merged_report));
  EXPECT_EQ(merged_report.frames, r.frame_count());
  EXPECT_EQ(merged_report.messages_by_topic["/nav/tanker/imu"], 50u);
  EXPECT_FALSE(std::filesystem::exists(dir + "/merged.mcap.part"));

  const auto whole = mcap_messages(dir + "/whole.mcap"), merged = mcap_messages(dir + "/merged.mcap");
  ASSERT_EQ(merged.size(), whole.size());
  for (std::size_t i = 0; i < whole.size(); ++i) {
    EXPECT_EQ(merged[i].first, whole[i].first) << "message " << i;
    EXPECT_TRUE(merged[i].second == whole[i].second) << merged[i].first;
  }
  auto meta = McapReader::open(dir + "/merged.mcap");
  ASSERT_TRUE(meta);
  auto m = (*meta)->metadata(kMcapRecordingMetadata);
  ASSERT_TRUE(m && *m);
  EXPECT_EQ((*m)->at("rig_yaml"), r.meta("rig_yaml"));
}

TEST(McapExport, MergeNamesWhatItCannotJoin) {
  const std::string dir = test::output_dir("mcap_export_merge_bad");
  McapExportReport rep;
  const Status none = merge_mcap({}, dir + "/x.mcap", nullptr, rep);
  ASSERT_FALSE(none);
  EXPECT_EQ(none.error().message, "recorder::merge_mcap(): " + dir + "/x.mcap: no files to join");
  const Status missing = merge_mcap({dir + "/absent.mcap"}, dir + "/x.mcap", nullptr, rep);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find(dir + "/absent.mcap"), std::string::npos) << missing.error().message;
  EXPECT_FALSE(std::filesystem::exists(dir + "/x.mcap"));
}

}  // namespace
}  // namespace augrig::recorder
