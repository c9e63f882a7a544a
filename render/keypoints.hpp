// keypoints: named points on the receiver for learned pose estimation (issue 35 §2; docs/LABELS.md).
// AAR keypoint detectors (YOLO-pose, keypoints + PnP) need, per camera and frame, where each named
// point of the receiver lies in the image and whether it can be seen there:
//   outside            not in the image (behind the camera, or projected off it);
//   visible            its pixel shows the receiver's surface at the point's depth, no boom on it;
//   hidden by the boom the boom is the front-most surface at its pixel;
//   hidden by receiver the receiver's own surface lies in front of it (the far wing, the fin
//                      seen from below);
//   not drawn          in the image, yet no pixel within one of it shows the receiver (an edge-on
//                      part thinner than a pixel).
// The decision is made at one pixel, reported: the keypoint's nearest pixel when the receiver is
// drawn there, else (a point on the silhouette) the nearest of its eight neighbours that shows the
// receiver at the point's depth. It reads the augmenter's mask bits and receiver depth only, so a
// label never disagrees with the masks.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "core/image.hpp"
#include "render/camera_model.hpp"
#include "render/mesh.hpp"
#include "render/rig.hpp"
#include "render/stats.hpp"

namespace augrig {

struct Keypoint {
  std::string name;
  Eigen::Vector3d p_receiver_m;  // in the receiver body frame (FRD)
};

// Keypoints every aircraft-shaped model has, found from its geometry (each the centre of the
// vertices within 1 cm of the extreme): nose (the foremost), tail (the aftmost), wing_tip_left and
// wing_tip_right (the outermost to each side), fin_tip (the topmost), tailplane_tip_left and _right (the
// outermost in the aft fifth of the length), each engine nacelle's front centre (meshes named "nacelle*",
// left or right by their side), and the receptacle. The built-in receiver's names are those.
std::vector<Keypoint> default_receiver_keypoints(const Model& receiver, const Eigen::Vector3d& receptacle_m);
// The rig's keypoints (`receiver.keypoints`), else the defaults of its model (`receiver`, loaded).
std::vector<Keypoint> receiver_keypoints(const ReceiverConfig& config, const Model& receiver);

// Each keypoint's mirror image for a left-right flip (YOLO's flip_idx): a name with the word `left`
// (between '_' or at an end) pairs with the same name with `right` there, and the other way; a
// keypoint without a partner is its own.
std::vector<int> keypoint_flip_index(const std::vector<Keypoint>& keypoints);

enum class KeypointClass : std::uint8_t {
  kOutside = 0,
  kVisible = 1,
  kHiddenByBoom = 2,
  kHiddenByReceiver = 3,
  kNotDrawn = 4,
};
std::string_view to_string(KeypointClass c);
// COCO's visibility flag: 0 not labelled (outside, not drawn), 1 labelled but hidden, 2 visible.
int coco_visibility(KeypointClass c);

struct KeypointInView {
  Eigen::Vector2d uv_px = Eigen::Vector2d::Constant(-1);  // raw pixel (centres at integers); -1: none
  KeypointClass cls = KeypointClass::kOutside;
  int decided_x = -1, decided_y = -1;  // the pixel that decided (-1: outside)
};

// Surfaces within this of the point's depth are its own: a vertex is drawn at a pixel centre up to
// a pixel's width away, on a slope (the receiver's far side is metres behind).
inline double keypoint_depth_tolerance_m(double z_m) {
  return 0.1 + 0.02 * z_m;
}

// One keypoint in one camera: `p_cam_m` the point in the camera frame, `mask` the augmenter's Mono8
// mask and `depth` its receiver depth for that camera (both the camera's size).
KeypointInView locate_keypoint(const Eigen::Vector3d& p_cam_m, const CameraModel& camera, ConstImageView mask,
                               const DepthImage& depth);

}  // namespace augrig
