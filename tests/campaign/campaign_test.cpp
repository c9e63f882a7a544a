// The campaign file, the shards and the manifest: what a campaign file may say and the located
// errors for what it may not; shards that tile a flight by time, aligned to the evaluation cadence;
// the tasks' command lines; the manifest read back as written.
#include "campaign/campaign.hpp"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "tests/support/test_support.hpp"

namespace augrig::campaign {
namespace {

namespace fs = std::filesystem;

// A folder that looks like a recording to the campaign file (recording.sqlite present).
fs::path fake_recording(const fs::path& dir, const std::string& name) {
  fs::create_directories(dir / name);
  std::ofstream(dir / name / "recording.sqlite") << "x";
  return dir / name;
}

struct Files {
  fs::path dir;
  // A folder per test: CTest runs the tests of this file at once, in separate processes.
  Files()
      : dir(test::output_dir(std::string("campaign_file_") +
                             ::testing::UnitTest::GetInstance()->current_test_info()->name())) {
    fake_recording(dir, "f042");
    fake_recording(dir, "f043");
    fs::create_directories(dir / "euroc" / "mav0");
    std::ofstream(dir / "matcher.yaml") << "algorithm: sgbm\n";
    std::ofstream(dir / "boom.csv") << "t_s,elevation_deg,azimuth_deg,extension_m\n0,30,0,2\n";
    std::ofstream(dir / "poses.csv") << "x\n";
  }
  Expected<CampaignSpec> parse(const std::string& text) const { return parse_campaign(text, dir / "c.yaml"); }
};

TEST(CampaignFile, ReadsFlightsVariantsShardsAndSlurm) {
  const Files f;
  auto s = f.parse(
      "augrig_campaign: 1\n"
      "name: boom-study\n"
      "out: results\n"
      "recordings:\n"
      "  - f042\n"
      "  - {path: f043, name: second, poses: poses.csv}\n"
      "  - {path: euroc, poses: poses.csv}\n"
      "variants:\n"
      "  - name: recorded\n"
      "  - name: scripted\n"
      "    boom: script:boom.csv\n"
      "    rig: default\n"
      "    evaluate: {matcher: matcher.yaml, every: 3, context_px: 64}\n"
      "shards: {seconds: 90}\n"
      "slurm: {partition: batch, cpus_per_task: 4, max_running: 8, extra: [--qos=long]}\n");
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(s->name, "boom-study");
  EXPECT_EQ(s->out, fs::weakly_canonical(f.dir / "results"));
  ASSERT_EQ(s->flights.size(), 3u);
  EXPECT_EQ(s->flights[0].name, "f042");
  EXPECT_EQ(s->flights[0].kind, FlightKind::kRecording);
  EXPECT_TRUE(s->flights[0].poses.empty());
  EXPECT_EQ(s->flights[1].name, "second");
  EXPECT_EQ(s->flights[1].poses, fs::weakly_canonical(f.dir / "poses.csv"));
  EXPECT_EQ(s->flights[2].kind, FlightKind::kEuroc);
  EXPECT_EQ(s->flights[2].name, "euroc");
  ASSERT_EQ(s->variants.size(), 2u);
  EXPECT_FALSE(s->variants[0].evaluate);
  EXPECT_TRUE(s->variants[1].evaluate);
  EXPECT_EQ(s->variants[1].every, 3);
  EXPECT_EQ(s->variants[1].context_px, 64);
  EXPECT_EQ(s->variants[1].boom, "script:" + fs::weakly_canonical(f.dir / "boom.csv").string());
  EXPECT_EQ(s->variants[1].rig, "default");
  EXPECT_EQ(s->variants[1].matcher, fs::weakly_canonical(f.dir / "matcher.yaml").string());
  ASSERT_TRUE(s->shard_seconds);
  EXPECT_EQ(*s->shard_seconds, 90);
  EXPECT_EQ(s->slurm.partition, "batch");
  EXPECT_EQ(s->slurm.cpus_per_task, 4);
  EXPECT_EQ(s->slurm.max_running, 8);
  ASSERT_EQ(s->slurm.extra.size(), 1u);
}

TEST(CampaignFile, WithoutVariantsTheRecordingIsReplayedAsRecorded) {
  const Files f;
  auto s = f.parse("augrig_campaign: 1\nname: c\nout: o\nrecordings: [f042]\n");
  ASSERT_TRUE(s) << s.error().message;
  ASSERT_EQ(s->variants.size(), 1u);
  EXPECT_EQ(s->variants[0].name, "recorded");
  EXPECT_FALSE(s->variants[0].evaluate);
  EXPECT_FALSE(s->shard_seconds);
  EXPECT_EQ(s->task_minutes, 30);
}

TEST(CampaignFile, ErrorsNameTheLineTheKeyAndWhatWasExpected) {
  const Files f;
  const std::string head = "augrig_campaign: 1\nname: c\nout: o\n";
  struct Case {
    std::string text, want;
  };
  const Case cases[] = {
      {head + "recordings: [f042]\nvariants:\n  - name: v\n    bom: track\n",
       "c.yaml:7:5: key 'variants[0].bom': unknown key; allowed keys here: name, rig, boom"},
      {head + "recordings: [nowhere]\n",
       "key 'recordings[0]': expected a recording, EuRoC folder or MCAP file, but"},
      {head + "recordings: [matcher.yaml]\n", "is none of them"},
      {head + "recordings: [f042, f042]\n", "two flights are named 'f042'"},
      {head + "recordings: []\n", "key 'recordings': expected a list of at least one recording"},
      {head + "recordings: [euroc]\n", "a EuRoC folder holds no receiver poses"},
      {head + "recordings: [f042]\nvariants: [{name: v, evaluate: {every: 0}}]\n",
       "key 'variants[0].evaluate.every': expected a whole number in [1, 1000000], got '0'"},
      {head + "recordings: [f042]\nvariants: [{name: v, boom: sideways}]\n",
       "key 'variants[0].boom': expected track, fixed:EL_DEG,AZ_DEG,EXT_M or script:FILE.csv"},
      {head + "recordings: [f042]\nvariants: [{name: 'a b'}]\n", "key 'variants[0].name': expected a name"},
      {head + "recordings: [f042]\nvariants: [{name: v, exports: [mcap, kitti]}]\n",
       "key 'variants[0].exports': expected mcap, euroc or recording (the formats a shard can write and the "
       "merge join), got 'kitti'"},
      {head + "recordings: [f042]\nvariants: [{name: v, exports: mcap}]\n",
       "key 'variants[0].exports': expected a list of export formats ([mcap, euroc, recording])"},
      {head + "recordings: [f042]\nvariants: [{name: v, evaluate: true, exports: [recording]}]\n",
       "exports are written by replay variants (without evaluate)"},
      {head + "recordings: [f042]\nvariants: [{name: v, evaluate: true, exports: [euroc]}]\n",
       "exports are written by replay variants (without evaluate)"},
      {head + "recordings: [f042]\nvariants: [{name: v, evaluate: true, exports: [mcap]}]\n",
       "exports are written by replay variants (without evaluate)"},
      {head + "recordings: [f042]\nvariants: [{name: v, look: shiny}]\n",
       "key 'variants[0].look': expected plain or camera, got 'shiny'"},
      {head + "recordings: [f042]\nslurm: {extra: [--array=0-3]}\n", "--array is set by the plan"},
      {head + "recordings: [f042]\nshards: {seconds: 10, task_minutes: 5}\n", "give seconds or task_minutes"},
      {head + "recordings: [f042]\nshards: {seconds: -1}\n", "key 'shards.seconds': expected seconds > 0"},
      {"augrig_campaign: 2\nname: c\nout: o\nrecordings: [f042]\n", "expected the format version 1"},
      {"name: c\nout: o\nrecordings: [f042]\n", "key 'augrig_campaign': missing"},
      {head + "recordings: [f042\n", "YAML syntax error"},
  };
  for (const Case& c : cases) {
    auto s = f.parse(c.text);
    ASSERT_FALSE(s) << c.text;
    EXPECT_NE(s.error().message.find(c.want), std::string::npos) << s.error().message;
    EXPECT_EQ(s.error().message.rfind("campaign::load(): ", 0), 0u) << s.error().message;
  }
  auto missing = load_campaign(f.dir / "absent.yaml");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("absent.yaml: cannot read the campaign file"), std::string::npos);
}

FlightFrames frames_every(double dt_s, std::size_t n) {
  FlightFrames f;
  for (std::size_t i = 0; i < n; ++i)
    f.t_ns.push_back(1'000'000'000'000 +
                     static_cast<std::int64_t>(i) * static_cast<std::int64_t>(dt_s * 1e9 + 0.5));
  return f;
}

// The shards cover [0, n) once, in order.
void expect_tiling(const std::vector<Shard>& s, std::size_t n) {
  std::size_t next = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    EXPECT_EQ(s[i].index, i);
    EXPECT_EQ(s[i].from_frame, next);
    EXPECT_GT(s[i].frames, 0u);
    next += s[i].frames;
  }
  EXPECT_EQ(next, n);
}

