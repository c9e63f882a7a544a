// The network live view as a sink (net::FoxgloveServer): each pair as it is made (or, captured
// only, raw), each event as the health until the next status, and once a second the run's health
// in plain words with its numbers: rate, cameras, pose, recording, drops. Never blocks the run:
// the server drops for slow clients.
#include <iomanip>
#include <sstream>

#include "core/clock.hpp"
#include "pipeline/report.hpp"
#include "pipeline/sinks/sinks.hpp"

namespace augrig::pipeline {

namespace {

class FoxgloveSink final : public FrameSink {
 public:
  explicit FoxgloveSink(std::shared_ptr<net::FoxgloveServer> server)
      : server_(std::move(server)), health_t_ns_(monotonic_now_ns()) {}
  SinkNeeds needs() const override { return {.health = true}; }

  Status consume(PairContext& pair) override {
    server_->publish_pair(pair.raw, pair.result, pair.scene,
                          {pair.pair, pair.poses.sigma_pos_m, pair.poses.sigma_att_deg});
    last_t_key_ns_ = pair.raw.t_key_ns;
    return {};
  }

  void event(const SinkEvent& e) override {
    if (e.notify) server_->publish_health(e.pair_t_key_ns, net::HealthLevel::kWarn, e.text);
  }

  void health(const RunHealth& h) override {
    // The rate since the last health.
    const TimestampNs now = monotonic_now_ns();
    const double dt = ns_to_s(now - health_t_ns_);
    const double rate = dt > 0 ? static_cast<double>(h.pairs - health_pairs_) / dt : 0.0;
    health_pairs_ = h.pairs, health_t_ns_ = now;
    const std::uint64_t pairing = h.source.pairing.unpaired_left + h.source.pairing.unpaired_right;
    const std::uint64_t queue = h.source.queue_drops[0] + h.source.queue_drops[1];
    net::HealthLevel level = net::HealthLevel::kOk;
    std::ostringstream text;
    text << std::fixed << std::setprecision(1) << rate << " pairs/s";
    std::string cameras;
    for (const SourceHealth& c : h.cameras)
      if (!c.connected) {
        cameras += (cameras.empty() ? "" : "; ") + c.message;
        level = net::HealthLevel::kError;
      }
    text << "; cameras " << (cameras.empty() ? std::string("streaming") : cameras);
    if (h.pose_shown) {
      text << "; pose " << (h.pose_stale ? "stale" : "good");
      if (h.pose_stale && !h.pose_problem.empty()) text << " (" << h.pose_problem << ")";
      if (h.pose_stale && level == net::HealthLevel::kOk) level = net::HealthLevel::kWarn;
    }
    if (!h.recording.empty()) {
      text << "; recording " << h.recording;
      if (h.recording == "stopped") level = net::HealthLevel::kError;
    }
    text << "; drops: camera " << h.source.camera_drops << ", pairing " << pairing << ", queue " << queue;
    const net::ServeStats serve = server_->stats();  // the JPEG and H.264 topics' encoders
    if (serve.jpeg_dropped) text << ", JPEG " << serve.jpeg_dropped;
    if (serve.h264_dropped) text << ", H.264 " << serve.h264_dropped;
    for (const std::string& c : h.camera_clocks) text << "; camera clock " << c;
    if (h.pairs == 0 && level == net::HealthLevel::kOk) level = net::HealthLevel::kStale;
    std::vector<std::pair<std::string, std::string>> values = {
                             {"pairs", std::to_string(h.pairs)},
                             {"pairs_per_s", std::to_string(rate)},
                             {"drops_camera", std::to_string(h.source.camera_drops)},
                             {"drops_transport", std::to_string(h.source.transport_drops)},
                             {"drops_pairing", std::to_string(pairing)},
                             {"drops_queue", std::to_string(queue)},
                             {"failed_pairs", std::to_string(h.failed_pairs)},
                             {"stale_pairs", std::to_string(h.stale_pairs)},
                             {"recorder_dropped", std::to_string(h.recorder_dropped)},
                             {"jpeg_encoded", std::to_string(serve.jpeg_encoded)},
                             {"drops_jpeg", std::to_string(serve.jpeg_dropped + serve.jpeg_failed)},
                             {"h264_encoded", std::to_string(serve.h264_encoded)},
                             {"h264_keyframes", std::to_string(serve.h264_keyframes)},
                             {"drops_h264", std::to_string(serve.h264_dropped + serve.h264_failed)}};
    values.insert(values.end(), h.camera_clock_values.begin(), h.camera_clock_values.end());
    server_->publish_health(h.pair_t_key_ns, level, text.str(), values);
  }

  Status close(PipelineReport& report) override {
    server_->publish_health(last_t_key_ns_, net::HealthLevel::kStale,
                            "the run has ended after " + std::to_string(report.pairs) + " pairs");
    report.serve = server_->stats();
    return {};
  }

 private:
  std::shared_ptr<net::FoxgloveServer> server_;
  std::uint64_t health_pairs_ = 0;
  TimestampNs health_t_ns_ = 0;
  TimestampNs last_t_key_ns_ = 0;  // the last pair's, to stamp the end
};

}  // namespace

std::unique_ptr<FrameSink> make_foxglove_sink(std::shared_ptr<net::FoxgloveServer> server) {
  return std::make_unique<FoxgloveSink>(std::move(server));
}

}  // namespace augrig::pipeline
