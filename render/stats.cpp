#include "render/stats.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <future>
#include <limits>
#include <memory>
#include <mutex>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <system_error>

#include "core/csv.hpp"
#include "core/worker.hpp"

namespace augrig {
namespace {

double pct(std::int64_t part, std::int64_t whole) {
  return whole > 0 ? 100.0 * static_cast<double>(part) / static_cast<double>(whole) : 0.0;
}

void check_mask(const Image& m, const char* name) {
  if (m.format() != PixelFormat::kMono8)
    throw std::invalid_argument(std::string("compute_occlusion_stats: ") + name + " is not Mono8");
}

void check_depth(const DepthImage& d, const Image& m, const char* name) {
  if (d.width != m.width() || d.height != m.height() ||
      d.z_m.size() != static_cast<std::size_t>(d.width) * static_cast<std::size_t>(d.height))
    throw std::invalid_argument(std::string("compute_occlusion_stats: ") + name +
                                " does not match its mask's size");
}

// Cache of undistorted maps, keyed by every field of the CameraModel: undistort() is an iterative
// inversion, far too slow to run per receiver pixel per frame, while cameras change rarely.
struct CachedMap {
  CameraModel camera;
  std::shared_ptr<const std::vector<Eigen::Vector2f>> map;
};

bool same_camera(const CameraModel& a, const CameraModel& b) {
  return a.width_px == b.width_px && a.height_px == b.height_px && a.fx_px == b.fx_px && a.fy_px == b.fy_px &&
         a.cx_px == b.cx_px && a.cy_px == b.cy_px && a.distortion == b.distortion && a.coeffs == b.coeffs;
}

std::shared_ptr<const std::vector<Eigen::Vector2f>> cached_xy_map(const CameraModel& camera) {
  static std::mutex mutex;
  static std::vector<CachedMap> cache;  // most recently used last
  constexpr std::size_t kMaxEntries = 4;
  std::lock_guard<std::mutex> lock(mutex);
  for (std::size_t i = 0; i < cache.size(); ++i) {
    if (same_camera(cache[i].camera, camera)) {
      std::rotate(cache.begin() + static_cast<std::ptrdiff_t>(i),
                  cache.begin() + static_cast<std::ptrdiff_t>(i) + 1, cache.end());
      return cache.back().map;
    }
  }
  auto map = std::make_shared<const std::vector<Eigen::Vector2f>>(undistorted_xy_map(camera));
  if (cache.size() >= kMaxEntries) cache.erase(cache.begin());
  cache.push_back({camera, map});
  return map;
}

// The CSV / summary columns, in their fixed order, with how to read each from OcclusionStats.
struct Column {
  const char* name;
  bool is_int;
  double (*get)(const OcclusionStats&);
  // The field itself, for read_stats_csv(): an integer column's or a percentage's.
  std::int64_t OcclusionStats::*int_field;
  double OcclusionStats::*real_field;
};

#define AUGRIG_INT_COL(f)                                                                                   \
  Column {                                                                                                  \
#f, true, [](const OcclusionStats& s) { return static_cast<double>(s.f); }, &OcclusionStats::f, nullptr \
  }
#define AUGRIG_PCT_COL(f)                                                               \
  Column {                                                                              \
#f, false, [](const OcclusionStats& s) { return s.f; }, nullptr, &OcclusionStats::f \
  }
constexpr Column kColumns[] = {
    AUGRIG_INT_COL(t_ns),
    AUGRIG_INT_COL(receiver_px_left),
    AUGRIG_INT_COL(receiver_px_right),
    AUGRIG_INT_COL(boom_px_left),
    AUGRIG_INT_COL(boom_px_right),
    AUGRIG_INT_COL(boom_overlap_px),
    AUGRIG_PCT_COL(boom_overlap_pct_union),
    AUGRIG_INT_COL(occluded_px_left),
    AUGRIG_INT_COL(occluded_px_right),
    AUGRIG_PCT_COL(occluded_pct_left),
    AUGRIG_PCT_COL(occluded_pct_right),
    AUGRIG_INT_COL(stereo_both_px),
    AUGRIG_INT_COL(left_only_px),
    AUGRIG_INT_COL(right_only_px),
    AUGRIG_INT_COL(neither_px),
    AUGRIG_PCT_COL(receiver_pct_left),
    AUGRIG_PCT_COL(receiver_pct_right),
    AUGRIG_PCT_COL(boom_pct_left),
    AUGRIG_PCT_COL(boom_pct_right),
    // Appended later: files written before have exactly the columns above (kColumnsBeforeShadow).
    AUGRIG_INT_COL(shadow_px_left),
    AUGRIG_INT_COL(shadow_px_right),
    AUGRIG_PCT_COL(shadow_pct_left),
    AUGRIG_PCT_COL(shadow_pct_right),
};
// The stats.csv columns before the shadow columns were appended: read_stats_csv() still reads
// such files (their shadow fields 0).
constexpr std::size_t kColumnsBeforeShadow = 19;
static_assert(std::string_view(kColumns[kColumnsBeforeShadow - 1].name) == "boom_pct_right");
#undef AUGRIG_INT_COL
#undef AUGRIG_PCT_COL

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}
std::string fmt_int(std::int64_t v) {
  return std::to_string(v);
}

// Counts that need only the masks, in one pass over both. Bit tests (bits 0, 1 and 2), so other
// bits are ignored. SWAR: one byte lane per pixel, 16 pixels a step (two 64-bit words in an SSE2
// register), then 8, then a scalar tail; the lanes are summed every 255 steps before they could
// overflow (the build targets baseline x86-64, so no reliance on popcnt/AVX).
struct MaskCounts {
  std::int64_t rl = 0, rr = 0, bl = 0, br = 0, ov = 0, ol = 0, orr = 0, sl = 0, sr = 0;
};

constexpr std::uint64_t kLanes = 0x0101010101010101ull;

std::int64_t lane_sum(std::uint64_t v) {
  // Every lane <= 255: fold the eight lanes into 16-bit lanes, then add those.
  v = (v & 0x00FF00FF00FF00FFull) + ((v >> 8) & 0x00FF00FF00FF00FFull);
  return static_cast<std::int64_t>((v * 0x0001000100010001ull) >> 48);
}

void add(MaskCounts& a, const MaskCounts& b) {
  a.rl += b.rl, a.rr += b.rr, a.bl += b.bl, a.br += b.br, a.ov += b.ov, a.ol += b.ol, a.orr += b.orr;
  a.sl += b.sl, a.sr += b.sr;
}

// The SWAR lanes of one word type: std::uint64_t (8 pixels), or two of them in an SSE2 register
// (16 pixels, GCC/Clang vector extensions; baseline x86-64 has SSE2).
using U64x2 = std::uint64_t __attribute__((vector_size(16)));
std::int64_t lane_sum(U64x2 v) {
  return lane_sum(v[0]) + lane_sum(v[1]);
}

// Up to `words` words of W from a[x], b[x] on (each lane counts at most 255 of them), x moved past
// them, their counts added to c.
template <typename W>
void count_words(const std::uint8_t* a, const std::uint8_t* b, int& x, int words, MaskCounts& c) {
  W rl{}, rr{}, bl{}, br{}, ov{}, ol{}, orr{}, sl{}, sr{};
  for (int k = 0; k < words; ++k, x += static_cast<int>(sizeof(W))) {
    W va, vb;
    std::memcpy(&va, a + x, sizeof(W));
    std::memcpy(&vb, b + x, sizeof(W));
    const W ba = va & kLanes, bb = vb & kLanes;
    const W ra = (va >> 1) & kLanes, rb = (vb >> 1) & kLanes;
    bl += ba, br += bb, rl += ra, rr += rb;
    ov += ba & bb, ol += ba & ra, orr += bb & rb;
    sl += (va >> 2) & kLanes, sr += (vb >> 2) & kLanes;
  }
  c.rl += lane_sum(rl), c.rr += lane_sum(rr), c.bl += lane_sum(bl), c.br += lane_sum(br);
  c.ov += lane_sum(ov), c.ol += lane_sum(ol), c.orr += lane_sum(orr);
  c.sl += lane_sum(sl), c.sr += lane_sum(sr);
}

// Rows y0, y0 + step, ... below y1 and columns [x0, w) of the masks (columns from x0 rounded down
// to a word).
MaskCounts count_masks(const Image& ml, const Image& mr, int x0, int y0, int w, int y1, int step = 1) {
  MaskCounts c;
  for (int y = y0; y < y1; y += step) {
    const std::uint8_t* a = ml.row(y);
    const std::uint8_t* b = mr.row(y);
    int x = x0 & ~7;
    while (x + 16 <= w) count_words<U64x2>(a, b, x, std::min(255, (w - x) / 16), c);
    if (x + 8 <= w) count_words<std::uint64_t>(a, b, x, 1, c);
    for (; x < w; ++x) {
      const unsigned va = a[x], vb = b[x];
      c.bl += va & 1u, c.br += vb & 1u, c.rl += (va >> 1) & 1u, c.rr += (vb >> 1) & 1u;
      c.ov += va & vb & 1u, c.ol += va & (va >> 1) & 1u, c.orr += vb & (vb >> 1) & 1u;
      c.sl += (va >> 2) & 1u, c.sr += (vb >> 2) & 1u;
    }
  }
  return c;
}

// The counts that need only the masks, and the percentages from them.
void set_mask_counts(OcclusionStats& s, const MaskCounts& c, std::size_t n) {
  s.receiver_px_left = c.rl;
  s.receiver_px_right = c.rr;
  s.boom_px_left = c.bl;
  s.boom_px_right = c.br;
  s.boom_overlap_px = c.ov;
  s.occluded_px_left = c.ol;
  s.occluded_px_right = c.orr;
  s.shadow_px_left = c.sl;
  s.shadow_px_right = c.sr;
  const std::int64_t area = static_cast<std::int64_t>(n);
  s.boom_overlap_pct_union = pct(s.boom_overlap_px, s.boom_px_left + s.boom_px_right - s.boom_overlap_px);
  s.occluded_pct_left = pct(s.occluded_px_left, s.receiver_px_left);
  s.occluded_pct_right = pct(s.occluded_px_right, s.receiver_px_right);
  s.receiver_pct_left = pct(s.receiver_px_left, area);
  s.receiver_pct_right = pct(s.receiver_px_right, area);
  s.boom_pct_left = pct(s.boom_px_left, area);
  s.boom_pct_right = pct(s.boom_px_right, area);
  s.shadow_pct_left = pct(s.shadow_px_left, s.receiver_px_left);
  s.shadow_pct_right = pct(s.shadow_px_right, s.receiver_px_right);
}

// The stereo classes of the left receiver pixels, and the mask counts on the way, rows of one
// parity at a time (two threads take alternate rows, which shares the receiver between them
// wherever it lies in the box). The rig and the right lens are held as plain scalars: this runs
// once per receiver pixel.
class StereoClassifier {
 public:
  using Counts = std::array<std::int64_t, 5>;  // by StereoClass
  struct Pass {
    MaskCounts masks;
    Counts classes{};
  };

