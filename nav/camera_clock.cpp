#include "nav/camera_clock.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>
#include <utility>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "nav/geodesy.hpp"
#include "nav/ins.hpp"
#include "nav/logs.hpp"
#include "render/image_file.hpp"

namespace augrig::nav {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

Eigen::Vector3d log_so3(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

// Rotation R with R a_i ~ b_i (Kabsch: SVD of sum b a^T, no reflection).
Eigen::Matrix3d kabsch(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                       const std::vector<int>& use) {
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (int i : use) H += b[static_cast<std::size_t>(i)] * a[static_cast<std::size_t>(i)].transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  return svd.matrixU() * D * svd.matrixV().transpose();
}

// Gray 8-bit copy of an image of core/image.hpp's formats (Bayer by OpenCV's names, which count
// the pattern from the second row and column: our RG is OpenCV's BG).
Expected<cv::Mat> to_gray(ConstImageView v) {
  const cv::Mat src(v.height, v.width, CV_8UC(bytes_per_pixel(v.format)),
                    const_cast<std::uint8_t*>(v.data), v.stride_bytes);
  cv::Mat gray;
  switch (v.format) {
    case PixelFormat::kMono8: gray = src.clone(); break;
    case PixelFormat::kRGB8: cv::cvtColor(src, gray, cv::COLOR_RGB2GRAY); break;
    case PixelFormat::kRGBA8: cv::cvtColor(src, gray, cv::COLOR_RGBA2GRAY); break;
    case PixelFormat::kBayerRG8: cv::cvtColor(src, gray, cv::COLOR_BayerBG2GRAY); break;
    case PixelFormat::kBayerGR8: cv::cvtColor(src, gray, cv::COLOR_BayerGB2GRAY); break;
    case PixelFormat::kBayerGB8: cv::cvtColor(src, gray, cv::COLOR_BayerGR2GRAY); break;
    case PixelFormat::kBayerBG8: cv::cvtColor(src, gray, cv::COLOR_BayerRG2GRAY); break;
    default:
      return make_error("nav::CameraRotationTracker::add_frame(): pixel format ", std::string(to_string(v.format)),
                        " is not supported (expected 8-bit mono, RGB, RGBA or Bayer)");
  }
  return gray;
}

double median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

double CameraClockEstimate::offset_at_s(TimestampNs t_camera_ns) const {
  const double drift = drift_observable ? drift_ppm * 1e-6 : 0.0;
  return offset_s + drift * ns_to_s(t_camera_ns - reference_camera_ns);
}

// ---- tracker -----------------------------------------------------------------------------------

struct CameraRotationTracker::Impl {
  struct Track {
    cv::Point2f px;
    Eigen::Vector3d ray;                                 // unit ray in the camera frame of the last frame
    Eigen::Vector3d misfit = Eigen::Vector3d::Zero();    // exponentially weighted misfit
    bool flagged = false;                                // moves unlike the ground: never used again
  };

  CameraModel model;
  Eigen::Matrix3d R_body_cam;
  CameraClockOptions opt;
  GroundMotionFunction ground;
  AngularRateFunction omega;
  double focal_px = 1;
  cv::Size window;

  std::vector<cv::Mat> prev_pyramid;
  TimestampNs prev_t_ns = 0;
  bool have_prev = false;
  std::vector<Track> tracks;
  std::vector<FrameRotation> rotations;
  int frames = 0;
  std::mt19937 rng{20u};

  void replenish(const cv::Mat& gray);
  // The rays of the previous frame as seen from the current camera position (parallax removed).
  void remove_parallax(TimestampNs t0_ns, TimestampNs t1_ns, std::vector<Eigen::Vector3d>& rays) const;
  void track(const cv::Mat& gray, const std::vector<cv::Mat>& pyramid, TimestampNs t_ns);

  // track()'s parts. The tracks followed into the current frame (forward-backward checked), with
  // their new rays.
  void follow(const cv::Mat& gray, const std::vector<cv::Mat>& pyramid, std::vector<Track>& kept,
              std::vector<Eigen::Vector3d>& new_rays) const;
  // The nav rate's rotation over the interval ending at t_ns and how far a hypothesis may lie from
  // it (none without a nav rate).
  struct NavGate {
    std::optional<Eigen::Matrix3d> R21;
    double rad = 0;
    bool admits(const Eigen::Matrix3d& R) const {
      return !R21 || log_so3(R * R21->transpose()).norm() <= rad;
    }
  };
  NavGate nav_gate(TimestampNs t_ns) const;
  // The rotation R21 (r2 = R21 r1) of the candidate rays: MSAC, then refined on its inliers.
  bool fit_rotation(const std::vector<Eigen::Vector3d>& c1, const std::vector<Eigen::Vector3d>& c2,
                    double thr_rad, const NavGate& gate, Eigen::Matrix3d& R21, std::vector<int>& inliers);
  // Each track's exponentially weighted misfit, flagged above 4 sigma and back below half that.
  void follow_misfits(std::vector<Track>& kept, const std::vector<Eigen::Vector3d>& r1,
                      const std::vector<Eigen::Vector3d>& r2, const Eigen::Matrix3d& R21, double sigma,
                      double thr_rad) const;
};

void CameraRotationTracker::Impl::replenish(const cv::Mat& gray) {
  int active = 0;
  for (const Track& t : tracks) active += t.flagged ? 0 : 1;
  // Below 80 % of the target only: detection is the tracker's dearest step.
  if (active >= opt.max_features * 4 / 5) return;
  cv::Mat mask(gray.size(), CV_8UC1, cv::Scalar(255));
  // Every track, flagged ones too, keeps its neighbourhood: the receiver stays occupied by its
  // flagged tracks rather than giving fresh features every frame.
  for (const Track& t : tracks)
    cv::circle(mask, t.px, static_cast<int>(opt.min_distance_px), cv::Scalar(0), -1);
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(gray, corners, opt.max_features - active, opt.quality_level, opt.min_distance_px, mask, 7);
  for (const cv::Point2f& c : corners) {
    const auto ray = model.ray(Eigen::Vector2d(c.x, c.y));
    if (!ray) continue;
    tracks.push_back({c, *ray});
  }
}

void CameraRotationTracker::Impl::remove_parallax(TimestampNs t0_ns, TimestampNs t1_ns,
                                                  std::vector<Eigen::Vector3d>& rays) const {
  if (!ground) return;
  const TimestampNs prior_ns = s_to_ns(opt.prior_offset_s);
  const auto g0 = ground(t0_ns - prior_ns);
  const auto g1 = ground(t1_ns - prior_ns);
  if (!g0 || !g1 || !(g0->height_m > 0)) return;
  const Eigen::Vector3d dp_ned_m = 0.5 * (g0->v_ned_mps + g1->v_ned_mps) * ns_to_s(t1_ns - t0_ns);
  const Eigen::Matrix3d R_ned_cam = g0->R_ned_body * R_body_cam;
  for (Eigen::Vector3d& r : rays) {
    const Eigen::Vector3d d = R_ned_cam * r;
    if (!(d.z() > 1e-6)) continue;  // sky: at infinity, no parallax
    const Eigen::Vector3d p_ned_m = d * (g0->height_m / d.z());
    r = (R_ned_cam.transpose() * (p_ned_m - dp_ned_m)).normalized();
  }
}

void CameraRotationTracker::Impl::follow(const cv::Mat& gray, const std::vector<cv::Mat>& pyramid,
                                         std::vector<Track>& kept,
                                         std::vector<Eigen::Vector3d>& new_rays) const {
  std::vector<cv::Point2f> p0, p1, p0_back;
  p0.reserve(tracks.size());
  for (const Track& t : tracks) p0.push_back(t.px);
  std::vector<unsigned char> st1, st0;
  std::vector<float> err;
  const cv::TermCriteria term(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01);
  cv::calcOpticalFlowPyrLK(prev_pyramid, pyramid, p0, p1, st1, err, window, opt.lk_levels, term);
  p0_back = p0;
  cv::calcOpticalFlowPyrLK(pyramid, prev_pyramid, p1, p0_back, st0, err, window, opt.lk_levels, term,
                           cv::OPTFLOW_USE_INITIAL_FLOW);
  const double fb2 = opt.max_forward_backward_px * opt.max_forward_backward_px;
  kept.reserve(tracks.size());
  for (std::size_t i = 0; i < tracks.size(); ++i) {
    if (!st1[i] || !st0[i]) continue;
    const cv::Point2f d = p0_back[i] - p0[i];
    if (d.x * d.x + d.y * d.y > fb2) continue;
    if (p1[i].x < 0 || p1[i].y < 0 || p1[i].x > gray.cols - 1 || p1[i].y > gray.rows - 1) continue;
    const auto ray = model.ray(Eigen::Vector2d(p1[i].x, p1[i].y));
    if (!ray) continue;
    Track t = tracks[i];
    t.px = p1[i];
    kept.push_back(t);
    new_rays.push_back(*ray);
    kept.back().ray = tracks[i].ray;  // still the previous frame's until the fit
  }
}

CameraRotationTracker::Impl::NavGate CameraRotationTracker::Impl::nav_gate(TimestampNs t_ns) const {
  NavGate g;
  if (!omega) return g;
  auto predicted = [&](double shift_s) -> std::optional<Eigen::Vector3d> {
    const TimestampNs s_ns = s_to_ns(opt.prior_offset_s + shift_s);
    const TimestampNs a = prev_t_ns - s_ns, b = t_ns - s_ns;
    const auto wa = omega(a), wm = omega(a + (b - a) / 2), wb = omega(b);
    if (!wa || !wm || !wb) return std::nullopt;
    return Eigen::Vector3d(R_body_cam.transpose() * ((*wa + 4 * *wm + *wb) / 6.0) * ns_to_s(b - a));
  };
  const auto th0 = predicted(0), thm = predicted(-opt.search_s), thp = predicted(opt.search_s);
  if (th0 && thm && thp) {
    // r2 = R21 r1 with R_cam0_cam1 = Exp(theta) = R21^T.
    g.R21 = Eigen::AngleAxisd(th0->norm(), th0->norm() > 0 ? th0->normalized() : Eigen::Vector3d::UnitX())
                .toRotationMatrix()
                .transpose();
    g.rad = std::max((*thm - *th0).norm(), (*thp - *th0).norm()) + opt.nav_gate_px / focal_px;
  }
  return g;
}

bool CameraRotationTracker::Impl::fit_rotation(const std::vector<Eigen::Vector3d>& c1,
                                               const std::vector<Eigen::Vector3d>& c2, double thr_rad,
                                               const NavGate& gate, Eigen::Matrix3d& R21,
                                               std::vector<int>& inliers) {
  const int n = static_cast<int>(c1.size());
  std::uniform_int_distribution<int> pick(0, n - 1);
  // MSAC: the truncated squared misfit, so a hypothesis between two motions (ground and the
  // receiver, each within the threshold of it) loses to one that fits the ground tightly.
  const double thr2 = thr_rad * thr_rad;
  auto msac = [&](const Eigen::Matrix3d& R) {
    double cost = 0;
    for (int i = 0; i < n; ++i)
      cost += std::min((c2[static_cast<std::size_t>(i)] - R * c1[static_cast<std::size_t>(i)]).squaredNorm(),
                       thr2);
    return cost;
  };
  double best = std::numeric_limits<double>::infinity();
  Eigen::Matrix3d best_R = Eigen::Matrix3d::Identity();
  for (int it = 0; it < opt.ransac_iterations; ++it) {
    const int a = pick(rng);
    int b = pick(rng);
    if (b == a) b = (a + 1) % n;
    // Two nearly parallel rays do not fix a rotation.
    if (c1[static_cast<std::size_t>(a)].cross(c1[static_cast<std::size_t>(b)]).norm() < 20 * thr_rad)
      continue;
    const Eigen::Matrix3d R = kabsch(c1, c2, {a, b});
    if (!gate.admits(R)) continue;
    const double c = msac(R);
    if (c < best) {
      best = c;
      best_R = R;
    }
  }
  if (!std::isfinite(best)) return false;
  R21 = best_R;
  // Refine on the inliers, the threshold tightened to 3 sigma of their own misfit.
  double thr = thr_rad;
  for (int round = 0; round < 4; ++round) {
    inliers.clear();
    std::vector<double> res;
    for (int i = 0; i < n; ++i) {
      const double e = (c2[static_cast<std::size_t>(i)] - R21 * c1[static_cast<std::size_t>(i)]).norm();
      if (e < thr) {
        inliers.push_back(i);
        res.push_back(e);
      }
    }
    if (static_cast<int>(inliers.size()) < opt.min_inliers) break;
    R21 = kabsch(c1, c2, inliers);
    thr = std::clamp(3.0 * median(res) / 1.18, 0.1 / focal_px, thr_rad);
  }
  return static_cast<int>(inliers.size()) >= opt.min_inliers && gate.admits(R21);
}

void CameraRotationTracker::Impl::follow_misfits(std::vector<Track>& kept,
                                                 const std::vector<Eigen::Vector3d>& r1,
                                                 const std::vector<Eigen::Vector3d>& r2,
                                                 const Eigen::Matrix3d& R21, double sigma,
                                                 double thr_rad) const {
  const double lambda = opt.track_memory;
  const double limit = 4.0 * sigma / std::sqrt(1.0 - lambda * lambda);
  for (std::size_t i = 0; i < kept.size(); ++i) {
    Track& t = kept[i];
    const Eigen::Vector3d res = r2[i] - R21 * r1[i];
    t.misfit = lambda * (R21 * t.misfit) + res;
    if (!t.flagged && (t.misfit.norm() > limit || res.norm() > 3 * thr_rad))
      t.flagged = true;
    else if (t.flagged && t.misfit.norm() < 0.5 * limit && res.norm() < thr_rad)
      t.flagged = false;
  }
}

void CameraRotationTracker::Impl::track(const cv::Mat& gray, const std::vector<cv::Mat>& pyramid,
                                        TimestampNs t_ns) {
  std::vector<Track> kept;
  std::vector<Eigen::Vector3d> new_rays;
  follow(gray, pyramid, kept, new_rays);
  // Every kept track's rays: r1 previous (parallax removed), r2 current. The rotation is fitted to
  // the unflagged ones; the misfit is followed for all, so a flagged track can come back.
  const int n_all = static_cast<int>(kept.size());
  std::vector<Eigen::Vector3d> r1, r2;
  r1.reserve(kept.size());
  for (const Track& t : kept) r1.push_back(t.ray);
  r2 = new_rays;
  remove_parallax(prev_t_ns, t_ns, r1);
  std::vector<int> cand;
  for (int i = 0; i < n_all; ++i)
    if (!kept[static_cast<std::size_t>(i)].flagged) cand.push_back(i);
  const int n = static_cast<int>(cand.size());
  const double thr_rad = opt.inlier_px / focal_px;
  // The nav rate's rotation over the interval, at the prior offset and at +-search_s: a hypothesis
  // must lie within what the offset's uncertainty allows (plus a floor), so that a large receiver
  // moving with the tanker cannot win the consensus over the ground.
  const NavGate gate = nav_gate(t_ns);
  Eigen::Matrix3d R21 = Eigen::Matrix3d::Identity();  // r2 = R21 r1
  bool solved = false;
  std::vector<int> inliers;  // indices into cand
  std::vector<Eigen::Vector3d> c1, c2;
  for (int k = 0; k < n; ++k) {
    c1.push_back(r1[static_cast<std::size_t>(cand[static_cast<std::size_t>(k)])]);
    c2.push_back(r2[static_cast<std::size_t>(cand[static_cast<std::size_t>(k)])]);
  }
  if (n >= std::max(opt.min_inliers, 3)) solved = fit_rotation(c1, c2, thr_rad, gate, R21, inliers);
  if (solved) {
    double ss = 0;
    for (int k : inliers)
      ss += (c2[static_cast<std::size_t>(k)] - R21 * c1[static_cast<std::size_t>(k)]).squaredNorm();
    FrameRotation fr;
    fr.t0_camera_ns = prev_t_ns;
    fr.t1_camera_ns = t_ns;
    fr.rotvec_cam_rad = log_so3(R21.transpose());  // R_cam0_cam1 = R21^T
    fr.inliers = static_cast<int>(inliers.size());
    fr.features = n;
    fr.rms_rad = std::sqrt(ss / static_cast<double>(inliers.size()));
    rotations.push_back(fr);
    // Noise of one misfit, robustly, from the candidates (a 2-D misfit's median is 1.18 sigma).
    std::vector<double> m;
    m.reserve(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k)
      m.push_back((c2[static_cast<std::size_t>(k)] - R21 * c1[static_cast<std::size_t>(k)]).norm());
    follow_misfits(kept, r1, r2, R21, std::max(median(m) / 1.18, 0.02 / focal_px), thr_rad);
  }
  for (std::size_t i = 0; i < kept.size(); ++i) kept[i].ray = new_rays[i];
  tracks = std::move(kept);
}

CameraRotationTracker::CameraRotationTracker(const CameraModel& model, const Eigen::Matrix3d& R_cam_body,
                                             const CameraClockOptions& options, GroundMotionFunction ground,
                                             AngularRateFunction omega_body)
    : impl_(std::make_unique<Impl>()) {
  impl_->omega = std::move(omega_body);
  impl_->model = model;
  impl_->R_body_cam = R_cam_body.transpose();
  impl_->opt = options;
  impl_->ground = std::move(ground);
  impl_->focal_px = std::max(0.5 * (model.fx_px + model.fy_px), 1.0);
  impl_->window = cv::Size(options.lk_window_px, options.lk_window_px);
}

CameraRotationTracker::~CameraRotationTracker() = default;

const std::vector<FrameRotation>& CameraRotationTracker::rotations() const {
  return impl_->rotations;
}

std::vector<FrameRotation> CameraRotationTracker::take_rotations() {
  std::vector<FrameRotation> out;
  out.swap(impl_->rotations);
  return out;
}

int CameraRotationTracker::frames() const {
  return impl_->frames;
}

Status CameraRotationTracker::add_frame(TimestampNs t_camera_ns, ConstImageView image) {
  Impl& s = *impl_;
  if (image.width != s.model.width_px || image.height != s.model.height_px) {
    return make_error("nav::CameraRotationTracker::add_frame(): image is ", image.width, "x", image.height,
                      ", the camera model ", s.model.width_px, "x", s.model.height_px);
  }
  if (s.have_prev && t_camera_ns <= s.prev_t_ns) {
    return make_error("nav::CameraRotationTracker::add_frame(): frame at ", t_camera_ns,
                      " ns is not after the previous one (", s.prev_t_ns, " ns)");
  }
  auto gray = to_gray(image);
  if (!gray) return gray.error();
  std::vector<cv::Mat> pyramid;
  cv::buildOpticalFlowPyramid(*gray, pyramid, s.window, s.opt.lk_levels);
  ++s.frames;
  if (s.have_prev && ns_to_s(t_camera_ns - s.prev_t_ns) <= s.opt.max_interval_s && !s.tracks.empty()) {
    s.track(*gray, pyramid, t_camera_ns);
  } else {
    s.tracks.clear();  // a gap: start afresh
  }
  s.replenish(*gray);
  s.prev_pyramid = std::move(pyramid);
  s.prev_t_ns = t_camera_ns;
  s.have_prev = true;
  return {};
}

// ---- fit ---------------------------------------------------------------------------------------

namespace {

// The angular rate on a uniform grid, with its running integral (exact for the piecewise-linear
// rate between the samples), so that any interval's mean rate costs two look-ups.
class RateGrid {
 public:
  RateGrid(const AngularRateFunction& omega, TimestampNs t_ref_ns, double u0_s, double u1_s, double step_s)
      : u0_(u0_s), h_(step_s) {
    const auto n = static_cast<std::size_t>(std::ceil((u1_s - u0_s) / step_s)) + 2;
    w_.resize(n);
    phi_.resize(n);
    bad_.assign(n + 1, 0);
    for (std::size_t i = 0; i < n; ++i) {
      const auto w = omega(t_ref_ns + s_to_ns(u0_ + static_cast<double>(i) * h_));
      const bool ok = w && w->allFinite();
      w_[i] = ok ? *w : Eigen::Vector3d::Zero();
      bad_[i + 1] = bad_[i] + (ok ? 0 : 1);
    }
    phi_[0].setZero();
    for (std::size_t i = 1; i < n; ++i) phi_[i] = phi_[i - 1] + 0.5 * h_ * (w_[i - 1] + w_[i]);
  }
  // Whether every sample that [a, b] uses is known.
  bool valid(double a_s, double b_s) const {
    const double fa = (a_s - u0_) / h_, fb = (b_s - u0_) / h_;
    if (!(fa >= 0) || !(fb + 1 < static_cast<double>(w_.size()))) return false;
    const auto ia = static_cast<std::size_t>(fa), ib = static_cast<std::size_t>(fb) + 1;
    return bad_[ib + 1] - bad_[ia] == 0;
  }
  Eigen::Vector3d integral(double u_s) const {
    const double f = (u_s - u0_) / h_;
    const auto i = std::min(static_cast<std::size_t>(std::max(f, 0.0)), w_.size() - 2);
    const double x = u_s - (u0_ + static_cast<double>(i) * h_);
    return phi_[i] + x * w_[i] + (0.5 * x * x / h_) * (w_[i + 1] - w_[i]);
  }
  Eigen::Vector3d mean(double a_s, double b_s) const { return (integral(b_s) - integral(a_s)) / (b_s - a_s); }

 private:
  double u0_, h_;
  std::vector<Eigen::Vector3d> w_, phi_;
  std::vector<int> bad_;
};

struct Interval {
  double t0_s, t1_s;  // camera time relative to the reference
  Eigen::Vector3d c;  // measured camera rate, rad/s
};

}  // namespace

namespace {

// What one fit over a set of intervals gives.
struct FitOutcome {
  bool observable = false;
  std::string reason;
  bool with_drift = false;
  double offset_s = kNaN, offset_sigma_s = kNaN;
  double drift = kNaN, drift_sigma = kNaN;  // s/s, where with_drift
  double scale = 1;
  Eigen::Vector3d bias = Eigen::Vector3d::Zero();
  double rms = 0, explained = 0;
  std::vector<double> coarse_cost;
  // Per interval: its part of the offset's information, the other parameters profiled out (they
  // add up to 1 / var(offset) of the residuals' covariance, up to its scale).
  std::vector<double> offset_information;
  // Per interval: the parameters' change for a unit change of that interval's clock.
  std::vector<Eigen::VectorXd> lever;
};

enum class DriftModel { kTry, kFit, kNone };  // kTry: fitted, and dropped where not observable

// One Gauss-Newton fit's working state: its parameters' layout, the robust weights, the residuals
// and their Jacobians. Parameters: offset, [drift], [scale], bias (3).
struct GaussNewton {
  bool with_drift = false;
  int P = 0, i_scale = 1, i_bias = 0;
  std::vector<double> w;
  std::vector<Eigen::Vector3d> r;
  std::vector<Eigen::Matrix<double, 3, Eigen::Dynamic>> J;
};

// The fit over one set of intervals. Model: c_k = scale R_cam_body mean(omega over [t0 - d_k,
// t1 - d_k]) + bias, d_k = offset + drift tmid_k; a drift not fitted is fixed_drift.
class IntervalFit {
 public:
  IntervalFit(const std::vector<Interval>& iv, const RateGrid& grid, const Eigen::Matrix3d& R_cam_body,
              const CameraClockOptions& opt, int hac_lag, double fixed_drift)
      : iv_(iv),
        grid_(grid),
        R_(R_cam_body),
        opt_(opt),
        hac_lag_(hac_lag),
        fixed_drift_(fixed_drift),
        n_(static_cast<int>(iv.size())) {
    Eigen::Vector3d c_mean = Eigen::Vector3d::Zero();
    for (const Interval& x : iv_) c_mean += x.c;
    c_mean /= n_;
    for (const Interval& x : iv_) rss0_ += (x.c - c_mean).squaredNorm();
  }

  // The offset on the coarse grid prior +- i coarse_step_s, |i| <= steps, of the least cost (each
  // step's cost in coarse_cost); returns its i and sets best_d.
  int coarse_search(int steps, double& best_d, std::vector<double>& coarse_cost) const;
  // The robust Gauss-Newton from best_d and its 1-sigma (the larger of the residuals' and
  // Newey-West's); false where it does not converge or is singular. On success also sets info and
  // lever below.
  bool run(bool with_drift, double best_d, Eigen::VectorXd& p, Eigen::MatrixXd& cov_out, double& rms_out,
           double& explained_out);

  // Per interval, from the last successful run: its part of the offset's information and its lever.
  std::vector<double> info;
  std::vector<Eigen::VectorXd> lever;

 private:
  const Interval& at(int k) const { return iv_[static_cast<std::size_t>(k)]; }
  Eigen::Vector3d model_rate(int k, double d) const {
    return Eigen::Vector3d(R_ * grid_.mean(at(k).t0_s - d, at(k).t1_s - d));
  }
  double tmid(int k) const { return 0.5 * (at(k).t0_s + at(k).t1_s); }
  // Linear part (scale, bias) for given model rates m: least squares, weights w.
  void solve_linear(const std::vector<Eigen::Vector3d>& m, const std::vector<double>& w, double& scale,
                    Eigen::Vector3d& bias) const;
  GaussNewton start(bool with_drift, double best_d, Eigen::VectorXd& p) const;
  void evaluate(GaussNewton& g, const Eigen::VectorXd& q) const;
  void huber_weights(GaussNewton& g) const;
  bool iterate(GaussNewton& g, Eigen::VectorXd& p) const;
  bool finish(const GaussNewton& g, Eigen::MatrixXd& cov_out, double& rms_out, double& explained_out);

  const std::vector<Interval>& iv_;
  const RateGrid& grid_;
  const Eigen::Matrix3d& R_;
  const CameraClockOptions& opt_;
  const int hac_lag_;
  const double fixed_drift_;
  const int n_;
  double rss0_ = 0;
};

void IntervalFit::solve_linear(const std::vector<Eigen::Vector3d>& m, const std::vector<double>& w,
                               double& scale, Eigen::Vector3d& bias) const {
  if (!opt_.estimate_scale) {
    scale = 1;
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    double sw = 0;
    for (int k = 0; k < n_; ++k) {
      s += w[static_cast<std::size_t>(k)] * (at(k).c - m[static_cast<std::size_t>(k)]);
      sw += w[static_cast<std::size_t>(k)];
    }
    bias = s / sw;
    return;
  }
  Eigen::Matrix4d A = Eigen::Matrix4d::Zero();
  Eigen::Vector4d b = Eigen::Vector4d::Zero();
  for (int k = 0; k < n_; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    for (int a = 0; a < 3; ++a) {
      Eigen::Vector4d j = Eigen::Vector4d::Zero();
      j(0) = m[ku](a);
      j(1 + a) = 1;
      A += w[ku] * j * j.transpose();
      b += w[ku] * j * iv_[ku].c(a);
    }
  }
  const Eigen::Vector4d x = A.ldlt().solve(b);
  scale = x(0);
  bias = x.tail<3>();
}

int IntervalFit::coarse_search(int steps, double& best_d, std::vector<double>& coarse_cost) const {
  const auto nu = static_cast<std::size_t>(n_);
  const std::vector<double> ones(nu, 1.0);
  std::vector<Eigen::Vector3d> m(nu);
  double best_cost = std::numeric_limits<double>::infinity();
  int best_i = 0;
  for (int i = -steps; i <= steps; ++i) {
    const double d = opt_.prior_offset_s + i * opt_.coarse_step_s;
    for (int k = 0; k < n_; ++k) m[static_cast<std::size_t>(k)] = model_rate(k, d + fixed_drift_ * tmid(k));
    double scale = 1;
    Eigen::Vector3d bias;
    solve_linear(m, ones, scale, bias);
    double cost = 0;
    for (int k = 0; k < n_; ++k)
      cost += (at(k).c - scale * m[static_cast<std::size_t>(k)] - bias).squaredNorm();
    cost /= 3.0 * n_;
    coarse_cost.push_back(cost);
    if (cost < best_cost) {
      best_cost = cost;
      best_d = d;
      best_i = i;
    }
  }
  return best_i;
}

// The parameters' layout and their start: the linear part solved at best_d.
GaussNewton IntervalFit::start(bool with_drift, double best_d, Eigen::VectorXd& p) const {
  const auto nu = static_cast<std::size_t>(n_);
  GaussNewton g;
  g.with_drift = with_drift;
  g.P = 1 + (with_drift ? 1 : 0) + (opt_.estimate_scale ? 1 : 0) + 3;
  g.i_scale = with_drift ? 2 : 1;
  g.i_bias = g.P - 3;
  g.w.assign(nu, 1.0);
  g.r.resize(nu);
  g.J.resize(nu);
  std::vector<Eigen::Vector3d> m(nu);
  double scale = 1;
  Eigen::Vector3d bias;
  for (int k = 0; k < n_; ++k)
    m[static_cast<std::size_t>(k)] = model_rate(k, best_d + (with_drift ? 0.0 : fixed_drift_ * tmid(k)));
  solve_linear(m, g.w, scale, bias);
  p = Eigen::VectorXd::Zero(g.P);
  p(0) = best_d;
  if (opt_.estimate_scale) p(g.i_scale) = scale;
  p.tail<3>() = bias;
  return g;
}

// Residuals and Jacobians at q. The offset's Jacobian is the model's difference over
// +-derivative_step_s: nav rate noise would otherwise pass for angular acceleration.
void IntervalFit::evaluate(GaussNewton& g, const Eigen::VectorXd& q) const {
  const double hs = opt_.derivative_step_s;
  const double sc = opt_.estimate_scale ? q(g.i_scale) : 1.0;
  for (int k = 0; k < n_; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    const double tm = 0.5 * (iv_[ku].t0_s + iv_[ku].t1_s);
    const double d = q(0) + (g.with_drift ? q(1) : fixed_drift_) * tm;
    const Eigen::Vector3d mk = model_rate(k, d);
    const Eigen::Vector3d dm = (model_rate(k, d + hs) - model_rate(k, d - hs)) / (2 * hs);
    g.r[ku] = iv_[ku].c - sc * mk - q.tail<3>();
    g.J[ku].setZero(3, g.P);
    g.J[ku].col(0) = -sc * dm;
    if (g.with_drift) g.J[ku].col(1) = -sc * dm * tm;
    if (opt_.estimate_scale) g.J[ku].col(g.i_scale) = -mk;
    g.J[ku].block<3, 3>(0, g.i_bias) = -Eigen::Matrix3d::Identity();
  }
}

// Huber weights at 2 sigma of the residual norms (MAD): bad rotations count less.
void IntervalFit::huber_weights(GaussNewton& g) const {
  std::vector<double> norms(static_cast<std::size_t>(n_));
  for (int k = 0; k < n_; ++k) norms[static_cast<std::size_t>(k)] = g.r[static_cast<std::size_t>(k)].norm();
  const double s = std::max(median(norms) / 1.54, 1e-12);  // median of a 3-D norm ~ 1.54 sigma
  for (int k = 0; k < n_; ++k) {
    const double z = norms[static_cast<std::size_t>(k)] / (2.5 * s);
    g.w[static_cast<std::size_t>(k)] = z <= 1 ? 1.0 : 1.0 / z;
  }
}

// The iteratively reweighted steps; true once the offset's step is below 1e-8 s.
bool IntervalFit::iterate(GaussNewton& g, Eigen::VectorXd& p) const {
  for (int it = 0; it < 40; ++it) {
    evaluate(g, p);
    if (it >= 2) huber_weights(g);
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(g.P, g.P);
    Eigen::VectorXd gr = Eigen::VectorXd::Zero(g.P);
    for (int k = 0; k < n_; ++k) {
      const auto ku = static_cast<std::size_t>(k);
      H += g.w[ku] * g.J[ku].transpose() * g.J[ku];
      gr += g.w[ku] * g.J[ku].transpose() * g.r[ku];
    }
    const Eigen::VectorXd dp = -H.ldlt().solve(gr);
    if (!dp.allFinite()) return false;
    // Keep steps within the coarse search's resolution region to stay in the right valley.
    Eigen::VectorXd step = dp;
    const double max_step = std::max(2 * opt_.coarse_step_s, 1e-4);
    if (std::abs(step(0)) > max_step) step *= max_step / std::abs(step(0));
    p += step;
    if (std::abs(p(0) - opt_.prior_offset_s) > opt_.search_s + opt_.coarse_step_s) return false;
    if (g.with_drift && !(std::abs(p(1)) < 200e-6)) return false;  // beyond the rate grid's reach
    if (it >= 4 && std::abs(step(0)) < 1e-8) return true;
  }
  return false;
}

// The covariance at the converged parameters (g evaluated there), each interval's information
// and lever, the residuals' rms and the share of the rates' variation explained.
bool IntervalFit::finish(const GaussNewton& g, Eigen::MatrixXd& cov_out, double& rms_out,
                         double& explained_out) {
  const int P = g.P, n = n_;
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(P, P);
  std::vector<Eigen::VectorXd> score(static_cast<std::size_t>(n));
  double wrss = 0, rss = 0;
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    H += g.w[ku] * g.J[ku].transpose() * g.J[ku];
    score[ku] = g.w[ku] * g.J[ku].transpose() * g.r[ku];
    wrss += g.w[ku] * g.r[ku].squaredNorm();
    rss += g.r[ku].squaredNorm();
  }
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(H);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0)) return false;
  const Eigen::MatrixXd Hi = ldlt.solve(Eigen::MatrixXd::Identity(P, P));
  const double dof = std::max(3.0 * n - P, 1.0);
  const Eigen::MatrixXd cov_plain = Hi * (wrss / dof);
  // Newey-West (Bartlett) over hac_lag_s: neighbouring rates share frames and what is left of
  // the parallax is slow, so the residuals are not independent.
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(P, P);
  for (int k = 0; k < n; ++k)
    S += score[static_cast<std::size_t>(k)] * score[static_cast<std::size_t>(k)].transpose();
  for (int l = 1; l <= hac_lag_; ++l) {
    const double wl = 1.0 - static_cast<double>(l) / (hac_lag_ + 1);
    for (int k = 0; k + l < n; ++k) {
      const Eigen::MatrixXd x =
          score[static_cast<std::size_t>(k)] * score[static_cast<std::size_t>(k + l)].transpose();
      S += wl * (x + x.transpose());
    }
  }
  const Eigen::MatrixXd cov_hac = Hi * S * Hi * (3.0 * n / dof);
  cov_out = cov_plain;
  for (int i = 0; i < P; ++i)  // the larger of the two, per parameter
    if (cov_hac(i, i) > cov_out(i, i)) {
      const double f = std::sqrt(cov_hac(i, i) / cov_out(i, i));
      cov_out.row(i) *= f;
      cov_out.col(i) *= f;
    }
  // Each interval's part of the offset's information: its offset column less what the other
  // parameters' columns explain of it (over all intervals), squared.
  const Eigen::VectorXd beta = H.bottomRightCorner(P - 1, P - 1).ldlt().solve(H.col(0).tail(P - 1));
  info.assign(static_cast<std::size_t>(n), 0.0);
  lever.assign(static_cast<std::size_t>(n), Eigen::VectorXd());
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    info[ku] = g.w[ku] * (g.J[ku].col(0) - g.J[ku].rightCols(P - 1) * beta).squaredNorm();
    lever[ku] = Hi * (g.w[ku] * g.J[ku].transpose() * g.J[ku].col(0));
  }
  rms_out = std::sqrt(rss / (3.0 * n));
  explained_out = rss0_ > 0 ? 1.0 - rss / rss0_ : 0.0;
  return true;
}

