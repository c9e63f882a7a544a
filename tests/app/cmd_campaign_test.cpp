// augrig campaign through the real binary. Without a cluster: plan (measured cost, manifest,
// scripts), status from the files, resume --local, merge, and the errors. On a real single-node
// Slurm (Debian's slurm-wlm and munge, started here as root on loopback; skipped with the reason
// where that cannot be done): plan --submit, wait, merge and compare with the unsharded runs frame
// for frame; then a task killed with SIGKILL (task and command) and one cancelled with scancel
// mid-way, seen stopped and failed from their files, resumed, and merged to the same result.
#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include "recorder/store.hpp"
#include "tests/support/campaign_fixture.hpp"
#include "tests/support/local_slurm.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;

using test::lines_of;

std::string flag_output(const std::string& out, const std::string& pattern) {
  std::smatch m;
  return std::regex_search(out, m, std::regex(pattern)) ? m[1].str() : "";
}

struct CampaignCli : test::CampaignFlights {
  // A campaign of both recordings: the recorded statistics, and a scripted boom evaluated every
  // 3rd frame (or `variants` instead); shards of `seconds`.
  fs::path campaign_file(const std::string& name, const std::string& shards, const std::string& slurm = "",
                         const std::string& variants =
                             "  - name: stats\n  - name: eval\n    boom: script:boom.csv\n"
                             "    evaluate: {every: 3}\n") {
    const fs::path f = dir / (name + ".yaml");
    std::ofstream(f) << "augrig_campaign: 1\nname: " << name << "\nout: " << name << "-out\n"
                     << "recordings:\n  - {path: " << rec_a << ", name: a}\n  - {path: " << rec_b
                     << ", name: b}\n"
                     << "variants:\n"
                     << variants << "shards: " << shards << "\n"
                     << slurm;
    return f;
  }
};

TEST_F(CampaignCli, PlansMeasuresRunsLocallyAndMerges) {
  const fs::path file = campaign_file("local", "{seconds: 1.2}");
  std::string out;
  ASSERT_EQ(test::run_augrig("campaign plan " + file.string() + " --measure-frames 4", &out), 0) << out;
  for (const std::string want : {"campaign 'local': 2 flight(s), 2 variant(s)", "flight a (recording, ",
                                 "41 stereo frame(s) over 4.0 s", "31 stereo frame(s) over 3.0 s",
                                 "variant stats: ", "variant eval: ", " ms per frame, start-up ",
                                 "core-hour(s)", "array script(s), each task asking 2 CPU(s), "})
    EXPECT_NE(out.find(want), std::string::npos) << want << "\n" << out;
  const fs::path o = dir / "local-out";
  ASSERT_TRUE(fs::exists(o / "manifest.yaml"));
  ASSERT_TRUE(fs::exists(o / "slurm" / "campaign-0.sbatch"));
  const std::string tasks = flag_output(out, "\\n(\\d+) task\\(s\\):");
  ASSERT_FALSE(tasks.empty()) << out;
  const int n = std::stoi(tasks);
  EXPECT_GE(n, 12);  // 4 s and 3 s flights in 1.2 s shards, two variants

  ASSERT_EQ(test::run_augrig("campaign status " + o.string(), &out), 0) << out;
  EXPECT_NE(out.find("tasks " + tasks + " = done 0 + running 0 + failed 0 + stopped 0 + pending " + tasks),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("not done: augrig campaign resume"), std::string::npos) << out;
  // Merging before anything ran says what is missing.
  EXPECT_EQ(test::run_augrig("campaign merge " + o.string(), &out), 1) << out;
  EXPECT_NE(out.find("stats/a: shard(s) 0 (task 0)"), std::string::npos) << out;

  ASSERT_EQ(test::run_augrig("campaign resume " + o.string() + " --local --jobs 2", &out), 0) << out;
  EXPECT_NE(out.find(tasks + " of " + tasks + " task(s) ended (" + tasks + " ok, 0 failed)"),
            std::string::npos)
      << out;
  ASSERT_EQ(test::run_augrig("campaign status " + (o / "manifest.yaml").string() + " --tasks", &out), 0)
      << out;
  EXPECT_NE(out.find("tasks " + tasks + " = done " + tasks + " + running 0"), std::string::npos) << out;
  EXPECT_NE(out.find("all done: augrig campaign merge"), std::string::npos) << out;
  ASSERT_EQ(test::run_augrig("campaign resume " + o.string(), &out), 0) << out;
  EXPECT_NE(out.find("nothing to resume: " + tasks + " of " + tasks + " task(s) done"), std::string::npos)
      << out;

  ASSERT_EQ(test::run_augrig("campaign merge " + o.string() + " --no-plot", &out), 0) << out;
  EXPECT_NE(out.find("(4 flight report(s), 144 frame(s), 25 evaluated)"), std::string::npos) << out;
  expect_equals_unsharded(o / "report", "a");
  expect_equals_unsharded(o / "report", "b");
}

