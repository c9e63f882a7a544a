#include "pipeline/look_stage.hpp"

#include <cmath>
#include <cstdio>
#include <iomanip>
#include <sstream>

#include <pthread.h>
#include <sched.h>

#include "core/thread_name.hpp"
#include "nav/geodesy.hpp"
#include "nav/solar_position.hpp"

namespace augrig::pipeline {

namespace {

std::string camera_name(std::size_t c) {
  return c == 0 ? "left" : c == 1 ? "right" : "camera " + std::to_string(c);
}

// "a 0.213 b 1.90" per channel (R G B for colour).
std::string describe(const NoiseLevelFunction& f) {
  if (f.empty()) return "none yet";
  std::ostringstream o;
  char buf[64];
  for (int c = 0; c < f.channels; ++c) {
    std::snprintf(buf, sizeof buf, "a %.3g b %.3g", f.a[c], f.b[c]);
    o << (c ? ", " : "") << (f.channels == 3 ? std::string(1, "RGB"[c]) + " " : "") << buf;
  }
  return o.str();
}

// The mean linear level per colour channel (R, G, B) of an image over a grid of every 8th pixel
// (a Bayer mosaic: the 2x2 cell there; Mono: one level for all three), through the tone curve
// x^gamma: the light the scene around the cameras sends back (for cameras looking down at the
// receiver, mostly the ground's or the clouds'), with its colour.
Eigen::Vector3d mean_linear_level(const Image& img, double gamma) {
  const PixelFormat f = img.format();
  const int bpp = bytes_per_pixel(f);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  auto add = [&](int c, std::uint8_t v8) {
    const double v = v8 / 255.0;
    sum[c] += gamma == 1.0 ? v : std::pow(v, gamma), n[c] += 1;
  };
  for (int y = 2; y + 1 < img.height(); y += 8)
    for (int x = 2; x + 1 < img.width(); x += 8) {
      if (is_bayer(f)) {
        for (int dy = 0; dy < 2; ++dy)
          for (int dx = 0; dx < 2; ++dx) add(bayer_channel(f, x + dx, y + dy), img.row(y + dy)[x + dx]);
      } else if (bpp == 1) {
        for (int c = 0; c < 3; ++c) add(c, img.row(y)[x]);
      } else {
        for (int c = 0; c < 3; ++c) add(c, img.row(y)[x * bpp + c]);
      }
    }
  for (int c = 0; c < 3; ++c) sum[c] = n[c] > 0 ? sum[c] / n[c] : 0.0;
  return sum;
}

}  // namespace

SceneLight sun_light(TimestampNs t_gps_ns, const Pose& T_ecef_tanker) {
  const nav::Geodetic where = nav::geodetic_from_ecef(T_ecef_tanker.translation_m);
  const nav::SolarPosition sun = nav::solar_position(t_gps_ns, where);
  const Eigen::Matrix3d R_body_ecef = T_ecef_tanker.R().transpose();
  const Eigen::Vector3d towards_sun_body = R_body_ecef * nav::sun_direction_ecef(sun, where);
  const Eigen::Vector3d down_body = R_body_ecef * nav::R_ecef_ned(where.lat_rad, where.lon_rad).col(2);
  constexpr double kEarthRadius_m = 6371000.0;
  const double dip_rad = std::acos(kEarthRadius_m / (kEarthRadius_m + std::max(where.h_m, 0.0)));
  return SceneLight::sun(towards_sun_body, kPi / 2 - sun.zenith_rad > -dip_rad, LightSource::kEphemeris,
                         down_body);
}

LookStage::LookStage(LookConfig config) : config_(std::move(config)) {
  noise_.resize(config_.cameras.size());
  fresh_.assign(config_.cameras.size(), false);
  bool estimate = false;
  for (std::size_t c = 0; c < config_.cameras.size(); ++c) {
    noise_[c].configured = !config_.cameras[c].noise.empty();
    noise_[c].nlf = config_.cameras[c].noise;
    estimate |= !noise_[c].configured;
    estimators_.emplace_back();
  }
  estimating_ = config_.look == Look::kCamera && estimate;
  if (estimating_ && !config_.synchronous) thread_ = std::thread([this] { estimator_loop(); });
}

LookStage::~LookStage() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

Status LookStage::configure(Augmenter& augmenter) {
  if (config_.look != Look::kCamera) return {};
  probe_.emplace(augmenter.receiver_model());
  for (std::size_t c = 0; c < config_.cameras.size(); ++c)
    if (auto s = augmenter.set_camera_look(static_cast<int>(c), config_.cameras[c]); !s) return s;
  return {};
}

std::vector<std::string> LookStage::before_augment(const StereoFrame& frame, SceneState& scene,
                                                   Augmenter& augmenter) {
  std::vector<std::string> notes;
  // The sun: the pose source's where it knows time and place; else the default, said once. In
  // either look: the boom's shadow on the receiver (a mask bit) follows it.
  if (scene.light.source == LightSource::kFixed) {
    scene.light = SceneLight::default_sun();
    if (!default_sun_said_)
      notes.push_back(
          "look: no time or position for the sun from the pose source; the boom is lit and casts its shadow "
          "by the default sun (45 deg up, 45 deg right of the nose; docs/LOOK.md)");
    default_sun_said_ = true;
  }
  last_light_ = scene.light.source;
  if (config_.look != Look::kCamera) return notes;
  if (!exposure_said_) notes.push_back(exposure_note(frame)), exposure_said_ = true;
  const TimestampNs t = frame.t_key_ns, every = s_to_ns(config_.noise_every_s);
  if (sampled_ && (t < next_sample_ns_ - 2 * every)) sampled_ = false;  // time went back (a loop, a seek)
  const bool sample = !sampled_ || t >= next_sample_ns_;
  // The ground's light: what the frames around the boom send back (cheap: a sparse grid).
  if (sample) {
    const double g = config_.cameras.empty() ? 1.0 : config_.cameras[0].gamma;
    ground_ = Eigen::Vector3d(
        0.5 * (mean_linear_level(frame.left.image, g) + mean_linear_level(frame.right.image, g)));
  }
  if (scene.light.source != LightSource::kConfigured) {
    if (probe_fit_) {
      // Measured on the receiver; the sun's share only while the sun is up.
      scene.light.direct = scene.light.sun_up ? probe_fit_->direct : Eigen::Vector3d::Zero();
      scene.light.sky = probe_fit_->sky, scene.light.ground = probe_fit_->ground;
    } else if (ground_) {
      scene.light.ground = *ground_;
    }
  }
  probe_due_ = sample && probe_ && scene.light.source != LightSource::kConfigured;
  const bool due = estimating_ && sample;
  std::unique_lock lock(mutex_);
  if (due && config_.synchronous) {
    // At the frames' own times, before this pair: runs are repeatable.
    lock.unlock();
    estimate({&frame.left.image, &frame.right.image});
    lock.lock();
  } else if (due && !busy_ && pending_.empty()) {
    // Copied: the pair's buffers go on down the pipeline.
    pending_ = {Image::copy_of(frame.left.image.view()), Image::copy_of(frame.right.image.view())};
    busy_ = true;
    cv_.notify_all();
  }
  if (sample) sampled_ = true, next_sample_ns_ = t + every;
  hand_over(augmenter, notes);
  return notes;
}

std::string LookStage::exposure_note(const StereoFrame& frame) const {
  // Motion blur needs the exposure (render/motion_blur.hpp): the rig's key, else the frames'.
  std::ostringstream o;
  o << "look: exposure";
  bool unknown = true;
  for (std::size_t c = 0; c < config_.cameras.size() && c < 2; ++c) {
    const double rig_ms = config_.cameras[c].exposure_ms;
    const std::int64_t frame_ns = (c == 0 ? frame.left : frame.right).exposure_ns;
    o << (c ? "; " : " ") << camera_name(c) << " ";
    if (rig_ms >= 0)
      o << rig_ms << " ms (the rig's look.exposure_ms)", unknown = false;
    else if (frame_ns > 0)
      o << 1e-6 * static_cast<double>(frame_ns) << " ms (its frames')", unknown = false;
    else
      o << "unknown";
  }
  o << (unknown ? ": the boom is drawn without motion blur (give the rig's look.exposure_ms; docs/LOOK.md)"
                : ": a moving boom is blurred over it, a camera without one is not");
  return o.str();
}

void LookStage::after_augment(const StereoFrame& frame, const SceneState& scene, const StereoResult& result,
                              const Rig& rig) {
  if (!probe_due_ || !scene.receiver_present || rig.cameras.size() < 2) return;
  probe_due_ = false;
  probe_->clear();
  const double g = config_.cameras.empty() ? 1.0 : config_.cameras[0].gamma;
  probe_->add_view(frame.left.image, result.left.mask, result.left.receiver_depth, rig.cameras[0],
                   scene.T_body_receiver, g);
  probe_->add_view(frame.right.image, result.right.mask, result.right.receiver_depth, rig.cameras[1],
                   scene.T_body_receiver, g);
  std::string why;
  if (auto fit =
          probe_->fit(scene.light.towards_light_body, scene.light.down_body, scene.light.sun_up, &why)) {
    // Smoothed over the sampled pairs: the light changes slowly, the points in view do not. Each
    // fit weighs as many points as it used, the previous one half its own: a receiver coming
    // closer (ten times the points) is soon measured by what it shows now, not by its far past.
    if (probe_fit_) {
      const double w_new = static_cast<double>(fit->samples),
                   w_old = 0.5 * static_cast<double>(probe_fit_->samples), w = 1.0 / (w_new + w_old);
      fit->direct = w * (w_new * fit->direct + w_old * probe_fit_->direct);
      fit->sky = w * (w_new * fit->sky + w_old * probe_fit_->sky);
      fit->ground = w * (w_new * fit->ground + w_old * probe_fit_->ground);
    }
    probe_fit_ = fit;
    probe_note_.clear();
  } else {
    probe_note_ = why;
  }
}

void LookStage::estimator_loop() {
  set_thread_name("augrig-noise");
  // Background work: on a machine whose cores the capture, the augmenter and the window already
  // keep busy it runs in their idle time (SCHED_IDLE, this thread only) and never delays a frame;
  // a late estimate only means the previous one is used a little longer.
  const sched_param idle{};
  if (pthread_setschedparam(pthread_self(), SCHED_IDLE, &idle) != 0)
    std::fprintf(stderr, "look: the noise estimator runs at normal priority (SCHED_IDLE refused)\n");
  std::unique_lock lock(mutex_);
  for (;;) {
    cv_.wait(lock, [&] { return stop_ || !pending_.empty(); });
    if (stop_) return;
    std::vector<Image> frames = std::move(pending_);
    pending_.clear();
    lock.unlock();
    estimate({&frames[0], frames.size() > 1 ? &frames[1] : nullptr});
    lock.lock();
    busy_ = false;
    cv_.notify_all();
  }
}

void LookStage::estimate(const std::vector<const Image*>& frames) {
  // A few ms per frame; only this function touches the estimators.
  std::vector<std::optional<Expected<NoiseFitReport>>> fits(frames.size());
  for (std::size_t c = 0; c < frames.size() && c < estimators_.size(); ++c) {
    if (noise_[c].configured || !frames[c]) continue;
    if (estimators_[c].frames() >= static_cast<std::uint64_t>(config_.noise_window)) estimators_[c].clear();
    if (auto s = estimators_[c].add(*frames[c]); !s) {
      fits[c] = s.error();
      continue;
    }
    fits[c] = estimators_[c].fit();
  }
  std::lock_guard lock(mutex_);
  for (std::size_t c = 0; c < fits.size(); ++c) {
    if (!fits[c]) continue;
    CameraNoiseState& n = noise_[c];
    if (*fits[c]) {
      n.nlf = (*fits[c])->nlf;
      n.note = (*fits[c])->note;
      n.frames = estimators_[c].frames();
      ++n.fits;
      fresh_[c] = true;
    } else {
      n.note = fits[c]->error().message;
    }
  }
}

void LookStage::hand_over(Augmenter& augmenter, std::vector<std::string>& notes) {
  for (std::size_t c = 0; c < fresh_.size(); ++c) {
    CameraNoiseState& n = noise_[c];
    if (!n.configured && n.fits == 0 && !n.note.empty() && !n.failure_said) {
      notes.push_back("look: " + camera_name(c) +
                      " camera's noise cannot be estimated from its frames yet (" + n.note +
                      "); none is added until it can (or give the rig's look.noise_a/noise_b)");
      n.failure_said = true;
    }
    if (!fresh_[c]) continue;
    fresh_[c] = false;
    CameraLookParams p = augmenter.camera_look(static_cast<int>(c));
    p.noise = noise_[c].nlf;
    if (auto s = augmenter.set_camera_look(static_cast<int>(c), p); !s) notes.push_back(s.error().message);
    if (noise_[c].fits == 1)
      notes.push_back("look: " + camera_name(c) + " camera's noise estimated from its frames: " +
                      describe(noise_[c].nlf) + (noise_[c].note.empty() ? "" : " (" + noise_[c].note + ")"));
  }
}

void LookStage::flush() {
  std::unique_lock lock(mutex_);
  cv_.wait(lock, [&] { return stop_ || (!busy_ && pending_.empty()); });
}

std::vector<CameraNoiseState> LookStage::noise() const {
  std::lock_guard lock(mutex_);
  return noise_;
}

std::string LookStage::status() const {
  if (config_.look != Look::kCamera) return "look plain";
  std::ostringstream o;
  o << "look camera: sun " << to_string(last_light_) << std::setprecision(3);
  auto rgb = [&o](const Eigen::Vector3d& v) { o << v.x() << " " << v.y() << " " << v.z(); };
  if (probe_fit_) {
    o << "; light on the receiver (" << probe_fit_->samples << " points): direct ";
    rgb(probe_fit_->direct), o << ", sky ", rgb(probe_fit_->sky), o << ", ground ", rgb(probe_fit_->ground);
  } else if (ground_) {
    o << ", ground light ", rgb(*ground_);
    if (!probe_note_.empty()) o << " (receiver: " << probe_note_ << ")";
  }
  o << "; noise";
  std::lock_guard lock(mutex_);
  for (std::size_t c = 0; c < noise_.size(); ++c) {
    o << (c ? "; " : " ") << camera_name(c) << " " << describe(noise_[c].nlf);
    if (noise_[c].configured)
      o << " (configured)";
    else if (noise_[c].fits)
      o << " (" << noise_[c].fits << " estimates)";
    else if (!noise_[c].note.empty())
      o << " (" << noise_[c].note << ")";
  }
  return o.str();
}

}  // namespace augrig::pipeline