bool IntervalFit::run(bool with_drift, double best_d, Eigen::VectorXd& p, Eigen::MatrixXd& cov_out,
                      double& rms_out, double& explained_out) {
  GaussNewton g = start(with_drift, best_d, p);
  if (!iterate(g, p)) return false;
  evaluate(g, p);
  return finish(g, cov_out, rms_out, explained_out);
}

// Coarse search, robust Gauss-Newton and the 1-sigma (residuals and Newey-West) over `iv`.
FitOutcome fit_intervals(const std::vector<Interval>& iv, const RateGrid& grid,
                         const Eigen::Matrix3d& R_cam_body, const CameraClockOptions& opt, int hac_lag,
                         DriftModel drift_model, double fixed_drift = 0) {
  FitOutcome out;
  const int n = static_cast<int>(iv.size());
  auto unobservable = [&](std::string why) {
    out.observable = false;
    out.reason = std::move(why);
    return out;
  };
  if (n < std::max(opt.min_intervals, 8)) return unobservable("too few frame intervals");
  IntervalFit fit(iv, grid, R_cam_body, opt, hac_lag, fixed_drift);

  const int steps = static_cast<int>(std::floor(opt.search_s / opt.coarse_step_s));
  double best_d = opt.prior_offset_s;
  const int best_i = fit.coarse_search(steps, best_d, out.coarse_cost);
  if (best_i == -steps || best_i == steps) {
    std::ostringstream why;
    why << "the best offset lies at the edge of the search (" << best_d << " s, searched "
        << opt.prior_offset_s << " +- " << opt.search_s << " s): too little motion, or the offset is beyond it";
    return unobservable(why.str());
  }
  Eigen::VectorXd p;
  Eigen::MatrixXd cov;
  double rms = 0, explained = 0;
  bool with_drift = drift_model != DriftModel::kNone;
  bool ok = fit.run(with_drift, best_d, p, cov, rms, explained);
  if (drift_model == DriftModel::kTry && (!ok || !(std::sqrt(cov(1, 1)) * 1e6 <= opt.max_drift_sigma_ppm))) {
    with_drift = false;  // drift not observable: fit the offset alone
    ok = fit.run(false, best_d, p, cov, rms, explained);
  }
  out.rms = rms;
  out.explained = explained;
  if (!ok) return unobservable("the fit did not converge or is singular: too little angular acceleration");
  const int i_scale = with_drift ? 2 : 1;
  out.scale = opt.estimate_scale ? p(i_scale) : 1.0;
  out.bias = p.tail<3>();
  if (explained < opt.min_explained) {
    std::ostringstream why;
    why << "the nav angular rate explains " << std::round(explained * 1000) / 10 << " % of the camera rates' variation ("
        << opt.min_explained * 100 << " % needed): too little motion";
    return unobservable(why.str());
  }
  const double sigma = std::sqrt(cov(0, 0));
  if (!(sigma <= opt.max_offset_sigma_s)) {
    std::ostringstream why;
    why << "offset 1-sigma " << sigma * 1e3 << " ms exceeds " << opt.max_offset_sigma_s * 1e3
        << " ms: too little angular acceleration";
    return unobservable(why.str());
  }
  out.observable = true;
  out.offset_s = p(0);
  out.offset_sigma_s = sigma;
  out.with_drift = with_drift;
  if (with_drift) {
    out.drift = p(1);
    out.drift_sigma = std::sqrt(cov(1, 1));
  }
  out.offset_information = std::move(fit.info);
  out.lever = std::move(fit.lever);
  return out;
}

}  // namespace

