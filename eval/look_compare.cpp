#include "eval/look_compare.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <utility>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/ml.hpp>

namespace augrig::eval {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Samples per pixel that carry the look: RGBA's alpha does not.
int colour_samples(PixelFormat f) {
  return f == PixelFormat::kRGBA8 ? 3 : bytes_per_pixel(f);
}

Status check_mask(const char* where, ConstImageView img, ConstImageView mask) {
  if (mask.format != PixelFormat::kMono8 || mask.width != img.width || mask.height != img.height)
    return make_error(where, "the mask is ", to_string(mask.format), " ", mask.width, "x", mask.height,
                      ", expected Mono8 ", img.width, "x", img.height);
  return {};
}

// ---- noise ---------------------------------------------------------------------------------------

// |Immerkaer response| <= 16 * 255.
constexpr int kMaxResponse = 16 * 255;

// Immerkaer's responses of every channel at every pixel whose 3x3 neighbourhood (on a Bayer mosaic:
// its same-site neighbourhood, 2 px apart) lies in `mask` (an empty mask: the whole image), as a
// histogram of |response|: the responses of 8-bit data are integers.
std::vector<std::uint64_t> immerkaer_histogram(ConstImageView img, ConstImageView mask) {
  std::vector<std::uint64_t> hist(kMaxResponse + 1, 0);
  const int s = is_bayer(img.format) ? 2 : 1;  // neighbour distance
  const int bpp = bytes_per_pixel(img.format), channels = colour_samples(img.format);
  const bool masked = !mask.empty();
  auto inside = [&](int x, int y) {
    for (int dy = -s; dy <= s; dy += s) {
      const std::uint8_t* m = mask.row(y + dy);
      if (!m[x - s] || !m[x] || !m[x + s]) return false;
    }
    return true;
  };
  for (int y = s; y < img.height - s; ++y) {
    const std::uint8_t* r0 = img.row(y - s);
    const std::uint8_t* r1 = img.row(y);
    const std::uint8_t* r2 = img.row(y + s);
    for (int x = s; x < img.width - s; ++x) {
      if (masked && !inside(x, y)) continue;
      const int l = (x - s) * bpp, c = x * bpp, r = (x + s) * bpp;
      for (int ch = 0; ch < channels; ++ch) {
        const int v = r0[l + ch] - 2 * r0[c + ch] + r0[r + ch] - 2 * r1[l + ch] + 4 * r1[c + ch] -
                      2 * r1[r + ch] + r2[l + ch] - 2 * r2[c + ch] + r2[r + ch];
        ++hist[static_cast<std::size_t>(std::abs(v))];
      }
    }
  }
  return hist;
}

// The noise sigma from the histogram: 1.4826 * median(|r|) / 6, the median interpolated within its
// bin (integer k stands for |r| in [k - 1/2, k + 1/2), 0 for [0, 1/2)). NaN below min_responses.
double sigma_from_histogram(const std::vector<std::uint64_t>& hist, std::uint64_t min_responses) {
  std::uint64_t n = 0;
  for (const std::uint64_t h : hist) n += h;
  if (n == 0 || n < min_responses) return kNaN;
  if (hist[0] == n) return 0.0;  // no variation at all (the interpolation below would say 0.06)
  const double half = 0.5 * static_cast<double>(n);
  double below = 0;
  for (std::size_t k = 0; k < hist.size(); ++k) {
    const double h = static_cast<double>(hist[k]);
    if (h > 0 && below + h >= half) {
      const double lo = k == 0 ? 0.0 : static_cast<double>(k) - 0.5;
      const double width = k == 0 ? 0.5 : 1.0;
      return 1.4826 * (lo + (half - below) / h * width) / 6.0;
    }
    below += h;
  }
  return kNaN;  // not reached
}

// ---- luminance -----------------------------------------------------------------------------------

// The image as one float channel: Mono8 as is, RGB the mean of R, G and B, a Bayer mosaic averaged
// over 2 x 2 sites (each sees R, B and two G once, so a flat colour stays flat). The Bayer result is
// (width - 1) x (height - 1); its (i, j) lies at pixel position (i + 1/2, j + 1/2): `offset_px`.
cv::Mat luminance(ConstImageView img, double& offset_px) {
  offset_px = 0;
  if (is_bayer(img.format)) {
    offset_px = 0.5;
    cv::Mat out(std::max(img.height - 1, 0), std::max(img.width - 1, 0), CV_32F);
    for (int y = 0; y < out.rows; ++y) {
      const std::uint8_t* a = img.row(y);
      const std::uint8_t* b = img.row(y + 1);
      float* o = out.ptr<float>(y);
      for (int x = 0; x < out.cols; ++x) o[x] = 0.25f * static_cast<float>(a[x] + a[x + 1] + b[x] + b[x + 1]);
    }
    return out;
  }
  cv::Mat out(img.height, img.width, CV_32F);
  const int bpp = bytes_per_pixel(img.format), channels = colour_samples(img.format);
  for (int y = 0; y < img.height; ++y) {
    const std::uint8_t* r = img.row(y);
    float* o = out.ptr<float>(y);
    for (int x = 0; x < img.width; ++x) {
      int sum = 0;
      for (int c = 0; c < channels; ++c) sum += r[x * bpp + c];
      o[x] = static_cast<float>(sum) / static_cast<float>(channels);
    }
  }
  return out;
}

// ---- edge width ----------------------------------------------------------------------------------

constexpr double kMaskSigmaPx = 1.5;       // Gaussian that smooths the mask for its normals
constexpr double kMinMaskGradient = 0.12;  // a straight boundary gives 1 / (sqrt(2 pi) 1.5) = 0.27
constexpr double kMaxNormalAngleDeg = 20;  // neighbours' normals and the local fit's agree this well
constexpr int kNeighbourhoodPx = 3;        // ... over boundary pixels this near (Chebyshev)
// Gaussian weights of the boundary midpoints in the local fit: the long window first, the short one
// where the long one sees more than one smooth curve (near corners).
constexpr double kFitSigmasPx[2] = {10, 5};
constexpr double kMaxFitResidualPx = 0.6;  // the midpoints' RMS distance from the fit (staircase <= 0.35)
constexpr double kProfileHalfPx = 6;       // profiles from -6 to +6 px about the boundary
constexpr double kStripHalfPx = 1;         // pixels within 1 px of the normal line are its samples
constexpr double kPlateauPx = 4.5;         // |d| >= 4.5: the plateaus that normalise a profile
constexpr double kBinPx = 0.25;
constexpr int kBins = static_cast<int>(2 * kProfileHalfPx / kBinPx);
constexpr double kMaxDecrease = 0.3;  // of the contrast, after a 5-sample running mean
constexpr int kBorderPx = 9;          // boundary pixels nearer the image's border are skipped

struct BoundaryPixel {
  int x, y;
  double nx, ny;  // outward unit normal from the smoothed mask
  bool valid;     // the smoothed mask's gradient is strong enough for a normal
};

// Boundary pixels (in the mask, with a 4-neighbour out of it) and their normals from the mask
// smoothed by a Gaussian; `index` maps a pixel to its entry (-1: none).
std::vector<BoundaryPixel> boundary_pixels(const cv::Mat& in, std::vector<int>& index) {
  cv::Mat smooth;
  cv::GaussianBlur(in, smooth, cv::Size(0, 0), kMaskSigmaPx, kMaskSigmaPx, cv::BORDER_REPLICATE);
  index.assign(static_cast<std::size_t>(in.rows) * in.cols, -1);
  std::vector<BoundaryPixel> out;
  for (int y = 1; y + 1 < in.rows; ++y) {
    for (int x = 1; x + 1 < in.cols; ++x) {
      if (in.at<float>(y, x) == 0) continue;
      if (in.at<float>(y, x - 1) != 0 && in.at<float>(y, x + 1) != 0 && in.at<float>(y - 1, x) != 0 &&
          in.at<float>(y + 1, x) != 0)
        continue;
      const double gx = 0.5 * (smooth.at<float>(y, x + 1) - smooth.at<float>(y, x - 1));
      const double gy = 0.5 * (smooth.at<float>(y + 1, x) - smooth.at<float>(y - 1, x));
      const double g = std::hypot(gx, gy);
      index[static_cast<std::size_t>(y) * in.cols + x] = static_cast<int>(out.size());
      out.push_back({x, y, g > 0 ? -gx / g : 0.0, g > 0 ? -gy / g : 0.0, g >= kMinMaskGradient});
    }
  }
  return out;
}

// Whether every boundary pixel near `b` has a normal within kMaxNormalAngleDeg of b's: a locally
// straight (or gently curved) stretch of boundary, no corner, no thin part.
bool straight_around(const BoundaryPixel& b, const std::vector<BoundaryPixel>& all,
                     const std::vector<int>& index, int width, int height) {
  const double min_dot = std::cos(kMaxNormalAngleDeg * std::numbers::pi / 180);
  for (int y = std::max(b.y - kNeighbourhoodPx, 0); y <= std::min(b.y + kNeighbourhoodPx, height - 1); ++y) {
    for (int x = std::max(b.x - kNeighbourhoodPx, 0); x <= std::min(b.x + kNeighbourhoodPx, width - 1); ++x) {
      const int i = index[static_cast<std::size_t>(y) * width + x];
      if (i < 0) continue;
      const BoundaryPixel& o = all[static_cast<std::size_t>(i)];
      if (!o.valid || o.nx * b.nx + o.ny * b.ny < min_dot) return false;
    }
  }
  return true;
}

// The local boundary near `b`: a parabola d = a + slope t + curvature t^2 in b's frame (t along
// the boundary, d along the smoothed mask's normal), fitted by weighted least squares to the
// midpoints of the in/out pixel pairs near b. The mask is decided at pixel centres, so the true
// boundary crosses each pair, on average at its midpoint; the midpoints' offsets from it form a
// sawtooth along the boundary. A window with a hard edge leaves part of a sawtooth period
// unaveraged: an error tied to b's own sub-pixel phase, which warps the averaged profile
// periodically (up to +-0.1 px in the width). Gaussian weights average whole periods smoothly; a
// 10 px sigma averages periods up to ~25 px along the boundary (boundaries 2-3 degrees or more off
// a row, a column or a diagonal). The quadratic term keeps such a window usable round curves.
// Returns false where the midpoints lie off a parabola (a corner, another part of the region
// nearby) or the fitted normal leaves the smoothed mask's by more than kMaxNormalAngleDeg.
struct LocalBoundary {
  double px, py;     // the boundary's point nearest b (at t = 0)
  double nx, ny;     // outward unit normal there
  double curvature;  // the boundary lies at d = curvature * t^2 from its tangent (inward: < 0)
};
bool fit_boundary(const cv::Mat& in, const BoundaryPixel& b, double sigma_px, LocalBoundary& out) {
  const int r = static_cast<int>(std::ceil(3 * sigma_px));
  const double ex = -b.ny, ey = b.nx;  // along the boundary
  // Weighted normal equations of d = c0 + c1 t + c2 t^2: sums of w t^k (k <= 4), w d t^k (k <= 2).
  double st[5] = {0, 0, 0, 0, 0}, sd[3] = {0, 0, 0}, sdd = 0;
  auto add = [&](double x, double y) {
    const double dx = x - b.x, dy = y - b.y, r2 = dx * dx + dy * dy;
    if (r2 > r * r) return;
    const double w = std::exp(-0.5 * r2 / (sigma_px * sigma_px));
    const double t = dx * ex + dy * ey, d = dx * b.nx + dy * b.ny;
    double wtk = w;
    for (int k = 0; k <= 4; ++k, wtk *= t) {
      st[k] += wtk;
      if (k <= 2) sd[k] += d * wtk;
    }
    sdd += w * d * d;
  };
  for (int y = std::max(b.y - r, 0); y <= std::min(b.y + r, in.rows - 1); ++y) {
    for (int x = std::max(b.x - r, 0); x <= std::min(b.x + r, in.cols - 1); ++x) {
      const bool here = in.at<float>(y, x) != 0;
      if (x + 1 < in.cols && here != (in.at<float>(y, x + 1) != 0)) add(x + 0.5, y);
      if (y + 1 < in.rows && here != (in.at<float>(y + 1, x) != 0)) add(x, y + 0.5);
    }
  }
  if (st[0] < 4) return false;  // a boundary through the window gives sqrt(2 pi) sigma or more
  const cv::Matx33d m(st[0], st[1], st[2], st[1], st[2], st[3], st[2], st[3], st[4]);
  const cv::Vec3d rhs(sd[0], sd[1], sd[2]);
  cv::Vec3d c;
  if (!cv::solve(m, rhs, c, cv::DECOMP_CHOLESKY)) return false;
  // Weighted mean squared residual: (sum w d^2 - c . rhs) / sum w for the least-squares solution.
  const double residual2 = (sdd - c.dot(rhs)) / st[0];
  if (residual2 > kMaxFitResidualPx * kMaxFitResidualPx) return false;
  const double len = std::hypot(1.0, c[1]);
  if (1.0 / len < std::cos(kMaxNormalAngleDeg * std::numbers::pi / 180)) return false;
  // Tangent (1, slope) and normal (-slope, 1) in the (along, normal) frame, then in the image's.
  out.px = b.x + c[0] * b.nx, out.py = b.y + c[0] * b.ny;
  out.nx = (b.nx - c[1] * ex) / len, out.ny = (b.ny - c[1] * ey) / len;
  out.curvature = c[2] / (len * len * len);
  return true;
}

struct ProfileBins {
  std::array<double, kBins> sum_d{}, sum_v{};
  std::array<int, kBins> count{};
};

// One profile across the local boundary: the luminance samples within kStripHalfPx of its normal
// at `line`'s point, at their exact distance d from the boundary (no interpolation, so no added
// blur; the distances of pixels along a slanted boundary fall at all sub-pixel phases). Normalised
// by its plateaus, checked for monotony, added to `bins`. False when rejected.
bool add_profile(const cv::Mat& lum, double offset_px, const LocalBoundary& line, double min_contrast_dn,
                 ProfileBins& bins) {
  const double px = line.px, py = line.py;
  std::vector<std::pair<double, double>> samples;  // (d, luminance)
  const int r = static_cast<int>(std::ceil(kProfileHalfPx + kStripHalfPx)) + 1;
  const int cx = static_cast<int>(std::lround(px - offset_px)),
            cy = static_cast<int>(std::lround(py - offset_px));
  for (int j = cy - r; j <= cy + r; ++j) {
    for (int i = cx - r; i <= cx + r; ++i) {
      const double rx = i + offset_px - px, ry = j + offset_px - py;
      const double along = -rx * line.ny + ry * line.nx;
      const double d = rx * line.nx + ry * line.ny - line.curvature * along * along;
      if (std::abs(along) > kStripHalfPx || std::abs(d) >= kProfileHalfPx) continue;
      if (i < 0 || j < 0 || i >= lum.cols || j >= lum.rows) return false;
      samples.emplace_back(d, lum.at<float>(j, i));
    }
  }
  double lo = 0, hi = 0;
  int n_lo = 0, n_hi = 0;
  for (const auto& [d, v] : samples) {
    if (d <= -kPlateauPx) lo += v, ++n_lo;
    if (d >= kPlateauPx) hi += v, ++n_hi;
  }
  if (n_lo < 2 || n_hi < 2) return false;
  lo /= n_lo, hi /= n_hi;
  if (std::abs(hi - lo) < min_contrast_dn) return false;
  for (auto& s : samples) s.second = (s.second - lo) / (hi - lo);  // rises from 0 inside to 1 out
  std::sort(samples.begin(), samples.end());
  // Roughly monotonic: no running mean falls more than kMaxDecrease below an earlier one.
  double peak = -1e300;
  for (std::size_t i = 0; i + 5 <= samples.size(); ++i) {
    double m = 0;
    for (std::size_t k = i; k < i + 5; ++k) m += samples[k].second;
    m /= 5;
    peak = std::max(peak, m);
    if (peak - m > kMaxDecrease) return false;
  }
  for (const auto& [d, v] : samples) {
    const int k = std::clamp(static_cast<int>(std::floor((d + kProfileHalfPx) / kBinPx)), 0, kBins - 1);
    bins.sum_d[k] += d, bins.sum_v[k] += v, ++bins.count[k];
  }
  return true;
}

// The 10-90 % width of the averaged profile: from its 50 % crossing nearest the boundary outwards
// to the 10 % and 90 % crossings, linearly interpolated between populated bins.
double width_10_90(const ProfileBins& bins) {
  std::vector<double> d, v;
  for (int k = 0; k < kBins; ++k) {
    if (bins.count[k] == 0) continue;
    d.push_back(bins.sum_d[k] / bins.count[k]);
    v.push_back(bins.sum_v[k] / bins.count[k]);
  }
  auto cross = [&](std::size_t i, double level) {  // between samples i and i + 1
    return d[i] + (level - v[i]) / (v[i + 1] - v[i]) * (d[i + 1] - d[i]);
  };
  std::size_t mid = d.size();
  double best = 1e300;
  for (std::size_t i = 0; i + 1 < d.size(); ++i) {
    if (v[i] < 0.5 && v[i + 1] >= 0.5 && std::abs(cross(i, 0.5)) < best)
      best = std::abs(cross(i, 0.5)), mid = i;
  }
  if (mid == d.size()) return kNaN;
  std::size_t i10 = mid, i90 = mid;
  while (!(v[i10] < 0.1)) {
    if (i10 == 0) return kNaN;
    --i10;
  }
  while (!(v[i90 + 1] > 0.9)) {
    if (i90 + 2 >= d.size()) return kNaN;
    ++i90;
  }
  return cross(i90, 0.9) - cross(i10, 0.1);
}

// ---- patches -------------------------------------------------------------------------------------

// Energy of the mean-removed patch's 2-D DCT in radial bands (normalised radius sqrt(u^2 + v^2) / m
// of the m x m coefficients; cut at 1/4, 1/2, 3/4), as fractions of the total (0 for a flat patch).
std::array<float, 4> dct_bands(const cv::Mat& patch) {
  std::array<float, 4> bands{};
  const int m = std::min(patch.rows, patch.cols) & ~1;  // cv::dct needs even sizes
  if (m < 2) return bands;
  cv::Mat p = patch(cv::Rect(0, 0, m, m)).clone();
  p -= cv::mean(p)[0];
  cv::Mat c;
  cv::dct(p, c);
  double band[4] = {0, 0, 0, 0}, total = 0;
  for (int v = 0; v < m; ++v) {
    for (int u = 0; u < m; ++u) {
      if (u == 0 && v == 0) continue;
      const double e = static_cast<double>(c.at<float>(v, u)) * c.at<float>(v, u);
      const double rho = std::hypot(u, v) / m;
      band[rho <= 0.25 ? 0 : rho <= 0.5 ? 1 : rho <= 0.75 ? 2 : 3] += e;
      total += e;
    }
  }
  if (total > 0)
    for (int k = 0; k < 4; ++k) bands[k] = static_cast<float>(band[k] / total);
  return bands;
}

cv::Mat to_mat(const std::vector<std::vector<float>>& a, const std::vector<std::vector<float>>& b) {
  cv::Mat out(static_cast<int>(a.size() + b.size()), static_cast<int>(a.front().size()), CV_32F);
  for (std::size_t i = 0; i < a.size() + b.size(); ++i) {
    const std::vector<float>& row = i < a.size() ? a[i] : b[i - a.size()];
    std::copy(row.begin(), row.end(), out.ptr<float>(static_cast<int>(i)));
  }
  return out;
}

}  // namespace

