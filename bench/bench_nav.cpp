// bench_nav: cost of the GPS/INS fusion (nav/ins.hpp) for a 10-minute two-aircraft refuelling
// flight with a 200 Hz IMU and 10 Hz RTK fixes with HDT, and the cost of a state query at a camera
// frame's time. Prints the figures for docs/NAV_FUSION.md.
//   build/bench_nav [--minutes M] [--repeat N] [--imu-clock]
// --imu-clock: with the two IMU clock states (nav::InsConfig::imu_clock), the IMUs stamped on GPS time.
// The flight: a tanker at 150 m/s weaving with 25 deg bank turns and a receiver 25 m behind and 9 m
// below it, both with exact IMU increments plus tactical-grade noise and biases, and fixes with
// 2 cm white noise. Generating the data is not timed.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Geometry>

#include "nav/ins.hpp"

using namespace augrig;
using namespace augrig::nav;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

constexpr TimestampNs kT0 = 1'400'000'000'000'000'000;
constexpr double kG = 9.80665;

struct Truth {
  Vector3d p, v, a;
  Matrix3d R_eb;
};

// Weave at constant height in the tangent plane of the origin (see tests/nav/ins_test.cpp).
struct Flight {
  Geodetic origin{deg_to_rad(47.4), deg_to_rad(8.5), 3000.0};
  double speed_mps = 150.0, heading0_rad = deg_to_rad(30.0), bank_rad = deg_to_rad(25.0);
  double weave_period_s = 90.0, climb_amp_m = 15.0, climb_period_s = 40.0, aoa_rad = deg_to_rad(2.5);
  Vector3d offset_m = Vector3d::Zero();  // along, cross, down

  Truth at(double t) const {
    const Vector3d p0 = ecef_from_geodetic(origin);
    const Matrix3d R0 = R_ecef_ned(origin.lat_rad, origin.lon_rad);
    const double W = 2 * kPi / weave_period_s, A = kG * std::tan(bank_rad) / (W * W);
    const double W2 = 2 * kPi / climb_period_s;
    const double u = speed_mps * t + offset_m.x(), du = speed_mps;
    const double w = A * std::sin(W * t) + offset_m.y(), dw = A * W * std::cos(W * t),
                 ddw = -A * W * W * std::sin(W * t);
    const double d = -climb_amp_m * std::sin(W2 * t) + offset_m.z(),
                 dd = -climb_amp_m * W2 * std::cos(W2 * t), ddd = climb_amp_m * W2 * W2 * std::sin(W2 * t);
    const double c = std::cos(heading0_rad), s = std::sin(heading0_rad);
    const double N = c * u - s * w, E = s * u + c * w, dN = c * du - s * dw, dE = s * du + c * dw;
    const double ddN = -s * ddw, ddE = c * ddw;
    constexpr double Re = 6.371e6;
    const double D = d + (N * N + E * E) / (2 * Re), dD = dd + (N * dN + E * dE) / Re;
    const double ddD = ddd + (dN * dN + dE * dE + N * ddN + E * ddE) / Re;
    Truth tr;
    tr.p = p0 + R0 * Vector3d(N, E, D);
    tr.v = R0 * Vector3d(dN, dE, dD);
    tr.a = R0 * Vector3d(ddN, ddE, ddD);
    const Geodetic g = geodetic_from_ecef(tr.p);
    const Matrix3d R_en = R_ecef_ned(g.lat_rad, g.lon_rad);
    const Vector3d vl = R_en.transpose() * tr.v, al = R_en.transpose() * tr.a;
    const double vh = std::hypot(vl.x(), vl.y());
    const double rate = (vl.x() * al.y() - vl.y() * al.x()) / (vh * vh);
    tr.R_eb = R_en * rotation_from_ypr(std::atan2(vl.y(), vl.x()), std::atan2(-vl.z(), vh) + aoa_rad,
                                       std::atan(rate * vh / kG));
    return tr;
  }
};

struct Log {
  std::vector<ImuSample> imu;
  std::vector<GpsFix> fixes;
};

