// Merging a campaign's shards, with the real augrig on two simulated recordings: the joined
// per-frame files equal those of one unsharded `augrig evaluate` / `augrig replay` of each flight,
// row for row, and the tables made from them are the unsharded run's (a scripted boom and an
// evaluation cadence that a shard boundary cuts through included); a shard not done stops the merge
// unless --partial, which merges the rest and says what is missing.
#include "campaign/merge.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "campaign/task.hpp"
#include "recorder/reader.hpp"
#include "recorder/store.hpp"
#include "tests/support/campaign_fixture.hpp"
#include "tests/support/mcap_messages.hpp"
#include "tests/support/output_files.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::campaign {
namespace {

namespace fs = std::filesystem;

using test::lines_of;

struct MergeFixture : test::CampaignFlights {
  // Plans a campaign of `recordings` and `variants` (YAML) in shards of `seconds` and runs every
  // task here (or none).
  Manifest plan_and_run(const std::string& name, const std::string& recordings, const std::string& variants,
                        double seconds, bool run_all = true) {
    const std::string text = "augrig_campaign: 1\nname: " + name + "\nout: " + name +
                             "\nrecordings: " + recordings + "\nvariants:\n" + variants +
                             "shards: {seconds: " + std::to_string(seconds) + "}\n";
    auto spec = parse_campaign(text, dir / "campaign.yaml");
    EXPECT_TRUE(spec) << spec.error().message;
    Manifest m;
    m.file = spec->out / "manifest.yaml";
    m.name = name;
    m.out = spec->out;
    m.augrig = test::augrig_binary();
    std::vector<FlightFrames> frames;
    for (const FlightSpec& f : spec->flights) frames.push_back(*read_flight_frames(f));
    m.tasks = plan_tasks(*spec, frames, {});
    fs::create_directories(m.out);
    EXPECT_TRUE(write_manifest(m));
    if (run_all)
      for (const Task& t : m.tasks) {
        std::ostringstream out, err;
        EXPECT_EQ(run_task(m, t.id, out, err), 0) << out.str() << err.str();
      }
    return m;
  }

  // Flights a and b, a variant of statistics and one of evaluations.
  Manifest run_campaign(const std::string& name, double seconds, bool run_all = true) {
    return plan_and_run(name, "[{path: " + rec_a + ", name: a}, {path: " + rec_b + ", name: b}]",
                        "  - {name: stats}\n  - {name: eval, boom: script:boom.csv, evaluate: {every: 3}}\n",
                        seconds, run_all);
  }

