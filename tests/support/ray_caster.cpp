#include "tests/support/ray_caster.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/calib3d.hpp>

#include "core/conventions.hpp"

namespace augrig::test {

namespace {
constexpr double kExtent = 3.0;  // normalised coordinates covered by the grid (|x|, |y| <= 3)
constexpr int kCells = 128;
int cell_of(double v) {
  return std::clamp(static_cast<int>((v + kExtent) / (2 * kExtent) * kCells), 0, kCells - 1);
}
}  // namespace

void RayCaster::add(const Model& model, const Pose& T_cam_obj) {
  for (const Mesh& m : model.meshes)
    for (std::size_t k = 0; k + 2 < m.indices.size(); k += 3)
      tris_.push_back({T_cam_obj * m.positions_m[m.indices[k]].cast<double>(),
                       T_cam_obj * m.positions_m[m.indices[k + 1]].cast<double>(),
                       T_cam_obj * m.positions_m[m.indices[k + 2]].cast<double>()});
  built_ = false;
}

void RayCaster::build() const {
  cells_.assign(kCells * kCells, {});
  everywhere_.clear();
  for (int i = 0; i < static_cast<int>(tris_.size()); ++i) {
    const Tri& t = tris_[i];
    if (t.a.z() <= 1e-9 || t.b.z() <= 1e-9 || t.c.z() <= 1e-9) {
      everywhere_.push_back(i);
      continue;
    }
    // With all vertices in front, the projection is the triangle of the projected vertices.
    double x0 = 1e30, x1 = -1e30, y0 = 1e30, y1 = -1e30;
    for (const auto* p : {&t.a, &t.b, &t.c}) {
      x0 = std::min(x0, p->x() / p->z()), x1 = std::max(x1, p->x() / p->z());
      y0 = std::min(y0, p->y() / p->z()), y1 = std::max(y1, p->y() / p->z());
    }
    if (x1 < -kExtent || y1 < -kExtent || x0 > kExtent || y0 > kExtent) continue;
    for (int cy = cell_of(y0); cy <= cell_of(y1); ++cy)
      for (int cx = cell_of(x0); cx <= cell_of(x1); ++cx) cells_[cy * kCells + cx].push_back(i);
  }
  built_ = true;
}

double RayCaster::hit_z(double x, double y) const {
  if (!built_) build();
  const Eigen::Vector3d d(x, y, 1.0);
  double best = std::numeric_limits<double>::infinity();
  auto test = [&](const Tri& t) {
    // Plane intersection then an inside test by edge functions: a different formulation from the
    // renderer's Moller-Trumbore on purpose.
    const Eigen::Vector3d n = (t.b - t.a).cross(t.c - t.a);
    const double denom = n.dot(d);
    if (std::abs(denom) < 1e-300) return;
    const double s = n.dot(t.a) / denom;
    if (s <= 0) return;
    const Eigen::Vector3d p = s * d;
    const double e0 = n.dot((t.b - t.a).cross(p - t.a));
    const double e1 = n.dot((t.c - t.b).cross(p - t.b));
    const double e2 = n.dot((t.a - t.c).cross(p - t.c));
    if ((e0 >= 0 && e1 >= 0 && e2 >= 0) || (e0 <= 0 && e1 <= 0 && e2 <= 0)) best = std::min(best, s);
  };
  if (std::abs(x) <= kExtent && std::abs(y) <= kExtent)
    for (int i : cells_[cell_of(y) * kCells + cell_of(x)]) test(tris_[i]);
  for (int i : everywhere_) test(tris_[i]);
  return best;
}

std::vector<Eigen::Vector2d> opencv_pixel_rays(const CameraModel& camera) {
  const int W = camera.width_px, H = camera.height_px;
  std::vector<cv::Point2d> px;
  px.reserve(static_cast<std::size_t>(W) * H);
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) px.emplace_back(u, v);
  const Eigen::Matrix3d K = camera.K();
  const cv::Matx33d Kcv(K(0, 0), K(0, 1), K(0, 2), K(1, 0), K(1, 1), K(1, 2), K(2, 0), K(2, 1), K(2, 2));
  std::vector<cv::Point2d> und;
  if (camera.distortion == DistortionModel::kEquidistant) {
    const cv::Vec4d D(camera.coeffs[0], camera.coeffs[1], camera.coeffs[2], camera.coeffs[3]);
    cv::fisheye::undistortPoints(px, und, Kcv, D);
  } else {
    const std::vector<double> D(camera.coeffs.begin(), camera.coeffs.end());
    cv::undistortPoints(px, und, Kcv, D, cv::noArray(), cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-14));
  }
  std::vector<Eigen::Vector2d> out(und.size());
  for (std::size_t i = 0; i < und.size(); ++i) out[i] = {und[i].x, und[i].y};
  return out;
}

Image ray_cast_mask(const CameraModel& camera, const std::vector<Eigen::Vector2d>& rays,
                    const RayCaster& boom, const RayCaster& receiver) {
  Image mask(camera.width_px, camera.height_px, PixelFormat::kMono8);
  for (int v = 0; v < camera.height_px; ++v)
    for (int u = 0; u < camera.width_px; ++u) {
      const Eigen::Vector2d& r = rays[static_cast<std::size_t>(v) * camera.width_px + u];
      const double zb = boom.hit_z(r.x(), r.y());
      const double zr = receiver.hit_z(r.x(), r.y());
      std::uint8_t m = 0;
      if (std::isfinite(zr)) m |= kMaskReceiver;
      if (std::isfinite(zb) && zb < zr) m |= kMaskBoom;
      mask.row(v)[u] = m;
    }
  return mask;
}

}  // namespace augrig::test
