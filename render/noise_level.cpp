#include "render/noise_level.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <tuple>
#include <utility>
#include <vector>

namespace augrig {
namespace {

constexpr double kQuantisationVar = 1.0 / 12.0;  // variance of rounding a dithered value
constexpr double kTailZ = 3.09;                  // one-sided 99.9 % normal quantile
constexpr double kTailZt = 2.326;                // one-sided 99 % normal quantile
constexpr double kSeedQuantile = 0.02;           // seed a bin at its 2 % least textured blocks
constexpr double kSeedZ = -2.054;                // normal quantile of kSeedQuantile
constexpr int kMaxIterations = 12;
constexpr double kDropZ = 3;        // a bin this many standard errors above the line is textured
constexpr double kFitFloor = 0.01;  // relative model error added to a bin's sampling error

using BlockStat = NoiseLevelEstimator::BlockStat;

std::string num(double x) {
  char s[32];
  std::snprintf(s, sizeof s, "%.4g", x);
  return s;
}

const char* channel_name(int channels, int ch) {
  static const char* const kNames[3] = {"R", "G", "B"};
  return channels == 1 ? "Mono" : kNames[ch];
}

// Quantile / mean of chi^2_k / k at normal quantile z (Wilson & Hilferty 1931).
double chi2_ratio(double k, double z) {
  const double c = 2.0 / (9.0 * k);
  return std::pow(std::max(1.0 - c + z * std::sqrt(c), 0.0), 3.0);
}

// How block statistics of pure white noise are distributed, for a block side B.
struct BlockModel {
  double median_v, median_t;  // median / mean
  double tail_v, tail_t;      // 99.9 % quantile / mean
  double seed_t;              // kSeedQuantile quantile / mean of t
  double se_v;                // standard error of a median of v / mean, times sqrt(blocks)
};

// The 1D [1 -2 1] mask at a block row's interior positions: G = A1'A1 (B x B) and g = A1'c1, the
// mask's response to an alternating row (c1 = +-1 at the m = B - 2 positions).
struct RowMask {
  std::vector<double> G, g;
};
RowMask row_mask(int B) {
  const std::size_t n = static_cast<std::size_t>(B);
  RowMask r{std::vector<double>(n * n, 0.0), std::vector<double>(n, 0.0)};
  constexpr double kTap[3] = {1, -2, 1};
  for (int c = 0; c < B - 2; ++c)
    for (int i = 0; i < 3; ++i) {
      r.g[static_cast<std::size_t>(c + i)] += (c % 2 ? -1 : 1) * kTap[i];
      for (int j = 0; j < 3; ++j) r.G[static_cast<std::size_t>((c + i) * B + c + j)] += kTap[i] * kTap[j];
    }
  return r;
}

// tr Q of the quincunx's v = x'Qx / tr Q, Q = M - hh'/m^2 (h = g (x) g: the checkerboard's
// direction taken out of the residuals).
double checker_trace(int B) {
  const RowMask r = row_mask(B);
  double g2 = 0;
  for (double x : r.g) g2 += x * x;
  const double m = B - 2.0;
  return 36 * m * m - g2 * g2 / (m * m);
}

// t is chi^2_{B^2-3} / (B^2-3) exactly (B^2-4 with the checkerboard out). v = x'Qx / tr Q (Q = M = A'A, A the
// mask at the interior positions; the quincunx's Q = M - hh'/m^2) is a sum of chi^2_1 with unequal weights: a
// Satterthwaite chi^2 (11.4 dof at B = 8) puts its median 1.4 % high, so match its first three cumulants
// 2^(r-1) (r-1)! tr(Q^r) with a shifted, scaled chi^2 instead (Pearson 1959): median within 0.5 %, 99.9 %
// quantile within 0.1 %. M = G (x) G, so tr(M^r) = tr(G^r)^2, and the rank-one term needs g'G^k g only.
BlockModel block_model(int B, bool checker) {
  const RowMask rm = row_mask(B);
  const std::vector<double>& G = rm.G;
  const std::size_t n = static_cast<std::size_t>(B);
  std::vector<double> G2(n * n, 0.0), Gg(n, 0.0);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      Gg[i] += G[i * n + j] * rm.g[j];
      for (std::size_t k = 0; k < n; ++k) G2[i * n + j] += G[i * n + k] * G[k * n + j];
    }
  double tr1 = 0, tr2 = 0, tr3 = 0, a0 = 0, a1 = 0, a2 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    tr1 += G[i * n + i];
    for (std::size_t j = 0; j < n; ++j) tr2 += G2[i * n + j] * (i == j), tr3 += G2[i * n + j] * G[j * n + i];
    a0 += rm.g[i] * rm.g[i], a1 += rm.g[i] * Gg[i], a2 += Gg[i] * Gg[i];
  }
  double t1 = tr1 * tr1, t2 = tr2 * tr2, t3 = tr3 * tr3;  // tr(Q^r)
  if (checker) {
    const double e = 1.0 / ((B - 2.0) * (B - 2.0)), h2 = a0 * a0, hk = a1 * a1, hk2 = a2 * a2;
    t1 -= e * h2;
    t2 += -2 * e * hk + e * e * h2 * h2;
    t3 += -3 * e * hk2 + 3 * e * e * hk * h2 - e * e * e * h2 * h2 * h2;
  }
  const double k1 = t1, k2 = 2 * t2, k3 = 8 * t3;
  const double skew = k3 / std::pow(k2, 1.5), h = 8 / (skew * skew);  // chi^2_h has skewness sqrt(8/h)
  auto v_ratio = [&](double z) { return 1 + std::sqrt(k2 / (2 * h)) * h * (chi2_ratio(h, z) - 1) / k1; };
  const double dof_t = B * B - (checker ? 4.0 : 3.0);  // residual of a plane (and the checkerboard)
  return {v_ratio(0),
          chi2_ratio(dof_t, 0),
          v_ratio(kTailZ),
          chi2_ratio(dof_t, kTailZt),
          chi2_ratio(dof_t, kSeedZ),
          1.2533 * std::sqrt(k2) / k1};
}