  // Flight a in shards of 1.3 s (three or more), one variant.
  Manifest run_exports(const std::string& name, const std::string& variant) {
    Manifest m = plan_and_run(name, "[{path: " + rec_a + ", name: a}]", "  - " + variant + "\n", 1.3);
    EXPECT_GE(m.tasks.size(), 3u);
    return m;
  }
};

TEST_F(MergeFixture, ShardsMergeIntoTheUnshardedRunFrameForFrame) {
  const Manifest m = run_campaign("sharded", 0.9);
  std::size_t eval_a_shards = 0;
  for (const Task& t : m.tasks) eval_a_shards += t.variant == "eval" && t.flight == "a";
  ASSERT_GE(eval_a_shards, 4u);
  std::ostringstream out;
  auto s = merge_campaign(m, MergeOptions{false, false}, out);
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(s->flights_merged, 4u);
  EXPECT_EQ(s->frames, 2u * (41 + 31));

  expect_equals_unsharded(m.out / "report", "a");
  expect_equals_unsharded(m.out / "report", "b");
  // The campaign's report: a line per flight and variant, the frames adding up.
  const auto csv = lines_of(m.out / "report" / "campaign.csv");
  ASSERT_EQ(csv.size(), 5u);
  EXPECT_EQ(csv[1].rfind("stats,a,", 0), 0u) << csv[1];
  EXPECT_NE(csv[3].find("eval,a,"), std::string::npos) << csv[3];
  const auto txt = lines_of(m.out / "report" / "campaign.txt");
  ASSERT_FALSE(txt.empty());
  EXPECT_NE(txt[0].find("4 flight report(s) merged, 144 stereo frame(s), 25 evaluated"), std::string::npos)
      << txt[0];

  // One shard per flight merges into the same flight reports.
  const Manifest whole = run_campaign("whole", 1000);
  ASSERT_EQ(whole.tasks.size(), 4u);
  ASSERT_TRUE(merge_campaign(whole, MergeOptions{false, false}, out));
  for (const std::string f : {"a", "b"})
    for (const std::string file : {"evaluation.txt", "summary.txt", "evaluation.csv", "stats.csv"})
      EXPECT_EQ(lines_of(whole.out / "report" / "eval" / f / file),
                lines_of(m.out / "report" / "eval" / f / file))
          << f << "/" << file;
}

// exports: [mcap]: each shard's MCAP file joined per flight is the unsharded replay's file, message
// for message (the shards keep the recording's frame indices; one /tf_static; the nav inputs).
TEST_F(MergeFixture, ShardsMcapExportsJoinIntoTheUnshardedReplaysFile) {
  const Manifest m = run_exports("x", "{name: m, boom: script:boom.csv, look: plain, exports: [mcap]}");
  std::ostringstream out;
  ASSERT_TRUE(merge_campaign(m, MergeOptions{false, false}, out));
  EXPECT_NE(out.str().find("flight.mcap: 41 stereo frame(s)"), std::string::npos) << out.str();
  std::string log;
  ASSERT_EQ(test::run_augrig("replay " + rec_a +
                                 " --headless --look plain --boom script:" + (dir / "boom.csv").string() +
                                 " --sink mcap:" + (dir / "whole.mcap").string(),
                             &log),
            0)
      << log;
  // The unsharded file has no nav (a --sink of a replay); the flight's are joined after its frames.
  const auto merged = test::mcap_messages((m.out / "report" / "m" / "a" / "flight.mcap").string());
  const auto whole = test::mcap_messages((dir / "whole.mcap").string());
  ASSERT_GE(merged.size(), whole.size());
  for (std::size_t i = 0; i < whole.size(); ++i) {
    EXPECT_EQ(merged[i].first, whole[i].first) << "message " << i;
    EXPECT_TRUE(merged[i].second == whole[i].second) << merged[i].first;
  }
  for (std::size_t i = whole.size(); i < merged.size(); ++i)
    EXPECT_EQ(merged[i].first.rfind("/nav/", 0), 0u) << merged[i].first;
}

// exports: [euroc]: the shards' EuRoC folders joined per flight are, file for file and byte for
// byte, what one `augrig export FLIGHT OUT --reaugment` with the variant's options writes (the
// recording's clock, its frame indices, the receiver's velocities and the phases across the shards'
// joins); the shards keep their files (the join links them) and a merge again makes it again.
TEST_F(MergeFixture, ShardsEurocExportsJoinIntoTheExportOfTheWholeFlight) {
  const Manifest m = run_exports("e", "{name: e, boom: script:boom.csv, look: plain, exports: [euroc]}");
  std::ostringstream out;
  ASSERT_TRUE(merge_campaign(m, MergeOptions{false, false}, out));
  const fs::path joined = m.out / "report" / "e" / "a" / "euroc";
  EXPECT_NE(out.str().find(joined.string() + ": 41 stereo frame(s) from the shards' EuRoC folders"),
            std::string::npos)
      << out.str();
  std::string log;
  ASSERT_EQ(test::run_augrig("export " + rec_a + " " + (dir / "whole").string() +
                                 " --reaugment --look plain --boom script:" + (dir / "boom.csv").string(),
                             &log),
            0)
      << log;
  const auto merged = test::files_under(joined), whole = test::files_under(dir / "whole");
  for (const auto& [name, bytes] : whole) {
    ASSERT_TRUE(merged.count(name)) << name;
    if (name != "stats.png") {
      EXPECT_TRUE(merged.at(name) == bytes) << name;
    }
  }
  EXPECT_EQ(merged.size(), whole.size());
  for (const char* f : {"mav0/cam0_augmented/data.csv", "mav0/state_groundtruth_estimate0/data.csv",
                        "stats.csv", "frames.csv", "poses.csv", "stats.png"})
    EXPECT_TRUE(merged.count(f)) << f;
  for (const Task& t : m.tasks)
    EXPECT_TRUE(fs::exists(t.out / "euroc" / "mav0" / "cam0" / "data.csv")) << t.id;
  ASSERT_TRUE(merge_campaign(m, MergeOptions{false, false}, out));
  EXPECT_EQ(test::files_under(joined).size(), merged.size());
}

// exports: [recording]: the shards' recordings joined per flight hold, column for column and blob
// for blob, the frames one unsharded `augrig replay FLIGHT --record` with the variant's options
// records, with the flight's nav inputs; `augrig check` finds nothing wrong with it.
TEST_F(MergeFixture, ShardsRecordingsJoinIntoTheUnshardedReplaysRecording) {
  const Manifest m = run_exports("r", "{name: r, boom: script:boom.csv, look: plain, exports: [recording]}");
  std::ostringstream out;
  ASSERT_TRUE(merge_campaign(m, MergeOptions{false, false}, out));
  const fs::path joined = m.out / "report" / "r" / "a" / "recording";
  EXPECT_NE(out.str().find(joined.string() + ": 41 stereo frame(s) from the shards' recordings"),
            std::string::npos)
      << out.str();
  std::string log;
  ASSERT_EQ(test::run_augrig("replay " + rec_a + " --headless --fast --look plain --boom script:" +
                                 (dir / "boom.csv").string() + " --record " + (dir / "whole").string(),
                             &log),
            0)
      << log;
  auto frames_of = [](const fs::path& rec) {
    std::vector<std::string> rows;
    auto db = recorder::Database::open(recorder::database_path(rec.string()), SQLITE_OPEN_READONLY);
    EXPECT_TRUE(db) << db.error().message;
    if (!db) return rows;
    auto st = recorder::Statement::prepare(db->get(), "SELECT * FROM frames ORDER BY id");
    while (st && st->step() == SQLITE_ROW) {
      std::string row;
      for (int c = 0; c < sqlite3_column_count(st->get()); ++c) {
        const auto* p = static_cast<const char*>(sqlite3_column_blob(st->get(), c));
        row += (p ? std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(st->get(), c))) : "NULL") +
               '\x1f';
      }
      rows.push_back(row);
    }
    return rows;
  };
  const auto whole = frames_of(dir / "whole"), merged = frames_of(joined);
  ASSERT_EQ(whole.size(), 41u);
  ASSERT_EQ(merged.size(), whole.size());
  for (std::size_t i = 0; i < whole.size(); ++i) EXPECT_TRUE(merged[i] == whole[i]) << "frame " << i;
  auto flight = recorder::RecordingReader::open(rec_a);
  auto reader = recorder::RecordingReader::open(joined.string());
  ASSERT_TRUE(flight && reader);
  EXPECT_EQ((*reader)->meta("summary.nav_inputs"), (*flight)->meta("summary.nav_inputs"));
  EXPECT_EQ((*reader)->meta("summary.frames"), "41");
  ASSERT_EQ(test::run_augrig("check " + joined.string(), &log), 0) << log;
}

