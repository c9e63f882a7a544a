// bench_camera_clock: what the camera clock estimate (nav/camera_clock.hpp) costs per frame. Renders
// one camera of a 45 deg bank racetrack (the test's flight) frame by frame on the CPU back end, BayerRG8
// with noise, and times only CameraRotationTracker::add_frame() on it (gray conversion, pyramid,
// forward-backward LK, rays, parallax, gated MSAC, detection when tracks run short), then the fit
// (with the jackknife's refits, one per block of time).
// Process CPU time and wall time; on a shared machine trust the CPU figure. Diagnostics (environment):
// BENCH_TRUTH_ROTATIONS=1 also fits exact rotations at the same frames (the fit's own error),
// BENCH_NO_GROUND=1 leaves the parallax in, BENCH_NO_GATE=1 tracks without the nav gate.
//   build/bench_camera_clock [--frames N] [--width W] [--height H] [--every K]
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>

#include "core/clock.hpp"
#include "core/conventions.hpp"
#include "nav/camera_clock.hpp"
#include "nav/geodesy.hpp"
#include "render/rig.hpp"
#include "sim/flight.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "sim/synthetic_scene.hpp"

using namespace augrig;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  int frames = 600, width = 1280, height = 960, every = 1;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--frames")
      frames = std::max(2, std::atoi(argv[i + 1]));
    else if (a == "--width")
      width = std::atoi(argv[i + 1]);
    else if (a == "--height")
      height = std::atoi(argv[i + 1]);
    else if (a == "--every")
      every = std::max(1, std::atoi(argv[i + 1]));
    else {
      std::fprintf(stderr, "usage: bench_camera_clock [--frames N] [--width W] [--height H] [--every K]\n");
      return 2;
    }
  }
  sim::Scenario sc = *sim::builtin_scenario("demo");
  sc.duration_s = frames * every / 30.0 + 1.0;
  sc.tanker.pattern = sim::TankerPattern::kRacetrack;
  sc.tanker.speed_mps = 120;
  sc.tanker.bank_rad = deg_to_rad(45);
  sc.tanker.leg_length_m = 600;
  sc.tanker.roll_in_s = 4;
  for (RigCamera& c : sc.rig.cameras) c.model = CameraModel::pinhole_from_hfov(width, height, deg_to_rad(56));
  auto flight = sim::Flight::create(sc);
  if (!flight) {
    std::fprintf(stderr, "bench_camera_clock: %s\n", flight.error().message.c_str());
    return 1;
  }
  sim::CameraTimingConfig timing = sc.sensors.cameras;
  timing.clock_offset_ns = {20'000'000, 0};
  const auto times = sim::simulate_camera_timing(timing, 1, sc.duration_s, sc.seed, sc.start_gps_ns);
  auto renderer = SyntheticSceneRenderer::create(sc.rig);
  if (!renderer) {
    std::fprintf(stderr, "bench_camera_clock: %s\n", renderer.error().message.c_str());
    return 1;
  }
  const TimestampNs t0_ns = sc.start_gps_ns;
  const sim::Flight& f = *flight;
  nav::AngularRateFunction omega = [&f, t0_ns](TimestampNs t) -> std::optional<Eigen::Vector3d> {
    return f.tanker(ns_to_s(t - t0_ns)).w_eb_body_radps;
  };
  nav::GroundMotionFunction ground = [&](TimestampNs t_ns) -> std::optional<nav::GroundMotion> {
    const double t = ns_to_s(t_ns - t0_ns);
    const SkyState sky = sim::sky_at(sc, f, t);
    const sim::KinematicState k = f.tanker(t);
    const nav::Geodetic g = nav::geodetic_from_ecef(k.p_ecef_m);
    return nav::GroundMotion{sky.R_ned_body, nav::R_ecef_ned(g.lat_rad, g.lon_rad).transpose() * k.v_ecef_mps,
                             sky.altitude_m};
  };
  const Eigen::Matrix3d R_cam_body = sc.rig.cameras[0].T_body_cam.R().transpose();
  nav::CameraRotationTracker tracker(sc.rig.cameras[0].model, R_cam_body, {}, std::getenv("BENCH_NO_GROUND") ? nullptr : ground,
                                     std::getenv("BENCH_NO_GATE") ? nullptr : omega);
  SensorOptions sensor;
  sensor.format = PixelFormat::kBayerRG8;
  sensor.noise_sigma = 2.0;
  Image img;
  double cpu_ms = 0, wall_ms = 0;
  int n = 0;
  for (const sim::CameraFrameTime& ft : times[0]) {
    if (n >= frames) break;
    if (ft.dropped || ft.sequence % static_cast<std::uint64_t>(every) != 0) continue;
    sensor.noise_seed = ft.sequence + 1;
    if (auto st = (*renderer)->render(0, sim::sky_at(sc, f, ft.t_true_s), f.T_tanker_receiver(ft.t_true_s), true,
                                      sensor, img);
        !st) {
      std::fprintf(stderr, "bench_camera_clock: %s\n", st.error().message.c_str());
      return 1;
    }
    const double c0 = process_cpu_ms();
    const auto w0 = Clock::now();
    if (auto st = tracker.add_frame(ft.t_camera_ns, std::as_const(img).view()); !st) {
      std::fprintf(stderr, "bench_camera_clock: %s\n", st.error().message.c_str());
      return 1;
    }
    wall_ms += std::chrono::duration<double, std::milli>(Clock::now() - w0).count();
    cpu_ms += process_cpu_ms() - c0;
    ++n;
  }
  if (std::getenv("BENCH_TRUTH_ROTATIONS")) {  // the fit alone on exact rotations at the same frames
    std::vector<nav::FrameRotation> exact;
    for (const nav::FrameRotation& r : tracker.rotations()) {
      const double ta = ns_to_s(r.t0_camera_ns - t0_ns) - 0.020, tb = ns_to_s(r.t1_camera_ns - t0_ns) - 0.020;
      const Eigen::Matrix3d Ra = sim::sky_at(sc, f, ta).R_ned_body, Rb = sim::sky_at(sc, f, tb).R_ned_body;
      const Eigen::AngleAxisd aa(R_cam_body * Ra.transpose() * Rb * R_cam_body.transpose());
      nav::FrameRotation x = r;
      x.rotvec_cam_rad = aa.angle() * aa.axis();
      exact.push_back(x);
    }
    auto e = nav::fit_camera_clock(exact, R_cam_body, omega);
    if (e) std::printf("  exact rotations: offset %.4f ms, 1-sigma %.4f ms %s\n", e->offset_s * 1e3, e->offset_sigma_s * 1e3, e->reason.c_str());
  }
  const double c0 = process_cpu_ms();
  const auto w0 = Clock::now();
  auto est = nav::fit_camera_clock(tracker.rotations(), R_cam_body, omega);
  const double fit_wall_ms = std::chrono::duration<double, std::milli>(Clock::now() - w0).count();
  const double fit_cpu_ms = process_cpu_ms() - c0;
  std::printf("bench_camera_clock: %dx%d BayerRG8, %d frames (every %d), %zu rotations\n", width, height, n, every,
              tracker.rotations().size());
  std::printf("  tracking: %.2f ms CPU, %.2f ms wall per frame\n", cpu_ms / n, wall_ms / n);
  std::printf("  fit:      %.0f ms CPU, %.0f ms wall in all (the jackknife's refits included)\n", fit_cpu_ms,
              fit_wall_ms);
  if (est && est->observable) {
    std::printf("  offset %.3f ms (truth 20 ms), 1-sigma %.3f ms %s\n", est->offset_s * 1e3,
                est->offset_sigma_s * 1e3, nav::describe_sigma(*est).c_str());
    std::printf("  1-sigmas: the fit's own %.3f ms, jackknife %.3f ms, floor %.3f ms\n",
                est->offset_sigma_fit_s * 1e3, est->offset_sigma_jackknife_s * 1e3,
                est->offset_sigma_floor_s * 1e3);
  } else {
    std::printf("  offset: %s\n", est ? est->reason.c_str() : est.error().message.c_str());
  }
  return 0;
}
