// camera_look: the boom's pixels made a camera's. The augmenter composites a clean rendering of
// the boom over the raw frame (the plain look); the camera look then passes that rendering
// through what the real camera would have done to a boom in front of it:
//   1. the boom's light: the sun's direction, the sky's and the ground's diffuse light (SceneLight,
//      set per frame by whoever knows the time, place and attitude) instead of a fixed light;
//   2. optics: the boom's layer (premultiplied colour and coverage) blurred by the camera's
//      point-spread function in linear light, so its edges are as soft as the image's;
//   3. response: the tone curve (gamma) the camera applied, undone before the blur and redone after;
//   4. sensor noise: each re-composited pixel gets the noise the camera's noise level function
//      (render/noise_level.hpp) gives at its value, less what the raw pixel's own noise still
//      contributes there, drawn from a counter-based generator so that a (seed, frame, camera)
//      gives the same pixels every run. Bayer mosaics are handled per site in the raw domain.
// Masks, depth and statistics never depend on the look: only the augmented pixels change.
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "core/image.hpp"
#include "render/noise_level.hpp"
#include "render/pbr.hpp"

namespace augrig {

enum class Look : std::uint8_t {
  kPlain,   // the clean rendering: fixed light, no blur, no noise (before issue 33)
  kCamera,  // sun and sky, the camera's PSF, tone curve and sensor noise
};
const char* to_string(Look l);
// "plain" or "camera"; false for anything else.
bool parse_look(std::string_view name, Look& out);

// Where the light on the boom comes from, for one frame.
enum class LightSource : std::uint8_t {
  kFixed,       // the plain look's light: above the tanker, a little forward and to the right
  kDefaultSun,  // no time or position known: the documented default sun (kDefaultSunBody)
  kConfigured,  // a scene file's or rig's `sun` key
  kEphemeris,   // computed from the frame's GPS time and the tanker's position and attitude
};
const char* to_string(LightSource s);

// The light on a surface of a given finish (render/pbr.hpp) seen from a given side: its colour is
// 255 (albedo * scale + add) per channel, albedo being base colour times texture. A metal's
// reflection takes its albedo's colour (scale); the dielectric's, a white sheen, does not (add).
struct SurfaceLight {
  Eigen::Vector3d scale = Eigen::Vector3d::Zero();
  Eigen::Vector3d add = Eigen::Vector3d::Zero();
};

// The light on the boom in the tanker's body frame: the sun, and two hemispheres of diffuse
// light, the sky's above the horizon and the ground's (or clouds') below it. A surface of normal n
// (unit) and albedo rho has, per colour channel, the radiance
//   rho * 255 * (direct * max(n . towards_light, 0) + sky * (1 - n . down) / 2 + ground * (1 + n . down) / 2)
// in the image's linear DN: 1 is the light that makes a white surface full scale. A surface facing
// down sees the ground alone: `ground` is the ground's own radiance / 255, which the camera look
// measures in the frames (pipeline/look_stage.hpp). The three terms are per channel (R, G, B): a
// blue sky and a green-brown ground tint the boom as they tint everything else.
struct SceneLight {
  Eigen::Vector3d towards_light_body = Eigen::Vector3d(0.3, 0.2, -1.0).normalized();  // unit vector
  Eigen::Vector3d down_body =
      Eigen::Vector3d::UnitZ();  // the local vertical, down (NED z), in the body frame
  // The sun's share on a surface facing it (0: sun below the horizon, overcast), R, G, B.
  Eigen::Vector3d direct = Eigen::Vector3d::Constant(0.65);
  Eigen::Vector3d sky = Eigen::Vector3d::Constant(0.35);     // diffuse light from the upper hemisphere
  Eigen::Vector3d ground = Eigen::Vector3d::Constant(0.35);  // ... from the lower hemisphere
  LightSource source = LightSource::kFixed;
  // The sun is known and above the horizon: the boom casts a shadow (kMaskShadow) along
  // towards_light_body. Geometry, not light: the same in either look (the fixed light has none).
  bool sun_up = false;

