// bench_look: augrig's augmented boom against a boom that was there (issue 33 §3, docs/LOOK.md).
// The simulator renders each selected stereo frame of a flight twice through the same camera
// (sim/camera_sensor.hpp: PSF, shot and read noise, gain, tone curve, Bayer mosaic): boom-free,
// and with the boom physically in the scene (SyntheticSceneRenderer::render_with_boom). augrig
// augments the boom-free frames, seeing only them (the camera look estimates the noise and the
// ground's light from them; the sun comes from the ephemeris), once per look. Over the boom's
// footprint (mask bit kMaskBoom) it then measures, per look:
//   - the mean and RMS difference from the physical frames, DN;
//   - the noise: robust high-pass sigma inside the boom's interior, augmented over physical
//     (goal 0.9 to 1.1), and the boom's over the background's in the augmented frames;
//   - the edge: 10-90 % width across the boom's silhouette, augmented minus physical (goal <= 0.3 px);
//   - a patch classifier (OpenCV ml: random trees and logistic regression on patch statistics)
//     trained on the even frames to tell augmented from physical boom patches and tested on the
//     odd ones: the AUC (0.5: cannot tell; goal <= 0.60 with the camera look).
//   build/bench_look [--scenario NAME] [--frames N] [--bayer] [--psf PX] [--noise-a A] [--noise DN]
//                    [--gain G] [--true-noise] [--look-cadence S] [--out DIR]
// The looks see the flight as a run's look stage does: a boom-free pair every S seconds of frame
// time (default 0.5, LookConfig's) goes to the noise estimator and the light probe, whether or
// not it is one of the N compared pairs; --look-cadence 0 gives them the compared pairs only.
// --true-noise gives the camera looks the simulator's noise level function (as a rig would
// configure it) instead of estimating it: what the estimate costs. A table of the patch
// statistics (median augmented / physical) says which of them the classifier sees.
// --out writes crops of the left view (plain | camera | physical) as PNG, for docs/LOOK.md.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "core/conventions.hpp"
#include "eval/look_compare.hpp"
#include "pipeline/look_stage.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "render/image_file.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"

using namespace augrig;

namespace {

struct Args {
  std::string scenario = "demo";
  int frames = 24;  // stereo frames compared (half train, half test)
  bool bayer = false;
  bool true_noise = false;  // the camera looks given the simulator's NLF instead of estimating it
  double look_cadence_s = 0.5;  // frame time between the pairs the look stages sample (0: compared only)
  double psf_px = 0.8, noise_a = 0.12, noise_dn = 1.5, gain = 1.0;
  double exposure_ms = 0;  // the simulated camera's: its frames carry it to the camera look
  std::string out;
};

[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr,
               "bench_look: %s\nusage: bench_look [--scenario NAME] [--frames N] [--bayer] [--psf PX] "
               "[--noise-a A] [--noise DN] [--gain G] [--true-noise] [--exposure-ms MS] [--look-cadence S] [--out DIR]\n",
               why);
  std::exit(2);
}

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(("missing value after " + k).c_str());
      return argv[++i];
    };
    if (k == "--scenario")
      a.scenario = value();
    else if (k == "--frames")
      a.frames = std::stoi(value());
    else if (k == "--bayer")
      a.bayer = true;
    else if (k == "--true-noise")
      a.true_noise = true;
    else if (k == "--psf")
      a.psf_px = std::stod(value());
    else if (k == "--noise-a")
      a.noise_a = std::stod(value());
    else if (k == "--noise")
      a.noise_dn = std::stod(value());
    else if (k == "--gain")
      a.gain = std::stod(value());
    else if (k == "--exposure-ms")
      a.exposure_ms = std::stod(value());
    else if (k == "--look-cadence")
      a.look_cadence_s = std::stod(value());
    else if (k == "--out")
      a.out = value();
    else
      usage(("unknown option " + k).c_str());
  }
  if (a.frames < 4) usage("--frames must be >= 4");
  if (!(a.look_cadence_s >= 0)) usage("--look-cadence must be >= 0 s");
  return a;
}

// One selected stereo frame: its two views' truths (left, right).
struct Pair {
  const sim::FrameTruth* left = nullptr;
  const sim::FrameTruth* right = nullptr;
};

