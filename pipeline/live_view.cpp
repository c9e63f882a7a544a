#include "pipeline/live_view.hpp"

#include <algorithm>

#include "core/clock.hpp"

namespace augrig::pipeline {

LatencyHud rolling_hud(std::vector<double> v) {
  LatencyHud h;
  if (v.empty()) return h;
  std::sort(v.begin(), v.end());
  h.p50_ms = v[v.size() / 2];
  h.p99_ms = v[std::min(v.size() - 1, v.size() * 99 / 100)];
  return h;
}

// ---- Commands and the mailbox -----------------------------------------------------------------

void PipelineCommands::merge(const PipelineCommands& o) {
  quit = quit || o.quit;
  toggle_pause = toggle_pause != o.toggle_pause;
  toggle_recording = toggle_recording != o.toggle_recording;
  if (o.boom_mode) boom_mode = o.boom_mode;
  boom_nudge.elevation_rad += o.boom_nudge.elevation_rad;
  boom_nudge.azimuth_rad += o.boom_nudge.azimuth_rad;
  boom_nudge.extension_m += o.boom_nudge.extension_m;
  steps += o.steps;
  if (o.seek_frame) seek_frame = o.seek_frame;
  if (o.rate) rate = o.rate;
}

void LiveView::publish(StereoResult& result, const SceneState& scene, TimestampNs mid_host_ns) {
  std::lock_guard lock(mutex_);
  std::swap(newest_.result, result);
  newest_.scene = scene;
  newest_.id++;
  newest_mid_host_ns_ = mid_host_ns;
  changed_.notify_all();
}

void LiveView::set_hud(HudState hud, std::optional<Playback> playback) {
  std::lock_guard lock(mutex_);
  hud.latency_display = rolling_hud(recent_ms_);
  hud_ = std::move(hud);
  playback_ = playback;
}

PipelineCommands LiveView::take_commands() {
  std::lock_guard lock(mutex_);
  PipelineCommands c = std::move(commands_);
  commands_ = {};
  return c;
}

void LiveView::finish() {
  std::lock_guard lock(mutex_);
  finished_ = true;
  changed_.notify_all();
}

bool LiveView::wait_newer(std::uint64_t shown_id, std::chrono::nanoseconds timeout) const {
  std::unique_lock lock(mutex_);
  return changed_.wait_for(lock, timeout, [&] { return newest_.id != shown_id || finished_; });
}

TimestampNs LiveView::take_newest(Shown& shown) {
  std::lock_guard lock(mutex_);
  if (newest_.id == shown.id) return 0;
  std::swap(newest_.result, shown.result);
  shown.scene = newest_.scene;
  shown.id = newest_.id;
  return newest_mid_host_ns_;
}

HudState LiveView::hud() const {
  std::lock_guard lock(mutex_);
  return hud_;
}

std::optional<Playback> LiveView::playback() const {
  std::lock_guard lock(mutex_);
  return playback_;
}

void LiveView::post(const PipelineCommands& c) {
  std::lock_guard lock(mutex_);
  commands_.merge(c);
}

bool LiveView::finished() const {
  std::lock_guard lock(mutex_);
  return finished_;
}

void LiveView::drawn(TimestampNs mid_host_ns) {
  if (mid_host_ns) add_latency(monotonic_now_ns() - mid_host_ns);
}

void LiveView::add_latency(TimestampNs ns) {
  std::lock_guard lock(mutex_);
  if (recent_ms_.size() == 300) recent_ms_.erase(recent_ms_.begin());
  recent_ms_.push_back(static_cast<double>(ns) / 1e6);
  display_hist_.add(ns);
}

LatencyHud LiveView::display_latency() const {
  std::lock_guard lock(mutex_);
  return rolling_hud(recent_ms_);
}

}  // namespace augrig::pipeline