Expected<RegionDifference> region_difference(ConstImageView a, ConstImageView b, ConstImageView mask) {
  constexpr const char* kWhere = "eval::region_difference(): ";
  if (a.width != b.width || a.height != b.height || a.format != b.format)
    return make_error(kWhere, "the images differ: ", to_string(a.format), " ", a.width, "x", a.height,
                      " and ", to_string(b.format), " ", b.width, "x", b.height);
  if (Status s = check_mask(kWhere, a, mask); !s) return s.error();
  const int bpp = bytes_per_pixel(a.format), channels = colour_samples(a.format);
  std::int64_t sum = 0, sum2 = 0;  // exact: integer differences
  std::size_t pixels = 0;
  for (int y = 0; y < a.height; ++y) {
    const std::uint8_t* ra = a.row(y);
    const std::uint8_t* rb = b.row(y);
    const std::uint8_t* rm = mask.row(y);
    for (int x = 0; x < a.width; ++x) {
      if (!rm[x]) continue;
      ++pixels;
      for (int c = 0; c < channels; ++c) {
        const int d = ra[x * bpp + c] - rb[x * bpp + c];
        sum += d, sum2 += d * d;
      }
    }
  }
  RegionDifference out;
  out.pixels = pixels;
  const double samples = static_cast<double>(pixels) * channels;
  out.mean_dn = pixels ? static_cast<double>(sum) / samples : kNaN;
  out.rms_dn = pixels ? std::sqrt(static_cast<double>(sum2) / samples) : kNaN;
  return out;
}

