#include "pipeline/poses.hpp"

#include <cmath>
#include <filesystem>

#include "pipeline/camera_clock_online.hpp"
#include "pipeline/look_stage.hpp"
#include "pipeline/scene_file.hpp"
#include "pipeline/scene_folder_poses.hpp"
#include "recorder/replay_source.hpp"
#include "sim/flight_source.hpp"

namespace augrig::pipeline {
namespace {

class FixedScenePoses final : public PoseProvider {
 public:
  FixedScenePoses(const SceneState& scene, std::string name) : scene_(scene), name_(std::move(name)) {}
  std::string describe() const override { return "the scene " + name_; }
  FramePoses at(const StereoFrame&, TimestampNs) override {
    FramePoses p;
    p.scene = scene_;
    p.boom_given = true;
    p.hud.status = "fixed scene (no nav)";
    return p;
  }

 private:
  SceneState scene_;
  std::string name_;
};

class SimTruthPoses final : public PoseProvider {
 public:
  explicit SimTruthPoses(const SimulatedFlight& sim) {
    for (const sim::FrameTruth& f : sim::frame_truths(sim.scenario, *sim.flight, sim.logs.cameras))
      by_frame_[{f.camera, f.t_camera_ns}] = {
          f, sun_light(f.t_gps_ns, sim.flight->tanker(f.t_true_s).T_ecef_body())};
  }
  std::string describe() const override { return "the simulation's truth"; }
  FramePoses at(const StereoFrame& frame, TimestampNs) override {
    FramePoses p;
    const auto it = by_frame_.find({index_of(frame.left.camera), frame.left.t_ns});
    if (it == by_frame_.end()) {
      p.problems.push_back("no simulation truth at this frame's time");
      p.hud.status = "no pose: " + p.problems.back();
      return p;
    }
    // The receiver's true pose; the boom is augrig's to fly (it tracks, as in the demo), the
    // scenario's boom only its starting point.
    const sim::FrameTruth& truth = it->second.first;
    p.scene = SceneState{truth.boom, truth.T_body_receiver, true, it->second.second, {}};
    p.hud.status = "simulation truth";
    p.hud.fix = nav::FixQuality::kRtkFixed;
    p.hud.age_s = 0;
    p.sigma_pos_m = 0, p.sigma_att_deg = 0;
    p.hud.sigma_pos_m = 0, p.hud.sigma_att_deg = 0;
    return p;
  }

 private:
  std::map<std::pair<int, TimestampNs>, std::pair<sim::FrameTruth, SceneLight>> by_frame_;
};

class LiveNavPoses final : public PoseProvider {
 public:
  LiveNavPoses(const LiveNav& nav, std::vector<TimestampNs> offsets, const CameraClocks* clocks)
      : nav_(nav), offsets_(std::move(offsets)), clocks_(clocks) {}
  std::string describe() const override { return "the live nav (GPS/INS of both aircraft)"; }
  bool live() const override { return true; }
  FramePoses at(const StereoFrame& frame, TimestampNs mid_host_left_ns) override {
    // The pose at the left camera's mid-exposure on the nav clock (the right's differs by the skew).
    std::optional<TimestampNs> t_nav;
    // The left camera's estimated clock once applied: its stamp, or its host mid-exposure.
    if (clocks_) t_nav = clocks_->to_gps(0, clocks_->host_timed() ? mid_host_left_ns : frame.left.t_ns);
    if (!t_nav && !offsets_.empty()) {
      t_nav = frame.left.t_ns - offsets_[0];
    } else if (!t_nav && mid_host_left_ns) {
      if (auto t = nav_.host_to_nav(mid_host_left_ns)) t_nav = *t;
    }
    FrameNav fn;
    if (t_nav) {
      fn = nav_.at(0, *t_nav);
    } else {
      fn.problems.push_back("no nav clock for this frame yet (no GPS fix received)");
      fn.hud.status = "no pose: " + fn.problems.back();
    }
    FramePoses p;
    if (fn.pose) {
      // The receiver only: the boom stage aims the boom (LiveNav's tracking is the same command).
      p.scene = SceneState{fn.pose->boom.articulation, fn.pose->body.T_a_receiver, true,
                           sun_light(fn.pose->t_nav_ns, fn.pose->T_ecef_tanker), {}};
      p.sigma_pos_m = fn.hud.sigma_pos_m;
      p.sigma_att_deg = fn.hud.sigma_att_deg;
    }
    p.stale = fn.stale;
    p.problems = std::move(fn.problems);
    p.hud = fn.hud;
    return p;
  }

