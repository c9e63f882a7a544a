// merge_recordings(): a simulated flight's recording replayed whole (`augrig replay --record`) and
// in three shards (--from-frame/--frames), with the receiver's depth (--ground-truth), the shards'
// recordings joined: the merged recording's frames and depth rows equal the whole replay's column for column
// (blobs byte for byte), its summary adds up and `augrig check` finds nothing; the flight's nav inputs come
// with it when asked; parts that overlap, of another rig, not closed or not recordings are refused by name.
#include "recorder/recording_merge.hpp"

#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "recorder/reader.hpp"
#include "recorder/store.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::recorder {
namespace {

namespace fs = std::filesystem;

// Every row of `sql` in `db`, each column as text or blob bytes, for comparing two databases.
std::vector<std::vector<std::string>> rows(const std::string& db_path, const std::string& sql) {
  auto db = Database::open(database_path(db_path), SQLITE_OPEN_READONLY);
  EXPECT_TRUE(db) << db.error().message;
  std::vector<std::vector<std::string>> out;
  if (!db) return out;
  auto st = Statement::prepare(db->get(), sql);
  EXPECT_TRUE(st) << st.error().message;
  if (!st) return out;
  while (st->step() == SQLITE_ROW) {
    std::vector<std::string> row;
    for (int c = 0; c < sqlite3_column_count(st->get()); ++c) {
      const auto* p = static_cast<const char*>(sqlite3_column_blob(st->get(), c));
      row.emplace_back(p ? std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(st->get(), c)))
                         : "NULL");
    }
    out.push_back(std::move(row));
  }
  return out;
}

void exec(const std::string& db_path, const std::string& sql) {
  auto db = Database::open(database_path(db_path), SQLITE_OPEN_READWRITE);
  ASSERT_TRUE(db) << db.error().message;
  ASSERT_TRUE(db->exec(sql)) << sql;
}