Log make_log(const Flight& f, double duration_s, const Vector3d& lever, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  auto n3 = [&] { return Vector3d(n01(rng), n01(rng), n01(rng)); };
  const Vector3d gyro_bias = Vector3d(2.0, -1.5, 3.0) * deg_to_rad(1.0) / 3600.0;
  const Vector3d accel_bias = 9.80665e-3 * Vector3d(1.0, -0.8, 1.5);
  const double arw = deg_to_rad(0.15) / 60.0, vrw = 0.05 / 60.0;
  Log log;
  const TimestampNs dt_ns = 5'000'000;
  const double dt = 0.005;
  const int n = static_cast<int>(duration_s * 200.0);
  log.imu.resize(n);
  auto R_ib = [&](double t) {
    return Matrix3d(Eigen::AngleAxisd(kEarthRate_radps * t, Vector3d::UnitZ()).toRotationMatrix() *
                    f.at(t).R_eb);
  };
  static const double gx[3] = {-0.7745966692414834, 0.0, 0.7745966692414834};
  static const double gw[3] = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};
  Matrix3d R_prev = R_ib(ns_to_s(1'300'000));
  for (int k = 0; k < n; ++k) {
    ImuSample& s = log.imu[k];
    s.t_ns = kT0 + 1'300'000 + (k + 1) * dt_ns;
    s.dt_s = dt;
    const double t1 = ns_to_s(s.t_ns - kT0), t0 = t1 - dt;
    const Matrix3d R_next = R_ib(t1);
    const Eigen::AngleAxisd aa(R_prev.transpose() * R_next);
    R_prev = R_next;
    s.dtheta_rad = aa.angle() * aa.axis() + gyro_bias * dt + arw * std::sqrt(dt) * n3();
    Vector3d dv = Vector3d::Zero();
    for (int i = 0; i < 3; ++i) {
      const double t = t0 + 0.5 * dt * (1 + gx[i]);
      const Truth tr = f.at(t);
      dv += gw[i] * (tr.R_eb.transpose() * (tr.a + 2.0 * earth_rate_ecef().cross(tr.v) - gravity_ecef(tr.p)));
    }
    s.dv_mps = 0.5 * dt * dv + accel_bias * dt + vrw * std::sqrt(dt) * n3();
  }
  for (TimestampNs t = kT0; t <= kT0 + s_to_ns(duration_s); t += 100'000'000) {
    const Truth tr = f.at(ns_to_s(t - kT0));
    const Vector3d p_ant = tr.p + tr.R_eb * lever;
    const Geodetic g = geodetic_from_ecef(p_ant);
    const Matrix3d R_en = R_ecef_ned(g.lat_rad, g.lon_rad);
    GpsFix fx;
    fx.t_ns = t;
    fx.antenna = geodetic_from_ecef(p_ant + R_en * (0.02 * n3()));
    fx.quality = FixQuality::kRtkFixed;
    fx.sigma_ned_m = Vector3d::Constant(0.02);
    const Matrix3d R_nb = R_en.transpose() * tr.R_eb;
    fx.heading_rad = std::atan2(R_nb(1, 0), R_nb(0, 0)) + deg_to_rad(0.1) * n01(rng);
    log.fixes.push_back(fx);
  }
  return log;
}

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown CPU";
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  double minutes = 10;
  int repeat = 5;
  bool imu_clock = false;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--imu-clock")) imu_clock = true;
    if (i + 1 >= argc) continue;
    if (!std::strcmp(argv[i], "--minutes")) minutes = std::atof(argv[i + 1]);
    if (!std::strcmp(argv[i], "--repeat")) repeat = std::atoi(argv[i + 1]);
  }
  const double duration = minutes * 60.0;
  std::printf("bench_nav: %s, %u hardware threads\n", cpu_model().c_str(),
              std::thread::hardware_concurrency());
  std::printf("flight: %.0f s, two aircraft, 200 Hz IMU, 10 Hz fixes with HDT\n", duration);

  const Vector3d lever(1.2, -0.4, -1.6);
  Flight tanker, receiver;
  receiver.offset_m = Vector3d(-25.0, 0.0, 9.0);
  receiver.aoa_rad = deg_to_rad(3.5);
  const double tg = now_s();
  const Log logs[2] = {make_log(tanker, duration, lever, 1), make_log(receiver, duration, lever, 2)};
  std::printf("data generated in %.1f s: %zu IMU samples and %zu fixes per aircraft\n", now_s() - tg,
              logs[0].imu.size(), logs[0].fixes.size());

  InsConfig cfg;
  cfg.lever_arm_body_m = lever;
  cfg.imu_clock.estimate = imu_clock;
  std::printf("IMU clock states: %s\n", imu_clock ? "estimated (17 states)" : "off (15 states)");

  // Fusion, both aircraft one after the other, forward only and forward + RTS.
  std::vector<double> t_fwd, t_both, t_par, fwd_part, rts_part;
  std::vector<NavTrajectory> trajs;
  for (int r = 0; r < repeat; ++r) {
    double t0 = now_s();
    for (const Log& l : logs) {
      auto res = fuse(l.imu, l.fixes, cfg, false);
      if (!res) {
        std::fprintf(stderr, "%s\n", res.error().message.c_str());
        return 1;
      }
    }
    t_fwd.push_back(now_s() - t0);
    trajs.clear();
    t0 = now_s();
    for (const Log& l : logs) {
      auto res = fuse(l.imu, l.fixes, cfg, true);
      fwd_part.push_back(res->report().forward_s);
      rts_part.push_back(res->report().smoother_s);
      trajs.push_back(std::move(res).value());
    }
    t_both.push_back(now_s() - t0);
    // One aircraft per thread.
    t0 = now_s();
    std::thread th([&] { (void)fuse(logs[1].imu, logs[1].fixes, cfg, true); });
    (void)fuse(logs[0].imu, logs[0].fixes, cfg, true);
    th.join();
    t_par.push_back(now_s() - t0);
  }
  const double fwd = median(t_fwd), both = median(t_both), par = median(t_par);
  std::printf("\n| fusion of both aircraft (%.0f s of data)      | wall time | x real time |\n", duration);
  std::printf("|-----------------------------------------------|----------:|------------:|\n");
  std::printf("| forward filter only, one thread               | %7.3f s | %9.0f x |\n", fwd, duration / fwd);
  std::printf("| forward + RTS smoother, one thread            | %7.3f s | %9.0f x |\n", both,
              duration / both);
  std::printf("| forward + RTS smoother, one aircraft/thread   | %7.3f s | %9.0f x |\n", par, duration / par);
  std::printf("per aircraft: forward %.3f s, smoother %.3f s (medians of %d runs); %zu epochs\n",
              median(fwd_part), median(rts_part), repeat, trajs[0].epoch_count());

  // Queries at 30 Hz camera frame times (mid-exposure, between epochs).
  std::mt19937_64 rng(3);
  std::vector<TimestampNs> times;
  for (TimestampNs t = trajs[0].begin_ns() + 7'654'321; t < trajs[0].end_ns(); t += 33'333'333)
    times.push_back(t);
  std::shuffle(times.begin(), times.end(), rng);
  std::vector<double> per_query;
  double sink = 0;
  for (int r = 0; r < repeat; ++r) {
    const double t0 = now_s();
    for (TimestampNs t : times) {
      const auto s = trajs[0].at(t);
      sink += s->p_ecef_m.x();
    }
    per_query.push_back((now_s() - t0) / static_cast<double>(times.size()));
  }
  std::printf("query at(t) at %zu frame times: %.2f us per frame (median of %d passes)%s\n", times.size(),
              1e6 * median(per_query), repeat, sink == 0 ? " " : "");

  // Accuracy of this run against the truth, at the frame times.
  for (int a = 0; a < 2; ++a) {
    const Flight& f = a ? receiver : tanker;
    double sum2 = 0, worst_att = 0;
    for (TimestampNs t : times) {
      const auto s = trajs[a].at(t);
      const Truth tr = f.at(ns_to_s(t - kT0));
      sum2 += (s->p_ecef_m - tr.p).squaredNorm();
      worst_att = std::max(
          worst_att, Eigen::AngleAxisd(s->q_ecef_body.toRotationMatrix() * tr.R_eb.transpose()).angle());
    }
    const FusionReport& rep = trajs[a].report();
    std::printf(
        "%s: position RMS %.1f mm, attitude max %.4f deg (smoothed, at the frame times); fixes used %zu, "
        "rejected %zu, outages %zu\n",
        a ? "receiver" : "tanker  ", 1e3 * std::sqrt(sum2 / times.size()), rad_to_deg(worst_att),
        rep.fixes_used, rep.fixes_rejected, rep.outages);
  }
  return 0;
}
