// camera_sensor: what a simulated camera does to the light that reaches it, applied to the whole
// image as a real camera applies it to everything in front of it (the physically present boom
// included):
//   1. optics: a Gaussian point-spread function blurs the scene's linear radiance;
//   2. exposure and gain scale it to raw digital numbers;
//   3. the colour filter array keeps one channel per pixel (Bayer formats);
//   4. sensor noise: Poisson-Gaussian, variance a * raw + b (shot noise and read noise), drawn per
//      pixel from a counter-based generator, so a (seed, camera) gives the same image on any thread;
//   5. the tone curve (gamma) encodes the raw value; 6. rounding and clipping to 8 bits.
// The scene renderers (sim/synthetic_scene.hpp) produce the radiance (their clean RGB8 render,
// linear DN); the camera look of the augmenter (render/camera_look.hpp) must estimate from the
// finished frames what this applied.
#pragma once

#include <cstdint>

#include "core/expected.hpp"
#include "core/image.hpp"

namespace augrig {

struct CameraResponse {
  double psf_sigma_px = 0.0;  // Gaussian PSF, 1-sigma in pixels (0: none); at most 8
  double noise_a = 0.0;       // shot noise: variance per raw DN of signal (DN); 0: none
  double noise_sigma = 0.0;   // read noise, 1-sigma in raw DN (b = noise_sigma^2)
  double gain = 1.0;          // exposure x gain: raw DN per radiance DN
  double gamma = 1.0;         // encoded = 255 (raw / 255)^(1 / gamma); 1: linear
  bool operator==(const CameraResponse&) const = default;
};

// True where the response does more than add read noise to an unblurred linear image, so that
// the renderers' fast path (their own additive noise) cannot stand in for it.
bool needs_camera_model(const CameraResponse& r);

// Checks the response's ranges: "SyntheticSceneRenderer::render(): <field> ...".
Status check_camera_response(const CameraResponse& r);

// The finished frame of camera `camera` in `format` from the scene's radiance `radiance`
// (RGB8, linear DN), with the noise of (`seed`, `camera`). `threads` row bands (1..8): the output
// does not depend on it.
void apply_camera_response(const Image& radiance, const CameraResponse& r, PixelFormat format,
                           std::uint64_t seed, int camera, Image& out, int threads = 1);

}  // namespace augrig
