// campaign/process: real programs run to their end (/bin/sh): exit status, a signal, a program that
// cannot start, output in the log, peak memory, the pid while running, and a log's last lines.
#include "campaign/process.hpp"

#include <fstream>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

#include "tests/support/test_support.hpp"

namespace augrig::campaign {
namespace {

namespace fs = std::filesystem;

// A folder per test (CTest runs them at once), made once per test.
fs::path dir() {
  static std::string made;
  const std::string name =
      std::string("campaign_process_") + ::testing::UnitTest::GetInstance()->current_test_info()->name();
  const fs::path d = fs::path(AUGRIG_TEST_OUTPUT_DIR) / name;
  if (made != name) {
    test::output_dir(name);
    made = name;
  }
  return d;
}

std::string read(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(Process, ExitStatusAndOutputIntoTheLog) {
  const fs::path log = dir() / "exit.log";
  std::ofstream(log) << "old contents\n";
  const LoggedRun ok = run_logged("/bin/sh", {"-c", "echo out; echo err >&2"}, log);
  EXPECT_TRUE(ok.ok()) << ok.why();
  EXPECT_EQ(ok.why(), "");
  EXPECT_EQ(read(log), "out\nerr\n");       // truncated, stderr after stdout
  EXPECT_GT(ok.max_rss_bytes, 100 * 1024);  // a shell is more than 100 kB resident
  EXPECT_GE(ok.wall_s, 0.0);

  const LoggedRun bad = run_logged("/bin/sh", {"-c", "exit 3"}, log);
  EXPECT_FALSE(bad.ok());
  EXPECT_EQ(bad.why(), "the command exited with status 3");
}

TEST(Process, KilledBySignalAndNotStarted) {
  const fs::path log = dir() / "signal.log";
  const LoggedRun killed = run_logged("/bin/sh", {"-c", "kill -KILL $$"}, log);
  EXPECT_FALSE(killed.ok());
  EXPECT_EQ(killed.why(), "the command was killed by signal Killed");

  const LoggedRun missing = run_logged(dir() / "no-such-program", {}, log);
  EXPECT_FALSE(missing.ok());
  EXPECT_NE(missing.why().find("cannot start " + (dir() / "no-such-program").string()), std::string::npos)
      << missing.why();
}

TEST(Process, WallTimeAndThePidWhileItRuns) {
  std::atomic<pid_t> child{0};
  pid_t seen = 0;
  std::thread watch([&] {
    for (int i = 0; i < 200 && seen == 0; ++i) {
      seen = child.load();
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  const LoggedRun r = run_logged("/bin/sh", {"-c", "sleep 0.3"}, dir() / "sleep.log", &child);
  watch.join();
  EXPECT_TRUE(r.ok()) << r.why();
  EXPECT_GT(seen, 0);
  EXPECT_EQ(child.load(), 0);
  EXPECT_GE(r.wall_s, 0.29);
}

TEST(Process, LastLines) {
  const fs::path p = dir() / "lines.txt";
  std::ofstream(p) << "a\nb\nc\nd";
  EXPECT_EQ(last_lines(p, 2), "c\nd\n");
  EXPECT_EQ(last_lines(p, 9, "  "), "  a\n  b\n  c\n  d\n");
  EXPECT_EQ(last_lines(p, 0), "");
  EXPECT_EQ(last_lines(dir() / "absent.txt", 3), "");
}

}  // namespace
}  // namespace augrig::campaign