// Every pair of the flight with both cameras delivered, in time order.
std::vector<Pair> all_pairs(const std::vector<sim::FrameTruth>& truths) {
  std::vector<Pair> all;
  for (const sim::FrameTruth& t : truths) {
    if (t.camera != 0) continue;
    for (const sim::FrameTruth& r : truths)
      if (r.camera == 1 && r.sequence == t.sequence) all.push_back({&t, &r});
  }
  return all;
}

// One pair the looks are given: `compared` ones are also rendered with the physical boom and
// measured (their index among the compared pairs in `index`).
struct Step {
  Pair pair;
  bool compared = false;
  std::size_t index = 0;
};

// `n` compared pairs spread evenly over the flight, and between them the pairs a run's look
// stage would sample (one every `cadence_s` of frame time; none when 0).
std::vector<Step> pick_steps(const std::vector<Pair>& all, int n, double cadence_s) {
  std::vector<bool> compared(all.size(), false);
  for (int i = 0; i < n && !all.empty(); ++i)
    compared[std::min(all.size() - 1, (all.size() * (2 * static_cast<std::size_t>(i) + 1)) /
                                          (2 * static_cast<std::size_t>(n)))] = true;
  std::vector<Step> out;
  double next_s = -1e300;
  for (std::size_t k = 0; k < all.size(); ++k) {
    const bool sampled = cadence_s > 0 && all[k].left->t_true_s >= next_s;
    if (sampled) next_s = all[k].left->t_true_s + cadence_s;
    if (compared[k] || sampled) out.push_back({all[k], compared[k], 0});
  }
  std::size_t index = 0;
  for (Step& s : out)
    if (s.compared) s.index = index++;
  return out;
}

// Renders a pair's views (boom-free or with the physical boom) through the scenario's camera.
StereoFrame render_pair(sim::FlightSource& src) {
  StereoFrame f;
  for (Frame* out : {&f.left, &f.right}) {
    auto r = src.read(*out, {});
    if (!r || *r != ReadStatus::kFrame) {
      std::fprintf(stderr, "bench_look: the simulator gave no frame: %s\n",
                   r ? "end of stream" : r.error().message.c_str());
      std::exit(1);
    }
  }
  f.t_key_ns = (f.left.t_ns + f.right.t_ns) / 2;
  return f;
}

Image bit_mask(const Image& mask, std::uint8_t bit) {
  Image m(mask.width(), mask.height(), PixelFormat::kMono8);
  for (int y = 0; y < mask.height(); ++y)
    for (int x = 0; x < mask.width(); ++x) m.row(y)[x] = (mask.row(y)[x] & bit) ? 255 : 0;
  return m;
}

// The mask shrunk by `r` pixels (a pixel stays if its (2r+1)^2 neighbourhood is all in).
Image eroded(const Image& m, int r) {
  Image out(m.width(), m.height(), PixelFormat::kMono8);
  for (int y = 0; y < m.height(); ++y)
    for (int x = 0; x < m.width(); ++x) {
      bool in = true;
      for (int dy = -r; dy <= r && in; ++dy)
        for (int dx = -r; dx <= r && in; ++dx) {
          const int xx = x + dx, yy = y + dy;
          in = xx >= 0 && yy >= 0 && xx < m.width() && yy < m.height() && m.row(yy)[xx];
        }
      out.row(y)[x] = in ? 255 : 0;
    }
  return out;
}

// The background near the boom (a band 4..12 px outside it): the noise the boom should match.
Image background_band(const Image& m) {
  Image grown(m.width(), m.height(), PixelFormat::kMono8), near(m.width(), m.height(), PixelFormat::kMono8);
  auto dilate = [&m](Image& out, int r) {
    for (int y = 0; y < m.height(); ++y)
      for (int x = 0; x < m.width(); ++x) {
        bool any = false;
        for (int dy = -r; dy <= r && !any; dy += 2)
          for (int dx = -r; dx <= r && !any; dx += 2) {
            const int xx = std::clamp(x + dx, 0, m.width() - 1), yy = std::clamp(y + dy, 0, m.height() - 1);
            any = m.row(yy)[xx] != 0;
          }
        out.row(y)[x] = any ? 255 : 0;
      }
  };
  dilate(grown, 12), dilate(near, 4);
  for (int y = 0; y < m.height(); ++y)
    for (int x = 0; x < m.width(); ++x) grown.row(y)[x] = grown.row(y)[x] && !near.row(y)[x] ? 255 : 0;
  return grown;
}

