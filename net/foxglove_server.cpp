// FoxgloveServer (foxglove_server.hpp): the channels, the JSON ops (parsed by foxglove_ops.cpp), and each
// frame's messages built as recorder/mcap_export.cpp builds a recorded one. Locks: the server's mutex, then
// the WebSocketServer's inside send(); the WebSocket callbacks run on its I/O thread without its lock, so the
// order is always the same.
#include "net/foxglove_server.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <mutex>
#include <set>
#include <thread>

#include <nlohmann/json.hpp>

#include "core/clock.hpp"
#include "core/thread_name.hpp"
#include "core/thread_priority.hpp"
#include "net/foxglove_ops.hpp"
#include "net/h264_topics.hpp"
#include "net/latest_per_channel.hpp"
#include "render/image_file.hpp"
#include "ros2/messages.hpp"

namespace augrig::net {

using json = nlohmann::json;

namespace {

constexpr const char* kSubprotocol = "foxglove.websocket.v1";
constexpr const char* kBodyFrame = "tanker_body";
constexpr const char* kReceiverFrame = "receiver_body";
const char* const kCameraFrames[2] = {"left_camera", "right_camera"};
const char* const kCameraNames[2] = {"left", "right"};

// Channel ids: fixed, so a client that reconnects finds the same ids for the same topics.
enum Ch : std::uint32_t {
  kFrame = 1,
  kCam0 = 2,  // per camera: image_raw, camera_info, image_augmented, mask, receiver_pose
  kTfStatic = 12,
  kTf,
  kStats,
  kDiagnostics,
  kJpeg0,               // per camera: image_raw/compressed, image_augmented/compressed (16 to 19)
  kH2640 = kJpeg0 + 4,  // per camera: image_raw/h264, image_augmented/h264 (20 to 23)
  kChannelCount = kH2640 + 3,
};
enum CamTopic : std::uint32_t {
  kImageRaw = 0,
  kCameraInfo,
  kImageAugmented,
  kMask,
  kReceiverPose,
  kPerCamera
};
constexpr std::uint32_t cam_channel(int camera, CamTopic t) {
  return kCam0 + static_cast<std::uint32_t>(camera) * kPerCamera + t;
}
constexpr std::uint32_t jpeg_channel(int camera, bool augmented) {
  return kJpeg0 + 2 * static_cast<std::uint32_t>(camera) + (augmented ? 1 : 0);
}

constexpr std::uint32_t h264_channel(int camera, bool augmented) {
  return kH2640 + 2 * static_cast<std::uint32_t>(camera) + (augmented ? 1 : 0);
}
constexpr bool is_h264_channel(std::uint32_t channel) {
  return channel >= kH2640 && channel <= kChannelCount;
}

std::string dump(const json& j) {
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

// The augmented image whole, from either AugmentedOutput: the raw image's message with the
// changed box written over it. Empty when the view's sizes do not fit together.
std::vector<std::uint8_t> augmented_message(TimestampNs t_ns, const char* frame_id, const Image& raw,
                                            const ViewResult& v) {
  const Image& a = v.augmented;
  if (a.width() == raw.width() && a.height() == raw.height() && a.format() == raw.format() && !a.empty())
    return ros2::image(t_ns, frame_id, a.cview());
  const PixelBox& box = v.augmented_box;
  if (a.width() != box.width() || a.height() != box.height() || !box.inside(raw.width(), raw.height()) ||
      (!box.empty() && a.format() != raw.format()) || raw.empty())
    return {};
  std::vector<std::uint8_t> msg = ros2::image(t_ns, frame_id, raw.cview());
  const std::size_t bpp = static_cast<std::size_t>(bytes_per_pixel(raw.format()));
  const std::size_t row = static_cast<std::size_t>(raw.width()) * bpp;
  const std::size_t data = msg.size() - row * static_cast<std::size_t>(raw.height());
  for (int y = 0; y < box.height(); ++y)
    std::memcpy(msg.data() + data + static_cast<std::size_t>(box.y0 + y) * row +
                    static_cast<std::size_t>(box.x0) * bpp,
                a.row(y), static_cast<std::size_t>(box.width()) * bpp);
  return msg;
}

std::uint64_t log_time(TimestampNs t) {
  return static_cast<std::uint64_t>(std::max<TimestampNs>(t, 0));
}

}  // namespace

struct FoxgloveServer::Impl {
  ServeOptions opt;
  Rig rig;
  std::vector<ServeChannel> channels;
  std::unique_ptr<WebSocketServer> ws;  // set under `mu` before any callback can use it
  SharedBytes server_info, advertise;