Expected<double> robust_noise_sigma(ConstImageView img, ConstImageView mask) {
  if (Status s = check_mask("eval::robust_noise_sigma(): ", img, mask); !s) return s.error();
  if (img.empty()) return kNaN;
  return sigma_from_histogram(immerkaer_histogram(img, mask), 50);
}

Expected<EdgeWidth> edge_width(ConstImageView img, ConstImageView mask, double min_contrast_dn) {
  if (Status s = check_mask("eval::edge_width(): ", img, mask); !s) return s.error();
  EdgeWidth out;
  out.width_10_90_px = kNaN;
  if (img.width < 2 * kBorderPx + 1 || img.height < 2 * kBorderPx + 1) return out;
  cv::Mat in(img.height, img.width, CV_32F);
  for (int y = 0; y < img.height; ++y) {
    const std::uint8_t* m = mask.row(y);
    for (int x = 0; x < img.width; ++x) in.at<float>(y, x) = m[x] ? 1.0f : 0.0f;
  }
  double offset_px = 0;
  const cv::Mat lum = luminance(img, offset_px);
  std::vector<int> index;
  const std::vector<BoundaryPixel> boundary = boundary_pixels(in, index);
  ProfileBins bins;
  for (const BoundaryPixel& b : boundary) {
    if (!b.valid || b.x < kBorderPx || b.y < kBorderPx || b.x >= img.width - kBorderPx ||
        b.y >= img.height - kBorderPx)
      continue;
    if (!straight_around(b, boundary, index, img.width, img.height)) continue;
    LocalBoundary local;
    if (!fit_boundary(in, b, kFitSigmasPx[0], local) && !fit_boundary(in, b, kFitSigmasPx[1], local))
      continue;
    if (add_profile(lum, offset_px, local, min_contrast_dn, bins)) ++out.profiles;
  }
  if (out.profiles > 0) out.width_10_90_px = width_10_90(bins);
  return out;
}

