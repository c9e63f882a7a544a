#include "render/light_probe.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Dense>

#include "core/conventions.hpp"

namespace augrig {
namespace {

// Bilinear, repeating sample of a texture (0..1 per channel), as the rasterisers read it.
Eigen::Vector3d texel(const Texture& t, double u, double v) {
  auto wrap = [](double x, int n, int& i0, int& i1) {
    const double f = x * n - 0.5;
    const double fl = std::floor(f);
    i0 = static_cast<int>(fl) % n;
    if (i0 < 0) i0 += n;
    i1 = (i0 + 1) % n;
    return f - fl;
  };
  int x0, x1, y0, y1;
  const double ax = wrap(u, t.width, x0, x1), ay = wrap(v, t.height, y0, y1);
  auto at = [&](int x, int y) -> Eigen::Vector3d {  // a value, not an expression of a temporary
    const std::uint8_t* p = &t.rgba[(static_cast<std::size_t>(y) * t.width + x) * 4];
    return Eigen::Vector3d(p[0], p[1], p[2]) / 255.0;
  };
  return (1 - ay) * ((1 - ax) * at(x0, y0) + ax * at(x1, y0)) +
         ay * ((1 - ax) * at(x0, y1) + ax * at(x1, y1));
}

constexpr double kLuma[3] = {0.299, 0.587, 0.114};

}  // namespace

LightProbe::LightProbe(const Model& receiver) {
  for (const Mesh& m : receiver.meshes) {
    const bool textured =
        m.texture && m.texture->width > 0 && m.texture->height > 0 && m.uvs.size() == m.positions_m.size();
    const Eigen::Vector3d base = m.base_color.cast<double>();
    for (std::size_t k = 0; k + 2 < m.indices.size(); k += 3) {
      const std::uint32_t i0 = m.indices[k], i1 = m.indices[k + 1], i2 = m.indices[k + 2];
      Point p;
      p.v = {m.positions_m[i0].cast<double>(), m.positions_m[i1].cast<double>(),
             m.positions_m[i2].cast<double>()};
      Eigen::Vector3d n = (p.v[1] - p.v[0]).cross(p.v[2] - p.v[0]);
      if (n.norm() < 1e-6) continue;  // degenerate
      n.normalize();
      // Oriented as the vertex normals say (the outside), whatever the winding.
      if (i2 < m.normals.size() && n.dot((m.normals[i0] + m.normals[i1] + m.normals[i2]).cast<double>()) < 0)
        n = -n;
      p.n = n;
      const bool smooth = std::max({i0, i1, i2}) < m.normals.size();
      for (int j = 0; j < 3; ++j) {
        const std::uint32_t vi = m.indices[k + static_cast<std::size_t>(j)];
        Eigen::Vector3d vn = smooth ? m.normals[vi].cast<double>() : n;
        // A vertex normal that is not a direction, or one across the surface from the face's, is
        // not a smooth surface's: the flat normal stands in.
        vn = vn.norm() > 1e-6 ? vn.normalized() : n;
        p.vn[static_cast<std::size_t>(j)] = vn.dot(n) > 0 ? vn : n;
      }
      p.albedo = base;
      if (textured) {
        // The texture's mean over the triangle (an 8 x 8 stratified grid of barycentric points):
        // what the mean of the triangle's pixels sees, fine speckle and stripes included.
        const Eigen::Vector2d ua = m.uvs[i0].cast<double>(), ub = m.uvs[i1].cast<double>(),
                              uc = m.uvs[i2].cast<double>();
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        int count = 0;
        for (int i = 0; i < 8; ++i)
          for (int j = 0; j < 8 - i; ++j) {
            const double b1 = (i + 1.0 / 3) / 8, b2 = (j + 1.0 / 3) / 8;
            const Eigen::Vector2d uv = ua + b1 * (ub - ua) + b2 * (uc - ua);
            sum += texel(*m.texture, uv.x(), uv.y()), ++count;
          }
        p.albedo = base.cwiseProduct(sum / count);
      }
      if (p.albedo.minCoeff() < 0.03) continue;  // too dark to measure the light by
      points_.push_back(p);
    }
  }
}

void LightProbe::add_view(const Image& raw, const Image& mask, const DepthImage& depth, const RigCamera& cam,
                          const Pose& T_body_receiver, double gamma) {
  const PixelFormat f = raw.format();
  const int W = raw.width(), H = raw.height(), bpp = bytes_per_pixel(f);
  if (mask.width() != W || mask.height() != H || depth.width != W || depth.height != H) return;
  const Pose T_cam_recv = cam.T_body_cam.inverse() * T_body_receiver;
  const Eigen::Matrix3d R_cam_recv = T_cam_recv.R(), R_body_recv = T_body_receiver.R();
  auto linear = [gamma](double v8) { return gamma == 1.0 ? v8 / 255.0 : std::pow(v8 / 255.0, gamma); };
  constexpr double kMargin = 0.15;  // barycentric margin: pixels near the triangle's edges are left out
  constexpr int kMaxPixels = 48;    // pixels read per triangle at most (a grid over its box)
  constexpr int kEdgeReach = 1;     // pixels: a PSF of up to ~1 px sigma reaches no further
  for (const Point& pt : points_) {
    std::array<Eigen::Vector3d, 3> pc;
    std::array<Eigen::Vector2d, 3> uv;
    bool ok = true;
    for (int j = 0; j < 3 && ok; ++j) {
      pc[static_cast<std::size_t>(j)] = T_cam_recv * pt.v[static_cast<std::size_t>(j)];
      const auto q = pc[static_cast<std::size_t>(j)].z() > 0
                         ? cam.model.project(pc[static_cast<std::size_t>(j)])
                         : std::nullopt;
      ok = q.has_value();
      if (ok) uv[static_cast<std::size_t>(j)] = *q;
    }
    if (!ok || (R_cam_recv * pt.n).dot(pc[0]) >= 0) continue;  // off the lens, or facing away
    // Barycentric coordinates in the image (the lens' curvature over one triangle is negligible).
    const Eigen::Vector2d e1 = uv[1] - uv[0], e2 = uv[2] - uv[0];
    const double det = e1.x() * e2.y() - e1.y() * e2.x();
    if (std::abs(det) < 8.0) continue;  // under ~4 pixels: too small to read
    const double x0 = std::min({uv[0].x(), uv[1].x(), uv[2].x()}),
                 x1 = std::max({uv[0].x(), uv[1].x(), uv[2].x()});
    const double y0 = std::min({uv[0].y(), uv[1].y(), uv[2].y()}),
                 y1 = std::max({uv[0].y(), uv[1].y(), uv[2].y()});
    if (x0 < 1 || y0 < 1 || x1 > W - 2 || y1 > H - 2) continue;
    const double step = std::max(1.0, std::sqrt((x1 - x0) * (y1 - y0) / kMaxPixels));
    Eigen::Vector3d sum = Eigen::Vector3d::Zero(), n = Eigen::Vector3d::Zero(),
                    bary = Eigen::Vector3d::Zero();
    double bary_n = 0;
    bool clipped = false;
    double last_b1 = 0, last_b2 = 0;  // the barycentric weights of the last pixel on_triangle() took
    // A pixel well inside this triangle, on the receiver alone, and this triangle the surface it sees.
    auto on_triangle = [&](int x, int y) {
      const Eigen::Vector2d d = Eigen::Vector2d(x, y) - uv[0];
      const double b1 = (d.x() * e2.y() - d.y() * e2.x()) / det, b2 = (e1.x() * d.y() - e1.y() * d.x()) / det;
      if (b1 < kMargin || b2 < kMargin || 1 - b1 - b2 < kMargin) return false;
      last_b1 = b1, last_b2 = b2;
      const std::uint8_t m = mask.row(y)[x];
      // Not the boom, nor the receiver in its shadow (lit by the sky alone there).
      if (!(m & kMaskReceiver) || (m & (kMaskBoom | kMaskShadow))) return false;
      const double z = pc[0].z() + b1 * (pc[1].z() - pc[0].z()) + b2 * (pc[2].z() - pc[0].z());
      if (std::abs(depth.at(x, y) - z) >= std::max(0.05, 0.01 * z)) return false;
      // Away from the receiver's silhouettes and its parts' edges by the lens' reach: the PSF mixes
      // the background (or a nearer part) into pixels next to them, and the silhouettes are where
      // the surfaces facing sideways and down are, the ones that tell the ground's light.
      const double jump = std::max(0.3, 0.03 * z);
      for (int k = 0; k < 8; ++k) {
        static constexpr int kDx[8] = {1, 1, 0, -1, -1, -1, 0, 1}, kDy[8] = {0, 1, 1, 1, 0, -1, -1, -1};
        const int xx = std::clamp(x + kEdgeReach * kDx[k], 0, W - 1),
                  yy = std::clamp(y + kEdgeReach * kDy[k], 0, H - 1);
        const std::uint8_t mn = mask.row(yy)[xx];
        if (!(mn & kMaskReceiver) || (mn & kMaskBoom) || std::abs(depth.at(xx, yy) - z) > jump) return false;
      }
      return true;
    };
    auto add = [&](int c, std::uint8_t v) {
      clipped |= v >= 250;
      sum[c] += linear(v), n[c] += 1;
      bary += Eigen::Vector3d(1 - last_b1 - last_b2, last_b1, last_b2), bary_n += 1;
    };
    if (is_bayer(f)) {
      // Whole 2x2 cells on an even lattice, each of their pixels on the triangle read for its site's
      // channel: every channel from the same points, no pixel twice.
      const double cell_step = 2.0 * std::max(1.0, std::round(step / 2));
      for (double yy = 2 * std::floor(y0 / 2); yy <= y1; yy += cell_step)
        for (double xx = 2 * std::floor(x0 / 2); xx <= x1; xx += cell_step)
          for (int dy = 0; dy < 2; ++dy)
            for (int dx = 0; dx < 2; ++dx) {
              const int x = static_cast<int>(xx) + dx, y = static_cast<int>(yy) + dy;
              if (x < W && y < H && on_triangle(x, y)) add(bayer_channel(f, x, y), raw.row(y)[x]);
            }
    } else {
      for (double yy = std::ceil(y0); yy <= y1; yy += step)
        for (double xx = std::ceil(x0); xx <= x1; xx += step) {
          const int x = static_cast<int>(xx), y = static_cast<int>(yy);
          if (!on_triangle(x, y)) continue;
          const std::uint8_t* px = raw.row(y) + static_cast<std::ptrdiff_t>(x) * bpp;
          for (int c = 0; c < 3; ++c) add(c, px[bpp == 1 ? 0 : c]);
        }
    }
    // Clipped: the light is above what it reads. A Bayer triangle samples the colours it holds.
    if (clipped || n.maxCoeff() < 1) continue;
    Sample s;
    for (int j = 0; j < 3; ++j)
      s.vn_body[static_cast<std::size_t>(j)] = R_body_recv * pt.vn[static_cast<std::size_t>(j)];
    s.bary = bary / bary_n;
    s.albedo = pt.albedo;
    s.observed = sum.cwiseQuotient(n.cwiseMax(1.0));
    s.pixels = n;
    s.grey = bpp == 1 && !is_bayer(f);
    samples_.push_back(s);
  }
}

std::optional<LightFit> LightProbe::fit(const Eigen::Vector3d& towards_sun_body,
                                        const Eigen::Vector3d& down_body, bool sun_up,
                                        std::string* why) const {
  auto fail = [why](std::string w) -> std::optional<LightFit> {
    if (why) *why = std::move(w);
    return std::nullopt;
  };
  constexpr std::size_t kMinSamples = 40;
  if (samples_.size() < kMinSamples)
    return fail(std::to_string(samples_.size()) + " points of the receiver in view, " +
                std::to_string(kMinSamples) + " needed");
  const Eigen::Vector3d s = towards_sun_body.normalized(), d = down_body.normalized();
  // The light basis of each sample: the sun's cosine and the two hemispheres' shares at each
  // vertex, weighted as its pixels weigh the vertices (Gouraud).
  std::vector<Eigen::Vector3d> basis(samples_.size(), Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < samples_.size(); ++i)
    for (std::size_t j = 0; j < 3; ++j) {
      const Eigen::Vector3d& nb = samples_[i].vn_body[j];
      basis[i] += samples_[i].bary[static_cast<Eigen::Index>(j)] *
                  Eigen::Vector3d(sun_up ? std::max(nb.dot(s), 0.0) : 0.0, 0.5 * (1 - nb.dot(d)),
                                  0.5 * (1 + nb.dot(d)));
    }
  const bool grey = samples_.front().grey;
  LightFit out;
  double rms_sum = 0;
  std::size_t used = 0;
  for (int c = 0; c < (grey ? 1 : 3); ++c) {
    auto rho = [&](const Sample& q) {
      return grey ? kLuma[0] * q.albedo[0] + kLuma[1] * q.albedo[1] + kLuma[2] * q.albedo[2] : q.albedo[c];
    };
    // The samples of this channel (grey: all of them).
    auto has = [&](std::size_t i) { return grey || samples_[i].pixels[c] >= 1; };
    std::vector<double> w(samples_.size(), 1.0), r(samples_.size());
    // A sample's weight by the pixels behind it: a mean of n pixels has the texture's and the
    // noise's variance over n, plus the model's own error, which more pixels do not reduce (a
    // triangle of 4 pixels weighs half one of many). On a Bayer mosaic a small triangle may hold
    // one pixel of a colour: it counts, but little.
    auto prior = [&](std::size_t i) {
      const double n = grey ? samples_[i].pixels.maxCoeff() : samples_[i].pixels[c];
      return n / (n + 4.0);
    };
    for (std::size_t i = 0; i < samples_.size(); ++i) w[i] = has(i) ? prior(i) : 0.0;
    std::size_t present = 0;
    for (std::size_t i = 0; i < samples_.size(); ++i) present += has(i);
    if (present < kMinSamples)
      return fail(std::to_string(present) + " points of the receiver in view for one colour, " +
                  std::to_string(kMinSamples) + " needed");
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    std::array<bool, 3> active{};
    for (int iter = 0; iter < 12; ++iter) {
      // Every term starts each round active: one dropped under the first round's outliers comes
      // back once they weigh nothing.
      active = {sun_up, true, true};
      // Weighted least squares over the active terms; a term that comes out negative is dropped
      // (held at 0) and the rest solved again.
      for (int pass = 0; pass < 3; ++pass) {
        Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
        Eigen::Vector3d b = Eigen::Vector3d::Zero();
        for (std::size_t i = 0; i < samples_.size(); ++i) {
          Eigen::Vector3d a = rho(samples_[i]) * basis[i];
          for (int k = 0; k < 3; ++k)
            if (!active[static_cast<std::size_t>(k)]) a[k] = 0;
          A += w[i] * a * a.transpose();
          b += w[i] * a * samples_[i].observed[c];
        }
        for (int k = 0; k < 3; ++k)
          if (!active[static_cast<std::size_t>(k)]) A(k, k) = 1, b[k] = 0;
        // The terms must be told apart: a view of surfaces facing one way only cannot.
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(A);
        if (eig.eigenvalues()[0] < 1e-6 * eig.eigenvalues()[2])
          return fail("the receiver's surfaces in view face too few ways to separate sun, sky and ground");
        x = A.ldlt().solve(b);
        bool dropped = false;
        for (int k = 0; k < 3; ++k)
          if (active[static_cast<std::size_t>(k)] && x[k] < 0)
            active[static_cast<std::size_t>(k)] = false, dropped = true;
        if (!dropped) break;
      }
      for (int k = 0; k < 3; ++k) x[k] = active[static_cast<std::size_t>(k)] ? std::max(x[k], 0.0) : 0.0;
      // Tukey's biweight on the residuals, scaled by their median absolute deviation.
      std::vector<double> abs_r;
      for (std::size_t i = 0; i < samples_.size(); ++i) {
        r[i] = samples_[i].observed[c] - rho(samples_[i]) * basis[i].dot(x);
        if (has(i)) abs_r.push_back(std::abs(r[i]));
      }
      std::nth_element(abs_r.begin(), abs_r.begin() + static_cast<std::ptrdiff_t>(abs_r.size() / 2),
                       abs_r.end());
      const double cutoff = 4.685 * std::max(1.4826 * abs_r[abs_r.size() / 2], 1e-4);
      for (std::size_t i = 0; i < r.size(); ++i) {
        const double u = r[i] / cutoff;
        w[i] = has(i) && std::abs(u) < 1 ? prior(i) * (1 - u * u) * (1 - u * u) : 0.0;
      }
    }
    std::size_t inliers = 0;
    for (std::size_t i = 0; i < r.size(); ++i)
      if (w[i] > 0) rms_sum += r[i] * r[i], ++inliers;
    used = std::max(used, inliers);
    for (int ch = grey ? 0 : c; ch < (grey ? 3 : c + 1); ++ch)
      out.direct[ch] = x[0], out.sky[ch] = x[1], out.ground[ch] = x[2];
  }
  if (used < kMinSamples) return fail("too few points of the receiver agree on one light");
  out.samples = used;
  out.rms = std::sqrt(rms_sum / static_cast<double>(used * (grey ? 1 : 3)));
  return out;
}

}  // namespace augrig