  mutable std::mutex mu;
  struct Client {
    std::map<std::uint32_t, std::uint32_t> subscriptions;  // subscription id -> channel id
    // H.264 channels on which this client has no decodable stream yet (just subscribed, or a unit
    // was dropped for it): it gets nothing there until the next keyframe.
    std::set<std::uint32_t> awaiting_key;
  };
  std::map<ClientId, Client> clients;
  // Per channel id: (client, subscription id) of every subscriber.
  std::vector<std::vector<std::pair<ClientId, std::uint32_t>>> subscribers;
  TimestampNs last_key_ns = 0;
  SharedBytes last_health;
  TimestampNs last_health_ns = 0;
  std::uint64_t pairs = 0, healths = 0, serialised = 0, serialised_bytes = 0, client_errors = 0;
  bool stopped = false;

  // ---- The JPEG topics' encoder: one thread, the newest frame per channel, channels in turn. ----
  struct JpegJob {
    TimestampNs t_ns = 0;
    int camera = 0;
    Image image;
  };
  LatestPerChannel<JpegJob> jpeg_jobs;
  std::mutex jpeg_mu;  // the counts; never held while taking `mu`
  std::uint64_t jpeg_encoded = 0, jpeg_dropped = 0, jpeg_failed = 0;
  double jpeg_ms = 0;
  std::thread jpeg_thread;

  // ---- The H.264 topics' encoder (h264_topics.hpp); its units come back through deliver_h264(). ----
  std::unique_ptr<H264Topics> h264;
  std::uint64_t h264_held = 0;  // units not sent to a client waiting for a keyframe

  void deliver_h264(std::uint32_t channel, TimestampNs t_ns, const SharedBytes& body, bool keyframe) {
    std::lock_guard<std::mutex> l(mu);
    if (stopped) return;
    ++serialised;
    serialised_bytes += body->size();
    bool lost = false;
    for (const auto& [client, sub] : subscribers[channel]) {
      const auto cl = clients.find(client);
      if (cl == clients.end()) continue;
      auto& awaiting = cl->second.awaiting_key;
      if (keyframe) {
        awaiting.erase(channel);
      } else if (awaiting.count(channel)) {
        ++h264_held;  // undecodable for it without the frames before
        continue;
      }
      // A unit dropped for a slow client breaks its stream until the next keyframe: ask for one.
      if (send_data(client, sub, log_time(t_ns), body, true) == SendResult::kDropped) {
        awaiting.insert(channel);
        lost = true;
      }
    }
    if (lost) h264->request_keyframe(channel);
  }

  void offer_jpeg(std::uint32_t channel, JpegJob job) {
    if (jpeg_jobs.offer(channel, std::move(job))) return;
    std::lock_guard<std::mutex> lock(jpeg_mu);
    ++jpeg_dropped;
  }

  void jpeg_loop() {
    set_thread_name("augrig-jpeg");
    lower_thread_priority(10);  // like the H.264 coder: the pipeline first (core/thread_priority.hpp)
    while (auto next = jpeg_jobs.take()) {
      const auto& [channel, job] = *next;
      const auto t0 = std::chrono::steady_clock::now();
      auto jpeg = encode_jpeg(job.image.cview(), opt.jpeg_quality);
      SharedBytes body;
      if (jpeg)
        body = share_bytes(ros2::compressed_image(job.t_ns, kCameraFrames[job.camera], "jpeg", *jpeg));
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      {
        std::lock_guard<std::mutex> l(mu);
        if (body && !stopped) {
          ++serialised;
          serialised_bytes += body->size();
          for (const auto& [client, sub] : subscribers[channel])
            send_data(client, sub, log_time(job.t_ns), body, true);
        }
      }
      std::lock_guard<std::mutex> lock(jpeg_mu);
      ++(jpeg ? jpeg_encoded : jpeg_failed);
      jpeg_ms += ms;
    }
  }

