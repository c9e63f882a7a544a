#include "tests/support/local_slurm.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <thread>

#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

namespace augrig::test {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

// The programs a cluster needs and the Debian 12 packages that have them.
struct Program {
  const char* name;
  const char* package;
};
constexpr Program kPrograms[] = {
    {"munged", "munge"},        {"slurmctld", "slurmctld"},   {"slurmd", "slurmd"},
    {"sbatch", "slurm-client"}, {"squeue", "slurm-client"},   {"scancel", "slurm-client"},
    {"sinfo", "slurm-client"},  {"scontrol", "slurm-client"},
};

// The PATH the daemons get, and where programs are looked for besides the caller's PATH (root's
// PATH in a container may lack the sbin directories the daemons are in).
constexpr const char* kSystemPath = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin";

// Variables Slurm clients take input from: a test running inside a Slurm job must not hand its
// own job's to this cluster's clients.
constexpr const char* kClientInputPrefixes[] = {"SLURM_",  "SBATCH_", "SALLOC_",  "SRUN_",
                                                "SQUEUE_", "SINFO_",  "SCANCEL_", "SACCT_"};
constexpr const char* kMarkVariable = "AUGRIG_LOCAL_SLURM";

std::string find_program(const std::string& name) {
  std::string path;
  if (const char* p = std::getenv("PATH")) path = p;
  path += std::string(":") + kSystemPath;
  std::stringstream ss(path);
  std::string d;
  while (std::getline(ss, d, ':')) {
    if (d.empty()) continue;
    const fs::path candidate = fs::path(d) / name;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "";
}

std::string read_text(const fs::path& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

bool write_text(const fs::path& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f << text;
  return static_cast<bool>(f);
}

std::string tail_lines(const std::string& text, int lines) {
  std::size_t end = text.size();
  while (end > 0 && text[end - 1] == '\n') --end;
  std::size_t pos = end;
  for (int n = 0; n < lines && pos > 0; ++n) {
    const std::size_t nl = text.rfind('\n', pos - 1);
    if (nl == std::string::npos) {
      pos = 0;
      break;
    }
    pos = nl;
  }
  if (pos > 0) ++pos;
  return text.substr(pos, end - pos);
}

std::string trim(std::string s) {
  const auto not_space = [](unsigned char c) { return !std::isspace(c); };
  s.erase(s.begin(), std::find_if(s.begin(), s.end(), not_space));
  s.erase(std::find_if(s.rbegin(), s.rend(), not_space).base(), s.end());
  return s;
}

// NUL-separated /proc/PID/{cmdline,environ} into strings.
std::vector<std::string> proc_strings(pid_t pid, const char* what) {
  const std::string raw = read_text("/proc/" + std::to_string(pid) + "/" + what);
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start < raw.size()) {
    std::size_t end = raw.find('\0', start);
    if (end == std::string::npos) end = raw.size();
    out.push_back(raw.substr(start, end - start));
    start = end + 1;
  }
  return out;
}

// A process's state letter and parent from /proc/PID/stat ('\0' when it is gone).
char proc_state(pid_t pid, pid_t* parent = nullptr) {
  const std::string stat = read_text("/proc/" + std::to_string(pid) + "/stat");
  const std::size_t paren = stat.rfind(')');
  if (paren == std::string::npos || paren + 2 >= stat.size()) return '\0';
  std::istringstream rest(stat.substr(paren + 2));
  char state = '\0';
  pid_t ppid = 0;
  rest >> state >> ppid;
  if (parent) *parent = ppid;
  return state;
}

bool alive(pid_t pid) {
  const char s = proc_state(pid);
  return s != '\0' && s != 'Z' && s != 'X';
}

// This process and its ancestors: never counted among a cluster's processes.
std::set<pid_t> self_and_ancestors() {
  std::set<pid_t> out;
  pid_t pid = ::getpid();
  while (pid > 1 && out.insert(pid).second) {
    pid_t parent = 0;
    if (proc_state(pid, &parent) == '\0') break;
    pid = parent;
  }
  return out;
}

bool port_free(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return false;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_ANY);  // slurmctld and slurmd listen on every address
  const bool ok = ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  ::close(fd);
  return ok;
}

// Two free neighbouring ports in 20000-29999 (below Linux's ephemeral range, away from Slurm's
// 6817/6818), starting at a random place so that clusters started at once pick different ones.
bool pick_ports(int* ctld, int* slurmd) {
  std::random_device rd;
  const int start = 20000 + static_cast<int>(rd() % 5000) * 2;
  for (int i = 0; i < 5000; ++i) {
    const int p = 20000 + (start - 20000 + 2 * i) % 10000;
    if (port_free(p) && port_free(p + 1)) {
      *ctld = p;
      *slurmd = p + 1;
      return true;
    }
  }
  return false;
}

long mem_total_mb() {
  std::ifstream f("/proc/meminfo");
  std::string key;
  long kb = 0;
  std::string unit;
  while (f >> key >> kb >> unit)
    if (key == "MemTotal:") return kb / 1024;
  return 0;
}

// execve()'s arrays from strings (kept alive by the caller).
std::vector<char*> c_array(std::vector<std::string>& strings) {
  std::vector<char*> out;
  for (std::string& s : strings) out.push_back(s.data());
  out.push_back(nullptr);
  return out;
}

// Starts argv[0] (an absolute path) as a child in its own process group with stdout and stderr
// appended to `log`, stdin /dev/null, only `env` as environment, and SIGTERM when the thread that
// started it ends. -1 when fork fails.
pid_t spawn(std::vector<std::string> argv, std::vector<std::string> env, const fs::path& log) {
  std::vector<char*> args = c_array(argv), envp = c_array(env);
  const int out = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  const int in = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::setpgid(0, 0);
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (::getppid() != parent) ::_exit(127);  // the parent already died
    if (in >= 0) ::dup2(in, 0);
    if (out >= 0) {
      ::dup2(out, 1);
      ::dup2(out, 2);
    }
    ::close_range(3, ~0U, 0);
    ::execve(args[0], args.data(), envp.data());
    ::_exit(127);
  }
  if (out >= 0) ::close(out);
  if (in >= 0) ::close(in);
  return pid;
}

