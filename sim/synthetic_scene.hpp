// SyntheticSceneRenderer: renders what a real camera of the rig would record in flight — sky,
// horizon and ground seen from the tanker's attitude and altitude, and the textured receiver at
// its pose — as raw images through the camera's real lens model, optionally mosaicked to Bayer
// with sensor noise. These are the stand-in for real flight imagery in the demo and the tests.
// Two back ends (docs/SIMULATION.md): the CPU renderer (default; no GL context, cheap enough for a
// live sim:// source) and the earlier OpenGL renderer (needs a current GL context).
#pragma once

#include <cstdint>
#include <memory>

#include <Eigen/Core>

#include "core/expected.hpp"
#include "core/image.hpp"
#include "core/pose.hpp"
#include "render/mesh.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"
#include "sim/camera_sensor.hpp"

namespace augrig {

struct SkyState {
  Eigen::Matrix3d R_ned_body = Eigen::Matrix3d::Identity();  // tanker attitude
  double altitude_m = 6000.0;                                // tanker height above the ground
  // Tanker's horizontal position over the ground (north, east metres from an arbitrary origin):
  // the ground texture is fixed in the world, so it moves under a flying tanker.
  Eigen::Vector2d north_east_m = Eigen::Vector2d::Zero();
  // Unit vector towards the sun in NED (lights the receiver, glows in the sky); default: south-east,
  // 55 deg above the horizon.
  Eigen::Vector3d sun_ned = Eigen::Vector3d(-0.406, 0.406, -0.819);
  // The objects' diffuse light: false (default), the fixed ambient of the OpenGL shader (blue-grey
  // sky 0.36-0.46, ground 0.22), which the OpenGL back end always uses; true (CPU back end), the
  // sky's and the ground's radiance as rendered, averaged over each hemisphere: consistent with
  // the frame, brighter (up-facing white surfaces clip under a high sun).
  bool ambient_from_world = false;
};

struct SensorOptions {
  PixelFormat format = PixelFormat::kRGB8;  // Bayer formats are mosaicked from RGB
  double noise_sigma = 0.0;                 // additive Gaussian (read) noise, digital numbers
  std::uint64_t noise_seed = 1;             // the noise of a render depends on this and the camera only
  // The camera's response (sim/camera_sensor.hpp), applied to the whole image: PSF, shot noise
  // (variance noise_a x signal), gain and tone curve. At their defaults the renderer adds the read
  // noise to its clean render directly (the fast path of earlier flights, byte for byte).
  double psf_sigma_px = 0.0;
  double noise_a = 0.0;
  double gain = 1.0;
  double gamma = 1.0;
  // The exposure time: render_with_boom() integrates a moving boom over it (motion blur; 0: an
  // instant, the default, as before). Nothing else in the scene moves during it.
  double exposure_ms = 0.0;
  CameraResponse response() const { return {psf_sigma_px, noise_a, noise_sigma, gain, gamma}; }
};

enum class SceneBackend {
  // Per raw pixel on the CPU: sky and ground from each pixel's precomputed lens ray, the receiver
  // rasterised by render/soft_raster with per-vertex lighting; both cores in row bands.
  kCpu,
  // OpenGL in a virtual pinhole, read back and resampled through the lens (llvmpipe: ~4x the CPU).
  kOpenGL,
};

struct SceneRendererOptions {
  SceneBackend backend = SceneBackend::kCpu;
  int threads = 2;  // kCpu: threads per render (row bands), 1..8; the output does not depend on it
};

class SyntheticSceneRenderer {
 public:
  // kOpenGL needs a current GL context; kCpu needs none. `receiver` null: the rig's receiver (the
  // built-in one unless the rig names a model file, which is then loaded).
  static Expected<std::unique_ptr<SyntheticSceneRenderer>> create(
      const Rig& rig, std::shared_ptr<const Model> receiver = nullptr, const SceneRendererOptions& options = {});
  virtual ~SyntheticSceneRenderer() = default;
  // Raw image of camera `camera` (index into rig.cameras) into `out` (reallocated only when needed).
  // Raw pixels whose ray the lens model cannot invert are black. Byte-identical for equal inputs.
  virtual Status render(int camera, const SkyState& sky, const Pose& T_body_receiver, bool receiver_present,
                        const SensorOptions& sensor, Image& out) = 0;
  // The same view with the boom physically in the scene at articulation `boom` (the rig's boom
  // model, or the built-in one), lit and occluded as the receiver is, casting its shadow on the
  // receiver under a sun above the horizon, before the camera's response: the frame a flight with
  // a real boom would have given. The CPU back end only.
  // `boom` is the articulation at mid-exposure; moving at `boom_rate_per_s` (rad/s, m/s) over
  // sensor.exposure_ms, the scene is rendered at sub-exposure instants (render/motion_blur.hpp:
  // as many as the boom's trail in the image needs) and the radiance averaged before the camera's
  // response, as a sensor integrates light: the boom's motion blur.
  virtual Status render_with_boom(int camera, const SkyState& sky, const Pose& T_body_receiver,
                                  bool receiver_present, const BoomArticulation& boom,
                                  const BoomArticulation& boom_rate_per_s, const SensorOptions& sensor,
                                  Image& out) {
    (void)camera, (void)sky, (void)T_body_receiver, (void)receiver_present, (void)boom, (void)boom_rate_per_s,
        (void)sensor, (void)out;
    return make_error("SyntheticSceneRenderer::render_with_boom(): only the CPU back end renders the boom");
  }
  // A boom held still.
  Status render_with_boom(int camera, const SkyState& sky, const Pose& T_body_receiver, bool receiver_present,
                          const BoomArticulation& boom, const SensorOptions& sensor, Image& out) {
    return render_with_boom(camera, sky, T_body_receiver, receiver_present, boom, BoomArticulation{}, sensor,
                            out);
  }
};

}  // namespace augrig
