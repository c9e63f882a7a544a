// The local Slurm cluster the campaign tests run their array jobs on (tests/support/local_slurm.hpp):
// array tasks run with their index and their throttle, scancel ends a running task within seconds,
// sbatch refuses a job bigger than the node, and no process of a cluster outlives it, not even after
// the test that started it was killed. Skips where the cluster cannot run (not root, Slurm or MUNGE
// not installed), saying why.
#include "tests/support/local_slurm.hpp"

#include <algorithm>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;
using test::LocalSlurm;
using Clock = std::chrono::steady_clock;

std::string read_file(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::string cmdline_of(pid_t pid) {
  std::string s = read_file("/proc/" + std::to_string(pid) + "/cmdline");
  for (char& c : s)
    if (c == '\0') c = ' ';
  return s;
}

// Ended (a zombie that init has not reaped yet counts as ended).
bool gone(pid_t pid) {
  const std::string stat = read_file("/proc/" + std::to_string(pid) + "/stat");
  const std::size_t paren = stat.rfind(')');
  return paren == std::string::npos || paren + 2 >= stat.size() || stat[paren + 2] == 'Z';
}

std::string describe(const std::vector<pid_t>& pids) {
  std::string out;
  for (pid_t p : pids) out += "\n  " + std::to_string(p) + ": " + cmdline_of(p);
  return out;
}

// A cluster of 2 CPUs per test, in a directory of the test's own: CTest runs the tests of this file
// as separate processes, at once, and a cluster's start clears whatever runs in its directory.
class LocalSlurmTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    auto s = LocalSlurm::start(fs::path(AUGRIG_TEST_OUTPUT_DIR) / "slurm_local_slurm" / name, 2);
    if (!s) GTEST_SKIP() << "no local Slurm cluster: " << s.error().message;
    cluster_ = std::move(*s);
  }
  void TearDown() override { cluster_.reset(); }
  const LocalSlurm& slurm() const { return *cluster_; }

 private:
  std::unique_ptr<LocalSlurm> cluster_;
};

TEST_F(LocalSlurmTest, ArrayTasksRunWithTheirIndexTwoAtATime) {
  const LocalSlurm& s = slurm();
  const fs::path out = s.dir() / "array-out";
  fs::create_directories(out);
  const auto id = s.submit("--array=0-5%2 --cpus-per-task=1 --mem=100M -o " + out.string() +
                           "/slurm-%A_%a.out --wrap 'echo $SLURM_ARRAY_TASK_ID > " + out.string() +
                           "/$SLURM_ARRAY_TASK_ID.txt'");
  ASSERT_TRUE(id) << id.error().message;
  // The throttle (%2): never more than two tasks running at once.
  long max_running = 0;
  const auto deadline = Clock::now() + std::chrono::seconds(40);
  bool done = false;
  while (!done && Clock::now() < deadline) {
    const auto t = s.tasks(*id);
    max_running = std::max<long>(max_running, std::count_if(t.begin(), t.end(), [](const test::SlurmTask& x) {
                                   return x.state == "RUNNING";
                                 }));
    done = std::all_of(t.begin(), t.end(), [](const test::SlurmTask& x) { return x.finished(); });
    if (!done) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  const auto tasks = s.wait_for_jobs(*id, 5);
  ASSERT_TRUE(tasks) << tasks.error().message << "\n" << s.log_tail();
  EXPECT_LE(max_running, 2);
  ASSERT_EQ(tasks->size(), 6u);
  for (const test::SlurmTask& t : *tasks) {
    EXPECT_EQ(t.state, "COMPLETED") << t.id;
    EXPECT_EQ(t.exit_status, 0) << t.id;
  }
  for (int i = 0; i < 6; ++i)
    EXPECT_EQ(read_file(out / (std::to_string(i) + ".txt")), std::to_string(i) + "\n") << i;
}

TEST_F(LocalSlurmTest, AFailingTaskShowsAsFailedWithItsExitStatus) {
  const LocalSlurm& s = slurm();
  const auto id = s.submit("--array=0-1 -o /dev/null --wrap 'exit $((SLURM_ARRAY_TASK_ID * 3))'");
  ASSERT_TRUE(id) << id.error().message;
  const auto tasks = s.wait_for_jobs(*id, 30);
  ASSERT_TRUE(tasks) << tasks.error().message;
  ASSERT_EQ(tasks->size(), 2u);
  for (const test::SlurmTask& t : *tasks) {
    if (t.id == *id + "_0") {
      EXPECT_EQ(t.state, "COMPLETED");
      EXPECT_EQ(t.exit_status, 0);
    } else {
      EXPECT_EQ(t.id, *id + "_1");
      EXPECT_EQ(t.state, "FAILED");
      EXPECT_EQ(t.exit_status, 3);
      EXPECT_EQ(t.signal, 0);
    }
  }
}

TEST_F(LocalSlurmTest, ScancelEndsARunningTaskWithinSeconds) {
  const LocalSlurm& s = slurm();
  const auto id = s.submit("--array=0 --cpus-per-task=1 --mem=100M -o /dev/null --wrap 'sleep 300'");
  ASSERT_TRUE(id) << id.error().message;
  ASSERT_TRUE(s.wait_running(*id, 1, 20)) << s.log_tail();
  const auto t0 = Clock::now();
  const auto r = s.run("scancel " + *id);
  ASSERT_EQ(r.exit_code, 0) << r.output();
  const auto tasks = s.wait_for_jobs(*id, 15);
  const double took = std::chrono::duration<double>(Clock::now() - t0).count();
  ASSERT_TRUE(tasks) << tasks.error().message;
  ASSERT_EQ(tasks->size(), 1u);
  EXPECT_EQ((*tasks)[0].state, "CANCELLED");
  EXPECT_NE((*tasks)[0].signal, 0) << "ended by a signal";
  EXPECT_LT(took, 10.0);
  // And its sleep ends soon after (squeue may say CANCELLED while slurmd is still killing it).
  const auto sleeping = [&] {
    for (pid_t p : LocalSlurm::processes_of(s.dir()))
      if (cmdline_of(p) == "sleep 300 ") return true;
    return false;
  };
  while (sleeping() && Clock::now() - t0 < std::chrono::seconds(10))
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_FALSE(sleeping()) << "the cancelled task's sleep still runs";
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 10.0);
}