std::string describe_sigma(const CameraClockEstimate& e) {
  if (!e.observable) return "not observable";
  std::ostringstream o;
  switch (e.sigma_source) {
    case CameraClockEstimate::SigmaSource::kFit:
      o << "from the fit's residuals";
      break;
    case CameraClockEstimate::SigmaSource::kJackknife:
      o << "from the jackknife";
      break;
    case CameraClockEstimate::SigmaSource::kFloor:
      o << "from the floor for few manoeuvres";
      break;
  }
  o << " (information from about " << std::fixed << std::setprecision(1) << e.effective_blocks << " of "
    << e.jackknife_blocks << " time " << (e.jackknife_blocks == 1 ? "block" : "blocks");
  if (e.edge_cut) o << ", one cut by the data's start or end";
  o << ")";
  return o.str();
}

namespace {

constexpr double kQuietS = 1.0;  // a cut counts the information within this of it

Status check_clock_inputs(const std::vector<FrameRotation>& rotations, const AngularRateFunction& omega_body,
                          const CameraClockOptions& opt) {
  const char* fn = "nav::estimate_camera_clock(): ";
  if (!omega_body) return make_error(fn, "no angular-rate function given");
  if (!(opt.search_s > 0 && opt.coarse_step_s > 0 && opt.rate_sample_s > 0 && opt.derivative_step_s > 0))
    return make_error(fn, "search_s, coarse_step_s, rate_sample_s and derivative_step_s must be > 0");
  if (!(opt.block_s > 0) || !(opt.block_bias_s >= 0) || !(opt.cut_block_bias_factor >= 1))
    return make_error(fn, "block_s must be > 0, block_bias_s >= 0 and cut_block_bias_factor >= 1");
  if (rotations.size() < static_cast<std::size_t>(std::max(opt.min_intervals, 8)))
    return make_error(fn, rotations.size(), " frame intervals with a rotation; at least ",
                      std::max(opt.min_intervals, 8), " needed");
  return {};
}

// The shifts of nav time the fit may ask for: prior +- search, plus the derivative's step and
// what a drift of 200 ppm adds over half the data's span.
struct ShiftReach {
  double lo_s, hi_s;
};

ShiftReach shift_reach(const CameraClockOptions& opt, double half_span_s) {
  const double reach_s = opt.search_s + opt.derivative_step_s + 200e-6 * half_span_s + 2 * opt.rate_sample_s;
  return {opt.prior_offset_s - reach_s, opt.prior_offset_s + reach_s};
}

// The camera's mean rates over its frame intervals (camera time relative to t_ref) that the nav
// rate covers at every shift, in time order for the blocks.
std::vector<Interval> covered_intervals(const std::vector<FrameRotation>& rotations, TimestampNs t_ref,
                                        const RateGrid& grid, const ShiftReach& reach) {
  std::vector<Interval> iv;
  for (const FrameRotation& r : rotations) {
    const double t0 = ns_to_s(r.t0_camera_ns - t_ref), t1 = ns_to_s(r.t1_camera_ns - t_ref);
    if (!(t1 > t0) || !r.rotvec_cam_rad.allFinite()) continue;
    if (!grid.valid(t0 - reach.hi_s, t1 - reach.lo_s)) continue;  // the nav rate must cover every shift
    iv.push_back({t0, t1, r.rotvec_cam_rad / (t1 - t0)});
  }
  std::stable_sort(iv.begin(), iv.end(),
                   [](const Interval& a, const Interval& b) { return a.t0_s < b.t0_s; });
  return iv;
}

// The full fit's results into the estimate; false where it is not observable.
bool take_full_fit(FitOutcome& full, CameraClockEstimate& est) {
  est.coarse_cost = std::move(full.coarse_cost);
  est.residual_rms_radps = full.rms;
  est.explained = full.explained;
  est.scale = full.scale;
  est.bias_cam_radps = full.bias;
  est.drift_ppm = est.drift_sigma_ppm = kNaN;
  est.drift_sigma_fit_ppm = est.drift_sigma_jackknife_ppm = est.drift_sigma_floor_ppm = kNaN;
  est.offset_sigma_fit_s = est.offset_sigma_jackknife_s = est.offset_sigma_floor_s = kNaN;
  if (!full.observable) {
    est.observable = false;
    est.reason = full.reason;
    est.offset_s = est.offset_sigma_s = kNaN;
    return false;
  }
  est.observable = true;
  est.offset_s = full.offset_s;
  est.offset_sigma_fit_s = full.offset_sigma_s;
  est.drift_observable = full.with_drift;
  if (full.with_drift) {
    est.drift_ppm = full.drift * 1e6;
    est.drift_sigma_fit_ppm = full.drift_sigma * 1e6;
  }
  return true;
}

// The data cut into blocks of time for the 1-sigma beyond the residuals. The images' own error
// lies along each manoeuvre's signal, so neither the residuals nor their autocorrelation show it;
// manoeuvres compared with each other do. The data are cut into blocks of about block_s, each cut
// moved to where the least information lies, so that a manoeuvre stays whole in one block.
class TimeBlocks {
 public:
  TimeBlocks(const std::vector<Interval>& iv, const FitOutcome& full, const CameraClockOptions& opt);

