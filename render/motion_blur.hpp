// motion_blur: the boom's motion over a camera's exposure. A camera integrates light over its
// exposure; a boom that moves (its articulation changes) during it leaves a trail that real
// frames show and a boom drawn at one instant does not. Both the augmenter's camera look and the
// simulator's physical boom draw the boom at K sub-exposure instants and average: K from the
// boom's largest image-space displacement over the exposure (one instant per kMotionStepPx,
// capped), K = 1 (one instant, the mid-exposure's: the still boom's cost and pixels) below
// kMotionMinPx. Masks, depth and statistics stay those of mid-exposure.
#pragma once

#include <Eigen/Core>

#include "render/models.hpp"
#include "render/rig.hpp"

namespace augrig {

// Below this displacement over the exposure the boom is drawn still (a quarter pixel: under the
// PSF's reach, and the static case must cost nothing).
inline constexpr double kMotionMinPx = 0.25;
// The sub-exposure instants' spacing in the image: a box blur sampled at 0.5 px, under the PSF,
// is smooth.
inline constexpr double kMotionStepPx = 0.5;
// At most this many instants (8 px of motion at kMotionStepPx; beyond, they are spaced wider).
inline constexpr int kMaxMotionSamples = 16;

// The articulation `dt_s` after mid-exposure, moving at `rate_per_s` (rad/s, m/s) through it.
BoomArticulation articulation_at(const BoomArticulation& mid, const BoomArticulation& rate_per_s,
                                 double dt_s);
// Whether the rate moves the boom at all.
bool moves(const BoomArticulation& rate_per_s);

// The largest displacement, in raw pixels of `cam`, of any vertex of `boom` (the vertices in
// front of the camera that its lens projects) between the exposure's start and end.
double boom_motion_px(const BoomModel& boom, const Eigen::Vector3d& pivot_body_m, const RigCamera& cam,
                      const BoomArticulation& mid, const BoomArticulation& rate_per_s, double exposure_s);

// How many sub-exposure instants a displacement of `motion_px` needs (1: none).
int motion_samples(double motion_px);

// Instant k of K, seconds from mid-exposure: the middle of the k-th of K equal parts of the exposure.
inline double sub_exposure_offset_s(int k, int samples, double exposure_s) {
  return ((k + 0.5) / samples - 0.5) * exposure_s;
}

}  // namespace augrig