  // Message Data: opcode, subscription id and log time before the shared CDR body.
  SendResult send_data(ClientId client, std::uint32_t sub, std::uint64_t t_ns, const SharedBytes& body,
                       bool droppable) {
    std::uint8_t prefix[13];
    prefix[0] = 0x01;
    for (int b = 0; b < 4; ++b) prefix[1 + b] = static_cast<std::uint8_t>(sub >> (8 * b));
    for (int b = 0; b < 8; ++b) prefix[5 + b] = static_cast<std::uint8_t>(t_ns >> (8 * b));
    return ws->send(client, true, body, prefix, droppable);
  }

  void status(ClientId client, int level, const std::string& message) {
    if (level == 2) ++client_errors;
    ws->send_text(client, dump(json{{"op", "status"}, {"level", level}, {"message", message}}));
  }

  SharedBytes tf_static() const {
    std::vector<ros2::Transform> tf;
    tf.reserve(2);
    for (int c = 0; c < 2; ++c)
      tf.push_back(
          {last_key_ns, kBodyFrame, kCameraFrames[c], rig.cameras[static_cast<std::size_t>(c)].T_body_cam});
    return share_bytes(ros2::tf_message(tf));
  }

  // What a new subscriber gets at once: the static transforms, the latest health.
  void on_subscribed(ClientId client, std::uint32_t sub, std::uint32_t channel) {
    if (channel == kTfStatic) {
      ++serialised;
      const SharedBytes b = tf_static();
      serialised_bytes += b->size();
      send_data(client, sub, log_time(last_key_ns), b, false);
    } else if (channel == kDiagnostics && last_health) {
      send_data(client, sub, log_time(last_health_ns), last_health, false);
    }
  }

  // One well-formed subscription: to a channel this server has, by an id not in use, once per channel.
  void subscribe(ClientId client, Client& cl, std::uint32_t sub, std::uint64_t ch) {
    if (ch < 1 || ch > kChannelCount)
      return status(client, 2,
                    "subscribe: unknown channel id " + std::to_string(ch) + " (this server advertised 1 to " +
                        std::to_string(kChannelCount) + ")");
    const auto channel = static_cast<std::uint32_t>(ch);
    if (cl.subscriptions.count(sub))
      return status(client, 2, "subscribe: subscription id " + std::to_string(sub) + " is already in use");
    if (std::any_of(cl.subscriptions.begin(), cl.subscriptions.end(),
                    [&](const auto& kv) { return kv.second == channel; }))
      return status(client, 2,
                    "subscribe: already subscribed to channel " + std::to_string(channel) + " (" +
                        channels[channel - 1].topic + ")");
    cl.subscriptions.emplace(sub, channel);
    subscribers[channel].emplace_back(client, sub);
    if (is_h264_channel(channel)) {
      // Foxglove needs a keyframe with its parameter sets first: this client waits for the next,
      // which is asked for now.
      cl.awaiting_key.insert(channel);
      h264->request_keyframe(channel);
    }
    on_subscribed(client, sub, channel);
  }

  void unsubscribe(ClientId client, Client& cl, std::uint32_t sub) {
    const auto found = cl.subscriptions.find(sub);
    if (found == cl.subscriptions.end())
      return status(client, 1, "unsubscribe: no subscription with id " + std::to_string(sub));
    auto& subs = subscribers[found->second];
    subs.erase(std::remove(subs.begin(), subs.end(), std::make_pair(client, sub)), subs.end());
    cl.awaiting_key.erase(found->second);
    cl.subscriptions.erase(found);
  }

  void on_open(ClientId client) {
    std::lock_guard<std::mutex> lock(mu);
    clients[client];
    ws->send(client, false, server_info);
    ws->send(client, false, advertise);
  }

