// FoxgloveServer: the live view of a run for a ground crew, as the Foxglove WebSocket protocol v1
// (subprotocol "foxglove.websocket.v1") over net/websocket.hpp. On connect a client gets
// "serverInfo" and one "advertise" of every channel: the topics, ROS 2 types, CDR messages and
// ros2msg schemas of the MCAP export (docs/MCAP.md, ros2/messages.hpp), so Foxglove shows a
// live run exactly as it shows an exported file, plus /diagnostics, the pipeline's health in
// plain words, and per camera the raw and augmented images compressed, sensor_msgs/msg/CompressedImage
// in JPEG ("/left/image_augmented/compressed", as image_transport names them) and as H.264 video,
// foxglove_msgs/msg/CompressedVideo ("/left/image_augmented/h264", net/h264_topics.hpp: a keyframe
// with its parameter sets to each new subscriber and every keyframe interval), for links that cannot
// carry raw images. Clients "subscribe" and "unsubscribe"; each message goes to each subscriber as
// binary Message Data (opcode 0x01, subscription id, log time in ns, the CDR message). A message is
// serialised only when some client subscribes to its channel, once however many do. The JPEG topics
// (and, apart, the H.264 topics) are encoded on a thread of their own, the newest frame per topic: a frame still waiting when the
// next comes is dropped and counted, so an encoder that falls behind costs that topic frames, never
// the pipeline's thread nor the other topics. The publish
// calls are made from the pipeline's thread and never block on a client: a slow client's queue
// fills, its messages are dropped and counted (images first, being the biggest), and one that
// stops reading altogether is disconnected (counted). A client's mistakes (bad JSON, an unknown
// channel or op) are answered with a "status" message, never by closing. docs/LIVE_VIEW.md says
// how to watch a run.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/expected.hpp"
#include "core/frame.hpp"
#include "net/websocket.hpp"
#include "render/augmenter.hpp"
#include "render/rig.hpp"

