// LiveView: the mailbox between the pipeline's thread and the window's (or any controller's): the
// newest augmented pair (by swap, never copied), the HUD, the playback position of a recording,
// and the window's commands back. Neither side waits for the other. The pipeline's side is the
// view sink (pipeline/sinks/view_sink.cpp) and the pipeline's loop (the HUD and the commands);
// the window's side is app/window_runner.cpp.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <vector>

#include "capture/stereo_pairer.hpp"
#include "core/frame.hpp"
#include "pipeline/status.hpp"
#include "render/augmenter.hpp"
#include "render/stats.hpp"

namespace augrig::pipeline {

// What the window (or any controller) asks of the running pipeline; merged until taken.
struct PipelineCommands {
  bool quit = false;
  bool toggle_pause = false;
  bool toggle_recording = false;
  std::optional<DisplayBoomMode> boom_mode;
  BoomNudge boom_nudge;
  int steps = 0;                          // paused: advance this many stereo frames (replay)
  std::optional<std::size_t> seek_frame;  // replay: jump to this recorded frame
  std::optional<double> rate;             // replay: real rate x (0: as fast as possible)
  void merge(const PipelineCommands& o);
};

// Where the playback of a recording stands, for the window's timeline.
struct Playback {
  std::size_t frame = 0;           // the recorded index of the frame shown
  std::size_t frame_count = 0;     // frames in the recording
  double t_s = 0, duration_s = 0;  // from the first frame
  int pass = 0;
  double rate = 0;  // real rate x; 0: as fast as possible
};

// The mailbox between the pipeline's thread and the window's: the newest augmented pair (by
// swap, never copied), the HUD, the playback position, and commands back. Neither side waits.
class LiveView {
 public:
  // ---- The pipeline's side ----
  // Hands over a new augmented pair (whole augmented images); `result` gets the previous buffers.
  void publish(StereoResult& result, const SceneState& scene, TimestampNs mid_host_ns);
  void set_hud(HudState hud, std::optional<Playback> playback);
  PipelineCommands take_commands();
  void finish();  // the pipeline stopped: the window closes
  // ---- The window's side ----
  struct Shown {
    StereoResult result;
    SceneState scene;
    std::uint64_t id = 0;  // 0: nothing yet
  };
  // Swaps the newest pair into `shown` when there is one newer than shown.id; returns its
  // mid-exposure on the host clock (0: no new pair or unknown).
  TimestampNs take_newest(Shown& shown);
  HudState hud() const;
  std::optional<Playback> playback() const;
  void post(const PipelineCommands& c);
  bool finished() const;
  // Waits until a pair newer than `shown_id` is published or the pipeline finished (true), or the
  // timeout passed (false): the window draws a new pair as soon as it is handed over.
  bool wait_newer(std::uint64_t shown_id, std::chrono::nanoseconds timeout) const;
  // The window drew the pair with mid-exposure `mid_host_ns`: its latency to the screen.
  void drawn(TimestampNs mid_host_ns);
  // Mid-exposure to the window's draw (or, headless, to the hand-off), over the last pairs.
  LatencyHud display_latency() const;
  const SkewStats& display_histogram() const { return display_hist_; }

 private:
  void add_latency(TimestampNs ns);
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;  // a new pair or the finish
  Shown newest_;
  TimestampNs newest_mid_host_ns_ = 0;
  HudState hud_;
  std::optional<Playback> playback_;
  PipelineCommands commands_;
  bool finished_ = false;
  std::vector<double> recent_ms_;  // the last 300 latencies, for the HUD
  SkewStats display_hist_;         // the whole run's, for the summary
};

// The last latencies (ms) as the HUD's p50/p99.
LatencyHud rolling_hud(std::vector<double> v);

}  // namespace augrig::pipeline