  // The content box [cx0, cx1) x [cy0, cy1) holds every mask bit.
  StereoClassifier(const Image& mask_left, const Image& mask_right, const DepthImage& depth_left,
                   const DepthImage& depth_right, const CameraModel& right, const Pose& T_right_left,
                   const StereoClassOptions& options, const std::vector<Eigen::Vector2f>& rays,
                   std::vector<std::uint8_t>* classes_out, int cx0, int cy0, int cx1, int cy1);
  // Every second row from `parity`: the mask counts, the class image and the class counts.
  Pass classify_rows(int parity) const;

 private:
  void classify_row(int y, Counts& counts) const;
  void visible_right(const int* xs, int n, const float* zl, const Eigen::Vector2f* ry, bool* vis) const;
  bool seen_at(double u, double v, double zr) const;

  const Image &mask_left_, &mask_right_;
  const DepthImage& depth_left_;
  const float* depth_r_;
  const CameraModel& right_;
  const std::vector<Eigen::Vector2f>& rays_;
  std::vector<std::uint8_t>* classes_out_;
  int w_, h_, cx0_, cy0_, cx1_, cy1_;
  double r00_, r01_, r02_, r10_, r11_, r12_, r20_, r21_, r22_, tx_, ty_, tz_;
  double u_max_, v_max_, tol_m_, tol_rel_;
  double right_max_radius_;  // once, not per pixel
  bool batched_, radtan_;
  double k1_, k2_, p1_, p2_, k3_, fx_, fy_, cxr_, cyr_;
};

StereoClassifier::StereoClassifier(const Image& mask_left, const Image& mask_right,
                                   const DepthImage& depth_left, const DepthImage& depth_right,
                                   const CameraModel& right, const Pose& T_right_left,
                                   const StereoClassOptions& options,
                                   const std::vector<Eigen::Vector2f>& rays,
                                   std::vector<std::uint8_t>* classes_out, int cx0, int cy0, int cx1, int cy1)
    : mask_left_(mask_left),
      mask_right_(mask_right),
      depth_left_(depth_left),
      depth_r_(depth_right.z_m.data()),
      right_(right),
      rays_(rays),
      classes_out_(classes_out),
      w_(mask_left.width()),
      h_(mask_left.height()),
      cx0_(cx0),
      cy0_(cy0),
      cx1_(cx1),
      cy1_(cy1) {
  const Eigen::Matrix3d R = T_right_left.R();
  r00_ = R(0, 0), r01_ = R(0, 1), r02_ = R(0, 2), r10_ = R(1, 0), r11_ = R(1, 1), r12_ = R(1, 2);
  r20_ = R(2, 0), r21_ = R(2, 1), r22_ = R(2, 2);
  tx_ = T_right_left.translation_m.x(), ty_ = T_right_left.translation_m.y(),
  tz_ = T_right_left.translation_m.z();
  u_max_ = w_ - 0.5, v_max_ = h_ - 0.5;
  tol_m_ = options.depth_tolerance_m, tol_rel_ = options.depth_tolerance_rel;
  right_max_radius_ = right.max_valid_radius();
  // Pinhole and radial-tangential lenses project two points at a time (visible_right()).
  batched_ = right.distortion == DistortionModel::kNone || right.distortion == DistortionModel::kRadTan;
  radtan_ = right.distortion == DistortionModel::kRadTan;
  k1_ = right.coeffs[0], k2_ = right.coeffs[1], p1_ = right.coeffs[2], p2_ = right.coeffs[3],
  k3_ = right.coeffs[4];
  fx_ = right.fx_px, fy_ = right.fy_px, cxr_ = right.cx_px, cyr_ = right.cy_px;
}

// Is the right camera's surface at its pixel (u, v), for a point at depth zr in its frame, that
// point: in the image, no boom in front of it, and the receiver's depth there zr?
inline bool StereoClassifier::seen_at(double u, double v, double zr) const {
  // Projections land on exact pixel centres in rectified rigs; float rays put them 1e-5 px off.
  // Snapping within this keeps the 2x2 neighbourhood from picking up a spurious extra column.
  constexpr double kSnapPx = 1e-3;
  const int w = w_, h = h_;
  if (!(u >= -0.5 && u < u_max_ && v >= -0.5 && v < v_max_)) return false;
  // Left/top pixel centre of the neighbourhood: floor(u + snap) by truncation (u + snap + 2 > 0;
  // std::floor is a libm call on baseline x86-64). fu in [-snap, 1 - snap) is u's offset from it.
  const int xa = static_cast<int>(u + kSnapPx + 2.0) - 2, ya = static_cast<int>(v + kSnapPx + 2.0) - 2;
  const double fu = u - xa, fv = v - ya;
  // Boom in front of the point in the right view: its bit at the nearest pixel centre.
  const int un = std::min(xa + (fu >= 0.5), w - 1), vn = std::min(ya + (fv >= 0.5), h - 1);
  if (mask_right_.row(std::max(vn, 0))[std::max(un, 0)] & kMaskBoom) return false;
  // Self-occlusion: is the right camera's nearest receiver surface around (u, v) this point?
  // Any of the (up to 2x2) surrounding pixel centres agreeing suffices: sub-pixel slack.
  const int x0 = std::max(xa, 0), x1 = std::min(fu > kSnapPx ? xa + 1 : xa, w - 1);
  const int y0 = std::max(ya, 0), y1 = std::min(fv > kSnapPx ? ya + 1 : ya, h - 1);
  const double tol = tol_m_ + tol_rel_ * zr;
  const float* depth_r = depth_r_;
  auto near = [&](int xx, int yy) {  // +inf (no receiver there) never passes
    return std::abs(static_cast<double>(depth_r[static_cast<std::size_t>(yy) * w + xx]) - zr) <= tol;
  };
  return near(x0, y0) || (x1 != x0 && near(x1, y0)) ||
         (y1 != y0 && (near(x0, y1) || (x1 != x0 && near(x1, y1))));
}

// For the left receiver points zl[x] * (x_n, y_n, 1) of pixels xs[0..n) of one row (rays ry),
// whether each is the surface the right camera sees, into vis[]. The points move into the right
// camera's frame two at a time (SSE2 doubles, GCC/Clang vector extensions), and so does their
// projection for a pinhole or radial-tangential lens, in the same operations and order as
// CameraModel::project() (the same answers); other lenses project one point at a time.
void StereoClassifier::visible_right(const int* xs, int n, const float* zl, const Eigen::Vector2f* ry,
                                     bool* vis) const {
  using F64x2 = double __attribute__((vector_size(16)));
  const double k1 = k1_, k2 = k2_, p1 = p1_, p2 = p2_, k3 = k3_;
  for (int i = 0; i < n; i += 2) {
    const int xa = xs[i], xb = xs[i + 1 < n ? i + 1 : i];
    const F64x2 z{zl[xa], zl[xb]};
    const F64x2 xn{ry[xa].x(), ry[xb].x()}, yn{ry[xa].y(), ry[xb].y()};
    const F64x2 px = z * xn, py = z * yn;
    const F64x2 X = r00_ * px + r01_ * py + r02_ * z + tx_, Y = r10_ * px + r11_ * py + r12_ * z + ty_,
                Z = r20_ * px + r21_ * py + r22_ * z + tz_;
    const F64x2 x = X / Z, y = Y / Z;
    F64x2 u = x, v = y;
    if (radtan_) {
      const F64x2 r2 = x * x + y * y;
      const F64x2 radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
      u = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
      v = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
    }
    u = fx_ * u + cxr_, v = fy_ * v + cyr_;
    for (int l = 0; l < 2 && i + l < n; ++l) {
      // No receiver (inf) or no ray (NaN) at the left pixel: not seen.
      bool ok = z[l] < std::numeric_limits<double>::infinity() && xn[l] == xn[l] && yn[l] == yn[l];
      double ul = u[l], vl = v[l];
      if (batched_) {  // project()'s guards
        ok = ok && Z[l] > 0.0 && (!radtan_ || std::sqrt(x[l] * x[l] + y[l] * y[l]) < right_max_radius_);
      } else if (ok) {
        const auto uv = right_.project(Eigen::Vector3d(X[l], Y[l], Z[l]), right_max_radius_);
        ok = uv.has_value();
        if (ok) ul = uv->x(), vl = uv->y();
      }
      vis[i + l] = ok && seen_at(ul, vl, Z[l]);
    }
  }
}

// Row y's left receiver pixels, a batch at a time: x, then whether the right camera sees the
// same point; their classes counted and written.
void StereoClassifier::classify_row(int y, Counts& counts) const {
  constexpr std::uint64_t kReceiverLanes = kLanes * kMaskReceiver;
  const int w = w_;
  const std::uint8_t* ml = mask_left_.row(y);
  const float* zl = depth_left_.z_m.data() + static_cast<std::size_t>(y) * w;
  const Eigen::Vector2f* ry = rays_.data() + static_cast<std::size_t>(y) * w;
  std::uint8_t* cls = classes_out_ ? classes_out_->data() + static_cast<std::size_t>(y) * w : nullptr;
  if (cls) std::memset(cls, static_cast<int>(StereoClass::kNone), static_cast<std::size_t>(w));
  constexpr int kBatch = 64;
  int xs[kBatch];
  bool vis[kBatch];
  int nb = 0;
  auto flush = [&] {
    visible_right(xs, nb, zl, ry, vis);
    for (int i = 0; i < nb; ++i) {
      const bool vis_left = !(ml[xs[i]] & kMaskBoom);
      const StereoClass c = vis_left ? (vis[i] ? StereoClass::kBoth : StereoClass::kLeftOnly)
                                     : (vis[i] ? StereoClass::kRightOnly : StereoClass::kNeither);
      ++counts[static_cast<int>(c)];
      if (cls) cls[xs[i]] = static_cast<std::uint8_t>(c);
    }
    nb = 0;
  };
  for (int x = cx0_ & ~7; x < cx1_; ++x) {
    if ((x & 7) == 0 && x + 8 <= cx1_) {  // skip 8 receiver-free pixels at once
      std::uint64_t v8;
      std::memcpy(&v8, ml + x, 8);
      if (!(v8 & kReceiverLanes)) {
        x += 7;
        continue;
      }
    }
    if (!(ml[x] & kMaskReceiver)) continue;
    xs[nb++] = x;
    if (nb == kBatch) flush();
  }
  flush();
}

StereoClassifier::Pass StereoClassifier::classify_rows(int parity) const {
  Pass pass;
  const int w = w_;
  if (classes_out_)  // kNone outside the content box
    for (int y = parity; y < h_; y += 2)
      if (y < cy0_ || y >= cy1_)
        std::memset(classes_out_->data() + static_cast<std::size_t>(y) * w,
                    static_cast<int>(StereoClass::kNone), static_cast<std::size_t>(w));
  const int y_begin = cy0_ + ((cy0_ & 1) != parity);
  add(pass.masks, count_masks(mask_left_, mask_right_, cx0_, y_begin, cx1_, cy1_, 2));
  if (pass.masks.rl == 0 && !classes_out_) return pass;  // no left receiver pixel in these rows
  for (int y = y_begin; y < cy1_; y += 2) classify_row(y, pass.classes);
  return pass;
}

// The stereo classes' inputs checked, the class image sized; the left camera's pixel rays (the
// caller's or the cached map).
const std::vector<Eigen::Vector2f>* class_inputs(const Image& mask_left, const Image& mask_right,
                                                 const DepthImage& depth_left, const DepthImage& depth_right,
                                                 const CameraModel& left, const CameraModel& right,
                                                 const StereoClassOptions& options,
                                                 std::vector<std::uint8_t>* classes_out,
                                                 std::shared_ptr<const std::vector<Eigen::Vector2f>>& owned) {
  check_depth(depth_left, mask_left, "receiver_depth_left");
  check_depth(depth_right, mask_right, "receiver_depth_right");
  if (left.width_px != mask_left.width() || left.height_px != mask_left.height() ||
      right.width_px != mask_right.width() || right.height_px != mask_right.height())
    throw std::invalid_argument("compute_occlusion_stats: camera size differs from its mask's size");
  const std::size_t n =
      static_cast<std::size_t>(mask_left.width()) * static_cast<std::size_t>(mask_left.height());
  // Every class is written by the two threads of compute_occlusion_stats(), row by row (kNone
  // outside the receiver).
  if (classes_out) classes_out->resize(n);
  const std::vector<Eigen::Vector2f>* rays = options.left_rays_xy;
  if (rays && rays->size() != n)
    throw std::invalid_argument("compute_occlusion_stats: left_rays_xy has the wrong size");
  if (!rays) {
    owned = cached_xy_map(left);
    rays = owned.get();
  }
  return rays;
}

}  // namespace

