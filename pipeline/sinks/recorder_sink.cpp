// The recording as a sink. Per pair: in consume() the changed boxes, masks, statistics (and the
// receiver depth) are copied while they are the augmenter's boxes, before any sink makes them
// whole; in release() the raw frame is moved in with the poses and the boom, and the frame pushed
// (never blocking: a full queue drops it into the ledger). Events and the look's updates go in as
// they come; at the close the drop ledger, so that read = 2 x pairs + every ledger row.
#include <vector>

#include "core/clock.hpp"
#include "pipeline/report.hpp"
#include "pipeline/sinks/sinks.hpp"

namespace augrig::pipeline {

RecorderSink::RecorderSink(recorder::Recorder& recorder, const Rig& rig, bool ground_truth,
                           NavInputs* nav_inputs)
    : recorder_(recorder),
      rig_(rig),
      ground_truth_(ground_truth),
      nav_inputs_(nav_inputs),
      path_(recorder.path()) {}

SinkNeeds RecorderSink::needs() const {
  return {.look_updates = true};
}

Status RecorderSink::consume(PairContext& pair) {
  if (pair.look_updates)
    for (recorder::LookRecord& u : *pair.look_updates) recorder_.push(std::move(u));
  if (on_ && pair.result) pending_ = frame_record(*pair.result, ground_truth_);
  return {};
}

void RecorderSink::release(PairContext& pair) {
  if (!on_) return;
  recorder::FrameRecord fr = pending_ ? std::move(*pending_) : recorder::FrameRecord{};
  pending_.reset();
  if (pair.mid_host_ns) {
    const TimestampNs ns = monotonic_now_ns() - pair.mid_host_ns;
    latency_.add(ns);
    if (recent_ms_.size() == 300) recent_ms_.pop_front();
    recent_ms_.push_back(static_cast<double>(ns) / 1e6);
  }
  record_scene(pair, rig_, fr);
  fr.raw = std::move(pair.raw);
  recorder_.push(std::move(fr));
}

void RecorderSink::event(const SinkEvent& e) {
  recorder_.push(recorder::EventRecord{e.t_ns, e.clock, e.text});
}

std::string RecorderSink::state() const {
  return failed_ ? "stopped" : on_ ? "on" : "paused";
}

std::optional<std::string> RecorderSink::newly_failed() {
  if (failed_) return std::nullopt;
  const Status st = recorder_.status();
  if (st) return std::nullopt;
  failed_ = true;
  return st.error().message;
}

LatencyHud RecorderSink::latency() const {
  return rolling_hud({recent_ms_.begin(), recent_ms_.end()});
}

Status RecorderSink::close(PipelineReport& report) {
  if (nav_inputs_) nav_inputs_->ledger(recorder_);
  const StereoSourceStats& st = report.source;
  // The sources count their own gaps without timestamps; every other row has the first and last
  // frame time of what it counts.
  auto ledger = [&](recorder::DropStage stage, std::uint64_t n, const TimeSpan& t, const std::string& why) {
    if (n) recorder_.push(recorder::DropRecord{stage, n, t.first_t_ns, t.last_t_ns, why, "frame"});
  };
  ledger(recorder::DropStage::kCamera, st.camera_drops, {}, "frame-id gaps reported by the cameras");
  ledger(recorder::DropStage::kTransport, st.transport_drops, {}, "incomplete or failed buffers");
  ledger(recorder::DropStage::kPairing, st.pairing.unpaired_at_start.count, st.pairing.unpaired_at_start,
         "frames without a stereo partner before the first pair (the cameras' streams began at different "
         "moments)");
  ledger(recorder::DropStage::kPairing, st.pairing.unpaired_after_start.count,
         st.pairing.unpaired_after_start, "frames without a stereo partner");
  ledger(recorder::DropStage::kProcessing, st.queue_drops[0] + st.queue_drops[1], st.queue_drop_t,
         "capture queue full (the pipeline fell behind)");
  ledger(recorder::DropStage::kProcessing, report.failed_pairs * 2, report.failed_t,
         "augmentation failed (both frames of the pair)");
  ledger(recorder::DropStage::kProcessing, st.pending.count, st.pending,
         "pending in the capture queues or the pairer when the run stopped");
  report.recording_closed = recorder_.close();
  report.recorder_stats = recorder_.stats();
  report.recorder_latency = latency_;
  return {};
}

}  // namespace augrig::pipeline
