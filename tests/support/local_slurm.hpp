// LocalSlurm: a real single-node Slurm cluster (Debian 12's slurm-wlm 22.05 and MUNGE) started by a
// test as root on loopback, for tests of what augrig hands to Slurm (`augrig campaign`'s array job
// scripts run with `sbatch --array`). Everything the cluster has is under the directory it is
// given: its own munge key and munged socket, a slurm.conf (one node "localhost" with the CPUs asked
// for and the machine's memory, cons_tres with CR_Core_Memory so --cpus-per-task and --mem count, no
// cgroups, no accounting), state, spool, logs and pid files; its ports are two free ones picked per
// run in 20000-29999, so it disturbs no system Slurm and several can run at once.
//
// The daemons (munged -F, slurmctld -D, slurmd -D) are children of the process that called start(),
// with PR_SET_PDEATHSIG: if the test dies, they get SIGTERM. Call start() from the thread that
// outlives the cluster (the test's main thread; GoogleTest's SetUpTestSuite is on it). The
// destructor cancels every job, stops slurmd, slurmctld and munged (SIGTERM, then SIGKILL after
// 10 s) and kills whatever of the cluster is left (job steps, their tasks). start() first kills
// what a crashed run left in the same directory and empties it.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <sys/types.h>

#include "core/expected.hpp"

namespace augrig::test {

// What a command run against the cluster did.
struct SlurmCommandResult {
  int exit_code = -1;  // the exit status; 128+N when killed by signal N; -1 when it could not run
  bool timed_out = false;
  std::string out, err;  // stdout and stderr
  std::string output() const { return out + err; }
};

// One job, or one task of an array job, as squeue shows it (`squeue -r -t all`).
struct SlurmTask {
  std::string id;         // "12" for a job, "12_3" for task 3 of array job 12
  std::string state;      // PENDING, RUNNING, COMPLETED, FAILED, CANCELLED, TIMEOUT, ...
  int exit_status = -1;   // the batch script's exit status (-1: squeue gave none, or a signal ended it)
  int signal = 0;         // the signal that ended it, 0 if none
  bool finished() const;  // a terminal state: none of PENDING, RUNNING, CONFIGURING, COMPLETING, ...
};

class LocalSlurm {
 public:
  // Starts munged, slurmctld and slurmd under `dir` (made absolute; emptied first) with a node of
  // `cpus` CPUs, and waits up to `timeout_s` until sinfo shows the node idle. The error says in
  // plain words why the cluster cannot run: not root, a program missing (with the Debian package
  // that has it), or a daemon that failed to start (with the end of its log).
  static Expected<std::unique_ptr<LocalSlurm>> start(const std::filesystem::path& dir, int cpus = 2,
                                                     double timeout_s = 30);
  // Why no cluster can start here at all (not root, a program missing, with its Debian package), or
  // "" when start() may go ahead. start() checks it first and returns the same words.
  static std::string missing_requirements();
  ~LocalSlurm();  // stop()
  LocalSlurm(const LocalSlurm&) = delete;
  LocalSlurm& operator=(const LocalSlurm&) = delete;

  // Cancels every job, stops the daemons and kills what is left of the cluster. Idempotent. Leaves
  // `dir` (logs, state) in place for inspection.
  void stop();

  const std::filesystem::path& dir() const { return dir_; }
  const std::filesystem::path& conf() const { return conf_; }  // dir/slurm.conf
  int cpus() const { return cpus_; }
  long real_memory_mb() const { return real_memory_mb_; }  // the node's RealMemory
  static constexpr const char* kPartition = "debug";       // the one (default) partition

  // The variables a client (sbatch, squeue, ..., and whatever they run) needs: SLURM_CONF=dir/
  // slurm.conf and AUGRIG_LOCAL_SLURM=dir (the mark stop() finds leftovers by).
  std::vector<std::pair<std::string, std::string>> env() const;
  // This process's environment for a client: env() set, and the variables Slurm clients read as
  // input (SLURM_*, SBATCH_*, SALLOC_*, SRUN_*, SQUEUE_*, SINFO_*, SCANCEL_*, SACCT_*) removed, so
  // a test that itself runs inside a Slurm job still talks to this cluster only. For execve().
  std::vector<std::string> client_environment() const;
  // Applies the same to this process (setenv/unsetenv): afterwards run_command(), popen() and any
  // child reach this cluster. Not undone by stop().
  void apply_env() const;

  // Runs `shell_command` with /bin/sh -c in client_environment() (in this process's working
  // directory), killing it (its process group) after `timeout_s`.
  SlurmCommandResult run(const std::string& shell_command, double timeout_s = 60) const;
  // `sbatch --parsable ARGS`: the job id ("12"), or an error with sbatch's output.
  Expected<std::string> submit(const std::string& sbatch_args) const;
  // Every task of `job_id` (array tasks one by one) in any state; empty once Slurm forgot the job.
  std::vector<SlurmTask> tasks(const std::string& job_id) const;
  // Waits until no task of `job_id` is pending or running any more (squeue lists none, or only
  // finished ones) and returns the tasks' final states; an error (with squeue's listing) after
  // `timeout_s`.
  Expected<std::vector<SlurmTask>> wait_for_jobs(const std::string& job_id, double timeout_s = 60) const;
  // Waits until at least `count` tasks of `job_id` are RUNNING; false after `timeout_s`.
  bool wait_running(const std::string& job_id, int count = 1, double timeout_s = 30) const;

  // The last `lines` lines of the slurmctld, slurmd and munged logs, headed by their names: for
  // failure messages.
  std::string log_tail(int lines = 30) const;

  // Processes other than this one that belong to a cluster under `dir`: their command line names
  // a path under it, or their environment has AUGRIG_LOCAL_SLURM=dir or SLURM_CONF=dir/slurm.conf
  // (daemons, slurmstepd, job tasks, clients). Empty after stop().
  static std::vector<pid_t> processes_of(const std::filesystem::path& dir);

 private:
  LocalSlurm() = default;
  static Expected<std::unique_ptr<LocalSlurm>> start_once(const std::filesystem::path& dir, int cpus,
                                                          double timeout_s);
  std::filesystem::path dir_, conf_, runtime_dir_, log_dir_;
  bool own_runtime_dir_ = false;  // runtime_dir_ is a short /tmp directory of our own
  int cpus_ = 0;
  long real_memory_mb_ = 0;
  pid_t munged_ = -1, slurmctld_ = -1, slurmd_ = -1;
  bool stopped_ = false;
};

}  // namespace augrig::test