Status check_options(const NoiseEstimateOptions& o, const char* fn) {
  if (o.block_px < 6 || o.block_px > 64) return make_error(fn, ": block_px ", o.block_px, " is not in 6..64");
  if (o.bins < 1 || o.bins > 256) return make_error(fn, ": bins ", o.bins, " is not in 1..256");
  if (o.min_blocks_per_bin < 1 || o.max_blocks_per_bin < o.min_blocks_per_bin)
    return make_error(fn, ": need 1 <= min_blocks_per_bin (", o.min_blocks_per_bin,
                      ") <= max_blocks_per_bin (", o.max_blocks_per_bin, ")");
  if (!(o.clip_low_dn < o.clip_high_dn))
    return make_error(fn, ": clip_low_dn ", num(o.clip_low_dn), " is not below clip_high_dn ",
                      num(o.clip_high_dn));
  if (!(o.clip_margin_sigma >= 0) || !(o.max_band_ratio > 1))
    return make_error(fn, ": need clip_margin_sigma >= 0 and max_band_ratio > 1");
  return {};
}

float median_of(std::vector<float>& v) {
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// The measured (8-bit) variance line var(L) = a L + b + q of a previous pass.
struct Line {
  double a = 0, b = 0;
  double at(double level) const { return std::max(a * level + b, 1e-6); }
};

struct BinFit {
  bool usable = false;
  bool not_white = false;       // enough blocks, but full-band and high-pass variance disagree
  double level = 0;             // where var_v applies
  double var_v = 0, var_t = 0;  // high-pass and full-band variance (means) at `level`
  int kept_samples = 0;
  double kept = 0, texture = 0, clipped = 0;  // blocks, scaled from the reservoir to all blocks
  double sparse = 0;                          // flat blocks of a bin with too few of them
};

struct BinData {
  const std::vector<BlockStat>* samples;
  std::uint64_t blocks;
};

// One bin's noise-only population: the fixed-point iteration of the header's method. `prev`
// (usable) starts it from a previous pass; `line` (non-null) scales each block's thresholds
// by the line at its own level relative to prev.level.
BinFit fit_bin(const BinData& bin, const BlockModel& bm, const NoiseEstimateOptions& o, const BinFit& prev,
               const Line* line) {
  const std::vector<BlockStat>& samples = *bin.samples;
  BinFit f;
  if (samples.empty()) return f;
  std::vector<float> vs, ts;
  vs.reserve(samples.size()), ts.reserve(samples.size());
  double ref_v = prev.var_v, ref_t = prev.var_t;
  if (!prev.usable) {
    for (const BlockStat& s : samples) ts.push_back(s.t);
    auto q = ts.begin() + static_cast<std::ptrdiff_t>(kSeedQuantile * static_cast<double>(ts.size() - 1));
    std::nth_element(ts.begin(), q, ts.end());
    ref_t = *q / bm.seed_t;
    ref_v = ref_t;  // white noise: both read the same variance
  }
  const double ref_level = prev.usable ? prev.level : 0;
  const double line_ref = line ? line->at(ref_level) : 1;
  double texture = 0, clipped = 0, level_sum = 0;
  for (int it = 0; it < kMaxIterations; ++it) {
    vs.clear(), ts.clear();
    texture = clipped = level_sum = 0;
    for (const BlockStat& s : samples) {
      const double sc = line ? line->at(s.level) / line_ref : 1.0;
      const double sigma = std::sqrt(ref_v * sc);
      if (s.level - o.clip_margin_sigma * sigma <= o.clip_low_dn ||
          s.level + o.clip_margin_sigma * sigma >= o.clip_high_dn) {
        ++clipped;
      } else if (s.t > bm.tail_t * ref_t * sc || s.v > bm.tail_v * ref_v * sc) {
        ++texture;
      } else {
        vs.push_back(static_cast<float>(s.v / sc)), ts.push_back(static_cast<float>(s.t / sc));
        level_sum += s.level;
      }
    }
    if (vs.empty()) break;
    const double new_v = median_of(vs) / bm.median_v, new_t = median_of(ts) / bm.median_t;
    const bool settled = std::abs(new_v - ref_v) <= 1e-4 * ref_v && std::abs(new_t - ref_t) <= 1e-4 * ref_t;
    ref_v = new_v, ref_t = new_t;
    if (settled) break;
  }
  const double scale = static_cast<double>(bin.blocks) / static_cast<double>(samples.size());
  f.kept_samples = static_cast<int>(vs.size());
  f.kept = scale * static_cast<double>(vs.size());
  f.texture = scale * texture;
  f.clipped = scale * clipped;
  if (vs.empty()) return f;
  // With a line the values were brought to ref_level; without, the median is at the mean level.
  f.level = line ? ref_level : level_sum / static_cast<double>(vs.size());
  f.var_v = ref_v, f.var_t = ref_t;
  const bool noise_free = ref_v < 1e-9 && ref_t < 1e-9;  // a noiseless flat image: nothing to test
  const double ratio = noise_free ? 1.0 : ref_t / std::max(ref_v, 1e-12);
  f.not_white =
      f.kept_samples >= o.min_blocks_per_bin && (ratio * o.max_band_ratio < 1 || ratio > o.max_band_ratio);
  f.usable = f.kept_samples >= o.min_blocks_per_bin && !f.not_white;
  if (f.not_white) {
    f.texture += f.kept, f.kept = 0;  // texture (or spatially correlated noise)
  } else if (!f.usable) {
    f.sparse = f.kept, f.kept = 0;
  }
  return f;
}

// Weighted least squares y = a x + b with a, b >= 0: the unconstrained solution if feasible,
// else the better of the fits with one constraint active.
std::pair<double, double> fit_nonnegative_line(const std::vector<double>& x, const std::vector<double>& y,
                                               const std::vector<double>& w) {
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sw += w[i], sx += w[i] * x[i], sy += w[i] * y[i], sxx += w[i] * x[i] * x[i], sxy += w[i] * x[i] * y[i];
  }
  const double det = sw * sxx - sx * sx;
  if (det > 1e-12 * sw * sxx) {
    const double a = (sw * sxy - sx * sy) / det, b = (sy - a * sx) / sw;
    if (a >= 0 && b >= 0) return {a, b};
  }
  auto cost = [&](double a, double b) {
    double c = 0;
    for (std::size_t i = 0; i < x.size(); ++i) c += w[i] * (y[i] - a * x[i] - b) * (y[i] - a * x[i] - b);
    return c;
  };
  const std::pair<double, double> b_only{0.0, std::max(sy / sw, 0.0)};
  const std::pair<double, double> a_only{sxx > 0 ? std::max(sxy / sxx, 0.0) : 0.0, 0.0};
  return cost(a_only.first, a_only.second) < cost(b_only.first, b_only.second) ? a_only : b_only;
}

