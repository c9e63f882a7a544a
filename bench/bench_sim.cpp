// bench_sim: what the simulated cameras (sim://) cost per frame, the live pipeline's bottleneck on
// a machine without a GPU: SyntheticSceneRenderer::render() of the paper's rig, 1280x960, sky and
// ground seen from a banked tanker, the receiver 22 m aft, without and with lens distortion, as
// BayerRG8 and RGB8 with sensor noise. Wall and process CPU time per frame (llvmpipe renders on its
// own threads).
//   build/bench_sim [--frames N]
#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include "core/clock.hpp"
#include "core/conventions.hpp"
#include "render/gl_context.hpp"
#include "render/rig.hpp"
#include "sim/synthetic_scene.hpp"

using namespace augrig;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  int frames = 40;
  for (int i = 1; i + 1 < argc; i += 2)
    if (std::string(argv[i]) == "--frames") frames = std::max(1, std::atoi(argv[i + 1]));
  auto ctx = create_gl_context(GlBackend::kEglHeadless);
  if (!ctx) {
    std::fprintf(stderr, "bench_sim: %s\n", ctx.error().message.c_str());
    return 1;
  }
  std::printf("bench_sim: %s, %u hardware threads, %d frames per row\n\n", (*ctx)->renderer().c_str(),
              std::thread::hardware_concurrency(), frames);
  std::printf("| lens | sensor | wall ms / frame | CPU ms / frame (all threads) |\n");
  std::printf("|---|---|---:|---:|\n");
  const Pose T_body_receiver = Pose::from(Eigen::Matrix3d::Identity(), {-22.0, 0.5, 9.0});
  for (const bool distorted : {false, true}) {
    // The paper's rig as the live scenarios fly it (no distortion: rendered straight), and with a
    // real lens (rendered in a larger virtual pinhole, then resampled through it).
    Rig rig = Rig::paper_default();
    if (distorted)
      for (RigCamera& c : rig.cameras) {
        c.model.distortion = DistortionModel::kRadTan;
        c.model.coeffs = {-0.28, 0.12, 8e-4, -6e-4, -0.02};
      }
    auto renderer = SyntheticSceneRenderer::create(rig);
    if (!renderer) {
      std::fprintf(stderr, "bench_sim: %s\n", renderer.error().message.c_str());
      return 1;
    }
    for (PixelFormat f : {PixelFormat::kBayerRG8, PixelFormat::kRGB8}) {
      SensorOptions sensor;
      sensor.format = f;
      sensor.noise_sigma = 1.5;
      Image out;
      SkyState sky;
      sky.altitude_m = 7000.0;
      // Warm-up: first frames allocate and compile.
      for (int k = 0; k < 2; ++k)
        if (!(*renderer)->render(k % 2, sky, T_body_receiver, true, sensor, out)) return 1;
      const auto t0 = Clock::now();
      const double c0 = process_cpu_ms();
      for (int i = 0; i < frames; ++i) {
        // Flying: the tanker moves 5.7 m a frame (170 m/s at 30 fps) and banks a little.
        sky.north_east_m = {5.7 * i, 0.0};
        sky.R_ned_body = rotation_from_ypr(0.0, deg_to_rad(2.0), deg_to_rad(0.2 * i));
        sensor.noise_seed = static_cast<std::uint64_t>(i);
        if (!(*renderer)->render(i % 2, sky, T_body_receiver, true, sensor, out)) return 1;
      }
      const double wall_ms = 1e3 * std::chrono::duration<double>(Clock::now() - t0).count() / frames;
      const double cpu_ms = (process_cpu_ms() - c0) / frames;
      std::printf("| %s | %s %dx%d, noise 1.5 DN | %.1f | %.1f |\n", distorted ? "radtan" : "none",
                  to_string(f).data(), out.width(), out.height(), wall_ms, cpu_ms);
    }
  }
  return 0;
}