std::shared_ptr<const std::vector<Eigen::Vector2f>> shared_undistorted_xy_map(const CameraModel& camera) {
  return cached_xy_map(camera);
}

std::vector<Eigen::Vector2f> undistorted_xy_map(const CameraModel& camera) {
  const int w = camera.width_px, h = camera.height_px;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<Eigen::Vector2f> map(static_cast<std::size_t>(std::max(w, 0)) * std::max(h, 0));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const auto xy = camera.undistort(Eigen::Vector2d(x, y));
      map[static_cast<std::size_t>(y) * w + x] = xy ? xy->cast<float>() : Eigen::Vector2f(nan, nan);
    }
  return map;
}

OcclusionStats compute_occlusion_stats(TimestampNs t_ns, const Image& mask_left, const Image& mask_right,
                                       const DepthImage& receiver_depth_left,
                                       const DepthImage& receiver_depth_right, const CameraModel& left,
                                       const CameraModel& right, const Pose& T_right_left,
                                       const StereoClassOptions& options,
                                       std::vector<std::uint8_t>* classes_out) {
  check_mask(mask_left, "mask_left");
  check_mask(mask_right, "mask_right");
  if (mask_left.width() != mask_right.width() || mask_left.height() != mask_right.height())
    throw std::invalid_argument("compute_occlusion_stats: left and right masks differ in size");
  const int w = mask_left.width(), h = mask_left.height();
  const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  OcclusionStats s;
  s.t_ns = t_ns;
  s.width = w;
  s.height = h;
  // Only the content box can hold mask bits.
  const int cx0 = std::clamp(options.content_x0, 0, w), cx1 = std::clamp(options.content_x1, cx0, w);
  const int cy0 = std::clamp(options.content_y0, 0, h), cy1 = std::clamp(options.content_y1, cy0, h);
  if (!options.compute_classes) {
    // The masks alone: one pass over the content box on this thread.
    set_mask_counts(s, count_masks(mask_left, mask_right, cx0, cy0, cx1, cy1), n);
    if (classes_out) classes_out->clear();
    return s;
  }
  std::shared_ptr<const std::vector<Eigen::Vector2f>> owned;
  const std::vector<Eigen::Vector2f>* rays =
      class_inputs(mask_left, mask_right, receiver_depth_left, receiver_depth_right, left, right, options,
                   classes_out, owned);
  const StereoClassifier classifier(mask_left, mask_right, receiver_depth_left, receiver_depth_right, right,
                                    T_right_left, options, *rays, classes_out, cx0, cy0, cx1, cy1);
  // Even rows on the caller's worker, or a thread of their own; odd rows here.
  StereoClassifier::Pass even_pass;
  std::future<void> even;
  if (options.worker)
    options.worker->start([&] { even_pass = classifier.classify_rows(0); });
  else
    even = std::async(std::launch::async, [&] { even_pass = classifier.classify_rows(0); });
  const StereoClassifier::Pass odd = classifier.classify_rows(1);  // allocates nothing, throws nothing
  options.worker ? options.worker->wait() : even.get();
  MaskCounts masks = even_pass.masks;
  add(masks, odd.masks);
  set_mask_counts(s, masks, n);
  StereoClassifier::Counts counts = even_pass.classes;
  for (int k = 0; k < 5; ++k) counts[k] += odd.classes[k];
  s.stereo_both_px = counts[static_cast<int>(StereoClass::kBoth)];
  s.left_only_px = counts[static_cast<int>(StereoClass::kLeftOnly)];
  s.right_only_px = counts[static_cast<int>(StereoClass::kRightOnly)];
  s.neither_px = counts[static_cast<int>(StereoClass::kNeither)];
  return s;
}