  void on_message(ClientId client, bool binary, std::string_view data) {
    std::lock_guard<std::mutex> lock(mu);
    const auto cit = clients.find(client);
    if (cit == clients.end()) return;
    // The op (foxglove_ops.hpp), then each entry in order: a status for each that is wrong.
    const ClientOp op = parse_client_op(binary, data);
    if (op.kind == ClientOp::Kind::kError) return status(client, 2, op.error);
    for (const ClientOp::Entry& e : op.entries) {
      if (!e.problem.empty())
        status(client, 2, e.problem);
      else if (op.kind == ClientOp::Kind::kSubscribe)
        subscribe(client, cit->second, e.id, e.channel);
      else
        unsubscribe(client, cit->second, e.id);
    }
  }

  void on_close(ClientId client) {
    std::lock_guard<std::mutex> lock(mu);
    const auto it = clients.find(client);
    if (it == clients.end()) return;
    for (const auto& [sub, channel] : it->second.subscriptions) {
      auto& subs = subscribers[channel];
      subs.erase(std::remove(subs.begin(), subs.end(), std::make_pair(client, sub)), subs.end());
    }
    clients.erase(it);
  }
};

Expected<std::unique_ptr<FoxgloveServer>> FoxgloveServer::start(const ServeOptions& options, const Rig& rig) {
  const std::string where = "net::FoxgloveServer::start(): ";
  if (rig.cameras.size() < 2) return Error{where + "the rig has fewer than 2 cameras"};
  if (options.jpeg_quality < 1 || options.jpeg_quality > 100)
    return Error{where + "JPEG quality " + std::to_string(options.jpeg_quality) + ": expected 1..100"};
  // The H.264 options checked now (an encoder made and thrown away), not at the first subscriber.
  H264Options h264_options;
  h264_options.crf = options.h264_crf;
  h264_options.gop_frames = options.h264_keyframe_interval;
  h264_options.max_kbps = options.h264_max_kbps;
  h264_options.preset = options.h264_preset;
  if (auto probe = H264Encoder::create(16, 16, h264_options); !probe)
    return Error{where + "H.264 topics: " + probe.error().message};
  std::unique_ptr<FoxgloveServer> s(new FoxgloveServer());
  s->impl_ = std::make_unique<Impl>();
  Impl& im = *s->impl_;
  im.opt = options;
  im.rig = rig;

  auto add = [&](std::uint32_t id, const std::string& topic, const std::string& type, bool droppable) {
    im.channels.push_back({id, topic, type, droppable});
  };
  add(kFrame, "/augrig/frame", "augrig_msgs/msg/StereoFrameInfo", true);
  for (int c = 0; c < 2; ++c) {
    const std::string cam = std::string("/") + kCameraNames[c];
    add(cam_channel(c, kImageRaw), cam + "/image_raw", "sensor_msgs/msg/Image", true);
    add(cam_channel(c, kCameraInfo), cam + "/camera_info", "sensor_msgs/msg/CameraInfo", true);
    add(cam_channel(c, kImageAugmented), cam + "/image_augmented", "sensor_msgs/msg/Image", true);
    add(cam_channel(c, kMask), cam + "/mask", "sensor_msgs/msg/Image", true);
    add(cam_channel(c, kReceiverPose), cam + "/receiver_pose", "geometry_msgs/msg/PoseWithCovarianceStamped",
        true);
  }
  add(kTfStatic, "/tf_static", "tf2_msgs/msg/TFMessage", false);
  add(kTf, "/tf", "tf2_msgs/msg/TFMessage", true);
  add(kStats, "/augrig/occlusion_stats", "augrig_msgs/msg/OcclusionStats", true);
  add(kDiagnostics, "/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", true);
  for (int c = 0; c < 2; ++c) {
    const std::string cam = std::string("/") + kCameraNames[c];
    add(jpeg_channel(c, false), cam + "/image_raw/compressed", "sensor_msgs/msg/CompressedImage", true);
    add(jpeg_channel(c, true), cam + "/image_augmented/compressed", "sensor_msgs/msg/CompressedImage", true);
  }
  for (int c = 0; c < 2; ++c) {
    const std::string cam = std::string("/") + kCameraNames[c];
    add(h264_channel(c, false), cam + "/image_raw/h264", "foxglove_msgs/msg/CompressedVideo", true);
    add(h264_channel(c, true), cam + "/image_augmented/h264", "foxglove_msgs/msg/CompressedVideo", true);
  }
  im.subscribers.resize(kChannelCount + 1);
  s->channels_ = im.channels;

  json adv = json::array();
  for (const ServeChannel& c : im.channels)
    adv.push_back({{"id", c.id},
                   {"topic", c.topic},
                   {"encoding", "cdr"},
                   {"schemaName", c.schema_name},
                   {"schema", ros2::schema_text(c.schema_name)},
                   {"schemaEncoding", "ros2msg"}});
  im.advertise = share_bytes(dump(json{{"op", "advertise"}, {"channels", adv}}));
  json meta = json::object();
  meta["augrig_version"] = AUGRIG_VERSION;
  std::string cams;
  for (std::size_t c = 0; c < 2; ++c)
    cams += (c ? ", " : "") + std::string(kCameraNames[c]) + " " +
            std::to_string(rig.cameras[c].model.width_px) + "x" +
            std::to_string(rig.cameras[c].model.height_px);
  meta["cameras"] = cams;
  for (const auto& [k, v] : options.metadata) meta[k] = v;
  im.server_info = share_bytes(dump(json{{"op", "serverInfo"},
                                         {"name", options.name},
                                         {"capabilities", json::array()},
                                         {"supportedEncodings", json::array({"cdr"})},
                                         {"metadata", meta},
                                         {"sessionId", std::to_string(monotonic_now_ns())}}));

  WebSocketOptions wo;
  wo.address = options.address;
  wo.port = options.port;
  wo.subprotocols = {kSubprotocol};
  wo.max_clients = options.max_clients;
  wo.queue_bytes = options.client_queue_bytes;
  wo.control_reserve_bytes = std::max<std::size_t>(std::size_t{1024} * 1024, options.client_queue_bytes / 8);
  wo.max_message_bytes = std::size_t{256} * 1024;  // subscribe lists; nothing else is accepted from clients
  wo.stall_timeout_ms = options.stall_timeout_ms;
  wo.server_header = "augrig " AUGRIG_VERSION " (Foxglove WebSocket, " + std::string(kSubprotocol) + ")";
  WebSocketHandler h;
  Impl* p = &im;
  h.on_open = [p](ClientId id, const std::string&, const std::string&) { p->on_open(id); };
  h.on_message = [p](ClientId id, bool binary, std::string_view data) { p->on_message(id, binary, data); };
  h.on_close = [p](ClientId id, const CloseInfo&) { p->on_close(id); };
  std::lock_guard<std::mutex> lock(im.mu);  // callbacks wait for `ws` to be set
  auto ws = WebSocketServer::start(wo, std::move(h));
  if (!ws) {
    std::string m = ws.error().message;
    const std::string inner = "net::WebSocketServer::start(): ";
    if (m.rfind(inner, 0) == 0) m = m.substr(inner.size());
    return Error{where + m};
  }
  im.ws = std::move(*ws);
  im.jpeg_thread = std::thread([p] { p->jpeg_loop(); });
  im.h264 =
      std::make_unique<H264Topics>(h264_options, [p](std::uint32_t ch, TimestampNs t, const SharedBytes& b,
                                                     bool key) { p->deliver_h264(ch, t, b, key); });
  return s;
}

FoxgloveServer::~FoxgloveServer() {
  stop();
}

void FoxgloveServer::stop() {
  if (!impl_) return;
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    if (impl_->stopped) return;
    impl_->stopped = true;
  }
  impl_->jpeg_jobs.stop();
  if (impl_->jpeg_thread.joinable()) impl_->jpeg_thread.join();
  if (impl_->h264) impl_->h264->stop();
  // Not under `mu`: the I/O thread's last on_close calls take it.
  if (impl_->ws) impl_->ws->stop();
}

int FoxgloveServer::port() const {
  return impl_->ws->port();
}

std::string FoxgloveServer::url() const {
  const std::string& a = impl_->ws->address();
  return "ws://" + (a.find(':') != std::string::npos ? "[" + a + "]" : a) + ":" + std::to_string(port());
}

void FoxgloveServer::publish_pair(const StereoFrame& raw, const StereoResult* result, const SceneState* scene,
                                  const PairInfo& info) {
  Impl& im = *impl_;
  std::array<bool, kChannelCount + 1> wanted{};
  {
    std::lock_guard<std::mutex> lock(im.mu);
    if (im.stopped) return;
    ++im.pairs;
    im.last_key_ns = raw.t_key_ns;
    bool any = false;
    for (std::uint32_t c = 1; c <= kChannelCount; ++c) any |= wanted[c] = !im.subscribers[c].empty();
    if (!any) return;
  }
  // Serialised outside the lock (the images are the time here), in the export's order.
  struct Out {
    std::uint32_t channel;
    TimestampNs t_ns;
    SharedBytes body;
  };
  std::vector<Out> out;
  auto put = [&](std::uint32_t channel, TimestampNs t, std::vector<std::uint8_t> msg) {
    if (!msg.empty()) out.push_back({channel, t, share_bytes(std::move(msg))});
  };
  if (wanted[kFrame]) {
    ros2::StereoFrameInfo fi = ros2::stereo_frame_info_of(raw, info.index);
    fi.receiver_present = scene ? (scene->receiver_present ? 1 : 0) : -1;
    if (scene) fi.boom = scene->boom;
    fi.sigma_pos_m = info.sigma_pos_m;
    fi.sigma_att_deg = info.sigma_att_deg;
    put(kFrame, raw.t_key_ns, ros2::stereo_frame_info(raw.t_key_ns, fi));
  }
  for (int c = 0; c < 2; ++c) {
    const Frame& fr = c == 0 ? raw.left : raw.right;
    const char* frame_id = kCameraFrames[c];
    if (wanted[cam_channel(c, kImageRaw)] && !fr.image.empty())
      put(cam_channel(c, kImageRaw), fr.t_ns, ros2::image(fr.t_ns, frame_id, fr.image.cview()));
    if (wanted[cam_channel(c, kCameraInfo)])
      put(cam_channel(c, kCameraInfo), fr.t_ns,
          ros2::camera_info(fr.t_ns, frame_id, im.rig.cameras[static_cast<std::size_t>(c)].model));
    if (result) {
      const ViewResult& v = c == 0 ? result->left : result->right;
      if (wanted[cam_channel(c, kImageAugmented)])
        put(cam_channel(c, kImageAugmented), fr.t_ns, augmented_message(fr.t_ns, frame_id, fr.image, v));
      if (wanted[cam_channel(c, kMask)] && !v.mask.empty())
        put(cam_channel(c, kMask), fr.t_ns, ros2::image(fr.t_ns, frame_id, v.mask.cview()));
      if (wanted[jpeg_channel(c, true)] && !fr.image.empty())
        im.offer_jpeg(jpeg_channel(c, true), {fr.t_ns, c, whole_augmented(fr.image, v)});
    }
    // The JPEG and H.264 topics: a copy for the encoders' threads (the pipeline reuses its buffers).
    if (wanted[jpeg_channel(c, false)] && !fr.image.empty())
      im.offer_jpeg(jpeg_channel(c, false), {fr.t_ns, c, Image::copy_of(fr.image.cview())});
    if (wanted[h264_channel(c, false)] && !fr.image.empty())
      im.h264->offer(h264_channel(c, false), fr.t_ns, frame_id, Image::copy_of(fr.image.cview()));
    if (result && wanted[h264_channel(c, true)] && !fr.image.empty())
      im.h264->offer(h264_channel(c, true), fr.t_ns, frame_id,
                     whole_augmented(fr.image, c == 0 ? result->left : result->right));
    if (scene && wanted[cam_channel(c, kReceiverPose)]) {
      const Pose T_cam_receiver =
          im.rig.cameras[static_cast<std::size_t>(c)].T_body_cam.inverse() * scene->T_body_receiver;
      put(cam_channel(c, kReceiverPose), raw.t_key_ns,
          ros2::pose_with_covariance(raw.t_key_ns, frame_id, T_cam_receiver,
                                     ros2::pose_covariance(info.sigma_pos_m, info.sigma_att_deg)));
    }
  }
  if (scene && wanted[kTf])
    put(kTf, raw.t_key_ns,
        ros2::tf_message({{raw.t_key_ns, kBodyFrame, kReceiverFrame, scene->T_body_receiver}}));
  if (result && wanted[kStats]) put(kStats, raw.t_key_ns, ros2::occlusion_stats(raw.t_key_ns, result->stats));

  std::lock_guard<std::mutex> lock(im.mu);
  if (im.stopped) return;
  for (const Out& o : out) {
    ++im.serialised;
    im.serialised_bytes += o.body->size();
    const bool droppable = im.channels[o.channel - 1].droppable;
    for (const auto& [client, sub] : im.subscribers[o.channel])
      im.send_data(client, sub, log_time(o.t_ns), o.body, droppable);
  }
}

void FoxgloveServer::publish_health(TimestampNs stamp_ns, HealthLevel level, const std::string& text,
                                    const std::vector<std::pair<std::string, std::string>>& values) {
  Impl& im = *impl_;
  ros2::DiagnosticStatus st;
  st.level = static_cast<std::uint8_t>(level);
  st.name = "augrig pipeline";
  st.hardware_id = im.opt.name;
  st.message = text;
  st.values = values;
  // Small: made every time, since the latest is kept for the next subscriber anyway.
  const SharedBytes body = share_bytes(ros2::diagnostic_array(std::max<TimestampNs>(stamp_ns, 0), {st}));
  std::lock_guard<std::mutex> lock(im.mu);
  if (im.stopped) return;
  ++im.healths;
  ++im.serialised;
  im.serialised_bytes += body->size();
  im.last_health = body;
  im.last_health_ns = stamp_ns;
  for (const auto& [client, sub] : im.subscribers[kDiagnostics])
    im.send_data(client, sub, log_time(stamp_ns), body, true);
}

ServeStats FoxgloveServer::stats() const {
  const WebSocketStats w = impl_->ws->stats();
  ServeStats s;
  s.clients_now = w.clients_now;
  s.clients_ever = w.clients_ever;
  s.messages_sent = w.messages_sent;
  s.bytes_sent = w.bytes_sent;
  s.messages_dropped = w.messages_dropped;
  s.disconnects = w.disconnects;
  s.disconnects_slow = w.disconnects_overflow + w.disconnects_stalled;
  s.handshakes_refused = w.handshakes_refused;
  {
    std::lock_guard<std::mutex> jl(impl_->jpeg_mu);
    s.jpeg_encoded = impl_->jpeg_encoded;
    s.jpeg_dropped = impl_->jpeg_dropped;
    s.jpeg_failed = impl_->jpeg_failed;
    s.jpeg_encode_ms = impl_->jpeg_ms;
  }
  {
    const H264TopicStats h = impl_->h264->stats();
    s.h264_encoded = h.encoded;
    s.h264_keyframes = h.keyframes;
    s.h264_dropped = h.dropped;
    s.h264_failed = h.failed;
    s.h264_bytes = h.bytes;
    s.h264_encode_ms = h.encode_ms;
  }
  std::lock_guard<std::mutex> lock(impl_->mu);
  s.pairs_published = impl_->pairs;
  s.health_published = impl_->healths;
  s.messages_serialised = impl_->serialised;
  s.bytes_serialised = impl_->serialised_bytes;
  s.client_errors = impl_->client_errors;
  s.h264_held = impl_->h264_held;
  for (const ClientStats& c : w.clients) {
    ServeClientStats cs;
    cs.id = c.id;
    cs.peer = c.peer;
    cs.queued_bytes = c.queued_bytes;
    cs.messages_sent = c.messages_sent;
    cs.bytes_sent = c.bytes_sent;
    cs.messages_dropped = c.messages_dropped;
    if (const auto it = impl_->clients.find(c.id); it != impl_->clients.end())
      cs.subscriptions = it->second.subscriptions.size();
    s.clients.push_back(std::move(cs));
  }
  return s;
}

}  // namespace augrig::net
