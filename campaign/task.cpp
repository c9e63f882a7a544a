#include "campaign/task.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <ctime>
#include <fstream>
#include <mutex>
#include <ostream>
#include <sstream>
#include <thread>

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include "campaign/process.hpp"

namespace augrig::campaign {

namespace fs = std::filesystem;

const char* to_string(TaskState s) {
  switch (s) {
    case TaskState::kPending:
      return "pending";
    case TaskState::kRunning:
      return "running";
    case TaskState::kDone:
      return "done";
    case TaskState::kFailed:
      return "failed";
    case TaskState::kStopped:
      return "stopped";
  }
  return "?";
}

namespace {

fs::path partial_of(const Task& t) {
  return t.out.string() + ".partial";
}
fs::path failed_of(const Task& t) {
  return t.out.string() + ".failed";
}

std::string host_name() {
  char b[256] = {};
  if (gethostname(b, sizeof b - 1) != 0) return "?";
  return b;
}

double mtime_s(const fs::path& p) {
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0) return 0;
  return static_cast<double>(st.st_mtim.tv_sec) + static_cast<double>(st.st_mtim.tv_nsec) * 1e-9;
}

// The command line as text, for the records and a person repeating it.
std::string joined(const std::vector<std::string>& argv) {
  std::string s;
  for (const auto& a : argv) {
    if (!s.empty()) s += ' ';
    const bool plain = !a.empty() && a.find_first_of(" \t\n'\"\\$`*?&;|<>()") == std::string::npos;
    if (plain) {
      s += a;
    } else {
      s += '\'';
      for (char c : a) s += c == '\'' ? std::string("'\\''") : std::string(1, c);
      s += '\'';
    }
  }
  return s;
}

std::optional<YAML::Node> read_yaml(const fs::path& p) {
  try {
    if (!fs::is_regular_file(p)) return std::nullopt;
    return YAML::LoadFile(p.string());
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

// Writes `text` to `path` durably: a marker must not be half there after a crash.
bool write_durably(const fs::path& path, const std::string& text) {
  const fs::path tmp = path.string() + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return false;
  bool ok = ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  ok = ::fsync(fd) == 0 && ok;
  ok = ::close(fd) == 0 && ok;
  std::error_code ec;
  if (ok) fs::rename(tmp, path, ec);
  return ok && !ec;
}

void fsync_dir(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

// The data rows of a CSV file (lines after the header that are not blank).
std::size_t csv_data_rows(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::string line;
  std::size_t n = 0;
  if (!std::getline(in, line)) return 0;
  while (std::getline(in, line))
    if (!line.empty() && line != "\r") ++n;
  return n;
}

// SIGTERM/SIGINT (scancel, the time limit) go on to the command, which stops cleanly.
std::atomic<pid_t> g_child{0};
void forward_signal(int sig) {
  const pid_t c = g_child.load();
  if (c > 0) ::kill(c, sig);
}

}  // namespace

std::string slurm_job_name() {
  const char* job = std::getenv("SLURM_ARRAY_JOB_ID");
  const char* task = std::getenv("SLURM_ARRAY_TASK_ID");
  if (job && task) return std::string(job) + "_" + task;
  if (const char* j = std::getenv("SLURM_JOB_ID")) return j;
  return "";
}

TaskStatus task_status(const Manifest& m, const Task& t, double now_s) {
  TaskStatus s;
  // Done: the shard folder holds done.yaml for exactly this command (a folder from an earlier,
  // different plan is not this task's result).
  if (auto done = read_yaml(t.out / "done.yaml")) {
    const YAML::Node& d = *done;
    if (d["command"] && d["command"].Scalar() == joined(t.argv)) {
      s.state = TaskState::kDone;
      if (d["wall_s"]) s.wall_s = d["wall_s"].as<double>(0);
      if (d["max_rss_bytes"]) s.max_rss_bytes = d["max_rss_bytes"].as<std::int64_t>(0);
      if (d["frames_left_out"]) s.frames_left_out = d["frames_left_out"].as<std::size_t>(0);
      if (d["host"]) s.host = d["host"].Scalar();
      if (d["job"]) s.job = d["job"].Scalar();
      return s;
    }
    s.detail = "its folder holds another plan's result (planned again since): it runs again";
    return s;
  }
  const fs::path partial = partial_of(t);
  const bool has_partial = fs::is_directory(partial);
  if (has_partial) {
    const double age = now_s - mtime_s(partial / "heartbeat");
    if (auto info = read_yaml(partial / "task.yaml")) {
      if ((*info)["host"]) s.host = (*info)["host"].Scalar();
      if ((*info)["job"]) s.job = (*info)["job"].Scalar();
    }
    if (age <= 3 * m.heartbeat_s) {
      s.state = TaskState::kRunning;
      return s;
    }
  }
  if (auto failed = read_yaml(failed_of(t))) {
    s.state = TaskState::kFailed;
    const YAML::Node& f = *failed;
    if (f["host"]) s.host = f["host"].Scalar();
    if (f["job"]) s.job = f["job"].Scalar();
    s.detail = f["why"] ? f["why"].Scalar() : "failed";
    return s;
  }
  if (has_partial) {
    s.state = TaskState::kStopped;
    char b[64];
    std::snprintf(b, sizeof b, "%.0f", now_s - mtime_s(partial / "heartbeat"));
    s.detail = std::string("started") + (s.host.empty() ? "" : " on " + s.host) +
               (s.job.empty() ? "" : " as job " + s.job) + ", silent for " + b +
               " s: stopped without a word (killed, or its node lost)";
  }
  return s;
}

int run_task(const Manifest& m, std::size_t id, std::ostream& out, std::ostream& err) {
  if (id >= m.tasks.size()) {
    err << "augrig campaign task: " << m.file.string() << ": no task " << id << " (the manifest has "
        << m.tasks.size() << ", 0.." << (m.tasks.empty() ? 0 : m.tasks.size() - 1) << ")\n";
    return 2;
  }
  const Task& t = m.tasks[id];
  const std::string what =
      "task " + std::to_string(id) + " (flight " + t.flight + ", variant " + t.variant + ", shard " +
      std::to_string(t.shard.index) + ", frames " + std::to_string(t.shard.from_frame) + ".." +
      std::to_string(t.shard.from_frame + t.shard.frames - (t.shard.frames ? 1 : 0)) + ")";
  const TaskStatus before = task_status(m, t, wall_clock_s());
  if (before.state == TaskState::kDone) {
    out << "campaign: " << what << " is done already (" << t.out.string() << "); skipped\n";
    return 0;
  }
  if (before.state == TaskState::kRunning) {
    out << "campaign: " << what << " is running elsewhere (" << (before.job.empty() ? "?" : before.job)
        << " on " << (before.host.empty() ? "?" : before.host) << "); left to it\n";
    return 0;
  }

  // A fresh start: what an earlier attempt left goes, the failure marker last (status reads it).
  const fs::path partial = partial_of(t);
  std::error_code ec;
  fs::remove_all(partial, ec);
  if (fs::exists(t.out)) fs::remove_all(t.out, ec);  // another plan's result
  fs::create_directories(partial, ec);
  if (ec) {
    err << "augrig campaign task: " << partial.string() << ": cannot create the folder: " << ec.message()
        << "\n";
    return 1;
  }
  const std::string job = slurm_job_name(), host = host_name();
  {
    YAML::Emitter e;
    e << YAML::BeginMap << YAML::Key << "task" << YAML::Value << id << YAML::Key << "command" << YAML::Value
      << joined(t.argv) << YAML::Key << "host" << YAML::Value << host << YAML::Key << "job" << YAML::Value
      << job << YAML::Key << "pid" << YAML::Value << ::getpid() << YAML::Key << "started_at" << YAML::Value
      << utc_now_iso() << YAML::EndMap;
    write_durably(partial / "task.yaml", std::string(e.c_str()) + "\n");
    std::ofstream(partial / "heartbeat") << utc_now_iso() << "\n";
  }
  fs::remove(failed_of(t), ec);

  // The command: the manifest's augrig binary, output into the partial folder, its stdout and
  // stderr into task.log (kept with the shard).
  std::vector<std::string> args = t.argv;
  for (std::string& a : args)
    for (std::size_t at; (at = a.find(kTaskOut)) != std::string::npos;)
      a.replace(at, std::string(kTaskOut).size(), partial.string());
  args.insert(args.end(), {"--out", partial.string()});
  const std::string prog = m.augrig.string();
  const fs::path log = partial / "task.log";
  out << "campaign: " << what << " on " << host << (job.empty() ? "" : " as job " + job) << ": " << prog
      << " " << joined(args) << std::endl;

  struct sigaction sa {
  }, old_term{}, old_int{};
  sa.sa_handler = forward_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGTERM, &sa, &old_term);
  sigaction(SIGINT, &sa, &old_int);
  // The heartbeat says "alive" while the command runs; status ages it.
  std::mutex mu;
  std::condition_variable cv;
  bool finished = false;
  std::thread beat([&] {
    std::unique_lock lock(mu);
    while (!cv.wait_for(lock, std::chrono::duration<double>(m.heartbeat_s), [&] { return finished; })) {
      const struct timespec times[2] = {{0, UTIME_NOW}, {0, UTIME_NOW}};
      ::utimensat(AT_FDCWD, (partial / "heartbeat").c_str(), times, 0);
    }
  });
  const LoggedRun run = run_logged(m.augrig, args, log, &g_child);
  {
    std::lock_guard lock(mu);
    finished = true;
  }
  cv.notify_all();
  beat.join();
  sigaction(SIGTERM, &old_term, nullptr);
  sigaction(SIGINT, &old_int, nullptr);
  std::string why = run.why();
  const double wall_s = run.wall_s;
  const std::string last = last_lines(log, 8);
  out << last;

  if (why.empty() && !fs::is_regular_file(partial / "stats.csv")) why = "the command wrote no stats.csv";
  if (!why.empty()) {
    // Not running any more: the partial folder stays to look at, without a heartbeat.
    fs::remove(partial / "heartbeat", ec);
    YAML::Emitter e;
    e << YAML::BeginMap << YAML::Key << "task" << YAML::Value << id << YAML::Key << "why" << YAML::Value
      << why << YAML::Key << "command" << YAML::Value << joined(t.argv) << YAML::Key << "host" << YAML::Value
      << host << YAML::Key << "job" << YAML::Value << job << YAML::Key << "wall_s" << YAML::Value << wall_s
      << YAML::Key << "failed_at" << YAML::Value << utc_now_iso() << YAML::Key << "log" << YAML::Value
      << log.string() << YAML::Key << "last_lines" << YAML::Value << YAML::Literal << last << YAML::EndMap;
    write_durably(failed_of(t), std::string(e.c_str()) + "\n");
    err << "augrig campaign task: " << what << ": " << why << " (log: " << log.string() << ")\n";
    return 1;
  }
  const std::int64_t rss = run.max_rss_bytes;
  // The frames in the outputs: stats.csv has a row per augmented frame. The rest of the shard was
  // left out (a damaged or unreadable frame, one without a pose): task.log says which.
  const std::size_t frames_out = csv_data_rows(partial / "stats.csv");
  const std::size_t left_out = t.shard.frames > frames_out ? t.shard.frames - frames_out : 0;
  YAML::Emitter e;
  e << YAML::BeginMap << YAML::Key << "task" << YAML::Value << id << YAML::Key << "command" << YAML::Value
    << joined(t.argv) << YAML::Key << "frames" << YAML::Value << t.shard.frames << YAML::Key << "frames_out"
    << YAML::Value << frames_out << YAML::Key << "frames_left_out" << YAML::Value << left_out << YAML::Key
    << "wall_s" << YAML::Value << wall_s << YAML::Key << "per_frame_s" << YAML::Value
    << (t.shard.frames ? wall_s / static_cast<double>(t.shard.frames) : 0.0) << YAML::Key << "max_rss_bytes"
    << YAML::Value << rss << YAML::Key << "host" << YAML::Value << host << YAML::Key << "job" << YAML::Value
    << job << YAML::Key << "finished_at" << YAML::Value << utc_now_iso() << YAML::EndMap;
  if (!write_durably(partial / "done.yaml", std::string(e.c_str()) + "\n")) {
    err << "augrig campaign task: " << (partial / "done.yaml").string() << ": cannot write\n";
    return 1;
  }
  fs::rename(partial, t.out, ec);
  if (ec) {
    err << "augrig campaign task: " << partial.string() << " -> " << t.out.string() << ": " << ec.message()
        << "\n";
    return 1;
  }
  fsync_dir(t.out.parent_path());
  out << "campaign: " << what << " done in " << wall_s << " s";
  if (left_out)
    out << "; " << left_out << " of its " << t.shard.frames
        << " frame(s) left out (damaged or unreadable input, or no pose: see "
        << (t.out / "task.log").string() << ")";
  out << "\n";
  return 0;
}

}  // namespace augrig::campaign