  double t_lo, t_hi;
  std::vector<double> tm;     // per interval: its midpoint
  double total_info = 0;      // the offset's information over all intervals
  int G = 1;                  // blocks
  std::vector<int> block;     // per interval: its block
  std::vector<double> share;  // per block: its share of the information
  double sum_share2 = 0;

  // The information of the intervals with midpoints in [a, b).
  double info_between(double a, double b) const {
    const auto lo = std::lower_bound(tm.begin(), tm.end(), a) - tm.begin();
    const auto hi = std::lower_bound(tm.begin(), tm.end(), b) - tm.begin();
    return cum_[static_cast<std::size_t>(hi)] - cum_[static_cast<std::size_t>(lo)];
  }

 private:
  void place_cuts(const std::vector<Interval>& iv, int nominal_blocks);
  void drop_empty_blocks();
  int block_of(double t) const {
    return static_cast<int>(std::upper_bound(cuts_.begin(), cuts_.end(), t) - cuts_.begin());
  }

  std::vector<double> cum_;  // the information's running sum over the intervals
  std::vector<double> cuts_;
};

TimeBlocks::TimeBlocks(const std::vector<Interval>& iv, const FitOutcome& full, const CameraClockOptions& opt)
    : t_lo(iv.front().t0_s), t_hi(iv.back().t1_s) {
  const int n = static_cast<int>(iv.size());
  const int nominal_blocks =
      std::clamp(static_cast<int>(std::floor((t_hi - t_lo) / opt.block_s)), 1, std::max(opt.max_blocks, 1));
  tm.assign(static_cast<std::size_t>(n), 0.0);
  cum_.assign(static_cast<std::size_t>(n) + 1, 0.0);
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    tm[ku] = 0.5 * (iv[ku].t0_s + iv[ku].t1_s);
    cum_[ku + 1] = cum_[ku] + full.offset_information[ku];
  }
  total_info = cum_.back();
  place_cuts(iv, nominal_blocks);
  drop_empty_blocks();
  G = static_cast<int>(cuts_.size()) + 1;
  block.assign(static_cast<std::size_t>(n), 0);
  share.assign(static_cast<std::size_t>(G), 0.0);
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    block[ku] = block_of(tm[ku]);
    share[static_cast<std::size_t>(block[ku])] += full.offset_information[ku] / total_info;
  }
  for (double w : share) sum_share2 += w * w;
}