struct LookTotals {
  double diff_sum = 0, diff_sq = 0;
  std::size_t pixels = 0;
  // Over the receiver in the boom's shadow (mask bit kMaskShadow): the same differences and noise.
  double shadow_diff_sum = 0, shadow_diff_sq = 0;
  std::size_t shadow_pixels = 0;
  std::vector<double> shadow_noise_ratio;
  std::vector<double> noise_ratio, boom_vs_background, edge_aug, edge_phys;
  std::vector<std::vector<float>> train_a, train_b, test_a, test_b;  // augmented, physical patches
};

double median(std::vector<double> v) {
  std::erase_if(v, [](double x) { return !std::isfinite(x); });
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Patches of 16 px, 8 px apart, whose centre and most of whose pixels are boom.
void add_patches(const Image& aug, const Image& phys, const Image& boom, bool train, LookTotals& t) {
  constexpr int kSize = 16;
  for (int y = 0; y + kSize <= boom.height(); y += 8)
    for (int x = 0; x + kSize <= boom.width(); x += 8) {
      int in = 0;
      for (int dy = 0; dy < kSize; ++dy)
        for (int dx = 0; dx < kSize; ++dx) in += boom.row(y + dy)[x + dx] != 0;
      if (in < kSize * kSize * 3 / 4) continue;
      (train ? t.train_a : t.test_a).push_back(eval::patch_features(aug.view(), x, y, kSize));
      (train ? t.train_b : t.test_b).push_back(eval::patch_features(phys.view(), x, y, kSize));
    }
}

// The receiver in the boom's shadow: the differences over it, and the noise in its interior.
void measure_shadow(const Image& aug, const Image& phys, const Image& mask, LookTotals& t) {
  const Image shadow = bit_mask(mask, kMaskShadow);
  if (auto d = eval::region_difference(aug.view(), phys.view(), shadow.view()); d && d->pixels > 0) {
    t.shadow_diff_sum += d->mean_dn * static_cast<double>(d->pixels);
    t.shadow_diff_sq += d->rms_dn * d->rms_dn * static_cast<double>(d->pixels);
    t.shadow_pixels += d->pixels;
  }
  const Image interior = eroded(shadow, 2);
  const Expected<double> sa = eval::robust_noise_sigma(aug.view(), interior.view()),
                         sp = eval::robust_noise_sigma(phys.view(), interior.view());
  if (sa && sp) t.shadow_noise_ratio.push_back(*sa / *sp);
}

void measure_view(const Image& aug, const Image& phys, const Image& mask, bool train, LookTotals& t) {
  measure_shadow(aug, phys, mask, t);
  const Image boom = bit_mask(mask, kMaskBoom);
  if (auto d = eval::region_difference(aug.view(), phys.view(), boom.view()); d && d->pixels > 0) {
    t.diff_sum += d->mean_dn * static_cast<double>(d->pixels);
    t.diff_sq += d->rms_dn * d->rms_dn * static_cast<double>(d->pixels);
    t.pixels += d->pixels;
  }
  const Image interior = eroded(boom, 2), band = background_band(boom);
  auto sigma = [](const Image& img, const Image& m) {
    const Expected<double> s = eval::robust_noise_sigma(img.view(), m.view());
    return s ? *s : NAN;
  };
  const double s_aug = sigma(aug, interior), s_phys = sigma(phys, interior), s_bg = sigma(aug, band);
  t.noise_ratio.push_back(s_aug / s_phys);
  t.boom_vs_background.push_back(s_aug / s_bg);
  const Expected<eval::EdgeWidth> ea = eval::edge_width(aug.view(), boom.view());
  const Expected<eval::EdgeWidth> ep = eval::edge_width(phys.view(), boom.view());
  if (ea && ep && ea->profiles >= 20 && ep->profiles >= 20) {
    t.edge_aug.push_back(ea->width_10_90_px);
    t.edge_phys.push_back(ep->width_10_90_px);
  }
  add_patches(aug, phys, boom, train, t);
}

// A crop of `img` (RGB8) around `box`, `pad` pixels wider, into `dst` at column `at`.
void paste_crop(const Image& img, const PixelBox& box, int pad, Image& dst, int at) {
  for (int y = 0; y < dst.height(); ++y)
    for (int x = 0; x < dst.width() / 3; ++x) {
      const int sx = std::clamp(box.x0 - pad + x, 0, img.width() - 1),
                sy = std::clamp(box.y0 - pad + y, 0, img.height() - 1);
      const int bpp = bytes_per_pixel(img.format());
      for (int c = 0; c < 3; ++c) dst.row(y)[3 * (at + x) + c] = img.row(sy)[bpp * sx + (bpp == 1 ? 0 : c)];
    }
}

// The looks compared, and a diagnostic: the camera look given the simulator's own light (its
// fixed ambient and sun, sim/synthetic_scene_cpu.cpp) instead of measuring it, which separates
// the light's estimation from the rest of the insertion.
struct Variant {
  Look look;
  bool true_light;
  const char* name;
};
constexpr Variant kVariants[] = {{Look::kPlain, false, "plain"},
                                 {Look::kCamera, false, "camera"},
                                 {Look::kCamera, true, "camera, the simulator's light"}};
constexpr std::size_t kLooks = std::size(kVariants);

// The scenario with the simulated camera the options ask for.
Expected<sim::Scenario> make_scenario(const Args& args) {
  auto scenario = sim::builtin_scenario(args.scenario);
  if (!scenario) return scenario;
  sim::CameraTimingConfig& cam = scenario->sensors.cameras;
  cam.psf_sigma_px = args.psf_px, cam.noise_a = args.noise_a, cam.noise_sigma = args.noise_dn,
  cam.gain = args.gain;
  cam.exposure_ms = args.exposure_ms;  // the physical boom's motion blur (and the frames' exposure)
  if (args.bayer) cam.format = PixelFormat::kBayerRG8;
  return scenario;
}

// The pairs the looks are given, the compared ones among them, and the two renderers: boom-free
// (every pair given) and with the physical boom (the compared pairs only).
struct Sources {
  std::vector<Step> steps;
  std::vector<Pair> pairs;  // the compared ones
  std::unique_ptr<sim::FlightSource> free_src, phys_src;
};

bool make_sources(const Args& args, const sim::Scenario& scenario, const sim::Flight& flight,
                  const std::vector<sim::FrameTruth>& truths, Sources& out) {
  out.steps = pick_steps(all_pairs(truths), args.frames, args.look_cadence_s);
  std::vector<sim::FrameTruth> given, compared;
  for (const Step& s : out.steps) {
    given.push_back(*s.pair.left), given.push_back(*s.pair.right);
    if (!s.compared) continue;
    compared.push_back(*s.pair.left), compared.push_back(*s.pair.right);
    out.pairs.push_back(s.pair);
  }
  auto free_src = sim::FlightSource::create(scenario, flight, given);
  auto phys_src = sim::FlightSource::create(scenario, flight, compared);
  if (!free_src || !phys_src) {
    std::fprintf(stderr, "bench_look: %s\n", (!free_src ? free_src : phys_src).error().message.c_str());
    return false;
  }
  (*phys_src)->set_physical_boom(true);
  out.free_src = std::move(*free_src);
  out.phys_src = std::move(*phys_src);
  return true;
}

// Per look: its own augmenter (CPU rasteriser: the same masks) and look stage.
struct LookRigs {
  std::vector<std::unique_ptr<Augmenter>> augmenters;
  std::vector<std::unique_ptr<pipeline::LookStage>> stages;
};

bool make_looks(const Args& args, const sim::Scenario& scenario, LookRigs& out) {
  for (const Variant& v : kVariants) {
    AugmentOptions o;
    o.rasterizer = Rasterizer::kCpu;
    o.look = v.look;
    auto a = Augmenter::create(scenario.rig, o);
    if (!a) {
      std::fprintf(stderr, "bench_look: %s\n", a.error().message.c_str());
      return false;
    }
    pipeline::LookConfig lc;
    lc.look = v.look;
    lc.cameras.assign(scenario.rig.cameras.size(), CameraLookParams{});
    for (std::size_t c = 0; c < lc.cameras.size(); ++c) {
      lc.cameras[c] = scenario.rig.cameras[c].look;
      if (args.true_noise) {
        // A diagnostic: the simulator's own noise (shot a I + read sigma^2), as a rig would configure it.
        NoiseLevelFunction& n = lc.cameras[c].noise;
        n.channels = 3;  // RGB channels or Bayer site colours
        n.a.fill(args.noise_a), n.b.fill(args.noise_dn * args.noise_dn);
      }
    }
    lc.noise_every_s = args.look_cadence_s;  // 0: every pair given (the compared ones, seconds apart)
    auto st = std::make_unique<pipeline::LookStage>(lc);
    if (auto s = st->configure(**a); !s) return false;
    out.augmenters.push_back(std::move(*a));
    out.stages.push_back(std::move(st));
  }
  return true;
}

// The scene a look augments the pair with: the boom as flown, the sun from the ephemeris, or for
// the diagnostic variant the simulator's own light.
SceneState scene_for(const Pair& p, const sim::Flight& flight, const Variant& v) {
  const Pose T_ecef_tanker = flight.tanker(p.left->t_true_s).T_ecef_body();
  SceneState scene{p.left->boom, p.left->T_body_receiver, true,
                   pipeline::sun_light(p.left->t_gps_ns, T_ecef_tanker),
                   sim::boom_rate(flight, p.left->t_true_s)};  // the rate: as the physical boom moves
  if (v.true_light) {
    const bool sun_up = scene.light.direct.maxCoeff() > 0;
    scene.light.direct = sun_up ? Eigen::Vector3d(0.75, 0.75 * 0.97, 0.75 * 0.92) : Eigen::Vector3d::Zero();
    scene.light.sky = Eigen::Vector3d(0.36, 0.40, 0.46),
    scene.light.ground = Eigen::Vector3d(0.22, 0.22, 0.20);
    scene.light.source = LightSource::kConfigured;
  }
  return scene;
}

// What the run over the pairs gathers.
struct Run {
  std::vector<LookTotals> totals = std::vector<LookTotals>(kLooks);
  std::vector<StereoResult> results = std::vector<StereoResult>(kLooks);
  std::vector<double> probe_ms = std::vector<double>(kLooks, 0.0);  // the slowest light measurement
  Image crops;
  double secs = 0;
};

// One pair through every look: augment, let the look stage measure, and (compared pairs) measure
// the augmented views against the physical ones.
bool augment_step(std::size_t k, const Step& step, const StereoFrame& raw, const StereoFrame& phys,
                  const sim::Flight& flight, const sim::Scenario& scenario, LookRigs& rigs, Run& run) {
  for (std::size_t l = 0; l < kLooks; ++l) {
    SceneState scene = scene_for(step.pair, flight, kVariants[l]);  // the look stage may set its light
    for (const std::string& note : rigs.stages[l]->before_augment(raw, scene, *rigs.augmenters[l]))
      if (k == 0) std::printf("  %s\n", note.c_str());
    if (auto s = rigs.augmenters[l]->augment(raw, scene, run.results[l]); !s) {
      std::fprintf(stderr, "bench_look: %s\n", s.error().message.c_str());
      return false;
    }
    const auto p0 = std::chrono::steady_clock::now();
    rigs.stages[l]->after_augment(raw, scene, run.results[l], scenario.rig);
    run.probe_ms[l] =
        std::max(run.probe_ms[l],
                 std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - p0).count());
    // The first compared pair only warms the look up (its first noise estimate and light measurement).
    if (!step.compared || step.index == 0) continue;
    const bool train = step.index % 2 == 0;
    const StereoResult& r = run.results[l];
    measure_view(r.left.augmented, phys.left.image, r.left.mask, train, run.totals[l]);
    measure_view(r.right.augmented, phys.right.image, r.right.mask, train, run.totals[l]);
  }
  return true;
}