// Flights of other images cost other time and memory per frame: the plan measures a variant on
// one flight of each kind and gives every task the largest cost of them.
TEST_F(CampaignCli, EachKindOfImagesIsMeasuredAndTasksGetTheLargestCost) {
  std::string why;
  const std::string rec_c = test::sim_recording("campaign/flight_c.yaml", 3, "campaign_c", &why);
  ASSERT_FALSE(rec_c.empty()) << why;
  const fs::path file = dir / "kinds.yaml";
  std::ofstream(file) << "augrig_campaign: 1\nname: kinds\nout: kinds-out\nrecordings:\n  - {path: " << rec_a
                      << ", name: a}\n  - {path: " << rec_b << ", name: b}\n  - {path: " << rec_c
                      << ", name: c}\nvariants:\n  - name: stats\nshards: {seconds: 1}\n";
  std::string out;
  ASSERT_EQ(test::run_augrig("campaign plan " + file.string() + " --measure-frames 3", &out), 0) << out;
  EXPECT_NE(out.find("on each of 2 kinds of images: a task is given the largest cost"), std::string::npos)
      << out;
  // a and c measured (b's images are a's), each line naming its images.
  const std::string a_line = flag_output(out, "(variant stats: [^\\n]*flight a, [^\\n]*)");
  const std::string c_line = flag_output(out, "(variant stats: [^\\n]*flight c, [^\\n]*)");
  EXPECT_TRUE(std::regex_search(a_line, std::regex("images \\S+ 640x480 \\+ \\S+ 640x480\\)$"))) << out;
  EXPECT_TRUE(std::regex_search(c_line, std::regex("images \\S+ 320x240 \\+ \\S+ 320x240\\)$"))) << out;
  EXPECT_EQ(out.find("flight b, frames"), std::string::npos) << out;
  // The manifest's cost is the larger of the two measurements, field by field.
  auto ms = [&](const std::string& line, const std::string& pattern) {
    return std::stod(flag_output(line, pattern));
  };
  const std::string manifest = [&] {
    std::ifstream in(dir / "kinds-out" / "manifest.yaml");
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }();
  const double per_frame_s = ms(manifest, "per_frame_s: ([0-9.e+-]+)");
  EXPECT_NEAR(per_frame_s * 1000,
              std::max(ms(a_line, ": ([0-9.]+) ms per frame"), ms(c_line, ": ([0-9.]+) ms per frame")), 0.051)
      << manifest;
  EXPECT_NE(manifest.find("flight a, frames 0..3"), std::string::npos) << manifest;
  EXPECT_NE(manifest.find("; flight c, frames 0..3"), std::string::npos) << manifest;
}

