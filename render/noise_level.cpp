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
};

// t is chi^2_{B^2-3} / (B^2-3) exactly. v = x'Mx / tr M (M = A'A, A the mask at the interior
// positions) is a sum of chi^2_1 with unequal weights: a Satterthwaite chi^2 (11.4 dof at B = 8)
// puts its median 1.4 % high, so match its first three cumulants with a shifted, scaled chi^2
// instead (Pearson 1959): median within 0.5 %, 99.9 % quantile within 0.1 %. M is the Kronecker
// square of the 1D G = A1'A1, so the cumulants 2^(r-1) (r-1)! tr(M^r) need tr(G^r)^2 only.
BlockModel block_model(int B) {
  const int m = B - 2;
  const std::size_t n = static_cast<std::size_t>(B);
  std::vector<double> g(n * n, 0.0);
  constexpr double kTap[3] = {1, -2, 1};
  for (int r = 0; r < m; ++r)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) g[static_cast<std::size_t>((r + i) * B + r + j)] += kTap[i] * kTap[j];
  double tr1 = 0, tr2 = 0, tr3 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    tr1 += g[i * n + i];
    for (std::size_t j = 0; j < n; ++j) {
      tr2 += g[i * n + j] * g[j * n + i];
      for (std::size_t k = 0; k < n; ++k) tr3 += g[i * n + j] * g[j * n + k] * g[k * n + i];
    }
  }
  const double k1 = tr1 * tr1, k2 = 2 * tr2 * tr2, k3 = 8 * tr3 * tr3;
  const double skew = k3 / std::pow(k2, 1.5), h = 8 / (skew * skew);  // chi^2_h has skewness sqrt(8/h)
  auto v_ratio = [&](double z) { return 1 + std::sqrt(k2 / (2 * h)) * h * (chi2_ratio(h, z) - 1) / k1; };
  const double dof_t = B * B - 3.0;  // residual of a 3-parameter plane
  return {v_ratio(0), chi2_ratio(dof_t, 0), v_ratio(kTailZ), chi2_ratio(dof_t, kTailZt),
          chi2_ratio(dof_t, kSeedZ)};
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
std::pair<double, double> fit_bins(const std::vector<BinFit>& fits, double q) {
  std::vector<double> x, y, w, var;
  for (const BinFit& f : fits) {
    if (!f.usable) continue;
    x.push_back(f.level), y.push_back(f.var_v - q), var.push_back(std::max(f.var_v, 1e-6));
    w.push_back(f.kept_samples / (var.back() * var.back()));
  }
  std::pair<double, double> ab{0, 0};
  for (int it = 0; it < 3; ++it) {
    ab = fit_nonnegative_line(x, y, w);
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double v = std::max(ab.first * x[i] + ab.second + q, 1e-6);
      w[i] = w[i] * var[i] * var[i] / (v * v), var[i] = v;
    }
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
    const auto [a, b] = fit_bins(fits, q);
    const Line line{a, b + q};
    for (std::size_t j = 0; j < bins.size(); ++j)
      if (fits[j].usable) fits[j] = fit_bin(bins[j], bm, o, fits[j], &line);
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
    std::tie(c.a, c.b) = fit_bins(fits, q);
  }
  return c;
}