// The crops: plain | camera | physical around the boom's box in the left view.
Image make_crops(const Run& run, const StereoFrame& phys) {
  const PixelBox& b = run.results[1].left.boom_box;
  const int w = std::min(b.x1 - b.x0 + 16, 480), h = std::min(b.y1 - b.y0 + 16, 360);
  Image crops(3 * w, h, PixelFormat::kRGB8);
  paste_crop(run.results[0].left.augmented, b, 8, crops, 0);
  paste_crop(run.results[1].left.augmented, b, 8, crops, w);
  paste_crop(phys.left.image, b, 8, crops, 2 * w);
  return crops;
}

// BENCH_LOOK_TRACE: per compared pair, the left boom's mean difference and the camera look's status.
void trace_pair(std::size_t i, const Run& run, const StereoFrame& phys, const LookRigs& rigs) {
  const std::string st = rigs.stages[1]->status();
  const Image boom = bit_mask(run.results[1].left.mask, kMaskBoom);
  const auto d1 =
      eval::region_difference(run.results[1].left.augmented.cview(), phys.left.image.cview(), boom.view());
  const auto d2 =
      eval::region_difference(run.results[2].left.augmented.cview(), phys.left.image.cview(), boom.view());
  std::fprintf(stderr, "\npair %zu: left boom diff camera %+.2f, sim light %+.2f DN; %s\n", i,
               d1 ? d1->mean_dn : NAN, d2 ? d2->mean_dn : NAN, st.substr(0, st.find("; noise")).c_str());
}