std::vector<float> patch_features(ConstImageView img, int x0, int y0, int size) {
  if (size < 8 || x0 < 0 || y0 < 0 || x0 > img.width - size || y0 > img.height - size) return {};
  const ConstImageView raw = sub_view(img, PixelBox{x0, y0, x0 + size, y0 + size});
  double offset_px = 0;
  cv::Mat lum = luminance(raw, offset_px);
  cv::Scalar mean, stddev;
  cv::meanStdDev(lum, mean, stddev);
  // Gradient and Laplacian over the interior (their neighbours in the patch).
  double grad = 0, lap_sum = 0, lap_sum2 = 0;
  int n = 0;
  for (int y = 1; y + 1 < lum.rows; ++y) {
    for (int x = 1; x + 1 < lum.cols; ++x) {
      const double gx = 0.5 * (lum.at<float>(y, x + 1) - lum.at<float>(y, x - 1));
      const double gy = 0.5 * (lum.at<float>(y + 1, x) - lum.at<float>(y - 1, x));
      const double lap = lum.at<float>(y, x + 1) + lum.at<float>(y, x - 1) + lum.at<float>(y + 1, x) +
                         lum.at<float>(y - 1, x) - 4.0 * lum.at<float>(y, x);
      grad += gx * gx + gy * gy, lap_sum += lap, lap_sum2 += lap * lap, ++n;
    }
  }
  const double lap_mean = lap_sum / n;
  const std::array<float, 4> bands = dct_bands(lum);
  // The patch's own noise from its raw samples, from however many responses it has.
  const double noise = sigma_from_histogram(immerkaer_histogram(raw, ConstImageView{}), 1);
  return {static_cast<float>(mean[0]),
          static_cast<float>(stddev[0] * stddev[0]),
          static_cast<float>(grad / n),
          static_cast<float>(lap_sum2 / n - lap_mean * lap_mean),
          bands[0],
          bands[1],
          bands[2],
          bands[3],
          static_cast<float>(noise)};
}