void write_stats_csv_header(std::ostream& out) {
  bool first = true;
  for (const Column& c : kColumns) {
    if (!first) out << ',';
    out << c.name;
    first = false;
  }
  out << '\n';
}

void write_stats_csv_row(std::ostream& out, const OcclusionStats& s) {
  bool first = true;
  for (const Column& c : kColumns) {
    if (!first) out << ',';
    // Integers straight from the int64 fields (t_ns would lose digits through double).
    if (c.is_int)
      out << (std::string_view(c.name) == "t_ns" ? fmt_int(s.t_ns)
                                                 : fmt_int(static_cast<std::int64_t>(c.get(s))));
    else
      out << fmt("%.4f", c.get(s));
    first = false;
  }
  out << '\n';
}

Expected<std::vector<OcclusionStats>> read_stats_csv(const std::string& path) {
  const std::string where = "render::read_stats_csv(): " + path;
  std::ifstream in(path, std::ios::binary);
  if (!in) return make_error(where, ": cannot read the file");
  std::string line;
  if (!std::getline(in, line))
    return make_error(where, ": empty, expected the header line (t_ns,receiver_px_left,...)");
  // The whole column list, or exactly the columns before the shadow columns (an older file): a
  // header as long as the older one is checked against that, any other against the whole list.
  const std::vector<std::string_view> header = split_csv_line(line);
  const std::size_t n = header.size() == kColumnsBeforeShadow ? kColumnsBeforeShadow : std::size(kColumns);
  std::vector<std::string_view> names;
  for (std::size_t i = 0; i < n; ++i) names.emplace_back(kColumns[i].name);
  if (auto bad = check_csv_header(header, names, where,
                                  "a stats.csv header (docs/STATISTICS.md: all its columns, or the first 19 "
                                  "of a file written before the shadow columns)"))
    return *bad;
  std::vector<OcclusionStats> rows;
  for (std::size_t line_no = 2; std::getline(in, line); ++line_no) {
    const std::vector<std::string_view> cells = split_csv_line(line);
    if (is_blank_csv_line(cells)) continue;  // the file's end
    if (auto bad = check_csv_field_count(cells, n, where, line_no)) return *bad;
    OcclusionStats s;  // width and height are not in the file: 0; nor in an older file the shadow's
    for (std::size_t i = 0; i < n; ++i) {
      const Column& c = kColumns[i];
      const char* b = cells[i].data();
      const char* e = b + cells[i].size();
      std::from_chars_result r{b, std::errc::invalid_argument};
      if (c.is_int)
        r = std::from_chars(b, e, s.*c.int_field);
      else if (b != e && *b != '+')
        r = std::from_chars(b, e, s.*c.real_field);
      if (b == e || r.ec != std::errc() || r.ptr != e)
        return make_error(where, ":", line_no, ":", c.name, ": expected ",
                          c.is_int ? "an integer" : "a number", ", got '", std::string(cells[i]), "'");
    }
    rows.push_back(s);
  }
  if (in.bad()) return make_error(where, ": read failed");
  return rows;
}