// Every pair given, in time order, through every look.
bool run_looks(const Args& args, const sim::Scenario& scenario, const sim::Flight& flight, Sources& src,
               LookRigs& rigs, Run& run) {
  const auto t0 = std::chrono::steady_clock::now();
  for (std::size_t k = 0; k < src.steps.size(); ++k) {
    const Step& step = src.steps[k];
    const StereoFrame raw = render_pair(*src.free_src);
    const StereoFrame phys = step.compared ? render_pair(*src.phys_src) : StereoFrame{};
    if (!augment_step(k, step, raw, phys, flight, scenario, rigs, run)) return false;
    std::fprintf(stderr, "\r  pair %zu/%zu", k + 1, src.steps.size());
    if (!step.compared) continue;
    // The crops: the frame where the boom's box is largest in the middle of the flight.
    if (!args.out.empty() && step.index == src.pairs.size() / 2) run.crops = make_crops(run, phys);
    if (std::getenv("BENCH_LOOK_TRACE")) trace_pair(step.index, run, phys, rigs);
  }
  std::fprintf(stderr, "\n");
  run.secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return true;
}

// The main table: differences, noise, edge and the classifiers' AUC per look.
void print_look_table(const Run& run) {
  std::printf(
      "\n| look | boom px | mean diff DN | RMS diff DN | noise aug/phys | noise boom/bg | edge 10-90 aug px "
      "| "
      "edge phys px | edge diff px | AUC trees | AUC logistic "
      "|\n|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (std::size_t l = 0; l < kLooks; ++l) {
    const LookTotals& t = run.totals[l];
    const double n = std::max<double>(1.0, static_cast<double>(t.pixels));
    const Expected<eval::ClassifierResult> cr =
        eval::classify_patches(t.train_a, t.train_b, t.test_a, t.test_b);
    eval::ClassifierResult c;
    c.auc_random_trees = c.auc_logistic = NAN;
    if (cr)
      c = *cr;
    else
      std::fprintf(stderr, "bench_look: %s\n", cr.error().message.c_str());
    const double ea = median(t.edge_aug), ep = median(t.edge_phys);
    std::printf("| %s | %zu | %+.2f | %.2f | %.3f | %.3f | %.2f | %.2f | %+.2f | %.3f | %.3f |\n",
                kVariants[l].name, t.pixels, t.diff_sum / n, std::sqrt(t.diff_sq / n), median(t.noise_ratio),
                median(t.boom_vs_background), ea, ep, ea - ep, c.auc_random_trees, c.auc_logistic);
  }
}