struct ChannelFit {
  double a = 0, b = 0;
  int bins = 0;       // 0: no usable bin
  int not_white = 0;  // bins with enough blocks that failed the band-ratio test
  double used = 0, texture = 0, clipped = 0, sparse = 0;
  double level_min = 0, level_max = 0, band_ratio = 0;
  std::string note;
};

// The NLF line through a channel's usable bins: iteratively reweighted (weights blocks /
// sigma^4 from the fitted variance, so chance-low bins get no extra weight).
std::pair<double, double> fit_line(const std::vector<double>& x, const std::vector<double>& y,
                                   const std::vector<double>& n, double q) {
  std::vector<double> w(x.size()), var(x.size());
  for (std::size_t i = 0; i < x.size(); ++i)
    var[i] = std::max(y[i] + q, 1e-6), w[i] = n[i] / (var[i] * var[i]);
  std::pair<double, double> ab{0, 0};
  for (int it = 0; it < 3; ++it) {
    ab = fit_nonnegative_line(x, y, w);
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double v = std::max(ab.first * x[i] + ab.second + q, 1e-6);
      w[i] = n[i] / (v * v);
    }
  }
  return ab;
}

// Texture that passes for noise only ever raises a bin's variance: bins significantly above the
// line (their sampling error, `se_v` / sqrt(blocks) relative, and kFitFloor) are dropped one at a
// time, the worst first, and the line refitted, while min_bins remain. Returns a, b; `drop` marks
// the dropped bins (indices into fits).
std::pair<double, double> fit_bins(const std::vector<BinFit>& fits, double q, double se_v, int min_bins,
                                   std::vector<char>* drop = nullptr) {
  std::vector<double> x, y, n;
  std::vector<std::size_t> idx;
  for (std::size_t j = 0; j < fits.size(); ++j) {
    const BinFit& f = fits[j];
    if (!f.usable) continue;
    x.push_back(f.level), y.push_back(f.var_v - q), n.push_back(f.kept_samples), idx.push_back(j);
  }
  if (drop) drop->assign(fits.size(), 0);
  std::pair<double, double> ab = fit_line(x, y, n, q);
  while (x.size() > static_cast<std::size_t>(std::max(min_bins, 2))) {
    std::size_t worst = 0;
    double worst_z = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double v = std::max(ab.first * x[i] + ab.second + q, 1e-6);
      const double z = (y[i] + q - v) / (v * std::sqrt(se_v * se_v / n[i] + kFitFloor * kFitFloor));
      if (z > worst_z) worst_z = z, worst = i;
    }
    if (worst_z <= kDropZ) break;
    if (drop) (*drop)[idx[worst]] = 1;
    for (auto* vec : {&x, &y, &n}) vec->erase(vec->begin() + static_cast<std::ptrdiff_t>(worst));
    idx.erase(idx.begin() + static_cast<std::ptrdiff_t>(worst));
    ab = fit_line(x, y, n, q);
  }
  return ab;
}