void TimeBlocks::place_cuts(const std::vector<Interval>& iv, int nominal_blocks) {
  const double nominal_s = (t_hi - t_lo) / nominal_blocks;
  // Moving a cut by half a block costs as much as the information near a cut on average: evenly
  // spread information (turbulence) keeps the cuts near their nominal places.
  const double move_cost = total_info * 2 * kQuietS / (t_hi - t_lo);
  for (int i = 1; i < nominal_blocks; ++i) {
    const double b0 = t_lo + i * nominal_s;
    double best_t = b0, best = info_between(b0 - kQuietS, b0 + kQuietS);
    for (const Interval& x : iv) {
      const double t = x.t0_s;
      if (std::abs(t - b0) > nominal_s / 2) continue;
      const double cost =
          info_between(t - kQuietS, t + kQuietS) + move_cost * std::abs(t - b0) / (nominal_s / 2);
      if (cost < best) {
        best = cost;
        best_t = t;
      }
    }
    if (cuts_.empty() || best_t > cuts_.back())
      cuts_.push_back(best_t);  // two cuts in one place: one block fewer
  }
}

void TimeBlocks::drop_empty_blocks() {
  std::vector<int> count(cuts_.size() + 1, 0);
  for (double t : tm) ++count[static_cast<std::size_t>(block_of(t))];
  std::vector<double> kept;
  for (std::size_t c = 0; c < cuts_.size(); ++c)
    if (count[c] > 0 && count[c + 1] > 0) kept.push_back(cuts_[c]);
  cuts_ = std::move(kept);
}

