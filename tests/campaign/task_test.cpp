// A campaign task with the real augrig on a simulated recording: a shard runs once and is skipped
// after; a failing command leaves its reason and runs again; a task killed with its command (as a
// lost node or kill -9 does) is seen stopped from its files alone and reruns from scratch; a shard
// folder from another plan is not taken for this one's.
#include "campaign/task.hpp"

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include "tests/support/test_support.hpp"

namespace augrig::campaign {
namespace {

namespace fs = std::filesystem;

std::size_t data_rows(const fs::path& csv) {
  std::ifstream in(csv);
  std::string line;
  std::size_t n = 0;
  while (std::getline(in, line)) n += !line.empty();
  return n ? n - 1 : 0;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct TaskFixture : ::testing::Test {
  fs::path dir;
  std::string recording;
  Manifest m;
  void SetUp() override {
    std::string why;
    recording = test::sim_recording("campaign/flight_a.yaml", 3, "campaign_a", &why);
    ASSERT_FALSE(recording.empty()) << why;
    dir = test::output_dir(std::string("campaign_task_") +
                           ::testing::UnitTest::GetInstance()->current_test_info()->name());
    m.file = dir / "manifest.yaml";
    m.name = "t";
    m.out = dir;
    m.augrig = test::augrig_binary();
    m.heartbeat_s = 0.2;
    Task t;
    t.id = 0;
    t.flight = "a";
    t.variant = "v";
    t.shard = Shard{1, 10, 8, 0, 0};
    t.out = shard_dir(dir, "v", "a", 1);
    t.argv = {"evaluate", recording, "--from-frame", "10", "--frames", "8", "--every", "2", "--no-plot"};
    m.tasks = {t};
    ASSERT_TRUE(write_manifest(m));
  }
  TaskStatus status() const { return task_status(m, m.tasks[0], now()); }
  static double now() {
    return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  }
};

TEST_F(TaskFixture, RunsAShardOnceAndSkipsItAfter) {
  EXPECT_EQ(status().state, TaskState::kPending);
  std::ostringstream out, err;
  ASSERT_EQ(run_task(m, 0, out, err), 0) << out.str() << err.str();
  const Task& t = m.tasks[0];
  EXPECT_EQ(data_rows(t.out / "stats.csv"), 8u);
  EXPECT_EQ(data_rows(t.out / "evaluation.csv"), 4u);
  EXPECT_TRUE(fs::exists(t.out / "task.log"));
  EXPECT_FALSE(fs::exists(t.out.string() + ".partial"));
  EXPECT_FALSE(fs::exists(t.out.string() + ".failed"));
  const TaskStatus s = status();
  EXPECT_EQ(s.state, TaskState::kDone);
  EXPECT_GT(s.wall_s, 0);
  EXPECT_GT(s.max_rss_bytes, 1 << 20);
  const auto before = fs::last_write_time(t.out / "done.yaml");
  std::ostringstream again;
  EXPECT_EQ(run_task(m, 0, again, err), 0);
  EXPECT_NE(again.str().find("is done already"), std::string::npos) << again.str();
  EXPECT_EQ(fs::last_write_time(t.out / "done.yaml"), before);

  std::ostringstream bad;
  EXPECT_EQ(run_task(m, 5, out, bad), 2);
  EXPECT_NE(bad.str().find("no task 5 (the manifest has 1, 0..0)"), std::string::npos) << bad.str();
}

TEST_F(TaskFixture, AFailedCommandLeavesItsReasonAndRunsAgain) {
  Task& t = m.tasks[0];
  t.argv.insert(t.argv.end(), {"--boom", "sideways"});
  std::ostringstream out, err;
  EXPECT_EQ(run_task(m, 0, out, err), 1);
  EXPECT_NE(err.str().find("the command exited with status 2"), std::string::npos) << err.str();
  const TaskStatus s = status();
  EXPECT_EQ(s.state, TaskState::kFailed);
  EXPECT_EQ(s.detail, "the command exited with status 2");
  const std::string failed = slurp(t.out.string() + ".failed");
  EXPECT_NE(failed.find("--boom"), std::string::npos) << failed;  // the command's own error line
  EXPECT_TRUE(fs::exists(t.out.string() + ".partial/task.log"));  // kept to look at
  EXPECT_FALSE(fs::exists(t.out));

  t.argv.resize(t.argv.size() - 2);
  ASSERT_EQ(run_task(m, 0, out, err), 0) << out.str() << err.str();
  EXPECT_EQ(status().state, TaskState::kDone);
  EXPECT_FALSE(fs::exists(t.out.string() + ".failed"));
  EXPECT_FALSE(fs::exists(t.out.string() + ".partial"));
}

TEST_F(TaskFixture, AKilledTaskIsSeenStoppedFromItsFilesAndRerunsFromScratch) {
  const Task& t = m.tasks[0];
  // The task and its command in their own process group, killed together as Slurm kills a job.
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    setpgid(0, 0);
    const std::string bin = test::augrig_binary();
    execl(bin.c_str(), bin.c_str(), "campaign", "task", m.file.c_str(), "0", static_cast<char*>(nullptr));
    _exit(127);
  }
  setpgid(pid, pid);
  // Running: its heartbeat is fresh.
  bool running = false;
  for (int i = 0; i < 200 && !running; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    running = status().state == TaskState::kRunning;
  }
  ASSERT_TRUE(running) << "the task never showed as running";
  std::ostringstream out, err;
  EXPECT_EQ(run_task(m, 0, out, err), 0);  // a second copy leaves it alone
  EXPECT_NE(out.str().find("is running elsewhere"), std::string::npos) << out.str();
  ::kill(-pid, SIGKILL);
  int st = 0;
  waitpid(pid, &st, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(800));  // > 3 heartbeats
  const TaskStatus s = status();
  EXPECT_EQ(s.state, TaskState::kStopped);
  EXPECT_NE(s.detail.find("stopped without a word"), std::string::npos) << s.detail;
  ASSERT_EQ(run_task(m, 0, out, err), 0) << out.str() << err.str();
  EXPECT_EQ(status().state, TaskState::kDone);
  EXPECT_EQ(data_rows(t.out / "stats.csv"), 8u);
}

TEST_F(TaskFixture, AShardFolderOfAnotherPlanIsNotThisTasksResult) {
  const Task& t = m.tasks[0];
  fs::create_directories(t.out);
  std::ofstream(t.out / "done.yaml") << "command: evaluate elsewhere --frames 99\n";
  const TaskStatus s = status();
  EXPECT_EQ(s.state, TaskState::kPending);
  EXPECT_NE(s.detail.find("another plan's result"), std::string::npos);
  std::ostringstream out, err;
  ASSERT_EQ(run_task(m, 0, out, err), 0) << out.str() << err.str();
  EXPECT_EQ(status().state, TaskState::kDone);
  EXPECT_EQ(data_rows(t.out / "stats.csv"), 8u);
}

}  // namespace
}  // namespace augrig::campaign