// Fits one channel (bins = 0: nothing usable).
ChannelFit fit_channel(const std::vector<BinData>& bins, const BlockModel& bm, const NoiseEstimateOptions& o,
                       const std::string& name) {
  const double q = o.remove_quantisation ? kQuantisationVar : 0.0;
  std::vector<BinFit> fits(bins.size());
  for (std::size_t j = 0; j < bins.size(); ++j) fits[j] = fit_bin(bins[j], bm, o, BinFit{}, nullptr);
  auto usable = [&fits] {
    std::vector<const BinFit*> u;
    for (const BinFit& f : fits)
      if (f.usable) u.push_back(&f);
    return u;
  };
  std::vector<const BinFit*> used = usable();
  const double bin_width = 256.0 / static_cast<double>(bins.size());
  auto span = [&used] {
    auto [lo, hi] = std::minmax_element(used.begin(), used.end(),
                                        [](const BinFit* l, const BinFit* r) { return l->level < r->level; });
    return (*hi)->level - (*lo)->level;
  };
  auto too_few_levels = [&] {
    return used.size() < static_cast<std::size_t>(std::max(o.min_bins, 2)) || span() < 0.5 * bin_width;
  };
  ChannelFit c;
  if (!used.empty() && !too_few_levels()) {
    // Second pass: each block judged against the first line at its own level.
    const auto [a, b] = fit_bins(fits, q, bm.se_v, o.min_bins);
    const Line line{a, b + q};
    for (std::size_t j = 0; j < bins.size(); ++j)
      if (fits[j].usable) fits[j] = fit_bin(bins[j], bm, o, fits[j], &line);
    used = usable();
  }
  if (!used.empty() && !too_few_levels()) {
    // Bins the line drops as textured count as such.
    std::vector<char> drop;
    fit_bins(fits, q, bm.se_v, o.min_bins, &drop);
    for (std::size_t j = 0; j < fits.size(); ++j)
      if (drop[j]) fits[j].texture += fits[j].kept, fits[j].kept = 0, fits[j].usable = false;
    used = usable();
  }
  for (const BinFit& f : fits)
    c.texture += f.texture, c.clipped += f.clipped, c.sparse += f.sparse, c.not_white += f.not_white;
  if (used.empty()) return c;
  double n = 0, yn = 0, ratio = 0;
  c.level_min = 255, c.level_max = 0;
  for (const BinFit* f : used) {
    c.used += f->kept, n += f->kept_samples, yn += f->kept_samples * (f->var_v - q);
    ratio += f->kept_samples * f->var_t / std::max(f->var_v, 1e-12);
    c.level_min = std::min(c.level_min, f->level), c.level_max = std::max(c.level_max, f->level);
  }
  c.bins = static_cast<int>(used.size());
  c.band_ratio = ratio / n;
  if (too_few_levels()) {
    c.b = std::max(yn / n, 0.0);
    c.note = "channel " + name + ": too few levels to tell shot from read noise (" + std::to_string(c.bins) +
             (c.bins == 1 ? " bin at " : " bins over ") + num(c.level_min) + ".." + num(c.level_max) +
             " DN; needs " + std::to_string(std::max(o.min_bins, 2)) + " bins " + num(0.5 * bin_width) +
             " DN apart): a = 0, b = the measured variance";
  } else {
    std::tie(c.a, c.b) = fit_bins(fits, q, bm.se_v, o.min_bins);
  }
  return c;
}

