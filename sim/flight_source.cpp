#include "sim/flight_source.hpp"

#include <algorithm>
#include <cmath>

#include "nav/geodesy.hpp"
#include "nav/solar_position.hpp"

namespace augrig::sim {

std::vector<FrameTruth> frame_truths(const Scenario& scenario, const Flight& flight,
                                     const std::vector<std::vector<CameraFrameTime>>& cameras) {
  std::vector<FrameTruth> out;
  for (std::size_t c = 0; c < cameras.size() && c < scenario.rig.cameras.size(); ++c) {
    const Pose T_cam_body = scenario.rig.cameras[c].T_body_cam.inverse();
    for (const CameraFrameTime& f : cameras[c]) {
      if (f.dropped) continue;  // never delivered: the drop ledger counts it, nothing else sees it
      FrameTruth t;
      t.sequence = f.sequence;
      t.camera = static_cast<int>(c);
      t.t_camera_ns = f.t_camera_ns;
      t.t_true_s = f.t_true_s;
      t.t_gps_ns = scenario.start_gps_ns + s_to_ns(f.t_true_s);
      t.T_body_receiver = flight.T_tanker_receiver(f.t_true_s);
      t.T_cam_receiver = T_cam_body * t.T_body_receiver;
      t.boom = flight.boom(f.t_true_s);
      t.phase = flight.phase(f.t_true_s);
      out.push_back(std::move(t));
    }
  }
  // Delivery order: by camera timestamp, left before right on ties.
  std::stable_sort(out.begin(), out.end(), [](const FrameTruth& a, const FrameTruth& b) {
    return a.t_camera_ns != b.t_camera_ns ? a.t_camera_ns < b.t_camera_ns : a.camera < b.camera;
  });
  return out;
}

nav::CameraPoseRow pose_row(const FrameTruth& t) {
  nav::CameraPoseRow r;
  r.sequence = t.sequence, r.camera = t.camera, r.t_ns = t.t_camera_ns, r.t_nav_ns = t.t_gps_ns;
  const Eigen::Vector3d& p = t.T_cam_receiver.translation_m;
  const Eigen::Quaterniond& q = t.T_cam_receiver.rotation;
  r.x_m = p.x(), r.y_m = p.y(), r.z_m = p.z(), r.qw = q.w(), r.qx = q.x(), r.qy = q.y(), r.qz = q.z();
  r.sigma_pos_m = 0, r.sigma_att_deg = 0;
  r.boom_elevation_deg = rad_to_deg(t.boom.elevation_rad);
  r.boom_azimuth_deg = rad_to_deg(t.boom.azimuth_rad);
  r.boom_extension_m = t.boom.extension_m;
  return r;
}

BoomArticulation boom_rate(const Flight& flight, double t_s) {
  constexpr double h_s = 1e-4;  // the boom follows turbulence: a step well under its time scales
  const BoomArticulation a0 = flight.boom(t_s - h_s), a1 = flight.boom(t_s + h_s);
  return {(a1.elevation_rad - a0.elevation_rad) / (2 * h_s), (a1.azimuth_rad - a0.azimuth_rad) / (2 * h_s),
          (a1.extension_m - a0.extension_m) / (2 * h_s)};
}

SkyState sky_at(const Scenario& scenario, const Flight& flight, double t_s) {
  const KinematicState k = flight.tanker(t_s);
  const nav::Geodetic g = nav::geodetic_from_ecef(k.p_ecef_m);
  SkyState sky;
  sky.R_ned_body = nav::R_ecef_ned(g.lat_rad, g.lon_rad).transpose() * k.R_ecef_body();
  sky.altitude_m = g.h_m;  // the ground is the ellipsoid: flat terrain at height 0
  // The ground texture is fixed to the Earth: north/east of the start point, in its NED frame
  // (only the texture uses this, so the tangent-plane approximation is harmless).
  const Eigen::Vector3d d_ned = nav::R_ecef_ned(scenario.start.lat_rad, scenario.start.lon_rad).transpose() *
                                (k.p_ecef_m - nav::ecef_from_geodetic(scenario.start));
  sky.north_east_m = d_ned.head<2>();
  // The sun from the ephemeris the camera look uses (nav/solar_position.hpp), at the frame's GPS time.
  sky.sun_ned = nav::solar_position(scenario.start_gps_ns + s_to_ns(t_s), g).sun_ned;
  return sky;
}

Expected<std::unique_ptr<FlightSource>> FlightSource::create(const Scenario& scenario, const Flight& flight,
                                                             std::vector<FrameTruth> frames, int every,
                                                             SceneBackend backend) {
  std::unique_ptr<FlightSource> s(new FlightSource());
  s->scenario_ = scenario;
  s->flight_ = &flight;
  if (every > 1) {
    std::erase_if(frames, [every](const FrameTruth& f) { return f.sequence % every != 0; });
  }
  s->frames_ = std::move(frames);
  SceneRendererOptions options;
  options.backend = backend;
  auto renderer = SyntheticSceneRenderer::create(scenario.rig, nullptr, options);
  if (!renderer) return renderer.error();
  s->renderer_ = std::move(*renderer);
  s->sensor_.format = scenario.sensors.cameras.format;
  const CameraTimingConfig& cam = scenario.sensors.cameras;
  s->sensor_.noise_sigma = cam.noise_sigma;
  s->sensor_.noise_a = cam.noise_a, s->sensor_.psf_sigma_px = cam.psf_sigma_px;
  s->sensor_.gain = cam.gain, s->sensor_.gamma = cam.gamma;
  s->sensor_.exposure_ms = cam.exposure_ms;
  return s;
}

Expected<ReadStatus> FlightSource::read(Frame& out, std::chrono::nanoseconds) {
  if (next_ >= frames_.size()) return ReadStatus::kEndOfStream;
  const FrameTruth& t = frames_[next_];
  // Sensor noise differs per frame but is reproducible: seeded by the scenario and the frame.
  SensorOptions sensor = sensor_;
  sensor.noise_seed = derive_seed(scenario_.seed, "camera-noise") ^ (t.sequence * 0x9E3779B97F4A7C15ull);
  const SkyState sky = sky_at(scenario_, *flight_, t.t_true_s);
  if (auto s = physical_boom_
                   ? renderer_->render_with_boom(t.camera, sky, t.T_body_receiver, true, t.boom,
                                                 boom_rate(*flight_, t.t_true_s), sensor, out.image)
                   : renderer_->render(t.camera, sky, t.T_body_receiver, true, sensor, out.image);
      !s)
    return s.error();
  out.exposure_ns = std::llround(1e6 * sensor.exposure_ms);  // 0: unknown, as a camera that says none
  out.camera = t.camera == 0 ? CameraId::kLeft : CameraId::kRight;
  out.sequence = t.sequence;
  out.t_ns = t.t_camera_ns;
  out.clock = ClockDomain::kDevice;
  ++next_;
  return ReadStatus::kFrame;
}

}  // namespace augrig::sim