TEST(Shards, CutAFlightByRecordedTime) {
  const FlightFrames f = frames_every(0.1, 95);  // 9.4 s at 10 Hz
  const auto s = split_flight(f, 2.0);
  expect_tiling(s, 95);
  ASSERT_EQ(s.size(), 5u);
  EXPECT_EQ(s[0].frames, 20u);
  EXPECT_NEAR(s[1].t_from_s, 2.0, 1e-9);
  EXPECT_NEAR(s[4].t_to_s, 9.4, 1e-9);
  EXPECT_EQ(s[4].frames, 15u);
  // Longer than the flight: one shard.
  expect_tiling(split_flight(f, 100), 95);
  EXPECT_EQ(split_flight(f, 100).size(), 1u);
}

TEST(Shards, StartOnTheEvaluationCadenceAndSurviveGapsAndUnreadableFrames) {
  FlightFrames f = frames_every(0.1, 60);
  f.t_ns[7].reset();
  f.t_ns[8].reset();
  for (std::size_t i = 30; i < 60; ++i) *f.t_ns[i] += 5'000'000'000;  // a 5 s gap
  const auto s = split_flight(f, 1.0, 4);
  expect_tiling(s, 60);
  for (const Shard& x : s) EXPECT_EQ(x.from_frame % 4, 0u) << x.from_frame;
  // Time, not frame count, cuts: the gap ends a shard.
  bool cut_at_gap = false;
  for (const Shard& x : s) cut_at_gap = cut_at_gap || x.from_frame == 32;
  EXPECT_TRUE(cut_at_gap);
  FlightFrames mcap;
  mcap.splittable = false;
  const auto one = split_flight(mcap, 1.0);
  ASSERT_EQ(one.size(), 1u);
}