// Where one same-colour lattice's blocks lie in an image: block (bj, bi)'s pixel (j, i) is image
// pixel (x0, y0) + (B bj + j) * dj + (B bi + i) * di. A site plane steps (0, 2) and (2, 0) (1 for
// RGB and Mono); the Bayer green quincunx steps along the diagonals, (1, 1) and (1, -1).
struct PlaneScan {
  const std::uint8_t* data = nullptr;  // the image's pixel (0, 0), at the channel's byte
  std::ptrdiff_t stride = 0, bpp = 0;
  int width = 0, height = 0;
  int x0 = 0, y0 = 0, djx = 0, djy = 0, dix = 0, diy = 0;
  int bj0 = 0, bj1 = 0, bi0 = 0, bi1 = 0;   // block index ranges
  bool checker = false;                     // remove the two green sites' offset (quincunx)
  std::array<std::uint8_t, 256> clipped{};  // 1 for values at or beyond the clip levels
  const int* weight = nullptr;              // level weight per block row and column
};

// Measures every block of a plane: emit(nullptr) for a clipped block, emit(&stat) otherwise.
// kB > 0 fixes the block side at compile time (the usual 8: unrolled loops); 0 takes b_runtime.
template <int kB, typename Emit>
void scan_plane(const PlaneScan& p, int b_runtime, Emit&& emit) {
  constexpr int kMaxB = 64;
  const int B = kB > 0 ? kB : b_runtime, m = B - 2, n = B * B;
  int px[kB > 0 ? kB * kB : kMaxB * kMaxB];
  int d2[kB > 0 ? kB * kB : kMaxB * kMaxB];
  const double sum_x2 = B * (B * B - 1.0) / 3.0 * B;  // sum of (2x - B + 1)^2 over the block
  const double level_norm = 1.0 / (6.0 * m * 6.0 * m);
  // The quincunx's checkerboard (the green sites' offset) is taken out of v and t.
  const double v_norm = 1.0 / (p.checker ? checker_trace(B) : 36.0 * m * m);
  const int t_dof = n - (p.checker ? 4 : 3);
  const std::ptrdiff_t row_step = p.djy * p.stride + p.djx * p.bpp,
                       col_step = p.diy * p.stride + p.dix * p.bpp;
  auto inside = [&p](int x, int y) { return x >= 0 && y >= 0 && x < p.width && y < p.height; };
  for (int by = p.bj0; by < p.bj1; ++by) {
    for (int bx = p.bi0; bx < p.bi1; ++bx) {
      const int x = p.x0 + by * B * p.djx + bx * B * p.dix, y = p.y0 + by * B * p.djy + bx * B * p.diy;
      const int xe = (B - 1) * p.djx, ye = (B - 1) * p.djy, xi = (B - 1) * p.dix, yi = (B - 1) * p.diy;
      if (!inside(x, y) || !inside(x + xe, y + ye) || !inside(x + xi, y + yi) ||
          !inside(x + xe + xi, y + ye + yi))
        continue;  // a quincunx block across the image's edge
      const std::uint8_t* block = p.data + y * p.stride + x * p.bpp;
      unsigned clipped = 0;  // a table and OR: no min/max dependency chain
      for (int j = 0; j < B; ++j) {
        const std::uint8_t* src = block + j * row_step;
        for (int i = 0; i < B; ++i) {
          const std::uint8_t v = src[i * col_step];
          px[j * B + i] = v;
          clipped |= p.clipped[v];
        }
      }
      if (clipped) {
        emit(nullptr);
        continue;
      }
      // Plane-fit sums (centred, doubled coordinates), the v-weighted level, the checkerboard.
      std::int64_t s = 0, s2 = 0, sx = 0, sy = 0, level = 0, sc = 0;
      for (int j = 0; j < B; ++j) {
        const int* r = px + j * B;
        int rs = 0, rsx = 0, rs2 = 0, rw = 0;
        for (int i = 0; i < B; ++i) {
          rs += r[i], rs2 += r[i] * r[i], rsx += (2 * i - B + 1) * r[i];
          rw += p.weight[i] * r[i];
        }
        s += rs, s2 += rs2, sx += rsx, sy += static_cast<std::int64_t>(2 * j - B + 1) * rs;
        level += static_cast<std::int64_t>(p.weight[j]) * rw;
        if (p.checker)
          for (int i = 0; i < B; ++i) sc += (i + j) % 2 ? -r[i] : r[i];
      }
      const double ds = static_cast<double>(s), dsx = static_cast<double>(sx), dsy = static_cast<double>(sy);
      const double dsc = static_cast<double>(sc);
      const double plane_ss =
          static_cast<double>(s2) - ds * ds / n - (dsx * dsx + dsy * dsy) / sum_x2 - dsc * dsc / n;
      // Immerkaer's mask, separably: vertical then horizontal [1 -2 1].
      for (int j = 1; j <= m; ++j)
        for (int i = 0; i < B; ++i)
          d2[(j - 1) * B + i] = px[(j - 1) * B + i] - 2 * px[j * B + i] + px[(j + 1) * B + i];
      std::int64_t ss = 0, rc = 0;
      for (int j = 0; j < m; ++j) {
        int row_ss = 0, row_c = 0;  // < 64 * 4080^2 fits in 31 bits
        for (int i = 1; i <= m; ++i) {
          const int r = d2[j * B + i - 1] - 2 * d2[j * B + i] + d2[j * B + i + 1];
          row_ss += r * r, row_c += (i + j) % 2 ? -r : r;
        }
        ss += row_ss, rc += row_c;
      }
      const double v_ss = static_cast<double>(ss) -
                          (p.checker ? static_cast<double>(rc) * static_cast<double>(rc) / (m * m) : 0.0);
      const BlockStat stat{static_cast<float>(static_cast<double>(level) * level_norm),
                           static_cast<float>(std::max(v_ss, 0.0) * v_norm),
                           static_cast<float>(std::max(plane_ss, 0.0) / t_dof)};
      emit(&stat);
    }
  }
}

