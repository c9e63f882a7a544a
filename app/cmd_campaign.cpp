// augrig campaign: a campaign of recordings and variants on a cluster (docs/CAMPAIGN.md).
//   plan CAMPAIGN.yaml   shards, measured cost, manifest and Slurm array script (--submit: sbatch)
//   status OUT           done / running / failed / stopped / pending per flight, from the files alone
//   resume OUT           the tasks not done, submitted again (or run here with --local)
//   merge OUT            the shards joined into a report per flight and one for the campaign
//   task MANIFEST ID     one task, as the array job runs it
#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <map>
#include <set>

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include "app/cli.hpp"
#include "campaign/campaign.hpp"
#include "campaign/merge.hpp"
#include "campaign/process.hpp"
#include "campaign/slurm.hpp"
#include "campaign/task.hpp"

extern char** environ;

namespace augrig::app {
namespace {

namespace cp = augrig::campaign;

const char* kCampaignUsage =
    "augrig campaign plan CAMPAIGN.yaml [--measure-frames N | --per-frame-s S] [--submit]\n"
    "       augrig campaign status OUT|MANIFEST [--tasks]\n"
    "       augrig campaign resume OUT|MANIFEST [--dry-run | --local [--jobs N]]\n"
    "       augrig campaign merge OUT|MANIFEST [--partial] [--no-plot]\n"
    "       augrig campaign task MANIFEST ID";

const std::vector<OptionSpec>& campaign_specs() {
  static const std::vector<OptionSpec> specs = {
      {"measure-frames", ArgKind::kValue, "N",
       "plan: measure each variant's cost per frame on N frames of the first flight (default 20)"},
      {"per-frame-s", ArgKind::kValue, "S",
       "plan: take S seconds per frame instead of measuring (no memory figure: 2 GB asked)"},
      {"heartbeat-s", ArgKind::kValue, "S", "plan: tasks touch their heartbeat every S seconds (default 10)"},
      {"submit", ArgKind::kFlag, "", "plan: submit the array job(s) with sbatch"},
      {"tasks", ArgKind::kFlag, "", "status: a line per task that is not done"},
      {"dry-run", ArgKind::kFlag, "", "resume: write the array script(s), do not submit"},
      {"local", ArgKind::kFlag, "", "resume: run the tasks not done on this machine instead of Slurm"},
      {"jobs", ArgKind::kValue, "N", "resume --local: tasks at once (default 1)"},
      {"partial", ArgKind::kFlag, "", "merge: merge the flights whose shards are done, list the others"},
      {"no-plot", ArgKind::kFlag, "", "merge: no evaluation.png (it needs gnuplot)"},
  };
  return specs;
}

std::string fixed(double v, int digits) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

// This binary: the tasks run the augrig that planned them.
fs::path self_binary() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  if (ec) runtime_error("cannot find this program's path (/proc/self/exe): " + ec.message());
  return p;
}

// A manifest given as itself or as the campaign's output folder.
cp::Manifest load_manifest_arg(const std::string& arg) {
  fs::path p = arg;
  if (fs::is_directory(p)) p /= "manifest.yaml";
  return unwrap(cp::load_manifest(p));
}

// The flights a variant's cost is measured on: the first of each kind of images (sizes and
// formats), since a flight of larger images costs more time and memory per frame. Flights that
// cannot be cut (MCAP) or have one frame are not measured.
std::vector<std::size_t> flights_to_measure(const cp::CampaignSpec& spec,
                                            const std::vector<cp::FlightFrames>& frames) {
  std::vector<std::size_t> pick;
  std::set<std::string> kinds;
  for (std::size_t i = 0; i < spec.flights.size(); ++i)
    if (frames[i].splittable && frames[i].t_ns.size() >= 2 && kinds.insert(frames[i].images).second)
      pick.push_back(i);
  return pick;
}

// A variant's cost on flight `fi`: the shard command on 1 and on 1 + n frames of it; the difference
// is the cost per frame, the rest the start-up (GL context, opening the recording, the rig).
cp::TaskCost measure_cost(const cp::CampaignSpec& spec, const cp::VariantSpec& v,
                          const std::vector<cp::FlightFrames>& frames, std::size_t fi, int n,
                          const fs::path& prog, std::ostream& out) {
  const cp::FlightSpec& f = spec.flights[fi];
  const std::size_t extra = std::min<std::size_t>(static_cast<std::size_t>(n), frames[fi].t_ns.size() - 1);
  // Whole evaluation periods, so that both runs evaluate in proportion.
  const std::size_t k = std::max<std::size_t>(1, static_cast<std::size_t>(v.every));
  const std::size_t small = std::min(k, frames[fi].t_ns.size() - 1);
  const std::size_t large = std::min(frames[fi].t_ns.size(), small + std::max(extra, k));
  const fs::path dir = spec.out / ".measure" / v.name;
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::create_directories(dir, ec);
  cp::LoggedRun r[2];
  const std::size_t counts[2] = {small, large};
  for (int i = 0; i < 2; ++i) {
    cp::Shard s{0, 0, counts[i], 0, 0};
    std::vector<std::string> args = cp::task_command(f, v, s, false);
    const fs::path o = dir / ("run" + std::to_string(i));
    args.insert(args.end(), {"--out", o.string()});
    r[i] = cp::run_logged(prog, args, dir / ("run" + std::to_string(i) + ".log"));
    if (!r[i].ok())
      runtime_error("variant '" + v.name + "' fails on flight " + f.name + " (" + std::to_string(counts[i]) +
                    " frame(s)); every task would: fix the campaign file. Its command's last lines (" +
                    (dir / ("run" + std::to_string(i) + ".log")).string() + "):\n" +
                    cp::last_lines(dir / ("run" + std::to_string(i) + ".log"), 6, "  "));
  }
  cp::TaskCost c;
  c.per_frame_s = std::max(1e-4, (r[1].wall_s - r[0].wall_s) / static_cast<double>(large - small));
  c.startup_s = std::max(0.0, r[0].wall_s - c.per_frame_s * static_cast<double>(small));
  c.max_rss_bytes = std::max(r[0].max_rss_bytes, r[1].max_rss_bytes);
  char host[256] = {};
  gethostname(host, sizeof host - 1);
  c.measured_on = "flight " + f.name + ", frames 0.." + std::to_string(large - 1) + ", host " + host;
  fs::remove_all(dir, ec);
  out << "  variant " << v.name << ": " << fixed(c.per_frame_s * 1000, 1) << " ms per frame, start-up "
      << fixed(c.startup_s, 2) << " s, peak memory " << c.max_rss_bytes / (1 << 20) << " MB ("
      << c.measured_on << (frames[fi].images.empty() ? "" : ", images " + frames[fi].images) << ")\n";
  return c;
}

int plan(const std::string& file, const ParsedArgs& a, std::ostream& out, std::ostream& err) {
  const cp::CampaignSpec spec = unwrap(cp::load_campaign(file));
  const fs::path prog = self_binary();
  std::error_code ec;
  fs::create_directories(spec.out, ec);
  if (ec) runtime_error(spec.out.string() + ": cannot create the output folder: " + ec.message());

  // Every flight's frames and times: the shards are cut on them.
  out << "campaign '" << spec.name << "': " << spec.flights.size() << " flight(s), " << spec.variants.size()
      << " variant(s)\n";
  std::vector<cp::FlightFrames> frames;
  for (const cp::FlightSpec& f : spec.flights) {
    frames.push_back(unwrap(cp::read_flight_frames(f)));
    const cp::FlightClock clock = cp::flight_clock(frames.back());
    out << "  flight " << f.name << " (" << cp::to_string(f.kind) << ", " << f.path.string() << "): ";
    if (!frames.back().splittable) {
      out << "read whole (one shard)";
      if (frames.back().whole_frames) out << ", " << frames.back().whole_frames << " stereo frame(s)";
      out << "\n";
      continue;
    }
    out << frames.back().t_ns.size() << " stereo frame(s) over "
        << fixed(clock.elapsed_s.empty() ? 0 : clock.elapsed_s.back(), 1) << " s\n";
    if (clock.steps_back)
      out << "    its clock steps back at " << clock.steps_back << " frame(s) (first at frame "
          << clock.first_step_back_frame << ", by up to " << fixed(clock.largest_step_back_s, 3)
          << " s): shards count the typical frame interval there\n";
  }

  // The cost of each variant, measured on this machine (or given).
  std::vector<std::pair<std::string, cp::TaskCost>> costs;
  if (a.has("per-frame-s")) {
    const double s = parse_real("per-frame-s", a.get("per-frame-s"));
    if (!(s > 0)) usage_error("--per-frame-s: expected seconds > 0, got '" + a.get("per-frame-s") + "'");
    for (const auto& v : spec.variants) costs.emplace_back(v.name, cp::TaskCost{20, s, 2LL << 30, "given"});
  } else {
    const int n = a.has("measure-frames")
                      ? static_cast<int>(parse_integer("measure-frames", a.get("measure-frames"), 1, 10000))
                      : 20;
    const std::vector<std::size_t> measured = flights_to_measure(spec, frames);
    if (measured.empty())
      runtime_error(
          "no flight to measure the variants' cost on (MCAP files only, or flights of one frame): give "
          "--per-frame-s");
    out << "measuring each variant's cost (" << n << " frames";
    if (measured.size() > 1)
      out << ", on each of " << measured.size() << " kinds of images: a task is given the largest cost";
    out << "):\n";
    for (const auto& v : spec.variants) {
      cp::TaskCost worst;
      for (std::size_t fi : measured) {
        const cp::TaskCost c = measure_cost(spec, v, frames, fi, n, prog, out);
        worst.per_frame_s = std::max(worst.per_frame_s, c.per_frame_s);
        worst.startup_s = std::max(worst.startup_s, c.startup_s);
        worst.max_rss_bytes = std::max(worst.max_rss_bytes, c.max_rss_bytes);
        worst.measured_on += (worst.measured_on.empty() ? "" : "; ") + c.measured_on;
      }
      costs.emplace_back(v.name, worst);
    }
  }

  cp::Manifest m;
  m.file = spec.out / "manifest.yaml";
  m.name = spec.name;
  m.campaign_file = spec.file;
  m.out = spec.out;
  m.augrig = prog;
  m.planned_at = cp::utc_now_iso();
  m.slurm = spec.slurm;
  m.costs = costs;
  if (a.has("heartbeat-s")) {
    m.heartbeat_s = parse_real("heartbeat-s", a.get("heartbeat-s"));
    if (!(m.heartbeat_s >= 0.1 && m.heartbeat_s <= 3600))
      usage_error("--heartbeat-s: expected seconds in [0.1, 3600], got '" + a.get("heartbeat-s") + "'");
  }
  m.tasks = cp::plan_tasks(spec, frames, costs);
  check(cp::write_manifest(m));

  // What it costs: per variant and flight the shards, and the whole campaign in core-hours.
  double core_s = 0;
  std::map<std::string, std::size_t> shards;
  for (const cp::Task& t : m.tasks) {
    const cp::TaskCost* c = m.cost_of(t.variant);
    core_s += (c->startup_s + c->per_frame_s * static_cast<double>(t.shard.frames)) * m.slurm.cpus_per_task;
    ++shards[t.variant + "/" + t.flight];
  }
  out << m.tasks.size() << " task(s):";
  for (const auto& [k, n] : shards) out << " " << k << " " << n;
  out << "\nestimated " << fixed(core_s / 3600, 2) << " core-hour(s) (" << m.slurm.cpus_per_task
      << " CPU(s) per task, at the measured cost)\n";

  std::vector<std::size_t> ids(m.tasks.size());
  for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = i;
  const auto scripts = unwrap(cp::write_scripts(m, ids, "campaign"));
  const cp::Resources r = cp::task_resources(m, ids);
  out << "wrote " << m.file.string() << " and " << scripts.size() << " array script(s), each task asking "
      << r.cpus << " CPU(s), " << r.mem_mb << " MB, " << cp::slurm_time(r.time_s) << ":\n";
  for (const auto& s : scripts) out << "  sbatch " << s.string() << "\n";
  if (a.has("submit")) {
    for (const auto& s : scripts)
      out << "submitted " << s.filename().string() << " as job " << unwrap(cp::submit(m, s)) << "\n";
    out << "follow it with: augrig campaign status " << spec.out.string() << "\n";
  }
  (void)err;
  return kExitOk;
}

// Per variant and flight, and in all: the tasks by state. The counts add up to the tasks.
int status(const std::string& arg, const ParsedArgs& a, std::ostream& out) {
  const cp::Manifest m = load_manifest_arg(arg);
  const double now = cp::wall_clock_s();
  constexpr int kStates = 5;
  std::map<std::string, std::array<std::size_t, kStates>> by;
  std::vector<std::string> order;
  std::array<std::size_t, kStates> total{};
  std::vector<std::string> notes;
  double done_s = 0;
  std::size_t done_frames = 0, left_out = 0, left_out_shards = 0;
  std::map<std::string, std::size_t> left_out_by;
  for (const cp::Task& t : m.tasks) {
    const cp::TaskStatus s = cp::task_status(m, t, now);
    const std::string key = t.variant + "/" + t.flight;
    if (!by.count(key)) {
      order.push_back(key);
      by[key] = {};
    }
    ++by[key][static_cast<std::size_t>(s.state)];
    ++total[static_cast<std::size_t>(s.state)];
    if (s.state == cp::TaskState::kDone) {
      done_s += s.wall_s;
      done_frames += t.shard.frames;
      if (s.frames_left_out) {
        left_out += s.frames_left_out;
        left_out_by[key] += s.frames_left_out;
        ++left_out_shards;
        if (a.has("tasks"))
          notes.push_back("  task " + std::to_string(t.id) + " (" + key + " shard " +
                          std::to_string(t.shard.index) + ", frames " + std::to_string(t.shard.from_frame) +
                          "+" + std::to_string(t.shard.frames) + "): done, " +
                          std::to_string(s.frames_left_out) + " frame(s) left out (" +
                          (t.out / "task.log").string() + ")");
      }
    }
    if (a.has("tasks") && s.state != cp::TaskState::kDone)
      notes.push_back("  task " + std::to_string(t.id) + " (" + key + " shard " +
                      std::to_string(t.shard.index) + ", frames " + std::to_string(t.shard.from_frame) + "+" +
                      std::to_string(t.shard.frames) + "): " + cp::to_string(s.state) +
                      (s.detail.empty() ? "" : ": " + s.detail));
  }
  auto line = [](const std::array<std::size_t, kStates>& c) {
    std::size_t n = 0;
    for (auto x : c) n += x;
    return std::to_string(n) + " = done " + std::to_string(c[2]) + " + running " + std::to_string(c[1]) +
           " + failed " + std::to_string(c[3]) + " + stopped " + std::to_string(c[4]) + " + pending " +
           std::to_string(c[0]);
  };
  out << "campaign '" << m.name << "' (" << m.file.string() << ", planned " << m.planned_at << ")\n";
  for (const auto& k : order) {
    out << "  " << k << ": tasks " << line(by[k]);
    if (left_out_by.count(k)) out << "; " << left_out_by[k] << " frame(s) left out";
    out << "\n";
  }
  out << "tasks " << line(total) << "\n";
  if (done_frames)
    out << "done: " << done_frames << " frame(s) in " << fixed(done_s, 1) << " s of task time ("
        << fixed(done_s / static_cast<double>(done_frames) * 1000, 1) << " ms per frame)\n";
  if (left_out)
    out << "left out: " << left_out << " frame(s) in " << left_out_shards
        << " done shard(s): their input could not be read (damaged) or had no pose; each shard's task.log "
           "says which (--tasks lists them)\n";
  for (const auto& n : notes) out << n << "\n";
  if (total[2] == m.tasks.size())
    out << "all done: augrig campaign merge " << m.out.string() << "\n";
  else if (total[3] + total[4] + total[0] > 0 && total[1] == 0)
    out << "not done: augrig campaign resume " << m.out.string() << "\n";
  return kExitOk;
}

// Runs the tasks here, `jobs` at once, each as `augrig campaign task` (as Slurm would).
int run_local(const cp::Manifest& m, const std::vector<std::size_t>& ids, int jobs, std::ostream& out) {
  const fs::path prog = self_binary();
  std::map<pid_t, std::size_t> running;
  std::size_t next = 0, ok = 0, failed = 0;
  auto start = [&](std::size_t id) {
    std::vector<std::string> a = {prog.string(), "campaign", "task", m.file.string(), std::to_string(id)};
    std::vector<char*> argv;
    for (auto& s : a) argv.push_back(s.data());
    argv.push_back(nullptr);
    pid_t pid = 0;
    if (::posix_spawn(&pid, prog.c_str(), nullptr, nullptr, argv.data(), environ) != 0)
      runtime_error("cannot start " + prog.string());
    running[pid] = id;
  };
  while (next < ids.size() || !running.empty()) {
    while (next < ids.size() && running.size() < static_cast<std::size_t>(jobs)) start(ids[next++]);
    int status = 0;
    const pid_t pid = ::waitpid(-1, &status, 0);
    if (pid < 0) {
      if (errno == EINTR) continue;
      break;
    }
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    const bool good = WIFEXITED(status) && WEXITSTATUS(status) == 0;
    (good ? ok : failed)++;
    out << "campaign: " << ok + failed << " of " << ids.size() << " task(s) ended (" << ok << " ok, "
        << failed << " failed); task " << it->second << (good ? " ok" : " failed") << std::endl;
    running.erase(it);
  }
  return failed ? kExitRuntime : kExitOk;
}

int resume(const std::string& arg, const ParsedArgs& a, std::ostream& out) {
  const cp::Manifest m = load_manifest_arg(arg);
  if (a.has("local") && a.has("dry-run")) usage_error("--local and --dry-run exclude each other");
  if (a.has("jobs") && !a.has("local")) usage_error("--jobs is for --local");
  const double now = cp::wall_clock_s();
  std::vector<std::size_t> ids;
  std::size_t running = 0;
  for (const cp::Task& t : m.tasks) {
    const cp::TaskState s = cp::task_status(m, t, now).state;
    if (s == cp::TaskState::kRunning)
      ++running;
    else if (s != cp::TaskState::kDone)
      ids.push_back(t.id);
  }
  if (ids.empty()) {
    out << "nothing to resume: " << m.tasks.size() - running << " of " << m.tasks.size() << " task(s) done"
        << (running ? ", " + std::to_string(running) + " running" : std::string()) << "\n";
    return kExitOk;
  }
  out << ids.size() << " of " << m.tasks.size() << " task(s) not done: " << cp::array_spec(ids, 0)
      << (running ? " (" + std::to_string(running) + " running, left alone)" : std::string()) << "\n";
  if (a.has("local")) {
    const int jobs = a.has("jobs") ? static_cast<int>(parse_integer("jobs", a.get("jobs"), 1, 1024)) : 1;
    return run_local(m, ids, jobs, out);
  }
  const std::string stem = "resume-" + std::to_string(static_cast<long long>(now));
  const auto scripts = unwrap(cp::write_scripts(m, ids, stem));
  for (const auto& s : scripts) {
    if (a.has("dry-run"))
      out << "  sbatch " << s.string() << "\n";
    else
      out << "submitted " << s.filename().string() << " as job " << unwrap(cp::submit(m, s)) << "\n";
  }
  return kExitOk;
}

int merge(const std::string& arg, const ParsedArgs& a, std::ostream& out) {
  const cp::Manifest m = load_manifest_arg(arg);
  cp::MergeOptions o;
  o.partial = a.has("partial");
  o.plot = !a.has("no-plot");
  const cp::MergeSummary s = unwrap(cp::merge_campaign(m, o, out));
  out << "campaign report: " << (s.report_dir / "campaign.txt").string() << " (" << s.flights_merged
      << " flight report(s), " << s.frames << " frame(s), " << s.evaluated << " evaluated)";
  if (s.flights_incomplete) out << "; " << s.flights_incomplete << " not merged (shards not done)";
  out << "\n";
  return s.flights_incomplete ? kExitRuntime : kExitOk;
}

int campaign_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  std::vector<std::string> pos;
  // The sub-command and its operands are positionals: `task` takes two, the others one.
  std::vector<std::string> names = {"COMMAND", "OUT"};
  if (!args.empty() && args[0] == "task") names = {"COMMAND", "MANIFEST", "ID"};
  const ParsedArgs a = parse_with_positionals(args, campaign_specs(), names, pos);
  if (a.help) {
    out << format_help(
        kCampaignUsage,
        "A campaign of recordings (or EuRoC folders, MCAP files) and variants (boom, rig, scene,\n"
        "evaluation settings) on a Slurm cluster. plan cuts every flight into shards by time, measures\n"
        "each variant's cost per frame, and writes the manifest and the array job script (one task per\n"
        "shard, each an ordinary `augrig evaluate` or `augrig replay` on its frames). Tasks are\n"
        "idempotent: status reads done, running, failed, stopped and pending from the output files\n"
        "alone, resume submits what is not done, merge joins the shards into one report per flight\n"
        "and one for the campaign, equal to an unsharded run's (docs/CAMPAIGN.md).",
        campaign_specs());
    return kExitOk;
  }
  const std::string& sub = pos[0];
  auto only = [&](std::initializer_list<const char*> allowed) {
    for (const auto& [k, v] : a.values) {
      bool ok = false;
      for (const char* x : allowed) ok = ok || k == x;
      if (!ok) usage_error("--" + k + " is not an option of 'campaign " + sub + "'");
    }
  };
  if (sub == "plan") {
    only({"measure-frames", "per-frame-s", "heartbeat-s", "submit"});
    if (a.has("measure-frames") && a.has("per-frame-s"))
      usage_error("--measure-frames and --per-frame-s exclude each other");
    return plan(pos[1], a, out, err);
  }
  if (sub == "status") {
    only({"tasks"});
    return status(pos[1], a, out);
  }
  if (sub == "resume") {
    only({"dry-run", "local", "jobs"});
    return resume(pos[1], a, out);
  }
  if (sub == "merge") {
    only({"partial", "no-plot"});
    return merge(pos[1], a, out);
  }
  if (sub == "task") {
    only({});
    const long long id = parse_integer("ID", pos[2], 0, 1LL << 40);
    const cp::Manifest m = load_manifest_arg(pos[1]);
    return cp::run_task(m, static_cast<std::size_t>(id), out, err);
  }
  usage_error("expected plan, status, resume, merge or task, got '" + sub + "'");
}

}  // namespace

int cmd_campaign(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("campaign", err, [&] { return campaign_command(args, out, err); });
}

}  // namespace augrig::app