// A clock that steps back (an hour, then a repeated time) must not make one shard of the rest of
// the flight: the step counts as a typical frame interval, and every shard stays ~2 s.
TEST(Shards, AClockThatStepsBackStillCutsShardsOfTheAskedLength) {
  FlightFrames f = frames_every(0.1, 200);                                 // 19.9 s at 10 Hz
  for (std::size_t i = 70; i < 200; ++i) *f.t_ns[i] -= 3'600'000'000'000;  // back an hour at frame 70
  *f.t_ns[150] = *f.t_ns[149];                                             // one time repeated
  const FlightClock c = flight_clock(f);
  EXPECT_EQ(c.steps_back, 2u);
  EXPECT_EQ(c.first_step_back_frame, 70u);
  EXPECT_NEAR(c.largest_step_back_s, 3600 - 0.1, 1e-6);
  // 19.9 s of frames: the hour back counts 0.1 s; the repeated time 0.1 s more, the step after it
  // its true 0.2 s.
  EXPECT_NEAR(c.elapsed_s.back(), 20.0, 1e-6);
  for (std::size_t i = 1; i < c.elapsed_s.size(); ++i) EXPECT_GT(c.elapsed_s[i], c.elapsed_s[i - 1]) << i;
  const auto s = split_flight(f, 2.0, 3);
  expect_tiling(s, 200);
  for (const Shard& x : s) {
    EXPECT_LE(x.frames, 24u) << "shard " << x.index;  // 20 frames, moved up to a multiple of 3
    EXPECT_EQ(x.from_frame % 3, 0u);
  }
  EXPECT_GE(s.size(), 9u);
  // A clock that never steps back counts exactly its time since the first frame.
  const FlightClock m = flight_clock(frames_every(0.1, 95));
  EXPECT_EQ(m.steps_back, 0u);
  EXPECT_EQ(m.elapsed_s[20], 2.0);
}