// A flight with a damaged frame: the shard holding it is done, not failed on every run; the frame
// is left out and counted (the task, status, merge, the report), and the merged files equal the
// unsharded runs', which leave the same frame out.
TEST_F(CampaignCli, ADamagedFrameIsLeftOutAndCountedNotAShardFailedForever) {
  const fs::path bad = dir / "damaged";
  fs::create_directories(bad);
  fs::copy_file(fs::path(rec_a) / "recording.sqlite", bad / "recording.sqlite");
  {
    auto d = recorder::Database::open((bad / "recording.sqlite").string(), SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(d);
    // Frame 6 (evaluated: a multiple of 3): its left raw blob's byte 101 zeroed.
    ASSERT_TRUE(
        d->exec("UPDATE frames SET left_raw = CAST(substr(left_raw, 1, 100) || x'00' || substr(left_raw, "
                "102) AS BLOB) "
                "WHERE id = (SELECT id FROM frames ORDER BY id LIMIT 1 OFFSET 6)"));
  }
  std::string out;
  ASSERT_EQ(test::run_augrig("check " + bad.string(), &out), 1) << out;  // the damage is real
  const fs::path file = dir / "damaged.yaml";
  std::ofstream(file) << "augrig_campaign: 1\nname: damaged\nout: damaged-out\nrecordings:\n  - {path: "
                      << bad.string()
                      << ", name: a}\nvariants:\n  - name: stats\n  - name: eval\n    boom: script:boom.csv\n"
                         "    evaluate: {every: 3}\nshards: {seconds: 1.0}\n";
  ASSERT_EQ(test::run_augrig("campaign plan " + file.string() + " --measure-frames 3", &out), 0) << out;
  const fs::path o = dir / "damaged-out";
  ASSERT_EQ(test::run_augrig("campaign resume " + o.string() + " --local --jobs 2", &out), 0) << out;
  const std::string tasks = flag_output(out, "(\\d+) of \\d+ task\\(s\\) not done");
  ASSERT_FALSE(tasks.empty()) << out;
  EXPECT_NE(out.find(tasks + " of " + tasks + " task(s) ended (" + tasks + " ok, 0 failed)"),
            std::string::npos)
      << out;
  ASSERT_EQ(test::run_augrig("campaign status " + o.string() + " --tasks", &out), 0) << out;
  EXPECT_NE(out.find("tasks " + tasks + " = done " + tasks + " + running 0"), std::string::npos) << out;
  EXPECT_NE(out.find("stats/a: tasks "), std::string::npos) << out;
  EXPECT_NE(out.find("; 1 frame(s) left out\n"), std::string::npos) << out;
  EXPECT_NE(out.find("left out: 2 frame(s) in 2 done shard(s)"), std::string::npos) << out;
  EXPECT_TRUE(std::regex_search(
      out, std::regex("task \\d+ \\(stats/a shard 0, frames 0\\+\\d+\\): done, 1 frame\\(s\\) left out")))
      << out;
  ASSERT_EQ(test::run_augrig("campaign merge " + o.string() + " --no-plot", &out), 0) << out;
  EXPECT_NE(out.find("merged stats/a: "), std::string::npos) << out;
  EXPECT_NE(out.find(" 40 frame(s), 1 left out (damaged input"), std::string::npos) << out;
  const auto csv = lines_of(o / "report" / "campaign.csv");
  ASSERT_EQ(csv.size(), 3u);
  EXPECT_NE(csv[0].find(",frames_left_out"), std::string::npos) << csv[0];
  EXPECT_EQ(csv[1].substr(csv[1].rfind(',')), ",1") << csv[1];
  rec_a = bad.string();  // the unsharded runs of the damaged copy
  expect_equals_unsharded(o / "report", "a");
}

// An MCAP flight is read whole: one shard, of the frames its statistics count (its time limit and
// its frames left out follow from them). One cut short fails the plan, naming the file and why,
// rather than every task that would read it.
TEST_F(CampaignCli, AnMcapFlightIsOneShardOfItsFramesAndADamagedOneFailsThePlan) {
  const fs::path mcap = dir / "a.mcap";
  std::string out;
  ASSERT_EQ(test::run_augrig("export " + rec_a + " --format mcap " + mcap.string() + " 2>&1", &out), 0)
      << out;
  auto campaign = [&](const std::string& name, const fs::path& flight) {
    const fs::path file = dir / (name + ".yaml");
    std::ofstream(file) << "augrig_campaign: 1\nname: " << name << "\nout: " << name
                        << "-out\nrecordings:\n  - " << rec_a << "\n  - {path: " << flight.string()
                        << ", name: m}\nvariants:\n  - name: stats\n";
    return file;
  };
  ASSERT_EQ(
      test::run_augrig("campaign plan " + campaign("whole", mcap).string() + " --measure-frames 3", &out), 0)
      << out;
  EXPECT_NE(
      out.find("flight m (MCAP file, " + mcap.string() + "): read whole (one shard), 41 stereo frame(s)"),
      std::string::npos)
      << out;
  const fs::path o = dir / "whole-out";
  ASSERT_EQ(test::run_augrig("campaign resume " + o.string() + " --local --jobs 2", &out), 0) << out;
  ASSERT_EQ(test::run_augrig("campaign status " + o.string() + " --tasks", &out), 0) << out;
  // Both flights' 41 frames counted: the MCAP one's from its statistics (it counted 0 before).
  EXPECT_NE(out.find("done: 82 frame(s) in "), std::string::npos) << out;
  EXPECT_EQ(out.find("left out"), std::string::npos) << out;

  const fs::path cut = dir / "cut.mcap";
  fs::copy_file(mcap, cut);
  fs::resize_file(cut, fs::file_size(cut) / 2);
  EXPECT_EQ(test::run_augrig("campaign plan " + campaign("cut", cut).string() + " --measure-frames 3", &out),
            1)
      << out;
  EXPECT_NE(out.find("recorder::McapReader: " + cut.string() + ": offset "), std::string::npos) << out;
  EXPECT_NE(out.find("the file is truncated"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir / "cut-out" / "manifest.yaml"));
}

TEST_F(CampaignCli, BadInputsSayWhatAndWhere) {
  std::string out;
  EXPECT_EQ(test::run_augrig("campaign", &out), 2) << out;
  EXPECT_EQ(test::run_augrig("campaign launch x", &out), 2) << out;
  EXPECT_NE(out.find("expected plan, status, resume, merge or task, got 'launch'"), std::string::npos) << out;
  EXPECT_EQ(test::run_augrig("campaign status x --submit", &out), 2) << out;
  EXPECT_NE(out.find("--submit is not an option of 'campaign status'"), std::string::npos) << out;
  const fs::path bad = dir / "bad.yaml";
  std::ofstream(bad) << "augrig_campaign: 1\nname: bad\nout: o\nrecordings:\n  - " << rec_a
                     << "\nvariants:\n  - {name: v, evaluate: {every: many}}\n";
  EXPECT_EQ(test::run_augrig("campaign plan " + bad.string(), &out), 1) << out;
  EXPECT_NE(out.find("bad.yaml:7:"), std::string::npos) << out;
  EXPECT_NE(out.find("key 'variants[0].evaluate.every'"), std::string::npos) << out;
  // A variant that fails on every shard fails the plan, with the command's own words.
  const fs::path broken = dir / "broken.yaml";
  std::ofstream(broken) << "augrig_campaign: 1\nname: broken\nout: o\nrecordings: [" << rec_a
                        << "]\nvariants:\n  - {name: v, rig: " << test::data_path("rigs/example.yaml")
                        << "}\n";
  EXPECT_EQ(test::run_augrig("campaign plan " + broken.string(), &out), 1) << out;
  EXPECT_NE(out.find("variant 'v' fails on flight"), std::string::npos) << out;
  EXPECT_EQ(test::run_augrig("campaign status " + (dir / "nowhere").string(), &out), 1) << out;
  EXPECT_NE(out.find("plan the campaign first"), std::string::npos) << out;
  EXPECT_EQ(test::run_augrig("campaign task " + (dir / "nowhere").string() + " x", &out), 2) << out;
}

// ---- On a real Slurm ------------------------------------------------------------------------------

class CampaignSlurm : public CampaignCli {
 protected:
  static void SetUpTestSuite() {
    if (const std::string why = test::LocalSlurm::missing_requirements(); !why.empty()) {
      skip_ = why;
      return;
    }
    // CTest runs each test in its own process, maybe at once: a cluster (and folder) per process.
    auto s = test::LocalSlurm::start(
        fs::path(AUGRIG_TEST_OUTPUT_DIR) / ("cmd_campaign_slurm_" + std::to_string(::getpid())), 2);
    if (!s) {
      skip_ = s.error().message;
      return;
    }
    cluster_ = std::move(*s);
    cluster_->apply_env();  // augrig's sbatch calls reach this cluster
  }
  static void TearDownTestSuite() {
    if (!cluster_) return;
    const fs::path d = cluster_->dir();
    cluster_.reset();  // stops it: nothing of it outlives the test
    std::error_code ec;
    fs::remove_all(d, ec);
  }
  void SetUp() override {
    if (!cluster_) GTEST_SKIP() << "no local Slurm cluster: " << skip_;
    CampaignFlights::SetUp();
  }
  // Waits for the job a "submitted ... as job N" line names.
  void wait_for(const std::string& out) {
    const std::string job = flag_output(out, "as job (\\d+)");
    ASSERT_FALSE(job.empty()) << out;
    auto done = cluster_->wait_for_jobs(job, 240);
    ASSERT_TRUE(done) << done.error().message << "\n" << cluster_->log_tail();
  }
  static inline std::unique_ptr<test::LocalSlurm> cluster_;
  static inline std::string skip_;
};

TEST_F(CampaignSlurm, SubmittedArrayMergesIntoTheUnshardedRun) {
  const fs::path file = campaign_file("cluster", "{seconds: 1.5}", "slurm: {cpus_per_task: 1}\n");
  const fs::path o = dir / "cluster-out";
  std::string out;
  ASSERT_EQ(test::run_augrig("campaign plan " + file.string() + " --measure-frames 3 --submit", &out), 0)
      << out;
  EXPECT_NE(out.find("submitted campaign-0.sbatch as job "), std::string::npos) << out;
  wait_for(out);
  const std::string tasks = flag_output(out, "\\n(\\d+) task\\(s\\):");
  ASSERT_EQ(test::run_augrig("campaign status " + o.string(), &out), 0) << out;
  EXPECT_NE(out.find("tasks " + tasks + " = done " + tasks + " + "), std::string::npos)
      << out << "\n"
      << cluster_->log_tail();
  // Every array task logged where Slurm was told to.
  std::size_t logs = 0;
  for (const auto& e : fs::directory_iterator(o / "logs"))
    logs += e.path().filename().string().rfind("slurm-", 0) == 0;
  EXPECT_EQ(logs, static_cast<std::size_t>(std::stoi(tasks)));
  ASSERT_EQ(test::run_augrig("campaign merge " + o.string() + " --no-plot", &out), 0) << out;
  expect_equals_unsharded(o / "report", "a");
  expect_equals_unsharded(o / "report", "b");

  // sbatch's own refusal comes back as the command's error.
  const fs::path bad = campaign_file("badpart", "{seconds: 1.5}", "slurm: {partition: nosuchpartition}\n");
  EXPECT_EQ(test::run_augrig("campaign plan " + bad.string() + " --per-frame-s 0.1 --submit", &out), 1)
      << out;
  std::string lower = out;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  EXPECT_NE(lower.find("invalid partition"), std::string::npos) << out;
}

TEST_F(CampaignSlurm, KilledAndCancelledTasksAreSeenAndResumed) {
  // One shard per flight, evaluated whole-frame every frame (some seconds a task), one CPU each:
  // both run at once.
  const fs::path file =
      campaign_file("killed", "{seconds: 100}", "slurm: {cpus_per_task: 1}\n",
                    "  - name: eval\n    boom: script:boom.csv\n    evaluate: {full_frame: true}\n");
  const fs::path o = dir / "killed-out";
  std::string out;
  ASSERT_EQ(test::run_augrig(
                "campaign plan " + file.string() + " --per-frame-s 0.2 --heartbeat-s 0.5 --submit", &out),
            0)
      << out;
  const std::string job = flag_output(out, "as job (\\d+)");
  ASSERT_FALSE(job.empty()) << out;
  // Both tasks at work, as their own files say (Slurm's RUNNING comes before the task starts).
  bool both = false;
  const auto t0 = std::chrono::steady_clock::now();
  while (!both && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    both = fs::exists(o / "shards/eval/a/0000.partial/heartbeat") &&
           fs::exists(o / "shards/eval/b/0000.partial/heartbeat");
  }
  ASSERT_TRUE(both) << cluster_->log_tail();
  // One killed outright with SIGKILL, the task before its command (as the OOM killer or a lost node
  // does: no word from either), one cancelled with scancel (SIGTERM, then Slurm's kill).
  std::string pid;
  {
    std::ifstream info(o / "shards/eval/a/0000.partial/task.yaml");
    std::string line;
    while (std::getline(info, line))
      if (line.rfind("pid: ", 0) == 0) pid = line.substr(5);
  }
  ASSERT_FALSE(pid.empty());
  auto r = cluster_->run("C=$(cat /proc/" + pid + "/task/" + pid + "/children); kill -9 " + pid + " $C");
  ASSERT_EQ(r.exit_code, 0) << r.output();
  r = cluster_->run("scancel " + job + "_1");
  ASSERT_EQ(r.exit_code, 0) << r.output();
  ASSERT_TRUE(cluster_->wait_for_jobs(job, 240)) << cluster_->log_tail();
  std::this_thread::sleep_for(std::chrono::milliseconds(1800));  // the killed one's heartbeat goes stale

  ASSERT_EQ(test::run_augrig("campaign status " + o.string() + " --tasks", &out), 0) << out;
  EXPECT_NE(out.find("tasks 2 = done 0 + running 0 + failed 1 + stopped 1 + pending 0"), std::string::npos)
      << out;
  EXPECT_NE(out.find("task 0 (eval/a shard 0, frames 0+41): stopped: started on "), std::string::npos) << out;
  EXPECT_NE(out.find("stopped without a word"), std::string::npos) << out;
  EXPECT_NE(out.find("task 1 (eval/b shard 0, frames 0+31): failed: the command"), std::string::npos) << out;
  EXPECT_NE(out.find("not done: augrig campaign resume"), std::string::npos) << out;
  ASSERT_EQ(test::run_augrig("campaign merge " + o.string(), &out), 1) << out;

  ASSERT_EQ(test::run_augrig("campaign resume " + o.string(), &out), 0) << out;
  EXPECT_NE(out.find("2 of 2 task(s) not done: 0-1"), std::string::npos) << out;
  wait_for(out);
  ASSERT_EQ(test::run_augrig("campaign status " + o.string(), &out), 0) << out;
  EXPECT_NE(out.find("tasks 2 = done 2 + "), std::string::npos) << out << "\n" << cluster_->log_tail();
  ASSERT_EQ(test::run_augrig("campaign merge " + o.string() + " --no-plot", &out), 0) << out;
  expect_equals_unsharded(o / "report", "a", "--full-frame", false);
  expect_equals_unsharded(o / "report", "b", "--full-frame", false);
}

}  // namespace
}  // namespace augrig
