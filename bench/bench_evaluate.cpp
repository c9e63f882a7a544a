// bench_evaluate: issue 18 §3's speed figure, stereo frames evaluated per second at 1280x960
// (eval::StereoEvaluator: truth, gray + rectification of the raw and augmented pairs, matching,
// scores), on the built-in demo flight's cameras (BayerRG8, the scenario's noise) from observation
// to contact. Each pair is rendered and augmented first (not timed); then, in one run, every
// variant evaluates the same pairs:
//   default      StereoSGBM 3-way, 64 disparities, block 5, the receiver's region + 128 px context
//                (what `augrig evaluate` does; 3-way runs on OpenCV's threads);
//   sgbm 5-path  OpenCV's MODE_SGBM (single-threaded): raw and augmented pairs on two threads,
//   ... serial   and both on one;
//   context 64   a narrower crop;
//   full frame   whole rectified frames;
//   bm           StereoBM, block 15.
// Then the real command, `augrig evaluate 'sim://demo?every=K'` as a child process, end to end
// (simulation, augmentation, evaluation, outputs), frames/s from its wall time without start-up.
//   build/bench_evaluate [--every K] [--augrig PATH|none]
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <sys/resource.h>
#include <sys/wait.h>

#include "eval/evaluator.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"

using namespace augrig;
using Clock = std::chrono::steady_clock;

namespace {

double cpu_s() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

struct Pair {
  StereoFrame frame;
  StereoResult result;
  double t_s = 0;
};

// The wall time of a shell command, in seconds (-1 when it fails).
double run_timed(const std::string& cmd) {
  const auto t0 = Clock::now();
  const int rc = std::system((cmd + " > /dev/null 2>&1").c_str());
  const double s = std::chrono::duration<double>(Clock::now() - t0).count();
  return rc == 0 ? s : -1.0;
}

}  // namespace

