// The pipeline's own sinks, one file each: what `PipelineParts` names (the recorder, stats.csv,
// the per-frame files, the window's mailbox, the network live view, a command's per-pair output)
// becomes one of these when a run starts; further outputs come from the sink registry
// (pipeline/sinks/registry.hpp: `--sink video:FILE.mp4`). See pipeline/frame_sink.hpp for the
// order a pair goes through them.
#pragma once

#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "net/foxglove_server.hpp"
#include "pipeline/frame_sink.hpp"
#include "pipeline/live_view.hpp"
#include "pipeline/nav_inputs.hpp"
#include "pipeline/outputs.hpp"
#include "recorder/recorder.hpp"
#include "render/rig.hpp"

namespace augrig::pipeline {

// stats.csv: a row per augmented pair (stats_sink.cpp).
std::unique_ptr<FrameSink> make_stats_sink(std::unique_ptr<StatsCsvWriter> writer);
// The per-frame images (and ground truth) of every `every`-th augmented pair (frame_files_sink.cpp).
std::unique_ptr<FrameSink> make_frame_files_sink(FrameFiles files, const Rig& rig);
// A command's own per-pair output, e.g. evaluate's matchers or the demo's files (callback_sink.cpp).
using PairCallback = std::function<Status(const StereoFrame& raw, const StereoResult& result,
                                          const SceneState& scene, const FramePoses& poses)>;
std::unique_ptr<FrameSink> make_callback_sink(PairCallback on_pair);
// The network live view: each pair as it is made, events and the run's health (foxglove_sink.cpp).
std::unique_ptr<FrameSink> make_foxglove_sink(std::shared_ptr<net::FoxgloveServer> server);
// The window's mailbox: whole augmented pairs (or, captured only, the raw pair) (view_sink.cpp).
std::unique_ptr<FrameSink> make_view_sink(std::shared_ptr<LiveView> view);

// The recording (recorder_sink.cpp): each pair's raw frame (moved in, never copied), the changed
// boxes, masks, statistics, poses, boom and, asked for, the receiver depth; the events, the look's
// updates, and at the close the drop ledger, so that every frame read is accounted for. The
// pipeline keeps a pointer to it: the window pauses and resumes it, the HUD shows its state.
class RecorderSink final : public FrameSink {
 public:
  RecorderSink(recorder::Recorder& recorder, const Rig& rig, bool ground_truth, NavInputs* nav_inputs);
  SinkNeeds needs() const override;
  Status consume(PairContext& pair) override;
  void release(PairContext& pair) override;
  void event(const SinkEvent& e) override;
  Status close(PipelineReport& report) override;

  void set_on(bool on) { on_ = on; }
  bool on() const { return on_; }
  // "on", "paused" or "stopped" (a write failed: disk full; what was recorded stays valid).
  std::string state() const;
  // The recorder's failure, once, the first time it is asked after the recorder failed.
  std::optional<std::string> newly_failed();
  std::uint64_t frames_dropped() const { return recorder_.stats().frames_dropped; }
  const std::string& path() const { return path_; }
  LatencyHud latency() const;  // mid-exposure to the hand-off, over the last pairs

 private:
  recorder::Recorder& recorder_;
  const Rig& rig_;
  bool ground_truth_;
  NavInputs* nav_inputs_;
  std::string path_;
  bool on_ = true, failed_ = false;
  std::optional<recorder::FrameRecord> pending_;  // this pair's boxes, until its raw frame comes
  SkewStats latency_;
  std::deque<double> recent_ms_;  // the last 300
};

}  // namespace augrig::pipeline