Expected<ClassifierResult> classify_patches(const std::vector<std::vector<float>>& train_a,
                                            const std::vector<std::vector<float>>& train_b,
                                            const std::vector<std::vector<float>>& test_a,
                                            const std::vector<std::vector<float>>& test_b) {
  constexpr const char* kWhere = "eval::classify_patches(): ";
  if (train_a.empty() || train_b.empty() || test_a.empty() || test_b.empty())
    return make_error(kWhere, "every set needs samples, got ", train_a.size(), " and ", train_b.size(),
                      " to train, ", test_a.size(), " and ", test_b.size(), " to test");
  const std::size_t dims = train_a.front().size();
  for (const auto* set : {&train_a, &train_b, &test_a, &test_b}) {
    for (const std::vector<float>& v : *set) {
      if (v.size() != dims || dims == 0)
        return make_error(kWhere, "feature vectors of ", v.size(), " and ", dims,
                          " values (expected equal, > 0)");
      for (const float f : v)
        if (!std::isfinite(f)) return make_error(kWhere, "a feature value is not finite");
    }
  }
  cv::Mat train = to_mat(train_a, train_b), test = to_mat(test_a, test_b);
  const int n_train = train.rows, n_a = static_cast<int>(train_a.size());
  // Standardised by the training set (the trees do not care; logistic regression converges).
  for (int j = 0; j < train.cols; ++j) {
    cv::Scalar mean, stddev;
    cv::meanStdDev(train.col(j), mean, stddev);
    const double scale = stddev[0] > 0 ? 1.0 / stddev[0] : 1.0;
    for (cv::Mat* m : {&train, &test})
      for (int i = 0; i < m->rows; ++i)
        m->at<float>(i, j) = static_cast<float>((m->at<float>(i, j) - mean[0]) * scale);
  }
  cv::Mat labels_i(n_train, 1, CV_32S), labels_f(n_train, 1, CV_32F);
  for (int i = 0; i < n_train; ++i)
    labels_i.at<int>(i) = i < n_a ? 0 : 1, labels_f.at<float>(i) = i < n_a ? 0.f : 1.f;

  cv::theRNG().state = 0x5eed0fa0c0ffeeULL;  // deterministic forests
  std::vector<double> rt_a, rt_b, lr_a, lr_b;
  try {
    cv::Ptr<cv::ml::RTrees> rt = cv::ml::RTrees::create();
    rt->setMaxDepth(10);
    rt->setMinSampleCount(5);
    rt->setUseSurrogates(false);
    rt->setCalculateVarImportance(false);
    rt->setActiveVarCount(0);  // sqrt(features) per split
    rt->setTermCriteria(cv::TermCriteria(cv::TermCriteria::MAX_ITER, 200, 0));
    rt->train(cv::ml::TrainData::create(train, cv::ml::ROW_SAMPLE, labels_i));
    cv::Mat votes;  // row 0: the class labels; then per sample the votes per class
    rt->getVotes(test, votes, 0);
    const int col_b = votes.cols == 2 && votes.at<int>(0, 0) == 1 ? 0 : 1;
    for (int i = 0; i < test.rows; ++i) {
      const double total = votes.at<int>(i + 1, 0) + (votes.cols > 1 ? votes.at<int>(i + 1, 1) : 0);
      const double score = total > 0 ? votes.at<int>(i + 1, col_b) / total : 0.5;
      (i < static_cast<int>(test_a.size()) ? rt_a : rt_b).push_back(score);
    }

    cv::Ptr<cv::ml::LogisticRegression> lr = cv::ml::LogisticRegression::create();
    // OpenCV steps by learning_rate / n times the mean gradient: n / 2 is a step of 0.5, stable for
    // standardised features.
    lr->setLearningRate(0.5 * n_train);
    lr->setIterations(500);
    lr->setRegularization(cv::ml::LogisticRegression::REG_L2);
    lr->setTrainMethod(cv::ml::LogisticRegression::BATCH);
    lr->train(cv::ml::TrainData::create(train, cv::ml::ROW_SAMPLE, labels_f));
    cv::Mat theta;  // 1 x (1 + features): bias first; the log-odds of label 1 (b)
    lr->get_learnt_thetas().convertTo(theta, CV_64F);
    if (theta.rows != 1 || theta.cols != test.cols + 1)
      return make_error(kWhere, "logistic regression gave ", theta.rows, "x", theta.cols, " parameters");
    for (int i = 0; i < test.rows; ++i) {
      double z = theta.at<double>(0, 0);
      for (int j = 0; j < test.cols; ++j) z += theta.at<double>(0, j + 1) * test.at<float>(i, j);
      (i < static_cast<int>(test_a.size()) ? lr_a : lr_b).push_back(z);
    }
  } catch (const cv::Exception& e) {
    return make_error(kWhere, "OpenCV: ", e.what());
  }
  ClassifierResult out;
  out.auc_random_trees = auc(rt_a, rt_b);
  out.auc_logistic = auc(lr_a, lr_b);
  out.train = static_cast<std::size_t>(n_train);
  out.test = static_cast<std::size_t>(test.rows);
  return out;
}

double auc(const std::vector<double>& scores_a, const std::vector<double>& scores_b) {
  if (scores_a.empty() || scores_b.empty()) return kNaN;
  std::vector<std::pair<double, bool>> all;  // (score, is b)
  all.reserve(scores_a.size() + scores_b.size());
  for (const double s : scores_a) all.emplace_back(s, false);
  for (const double s : scores_b) all.emplace_back(s, true);
  for (const auto& [s, is_b] : all)
    if (std::isnan(s)) return kNaN;
  std::sort(all.begin(), all.end());
  // Sum of b's ranks (1-based), tied scores sharing their mean rank.
  double rank_sum_b = 0;
  for (std::size_t i = 0; i < all.size();) {
    std::size_t j = i;
    while (j < all.size() && all[j].first == all[i].first) ++j;
    const double mean_rank = 0.5 * static_cast<double>(i + 1 + j);
    for (std::size_t k = i; k < j; ++k)
      if (all[k].second) rank_sum_b += mean_rank;
    i = j;
  }
  const double na = static_cast<double>(scores_a.size()), nb = static_cast<double>(scores_b.size());
  return (rank_sum_b - nb * (nb + 1) / 2) / (na * nb);
}

}  // namespace augrig::eval