// Floor: the images' own clock error, block_bias_s (1-sigma), slowly varying: correlated over
// about block_s (a Bartlett kernel), so one manoeuvre counts as one and two manoeuvres 9 s apart
// as two, whatever the blocks. It reaches the parameters through each interval's lever. A
// manoeuvre cut by the data's start or end is one-sided: its ramp trades against the rate bias,
// and its error was 2 to 5 times a whole one's (docs/CLOCK_OFFSETS.md, "Limits"). Such a block
// has its information crowded at the edge: within kQuietS of it, over twice the block's mean.
// Sets edge_cut where a block that counts is cut so.
Eigen::MatrixXd floor_covariance(const std::vector<Interval>& iv, const TimeBlocks& b, const FitOutcome& full,
                                 const CameraClockOptions& opt, bool& edge_cut) {
  const int n = static_cast<int>(iv.size());
  const auto Gu = static_cast<std::size_t>(b.G);
  std::vector<double> block_t0(Gu, b.t_hi), block_t1(Gu, b.t_lo);
  for (int k = 0; k < n; ++k) {
    const auto j = static_cast<std::size_t>(b.block[static_cast<std::size_t>(k)]);
    block_t0[j] = std::min(block_t0[j], iv[static_cast<std::size_t>(k)].t0_s);
    block_t1[j] = std::max(block_t1[j], iv[static_cast<std::size_t>(k)].t1_s);
  }
  auto cut_at_edge = [&](int j) {
    const auto ju = static_cast<std::size_t>(j);
    const double in_block = b.share[ju] * b.total_info, length = block_t1[ju] - block_t0[ju];
    if (!(in_block > 0) || !(length > kQuietS)) return false;
    double edge = 0;
    if (j == 0) edge = std::max(edge, b.info_between(b.t_lo - 1, b.t_lo + kQuietS));
    if (j == b.G - 1) edge = std::max(edge, b.info_between(b.t_hi - kQuietS, b.t_hi + 1));
    return edge / kQuietS > 2 * in_block / length;
  };
  std::vector<double> block_bias(Gu, opt.block_bias_s);
  for (int j = 0; j < b.G; ++j)
    if (cut_at_edge(j)) {
      block_bias[static_cast<std::size_t>(j)] *= opt.cut_block_bias_factor;
      if (b.share[static_cast<std::size_t>(j)] >= 0.05) edge_cut = true;
    }
  const auto P = static_cast<Eigen::Index>(full.lever.front().size());
  const std::vector<double>& tm = b.tm;
  Eigen::MatrixXd cov_floor = Eigen::MatrixXd::Zero(P, P);
  for (int k = 0, l0 = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    while (tm[static_cast<std::size_t>(l0)] <= tm[ku] - opt.block_s) ++l0;
    Eigen::VectorXd near = Eigen::VectorXd::Zero(P);
    for (int l = l0; l < n && tm[static_cast<std::size_t>(l)] < tm[ku] + opt.block_s; ++l) {
      const auto lu = static_cast<std::size_t>(l);
      near += (1 - std::abs(tm[lu] - tm[ku]) / opt.block_s) *
              block_bias[static_cast<std::size_t>(b.block[lu])] * full.lever[lu];
    }
    cov_floor += block_bias[static_cast<std::size_t>(b.block[ku])] * full.lever[ku] * near.transpose();
  }
  return cov_floor;
}

