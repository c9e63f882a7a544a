// bench_sim: what the simulated cameras (sim://) cost, the live pipeline's bottleneck on a machine
// without a GPU: SyntheticSceneRenderer::render() of the paper's rig, 1280x960, sky and ground seen
// from a banked tanker, the receiver 22 m aft, without and with lens distortion, as BayerRG8 and
// RGB8 with sensor noise, for each back end (OpenGL, CPU) in the same run. Each iteration renders a
// stereo pair (left then right, the same instant) as FlightSource does; the tanker moves between
// pairs. Process CPU time (all threads: llvmpipe's and the CPU renderer's bands) per view and per
// pair, and wall time per pair. On a shared machine trust the CPU figures and the ratios.
// --write DIR writes each row's last left view as DIR/<back end>_<lens>_<format>.pgm or .ppm.
// --lens none|radtan and --format bayer|rgb run only those rows (to profile one).
//   build/bench_sim [--frames N] [--backend gl|cpu|both] [--threads T] [--lens L] [--format F] [--write DIR]
#include <chrono>
#include <cstdio>
#include <cstring>
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
  int pairs = 20, threads = 2;
  std::string backends = "both", write_dir, lens = "both", format = "both";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--frames")
      pairs = std::max(1, std::atoi(argv[i + 1]));
    else if (a == "--backend")
      backends = argv[i + 1];
    else if (a == "--threads")
      threads = std::atoi(argv[i + 1]);
    else if (a == "--lens")
      lens = argv[i + 1];
    else if (a == "--format")
      format = argv[i + 1];
    else if (a == "--write")
      write_dir = argv[i + 1];
    else {
      std::fprintf(stderr, "usage: bench_sim [--frames N] [--backend gl|cpu|both] [--threads T] [--lens none|radtan|both] "
                   "[--format bayer|rgb|both] [--write DIR]\n");
      return 2;
    }
  }
  std::unique_ptr<GlContext> ctx;
  std::string gl_name = "no OpenGL";
  if (backends != "cpu") {
    auto c = create_gl_context(GlBackend::kEglHeadless);
    if (!c) {
      std::fprintf(stderr, "bench_sim: %s\n", c.error().message.c_str());
      return 1;
    }
    ctx = std::move(*c);
    gl_name = ctx->renderer();
  }
  std::printf("bench_sim: %s, %u hardware threads, CPU back end on %d thread(s), %d stereo pairs per row\n\n",
              gl_name.c_str(), std::thread::hardware_concurrency(), threads, pairs);
  std::printf("| back end | lens | sensor | CPU ms / view | CPU ms / stereo pair | wall ms / stereo pair |\n");
  std::printf("|---|---|---|---:|---:|---:|\n");
  const Pose T_body_receiver = Pose::from(Eigen::Matrix3d::Identity(), {-22.0, 0.5, 9.0});
  for (const SceneBackend backend : {SceneBackend::kOpenGL, SceneBackend::kCpu}) {
    if (backend == SceneBackend::kOpenGL && backends == "cpu") continue;
    if (backend == SceneBackend::kCpu && backends == "gl") continue;
    for (const bool distorted : {false, true}) {
      if (lens != "both" && (lens == "radtan") != distorted) continue;
      // The paper's rig as the live scenarios fly it (no distortion), and with a real lens.
      Rig rig = Rig::paper_default();
      if (distorted)
        for (RigCamera& c : rig.cameras) {
          c.model.distortion = DistortionModel::kRadTan;
          c.model.coeffs = {-0.28, 0.12, 8e-4, -6e-4, -0.02};
        }
      SceneRendererOptions options;
      options.backend = backend;
      options.threads = threads;
      auto renderer = SyntheticSceneRenderer::create(rig, nullptr, options);
      if (!renderer) {
        std::fprintf(stderr, "bench_sim: %s\n", renderer.error().message.c_str());
        return 1;
      }
      for (PixelFormat f : {PixelFormat::kBayerRG8, PixelFormat::kRGB8}) {
        if (format != "both" && (format == "rgb") != (f == PixelFormat::kRGB8)) continue;
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
        for (int i = 0; i < pairs; ++i) {
          // Flying: the tanker moves 5.7 m a pair (170 m/s at 30 fps) and banks a little.
          sky.north_east_m = {5.7 * i, 0.0};
          sky.R_ned_body = rotation_from_ypr(0.0, deg_to_rad(2.0), deg_to_rad(0.2 * i));
          sensor.noise_seed = static_cast<std::uint64_t>(i);
          for (int camera = 0; camera < 2; ++camera)
            if (!(*renderer)->render(camera, sky, T_body_receiver, true, sensor, out)) return 1;
        }
        if (!write_dir.empty()) {
          if (!(*renderer)->render(0, sky, T_body_receiver, true, sensor, out)) return 1;
          const std::string path = write_dir + "/" + (backend == SceneBackend::kCpu ? "cpu_" : "gl_") +
                                   (distorted ? "radtan_" : "none_") + std::string(to_string(f)) +
                                   (f == PixelFormat::kRGB8 ? ".ppm" : ".pgm");
          if (FILE* file = std::fopen(path.c_str(), "wb")) {
            std::fprintf(file, "P%d\n%d %d\n255\n", f == PixelFormat::kRGB8 ? 6 : 5, out.width(), out.height());
            for (int y = 0; y < out.height(); ++y)
              std::fwrite(out.row(y), 1, static_cast<std::size_t>(out.width()) * bytes_per_pixel(f), file);
            std::fclose(file);
          }
        }
        const double wall_ms = 1e3 * std::chrono::duration<double>(Clock::now() - t0).count() / pairs;
        const double cpu_ms = (process_cpu_ms() - c0) / pairs;
        std::printf("| %s | %s | %s %dx%d, noise 1.5 DN | %.1f | %.1f | %.1f |\n",
                    backend == SceneBackend::kCpu ? "CPU" : "OpenGL", distorted ? "radtan" : "none",
                    to_string(f).data(), out.width(), out.height(), cpu_ms / 2, cpu_ms, wall_ms);
      }
    }
  }
  return 0;
}
