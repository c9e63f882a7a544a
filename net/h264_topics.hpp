// H264Topics: the live view's H.264 topics (foxglove_msgs/msg/CompressedVideo, docs/LIVE_VIEW.md)
// encoded on a thread of their own: one x264 stream per channel (render/video_codec.hpp), made at
// the channel's first frame; the newest frame per channel waits its turn, channels in turn, so a
// frame still waiting when the next comes is dropped and counted (the stream stays decodable: a
// dropped frame is never coded). A keyframe with its parameter sets comes every keyframe_interval
// frames and at the next frame after request_keyframe() (a new subscriber, a client that lost a
// unit). Each coded unit is handed to `deliver` on that thread, with no lock of this class held.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include "core/conventions.hpp"
#include "core/image.hpp"
#include "net/latest_per_channel.hpp"
#include "net/websocket.hpp"
#include "render/video_codec.hpp"

namespace augrig::net {

struct H264TopicStats {
  std::uint64_t encoded = 0;    // units coded
  std::uint64_t keyframes = 0;  // ... of which IDR keyframes
  std::uint64_t dropped = 0;    // frames replaced while waiting (the encoder behind)
  std::uint64_t failed = 0;     // frames the encoder refused
  std::uint64_t bytes = 0;      // coded bytes, all units
  double encode_ms = 0;         // time spent converting and coding, all frames
};

class H264Topics {
 public:
  // One coded frame: the CDR message (foxglove_msgs/msg/CompressedVideo, format "h264").
  using Deliver =
      std::function<void(std::uint32_t channel, TimestampNs t_ns, const SharedBytes& message, bool keyframe)>;
  H264Topics(const H264Options& options, Deliver deliver);
  ~H264Topics();  // stop()
  H264Topics(const H264Topics&) = delete;
  H264Topics& operator=(const H264Topics&) = delete;

  // The channel's next frame (the image is the worker's now); replaces one still waiting (counted).
  void offer(std::uint32_t channel, TimestampNs t_ns, const char* frame_id, Image image);
  // The channel's next coded frame is an IDR keyframe.
  void request_keyframe(std::uint32_t channel);
  H264TopicStats stats() const;
  // Finishes the frame being coded and stops; idempotent. Frames still waiting are dropped.
  void stop();

 private:
  struct Job {
    TimestampNs t_ns = 0;
    const char* frame_id = "";
    Image image;
  };
  void loop();
  // Codes one job: an Error says why the encoder refused it.
  Expected<H264AccessUnit> code(std::uint32_t channel, const Job& job, bool keyframe);

  H264Options options_;
  Deliver deliver_;
  LatestPerChannel<Job> jobs_;
  mutable std::mutex mu_;             // want_key_ and stats_
  std::set<std::uint32_t> want_key_;  // channels whose next frame is a keyframe
  H264TopicStats stats_;
  std::map<std::uint32_t, std::unique_ptr<H264Encoder>> encoders_;  // the worker's only
  std::thread thread_;
};

}  // namespace augrig::net