// Which statistic tells them apart: per feature, the median over the patches of augmented over
// physical at the same place (1: alike).
void print_feature_table(const Run& run) {
  static constexpr const char* kFeatures[] = {"mean",          "variance",   "gradient",
                                              "laplacian var", "DCT band 0", "DCT band 1",
                                              "DCT band 2",    "DCT band 3", "noise"};
  std::printf("\nPatch statistics, median augmented / physical at the same place:\n\n| look |");
  for (const char* f : kFeatures) std::printf(" %s |", f);
  std::printf("\n|---|");
  for (std::size_t k = 0; k < std::size(kFeatures); ++k) std::printf("---|");
  std::printf("\n");
  for (std::size_t l = 0; l < kLooks; ++l) {
    const LookTotals& t = run.totals[l];
    std::printf("| %s |", kVariants[l].name);
    for (std::size_t k = 0; k < std::size(kFeatures); ++k) {
      std::vector<double> r;
      for (std::size_t i = 0; i < t.test_a.size(); ++i)
        if (k < t.test_a[i].size() && t.test_b[i][k] != 0) r.push_back(t.test_a[i][k] / t.test_b[i][k]);
      std::printf(" %.3f |", median(r));
    }
    std::printf("\n");
  }
}

void print_shadow_table(const Run& run) {
  std::printf(
      "\nThe receiver in the boom's shadow (mask bit 2; the plain look leaves the boom-free frame there):\n\n"
      "| look | shadow px | mean diff DN | RMS diff DN | noise aug/phys |\n|---|---|---|---|---|\n");
  for (std::size_t l = 0; l < kLooks; ++l) {
    const LookTotals& t = run.totals[l];
    const double n = std::max<double>(1.0, static_cast<double>(t.shadow_pixels));
    std::printf("| %s | %zu | %+.2f | %.2f | %.3f |\n", kVariants[l].name, t.shadow_pixels,
                t.shadow_diff_sum / n, std::sqrt(t.shadow_diff_sq / n), median(t.shadow_noise_ratio));
  }
}