std::string format_table1(const OcclusionStats& s, const std::string& title) {
  std::ostringstream o;
  const std::int64_t area = s.width * s.height;
  const std::int64_t boom_union = s.boom_px_left + s.boom_px_right - s.boom_overlap_px;
  o << title << '\n';
  o << "Image " << s.width << " x " << s.height << " = " << area
    << " pixels. Counts are pixels (the seed paper counted RGB channel values, 3 per pixel).\n";
  char line[256];
  std::snprintf(line, sizeof line, "%-36s %12s %10s  %s\n", "", "Pixels", "Percent", "Percent of");
  o << line;
  auto row = [&](const char* name, std::int64_t px, double p, const std::string& of) {
    std::snprintf(line, sizeof line, "%-36s %12lld %9.2f%%  %s\n", name, static_cast<long long>(px), p,
                  of.c_str());
    o << line;
  };
  const std::string whole = "whole image (" + std::to_string(area) + " px)";
  row("Receiver left", s.receiver_px_left, s.receiver_pct_left, whole);
  row("Receiver right", s.receiver_px_right, s.receiver_pct_right, whole);
  row("Boom left", s.boom_px_left, s.boom_pct_left, whole);
  row("Boom right", s.boom_px_right, s.boom_pct_right, whole);
  row("Boom overlap (both images)", s.boom_overlap_px, s.boom_overlap_pct_union,
      "boom pixels, left or right (" + std::to_string(boom_union) + " px)");
  row("Boom occlusion left", s.occluded_px_left, s.occluded_pct_left,
      "receiver pixels left (" + std::to_string(s.receiver_px_left) + " px)");
  row("Boom occlusion right", s.occluded_px_right, s.occluded_pct_right,
      "receiver pixels right (" + std::to_string(s.receiver_px_right) + " px)");
  row("Boom shadow on receiver left", s.shadow_px_left, s.shadow_pct_left,
      "receiver pixels left (" + std::to_string(s.receiver_px_left) + " px)");
  row("Boom shadow on receiver right", s.shadow_px_right, s.shadow_pct_right,
      "receiver pixels right (" + std::to_string(s.receiver_px_right) + " px)");
  const std::string recv_left = "receiver pixels left (" + std::to_string(s.receiver_px_left) + " px)";
  row("Stereo: visible to both", s.stereo_both_px, pct(s.stereo_both_px, s.receiver_px_left), recv_left);
  row("Stereo: left only", s.left_only_px, pct(s.left_only_px, s.receiver_px_left), recv_left);
  row("Stereo: right only", s.right_only_px, pct(s.right_only_px, s.receiver_px_left), recv_left);
  row("Stereo: neither", s.neither_px, pct(s.neither_px, s.receiver_px_left), recv_left);
  return o.str();
}

