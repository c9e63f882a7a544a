#include "render/keypoints.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "core/conventions.hpp"

namespace augrig {

namespace {

// The centre of the vertices that maximise `score` (to 1 cm: a wing tip's edge is a row of
// vertices, and the side with one more would pick another end), among those `keep` accepts.
template <typename Score, typename Keep>
Eigen::Vector3d extreme(const Model& m, Score&& score, Keep&& keep) {
  double best = -std::numeric_limits<double>::infinity();
  for (const Mesh& mesh : m.meshes)
    for (const Eigen::Vector3f& pf : mesh.positions_m)
      if (keep(mesh, pf.cast<double>())) best = std::max(best, score(pf.cast<double>()));
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int n = 0;
  for (const Mesh& mesh : m.meshes)
    for (const Eigen::Vector3f& pf : mesh.positions_m) {
      const Eigen::Vector3d p = pf.cast<double>();
      if (keep(mesh, p) && score(p) >= best - 0.01) sum += p, ++n;
    }
  return n ? Eigen::Vector3d(sum / n) : Eigen::Vector3d::Zero();
}

}  // namespace

std::vector<Keypoint> default_receiver_keypoints(const Model& receiver, const Eigen::Vector3d& receptacle_m) {
  std::vector<Keypoint> k;
  if (receiver.triangle_count() == 0) return {{"receptacle", receptacle_m}};
  const auto all = [](const Mesh&, const Eigen::Vector3d&) { return true; };
  const auto [lo, hi] = receiver.bounds();
  const double aft_fifth_x = lo.x() + 0.2 * (hi.x() - lo.x());
  const auto aft = [&](const Mesh&, const Eigen::Vector3d& p) { return p.x() <= aft_fifth_x; };
  k.push_back({"nose", extreme(
                           receiver, [](const Eigen::Vector3d& p) { return p.x(); }, all)});
  k.push_back({"tail", extreme(
                           receiver, [](const Eigen::Vector3d& p) { return -p.x(); }, all)});
  // FRD: +y is right, -z is up.
  k.push_back({"wing_tip_left", extreme(
                                    receiver, [](const Eigen::Vector3d& p) { return -p.y(); }, all)});
  k.push_back({"wing_tip_right", extreme(
                                     receiver, [](const Eigen::Vector3d& p) { return p.y(); }, all)});
  k.push_back({"fin_tip", extreme(
                              receiver, [](const Eigen::Vector3d& p) { return -p.z(); }, aft)});
  k.push_back({"tailplane_tip_left", extreme(
                                         receiver, [](const Eigen::Vector3d& p) { return -p.y(); }, aft)});
  k.push_back({"tailplane_tip_right", extreme(
                                          receiver, [](const Eigen::Vector3d& p) { return p.y(); }, aft)});
  // Each nacelle's front: the centre of its vertices within 5 cm of its foremost.
  for (const Mesh& mesh : receiver.meshes) {
    if (mesh.name.rfind("nacelle", 0) != 0 || mesh.positions_m.empty()) continue;
    float front = -std::numeric_limits<float>::infinity();
    for (const Eigen::Vector3f& p : mesh.positions_m) front = std::max(front, p.x());
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int n = 0;
    for (const Eigen::Vector3f& p : mesh.positions_m)
      if (p.x() >= front - 0.05f) sum += p.cast<double>(), ++n;
    const Eigen::Vector3d c = sum / n;
    k.push_back({c.y() < 0 ? "nacelle_front_left" : "nacelle_front_right", c});
  }
  k.push_back({"receptacle", receptacle_m});
  return k;
}

std::vector<Keypoint> receiver_keypoints(const ReceiverConfig& config, const Model& receiver) {
  if (config.keypoints.empty()) return default_receiver_keypoints(receiver, config.receptacle_m);
  std::vector<Keypoint> k;
  for (const NamedPoint& p : config.keypoints) k.push_back({p.name, p.p_m});
  return k;
}

namespace {

// `name` with its '_'-separated word `from` replaced by `to` (the first such word); "" if none.
std::string swap_word(const std::string& name, const std::string& from, const std::string& to) {
  for (std::size_t at = name.find(from); at != std::string::npos; at = name.find(from, at + 1)) {
    const bool starts = at == 0 || name[at - 1] == '_';
    const bool ends = at + from.size() == name.size() || name[at + from.size()] == '_';
    if (starts && ends) return name.substr(0, at) + to + name.substr(at + from.size());
  }
  return "";
}

}  // namespace

std::vector<int> keypoint_flip_index(const std::vector<Keypoint>& keypoints) {
  std::vector<int> flip(keypoints.size());
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    flip[i] = static_cast<int>(i);
    std::string mirror = swap_word(keypoints[i].name, "left", "right");
    if (mirror.empty()) mirror = swap_word(keypoints[i].name, "right", "left");
    for (std::size_t j = 0; j < keypoints.size() && !mirror.empty(); ++j)
      if (keypoints[j].name == mirror) flip[i] = static_cast<int>(j);
  }
  return flip;
}

