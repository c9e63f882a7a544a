// campaign/process: a program run to its end with its output in a log file, and measured: how it
// ended, its wall time and its peak memory (wait4's rusage). A task runs its command with it, and
// `augrig campaign plan` measures a variant's cost with it.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <sys/types.h>

namespace augrig::campaign {

struct LoggedRun {
  std::string start_error;  // why it did not start, or was lost; empty when it ran to its end
  int wait_status = 0;      // waitpid's status
  double wall_s = 0;
  std::int64_t max_rss_bytes = 0;

  bool ok() const;
  // Empty when ok(); else "cannot start ...", "lost the command: ...", "the command was killed by
  // signal ..." or "the command exited with status N".
  std::string why() const;
};

// Runs `prog` with `args`: stdin from /dev/null, stdout and stderr into `log` (truncated). While it
// runs its pid is in `*child` (for passing signals on), 0 before and after.
LoggedRun run_logged(const std::filesystem::path& prog, const std::vector<std::string>& args,
                     const std::filesystem::path& log, std::atomic<pid_t>* child = nullptr);

// The last `n` lines of a file, each after `indent` and ending in '\n'; empty if it cannot be read.
std::string last_lines(const std::filesystem::path& p, std::size_t n, const std::string& indent = "");

}  // namespace augrig::campaign