std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

}  // namespace

double NoiseLevelFunction::variance(int ch, double level_dn) const {
  if (ch < 0 || ch >= channels || ch >= 3) return 0.0;
  const double v = a[static_cast<std::size_t>(ch)] * level_dn + b[static_cast<std::size_t>(ch)];
  return v > 0 ? v : 0.0;  // also maps NaN to 0
}

int noise_channel(PixelFormat f, int x, int y, int c) {
  if (is_bayer(f)) return bayer_channel(f, x, y);
  if (f == PixelFormat::kRGB8 || f == PixelFormat::kRGBA8) return c >= 0 && c < 3 ? c : -1;
  return 0;
}

NoiseLevelEstimator::NoiseLevelEstimator(NoiseEstimateOptions options) : options_(options) {}

void NoiseLevelEstimator::clear() {
  channels_ = 0;
  format_ = PixelFormat::kMono8;
  for (auto& b : bins_) b.clear();
  seen_ = {}, clipped_ = {};
  frames_ = 0;
  rng_state_ = kRngSeed;
}

void NoiseLevelEstimator::add_block(int channel, const BlockStat& s) {
  std::vector<Bin>& bins = bins_[static_cast<std::size_t>(channel)];
  const int bin = std::clamp(static_cast<int>(s.level * static_cast<float>(bins.size()) / 256.f), 0,
                             static_cast<int>(bins.size()) - 1);
  Bin& b = bins[static_cast<std::size_t>(bin)];
  ++b.blocks;
  // Reservoir sampling (Vitter's algorithm R): every block ever added is kept with equal chance.
  if (b.samples.size() < static_cast<std::size_t>(options_.max_blocks_per_bin)) {
    b.samples.push_back(s);
  } else {
    const std::uint64_t j = splitmix64(rng_state_) % b.blocks;
    if (j < b.samples.size()) b.samples[j] = s;
  }
}

