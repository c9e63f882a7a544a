#include "pipeline/report.hpp"

#include <algorithm>
#include <iomanip>
#include <sstream>

#include "pipeline/pipeline.hpp"

namespace augrig::pipeline {

namespace {

std::string fmt_us(std::int64_t ns) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << static_cast<double>(ns) / 1e3;
  return s.str();
}
std::string fmt_ms(double ms) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << ms;
  return s.str();
}

}  // namespace

void print_report(const PipelineReport& r, const PipelineParts& parts, std::ostream& out) {
  const StereoSourceStats& st = r.source;
  if (r.summary.frames()) out << r.summary.format();
  const std::uint64_t pairing = st.pairing.unpaired_left + st.pairing.unpaired_right;
  const std::uint64_t queue = st.queue_drops[0] + st.queue_drops[1];
  const std::uint64_t pending = st.pending.count;
  out << "run: " << r.pairs << " stereo frames "
      << (parts.capture_only ? "captured (not augmented)" : "augmented") << " in " << std::fixed
      << std::setprecision(1) << r.wall_s << " s (" << r.pairs / std::max(r.wall_s, 1e-9) << "/s";
  if (r.pairs && !parts.capture_only)
    out << ", augmenter " << fmt_ms(r.augment_ms / static_cast<double>(r.pairs)) << " ms/frame, "
        << to_string(r.rasterizer) << " rasteriser";
  // Every frame read is in a pair or a ledger row: read = 2 pairs + pairing + queue + pending.
  const std::uint64_t pairs_read = r.pairs + r.failed_pairs + r.skipped_no_pose + r.seek_skipped_pairs;
  out << "); frames read: left " << st.frames[0] << ", right " << st.frames[1] << " = 2 x " << pairs_read
      << " pairs + " << pairing << " unpaired + " << queue << " dropped from full queues + " << pending
      << " pending at the stop\n";
  if (st.pairing.unpaired_at_start.count)
    out << "pairing at the start: " << st.pairing.unpaired_at_start.count
        << " of the unpaired frames came before the first pair (the cameras' streams began at different "
           "moments)\n";
  if (r.pairs_after_stop)
    out << "stop: " << r.pairs_after_stop
        << " pair(s) the cameras had delivered before it were still augmented (in the pairs above)\n";
  if (r.skipped_no_pose || r.seek_skipped_pairs)
    out << "pairs read but not augmented: " << r.skipped_no_pose << " without a pose, "
        << r.seek_skipped_pairs << " passed over by a seek\n";
  out << "drops: camera " << st.camera_drops << ", transport " << st.transport_drops << ", pairing "
      << pairing << ", processing " << queue + r.failed_pairs * 2 + pending << " (queue " << queue
      << ", failed " << r.failed_pairs << " pairs, pending at the stop " << pending << "), recorder "
      << r.recorder_stats.frames_dropped << "\n";
  // Latency from each pair's mid-exposure (the earlier camera's) on the host clock.
  auto latency_line = [&](const char* what, const SkewStats& h) {
    if (h.count)
      out << "latency mid-exposure to " << what << ": p50 " << fmt_ms(h.p50_abs_ns() / 1e6) << " ms, p99 "
          << fmt_ms(h.p99_abs_ns() / 1e6) << " ms, max " << fmt_ms(h.max_abs_ns / 1e6) << " ms (" << h.count
          << " pairs)\n";
  };
  // Where a pair's time goes, stage by stage.
  if (r.stage_augment.count) {
    auto stage = [&](const char* name, const SkewStats& h) {
      out << name << " " << fmt_ms(h.p50_abs_ns() / 1e6) << " / " << fmt_ms(h.p99_abs_ns() / 1e6);
    };
    out << "stages per pair, p50 / p99 ms: ";
    if (r.stage_queue.count) {
      stage("capture queues and pairing", r.stage_queue);
      out << ", ";
    }
    stage("pose", r.stage_pose);
    out << ", ";
    stage("augment", r.stage_augment);
    out << ", ";
    stage("sinks", r.stage_sinks);
    out << "\n";
  }
  latency_line(parts.view ? "display" : "display hand-off", r.display_latency);
  if (r.serve) {
    const net::ServeStats& v = *r.serve;
    out << "live view (" << (parts.serve ? parts.serve->url() : std::string()) << "): " << v.clients_ever
        << " client(s), " << v.messages_sent << " messages sent, " << v.messages_dropped
        << " dropped for slow clients, " << v.disconnects_slow << " client(s) cut off for not reading\n";
    if (v.jpeg_encoded + v.jpeg_dropped + v.jpeg_failed)
      out << "live view JPEG: " << v.jpeg_encoded << " frame(s) encoded ("
          << fmt_ms(v.jpeg_encoded ? v.jpeg_encode_ms / static_cast<double>(v.jpeg_encoded) : 0.0)
          << " ms each), " << v.jpeg_dropped << " dropped with the encoder behind, " << v.jpeg_failed
          << " failed\n";
    if (v.h264_encoded + v.h264_dropped + v.h264_failed)
      out << "live view H.264: " << v.h264_encoded << " frame(s) coded (" << v.h264_keyframes << " keyframes, "
          << fmt_ms(v.h264_encoded ? v.h264_encode_ms / static_cast<double>(v.h264_encoded) : 0.0) << " ms each, "
          << fmt_ms(v.h264_encoded ? static_cast<double>(v.h264_bytes) / 1e3 / static_cast<double>(v.h264_encoded)
                                   : 0.0)
          << " kB each), " << v.h264_dropped << " dropped with the encoder behind, " << v.h264_failed << " failed, "
          << v.h264_held << " held from clients waiting for a keyframe\n";
  }
  latency_line("recorder", r.recorder_latency);
  if (parts.live_nav) {
    out << "nav: " << r.no_pose_pairs << " pairs without a pose (boom only), " << r.stale_pairs
        << " with a stale or missing pose\n";
    for (Aircraft ac : {Aircraft::kTanker, Aircraft::kReceiver}) {
      const nav::LiveFusionStatus ns = parts.live_nav->status(ac);
      out << "nav " << to_string(ac) << ": " << (ns.initialised ? "fused" : "never initialised") << ", "
          << ns.imu_samples << " IMU samples (" << ns.imu_refused << " refused), " << ns.fixes
          << " fixes: " << ns.fixes_used << " used, " << ns.fixes_rejected << " rejected by the gate, "
          << ns.fixes_invalid << " without a fix, " << ns.fixes_late << " late\n";
    }
    if (const LiveBaselineReport b = parts.live_nav->baseline_report(); b.received)
      out << "nav " << b.summary() << "\n";
    if (parts.camera_clocks)
      for (const CameraClockOnlineStatus& c : parts.camera_clocks->status())
        out << "camera clock " << c.text() << " [" << c.frames_tracked << " frames tracked, "
            << c.frames_skipped_busy << " skipped with the worker busy, " << c.fits << " fits]\n";
  } else if (r.no_pose_pairs && !r.skipped_no_pose) {
    out << "nav: " << r.no_pose_pairs << " pairs without a pose (boom only)\n";
  }
  if (st.pairing.skew.count)
    out << "pair skew: p50 " << fmt_us(st.pairing.skew.p50_abs_ns()) << " us, p99 "
        << fmt_us(st.pairing.skew.p99_abs_ns()) << " us, max " << fmt_us(st.pairing.skew.max_abs_ns) << " us"
        << (st.pairing.pairs_within_uncertainty
                ? ", " + std::to_string(st.pairing.pairs_within_uncertainty) +
                      " pair(s) beyond the tolerance but within the clock estimates' uncertainty"
                : std::string())
        << "\n";
  for (const ClockOffsetLog& c : st.clocks)
    out << "clock " << to_string(c.camera) << ": host - device " << c.offset_ns << " ns, drift "
        << std::setprecision(2) << c.drift_ppm << " ppm, +-" << fmt_us(c.uncertainty_ns) << " us ("
        << c.samples << " samples, " << c.resets << " resets)\n";
  for (const std::string& line : r.outputs) out << "wrote " << line << "\n";
  for (std::size_t i = 0; i < parts.source->sources().size(); ++i) {
    const SourceHealth h = parts.source->health()[i];
    if (h.disconnects)
      out << parts.source->sources()[i]->uri() << ": lost " << h.disconnects << " time(s), reconnected "
          << h.reconnects << " time(s)" << (h.connected ? "" : "; not connected at the end") << "\n";
  }
}

}  // namespace augrig::pipeline