// Reaps `pid` if it ended; true while it runs.
bool child_running(pid_t pid, int* status = nullptr) {
  if (pid <= 0) return false;
  int st = 0;
  const pid_t r = ::waitpid(pid, &st, WNOHANG);
  if (r == pid) {
    if (status) *status = st;
    return false;
  }
  return r == 0;
}

std::string describe_status(int status) {
  if (WIFEXITED(status)) return "exit status " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return std::string("killed by ") + strsignal(WTERMSIG(status));
  return "status " + std::to_string(status);
}

// SIGTERM, up to `grace_s` to end, then SIGKILL; reaps it.
void terminate_child(pid_t pid, double grace_s) {
  if (pid <= 0) return;
  if (!child_running(pid)) return;
  ::kill(pid, SIGTERM);
  const auto deadline = Clock::now() + std::chrono::duration<double>(grace_s);
  while (Clock::now() < deadline) {
    if (!child_running(pid)) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ::kill(pid, SIGKILL);
  ::waitpid(pid, nullptr, 0);
}

// SIGKILLs every process of the cluster under `dir` and waits (up to 5 s) until none is left.
void kill_processes_of(const fs::path& dir) {
  const auto deadline = Clock::now() + std::chrono::seconds(5);
  for (;;) {
    const std::vector<pid_t> left = LocalSlurm::processes_of(dir);
    if (left.empty() || Clock::now() > deadline) return;
    for (pid_t p : left) {
      ::kill(p, SIGKILL);
      ::waitpid(p, nullptr, WNOHANG);  // our own children (clients run by run()) are reaped here
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

bool starts_with(const std::string& s, const std::string& prefix) {
  return s.rfind(prefix, 0) == 0;
}

}  // namespace

bool SlurmTask::finished() const {
  static const std::set<std::string> kTerminal = {"COMPLETED", "FAILED",        "CANCELLED", "TIMEOUT",
                                                  "NODE_FAIL", "OUT_OF_MEMORY", "PREEMPTED", "BOOT_FAIL",
                                                  "DEADLINE",  "REVOKED"};
  return kTerminal.count(state) > 0;
}

std::vector<pid_t> LocalSlurm::processes_of(const fs::path& dir_in) {
  const std::string dir = fs::absolute(dir_in).lexically_normal().string();
  const std::string under = dir + "/";
  const std::string mark = std::string(kMarkVariable) + "=" + dir;
  const std::string conf = "SLURM_CONF=" + under + "slurm.conf";
  const std::set<pid_t> exclude = self_and_ancestors();
  std::vector<pid_t> out;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator("/proc", ec)) {
    const std::string name = e.path().filename().string();
    if (name.empty() || !std::all_of(name.begin(), name.end(), ::isdigit)) continue;
    const pid_t pid = static_cast<pid_t>(std::stol(name));
    if (exclude.count(pid) || !alive(pid)) continue;
    bool ours = false;
    for (const std::string& arg : proc_strings(pid, "cmdline"))
      if (arg == dir || arg.find(under) != std::string::npos) ours = true;
    if (!ours)
      for (const std::string& var : proc_strings(pid, "environ"))
        if (var == mark || var == conf) ours = true;
    if (ours) out.push_back(pid);
  }
  return out;
}

std::string LocalSlurm::missing_requirements() {
  if (::geteuid() != 0)
    return "LocalSlurm: a local Slurm cluster needs root (slurmd starts jobs as their user), and this "
           "runs as uid " +
           std::to_string(::geteuid());
  std::string missing, packages;
  for (const Program& p : kPrograms) {
    if (!find_program(p.name).empty()) continue;
    missing += std::string(missing.empty() ? "" : ", ") + p.name;
    if (packages.find(p.package) == std::string::npos)
      packages += std::string(packages.empty() ? "" : " ") + p.package;
  }
  if (!missing.empty())
    return "LocalSlurm: " + missing + " not installed (Debian packages: " + packages +
           "; scripts/install-deps.sh installs them)";
  return "";
}

Expected<std::unique_ptr<LocalSlurm>> LocalSlurm::start(const fs::path& dir, int cpus, double timeout_s) {
  if (const std::string why = missing_requirements(); !why.empty()) return Error{why};
  if (cpus < 1) return make_error("LocalSlurm: cpus must be at least 1, not ", cpus);
  // Another cluster (or anything) may take the ports between their pick and the daemons' bind:
  // then again, on other ports.
  for (int attempt = 1;; ++attempt) {
    auto s = start_once(dir, cpus, timeout_s);
    if (s || attempt == 3 || s.error().message.find("Address already in use") == std::string::npos) return s;
  }
}

Expected<std::unique_ptr<LocalSlurm>> LocalSlurm::start_once(const fs::path& dir_in, int cpus,
                                                             double timeout_s) {
  std::map<std::string, std::string> prog;
  for (const Program& p : kPrograms) prog[p.name] = find_program(p.name);

  std::unique_ptr<LocalSlurm> s(new LocalSlurm);
  s->cpus_ = cpus;
  s->dir_ = fs::absolute(dir_in).lexically_normal();
  if (s->dir_.has_filename() == false) s->dir_ = s->dir_.parent_path();
  const fs::path& dir = s->dir_;
  // It is emptied below, and slurm.conf's paths cannot have blanks.
  if (dir == dir.root_path() || std::distance(dir.begin(), dir.end()) < 3)
    return make_error("LocalSlurm: ", dir.string(), " is too near the root to be emptied for a cluster");
  if (dir.string().find_first_of(" \t\n\"'#") != std::string::npos)
    return make_error("LocalSlurm: ", dir.string(),
                      ": a path with blanks, quotes or # cannot go in slurm.conf");
  s->conf_ = dir / "slurm.conf";
  s->log_dir_ = dir / "log";

  // What a crashed run left here: its processes (daemons, job steps), its /tmp runtime directory.
  kill_processes_of(dir);
  std::error_code ec;
  const std::string old_runtime = trim(read_text(dir / "runtime-dir"));
  if (starts_with(old_runtime, "/tmp/augrig-slurm-")) fs::remove_all(old_runtime, ec);
  fs::remove_all(dir, ec);
  for (const char* sub : {"state", "log", "munge", "pid"}) {
    fs::create_directories(dir / sub, ec);
    if (ec) return make_error("LocalSlurm: cannot create ", (dir / sub).string(), ": ", ec.message());
  }
  ::chmod(dir.c_str(), 0755);

  // munged's socket and slurmd's spool (its step sockets) must fit a socket path's 108 bytes: they
  // go under a short /tmp directory when `dir` is long.
  if (dir.string().size() <= 60) {
    s->runtime_dir_ = dir / "run";
    fs::create_directories(s->runtime_dir_, ec);
  } else {
    std::string tmpl = "/tmp/augrig-slurm-XXXXXX";
    if (!::mkdtemp(tmpl.data())) return make_error("LocalSlurm: mkdtemp ", tmpl, ": ", std::strerror(errno));
    s->runtime_dir_ = tmpl;
    s->own_runtime_dir_ = true;
    write_text(dir / "runtime-dir", tmpl + "\n");
  }
  ::chmod(s->runtime_dir_.c_str(), 0755);  // munged wants its socket directory searchable by all
  fs::create_directories(s->runtime_dir_ / "spool", ec);
  const fs::path socket = s->runtime_dir_ / "munge.socket";
  const fs::path key = dir / "munge" / "munge.key";

  {  // Our own munge key: 1024 random bytes, readable by root only.
    std::ifstream urandom("/dev/urandom", std::ios::binary);
    std::string bytes(1024, '\0');
    urandom.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    const int fd = ::open(key.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0400);
    if (fd < 0 || !urandom || ::write(fd, bytes.data(), bytes.size()) != static_cast<ssize_t>(bytes.size())) {
      if (fd >= 0) ::close(fd);
      return make_error("LocalSlurm: cannot write the munge key ", key.string(), ": ", std::strerror(errno));
    }
    ::close(fd);
  }

  const long total_mb = mem_total_mb();
  s->real_memory_mb_ = std::max(256L, total_mb - std::max(512L, total_mb / 10));
  int ctld_port = 0, slurmd_port = 0;
  if (!pick_ports(&ctld_port, &slurmd_port))
    return make_error("LocalSlurm: no two free TCP ports in 20000-29999");

  const std::string d = dir.string(), run = s->runtime_dir_.string();
  write_text(dir / "plugstack.conf", "# no SPANK plugins\n");
  std::ostringstream conf;
  conf << "# A one-node Slurm cluster on loopback for augrig's tests, written by\n"
       << "# tests/support/local_slurm.cpp. Everything it keeps is under " << d << "\n"
       << "# (munged's socket and slurmd's spool under " << run << ").\n"
       << "ClusterName=augrig\n"
       << "SlurmctldHost=localhost(127.0.0.1)\n"
       << "SlurmctldPort=" << ctld_port << "\n"
       << "SlurmdPort=" << slurmd_port << "\n"
       << "SlurmUser=root\n"
       << "SlurmdUser=root\n"
       << "AuthType=auth/munge\n"
       << "CredType=cred/munge\n"
       << "AuthInfo=socket=" << socket.string() << "\n"
       << "StateSaveLocation=" << d << "/state\n"
       << "SlurmdSpoolDir=" << run << "/spool\n"
       << "SlurmctldPidFile=" << d << "/pid/slurmctld.pid\n"
       << "SlurmdPidFile=" << d << "/pid/slurmd.pid\n"
       << "SlurmctldLogFile=" << d << "/log/slurmctld.log\n"
       << "SlurmdLogFile=" << d << "/log/slurmd.log\n"
       << "SlurmctldDebug=info\n"
       << "SlurmdDebug=info\n"
       << "PlugStackConfig=" << d
       << "/plugstack.conf\n"
       // No cgroups: processes tracked by their parentage, tasks not bound.
       << "ProctrackType=proctrack/linuxproc\n"
       << "TaskPlugin=task/none\n"
       << "JobAcctGatherType=jobacct_gather/none\n"
       << "AccountingStorageType=accounting_storage/none\n"
       << "JobCompType=jobcomp/none\n"
       << "MpiDefault=none\n"
       << "MailProg=/bin/true\n"
       // CPUs (cores) and memory are consumable: --cpus-per-task and --mem decide what runs at once.
       << "SelectType=select/cons_tres\n"
       << "SelectTypeParameters=CR_Core_Memory\n"
       << "DefMemPerCPU=" << std::max(1L, s->real_memory_mb_ / cpus) << "\n"
       << "SchedulerType=sched/backfill\n"
       << "SchedulerParameters=batch_sched_delay=0\n"
       // A job asking for more than the partition has is refused by sbatch, not left pending.
       << "EnforcePartLimits=ALL\n"
       // The node is what this file says, whatever the hardware (CPUs beyond the machine's).
       << "SlurmdParameters=config_overrides\n"
       << "MaxArraySize=10001\n"
       << "MaxJobCount=100000\n"
       << "MinJobAge=600\n"  // finished jobs stay in squeue -t all this long
       << "KillWait=5\n"
       << "InactiveLimit=0\n"
       << "ReturnToService=2\n"
       << "SlurmctldTimeout=120\n"
       << "SlurmdTimeout=300\n"
       << "NodeName=localhost NodeAddr=127.0.0.1 CPUs=" << cpus << " Sockets=1 CoresPerSocket=" << cpus
       << " ThreadsPerCore=1 RealMemory=" << s->real_memory_mb_ << " State=UNKNOWN\n"
       << "PartitionName=" << kPartition << " Nodes=localhost Default=YES MaxTime=INFINITE State=UP\n";
  if (!write_text(s->conf_, conf.str())) return make_error("LocalSlurm: cannot write ", s->conf_.string());

  std::vector<std::string> daemon_env = {std::string("PATH=") + kSystemPath,
                                         "SLURM_CONF=" + s->conf_.string(),
                                         std::string(kMarkVariable) + "=" + d};
  if (const char* home = std::getenv("HOME")) daemon_env.push_back(std::string("HOME=") + home);
  if (const char* tz = std::getenv("TZ")) daemon_env.push_back(std::string("TZ=") + tz);

  // `status`: the daemon's wait status, or -1 while it still runs.
  const auto failed = [&](const std::string& what, int status, const std::vector<fs::path>& logs) {
    std::string msg =
        "LocalSlurm: " + what + " (" + (status == -1 ? "still running" : describe_status(status)) + ")";
    for (const fs::path& log : logs) {
      const std::string t = tail_lines(read_text(log), 25);
      if (!t.empty()) msg += "\n--- " + log.string() + " (end) ---\n" + t;
    }
    return Error{msg};
  };

  // munged, in the foreground (its log on stderr), on our socket with our key.
  const fs::path munged_log = s->log_dir_ / "munged.log";
  s->munged_ = spawn(
      {prog["munged"], "--foreground", "--force", "--socket=" + socket.string(), "--key-file=" + key.string(),
       "--pid-file=" + d + "/pid/munged.pid", "--seed-file=" + d + "/munge/munged.seed",
       "--log-file=" + munged_log.string(), "--num-threads=2"},
      daemon_env, munged_log);
  if (s->munged_ < 0) return make_error("LocalSlurm: fork: ", std::strerror(errno));
  int status = 0;
  for (auto deadline = Clock::now() + std::chrono::seconds(10);;) {
    if (!child_running(s->munged_, &status)) {
      s->munged_ = -1;
      return failed("munged failed to start", status, {munged_log});
    }
    if (fs::exists(socket, ec)) break;
    if (Clock::now() > deadline) return failed("munged made no socket within 10 s", -1, {munged_log});
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }

  const fs::path ctld_out = s->log_dir_ / "slurmctld.out", ctld_log = s->log_dir_ / "slurmctld.log";
  const fs::path slurmd_out = s->log_dir_ / "slurmd.out", slurmd_log = s->log_dir_ / "slurmd.log";
  s->slurmctld_ = spawn({prog["slurmctld"], "-D", "-f", s->conf_.string()}, daemon_env, ctld_out);
  s->slurmd_ =
      spawn({prog["slurmd"], "-D", "-N", "localhost", "-f", s->conf_.string()}, daemon_env, slurmd_out);
  if (s->slurmctld_ < 0 || s->slurmd_ < 0) return make_error("LocalSlurm: fork: ", std::strerror(errno));

  // Up when sinfo shows the node idle.
  std::string last;
  for (auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);;) {
    if (!child_running(s->munged_, &status)) {
      s->munged_ = -1;
      return failed("munged stopped", status, {munged_log});
    }
    if (!child_running(s->slurmctld_, &status)) {
      s->slurmctld_ = -1;
      return failed("slurmctld failed to start", status, {ctld_out, ctld_log});
    }
    if (!child_running(s->slurmd_, &status)) {
      s->slurmd_ = -1;
      return failed("slurmd failed to start", status, {slurmd_out, slurmd_log});
    }
    const SlurmCommandResult r = s->run("sinfo -h -N -n localhost -o %T", 10);
    last = trim(r.output());
    if (r.exit_code == 0 && last == "idle") break;
    if (Clock::now() > deadline) {
      return failed("the node did not become idle within " + std::to_string(static_cast<int>(timeout_s)) +
                        " s (sinfo: " + (last.empty() ? "nothing" : last) + ")",
                    -1, {ctld_log, slurmd_log});
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  return Expected<std::unique_ptr<LocalSlurm>>(std::move(s));
}

LocalSlurm::~LocalSlurm() {
  stop();
}

void LocalSlurm::stop() {
  if (stopped_) return;
  stopped_ = true;
  // Jobs first, so that slurmd can still end their steps (briefly: what is left is killed below).
  if (child_running(slurmctld_) && child_running(slurmd_)) {
    run("scancel --user=root", 10);
    const auto deadline = Clock::now() + std::chrono::seconds(2);
    while (Clock::now() < deadline) {
      const SlurmCommandResult r = run("squeue -h -o %i", 5);
      if (r.exit_code != 0 || trim(r.out).empty()) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  terminate_child(slurmd_, 10);
  terminate_child(slurmctld_, 10);
  terminate_child(munged_, 10);
  slurmd_ = slurmctld_ = munged_ = -1;
  if (!dir_.empty()) kill_processes_of(dir_);  // job steps and tasks slurmd left, clients
  std::error_code ec;
  if (own_runtime_dir_) {
    fs::remove_all(runtime_dir_, ec);
    fs::remove(dir_ / "runtime-dir", ec);
  }
}

std::vector<std::pair<std::string, std::string>> LocalSlurm::env() const {
  return {{"SLURM_CONF", conf_.string()}, {kMarkVariable, dir_.string()}};
}

std::vector<std::string> LocalSlurm::client_environment() const {
  std::vector<std::string> out;
  for (char** e = environ; e && *e; ++e) {
    const std::string var = *e;
    bool drop = starts_with(var, std::string(kMarkVariable) + "=");
    for (const char* prefix : kClientInputPrefixes) drop = drop || starts_with(var, prefix);
    if (!drop) out.push_back(var);
  }
  for (const auto& [name, value] : env()) out.push_back(name + "=" + value);
  return out;
}

void LocalSlurm::apply_env() const {
  std::vector<std::string> names;
  for (char** e = environ; e && *e; ++e) {
    const std::string var = *e;
    for (const char* prefix : kClientInputPrefixes)
      if (starts_with(var, prefix)) names.push_back(var.substr(0, var.find('=')));
  }
  for (const std::string& n : names) ::unsetenv(n.c_str());
  for (const auto& [name, value] : env()) ::setenv(name.c_str(), value.c_str(), 1);
}

SlurmCommandResult LocalSlurm::run(const std::string& shell_command, double timeout_s) const {
  SlurmCommandResult result;
  std::vector<std::string> argv = {"/bin/sh", "-c", shell_command};
  std::vector<std::string> env = client_environment();
  std::vector<char*> args = c_array(argv), envp = c_array(env);
  int out[2], err[2];
  if (::pipe2(out, O_CLOEXEC) != 0) {
    result.err = std::string("pipe: ") + std::strerror(errno);
    return result;
  }
  if (::pipe2(err, O_CLOEXEC) != 0) {
    ::close(out[0]);
    ::close(out[1]);
    result.err = std::string("pipe: ") + std::strerror(errno);
    return result;
  }
  const int in = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::setpgid(0, 0);
    if (in >= 0) ::dup2(in, 0);
    ::dup2(out[1], 1);
    ::dup2(err[1], 2);
    ::execve(args[0], args.data(), envp.data());
    ::_exit(127);
  }
  ::close(out[1]);
  ::close(err[1]);
  if (in >= 0) ::close(in);
  if (pid < 0) {
    ::close(out[0]);
    ::close(err[0]);
    result.err = std::string("fork: ") + std::strerror(errno);
    return result;
  }
  ::setpgid(pid, pid);  // also here, so that a kill below finds the group whichever runs first
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  pollfd fds[2] = {{out[0], POLLIN, 0}, {err[0], POLLIN, 0}};
  std::string* sinks[2] = {&result.out, &result.err};
  int open_fds = 2;
  while (open_fds > 0) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) {
      result.timed_out = true;
      ::kill(-pid, SIGKILL);
      break;
    }
    const int n = ::poll(fds, 2, static_cast<int>(std::min<long long>(left, 1000)));
    if (n < 0 && errno != EINTR) break;
    for (int i = 0; i < 2; ++i) {
      if (fds[i].fd < 0 || !(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      char buf[4096];
      const ssize_t got = ::read(fds[i].fd, buf, sizeof buf);
      if (got > 0) {
        sinks[i]->append(buf, static_cast<std::size_t>(got));
      } else if (got == 0 || errno != EINTR) {
        ::close(fds[i].fd);
        fds[i].fd = -1;
        --open_fds;
      }
    }
  }
  for (pollfd& f : fds)
    if (f.fd >= 0) ::close(f.fd);
  int status = 0;
  if (::waitpid(pid, &status, 0) == pid) {
    if (WIFEXITED(status))
      result.exit_code = WEXITSTATUS(status);
    else if (WIFSIGNALED(status))
      result.exit_code = 128 + WTERMSIG(status);
  }
  if (result.timed_out) result.err += "\n(killed after " + std::to_string(timeout_s) + " s)";
  return result;
}

Expected<std::string> LocalSlurm::submit(const std::string& sbatch_args) const {
  const SlurmCommandResult r = run("sbatch --parsable " + sbatch_args, 60);
  std::string id = trim(r.out);
  id = id.substr(0, id.find(';'));  // "ID;CLUSTER" on a multi-cluster setup
  if (r.exit_code != 0 || id.empty() || !std::all_of(id.begin(), id.end(), ::isdigit))
    return make_error("sbatch --parsable ", sbatch_args, " failed (exit status ", r.exit_code,
                      "): ", r.output());
  return id;
}

std::vector<SlurmTask> LocalSlurm::tasks(const std::string& job_id) const {
  std::vector<SlurmTask> out;
  const SlurmCommandResult r =
      run("squeue -h -r -t all -j " + job_id + " -O JobArrayID:64,State:32,exit_code:16", 30);
  if (r.exit_code != 0) return out;  // "Invalid job id specified": Slurm forgot it
  std::istringstream lines(r.out);
  std::string line;
  while (std::getline(lines, line)) {
    std::istringstream f(line);
    SlurmTask t;
    if (f >> t.id >> t.state) {
      int raw = 0;  // squeue's exit_code is the wait status slurmstepd saw
      if (f >> raw) {
        if (WIFSIGNALED(raw))
          t.signal = WTERMSIG(raw);
        else
          t.exit_status = WEXITSTATUS(raw);
      }
      out.push_back(t);
    }
  }
  return out;
}

Expected<std::vector<SlurmTask>> LocalSlurm::wait_for_jobs(const std::string& job_id,
                                                           double timeout_s) const {
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  for (;;) {
    std::vector<SlurmTask> t = tasks(job_id);
    if (std::all_of(t.begin(), t.end(), [](const SlurmTask& x) { return x.finished(); })) return t;
    if (Clock::now() > deadline) {
      std::string listing;
      for (const SlurmTask& x : t) listing += "\n  " + x.id + " " + x.state;
      return make_error("job ", job_id, " not finished after ", static_cast<int>(timeout_s), " s:", listing);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
}

bool LocalSlurm::wait_running(const std::string& job_id, int count, double timeout_s) const {
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  for (;;) {
    const std::vector<SlurmTask> t = tasks(job_id);
    if (std::count_if(t.begin(), t.end(), [](const SlurmTask& x) { return x.state == "RUNNING"; }) >= count)
      return true;
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

std::string LocalSlurm::log_tail(int lines) const {
  std::string out;
  for (const char* name : {"slurmctld.log", "slurmd.log", "munged.log"}) {
    const std::string t = tail_lines(read_text(log_dir_ / name), lines);
    out += "--- " + (log_dir_ / name).string() + " (end) ---\n" + t + "\n";
  }
  return out;
}

}  // namespace augrig::test
