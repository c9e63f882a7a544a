#include "campaign/process.hpp"

#include <cerrno>
#include <chrono>
#include <cstring>
#include <deque>
#include <fstream>

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>

extern char** environ;

namespace augrig::campaign {

bool LoggedRun::ok() const {
  return start_error.empty() && WIFEXITED(wait_status) && WEXITSTATUS(wait_status) == 0;
}

std::string LoggedRun::why() const {
  if (!start_error.empty()) return start_error;
  if (WIFSIGNALED(wait_status))
    return std::string("the command was killed by signal ") + strsignal(WTERMSIG(wait_status));
  if (WEXITSTATUS(wait_status) != 0)
    return "the command exited with status " + std::to_string(WEXITSTATUS(wait_status));
  return "";
}

LoggedRun run_logged(const std::filesystem::path& prog, const std::vector<std::string>& args,
                     const std::filesystem::path& log, std::atomic<pid_t>* child) {
  std::vector<std::string> a = args;
  std::string p = prog.string();
  std::vector<char*> argv;
  argv.push_back(p.data());
  for (auto& s : a) argv.push_back(s.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  LoggedRun r;
  const auto t0 = std::chrono::steady_clock::now();
  pid_t pid = 0;
  const int rc = ::posix_spawn(&pid, p.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) {
    r.start_error = "cannot start " + p + ": " + std::strerror(rc);
    return r;
  }
  if (child) child->store(pid);
  struct rusage ru {};
  pid_t w = 0;
  do {
    w = ::wait4(pid, &r.wait_status, 0, &ru);
  } while (w < 0 && errno == EINTR);
  if (w < 0) r.start_error = std::string("lost the command: ") + std::strerror(errno);
  if (child) child->store(0);
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.max_rss_bytes = static_cast<std::int64_t>(ru.ru_maxrss) * 1024;  // kilobytes on Linux
  return r;
}

std::string last_lines(const std::filesystem::path& p, std::size_t n, const std::string& indent) {
  std::ifstream in(p, std::ios::binary);
  std::deque<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    lines.push_back(line);
    if (lines.size() > n) lines.pop_front();
  }
  std::string s;
  for (const auto& l : lines) s += indent + l + "\n";
  return s;
}

}  // namespace augrig::campaign
