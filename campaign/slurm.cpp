#include "campaign/slurm.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <fstream>
#include <sstream>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

namespace augrig::campaign {

namespace fs = std::filesystem;

std::string array_spec(const std::vector<std::size_t>& idx, int max_running) {
  std::string s;
  for (std::size_t i = 0; i < idx.size();) {
    std::size_t j = i;
    while (j + 1 < idx.size() && idx[j + 1] == idx[j] + 1) ++j;
    if (!s.empty()) s += ',';
    s += std::to_string(idx[i]);
    if (j > i) s += "-" + std::to_string(idx[j]);
    i = j + 1;
  }
  if (max_running > 0) s += "%" + std::to_string(max_running);
  return s;
}

std::vector<ArrayChunk> array_chunks(const std::vector<std::size_t>& ids_in, int max_array_size) {
  std::vector<std::size_t> ids = ids_in;
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  const std::size_t span = static_cast<std::size_t>(std::max(2, max_array_size));
  std::vector<ArrayChunk> out;
  for (std::size_t id : ids) {
    if (out.empty() || id - out.back().offset >= span) out.push_back(ArrayChunk{id, {}});
    out.back().indices.push_back(id - out.back().offset);
  }
  return out;
}

Resources task_resources(const Manifest& m, const std::vector<std::size_t>& ids) {
  Resources r;
  r.cpus = m.slurm.cpus_per_task;
  r.time_s = 0;
  for (std::size_t id : ids) {
    if (id >= m.tasks.size()) continue;
    const Task& t = m.tasks[id];
    const TaskCost* c = m.cost_of(t.variant);
    const double per = c ? c->per_frame_s : 1.0, startup = c ? c->startup_s : 30.0;
    // Slurm kills a task at its limit: the measured cost times the safety factor, and a minute
    // for a slow shared file system.
    r.time_s =
        std::max(r.time_s, (startup + per * static_cast<double>(t.shard.frames)) * m.slurm.time_safety + 60);
    // Memory: the measured peak and half again (frames differ), at least 256 MB.
    const double mb = c ? static_cast<double>(c->max_rss_bytes) / (1 << 20) * 1.5 + 64 : 2048;
    r.mem_mb = std::max<std::int64_t>(r.mem_mb, static_cast<std::int64_t>(std::ceil(mb)));
  }
  r.time_s = std::max(r.time_s, 60.0);
  return r;
}

namespace {

std::string quoted(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

}  // namespace

std::string sbatch_script(const Manifest& m, const ArrayChunk& chunk, const Resources& r) {
  std::ostringstream o;
  o << "#!/bin/bash\n";
  o << "# augrig campaign '" << m.name << "': tasks " << chunk.offset << " + SLURM_ARRAY_TASK_ID of "
    << m.file.string() << "\n";
  o << "# Each task runs one shard (augrig campaign task): a finished shard is skipped, a failed one\n"
       "# runs again. Resources from the measured cost per frame (augrig campaign plan).\n";
  o << "#SBATCH --job-name=augrig-" << m.name << "\n";
  o << "#SBATCH --array=" << array_spec(chunk.indices, m.slurm.max_running) << "\n";
  o << "#SBATCH --cpus-per-task=" << r.cpus << "\n";
  o << "#SBATCH --ntasks=1\n";
  o << "#SBATCH --mem=" << r.mem_mb << "M\n";
  o << "#SBATCH --time=" << slurm_time(r.time_s) << "\n";
  o << "#SBATCH --output=" << (m.out / "logs" / "slurm-%A_%a.out").string() << "\n";
  // Slurm sends SIGTERM at the limit; the task stops its command and marks the shard failed.
  o << "#SBATCH --signal=TERM@60\n";
  if (!m.slurm.partition.empty()) o << "#SBATCH --partition=" << m.slurm.partition << "\n";
  if (!m.slurm.account.empty()) o << "#SBATCH --account=" << m.slurm.account << "\n";
  for (const std::string& e : m.slurm.extra) o << "#SBATCH " << e << "\n";
  o << "\nexec " << quoted(m.augrig.string()) << " campaign task " << quoted(m.file.string()) << " \"$(("
    << chunk.offset << " + SLURM_ARRAY_TASK_ID))\"\n";
  return o.str();
}

Expected<std::vector<fs::path>> write_scripts(const Manifest& m, const std::vector<std::size_t>& ids,
                                              const std::string& stem) {
  std::vector<fs::path> out;
  std::error_code ec;
  fs::create_directories(m.out / "slurm", ec);
  fs::create_directories(m.out / "logs", ec);  // Slurm does not create the --output folder
  if (ec) return make_error("campaign::write_scripts(): ", (m.out / "slurm").string(), ": ", ec.message());
  const auto chunks = array_chunks(ids, m.slurm.max_array_size);
  for (std::size_t k = 0; k < chunks.size(); ++k) {
    std::vector<std::size_t> chunk_ids;
    for (std::size_t i : chunks[k].indices) chunk_ids.push_back(i + chunks[k].offset);
    const fs::path p = m.out / "slurm" / (stem + "-" + std::to_string(k) + ".sbatch");
    std::ofstream f(p, std::ios::binary);
    f << sbatch_script(m, chunks[k], task_resources(m, chunk_ids));
    if (!f.flush()) return make_error("campaign::write_scripts(): ", p.string(), ": cannot write");
    out.push_back(p);
  }
  return out;
}

ProgramResult run_program(const std::vector<std::string>& args) {
  ProgramResult r;
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) return r;
  std::vector<char*> argv;
  std::vector<std::string> a = args;
  for (auto& s : a) argv.push_back(s.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&fa, fds[1], 1);
  posix_spawn_file_actions_adddup2(&fa, fds[1], 2);
  pid_t pid = 0;
  const int rc = ::posix_spawnp(&pid, argv[0], &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  ::close(fds[1]);
  if (rc != 0) {
    ::close(fds[0]);
    r.output = std::string(args[0]) + ": " + std::strerror(rc);
    return r;
  }
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n > 0)
      r.output.append(buf, static_cast<std::size_t>(n));
    else if (n == 0 || errno != EINTR)
      break;
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

Expected<std::string> submit(const Manifest& m, const fs::path& script) {
  const ProgramResult r = run_program({"sbatch", "--parsable", script.string()});
  std::string out = r.output;
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
  if (r.status != 0)
    return make_error("campaign::submit(): sbatch ", script.string(), ": ",
                      r.status < 0 ? "cannot run sbatch (is Slurm's client installed: slurm-client?)" : out);
  // --parsable prints "JOBID" or "JOBID;CLUSTER" (possibly after warnings on other lines).
  std::string job = out.substr(out.find_last_of('\n') == std::string::npos ? 0 : out.find_last_of('\n') + 1);
  job = job.substr(0, job.find(';'));
  if (job.empty() || job.find_first_not_of("0123456789") != std::string::npos)
    return make_error("campaign::submit(): sbatch ", script.string(), ": expected a job id, got '", out, "'");
  std::ofstream log(m.out / "jobs.log", std::ios::app);
  log << utc_now_iso() << " job " << job << " " << script.string() << "\n";
  return job;
}

}  // namespace augrig::campaign
