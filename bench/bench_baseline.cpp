// bench_baseline: what the moving baseline costs `augrig nav`: reading the rover's UBX log, the
// fusion against both solutions (the likelihood grid over the model's scale and correlation time,
// then the filter and smoother) and the correction per frame pose, on the built-in contact-10min
// flight with a 5 Hz moving baseline (or --minutes of it). Prints a table for docs/PERFORMANCE.md.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "pipeline/baseline_nav.hpp"
#include "pipeline/flight_nav.hpp"
#include "sim/moving_baseline.hpp"
#include "sim/scenario.hpp"

namespace {

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string cpu_model() {
  std::ifstream f("/proc/cpuinfo");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown CPU";
}

}  // namespace

int main(int argc, char** argv) {
  using namespace augrig;
  double minutes = 10;
  int repeat = 3;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--minutes")) minutes = std::atof(argv[i + 1]);
    if (!std::strcmp(argv[i], "--repeat")) repeat = std::max(1, std::atoi(argv[i + 1]));
  }
  auto sc = sim::builtin_scenario("contact-10min");
  if (!sc) return std::fprintf(stderr, "%s\n", sc.error().message.c_str()), 1;
  sc->duration_s = std::min(sc->duration_s, 60 * minutes);
  sc->sensors.moving_baseline = sim::MovingBaselineConfig{};
  std::printf("bench_baseline: %s\nflight: contact-10min, %.0f s, moving baseline at %.0f Hz\n", cpu_model().c_str(),
              sc->duration_s, sc->sensors.moving_baseline->rate_hz);
  const sim::Flight flight = *sim::Flight::create(*sc);
  const sim::SensorLogs logs = sim::simulate_sensors(*sc, flight);
  const std::string path = "/tmp/bench_baseline_rover.ubx";
  if (!sim::write_relposned_ubx(path, sim::simulate_moving_baseline(*sc, flight))) return 1;
  const nav::InsConfig tk_cfg = pipeline::ins_config_for(sc->sensors.tanker);
  const nav::InsConfig rx_cfg = pipeline::ins_config_for(sc->sensors.receiver);
  auto tk = nav::fuse(logs.tanker_imu, logs.tanker_gps, tk_cfg);
  auto rx = nav::fuse(logs.receiver_imu, logs.receiver_gps, rx_cfg);
  if (!tk || !rx) return std::fprintf(stderr, "fusion failed\n"), 1;

  std::vector<double> read_s, fuse_s, correct_us;
  std::string summary;
  for (int r = 0; r < repeat; ++r) {
    double t = now_s();
    auto rover = pipeline::load_rover_log(path, logs.receiver_gps.front().t_ns);
    read_s.push_back(now_s() - t);
    if (!rover) return std::fprintf(stderr, "%s\n", rover.error().message.c_str()), 1;
    t = now_s();
    auto b = pipeline::BaselineNav::fuse(rover->measurements, *tk, *rx, tk_cfg.lever_arm_body_m,
                                         rx_cfg.lever_arm_body_m);
    fuse_s.push_back(now_s() - t);
    if (!b) return std::fprintf(stderr, "%s\n", b.error().message.c_str()), 1;
    summary = b->report().summary();
    // The correction at 30 Hz frame times (the states' own query excluded).
    std::vector<std::pair<nav::NavState, nav::NavState>> states;
    for (double s = 1; s < sc->duration_s - 1; s += 1.0 / 30) {
      const TimestampNs t_ns = sc->start_gps_ns + static_cast<TimestampNs>(s * 1e9);
      auto a = tk->at(t_ns);
      auto c = rx->at(t_ns);
      if (a && c) states.emplace_back(*a, *c);
    }
    t = now_s();
    std::size_t corrected = 0;
    for (auto& [a, c] : states) {
      const TimestampNs t_ns = a.t_ns;
      corrected += b->correct(t_ns, a, c) ? 1 : 0;
    }
    correct_us.push_back(1e6 * (now_s() - t) / static_cast<double>(states.size()));
    if (r == 0) std::printf("%zu of %zu frame times corrected\n", corrected, states.size());
  }
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::printf("%s\n\n| moving baseline (%.0f s of data) | median of %d |\n|---|---:|\n", summary.c_str(),
              sc->duration_s, repeat);
  std::printf("| read the rover's UBX log | %.1f ms |\n", 1e3 * median(read_s));
  std::printf("| fuse: likelihood grid (70 models) + filter + smoother | %.0f ms |\n", 1e3 * median(fuse_s));
  std::printf("| correct one frame's relative pose | %.2f us |\n", median(correct_us));
  return 0;
}