int main(int argc, char** argv) {
  int every = 60;
  std::string augrig_path = AUGRIG_BINARY;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--every" && i + 1 < argc) {
      every = std::atoi(argv[++i]);
    } else if (a == "--augrig" && i + 1 < argc) {
      augrig_path = argv[++i];
    } else {
      std::fprintf(stderr, "usage: bench_evaluate [--every K] [--augrig PATH|none]\n");
      return 2;
    }
  }
  if (every < 1) every = 1;
  auto scenario = sim::builtin_scenario("demo");
  if (!scenario) return std::fprintf(stderr, "%s\n", scenario.error().message.c_str()), 1;
  auto flight = sim::Flight::create(*scenario);
  if (!flight) return std::fprintf(stderr, "%s\n", flight.error().message.c_str()), 1;
  const sim::SensorLogs logs = sim::simulate_sensors(*scenario, *flight);
  auto source = sim::FlightSource::create(*scenario, *flight,
                                          sim::frame_truths(*scenario, *flight, logs.cameras), every);
  if (!source) return std::fprintf(stderr, "%s\n", source.error().message.c_str()), 1;
  auto ctx = create_gl_context(GlBackend::kEglHeadless);
  if (!ctx) return std::fprintf(stderr, "%s\n", ctx.error().message.c_str()), 1;
  AugmentOptions ao;
  ao.augmented_output = AugmentedOutput::kChangedBox;
  auto aug = Augmenter::create(scenario->rig, ao);
  if (!aug) return std::fprintf(stderr, "%s\n", aug.error().message.c_str()), 1;

  // The pairs: both cameras' frames of one exposure, augmented with the truth's scene.
  std::vector<Pair> pairs;
  Frame left;
  std::uint64_t left_sequence = ~0ull;
  double augment_ms = 0;
  std::fprintf(stderr, "rendering and augmenting the demo flight's frames (every %d-th)...\n", every);
  while (true) {
    Frame fr;
    auto st = (*source)->read(fr, std::chrono::nanoseconds(0));
    if (!st || *st != ReadStatus::kFrame) break;
    // A pair: the left and right frames of one exposure (same sequence; the cameras drop a few).
    const sim::FrameTruth truth = (*source)->last_truth();
    if (truth.camera == 0) {
      left = std::move(fr);
      left_sequence = truth.sequence;
      continue;
    }
    if (truth.sequence != left_sequence) continue;
    Pair p;
    p.frame.left = std::move(left);
    p.frame.right = std::move(fr);
    left_sequence = ~0ull;
    p.t_s = truth.t_true_s;
    SceneState scene;
    scene.boom = truth.boom;
    scene.T_body_receiver = truth.T_body_receiver;
    const auto t0 = Clock::now();
    if (!(*aug)->augment(p.frame, scene, p.result)) return std::fprintf(stderr, "augment failed\n"), 1;
    augment_ms += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    pairs.push_back(std::move(p));
  }
  if (pairs.empty()) return std::fprintf(stderr, "no pairs\n"), 1;
  std::printf(
      "bench_evaluate: %zu stereo pairs of the demo flight (every %d-th frame, t %.1f..%.1f s), %dx%d %s; "
      "augmenter %.1f ms a pair (for reference)\n",
      pairs.size(), every, pairs.front().t_s, pairs.back().t_s, pairs[0].frame.left.image.width(),
      pairs[0].frame.left.image.height(), to_string(pairs[0].frame.left.image.format()).data(),
      augment_ms / static_cast<double>(pairs.size()));

  struct Variant {
    const char* name;
    eval::EvaluatorOptions o;
  };
  std::vector<Variant> variants;
  variants.push_back({"default (3-way, 64 disp, crop+128)", {}});
  {
    eval::EvaluatorOptions o;
    o.context_px = 64;
    variants.push_back({"context 64 px", o});
    o = {};
    o.full_frame = true;
    variants.push_back({"full frame", o});
    o = {};
    o.matcher.mode = "sgbm";
    variants.push_back({"SGBM 5-path (MODE_SGBM), pairs on 2 threads", o});
    o.parallel = false;
    variants.push_back({"SGBM 5-path (MODE_SGBM), pairs on 1 thread", o});
    o = {};
    o.matcher.algorithm = "bm";
    o.matcher.block_size = 15;
    variants.push_back({"StereoBM block 15", o});
  }
  std::printf("%-48s %9s %9s %9s %9s %9s %9s %10s\n", "variant", "frames/s", "wall ms", "CPU ms", "prepare",
              "match", "score", "bad3 aug%");
  for (const Variant& v : variants) {
    auto ev = eval::StereoEvaluator::create(scenario->rig, v.o);
    if (!ev) return std::fprintf(stderr, "%s\n", ev.error().message.c_str()), 1;
    (void)(*ev)->evaluate(pairs[0].frame, pairs[0].result);  // warm-up (allocations, OpenCV's threads)
    double prep = 0, match = 0, score = 0;
    eval::PairScore total;
    const double c0 = cpu_s();
    const auto t0 = Clock::now();
    for (const Pair& p : pairs) {
      auto fe = (*ev)->evaluate(p.frame, p.result);
      if (!fe) return std::fprintf(stderr, "%s\n", fe.error().message.c_str()), 1;
      prep += fe->prepare_ms, match += fe->match_ms, score += fe->score_ms;
      total.merge(fe->augmented);
    }
    const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
    const double cpu = cpu_s() - c0;
    const double n = static_cast<double>(pairs.size());
    std::printf("%-48s %9.2f %9.1f %9.1f %9.1f %9.1f %9.1f %10.2f\n", v.name, n / wall, 1e3 * wall / n,
                1e3 * cpu / n, prep / n, match / n, score / n, total.all[0].bad3_pct());
  }

  // The real command, end to end; start-up measured by a one-frame run and taken off.
  if (augrig_path != "none") {
    // BayerRG8, as the GigE cameras deliver it.
    const std::string base =
        augrig_path + " evaluate 'sim://demo?bayer=RG&every=" + std::to_string(every) + "'";
    const double one = run_timed(base + " --frames 1 --out /tmp/augrig_bench_evaluate_1");
    const double all = run_timed(base + " --out /tmp/augrig_bench_evaluate");
    if (one < 0 || all < 0) {
      std::printf("augrig evaluate failed (%s)\n", base.c_str());
      return 1;
    }
    std::printf(
        "augrig evaluate 'sim://demo?bayer=RG&every=%d': %zu frames in %.2f s (one-frame run %.2f s): %.2f "
        "frames/s "
        "after start-up, %.2f including it\n",
        every, pairs.size(), all, one, static_cast<double>(pairs.size() - 1) / std::max(1e-9, all - one),
        static_cast<double>(pairs.size()) / all);
  }
  return 0;
}
