#include "pipeline/look_updates.hpp"

namespace augrig::pipeline {

namespace {

bool same_fit(const LightFit& a, const LightFit& b) {
  return a.direct == b.direct && a.sky == b.sky && a.ground == b.ground && a.samples == b.samples &&
         a.rms == b.rms;
}

}  // namespace

std::vector<recorder::LookRecord> LookUpdates::take(const LookStage& look, const Augmenter& augmenter,
                                                    const StereoFrame& frame, const SceneLight& light) {
  std::vector<recorder::LookRecord> out;
  if (look.look() != Look::kCamera) return out;
  auto stamped = [&](auto update) {
    recorder::LookRecord r;
    r.t_ns = frame.t_key_ns;
    r.clock = frame.left.clock;
    r.update = std::move(update);
    return r;
  };
  const std::vector<CameraNoiseState> state = look.noise();
  noise_.resize(state.size());
  for (std::size_t c = 0; c < state.size(); ++c) {
    // The augmenter's, not the estimator's latest: a live estimate reaches the augmenter between
    // two pairs, after the estimator has it.
    const NoiseLevelFunction& used = augmenter.camera_look(static_cast<int>(c)).noise;
    if (used.empty() || used == noise_[c]) continue;
    noise_[c] = used;
    recorder::LookNoise n;
    n.camera = static_cast<int>(c);
    n.nlf = used;
    n.configured = state[c].configured;
    // The estimator's word on this very estimate; a live estimator that is already one further
    // (a frame rate under 2 per second) leaves frames 0, unknown.
    if (!n.configured && state[c].nlf == used) {
      n.frames = state[c].frames;
      n.note = state[c].note;
    }
    out.push_back(stamped(std::move(n)));
  }
  const std::optional<LightFit>& fit = look.receiver_light();
  if (fit && !(light_ && same_fit(*light_, *fit))) {
    light_ = fit;
    recorder::LookLight l;
    l.direct = fit->direct;
    l.sky = fit->sky;
    l.ground = fit->ground;
    l.samples = fit->samples;
    l.rms = fit->rms;
    l.source = light.source;
    l.sun_up = light.sun_up;
    l.towards_sun_body = light.towards_light_body;
    out.push_back(stamped(std::move(l)));
  }
  return out;
}

}  // namespace augrig::pipeline