void NoiseLevelEstimator::add_plane(const Image& image, const Plane& p) {
  const int B = options_.block_px, w = image.width(), h = image.height();
  PlaneScan scan;
  scan.data = image.data() + p.byte;
  scan.stride = static_cast<std::ptrdiff_t>(image.stride_bytes());
  scan.bpp = bytes_per_pixel(image.format());
  scan.width = w, scan.height = h, scan.x0 = p.x0, scan.y0 = p.y0;
  if (p.step > 0) {  // a site plane or a channel
    scan.djy = scan.dix = p.step;
    scan.bj1 = (h - p.y0 + p.step - 1) / p.step / B;
    scan.bi1 = (w - p.x0 + p.step - 1) / p.step / B;
  } else {  // the green quincunx: rows along (1, 1), columns along (1, -1)
    scan.djx = scan.djy = scan.dix = 1, scan.diy = -1;
    scan.checker = true;
    scan.bj1 = (w + h) / (2 * B) + 1;
    scan.bi0 = -h / (2 * B) - 1, scan.bi1 = w / (2 * B) + 1;
  }
  for (int v = 0; v < 256; ++v)
    scan.clipped[static_cast<std::size_t>(v)] = v <= options_.clip_low_dn || v >= options_.clip_high_dn;
  scan.weight = weight_.data();
  const std::size_t c = static_cast<std::size_t>(p.channel);
  auto emit = [&](const BlockStat* s) {
    ++seen_[c];
    if (s) {
      add_block(p.channel, *s);
    } else {
      ++clipped_[c];
    }
  };
  if (B == 8) {
    scan_plane<8>(scan, B, emit);
  } else {
    scan_plane<0>(scan, B, emit);
  }
}

Status NoiseLevelEstimator::add(const Image& image) {
  if (Status s = check_options(options_, "NoiseLevelEstimator::add()"); !s) return s;
  if (image.empty()) return make_error("NoiseLevelEstimator::add(): empty image");
  const PixelFormat f = image.format();
  if (channels_ == 0) {
    format_ = f;
    channels_ = f == PixelFormat::kMono8 ? 1 : 3;
    for (int c = 0; c < channels_; ++c)
      bins_[static_cast<std::size_t>(c)].assign(static_cast<std::size_t>(options_.bins), Bin{});
  } else if (f != format_) {
    return make_error("NoiseLevelEstimator::add(): a ", to_string(f), " frame after ", to_string(format_),
                      " frames (clear() first)");
  }
  const int B = options_.block_px;
  weight_.assign(static_cast<std::size_t>(B), 0);
  for (int x = 0; x < B; ++x)  // sum over the interior mask centres of [1 -2 1]^2
    for (int c = std::max(1, x - 1); c <= std::min(B - 2, x + 1); ++c)
      weight_[static_cast<std::size_t>(x)] += c == x ? 4 : 1;
  if (is_bayer(f)) {
    // R and B on their site planes; G on the quincunx of both green sites (twice as dense: fine
    // texture that the planes' 2 px spacing would alias into their high-pass mostly leaves it).
    for (int y0 = 0; y0 < 2; ++y0)
      for (int x0 = 0; x0 < 2; ++x0)
        if (bayer_channel(f, x0, y0) != 1) add_plane(image, {x0, y0, 2, 0, bayer_channel(f, x0, y0)});
    add_plane(image, {bayer_channel(f, 0, 0) == 1 ? 0 : 1, 0, 0, 0, 1});
  } else {
    for (int c = 0; c < channels_; ++c) add_plane(image, {0, 0, 1, c, c});
  }
  ++frames_;
  return {};
}