std::string_view to_string(KeypointClass c) {
  switch (c) {
    case KeypointClass::kVisible:
      return "visible";
    case KeypointClass::kHiddenByBoom:
      return "hidden_by_boom";
    case KeypointClass::kHiddenByReceiver:
      return "hidden_by_receiver";
    case KeypointClass::kNotDrawn:
      return "not_drawn";
    default:
      return "outside";
  }
}

int coco_visibility(KeypointClass c) {
  switch (c) {
    case KeypointClass::kVisible:
      return 2;
    case KeypointClass::kHiddenByBoom:
    case KeypointClass::kHiddenByReceiver:
      return 1;
    default:
      return 0;
  }
}

KeypointInView locate_keypoint(const Eigen::Vector3d& p_cam_m, const CameraModel& camera, ConstImageView mask,
                               const DepthImage& depth) {
  KeypointInView out;
  const auto uv = camera.project(p_cam_m);
  const int w = mask.width, h = mask.height;
  // Pixel i covers [i - 0.5, i + 0.5).
  if (!uv || !(uv->x() >= -0.5 && uv->y() >= -0.5 && uv->x() < w - 0.5 && uv->y() < h - 0.5)) return out;
  out.uv_px = *uv;
  const int x0 = static_cast<int>(std::lround(uv->x())), y0 = static_cast<int>(std::lround(uv->y()));
  const double z = p_cam_m.z(), tol = keypoint_depth_tolerance_m(z);
  const auto decide = [&](int x, int y) {
    const std::uint8_t m =
        mask.data[static_cast<std::size_t>(y) * mask.stride_bytes + static_cast<std::size_t>(x)];
    out.decided_x = x, out.decided_y = y;
    if (depth.at(x, y) < z - tol)
      out.cls = KeypointClass::kHiddenByReceiver;
    else
      out.cls = (m & kMaskBoom) ? KeypointClass::kHiddenByBoom : KeypointClass::kVisible;
  };
  const auto receiver_at = [&](int x, int y) {
    return (mask.data[static_cast<std::size_t>(y) * mask.stride_bytes + static_cast<std::size_t>(x)] &
            kMaskReceiver) != 0;
  };
  if (receiver_at(x0, y0)) {
    decide(x0, y0);
    return out;
  }
  // On the silhouette: the nearest neighbour drawing the receiver at the point's depth.
  std::array<std::pair<double, std::array<int, 2>>, 8> around;
  int n = 0;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      if (!dx && !dy) continue;
      const double d2 = std::pow(x0 + dx - uv->x(), 2) + std::pow(y0 + dy - uv->y(), 2);
      around[static_cast<std::size_t>(n++)] = {d2, {x0 + dx, y0 + dy}};
    }
  std::sort(around.begin(), around.end());
  for (const auto& [d2, xy] : around) {
    const int x = xy[0], y = xy[1];
    if (x < 0 || y < 0 || x >= w || y >= h || !receiver_at(x, y)) continue;
    if (std::abs(depth.at(x, y) - z) > tol) continue;
    decide(x, y);
    return out;
  }
  out.decided_x = x0, out.decided_y = y0;
  out.cls = KeypointClass::kNotDrawn;
  return out;
}

}  // namespace augrig