// Where one same-colour plane's blocks lie in an image.
struct PlaneScan {
  const std::uint8_t* origin = nullptr;  // the plane's pixel (0, 0)
  std::size_t row_bytes = 0, col_bytes = 0;
  int blocks_x = 0, blocks_y = 0;
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
  const double level_norm = 1.0 / (6.0 * m * 6.0 * m), v_norm = 1.0 / (36.0 * m * m);
  for (int by = 0; by < p.blocks_y; ++by) {
    for (int bx = 0; bx < p.blocks_x; ++bx) {
      const std::uint8_t* block = p.origin + static_cast<std::size_t>(by * B) * p.row_bytes +
                                  static_cast<std::size_t>(bx * B) * p.col_bytes;
      unsigned clipped = 0;  // a table and OR: no min/max dependency chain
      for (int j = 0; j < B; ++j) {
        const std::uint8_t* src = block + static_cast<std::size_t>(j) * p.row_bytes;
        for (int i = 0; i < B; ++i) {
          const std::uint8_t v = src[static_cast<std::size_t>(i) * p.col_bytes];
          px[j * B + i] = v;
          clipped |= p.clipped[v];
        }
      }
      if (clipped) {
        emit(nullptr);
        continue;
      }
      // Plane-fit sums (centred, doubled coordinates) and the v-weighted level.
      std::int64_t s = 0, s2 = 0, sx = 0, sy = 0, level = 0;
      for (int j = 0; j < B; ++j) {
        const int* r = px + j * B;
        int rs = 0, rsx = 0, rs2 = 0, rw = 0;
        for (int i = 0; i < B; ++i) {
          rs += r[i], rs2 += r[i] * r[i], rsx += (2 * i - B + 1) * r[i];
          rw += p.weight[i] * r[i];
        }
        s += rs, s2 += rs2, sx += rsx, sy += static_cast<std::int64_t>(2 * j - B + 1) * rs;
        level += static_cast<std::int64_t>(p.weight[j]) * rw;
      }
      const double ds = static_cast<double>(s), dsx = static_cast<double>(sx), dsy = static_cast<double>(sy);
      const double plane_ss = static_cast<double>(s2) - ds * ds / n - (dsx * dsx + dsy * dsy) / sum_x2;
      // Immerkaer's mask, separably: vertical then horizontal [1 -2 1].
      for (int j = 1; j <= m; ++j)
        for (int i = 0; i < B; ++i)
          d2[(j - 1) * B + i] = px[(j - 1) * B + i] - 2 * px[j * B + i] + px[(j + 1) * B + i];
      std::int64_t ss = 0;
      for (int j = 0; j < m; ++j) {
        int row_ss = 0;  // < 64 * 4080^2 fits in 31 bits
        for (int i = 1; i <= m; ++i) {
          const int r = d2[j * B + i - 1] - 2 * d2[j * B + i] + d2[j * B + i + 1];
          row_ss += r * r;
        }
        ss += row_ss;
      }
      const BlockStat stat{static_cast<float>(static_cast<double>(level) * level_norm),
                           static_cast<float>(static_cast<double>(ss) * v_norm),
                           static_cast<float>(std::max(plane_ss, 0.0) / (n - 3))};
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
  const int B = options_.block_px;
  PlaneScan scan;
  const std::size_t bpp = static_cast<std::size_t>(bytes_per_pixel(image.format()));
  scan.origin = image.row(p.y0) + static_cast<std::size_t>(p.x0) * bpp + static_cast<std::size_t>(p.byte);
  scan.row_bytes = image.stride_bytes() * static_cast<std::size_t>(p.step);
  scan.col_bytes = bpp * static_cast<std::size_t>(p.step);
  scan.blocks_x = (image.width() - p.x0 + p.step - 1) / p.step / B;
  scan.blocks_y = (image.height() - p.y0 + p.step - 1) / p.step / B;
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
    for (int y0 = 0; y0 < 2; ++y0)
      for (int x0 = 0; x0 < 2; ++x0) add_plane(image, {x0, y0, 2, 0, bayer_channel(f, x0, y0)});
  } else {
    for (int c = 0; c < channels_; ++c) add_plane(image, {0, 0, 1, c, c});
  }
  ++frames_;
  return {};
}

Expected<NoiseFitReport> NoiseLevelEstimator::fit() const {
  if (Status s = check_options(options_, "NoiseLevelEstimator::fit()"); !s) return s.error();
  if (frames_ == 0) return make_error("NoiseLevelEstimator::fit(): no frames added");
  const BlockModel bm = block_model(options_.block_px);
  NoiseFitReport r;
  r.nlf.channels = channels_;
  double texture = 0, clipped = 0;
  std::vector<std::string> notes;
  for (int ch = 0; ch < channels_; ++ch) {
    const std::size_t c = static_cast<std::size_t>(ch);
    const std::string name = channel_name(channels_, ch);
    const std::string where = "NoiseLevelEstimator::fit(): channel " + name + ": ";
    r.blocks_seen += seen_[c];
    if (seen_[c] == 0)
      return make_error(where, "no blocks (frames smaller than one ", options_.block_px, " x ",
                        options_.block_px, " block of the channel's plane)");
    if (clipped_[c] == seen_[c])
      return make_error(where, "all ", seen_[c], " blocks clipped (a pixel <= ", num(options_.clip_low_dn),
                        " or >= ", num(options_.clip_high_dn), " DN): needs unclipped image regions");
    std::vector<BinData> bins;
    for (const Bin& b : bins_[c]) bins.push_back({&b.samples, b.blocks});
    const ChannelFit f = fit_channel(bins, bm, options_, name);
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
