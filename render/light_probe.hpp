// LightProbe: the light on the scene measured on the receiver. Its shape, pose and colours are
// known (the model's base colours and texture), and the cameras see it lit by the same sun, sky
// and ground as the boom: every visible surface point of known albedo rho and normal n gives, per
// colour channel,
//   observed / 255 = rho * (direct * max(n . s, 0) + sky * (1 - n . d) / 2 + ground * (1 + n . d) / 2)
// (render/camera_look.hpp's SceneLight, linear light), with the light evaluated at the triangle's
// vertices on their smooth normals and interpolated over it (Gouraud, as the boom is shaded): a
// pixel's light is sum_j b_j L(n_j), so each sample keeps its pixels' mean barycentric weights and
// its vertex normals. (A triangle's flat normal would miss the sun that a grazing side's vertices
// catch, and the fit would hand that light to the ground.) Points on many normals (the wings' tops, the
// fuselage's sides, the nacelles) make the three terms a small least-squares problem per channel,
// solved robustly (Tukey's biweight: texture edges, specks and shadows are outliers) with the terms
// kept >= 0. The camera look lights the boom with the result (pipeline/look_stage.hpp).
// Samples: the receiver's triangles, each the mean of up to 48 of its pixels (away from its edges)
// against its mean albedo (base colour times the texture's mean over the triangle: a livery's
// speckle and stripes average out on both sides), a pixel counting where the view's mask says the
// receiver alone covers it and the receiver's depth there is the triangle's own (not hidden by
// another part of the receiver); triangles with a clipped pixel are left out.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/image.hpp"
#include "core/pose.hpp"
#include "render/camera_look.hpp"
#include "render/mesh.hpp"
#include "render/rig.hpp"
#include "render/stats.hpp"

namespace augrig {

struct LightFit {
  Eigen::Vector3d direct, sky, ground;  // per channel, SceneLight's units
  std::size_t samples = 0;              // points used (after the robust weights)
  double rms = 0;                       // residual RMS of the inliers, in albedo-relative light units
};

class LightProbe {
 public:
  explicit LightProbe(const Model& receiver);

  // Adds the visible sample points of one view: `raw` the camera's frame (any format; Bayer is read
  // per 2x2 cell, Mono as grey), `mask` and `depth` the augmenter's for it, the camera, the
  // receiver's pose in the body frame, and the light's frame (towards the sun and down, body) for
  // the fit. `gamma`: the camera's tone curve (render/camera_look.hpp).
  void add_view(const Image& raw, const Image& mask, const DepthImage& depth, const RigCamera& cam,
                const Pose& T_body_receiver, double gamma);
  // The light from the points added since clear(); nullopt (and `why` says so) when too few
  // points or normals to tell the three terms apart. `sun_up` false: direct is 0.
  std::optional<LightFit> fit(const Eigen::Vector3d& towards_sun_body, const Eigen::Vector3d& down_body,
                              bool sun_up, std::string* why = nullptr) const;
  void clear() { samples_.clear(); }
  std::size_t points() const { return points_.size(); }  // usable points of the model
  std::size_t samples() const { return samples_.size(); }

 private:
  // A triangle of the receiver: its pixels' mean is its mean albedo times the light on its normal.
  struct Point {
    std::array<Eigen::Vector3d, 3> v;   // vertices, receiver frame
    Eigen::Vector3d n;                  // unit, outwards, receiver frame (the flat normal)
    std::array<Eigen::Vector3d, 3> vn;  // the vertices' smooth normals, outwards (flat where none)
    Eigen::Vector3d albedo;             // the texture's mean over the triangle times the base colour
  };
  struct Sample {
    std::array<Eigen::Vector3d, 3> vn_body;  // the vertex normals, body frame
    Eigen::Vector3d bary;                    // the pixels' mean barycentric weights of the vertices
    Eigen::Vector3d albedo, observed;        // observed: linear 0..1 per channel
    Eigen::Vector3d pixels;                  // pixels read per channel (a small triangle on a Bayer
                                             // mosaic may hold none of a colour: no sample of it)
    bool grey = false;                       // a Mono camera: only the luma is known
  };
  std::vector<Point> points_;
  std::vector<Sample> samples_;
};

}  // namespace augrig
