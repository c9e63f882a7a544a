#include "eval/stereo_eval.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

namespace augrig::eval {
namespace {

cv::Mat to_cv(const Eigen::Matrix3d& m) {
  cv::Mat out;
  cv::eigen2cv(m, out);
  return out;
}

bool fisheye(const CameraModel& c) {
  return c.distortion == DistortionModel::kEquidistant;
}

// The rectified pinhole's intrinsics for a pair OpenCV rectifies with one function only (one
// fisheye and one radtan or pinhole camera), from the rig's own lens models: the rotations R1,
// R2 as OpenCV gives them (they depend on the extrinsics alone), then, as stereoRectify with
// alpha 0, the largest centred rectified image whose every pixel sees into both raw images:
// each raw image's border is carried through its lens and rotation, and the rectangle inside
// both bounds the normalised coordinates. Then the maps from each model's project().
Status rectify_with_models(const CameraModel& left, const CameraModel& right, Rectification& r) {
  const char* where = "eval::rectify_rig(): ";
  double x0 = -1e300, x1 = 1e300, y0 = -1e300, y1 = 1e300;
  for (int i = 0; i < 2; ++i) {
    const CameraModel& cam = i == 0 ? left : right;
    const int W = cam.width_px, H = cam.height_px;
    // The border's image in the rectified normalised plane; a pixel whose ray does not reach it
    // (behind the rectified camera, or off the lens) leaves the rectangle at that side unbounded.
    auto at = [&](int x, int y) -> std::optional<Eigen::Vector2d> {
      const auto ray = cam.ray(Eigen::Vector2d(x, y));
      if (!ray) return std::nullopt;
      const Eigen::Vector3d p = r.R_rect_raw[i] * *ray;
      if (!(p.z() > 1e-6)) return std::nullopt;
      return Eigen::Vector2d(p.x() / p.z(), p.y() / p.z());
    };
    for (int y = 0; y < H; ++y) {
      if (const auto q = at(0, y)) x0 = std::max(x0, q->x());
      if (const auto q = at(W - 1, y)) x1 = std::min(x1, q->x());
    }
    for (int x = 0; x < W; ++x) {
      if (const auto q = at(x, 0)) y0 = std::max(y0, q->y());
      if (const auto q = at(x, H - 1)) y1 = std::min(y1, q->y());
    }
  }
  const int W = left.width_px, H = left.height_px;
  if (!(x1 > x0) || !(y1 > y0) || !(x1 - x0 < 1e6) || !(y1 - y0 < 1e6))
    return make_error(where, "the cameras' rectified views do not overlap");
  r.f_px = std::max((W - 1) / (x1 - x0), (H - 1) / (y1 - y0));
  r.cx_px = 0.5 * (W - 1) - r.f_px * 0.5 * (x0 + x1);
  r.cy_px = 0.5 * (H - 1) - r.f_px * 0.5 * (y0 + y1);
  for (int i = 0; i < 2; ++i) {
    const CameraModel& cam = i == 0 ? left : right;
    const Eigen::Matrix3d R_raw_rect = r.R_rect_raw[i].transpose();
    r.map_x[i].create(H, W, CV_32FC1);
    r.map_y[i].create(H, W, CV_32FC1);
    for (int v = 0; v < H; ++v) {
      auto* mx = r.map_x[i].ptr<float>(v);
      auto* my = r.map_y[i].ptr<float>(v);
      for (int u = 0; u < W; ++u) {
        const Eigen::Vector3d d((u - r.cx_px) / r.f_px, (v - r.cy_px) / r.f_px, 1.0);
        const auto q = cam.project(R_raw_rect * d);
        mx[u] = q ? static_cast<float>(q->x()) : -1.0f;  // outside: remap's constant border
        my[u] = q ? static_cast<float>(q->y()) : -1.0f;
      }
    }
  }
  return {};
}

}  // namespace

Expected<Rectification> rectify_rig(const CameraModel& left, const CameraModel& right,
                                    const Pose& T_right_left) {
  const char* where = "eval::rectify_rig(): ";
  if (left.width_px != right.width_px || left.height_px != right.height_px)
    return make_error(where, "the cameras' images differ in size (", left.width_px, "x", left.height_px,
                      " and ", right.width_px, "x", right.height_px, "); expected one size");
  const double baseline = T_right_left.translation_m.norm();
  if (!(baseline > 1e-6)) return make_error(where, "the cameras share their centre: no stereo baseline");
  const cv::Size size(left.width_px, left.height_px);
  const cv::Mat K1 = to_cv(left.K()), K2 = to_cv(right.K());
  cv::Mat D1, D2;
  cv::eigen2cv(Eigen::VectorXd(left.distortion_coeffs()), D1);
  cv::eigen2cv(Eigen::VectorXd(right.distortion_coeffs()), D2);
  const cv::Mat R = to_cv(T_right_left.R());
  const cv::Mat T = (cv::Mat_<double>(3, 1) << T_right_left.translation_m.x(), T_right_left.translation_m.y(),
                     T_right_left.translation_m.z());
  cv::Mat R1, R2, P1, P2, Q;
  Rectification r;
  r.width = left.width_px;
  r.height = left.height_px;
  try {
    if (fisheye(left) != fisheye(right)) {
      // One lens of each kind: OpenCV's rotations (no distortion needed for them), the rest from
      // the models.
      cv::stereoRectify(K1, cv::Mat(), K2, cv::Mat(), size, R, T, R1, R2, P1, P2, Q, cv::CALIB_ZERO_DISPARITY,
                        0.0, size);
      cv::cv2eigen(R1, r.R_rect_raw[0]);
      cv::cv2eigen(R2, r.R_rect_raw[1]);
      if (Status st = rectify_with_models(left, right, r); !st) return st.error();
      r.baseline_m = baseline;
      return r;
    }
    if (fisheye(left)) {
      cv::fisheye::stereoRectify(K1, D1, K2, D2, size, R, T, R1, R2, P1, P2, Q, cv::CALIB_ZERO_DISPARITY,
                                 size, 0.0, 1.0);
      cv::fisheye::initUndistortRectifyMap(K1, D1, R1, P1, size, CV_32FC1, r.map_x[0], r.map_y[0]);
      cv::fisheye::initUndistortRectifyMap(K2, D2, R2, P2, size, CV_32FC1, r.map_x[1], r.map_y[1]);
    } else {
      // alpha 0: every rectified pixel comes from inside both raw images.
      cv::stereoRectify(K1, D1, K2, D2, size, R, T, R1, R2, P1, P2, Q, cv::CALIB_ZERO_DISPARITY, 0.0, size);
      cv::initUndistortRectifyMap(K1, D1, R1, P1, size, CV_32FC1, r.map_x[0], r.map_y[0]);
      cv::initUndistortRectifyMap(K2, D2, R2, P2, size, CV_32FC1, r.map_x[1], r.map_y[1]);
    }
  } catch (const cv::Exception& e) {
    return make_error(where, "OpenCV could not rectify the rig: ", e.what());
  }
  cv::cv2eigen(R1, r.R_rect_raw[0]);
  cv::cv2eigen(R2, r.R_rect_raw[1]);
  r.f_px = P1.at<double>(0, 0);
  r.cx_px = P1.at<double>(0, 2);
  r.cy_px = P1.at<double>(1, 2);
  // P2 = [f 0 cx f*Tx; ...] with Tx the right camera's x in the rectified left frame (negative
  // when it is on the right).
  r.baseline_m = std::abs(P2.at<double>(0, 3) / P2.at<double>(0, 0));
  if (!(r.f_px > 0) || !(r.baseline_m > 0))
    return make_error(where, "OpenCV returned a degenerate rectification (f ", r.f_px, " px, baseline ",
                      r.baseline_m, " m)");
  return r;
}

void rectify_images(const Rectification& r, const cv::Mat& left, const cv::Mat& right, cv::Mat& left_rect,
                    cv::Mat& right_rect) {
  cv::remap(left, left_rect, r.map_x[0], r.map_y[0], cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  cv::remap(right, right_rect, r.map_x[1], r.map_y[1], cv::INTER_LINEAR, cv::BORDER_CONSTANT);
}

cv::Rect rectified_box(const Rectification& r, const CameraModel& left, const PixelBox& raw_box) {
  if (raw_box.empty()) return {};
  const cv::Rect whole(0, 0, r.width, r.height);
  double u0 = 1e300, v0 = 1e300, u1 = -1e300, v1 = -1e300;
  // The border one pixel outside the box (pixel centres), every pixel along it: the lens and the
  // rotation map the box's inside to the inside of its border's image.
  const int x0 = raw_box.x0 - 1, y0 = raw_box.y0 - 1, x1 = raw_box.x1, y1 = raw_box.y1;
  auto visit = [&](int x, int y) {
    const auto ray = left.ray(Eigen::Vector2d(x, y));
    if (!ray) return false;
    const Eigen::Vector3d p = r.R_rect_raw[0] * *ray;
    if (!(p.z() > 1e-9)) return false;
    const double u = r.f_px * p.x() / p.z() + r.cx_px, v = r.f_px * p.y() / p.z() + r.cy_px;
    u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v), v1 = std::max(v1, v);
    return true;
  };
  for (int x = x0; x <= x1; ++x)
    if (!visit(x, y0) || !visit(x, y1)) return whole;
  for (int y = y0; y <= y1; ++y)
    if (!visit(x0, y) || !visit(x1, y)) return whole;
  const int a = std::max(0, static_cast<int>(std::floor(u0)) - 2),
            b = std::max(0, static_cast<int>(std::floor(v0)) - 2);
  const int c = std::min(r.width, static_cast<int>(std::ceil(u1)) + 3),
            d = std::min(r.height, static_cast<int>(std::ceil(v1)) + 3);
  if (c <= a || d <= b) return {};
  return cv::Rect(a, b, c - a, d - b);
}

cv::Mat true_disparity(const Rectification& r, const DepthImage& depth_left, const cv::Rect& roi_in) {
  cv::Mat d(r.height, r.width, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  const int w = depth_left.width, h = depth_left.height;
  if (w <= 0 || h <= 0) return d;
  const Eigen::Matrix3d Rt = r.R_rect_raw[0].transpose();  // rectified -> raw left
  auto z_at = [&](int x, int y) {
    return static_cast<double>(depth_left.z_m[static_cast<std::size_t>(y) * w + x]);
  };
  const cv::Rect roi =
      roi_in.empty() ? cv::Rect(0, 0, r.width, r.height) : roi_in & cv::Rect(0, 0, r.width, r.height);
  for (int v = roi.y; v < roi.y + roi.height; ++v) {
    const float* mx = r.map_x[0].ptr<float>(v);
    const float* my = r.map_y[0].ptr<float>(v);
    float* out = d.ptr<float>(v);
    for (int u = roi.x; u < roi.x + roi.width; ++u) {
      const double x = mx[u], y = my[u];
      const int xn = static_cast<int>(std::lround(x)), yn = static_cast<int>(std::lround(y));
      if (xn < 0 || yn < 0 || xn >= w || yn >= h) continue;
      double z_raw = z_at(xn, yn);
      if (!std::isfinite(z_raw)) continue;
      // Bilinear inside the receiver, where the surface is smooth between pixel centres.
      const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
      if (x0 >= 0 && y0 >= 0 && x0 + 1 < w && y0 + 1 < h) {
        const double z00 = z_at(x0, y0), z10 = z_at(x0 + 1, y0), z01 = z_at(x0, y0 + 1),
                     z11 = z_at(x0 + 1, y0 + 1);
        if (std::isfinite(z00) && std::isfinite(z10) && std::isfinite(z01) && std::isfinite(z11)) {
          const double fx = x - x0, fy = y - y0;
          z_raw = (1 - fy) * ((1 - fx) * z00 + fx * z10) + fy * ((1 - fx) * z01 + fx * z11);
        }
      }
      // The rectified pixel's ray in the raw left frame; the point on it at raw depth z_raw lies
      // at rectified depth z_raw / (its raw direction's z) (the rectified ray has z = 1).
      const Eigen::Vector3d ray_rect((u - r.cx_px) / r.f_px, (v - r.cy_px) / r.f_px, 1.0);
      const double dz = (Rt * ray_rect).z();
      if (!(dz > 0)) continue;
      const double z_rect = z_raw / dz;
      out[u] = static_cast<float>(r.f_px * r.baseline_m / z_rect);
    }
  }
  return d;
}

cv::Mat rectify_labels(const Rectification& r, const cv::Mat& labels_left, std::uint8_t outside) {
  cv::Mat out;
  cv::remap(labels_left, out, r.map_x[0], r.map_y[0], cv::INTER_NEAREST, cv::BORDER_CONSTANT,
            cv::Scalar(outside));
  return out;
}

void DisparityErrors::add(double true_px, double estimated_px, double f_times_b) {
  ++pixels;
  if (!std::isfinite(estimated_px)) return;
  ++valid;
  const double e = estimated_px - true_px;
  sum_error_px += e;
  sum_sq_px2 += e * e;
  bad1 += std::abs(e) > 1.0;
  bad3 += std::abs(e) > 3.0;
  if (estimated_px > 0 && true_px > 0) {
    const double dz = f_times_b / estimated_px - f_times_b / true_px;
    sum_range_error_m += dz;
    sum_range_sq_m2 += dz * dz;
    ++range_n;
  }
}

void DisparityErrors::merge(const DisparityErrors& o) {
  pixels += o.pixels;
  valid += o.valid;
  sum_error_px += o.sum_error_px;
  sum_sq_px2 += o.sum_sq_px2;
  bad1 += o.bad1;
  bad3 += o.bad3;
  sum_range_error_m += o.sum_range_error_m;
  sum_range_sq_m2 += o.sum_range_sq_m2;
  range_n += o.range_n;
}

double DisparityErrors::valid_pct() const {
  return pixels ? 100.0 * static_cast<double>(valid) / pixels : 0.0;
}
double DisparityErrors::mean_px() const {
  return valid ? sum_error_px / static_cast<double>(valid) : std::numeric_limits<double>::quiet_NaN();
}
double DisparityErrors::rms_px() const {
  return valid ? std::sqrt(sum_sq_px2 / static_cast<double>(valid))
               : std::numeric_limits<double>::quiet_NaN();
}
double DisparityErrors::bad1_pct() const {
  return valid ? 100.0 * static_cast<double>(bad1) / valid : 0.0;
}
double DisparityErrors::bad3_pct() const {
  return valid ? 100.0 * static_cast<double>(bad3) / valid : 0.0;
}
double DisparityErrors::range_mean_m() const {
  return range_n ? sum_range_error_m / static_cast<double>(range_n)
                 : std::numeric_limits<double>::quiet_NaN();
}
double DisparityErrors::range_rms_m() const {
  return range_n ? std::sqrt(sum_range_sq_m2 / static_cast<double>(range_n))
                 : std::numeric_limits<double>::quiet_NaN();
}

void PairScore::merge(const PairScore& o) {
  for (int k = 0; k < 5; ++k) {
    all[k].merge(o.all[k]);
    boom_excluded[k].merge(o.boom_excluded[k]);
  }
}

PairScore score_disparity(const cv::Mat& true_disp, const cv::Mat& estimated, const cv::Mat& classes,
                          const cv::Mat& mask, double f_times_b) {
  PairScore s;
  CV_Assert(true_disp.type() == CV_32FC1 && estimated.type() == CV_32FC1 && classes.type() == CV_8UC1 &&
            mask.type() == CV_8UC1);
  CV_Assert(true_disp.size() == estimated.size() && true_disp.size() == classes.size() &&
            true_disp.size() == mask.size());
  for (int y = 0; y < true_disp.rows; ++y) {
    const float* t = true_disp.ptr<float>(y);
    const float* e = estimated.ptr<float>(y);
    const std::uint8_t* c = classes.ptr<std::uint8_t>(y);
    const std::uint8_t* m = mask.ptr<std::uint8_t>(y);
    for (int x = 0; x < true_disp.cols; ++x) {
      if (!std::isfinite(t[x])) continue;
      const int k = c[x] <= 4 ? c[x] : 0;
      const bool boom = (m[x] & 1) != 0;
      s.all[0].add(t[x], e[x], f_times_b);
      if (k) s.all[k].add(t[x], e[x], f_times_b);
      if (boom) continue;
      s.boom_excluded[0].add(t[x], e[x], f_times_b);
      if (k) s.boom_excluded[k].add(t[x], e[x], f_times_b);
    }
  }
  return s;
}

}  // namespace augrig::eval