// The measuring camera look's status, and the patch counts and time.
void print_status(const Run& run, const LookRigs& rigs) {
  for (std::size_t l = 0; l < kLooks; ++l)
    if (kVariants[l].look == Look::kCamera && !kVariants[l].true_light)
      std::printf("\n%s\n(light measured on the receiver in %.2f ms at most per sampled pair)\n",
                  rigs.stages[l]->status().c_str(), run.probe_ms[l]);
  std::printf("(%zu train / %zu test patches per class; %.1f s)\n", run.totals[0].train_a.size(),
              run.totals[0].test_a.size(), run.secs);
}

bool write_crops(const Args& args, const Image& crops) {
  if (args.out.empty() || crops.width() <= 0) return true;
  std::filesystem::create_directories(args.out);
  const std::string path = args.out + "/look_crops.png";
  if (auto s = write_png_file(path, crops); !s) {
    std::fprintf(stderr, "bench_look: %s\n", s.error().message.c_str());
    return false;
  }
  std::printf("crops (plain | camera | physical boom): %s\n", path.c_str());
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  auto scenario = make_scenario(args);
  if (!scenario) {
    std::fprintf(stderr, "bench_look: %s\n", scenario.error().message.c_str());
    return 1;
  }
  auto flight = sim::Flight::create(*scenario);
  if (!flight) {
    std::fprintf(stderr, "bench_look: %s\n", flight.error().message.c_str());
    return 1;
  }
  const sim::SensorLogs logs = sim::simulate_sensors(*scenario, *flight);
  const std::vector<sim::FrameTruth> truths = sim::frame_truths(*scenario, *flight, logs.cameras);
  Sources src;
  if (!make_sources(args, *scenario, *flight, truths, src)) return 1;
  std::printf(
      "bench_look: scenario %s, %zu stereo frames compared (the looks given %zu), %s, camera: PSF %.2f px, "
      "noise a %.3g, read %.2f DN, gain %.2f\n",
      args.scenario.c_str(), src.pairs.size(), src.steps.size(), args.bayer ? "BayerRG8" : "RGB8",
      args.psf_px, args.noise_a, args.noise_dn, args.gain);

  auto ctx =
      create_gl_context(GlBackend::kEglHeadless);  // the augmenter needs one, even rasterising on the CPU
  if (!ctx) {
    std::fprintf(stderr, "bench_look: %s\n", ctx.error().message.c_str());
    return 1;
  }
  LookRigs rigs;
  if (!make_looks(args, *scenario, rigs)) return 1;
  Run run;
  if (!run_looks(args, *scenario, *flight, src, rigs, run)) return 1;

  print_look_table(run);
  print_feature_table(run);
  print_shadow_table(run);
  print_status(run, rigs);
  return write_crops(args, run.crops) ? 0 : 1;
}