 private:
  const LiveNav& nav_;
  std::vector<TimestampNs> offsets_;
  const CameraClocks* clocks_ = nullptr;
};

class RecordedPoses final : public PoseProvider {
 public:
  explicit RecordedPoses(std::optional<Rig> rig) : rig_(std::move(rig)) {}
  std::string describe() const override { return "the poses recorded with each frame"; }
  FramePoses at(const StereoFrame& frame, TimestampNs) override {
    FramePoses p;
    const recorder::RecordedFrame* rf = frame.left.attachment ? frame.left.attachment->recorded() : nullptr;
    if (!rf) {
      p.problems.push_back("the frame comes from no recording");
      p.hud.status = "no pose: " + p.problems.back();
      return p;
    }
    const recorder::FrameRecord& r = rf->record;
    // A capture-only recording has the receiver's pose without a boom: the boom is then augrig's
    // to fly (it tracks the receptacle unless told otherwise).
    const bool has_receiver = r.T_body_receiver || (r.T_cam_receiver[0] && rig_);
    if (!r.boom && !has_receiver) {
      p.problems.push_back("frame " + std::to_string(rf->index) + " has no recorded scene");
      p.hud.status = "no pose: " + p.problems.back();
      return p;
    }
    // The boom and the receiver in the tanker body frame (or, when only the camera-relative pose
    // was recorded, through the recorded rig).
    SceneState s;
    if (r.boom) s.boom = *r.boom;
    if (r.T_body_receiver) {
      s.T_body_receiver = *r.T_body_receiver;
    } else if (r.T_cam_receiver[0] && rig_) {
      s.T_body_receiver = rig_->left().T_body_cam * *r.T_cam_receiver[0];
    } else {
      s.receiver_present = false;
    }
    if (r.receiver_present && !*r.receiver_present) s.receiver_present = false;
    p.scene = s;
    p.boom_given = r.boom.has_value();
    p.sigma_pos_m = r.sigma_pos_m;
    p.sigma_att_deg = r.sigma_att_deg;
    p.hud.status = "as recorded";
    p.hud.sigma_pos_m = r.sigma_pos_m;
    p.hud.sigma_att_deg = r.sigma_att_deg;
    return p;
  }

 private:
  std::optional<Rig> rig_;
};

class PosesCsv final : public PoseProvider {
 public:
  PosesCsv(std::string path, const Rig& rig, TimestampNs tolerance_ns, std::vector<nav::CameraPoseRow> rows)
      : path_(std::move(path)), T_body_cam_(rig.left().T_body_cam), tolerance_ns_(tolerance_ns) {
    for (const nav::CameraPoseRow& r : rows)
      if (r.camera == 0) by_t_[r.t_ns] = r;
  }
  std::string describe() const override { return "the poses of " + path_; }
  FramePoses at(const StereoFrame& frame, TimestampNs) override {
    FramePoses p;
    // The row nearest the left frame's timestamp, within the tolerance.
    const TimestampNs t = frame.left.t_ns;
    const nav::CameraPoseRow* best = nullptr;
    auto it = by_t_.lower_bound(t - tolerance_ns_);
    for (; it != by_t_.end() && it->first <= t + tolerance_ns_; ++it)
      if (!best || std::llabs(it->first - t) < std::llabs(best->t_ns - t)) best = &it->second;
    if (!best) {
      p.problems.push_back(path_ + ": no left-camera row at t_ns " + std::to_string(t) +
                           (tolerance_ns_ ? " (within " + std::to_string(tolerance_ns_) + " ns)" : ""));
      p.hud.status = "no pose: " + p.problems.back();
      return p;
    }
    const Pose T_cam_receiver{Eigen::Quaterniond(best->qw, best->qx, best->qy, best->qz).normalized(),
                              Eigen::Vector3d(best->x_m, best->y_m, best->z_m)};
    SceneState s;
    s.T_body_receiver = T_body_cam_ * T_cam_receiver;
    if (std::isfinite(best->boom_elevation_deg) && std::isfinite(best->boom_azimuth_deg) &&
        std::isfinite(best->boom_extension_m)) {
      s.boom = {deg_to_rad(best->boom_elevation_deg), deg_to_rad(best->boom_azimuth_deg),
                best->boom_extension_m};
      p.boom_given = true;
    }
    p.scene = s;
    p.sigma_pos_m = best->sigma_pos_m;
    p.sigma_att_deg = best->sigma_att_deg;
    p.hud.status = "from " + path_;
    p.hud.sigma_pos_m = best->sigma_pos_m;
    p.hud.sigma_att_deg = best->sigma_att_deg;
    return p;
  }