class RecordingMerge : public ::testing::Test {
 protected:
  std::string dir, flight;
  std::vector<std::string> parts;
  void SetUp() override {
    std::string why;
    flight = test::sim_recording("campaign/flight_a.yaml", 3, "campaign_a", &why);  // 41 frames
    ASSERT_FALSE(flight.empty()) << why;
    dir = test::output_dir(std::string("recording_merge_") +
                           ::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  // `augrig replay FLIGHT [--from-frame A --frames N] --record OUT` with the plain look (the camera
  // look's estimates start over in each shard; docs/CAMPAIGN.md).
  void replay(const std::string& range, const std::string& out) {
    std::string log;
    ASSERT_EQ(test::run_augrig("replay " + flight + " " + range +
                                   " --look plain --headless --fast --ground-truth --record " + out,
                               &log),
              0)
        << log;
  }
  void shards() {
    const std::pair<int, int> ranges[] = {{0, 14}, {14, 13}, {27, 14}};
    for (const auto& [from, n] : ranges) {
      parts.push_back(dir + "/part" + std::to_string(parts.size()));
      replay("--from-frame " + std::to_string(from) + " --frames " + std::to_string(n), parts.back());
    }
  }
};

TEST_F(RecordingMerge, ShardsJoinedEqualTheWholeReplay) {
  replay("", dir + "/whole");
  shards();
  RecordingMergeReport report;
  const Status s = merge_recordings(parts, dir + "/merged", nullptr, report);
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(report.parts, 3u);
  EXPECT_EQ(report.frames, 41u);
  const auto whole = rows(dir + "/whole", "SELECT * FROM frames ORDER BY id");
  const auto merged = rows(dir + "/merged", "SELECT * FROM frames ORDER BY id");
  ASSERT_EQ(whole.size(), 41u);
  ASSERT_EQ(merged.size(), whole.size());
  const std::vector<std::string> names = [] {
    std::vector<std::string> n{"id"};
    for (const std::string& c : frame_column_names()) n.push_back(c);
    return n;
  }();
  for (std::size_t i = 0; i < whole.size(); ++i)
    for (std::size_t c = 0; c < whole[i].size(); ++c)
      EXPECT_EQ(merged[i][c], whole[i][c]) << "frame " << i << ", column " << names.at(c);
  // The receiver's depth (--ground-truth) goes with its frame.
  const auto depth = rows(dir + "/whole", "SELECT * FROM depth ORDER BY frame_id");
  EXPECT_GT(depth.size(), 20u);
  EXPECT_EQ(rows(dir + "/merged", "SELECT * FROM depth ORDER BY frame_id"), depth);
  // The summary adds up: each part's events and look updates, the frames, the drops summed.
  auto reader = RecordingReader::open(dir + "/merged");
  ASSERT_TRUE(reader) << reader.error().message;
  EXPECT_EQ((*reader)->meta("summary.frames"), "41");
  EXPECT_EQ((*reader)->meta("summary.status"), "ok");
  std::size_t events = 0;
  for (const std::string& p : parts) events += rows(p, "SELECT id FROM events").size();
  EXPECT_EQ(report.events, events);
  EXPECT_EQ((*reader)->meta("summary.events"), std::to_string(events));
  EXPECT_NE((*reader)->meta("merged_from").find("3 part(s), in order: " + database_path(parts[0])),
            std::string::npos);
  EXPECT_EQ((*reader)->meta("rig_yaml"),
            rows(dir + "/whole", "SELECT value FROM meta WHERE key = 'rig_yaml'")[0][0]);
  const CheckReport check = (*reader)->check();
  EXPECT_TRUE(check.ok()) << check.to_string();
  EXPECT_EQ(check.frames_ok, 41u);
  std::string out;
  EXPECT_EQ(test::run_augrig("check " + dir + "/merged", &out), 0) << out;
  // Merged again over itself: replaced whole, the same frames.
  ASSERT_TRUE(merge_recordings(parts, dir + "/merged", nullptr, report));
  EXPECT_EQ(rows(dir + "/merged", "SELECT * FROM frames ORDER BY id"), merged);
  EXPECT_FALSE(fs::exists(database_path(dir + "/merged") + ".merging"));
}

// The flight's nav inputs (a replay does not record them) from the flight's own recording, once,
// in its order; without it, the parts' own.
TEST_F(RecordingMerge, NavInputsFromTheFlightsRecording) {
  shards();
  const std::string with_nav = dir + "/flight_with_nav";
  fs::create_directories(with_nav);
  fs::copy_file(database_path(flight), database_path(with_nav));
  exec(with_nav,
       "INSERT INTO nav_input (stream, t_ns, clock, arrival_ns, data) VALUES "
       "('tanker.gps', 5, 'gps', 6, '$GPGGA,one'), ('tanker.imu', 7, 'gps', 8, x'0102'), "
       "('receiver.gps', 9, 'gps', 10, '$GPGGA,two')");
  auto nav = RecordingReader::open(with_nav);
  ASSERT_TRUE(nav) << nav.error().message;
  RecordingMergeReport report;
  ASSERT_TRUE(merge_recordings(parts, dir + "/merged", nav->get(), report));
  EXPECT_EQ(report.nav_inputs, 3u);
  EXPECT_EQ(rows(dir + "/merged", "SELECT stream, t_ns, clock, arrival_ns, data FROM nav_input ORDER BY id"),
            rows(with_nav, "SELECT stream, t_ns, clock, arrival_ns, data FROM nav_input ORDER BY id"));
  auto reader = RecordingReader::open(dir + "/merged");
  ASSERT_TRUE(reader);
  EXPECT_EQ((*reader)->meta("summary.nav_inputs"), "3");
  EXPECT_TRUE((*reader)->check().ok());
}

TEST_F(RecordingMerge, BadPartsAreRefusedByNameAndLeaveNothing) {
  shards();
  RecordingMergeReport report;
  auto error_of = [&](const std::vector<std::string>& p) {
    const Status s = merge_recordings(p, dir + "/merged", nullptr, report);
    EXPECT_FALSE(s);
    EXPECT_FALSE(fs::exists(database_path(dir + "/merged"))) << "nothing half-written";
    return s ? std::string() : s.error().message;
  };
  std::string e = error_of({});
  EXPECT_NE(e.find("recorder::merge_recordings(): no parts to join"), std::string::npos) << e;
  e = error_of({parts[1], parts[0]});
  EXPECT_NE(e.find(database_path(parts[0]) + ": its first frame"), std::string::npos) << e;
  EXPECT_NE(e.find("the parts overlap or are out of order"), std::string::npos) << e;
  e = error_of({parts[0], parts[0]});
  EXPECT_NE(e.find("overlap"), std::string::npos) << e;
  e = error_of({parts[0], dir + "/nowhere"});
  EXPECT_NE(e.find("nowhere"), std::string::npos) << e;
  // A part that was never closed (a shard still running or killed): no summary.
  const std::string open = dir + "/open";
  fs::create_directories(open);
  fs::copy_file(database_path(parts[2]), database_path(open));
  exec(open, "DELETE FROM meta WHERE key LIKE 'summary.%'");
  e = error_of({parts[0], parts[1], open});
  EXPECT_NE(e.find(database_path(open) + ": not closed (no summary)"), std::string::npos) << e;
  // Another rig.
  const std::string other = dir + "/other_rig";
  fs::create_directories(other);
  fs::copy_file(database_path(parts[2]), database_path(other));
  exec(other, "UPDATE meta SET value = value || '# changed' WHERE key = 'rig_yaml'");
  e = error_of({parts[0], parts[1], other});
  EXPECT_NE(e.find(database_path(other) + ": another rig than " + database_path(parts[0])), std::string::npos)
      << e;
  // A stopped part (its status not ok) is joined, and the merged summary says which.
  const std::string failed = dir + "/failed";
  fs::create_directories(failed);
  fs::copy_file(database_path(parts[2]), database_path(failed));
  exec(failed, "UPDATE meta SET value = 'disk full' WHERE key = 'summary.status'");
  ASSERT_TRUE(merge_recordings({parts[0], parts[1], failed}, dir + "/merged", nullptr, report));
  auto reader = RecordingReader::open(dir + "/merged");
  ASSERT_TRUE(reader);
  EXPECT_EQ((*reader)->meta("summary.status"), database_path(failed) + ": disk full");
}

}  // namespace
}  // namespace augrig::recorder