Expected<NoiseFitReport> NoiseLevelEstimator::fit() const {
  if (Status s = check_options(options_, "NoiseLevelEstimator::fit()"); !s) return s.error();
  if (frames_ == 0) return make_error("NoiseLevelEstimator::fit(): no frames added");
  const BlockModel plane_model = block_model(options_.block_px, false);
  const BlockModel quincunx_model = block_model(options_.block_px, true);
  NoiseFitReport r;
  r.nlf.channels = channels_;
  double texture = 0, clipped = 0;
  std::vector<std::string> notes;
  for (int ch = 0; ch < channels_; ++ch) {
    const std::size_t c = static_cast<std::size_t>(ch);
    const std::string name = channel_name(channels_, ch);
    const std::string where = "NoiseLevelEstimator::fit(): channel " + name + ": ";
    const bool quincunx = is_bayer(format_) && ch == 1;  // Bayer G: read on the green quincunx
    r.blocks_seen += seen_[c];
    if (seen_[c] == 0)
      return make_error(where, "no blocks (frames smaller than one ", options_.block_px, " x ",
                        options_.block_px, " block of the channel's ",
                        quincunx
                            ? "quincunx: a diamond " + std::to_string(2 * options_.block_px - 1) +
                                  " px across, at 2 x " + std::to_string(options_.block_px) + " px steps)"
                            : std::string("plane)"));
    if (clipped_[c] == seen_[c])
      return make_error(where, "all ", seen_[c], " blocks clipped (a pixel <= ", num(options_.clip_low_dn),
                        " or >= ", num(options_.clip_high_dn), " DN): needs unclipped image regions");
    std::vector<BinData> bins;
    for (const Bin& b : bins_[c]) bins.push_back({&b.samples, b.blocks});
    const ChannelFit f = fit_channel(bins, quincunx ? quincunx_model : plane_model, options_, name);
    if (f.bins == 0) {
      const std::string white =
          f.not_white
              ? "; " + std::to_string(f.not_white) +
                    " levels' blocks differ in full-band and high-pass variance: texture, or spatially "
                    "correlated noise"
              : "";
      return make_error(where, "no level has ", options_.min_blocks_per_bin, " flat, unclipped blocks (",
                        seen_[c],
                        " blocks seen: ", std::llround(f.clipped + static_cast<double>(clipped_[c])),
                        " clipped, ", std::llround(f.texture), " textured, ", std::llround(f.sparse),
                        " flat but too few per level", white, "): needs flat, unclipped image regions");
    }
    r.nlf.a[c] = f.a, r.nlf.b[c] = f.b;
    r.bins_used[c] = f.bins;
    r.blocks_used[c] = static_cast<std::uint64_t>(std::llround(f.used));
    r.level_min_dn[c] = f.level_min, r.level_max_dn[c] = f.level_max;
    r.band_ratio[c] = f.band_ratio;
    texture += f.texture, clipped += f.clipped + static_cast<double>(clipped_[c]);
    if (!f.note.empty()) notes.push_back(f.note);
  }
  r.blocks_rejected_texture = static_cast<std::uint64_t>(std::llround(texture));
  r.blocks_rejected_clipped = static_cast<std::uint64_t>(std::llround(clipped));
  for (const std::string& n : notes) r.note += (r.note.empty() ? "" : "; ") + n;
  return r;
}

Expected<NoiseFitReport> estimate_noise_level(const Image& image, const NoiseEstimateOptions& options) {
  NoiseLevelEstimator e(options);
  if (Status s = e.add(image); !s) return s.error();
  return e.fit();
}

}  // namespace augrig
