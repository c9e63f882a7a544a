// McapSource and is_mcap_path() (mcap_source.hpp): an MCAP file written by export_mcap() or the
// mcap sink (mcap_export.cpp) read back through McapReader, per stereo frame two raw Frames
// carrying the recorded scene.
#include "recorder/mcap_source.hpp"

#include <cstring>
#include <fstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "recorder/mcap_writer.hpp"  // kMcapMagic
#include "ros2/messages.hpp"

namespace augrig::recorder {

namespace {

using mcap_names::kBodyFrame;
using mcap_names::kCameraNames;
using mcap_names::kReceiverFrame;

}  // namespace

bool is_mcap_path(const std::string& path) {
  if (path.size() >= 5 && path.compare(path.size() - 5, 5, ".mcap") == 0) return true;
  std::ifstream in(path, std::ios::binary);
  char b[8] = {};
  return in.read(b, 8) && std::memcmp(b, kMcapMagic, 8) == 0;
}

Expected<std::unique_ptr<McapSource>> McapSource::open(const std::string& uri_or_path) {
  const std::string path = uri_or_path.rfind("replay://", 0) == 0 ? uri_or_path.substr(9) : uri_or_path;
  auto r = McapReader::open(path);
  if (!r) return r.error();
  std::unique_ptr<McapSource> s(new McapSource());
  s->reader_ = std::move(*r);
  auto meta = s->reader_->metadata(kMcapRecordingMetadata);
  if (!meta) return meta.error();
  if (*meta) s->meta_ = **meta;
  const std::uint16_t frames = s->reader_->channel_id("/augrig/frame");
  if (frames == 0)
    return Error{"recorder::McapSource::open(): " + path +
                 ": no /augrig/frame channel: not an MCAP file written by augrig export "
                 "(augrig_msgs/msg/StereoFrameInfo)"};
  if (const auto& st = s->reader_->summary().statistics) {
    const auto it = st->channel_message_counts.find(frames);
    if (it != st->channel_message_counts.end()) s->frame_count_ = static_cast<std::size_t>(it->second);
  }
  return s;
}

Expected<bool> McapSource::next_frame(std::map<std::string, std::vector<std::uint8_t>>& messages) {
  messages.clear();
  McapMessage m;
  if (!have_pending_) {
    // The first /augrig/frame: everything before it (nothing, from our export) is skipped.
    while (true) {
      auto more = reader_->next(m);
      if (!more) return more.error();
      if (!*more) return false;
      if (reader_->channels().at(m.channel_id).topic == "/augrig/frame") break;
    }
    pending_ = std::move(m);
    have_pending_ = true;
  }
  messages["/augrig/frame"] = std::move(pending_.data);
  have_pending_ = false;
  while (true) {
    auto more = reader_->next(m);
    if (!more) return more.error();
    if (!*more) break;
    const std::string& topic = reader_->channels().at(m.channel_id).topic;
    if (topic == "/augrig/frame") {
      pending_ = std::move(m);
      have_pending_ = true;
      break;
    }
    if (topic.rfind("/nav/", 0) == 0) continue;  // the nav inputs follow the frames: not needed here
    messages[topic] = std::move(m.data);
  }
  return true;
}

namespace {

// A sensor_msgs/msg/CompressedImage in a format OpenCV reads (jpeg, png): RGB8, or Mono8 when gray.
Expected<Image> decode_compressed(const std::vector<std::uint8_t>& msg) {
  auto c = ros2::decode_compressed_image(msg);
  if (!c) return c.error();
  cv::Mat m;
  try {
    m = cv::imdecode(c->data, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return make_error("format '", c->format, "': ", e.what());
  }
  if (m.empty() || m.depth() != CV_8U || (m.channels() != 1 && m.channels() != 3))
    return make_error("format '", c->format, "', ", c->data.size(), " bytes: not an 8-bit gray or colour image OpenCV can decode");
  Image im(m.cols, m.rows, m.channels() == 1 ? PixelFormat::kMono8 : PixelFormat::kRGB8);
  cv::Mat out(m.rows, m.cols, m.type(), im.data(), im.stride_bytes());
  if (m.channels() == 3)
    cv::cvtColor(m, out, cv::COLOR_BGR2RGB);
  else
    m.copyTo(out);
  return im;
}

}  // namespace

// The next unit of camera `c`'s raw H.264 stream, cropped to the size the frame's info records.
Expected<Image> McapSource::decode_video(int c, const std::vector<std::uint8_t>& msg,
                                         const ros2::CameraFrameInfo& ci) {
  auto v = ros2::decode_compressed_video(msg);
  if (!v) return v.error();
  if (v->format != "h264") return make_error("format '", v->format, "': expected h264");
  auto& dec = decoders_[static_cast<std::size_t>(c)];
  if (!dec) {
    auto made = H264Decoder::create();
    if (!made) return made.error();
    dec = std::move(*made);
  }
  return dec->decode(v->data.data(), v->data.size(), ci.width, ci.height);
}

Expected<ReadStatus> McapSource::read(Frame& out, std::chrono::nanoseconds) {
  if (right_pending_) {
    right_pending_ = false;
    out = std::move(right_);
    right_ = Frame{};
    return ReadStatus::kFrame;
  }
  if (ended_) return ReadStatus::kEndOfStream;
  std::map<std::string, std::vector<std::uint8_t>> msgs;
  auto more = next_frame(msgs);
  if (!more) {
    // Damage to the file itself: nothing after it can be trusted to be found.
    ended_ = true;
    return Error{"recorder::McapSource::read(): " + more.error().message + "; the replay stops here"};
  }
  if (!*more) {
    ended_ = true;
    return ReadStatus::kEndOfStream;
  }
  auto info = ros2::decode_stereo_frame_info(msgs["/augrig/frame"]);
  const std::string where = "recorder::McapSource::read(): " + reader_->path() + ": ";
  if (!info) {
    ++damaged_;
    return Error{where + "a stereo frame: " + info.error().message + "; skipped, the next read() goes on"};
  }
  auto fail = [&](const std::string& what) -> Error {
    ++damaged_;
    return Error{where + "frame " + std::to_string(info->index) + ": " + what +
                 "; skipped, the next read() goes on"};
  };
  auto rf = std::make_shared<RecordedFrame>();
  rf->index = static_cast<std::size_t>(info->index);
  FrameRecord& rec = rf->record;
  rec.raw.pair_sequence = info->pair_sequence;
  rec.raw.t_key_ns = info->t_key_ns;
  rec.raw.skew_ns = info->skew_ns;
  for (int c = 0; c < 2; ++c) {
    const std::string cam = std::string("/") + kCameraNames[c];
    const ros2::CameraFrameInfo& ci = c == 0 ? info->left : info->right;
    Frame& fr = c == 0 ? rec.raw.left : rec.raw.right;
    if (const auto video = msgs.find(cam + "/image_raw/h264");
        video != msgs.end() && !msgs.count(cam + "/image_raw")) {
      // An H.264 export (--images h264): this camera's stream decoded in order, RGB8 (Mono8 for gray).
      auto im = decode_video(c, video->second, ci);
      if (!im) return fail(cam + "/image_raw/h264: " + im.error().message);
      fr.image = std::move(*im);
    } else if (const auto jpeg = msgs.find(cam + "/image_raw/compressed");
               jpeg != msgs.end() && !msgs.count(cam + "/image_raw")) {
      // A JPEG export (--images jpeg): the decoded colours (a Bayer camera's demosaiced), RGB8.
      auto im = decode_compressed(jpeg->second);
      if (!im) return fail(cam + "/image_raw/compressed: " + im.error().message);
      fr.image = std::move(*im);
    } else {
      const auto it = msgs.find(cam + "/image_raw");
      if (it == msgs.end()) return fail("no " + cam + "/image_raw message");
      auto im = ros2::decode_image(it->second);
      if (!im) return fail(cam + "/image_raw: " + im.error().message);
      // The recorded PFNC name wins over the ROS encoding (they agree for what we write).
      PixelFormat pf;
      if (!parse_pixel_format(ci.pixel_format, pf) || bytes_per_pixel(pf) != bytes_per_pixel(im->format()))
        return fail(cam + ": pixel format '" + ci.pixel_format + "' does not match the image's encoding");
      fr.image = Image::copy_of({im->data(), im->width(), im->height(), im->stride_bytes(), pf});
    }
    fr.t_ns = ci.t_ns;
    if (!parse_clock_domain(ci.clock, fr.clock)) fr.clock = ClockDomain::kUnknown;
    fr.t_host_ns = ci.t_host_ns;
    fr.sequence = ci.sequence;
    fr.exposure_ns = ci.exposure_ns;
    fr.camera = c == 0 ? CameraId::kLeft : CameraId::kRight;
    if (const auto p = msgs.find(cam + "/receiver_pose"); p != msgs.end()) {
      auto pose = ros2::decode_pose_with_covariance(p->second);
      if (!pose) return fail(cam + "/receiver_pose: " + pose.error().message);
      rec.T_cam_receiver[c] = *pose;
    }
  }
  if (const auto t = msgs.find("/tf"); t != msgs.end()) {
    auto tf = ros2::decode_tf_message(t->second);
    if (!tf) return fail("/tf: " + tf.error().message);
    for (const ros2::Transform& x : *tf)
      if (x.parent == kBodyFrame && x.child == kReceiverFrame) rec.T_body_receiver = x.T_parent_child;
  }
  if (const auto s = msgs.find("/augrig/occlusion_stats"); s != msgs.end()) {
    auto st = ros2::decode_occlusion_stats(s->second);
    if (!st) return fail("/augrig/occlusion_stats: " + st.error().message);
    rec.stats = *st;
  }
  if (info->receiver_present >= 0) rec.receiver_present = info->receiver_present == 1;
  rec.boom = info->boom;
  rec.sigma_pos_m = info->sigma_pos_m;
  rec.sigma_att_deg = info->sigma_att_deg;

  // The Frames carry the record (whose raw images the Frames already hold: not kept twice).
  Frame left = std::move(rec.raw.left), right = std::move(rec.raw.right);
  rec.raw.left.t_ns = left.t_ns;
  rec.raw.right.t_ns = right.t_ns;
  left.attachment = rf;
  right.attachment = rf;
  out = std::move(left);
  right_ = std::move(right);
  right_pending_ = true;
  return ReadStatus::kFrame;
}

}  // namespace augrig::recorder