TEST_F(LocalSlurmTest, SbatchRefusesAJobBiggerThanTheNode) {
  const LocalSlurm& s = slurm();
  const auto cpus = s.submit("--cpus-per-task=" + std::to_string(s.cpus() + 1) + " -o /dev/null --wrap true");
  ASSERT_FALSE(cpus) << "job " << *cpus << " accepted";
  EXPECT_NE(cpus.error().message.find("More processors requested than permitted"), std::string::npos)
      << cpus.error().message;
  const auto mem =
      s.submit("--mem=" + std::to_string(s.real_memory_mb() + 1024) + "M -o /dev/null --wrap true");
  ASSERT_FALSE(mem) << "job " << *mem << " accepted";
  EXPECT_NE(mem.error().message.find("Memory specification can not be satisfied"), std::string::npos)
      << mem.error().message;
  // What fits the node is accepted.
  const auto fits = s.submit("--cpus-per-task=" + std::to_string(s.cpus()) + " -o /dev/null --wrap true");
  ASSERT_TRUE(fits) << fits.error().message;
  EXPECT_TRUE(s.wait_for_jobs(*fits, 30));
}

// A test process killed with its cluster running (a job step and its task included): the next
// start in the same directory clears what it left, and stop() leaves nothing behind. The directory's
// path is long, so that the sockets go to a /tmp directory of the cluster's own, which goes too.
TEST(LocalSlurm, NothingOutlivesACrashedRunOrAStoppedCluster) {
  if (const std::string why = LocalSlurm::missing_requirements(); !why.empty())
    GTEST_SKIP() << "no local Slurm cluster: " << why;
  const fs::path dir = fs::path(AUGRIG_TEST_OUTPUT_DIR) / "slurm_local_slurm" /
                       "crashed_run_in_a_directory_too_long_for_socket_paths";
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {  // the run that crashes: no GoogleTest here, and no destructors
    ::close(ready[0]);
    auto s = LocalSlurm::start(dir, 1);
    if (!s) ::_exit(2);
    const auto id = (*s)->submit("-o /dev/null --wrap 'sleep 300'");
    if (!id || !(*s)->wait_running(*id, 1, 20)) ::_exit(3);
    if (::write(ready[1], "r", 1) != 1) ::_exit(4);
    for (;;) ::pause();
  }
  ::close(ready[1]);
  char c = 0;
  const bool running = ::read(ready[0], &c, 1) == 1;
  ::close(ready[0]);
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(running) << "the first run did not get its job running (" << status << ")\n"
                       << read_file(dir / "log/slurmctld.log");
  // Its daemons got SIGTERM with it; its job's step and sleep live on.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const auto left = LocalSlurm::processes_of(dir);
  EXPECT_FALSE(left.empty()) << "nothing left to clean up: the test proves less than it says";
  const fs::path crashed_runtime =
      read_file(dir / "runtime-dir").substr(0, read_file(dir / "runtime-dir").find('\n'));
  ASSERT_FALSE(crashed_runtime.empty());
  EXPECT_TRUE(fs::exists(crashed_runtime));

  std::string runtime;
  {
    auto s = LocalSlurm::start(dir, 1);
    ASSERT_TRUE(s) << s.error().message;
    for (pid_t p : left) EXPECT_TRUE(gone(p)) << "left from the crashed run and still alive: " << p;
    EXPECT_FALSE(fs::exists(crashed_runtime)) << crashed_runtime;
    const auto id = (*s)->submit("-o /dev/null --wrap 'sleep 300'");
    ASSERT_TRUE(id) << id.error().message;
    ASSERT_TRUE((*s)->wait_running(*id, 1, 20)) << (*s)->log_tail();
    EXPECT_FALSE(LocalSlurm::processes_of(dir).empty());
    runtime = read_file(dir / "runtime-dir").substr(0, read_file(dir / "runtime-dir").find('\n'));
    EXPECT_TRUE(fs::exists(fs::path(runtime) / "munge.socket")) << runtime;
  }  // stopped here, its job still running
  const auto after = LocalSlurm::processes_of(dir);
  EXPECT_TRUE(after.empty()) << "still running:" << describe(after);
  EXPECT_FALSE(fs::exists(runtime)) << runtime;
}

}  // namespace
}  // namespace augrig