  // The plain look's light (the values above: an even ambient of 0.35).
  static SceneLight fixed();
  // The default when no sun is known: sun 45 deg up, ahead and to the right of the nose, level flight.
  static SceneLight default_sun();
  // A clear sky's sun in the body frame; `sun_above_horizon` false leaves the diffuse light only.
  static SceneLight sun(const Eigen::Vector3d& towards_sun_body, bool sun_above_horizon, LightSource source,
                        const Eigen::Vector3d& down_body = Eigen::Vector3d::UnitZ());
  // The light factor per channel on a surface of unit normal n (body or any frame the three
  // vectors share).
  Eigen::Vector3d on(const Eigen::Vector3d& n, const Eigen::Vector3d& towards_light,
                     const Eigen::Vector3d& down) const {
    Eigen::Vector3d l;
    for (int c = 0; c < 3; ++c) {
      // An even ambient exactly (the plain look's light, as before the hemispheres).
      const double diffuse = sky[c] == ground[c]
                                 ? sky[c]
                                 : sky[c] * 0.5 * (1 - n.dot(down)) + ground[c] * 0.5 * (1 + n.dot(down));
      l[c] = diffuse + direct[c] * std::max(n.dot(towards_light), 0.0);
    }
    return l;
  }
  // The same light on a surface of finish `f` seen along unit `v` (towards the eye): the diffuse
  // light above times (1 - metallic), plus the sun's GGX lobe and the hemispheres' sheen with
  // Schlick's Fresnel (F0 0.04 for the dielectric, the albedo for the metal). docs/LOOK.md.
  SurfaceLight on(const Eigen::Vector3d& n, const Eigen::Vector3d& v, const Eigen::Vector3d& towards_light,
                  const Eigen::Vector3d& down, const SurfaceFinish& f) const;
  Eigen::Vector3d lowest() const { return sky.cwiseMin(ground); }
  Eigen::Vector3d highest() const { return sky.cwiseMax(ground) + direct; }
};

// One camera's look parameters.
struct CameraLookParams {
  NoiseLevelFunction noise;   // in the image's (encoded) DN; empty: no noise is added
  double psf_sigma_px = 0.7;  // Gaussian PSF, 1-sigma in pixels; 0: no blur
  double gamma = 1.0;         // encoded = 255 (linear / 255)^(1 / gamma); 1: the image is linear
  std::uint64_t seed = 0;     // noise seed (with the frame's time and the camera)
  // The exposure time (motion blur, render/motion_blur.hpp). Below 0: not known here, the frames'
  // own Frame::exposure_ns where they carry one, else none; 0: instantaneous (no motion blur).
  double exposure_ms = -1;
  friend bool operator==(const CameraLookParams&, const CameraLookParams&) = default;
};

// Largest accepted PSF sigma: a wider blur is no lens a camera-rig would fly with.
inline constexpr double kMaxPsfSigmaPx = 8.0;
// Longest accepted exposure (the rig's look.exposure_ms): a second is no flight-test camera's.
inline constexpr double kMaxExposureMs = 1000.0;

// The margin, in pixels, by which the PSF spreads the boom beyond the pixels it covers.
int psf_margin_px(const CameraLookParams& p);

// Reused buffers of apply_camera_look() (one per view): allocated once per box size.
struct LookBuffers {
  std::vector<float> layer, tmp;             // premultiplied linear colour and coverage; blur scratch
  std::vector<int> spans;                    // per box row: the columns the boom's layer covers
  PixelBox layer_box;                        // the box the layer is over (begin_look_layer())
  std::vector<float> decode, encode, carry;  // tone-curve tables for the gamma they were built for
  double table_gamma = 0;
  std::vector<float> shade;      // apply_shadow_look(): the shadow's share of the light, R G B per pixel
  std::vector<int> shade_spans;  // ... and its columns per box row
};

// Re-composites the boom inside `box` (image coordinates, lying in the image) with the camera
// look. `raw` is the camera's raw frame; `alpha` the boom's coverage per raw pixel (Mono8,
// 255 = opaque, frame-sized) as the plain composite used it; `aug` holds the plain composite's
// pixels of `box` (a view whose (0, 0) is the box's top-left pixel) and receives the result.
// `frame_key` identifies the frame (its timestamp) for the noise.
void apply_camera_look(ConstImageView raw, ConstImageView alpha, ImageView aug, const PixelBox& box,
                       const CameraLookParams& params, std::uint64_t frame_key, int camera, LookBuffers& buf);

// The same in three steps, for a layer averaged over sub-exposure instants (motion blur): an
// empty layer over `box`; each instant's layer added with its weight (`composite`: that instant's
// plain composite of `part` ((0, 0) its top-left; `part` inside `box`), `alpha` its coverage,
// frame-sized); the camera over the layer, the raw pixels of `aug` (which holds `box`'s pixels)
// re-composited where it covers them. apply_camera_look() is these with one instant of weight 1.
void begin_look_layer(const PixelBox& box, PixelFormat format, LookBuffers& buf);
void add_to_look_layer(ConstImageView raw, ConstImageView alpha, ConstImageView composite,
                       const PixelBox& part, float weight, LookBuffers& buf);
void apply_look_layer(ConstImageView raw, ImageView aug, const CameraLookParams& params,
                      std::uint64_t frame_key, int camera, LookBuffers& buf);

// A receiver pixel in the boom's shadow (image coordinates) and the share of its light, R G B,
// that the shadow takes away: the direct light's, direct max(n.s, 0) / (ambient + direct max(n.s, 0)).
struct ShadowPixel {
  int u, v;
  float share[3];
};

// Darkens the receiver in the boom's shadow, after apply_camera_look(): the shares as a field over
// `box` (image coordinates, lying in the image, holding every shadow pixel and the PSF's margin
// round them), blurred by the PSF (a shadow's edge passes through the lens like any other edge),
// each pixel's linear value scaled by 1 - share, the sensor's noise topped up to the NLF's level
// at the darker value. `aug` holds the pixels of `box` ((0, 0) its top-left) and is changed in place.
void apply_shadow_look(ImageView aug, const PixelBox& box, const std::vector<ShadowPixel>& shadow,
                       const CameraLookParams& params, std::uint64_t frame_key, int camera, LookBuffers& buf);

// A standard normal deviate for counter `key` (a splitmix64 hash through the inverse normal
// CDF; |value| <= 3.9): the noise generator, exposed for its tests.
float gaussian_for_key(std::uint64_t key);

}  // namespace augrig