// The jackknife's refits: each block left out, the changes of offset (and drift) and the blocks'
// shares as weights.
struct Refits {
  std::vector<double> d_offset, d_drift, w_offset, w_drift;
  bool informative_lost = false;  // a block that counts left a refit unobservable
};

// Refits search only +-10 ms about the full fit's offset (within the first search, so on the
// same rate grid): a tenth of the coarse search's cost. A refit whose best offset lies further
// off is on the window's edge, so unobservable: that block carried the estimate.
CameraClockOptions refit_options(const CameraClockOptions& opt, const FitOutcome& full) {
  CameraClockOptions refit_opt = opt;
  const double lo = std::max(opt.prior_offset_s - opt.search_s, full.offset_s - 0.01);
  const double hi = std::min(opt.prior_offset_s + opt.search_s, full.offset_s + 0.01);
  refit_opt.prior_offset_s = 0.5 * (lo + hi);
  refit_opt.search_s = 0.5 * (hi - lo);
  return refit_opt;
}

// The fit again with each block left out (same options but the search; no recursion). The
// offset's refits keep the drift at the full fit's: a refit from two manoeuvres on one side would
// otherwise extrapolate to the reference over a long lever and swamp the others.
Refits jackknife_refits(const std::vector<Interval>& iv, const TimeBlocks& b, const FitOutcome& full,
                        const RateGrid& grid, const Eigen::Matrix3d& R_cam_body,
                        const CameraClockOptions& opt, int hac_lag, bool drift_refits) {
  Refits out;
  if (b.G < 3) return out;
  const CameraClockOptions refit_opt = refit_options(opt, full);
  for (int j = 0; j < b.G; ++j) {
    std::vector<Interval> rest;
    rest.reserve(iv.size());
    for (std::size_t k = 0; k < iv.size(); ++k)
      if (b.block[k] != j) rest.push_back(iv[k]);
    const double w = b.share[static_cast<std::size_t>(j)];
    const FitOutcome r = fit_intervals(rest, grid, R_cam_body, refit_opt, hac_lag, DriftModel::kNone,
                                       full.with_drift ? full.drift : 0.0);
    if (r.observable) {
      out.d_offset.push_back(r.offset_s - full.offset_s);
      out.w_offset.push_back(w);
    } else if (w >= 0.05) {
      out.informative_lost = true;  // the estimate hinges on this block
    }
    if (drift_refits) {
      const FitOutcome rd = fit_intervals(rest, grid, R_cam_body, refit_opt, hac_lag, DriftModel::kFit);
      if (rd.observable) {
        out.d_drift.push_back(rd.drift - full.drift);
        out.w_drift.push_back(w);
      } else if (w >= 0.05) {
        out.informative_lost = true;
      }
    }
  }
  return out;
}

// The 1-sigma: the largest of the fit's, the jackknife's and the floor's.
void take_largest_sigma(bool with_drift, CameraClockEstimate& est) {
  est.offset_sigma_s = est.offset_sigma_fit_s;
  est.sigma_source = CameraClockEstimate::SigmaSource::kFit;
  if (est.offset_sigma_jackknife_s > est.offset_sigma_s) {
    est.offset_sigma_s = est.offset_sigma_jackknife_s;
    est.sigma_source = CameraClockEstimate::SigmaSource::kJackknife;
  }
  if (est.offset_sigma_floor_s > est.offset_sigma_s) {
    est.offset_sigma_s = est.offset_sigma_floor_s;
    est.sigma_source = CameraClockEstimate::SigmaSource::kFloor;
  }
  if (with_drift) {
    est.drift_sigma_ppm = est.drift_sigma_fit_ppm;
    if (est.drift_sigma_jackknife_ppm > est.drift_sigma_ppm)
      est.drift_sigma_ppm = est.drift_sigma_jackknife_ppm;
    if (est.drift_sigma_floor_ppm > est.drift_sigma_ppm) est.drift_sigma_ppm = est.drift_sigma_floor_ppm;
  }
}