 private:
  std::string path_;
  Pose T_body_cam_;
  TimestampNs tolerance_ns_;
  std::map<TimestampNs, nav::CameraPoseRow> by_t_;
};

class OfflineNavPoses final : public PoseProvider {
 public:
  OfflineNavPoses(std::shared_ptr<const RelativeNav> nav, std::string name)
      : nav_(std::move(nav)), name_(std::move(name)) {}
  std::string describe() const override { return "the nav fused from " + name_ + " (smoothed)"; }
  FramePoses at(const StereoFrame& frame, TimestampNs) override {
    FramePoses p;
    auto fp = nav_->at(index_of(frame.left.camera), frame.left.t_ns);
    if (!fp) {
      p.problems.push_back(fp.error().message);
      p.hud.status = "no pose: outside the nav data";
      return p;
    }
    p.scene = SceneState{fp->boom.articulation, fp->body.T_a_receiver, true,
                         sun_light(fp->t_nav_ns, fp->T_ecef_tanker), {}};
    p.sigma_pos_m = fp->body.sigma_position_m();
    p.sigma_att_deg = rad_to_deg(fp->body.sigma_attitude_rad());
    p.hud.status = "fused from logs (smoothed)";
    p.t_nav_ns = fp->t_nav_ns;
    p.hud.sigma_pos_m = p.sigma_pos_m;
    p.hud.sigma_att_deg = p.sigma_att_deg;
    return p;
  }

 private:
  std::shared_ptr<const RelativeNav> nav_;
  std::string name_;
};

}  // namespace

std::unique_ptr<PoseProvider> fixed_scene_poses(const SceneState& scene, const std::string& name) {
  return std::make_unique<FixedScenePoses>(scene, name);
}
std::unique_ptr<PoseProvider> sim_truth_poses(const SimulatedFlight& sim) {
  return std::make_unique<SimTruthPoses>(sim);
}
std::unique_ptr<PoseProvider> live_nav_poses(const LiveNav& nav, std::vector<TimestampNs> camera_offset_ns,
                                             const CameraClocks* clocks) {
  return std::make_unique<LiveNavPoses>(nav, std::move(camera_offset_ns), clocks);
}
std::unique_ptr<PoseProvider> recorded_poses(std::optional<Rig> recorded_rig) {
  return std::make_unique<RecordedPoses>(std::move(recorded_rig));
}
Expected<std::unique_ptr<PoseProvider>> poses_csv(const std::string& path, const Rig& rig,
                                                  TimestampNs tolerance_ns) {
  auto log = nav::read_camera_pose_csv(path);
  if (!log) return log.error();
  bool any_left = false;
  for (const nav::CameraPoseRow& r : log->rows) any_left = any_left || r.camera == 0;
  if (!any_left) return make_error("pipeline::poses_csv(): ", path, ": no row of camera 0 (the left camera)");
  return std::unique_ptr<PoseProvider>(
      std::make_unique<PosesCsv>(path, rig, tolerance_ns, std::move(log->rows)));
}
std::unique_ptr<PoseProvider> offline_nav_poses(std::shared_ptr<const RelativeNav> nav, std::string name) {
  return std::make_unique<OfflineNavPoses>(std::move(nav), std::move(name));
}

Expected<ChosenPoses> choose_poses(const PoseSources& src, const Rig& rig,
                                   const Eigen::Vector3d& receptacle_m) {
  const char* kWhere = "choose_poses(): ";
  const int alternatives =
      int{!src.scene_path.empty()} + int{!src.poses_csv_path.empty()} + int{src.live_nav != nullptr};
  if (alternatives > 1)
    return make_error(kWhere, "a scene, a poses CSV and the live nav are three sources of poses: give one");
  ChosenPoses c;
  std::error_code ec;
  if (!src.scene_path.empty() && src.scene_folder_ok && std::filesystem::is_directory(src.scene_path, ec)) {
    // One scene file per pair.
    auto folder = SceneFolderPoses::load(src.scene_path, rig, receptacle_m);
    if (!folder) return folder.error();
    for (std::size_t k = 0; k < (*folder)->size(); ++k) c.scene_t_ns.push_back((*folder)->extras(k).t_ns);
    c.provider = std::move(*folder);
    c.may_miss_frames = true;
  } else if (!src.scene_path.empty()) {
    SceneExtras extras;
    auto scene = load_scene(src.scene_path, rig, src.boom_dims, receptacle_m, &extras);
    if (!scene) return scene.error();
    c.provider = fixed_scene_poses(*scene, src.scene_path);
    c.scene_t_ns.push_back(extras.t_ns);
  } else if (!src.poses_csv_path.empty()) {
    auto csv = poses_csv(src.poses_csv_path, rig, src.pose_tolerance_ns);
    if (!csv) return csv.error();
    c.provider = std::move(*csv);
    c.may_miss_frames = true;
  } else if (src.live_nav) {
    c.provider = live_nav_poses(*src.live_nav, src.camera_offset_ns, src.camera_clocks);
  } else if (src.recorded) {
    c.provider = recorded_poses(src.recorded_rig);
    c.may_miss_frames = true;
  } else if (src.sim) {
    c.provider = sim_truth_poses(*src.sim);
  }
  return c;
}

}  // namespace augrig::pipeline