TEST(Tasks, OneCommandPerShardAndVariant) {
  const Files f;
  auto spec = f.parse(
      "augrig_campaign: 1\nname: c\nout: o\nrecordings: [f042, {path: f043, poses: poses.csv}]\n"
      "variants:\n  - {name: stats}\n  - {name: eval, boom: 'fixed:30,0,2', evaluate: {every: 5, full_frame: "
      "true}}\n"
      "shards: {seconds: 3}\n");
  ASSERT_TRUE(spec) << spec.error().message;
  const std::vector<FlightFrames> frames = {frames_every(0.1, 100), frames_every(0.1, 40)};
  const auto tasks = plan_tasks(*spec, frames, {});
  // stats: 4 + 2 shards; eval: shards of 30 frames aligned to 5: 4 + 2.
  ASSERT_EQ(tasks.size(), 12u);
  for (std::size_t i = 0; i < tasks.size(); ++i) EXPECT_EQ(tasks[i].id, i);
  const Task& t = tasks[1];
  EXPECT_EQ(t.variant, "stats");
  EXPECT_EQ(t.flight, "f042");
  EXPECT_EQ(t.out, spec->out / "shards" / "stats" / "f042" / "0001");
  const std::vector<std::string> want = {"replay",         (f.dir / "f042").string(),
                                         "--from-frame",   "30",
                                         "--frames",       "30",
                                         "--fast",         "--headless",
                                         "--every",        "1000000",
                                         "--allow-damaged"};
  EXPECT_EQ(t.argv, want);
  const Task& e = tasks[7];
  EXPECT_EQ(e.variant, "eval");
  EXPECT_EQ(e.argv[0], "evaluate");
  auto has = [&](const Task& x, const std::vector<std::string>& seq) {
    return std::search(x.argv.begin(), x.argv.end(), seq.begin(), seq.end()) != x.argv.end();
  };
  EXPECT_TRUE(has(e, {"--boom", "fixed:30,0,2"}));
  EXPECT_TRUE(has(e, {"--every", "5"}));
  EXPECT_TRUE(has(e, {"--full-frame"}));
  EXPECT_TRUE(has(tasks[10], {"--poses", (fs::weakly_canonical(f.dir / "poses.csv")).string()}));
  // A variant's look, and its MCAP export into the task's folder ({out}: run_task puts it in).
  auto x = f.parse(
      "augrig_campaign: 1\nname: c\nout: o\nrecordings: [f042]\n"
      "variants: [{name: m, look: plain, exports: [mcap]}, {name: e, exports: [euroc, mcap, recording]}]\n");
  ASSERT_TRUE(x) << x.error().message;
  const auto xt = plan_tasks(*x, {frames_every(0.1, 10)}, {});
  ASSERT_EQ(xt.size(), 2u);
  EXPECT_TRUE(has(xt[0], {"--look", "plain"}));
  EXPECT_TRUE(has(xt[0], {"--sink", "mcap:{out}/flight.mcap"}));
  EXPECT_FALSE(has(xt[0], {"--sink", "euroc:{out}/euroc,nav,no-plot"}));
  EXPECT_FALSE(has(xt[0], {"--record", "{out}/recording"}));
  // EuRoC: on the recording's clock with its nav inputs (nav), plotted once by the merge.
  EXPECT_TRUE(has(xt[1], {"--sink", "euroc:{out}/euroc,nav,no-plot"}));
  EXPECT_TRUE(has(xt[1], {"--sink", "mcap:{out}/flight.mcap"}));
  // The re-augmented frames recorded into the task's folder, joined per flight by the merge.
  EXPECT_TRUE(has(xt[1], {"--record", "{out}/recording"}));
  for (const Task& x : tasks) {
    if (x.variant == "eval") {
      EXPECT_EQ(x.shard.from_frame % 5, 0u);
    }
  }

  // task_minutes at the measured cost: 2 minutes at 0.5 s per frame is 240 frames = 24 s at 10 Hz.
  spec->shard_seconds.reset();
  spec->task_minutes = 2;
  const auto sized =
      plan_tasks(*spec, {frames_every(0.1, 500), frames_every(0.1, 40)},
                 {{"stats", TaskCost{1, 0.5, 1 << 20, ""}}, {"eval", TaskCost{1, 0.5, 1 << 20, ""}}});
  EXPECT_EQ(sized[0].shard.frames, 240u);
}