RunSummary::RunSummary() {
  const std::size_t n = std::size(kColumns);
  sum_.assign(n, 0.0);
  lo_.assign(n, std::numeric_limits<double>::infinity());
  hi_.assign(n, -std::numeric_limits<double>::infinity());
}

void RunSummary::add(const OcclusionStats& s) {
  ++frames_;
  for (std::size_t i = 0; i < std::size(kColumns); ++i) {
    // t_ns as a double would lose nanoseconds: its min and max are kept apart below.
    const double v = std::string_view(kColumns[i].name) == "t_ns" ? 0.0 : kColumns[i].get(s);
    sum_[i] += v;
    lo_[i] = std::min(lo_[i], v);
    hi_[i] = std::max(hi_[i], v);
  }
  t_lo_ = frames_ == 1 ? s.t_ns : std::min(t_lo_, s.t_ns);
  t_hi_ = frames_ == 1 ? s.t_ns : std::max(t_hi_, s.t_ns);
}

std::string RunSummary::format() const {
  std::ostringstream o;
  o << "Run summary over " << frames_ << " stereo frame(s); counts are pixels.\n";
  if (!frames_) return o.str();
  char line[256];
  std::snprintf(line, sizeof line, "%-24s %16s %16s %16s\n", "column", "mean", "min", "max");
  o << line;
  for (std::size_t i = 0; i < std::size(kColumns); ++i) {
    const Column& c = kColumns[i];
    if (std::string_view(c.name) == "t_ns") {
      std::snprintf(line, sizeof line, "%-24s %16s %16lld %16lld\n", c.name, "-",
                    static_cast<long long>(t_lo_), static_cast<long long>(t_hi_));
    } else {
      const double mean = sum_[i] / static_cast<double>(frames_);
      if (c.is_int)
        std::snprintf(line, sizeof line, "%-24s %16.1f %16.0f %16.0f\n", c.name, mean, lo_[i], hi_[i]);
      else
        std::snprintf(line, sizeof line, "%-24s %16.4f %16.4f %16.4f\n", c.name, mean, lo_[i], hi_[i]);
    }
    o << line;
  }
  return o.str();
}

std::string format_run_summary(const std::vector<OcclusionStats>& frames) {
  RunSummary r;
  for (const OcclusionStats& f : frames) r.add(f);
  return r.format();
}

}  // namespace augrig
