// task: one shard of a campaign run to completion, idempotently, and its state read back from the
// files it leaves (docs/CAMPAIGN.md, "Tasks"). A task works in SHARD.partial/: it writes task.yaml,
// touches `heartbeat` every Manifest::heartbeat_s, runs the shard's augrig command there with its
// output in task.log, and on success writes done.yaml and renames the folder to SHARD (one atomic
// rename: a shard folder is complete or absent). On failure it writes SHARD.failed (exit status,
// host, job, the log's last lines) and keeps SHARD.partial/ to look at. A killed task leaves a
// partial folder whose heartbeat goes stale: status says so from the files alone.
#pragma once

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>

#include "campaign/campaign.hpp"

namespace augrig::campaign {

enum class TaskState {
  kPending,  // nothing there yet (or planned differently: the shard's files are another plan's)
  kRunning,  // a partial folder with a fresh heartbeat
  kDone,     // the shard folder with done.yaml for this task's command
  kFailed,   // SHARD.failed: the command failed or was stopped
  kStopped,  // a partial folder whose heartbeat is stale: killed without a word (kill -9, node lost)
};
const char* to_string(TaskState s);

struct TaskStatus {
  TaskState state = TaskState::kPending;
  std::string detail;               // why failed/stopped/pending, in plain words
  double wall_s = 0;                // done: the command's wall time
  std::int64_t max_rss_bytes = 0;   // done: its peak memory
  std::size_t frames_left_out = 0;  // done: shard frames not in its outputs (damaged input, no pose)
  std::string host, job;            // who ran (or runs) it
};

// The task's state from its files. `now_s`: the wall clock (seconds since the epoch) to age the
// heartbeat against.
TaskStatus task_status(const Manifest& m, const Task& t, double now_s);

// Runs task `id` of the manifest, as a Slurm array task does: skips a finished shard (exit 0),
// leaves a shard another task is running alone (exit 0), else runs it. Returns the exit code:
// 0 done, 1 the command failed or was stopped. Progress and the command's last lines go to `out`.
int run_task(const Manifest& m, std::size_t id, std::ostream& out, std::ostream& err);

// The job that runs this process, "JOBID_TASK" from Slurm's environment; "" outside Slurm.
std::string slurm_job_name();

}  // namespace augrig::campaign
