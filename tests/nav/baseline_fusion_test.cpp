// nav/baseline_fusion: the moving-baseline correction of an INS baseline against a known truth.
// The truth is a smooth relative motion; the INS baseline is the truth plus a metres-large, slowly
// wandering error (what two GPS/INS solutions with single-point GPS give); the measurements are the
// truth plus the receiver's noise at 5 Hz. The corrected baseline at 30 Hz frame times must be
// centimetre-accurate, its sigma honest, and float solutions, outliers and outages handled as the
// header says.
#include "nav/baseline_fusion.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include <gtest/gtest.h>

namespace augrig::nav {
namespace {

constexpr TimestampNs kT0 = 1'400'000'000'000'000'000;

Eigen::Vector3d truth(double t) {
  return {22.0 + 2.0 * std::sin(0.3 * t), 3.0 * std::cos(0.2 * t), 8.0 + std::sin(0.5 * t + 1.0)};
}

// The INS baseline's error: metres, wandering over tens of seconds, with a slow random walk.
struct InsError {
  std::vector<Eigen::Vector3d> walk;  // at 100 Hz
  explicit InsError(std::uint64_t seed, double seconds) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> n(0.0, 1.0);
    Eigen::Vector3d v = Eigen::Vector3d::Zero(), p = Eigen::Vector3d::Zero();
    for (int k = 0; k <= static_cast<int>(seconds * 100) + 1; ++k) {
      v = 0.999 * v + 0.002 * Eigen::Vector3d(n(rng), n(rng), n(rng));  // m/s, correlated over ~10 s
      p += 0.01 * v;
      walk.push_back(p);
    }
  }
  Eigen::Vector3d operator()(double t) const {
    const double k = t * 100;
    const auto i = static_cast<std::size_t>(std::clamp(k, 0.0, static_cast<double>(walk.size() - 2)));
    const double w = k - static_cast<double>(i);
    const Eigen::Vector3d slow(1.5 * std::sin(0.05 * t + 0.3), -1.2 * std::cos(0.07 * t),
                               2.0 * std::sin(0.03 * t));
    return slow + (1 - w) * walk[i] + w * walk[i + 1];
  }
};

// The INS baseline as the solutions give it: with a 10 cm sigma per axis (optimistic: the error
// above is metres, as single-point solutions' filters report).
InsBaselineSample sample(const Eigen::Vector3d& v) {
  InsBaselineSample s;
  s.ned_m = v;
  s.cov_ned_m2 = 0.01 * Eigen::Matrix3d::Identity();
  return s;
}

TimestampNs at_s(double t) {
  return kT0 + static_cast<TimestampNs>(std::llround(t * 1e9));
}
double s_of(TimestampNs t) {
  return static_cast<double>(t - kT0) / 1e9;
}

std::vector<BaselineMeasurement> measure(double seconds, double rate_hz, double sigma_m, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<BaselineMeasurement> out;
  for (int k = 0; k <= static_cast<int>(seconds * rate_hz); ++k) {
    const double t = k / rate_hz;
    BaselineMeasurement m;
    m.t_ns = at_s(t);
    m.ned_m = truth(t) + sigma_m * Eigen::Vector3d(n(rng), n(rng), 1.5 * n(rng));
    m.sigma_ned_m = {sigma_m, sigma_m, 1.5 * sigma_m};
    out.push_back(m);
  }
  return out;
}

struct Scores {
  double rms_m = 0;          // 3D error of the corrected baseline over the frames with a correction
  double within_1sigma = 0;  // per-axis fraction inside the reported sigma
  std::size_t frames = 0, without = 0;
};

Scores score(const BaselineFusion& f, const InsError& ins, double t0, double t1) {
  Scores s;
  double sq = 0;
  std::size_t inside = 0;
  for (double t = t0; t <= t1; t += 1.0 / 30) {
    const auto c = f.at(at_s(t));
    if (!c) {
      ++s.without;
      continue;
    }
    const Eigen::Vector3d err = truth(t) + ins(t) + c->e_ned_m - truth(t);
    sq += err.squaredNorm();
    for (int k = 0; k < 3; ++k) inside += std::abs(err[k]) <= c->sigma_ned_m()[k];
    ++s.frames;
  }
  s.rms_m = s.frames ? std::sqrt(sq / static_cast<double>(s.frames)) : NAN;
  s.within_1sigma = s.frames ? static_cast<double>(inside) / static_cast<double>(3 * s.frames) : 0;
  return s;
}

TEST(BaselineFusion, CentimetreBaselinesCorrectAMetresOffInsBaseline) {
  const double seconds = 120;
  const InsError ins(5, seconds);
  const auto ins_baseline = [&](TimestampNs t) -> std::optional<InsBaselineSample> {
    return sample(truth(s_of(t)) + ins(s_of(t)));
  };
  auto f = BaselineFusion::fuse(measure(seconds, 5.0, 0.01, 9), ins_baseline);
  ASSERT_TRUE(f) << f.error().message;
  // The gate's false alarms are 1 in 1000 (p = 0.001): at most a few of 601.
  EXPECT_EQ(f->report().used + f->report().rejected, f->report().measurements);
  EXPECT_LE(f->report().rejected, 3u);
  // Uncorrected: metres.
  double raw_sq = 0;
  int n = 0;
  for (double t = 0; t <= seconds; t += 1.0 / 30, ++n) raw_sq += ins(t).squaredNorm();
  EXPECT_GT(std::sqrt(raw_sq / n), 1.0);
  const Scores s = score(*f, ins, 0, seconds);
  EXPECT_EQ(s.without, 0u);
  EXPECT_LT(s.rms_m, 0.012) << "the target is 1.5 cm RMS with 1 cm baselines";
  std::printf("corrected RMS %.4f m, %.0f %% within 1 sigma\n", s.rms_m, 100 * s.within_1sigma);
  EXPECT_GT(s.within_1sigma, 0.55) << "the reported sigma is honest";
  EXPECT_LT(s.within_1sigma, 0.95) << "and not wildly pessimistic";
  EXPECT_NE(
      f->report().summary().find("601 measurements: " + std::to_string(f->report().used) + " used (0 float)"),
      std::string::npos)
      << f->report().summary();
  // The model's density was chosen by the innovations' likelihood: a given one is used as given,
  // and one far off (a stiff model that cannot follow the error) does worse.
  // The INS solutions claimed 10 cm for metres: seen, and scaled.
  EXPECT_GE(f->report().sigma_scale, 10.0);
  BaselineFusionOptions believing;
  believing.sigma_scale = 1;
  believing.correlation_s = 0.3;
  auto g = BaselineFusion::fuse(measure(seconds, 5.0, 0.01, 9), ins_baseline, believing);
  ASSERT_TRUE(g) << g.error().message;
  EXPECT_EQ(g->report().sigma_scale, 1.0);
  EXPECT_EQ(g->report().correlation_s, 0.3);
  EXPECT_GT(score(*g, ins, 0, seconds).rms_m, 2 * s.rms_m);
}

// Float solutions carry a bias of decimetres: with their floor the fixed ones outweigh them; left
// out, the fixed ones alone carry the correction through.
TEST(BaselineFusion, FloatSolutionsAreDownWeightedOrLeftOut) {
  const double seconds = 60;
  const InsError ins(6, seconds);
  const auto ins_baseline = [&](TimestampNs t) -> std::optional<InsBaselineSample> {
    return sample(truth(s_of(t)) + ins(s_of(t)));
  };
  std::vector<BaselineMeasurement> ms = measure(seconds, 5.0, 0.01, 10);
  for (BaselineMeasurement& m : ms)
    if (static_cast<std::int64_t>(s_of(m.t_ns) * 5) % 4 == 3) {  // every 4th epoch float, biased 20 cm
      m.carr_soln = 1;
      m.ned_m += Eigen::Vector3d(0.2, -0.15, 0.3);
      m.sigma_ned_m = {0.05, 0.05, 0.08};
    }
  BaselineFusionOptions with, without;
  without.use_float = false;
  auto a = BaselineFusion::fuse(ms, ins_baseline, with);
  auto b = BaselineFusion::fuse(ms, ins_baseline, without);
  ASSERT_TRUE(a && b);
  // Every float epoch is used or, its bias beyond the gate, rejected; a fixed one only by the
  // gate's chance (1 in 1000).
  EXPECT_GE(a->report().used_float + a->report().rejected, 75u);
  EXPECT_LE(a->report().used_float + a->report().rejected, 77u);
  EXPECT_GT(a->report().used_float, 0u);
  EXPECT_EQ(b->report().float_skipped, 75u);
  const double rms_without = score(*b, ins, 0, seconds).rms_m, rms_with = score(*a, ins, 0, seconds).rms_m;
  EXPECT_LT(rms_without, 0.015);
  EXPECT_LT(rms_with, 0.03);
  std::printf("RMS with float %.4f m, without %.4f m\n", rms_with, rms_without);
}

// Wrong baselines (a bad fix) are rejected by the gate; an outage is bridged by the model with
// the sigma it deserves; past the last baseline by more than max_gap_s there is no correction.
TEST(BaselineFusion, OutliersAreGatedAndOutagesBridged) {
  const double seconds = 60;
  const InsError ins(7, seconds);
  const auto ins_baseline = [&](TimestampNs t) -> std::optional<InsBaselineSample> {
    if (s_of(t) > 58) return std::nullopt;  // the INS solutions end before the baselines
    return sample(truth(s_of(t)) + ins(s_of(t)));
  };
  std::vector<BaselineMeasurement> ms = measure(seconds, 5.0, 0.01, 11);
  std::vector<BaselineMeasurement> kept;
  for (BaselineMeasurement m : ms) {
    const double t = s_of(m.t_ns);
    if (t > 20 && t < 35) continue;                                                  // outage: no messages
    if (std::abs(t - 10.0) < 1e-9 || std::abs(t - 40.0) < 1e-9) m.ned_m.x() += 1.0;  // wrong fix
    if (std::abs(t - 45.0) < 1e-9) m.valid = false;
    kept.push_back(m);
  }
  auto f = BaselineFusion::fuse(kept, ins_baseline);
  ASSERT_TRUE(f) << f.error().message;
  EXPECT_GE(f->report().rejected, 2u);  // and the gate's rare false alarms
  EXPECT_LE(f->report().rejected, 4u);
  EXPECT_EQ(f->report().invalid, 1u);
  EXPECT_EQ(f->report().outside_ins, 10u);  // 58.2 .. 60 s
  // Through the outage the correction is carried by the model: its sigma grows towards the middle
  // and falls again, and stays honest.
  const auto edge = f->at(at_s(19.0)), middle = f->at(at_s(27.5));
  ASSERT_TRUE(edge && middle);
  EXPECT_GT(middle->sigma_ned_m().norm(), 3 * edge->sigma_ned_m().norm());
  const Eigen::Vector3d err = ins(27.5) + middle->e_ned_m;
  EXPECT_LT(err.norm(), 3 * middle->sigma_ned_m().norm()) << err.transpose();
  EXPECT_TRUE(f->at(at_s(59.0))) << "within max_gap_s of the last baseline";
  EXPECT_FALSE(f->at(at_s(65.0)));
  EXPECT_LT(score(*f, ins, 0, 20).rms_m, 0.015);
  EXPECT_LT(score(*f, ins, 36, 58).rms_m, 0.015);
}

TEST(BaselineFusion, NothingUsableIsAnError) {
  std::vector<BaselineMeasurement> ms(3);
  for (BaselineMeasurement& m : ms) m.valid = false;
  auto f = BaselineFusion::fuse(
      ms, [](TimestampNs) { return std::optional<InsBaselineSample>(sample(Eigen::Vector3d::Zero())); });
  ASSERT_FALSE(f);
  EXPECT_NE(f.error().message.find("no usable moving-baseline measurement"), std::string::npos)
      << f.error().message;
  EXPECT_NE(f.error().message.find("3 without a valid vector"), std::string::npos) << f.error().message;
}

// What both fusions (this one and the live one) use: a fixed or float vector; not one without
// relPosValid, without a carrier solution or with a non-finite component; floats only if allowed.
TEST(BaselineFusion, WhichMeasurementsAreUsed) {
  BaselineFusionOptions with_float, fixed_only;
  fixed_only.use_float = false;
  BaselineMeasurement m;
  m.ned_m = {10, -2, 3};
  EXPECT_EQ(baseline_use(m, fixed_only), BaselineUse::kUse);
  m.carr_soln = 1;
  EXPECT_EQ(baseline_use(m, with_float), BaselineUse::kUse);
  EXPECT_EQ(baseline_use(m, fixed_only), BaselineUse::kFloatSkipped);
  m.carr_soln = 0;
  EXPECT_EQ(baseline_use(m, with_float), BaselineUse::kInvalid);
  m.carr_soln = 2;
  m.valid = false;
  EXPECT_EQ(baseline_use(m, with_float), BaselineUse::kInvalid);
  m.valid = true;
  m.ned_m.y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(baseline_use(m, with_float), BaselineUse::kInvalid);
  m.ned_m.y() = std::numeric_limits<double>::infinity();
  m.carr_soln = 1;
  EXPECT_EQ(baseline_use(m, fixed_only), BaselineUse::kInvalid);  // invalid before float
}

}  // namespace
}  // namespace augrig::nav