namespace augrig::net {

struct ServeOptions {
  // Loopback by default: the live view has no authentication, so it is reached from another
  // machine through an SSH tunnel (docs/LIVE_VIEW.md) unless an address is given on purpose.
  std::string address = "127.0.0.1";
  int port = 0;  // 0: an ephemeral port (port() says which)
  // Per client: messages beyond this many bytes queued are dropped. 32 MiB is a few stereo frames
  // of every image topic at 1280x960: enough to ride out a hiccup, little enough to stay live.
  std::size_t client_queue_bytes = 32 * 1024 * 1024;
  std::size_t max_clients = 16;
  std::string name = "augrig";                  // serverInfo's name
  std::map<std::string, std::string> metadata;  // added to serverInfo's metadata
  // A client that has taken nothing for this long while data waits for it is disconnected (0: never).
  int stall_timeout_ms = 30'000;
  int jpeg_quality = 80;  // the compressed topics' JPEG quality, 1..100
  // The H.264 topics (render/video_codec.hpp): x264's quality and preset, a keyframe at least every
  // h264_keyframe_interval frames, and a cap per topic: 4 Mbit/s keeps both augmented views of a
  // 30 fps rig within 8 Mbit/s.
  int h264_crf = 23;
  int h264_keyframe_interval = 30;
  int h264_max_kbps = 4000;  // 0: no cap
  std::string h264_preset = "ultrafast";  // the cheapest (docs/PERFORMANCE.md: 2/3 of superfast's CPU)
};

enum class HealthLevel : std::uint8_t {
  kOk = 0,
  kWarn = 1,
  kError = 2,
  kStale = 3
};  // DiagnosticStatus levels

// What publish_pair() needs beyond the frame, its result and its scene.
struct PairInfo {
  std::uint64_t index = 0;  // the pair's count in this run (StereoFrameInfo.index)
  double sigma_pos_m = std::numeric_limits<double>::quiet_NaN();  // the pose's 1-sigma; NaN: unknown
  double sigma_att_deg = std::numeric_limits<double>::quiet_NaN();
};

// One advertised channel.
struct ServeChannel {
  std::uint32_t id = 0;
  std::string topic, schema_name;
  bool droppable = true;  // Message Data may be dropped for a slow client
};

struct ServeClientStats {
  ClientId id = 0;
  std::string peer;
  std::size_t subscriptions = 0, queued_bytes = 0;
  std::uint64_t messages_sent = 0, bytes_sent = 0, messages_dropped = 0;
};

struct ServeStats {
  std::size_t clients_now = 0;
  std::uint64_t clients_ever = 0;
  std::uint64_t messages_sent = 0, bytes_sent = 0;  // to every client, JSON included
  std::uint64_t messages_dropped = 0;               // every client ever
  std::uint64_t disconnects = 0;                    // clients gone, for any reason
  std::uint64_t disconnects_slow = 0;               // ... cut off because they did not read
  std::uint64_t handshakes_refused = 0;             // answered with an HTTP error (wrong subprotocol, ...)
  std::uint64_t pairs_published = 0, health_published = 0;  // calls
  std::uint64_t messages_serialised = 0,
                bytes_serialised = 0;     // CDR messages made (once per channel and call)
  std::uint64_t client_errors = 0;        // "status" errors sent to clients
  // The JPEG topics: frames encoded, frames dropped before their turn (the encoder behind), failures.
  std::uint64_t jpeg_encoded = 0, jpeg_dropped = 0, jpeg_failed = 0;
  double jpeg_encode_ms = 0;  // time spent encoding, all frames
  // The H.264 topics: units coded (of which keyframes), frames dropped before their turn (the encoder
  // behind), failures, coded bytes, coding time; units held from a client waiting for a keyframe.
  std::uint64_t h264_encoded = 0, h264_keyframes = 0, h264_dropped = 0, h264_failed = 0, h264_bytes = 0;
  double h264_encode_ms = 0;
  std::uint64_t h264_held = 0;
  std::vector<ServeClientStats> clients;  // the open clients, by id
};

class FoxgloveServer {
 public:
  // Listens on options.address:port. `rig` (at least 2 cameras) gives /left|right/camera_info and
  // /tf_static. Errors: "net::FoxgloveServer::start(): cannot bind 127.0.0.1:8765: Address already in use".
  static Expected<std::unique_ptr<FoxgloveServer>> start(const ServeOptions& options, const Rig& rig);
  ~FoxgloveServer();  // stop()
  FoxgloveServer(const FoxgloveServer&) = delete;
  FoxgloveServer& operator=(const FoxgloveServer&) = delete;

  int port() const;
  std::string url() const;  // ws://ADDRESS:PORT
  const std::vector<ServeChannel>& channels() const { return channels_; }

  // One stereo frame, as the MCAP export writes a recorded one: /augrig/frame; per camera
  // image_raw, camera_info, image_augmented, mask, receiver_pose; /tf; /augrig/occlusion_stats.
  // `result`: the augmentation (null: the raw images only); its augmented images may be whole or
  // changed boxes (render/augmenter.hpp AugmentedOutput), sent whole either way. `scene`: the
  // poses and boom used (null: none, so no receiver_pose and no /tf). Images and per-camera
  // messages are stamped with each camera's t_ns, the rest with raw.t_key_ns (negative times as 0).
  // Returns at once; copies only what some client subscribed to.
  void publish_pair(const StereoFrame& raw, const StereoResult* result, const SceneState* scene,
                    const PairInfo& info = {});
  // The pipeline's health on /diagnostics (diagnostic_msgs/msg/DiagnosticArray, one status named
  // "augrig pipeline"): `text` in plain words, `values` as key-value pairs (drops by stage, ...).
  // The latest is also sent to each new subscriber, as the state it is.
  void publish_health(TimestampNs stamp_ns, HealthLevel level, const std::string& text,
                      const std::vector<std::pair<std::string, std::string>>& values = {});

  ServeStats stats() const;
  // Closes every client (1001) and stops listening. Idempotent; publish calls afterwards do nothing.
  void stop();

 private:
  struct Impl;
  FoxgloveServer() = default;
  std::vector<ServeChannel> channels_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace augrig::net