TEST_F(MergeFixture, AShardNotDoneStopsTheMergeUnlessPartial) {
  Manifest m = run_campaign("partial", 1.5, false);
  for (const Task& t : m.tasks) {
    if (t.variant == "eval" && t.flight == "b" && t.shard.index == 1) continue;  // not run
    std::ostringstream out, err;
    ASSERT_EQ(run_task(m, t.id, out, err), 0) << out.str() << err.str();
  }
  std::ostringstream out;
  auto s = merge_campaign(m, MergeOptions{false, false}, out);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("eval/b: shard(s) 1 (task "), std::string::npos) << s.error().message;
  EXPECT_NE(s.error().message.find("merge with --partial"), std::string::npos) << s.error().message;
  s = merge_campaign(m, MergeOptions{true, false}, out);
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(s->flights_merged, 3u);
  EXPECT_EQ(s->flights_incomplete, 1u);
  EXPECT_FALSE(fs::exists(m.out / "report" / "eval" / "b"));
  const auto txt = lines_of(m.out / "report" / "campaign.txt");
  ASSERT_GT(txt.size(), 2u);
  EXPECT_EQ(txt[1], "Not merged (shards not done):");

  // A shard whose files are another command's does not join.
  const Task* t0 = nullptr;
  for (const Task& t : m.tasks)
    if (t.variant == "stats" && t.flight == "a" && t.shard.index == 1) t0 = &t;
  ASSERT_NE(t0, nullptr);
  auto rows = lines_of(t0->out / "stats.csv");
  rows[0] += ",extra";
  std::ofstream o(t0->out / "stats.csv");
  for (const auto& r : rows) o << r << "\n";
  o.close();
  s = merge_campaign(m, MergeOptions{true, false}, out);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("its header differs from the first shard's"), std::string::npos)
      << s.error().message;
}

}  // namespace
}  // namespace augrig::campaign
