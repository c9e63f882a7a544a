// bench_campaign: issue 21's figures, what a campaign costs, with the real `augrig campaign` end to
// end as child processes on a recording of the built-in demo flight (the paper rig, 1280x960
// BayerRG8, observation to contact):
//   1. `augrig run --record` makes the recording (not timed);
//   2. `augrig campaign plan` with two variants (the recorded statistics: replay; a fixed boom
//      evaluated every 5th frame: evaluate), measuring each variant's cost per frame and start-up;
//   3. `augrig campaign resume --local --jobs 1` runs every shard one at a time (wall time);
//   4. `augrig campaign merge` (wall time).
// From the measured costs: shards per hour per core for 10-minute shards, and the core-hours one
// 1-hour flight at 30 fps costs per variant. The shards' own done.yaml give the cost the tasks
// really had (start-up included), which the figures use.
//   build/bench_campaign [--frames N] [--every K] [--shard-s S]
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include <yaml-cpp/yaml.h>

#include "campaign/campaign.hpp"
#include "campaign/task.hpp"

using namespace augrig;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

namespace {

double run_timed(const std::string& cmd, const fs::path& log) {
  const auto t0 = Clock::now();
  const int rc = std::system((cmd + " > " + log.string() + " 2>&1").c_str());
  const double s = std::chrono::duration<double>(Clock::now() - t0).count();
  if (rc != 0) {
    std::fprintf(stderr, "bench_campaign: failed (%s): %s\n", log.c_str(), cmd.c_str());
    std::exit(1);
  }
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 120, every = 3;
  double shard_s = 4;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--frames")
      frames = std::atoi(argv[i + 1]);
    else if (a == "--every")
      every = std::atoi(argv[i + 1]);
    else if (a == "--shard-s")
      shard_s = std::atof(argv[i + 1]);
  }
  const std::string augrig = AUGRIG_BINARY;
  const fs::path dir = fs::temp_directory_path() / "bench_campaign";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::printf("bench_campaign: a recording of %d stereo frames of the demo flight (every %d), 1280x960\n",
              frames, every);
  run_timed(augrig + " run --source 'sim://demo?every=" + std::to_string(every) + "&rate=0' --frames " +
                std::to_string(frames) + " --headless --status-every 0 --record " + (dir / "rec").string(),
            dir / "record.log");
  std::ofstream(dir / "campaign.yaml") << "augrig_campaign: 1\nname: bench\nout: out\nrecordings: [rec]\n"
                                          "variants:\n  - name: stats\n"
                                          "  - {name: eval, boom: 'fixed:30,0,3', evaluate: {every: 5}}\n"
                                          "shards: {seconds: "
                                       << shard_s << "}\nslurm: {cpus_per_task: 2}\n";
  const double plan_s =
      run_timed(augrig + " campaign plan " + (dir / "campaign.yaml").string() + " --measure-frames 20",
                dir / "plan.log");
  const double run_s =
      run_timed(augrig + " campaign resume " + (dir / "out").string() + " --local --jobs 1", dir / "run.log");
  const double merge_s =
      run_timed(augrig + " campaign merge " + (dir / "out").string() + " --no-plot", dir / "merge.log");

  auto m = campaign::load_manifest(dir / "out" / "manifest.yaml");
  if (!m) {
    std::fprintf(stderr, "bench_campaign: %s\n", m.error().message.c_str());
    return 1;
  }
  // What the tasks really took, per variant: wall time and frames from their done.yaml.
  std::map<std::string, std::pair<double, std::size_t>> took;
  std::map<std::string, std::size_t> shards;
  for (const campaign::Task& t : m->tasks) {
    const YAML::Node d = YAML::LoadFile((t.out / "done.yaml").string());
    took[t.variant].first += d["wall_s"].as<double>();
    took[t.variant].second += t.shard.frames;
    ++shards[t.variant];
  }
  std::printf(
      "plan %.1f s (measuring both variants), %zu shard(s) of %.0f s run one at a time in %.1f s, merge %.2f "
      "s\n",
      plan_s, m->tasks.size(), shard_s, run_s, merge_s);
  std::printf("\n%-6s %12s %11s %13s %14s %18s %20s\n", "variant", "ms/frame", "start-up s", "task ms/frame",
              "peak memory MB", "10-min shards/h/core", "1-h flight core-h");
  for (const auto& [v, c] : m->costs) {
    const double task_per_frame = took[v].first / static_cast<double>(took[v].second);
    // A 10-minute shard at 30 fps: 18000 frames; a task holds cpus_per_task cores.
    const double shard_wall_s = c.startup_s + 18000 * c.per_frame_s;
    const double per_core = 3600 / (shard_wall_s * m->slurm.cpus_per_task);
    const double flight_core_h = (6 * c.startup_s + 108000 * c.per_frame_s) * m->slurm.cpus_per_task / 3600;
    std::printf("%-6s %12.1f %11.2f %13.1f %14lld %18.2f %20.2f\n", v.c_str(), c.per_frame_s * 1000,
                c.startup_s, task_per_frame * 1000, static_cast<long long>(c.max_rss_bytes >> 20), per_core,
                flight_core_h);
  }
  std::printf(
      "\n(task ms/frame: the shards' own wall time over their frames, start-up included; the other\n"
      "figures from the plan's measurement; a task holds %d CPU(s); a 1-hour flight is 108000 stereo\n"
      "frames at 30 fps in six 10-minute shards)\n",
      m->slurm.cpus_per_task);
  fs::remove_all(dir);
  return 0;
}
