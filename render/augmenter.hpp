// Augmenter: renders the virtual boom (and the receiver as a mask-only proxy) into each camera's
// raw frames, perspective-correct for that camera's intrinsics, distortion and extrinsics, and
// produces per camera the augmented image, the 8-bit mask (kMaskBoom | kMaskReceiver, decided at
// the pixel centre, and kMaskShadow where the sun is up: the receiver in the boom's shadow) and
// the receiver depth; per stereo frame the occlusion statistics.
//
// Flow per view: the boom's and receiver's projected boxes are found; each object is rasterised
// into a virtual pinhole image that covers the lens' undistorted field (triangle ids and shaded
// colour), by OpenGL or, where OpenGL is itself a software renderer, by render/soft_raster.hpp;
// every raw pixel centre is mapped through the inverse distortion into that image;
// where the ids around it disagree (silhouettes, boom/receiver crossings) the pixel centre's ray
// is intersected exactly with the candidate triangles. Raw pixels are never resampled: outside
// the boom's anti-aliased footprint the augmented image is the raw image, byte for byte.
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "core/expected.hpp"
#include "core/frame.hpp"
#include "core/pose.hpp"
#include "render/camera_look.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"
#include "render/stats.hpp"

namespace augrig {

enum class ReceiverDraw { kMaskOnly, kWireframe, kTranslucent };

// Who rasterises the virtual image. Both give the same masks: the CPU pass decides every pixel
// whose samples disagree by exact ray casting, whichever rasteriser produced the samples.
enum class Rasterizer {
  kAuto,    // kCpu when GL_RENDERER is a software renderer (llvmpipe, softpipe, swrast), else kOpenGl
  kOpenGl,  // the current GL context (a GPU: the flight machine)
  kCpu,     // render/soft_raster.hpp; both views in parallel. Mask-only receiver only: the
            // validation overlays (ReceiverDraw::kWireframe, kTranslucent) always use OpenGL
};
const char* to_string(Rasterizer r);

// What ViewResult::augmented holds.
enum class AugmentedOutput {
  kWholeImage,  // the raw image with the boom composited in: a frame-sized copy per camera
  kChangedBox,  // only its part inside ViewResult::augmented_box, the rest being the raw image:
                // for consumers that keep the raw frame anyway (the recorder stores the augmented
                // image as that box's difference; a display can upload the raw image and the box)
};

struct AugmentOptions {
  ReceiverDraw receiver_draw = ReceiverDraw::kMaskOnly;
  bool antialias = true;       // blend the boom's edge pixels by their coverage
  bool receiver_proxy = true;  // render the receiver (mask bit 1, depth, stereo classes)
  bool stereo_classes = true;  // compute the stereo visibility classes (needs receiver_proxy)
  StereoClassOptions class_options;
  Rasterizer rasterizer = Rasterizer::kAuto;
  AugmentedOutput augmented_output = AugmentedOutput::kWholeImage;
  // bench/: glFinish between GL stages so AugmentTimings splits clear/draw/readback (slower overall).
  bool profile_stages = false;
  // The boom's look (render/camera_look.hpp): kPlain, the clean rendering under a fixed light, or
  // kCamera, lit by SceneState::light and passed through each camera's PSF, tone curve and noise
  // (the parameters below, changed between frames by set_camera_look()). Masks, depth and
  // statistics are the same either way. Validation overlays (ReceiverDraw other than kMaskOnly)
  // are drawn plain.
  Look look = Look::kPlain;
  std::vector<CameraLookParams> camera_looks;  // per rig camera; missing ones get the defaults
  // Models to use instead of the rig's (tests, the simulator); null: build or load the rig's.
  std::shared_ptr<const BoomModel> boom_model;
  std::shared_ptr<const Model> receiver_model;
};

// Where everything is for one stereo frame.
struct SceneState {
  BoomArticulation boom;
  Pose T_body_receiver;  // receiver body frame in the tanker body frame
  bool receiver_present = true;
  SceneLight light;  // the light on the boom (used by Look::kCamera; the plain look's is fixed)
  // How fast the boom's articulation changes at mid-exposure (rad/s, m/s; zero: still). With the
  // camera look and a known exposure (CameraLookParams::exposure_ms, else Frame::exposure_ns) the
  // boom's colour and coverage are averaged over the exposure (render/motion_blur.hpp); its masks,
  // depth and statistics stay those of `boom`, mid-exposure.
  BoomArticulation boom_rate_per_s;
};

// The scene at contact: boom at `a`, the receiver (level, the tanker's attitude) placed so its
// receptacle (receiver body frame) sits at the nozzle tip, then moved by `offset_body_m`.
SceneState scene_at_contact(const Rig& rig, const BoomDimensions& boom, const Eigen::Vector3d& receptacle_m,
                            const BoomArticulation& a,
                            const Eigen::Vector3d& offset_body_m = Eigen::Vector3d::Zero());

struct ViewResult {
  // The augmented image (raw format): the whole image, or with AugmentedOutput::kChangedBox only
  // its part inside `augmented_box` (an image of that box's size).
  Image augmented;
  PixelBox augmented_box;     // outside it the augmented image is the raw image, byte for byte
  Image mask;                 // Mono8
  DepthImage receiver_depth;  // z of the receiver along each pixel centre's ray
  PixelBox boom_box;          // raw pixels the boom may touch (its anti-aliased footprint)
  PixelBox receiver_box;      // raw pixels the receiver may cover
  // Look::kCamera only: the boom's coverage of each raw pixel as composited before the camera
  // look (Mono8, frame-sized, 255 = opaque; zero outside boom_box). Empty with the plain look.
  Image boom_alpha;
};

// The whole augmented image of `r` (either AugmentedOutput) over the raw image it was made from.
Image whole_augmented(const Image& raw, const ViewResult& r);
// Makes `r.augmented` the whole augmented image (a no-op when it is already), for consumers that
// need whole images (a display, PNG files) from a pipeline running the changed-box output.
void make_whole_augmented(const Image& raw, ViewResult& r);

struct StereoResult {
  ViewResult left;
  ViewResult right;
  OcclusionStats stats;
  std::vector<std::uint8_t> stereo_classes;  // StereoClass per left pixel (empty if not computed)
  // The receiver was rendered (present in the scene and AugmentOptions::receiver_proxy): its mask
  // bit and depth mean something (labels need them).
  bool receiver_drawn = false;
};

// Wall time of each stage of the last augment() call, for bench/.
struct AugmentTimings {
  double render_ms = 0;    // rasterising, both views summed (GL: clear + draw + readback)
  double gl_clear_ms = 0;  // the three below only with AugmentOptions::profile_stages
  double gl_draw_ms = 0;
  double gl_readback_ms = 0;
  double masks_ms = 0;  // CPU pass, both views summed: masks, exact edge rays, depth and the
                        // composite of the augmented images (one pass over the pixels)
  double look_ms = 0;   // the camera look, both views summed (0 with the plain look)
  double shadow_ms = 0; // the boom's shadow on the receiver (mask bit, the camera look's darkening), summed
  double stats_ms = 0;  // counts and stereo classes
  double motion_ms = 0;    // the camera look's sub-exposure instants (motion blur), summed (in look_ms too)
  int motion_samples = 1;  // the most sub-exposure instants a view's boom was drawn at (1: still)
  double total_ms = 0;  // wall time of the whole augment() call (the stages above overlap)
};

class Augmenter {
 public:
  // Needs a current GL context (render/gl_context.hpp). Builds or loads the rig's models.
  static Expected<std::unique_ptr<Augmenter>> create(const Rig& rig, const AugmentOptions& options = {});
  virtual ~Augmenter() = default;

  // `out` is reused from frame to frame: its buffers are allocated once, so the hot path allocates nothing.
  virtual Status augment(const StereoFrame& frame, const SceneState& scene, StereoResult& out) = 0;
  // One camera only (index into rig.cameras); no statistics.
  virtual Status augment_view(int camera, const Frame& raw, const SceneState& scene, ViewResult& out) = 0;

  // Look::kCamera: camera `camera`'s look from the next frame on (a refreshed noise estimate).
  virtual Status set_camera_look(int camera, const CameraLookParams& params) = 0;
  virtual const CameraLookParams& camera_look(int camera) const = 0;

  virtual const AugmentTimings& timings() const = 0;
  virtual Rasterizer rasterizer() const = 0;  // kOpenGl or kCpu: what kAuto chose
  virtual const Rig& rig() const = 0;
  virtual const BoomModel& boom_model() const = 0;
  virtual const Model& receiver_model() const = 0;
};

}  // namespace augrig