// The 1-sigma beyond the residuals: the jackknife over blocks of time, and a floor for few
// manoeuvres.
void block_sigmas(const std::vector<Interval>& iv, const FitOutcome& full, const RateGrid& grid,
                  const Eigen::Matrix3d& R_cam_body, const CameraClockOptions& opt, int hac_lag,
                  CameraClockEstimate& est) {
  const TimeBlocks b(iv, full, opt);
  est.jackknife_blocks = b.G;
  est.effective_blocks = 1.0 / b.sum_share2;
  const Eigen::MatrixXd cov_floor = floor_covariance(iv, b, full, opt, est.edge_cut);
  // The drift's own refits need several blocks for two clock parameters.
  const bool drift_refits = full.with_drift && est.effective_blocks >= 4;
  const Refits rf = jackknife_refits(iv, b, full, grid, R_cam_body, opt, hac_lag, drift_refits);
  est.jackknife_refits = static_cast<int>(rf.d_offset.size());
  // Blocks of unequal information: sum_j ((1 - w_j) d_j)^2 / (1 - sum w^2), with w_j a block's share.
  // For G equal blocks it is the usual (G - 1) / G sum d_j^2; for a linear estimate it is unbiased.
  auto jackknife = [&](const std::vector<double>& d, const std::vector<double>& w) {
    double s = 0;
    for (std::size_t i = 0; i < d.size(); ++i) s += std::pow((1 - w[i]) * d[i], 2);
    return std::sqrt(s / (1 - b.sum_share2));
  };
  const bool usable = !rf.informative_lost && rf.d_offset.size() >= 3 && est.effective_blocks >= 2;
  if (usable) {
    est.offset_sigma_jackknife_s = jackknife(rf.d_offset, rf.w_offset);
    if (drift_refits && rf.d_drift.size() >= 3)
      est.drift_sigma_jackknife_ppm = jackknife(rf.d_drift, rf.w_drift) * 1e6;
  }
  // The floor stands in where the jackknife has too few manoeuvres to compare (under 3 blocks'
  // worth of information) or cannot see a cut one; with more, the manoeuvres' own scatter decides.
  if (usable && est.effective_blocks >= 3 && !est.edge_cut) {
    est.offset_sigma_floor_s = est.drift_sigma_floor_ppm = kNaN;
  } else {
    est.offset_sigma_floor_s = std::sqrt(cov_floor(0, 0));
    if (full.with_drift) est.drift_sigma_floor_ppm = std::sqrt(cov_floor(1, 1)) * 1e6;
  }
  take_largest_sigma(full.with_drift, est);
}

}  // namespace

Expected<CameraClockEstimate> fit_camera_clock(const std::vector<FrameRotation>& rotations,
                                               const Eigen::Matrix3d& R_cam_body,
                                               const AngularRateFunction& omega_body,
                                               const CameraClockOptions& opt) {
  if (auto st = check_clock_inputs(rotations, omega_body, opt); !st) return st.error();
  CameraClockEstimate est;
  TimestampNs t_min = rotations.front().t0_camera_ns, t_max = rotations.front().t1_camera_ns;
  for (const FrameRotation& r : rotations) {
    t_min = std::min(t_min, r.t0_camera_ns);
    t_max = std::max(t_max, r.t1_camera_ns);
  }
  est.reference_camera_ns = t_min + (t_max - t_min) / 2;
  const TimestampNs t_ref = est.reference_camera_ns;
  const double half_span_s = ns_to_s(t_max - t_min) / 2;
  const ShiftReach reach = shift_reach(opt, half_span_s);
  const RateGrid grid(omega_body, t_ref, -half_span_s - reach.hi_s - 0.01, half_span_s - reach.lo_s + 0.01,
                      opt.rate_sample_s);
  const std::vector<Interval> iv = covered_intervals(rotations, t_ref, grid, reach);
  const int n = static_cast<int>(iv.size());
  if (n < std::max(opt.min_intervals, 8))
    return make_error("nav::estimate_camera_clock(): ", n,
                      " frame intervals lie inside the angular-rate data (with the +-", opt.search_s,
                      " s search); at least ", std::max(opt.min_intervals, 8), " needed");
  est.intervals_used = n;
  std::vector<double> spans;
  for (const Interval& x : iv) spans.push_back(x.t1_s - x.t0_s);
  const int hac_lag = std::max(0, static_cast<int>(std::lround(opt.hac_lag_s / median(spans))));

  FitOutcome full = fit_intervals(iv, grid, R_cam_body, opt, hac_lag,
                                  opt.estimate_drift ? DriftModel::kTry : DriftModel::kNone);
  if (!take_full_fit(full, est)) return est;
  block_sigmas(iv, full, grid, R_cam_body, opt, hac_lag, est);
  return est;
}

Expected<CameraClockEstimate> estimate_camera_clock(const std::vector<CameraClockFrame>& frames,
                                                    const CameraModel& model, const Eigen::Matrix3d& R_cam_body,
                                                    const AngularRateFunction& omega_body,
                                                    const CameraClockOptions& options,
                                                    const GroundMotionFunction& ground) {
  CameraRotationTracker tracker(model, R_cam_body, options, ground, omega_body);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (!frames[i].image) return make_error("nav::estimate_camera_clock(): frame ", i, " has no image source");
    auto img = frames[i].image();
    if (!img) return make_error("nav::estimate_camera_clock(): frame ", i, ": ", img.error().message);
    if (auto st = tracker.add_frame(frames[i].t_camera_ns, std::as_const(*img).view()); !st)
      return make_error("nav::estimate_camera_clock(): frame ", i, ": ", st.error().message);
  }
  auto est = fit_camera_clock(tracker.rotations(), R_cam_body, omega_body, options);
  if (!est) return est;
  est->frames = static_cast<int>(frames.size());
  return est;
}

std::vector<CameraClockFrame> camera_clock_frames(const FrameIndex& index, int camera, const std::string& folder,
                                                  std::optional<PixelFormat> bayer, int every) {
  std::vector<const FrameIndexRow*> rows;
  for (const FrameIndexRow& r : index.rows)
    if (r.camera == camera && (every <= 1 || r.sequence % static_cast<std::uint64_t>(every) == 0)) rows.push_back(&r);
  std::stable_sort(rows.begin(), rows.end(), [](const FrameIndexRow* a, const FrameIndexRow* b) { return a->t_ns < b->t_ns; });
  std::vector<CameraClockFrame> out;
  out.reserve(rows.size());
  for (const FrameIndexRow* r : rows) {
    const std::string path = folder.empty() ? r->file : folder + "/" + r->file;
    out.push_back({r->t_ns, [path, bayer]() { return read_image_file(path, bayer); }});
  }
  return out;
}

// ---- from a fused trajectory --------------------------------------------------------------------

AngularRateFunction angular_rate_from_trajectory(const NavTrajectory& trajectory, double half_step_s) {
  const TimestampNs h_ns = std::max<TimestampNs>(s_to_ns(half_step_s), 1);
  return [&trajectory, h_ns](TimestampNs t_ns) -> std::optional<Eigen::Vector3d> {
    const auto a = trajectory.at(t_ns - h_ns);
    const auto b = trajectory.at(t_ns + h_ns);
    if (!a || !b) return std::nullopt;
    const Eigen::Matrix3d dR = a->q_ecef_body.toRotationMatrix().transpose() * b->q_ecef_body.toRotationMatrix();
    return Eigen::Vector3d(log_so3(dR) / ns_to_s(2 * h_ns));
  };
}

GroundMotionFunction ground_motion_from_trajectory(const NavTrajectory& trajectory, double terrain_height_m) {
  return [&trajectory, terrain_height_m](TimestampNs t_ns) -> std::optional<GroundMotion> {
    const auto x = trajectory.at(t_ns);
    if (!x) return std::nullopt;
    const Geodetic g = geodetic_from_ecef(x->p_ecef_m);
    const Eigen::Matrix3d R_ecef_ned_m = R_ecef_ned(g.lat_rad, g.lon_rad);
    GroundMotion gm;
    gm.R_ned_body = R_ecef_ned_m.transpose() * x->q_ecef_body.toRotationMatrix();
    gm.v_ned_mps = R_ecef_ned_m.transpose() * x->v_ecef_mps;
    gm.height_m = g.h_m - terrain_height_m;
    return gm;
  };
}

}  // namespace augrig::nav