TEST(Manifest, ReadsBackWhatWasWritten) {
  const fs::path dir = test::output_dir("campaign_manifest");
  Manifest m;
  m.file = dir / "manifest.yaml";
  m.name = "study";
  m.campaign_file = dir / "c.yaml";
  m.out = dir;
  m.augrig = "/usr/bin/augrig with space";
  m.planned_at = "2026-11-27T06:00:00Z";
  m.heartbeat_s = 0.5;
  m.slurm.partition = "gpu";
  m.slurm.extra = {"--qos=long", "--constraint=avx2"};
  m.slurm.max_running = 3;
  m.costs = {{"v", TaskCost{1.25, 0.1 + 0.2, 123456789, "flight a, frames 0..7"}}};
  Task t;
  t.id = 0;
  t.flight = "a";
  t.variant = "v";
  t.shard = Shard{0, 0, 12, 0, 1.1};
  t.out = dir / "shards" / "v" / "a" / "0000";
  t.argv = {"evaluate", "/data/flight 1/rec", "--boom", "script:/x/it's.csv"};
  m.tasks = {t};
  ASSERT_TRUE(write_manifest(m));
  auto r = load_manifest(m.file);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->name, m.name);
  EXPECT_EQ(r->augrig, m.augrig);
  EXPECT_EQ(r->heartbeat_s, 0.5);
  EXPECT_EQ(r->slurm.partition, "gpu");
  EXPECT_EQ(r->slurm.extra, m.slurm.extra);
  EXPECT_EQ(r->slurm.max_running, 3);
  ASSERT_EQ(r->costs.size(), 1u);
  EXPECT_EQ(r->costs[0].second.per_frame_s, 0.1 + 0.2);  // exactly
  EXPECT_EQ(r->costs[0].second.max_rss_bytes, 123456789);
  ASSERT_EQ(r->tasks.size(), 1u);
  EXPECT_EQ(r->tasks[0].argv, t.argv);
  EXPECT_EQ(r->tasks[0].out, t.out);
  EXPECT_EQ(r->tasks[0].shard.t_to_s, 1.1);
  EXPECT_FALSE(fs::exists(m.file.string() + ".tmp"));

  std::ofstream(dir / "broken.yaml")
      << "augrig_campaign_manifest: 1\nname: x\ncampaign: c\nout: o\naugrig: a\n"
         "tasks:\n  - {id: 1, flight: a}\n";
  auto bad = load_manifest(dir / "broken.yaml");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("broken.yaml:7:5: key 'tasks[0].id': expected 0 (tasks in order)"),
            std::string::npos)
      << bad.error().message;
  auto none = load_manifest(dir / "none.yaml");
  ASSERT_FALSE(none);
  EXPECT_NE(none.error().message.find("plan the campaign first"), std::string::npos);
}

TEST(Manifest, SlurmTimeIsRoundedUpToWholeMinutes) {
  EXPECT_EQ(slurm_time(1), "0-00:01:00");
  EXPECT_EQ(slurm_time(61), "0-00:02:00");
  EXPECT_EQ(slurm_time(3600), "0-01:00:00");
  EXPECT_EQ(slurm_time(86400 + 59), "1-00:01:00");
}

}  // namespace
}  // namespace augrig::campaign
