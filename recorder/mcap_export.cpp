// export_mcap(), McapFrameWriter and merge_mcap() (mcap_export.hpp): a recording's frames and nav
// inputs as ROS 2 messages through McapWriter. Read back by McapSource (mcap_source.cpp).
#include "recorder/mcap_export.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "nav/imu_stream.hpp"
#include "nav/logs.hpp"
#include "nav/nmea.hpp"
#include "recorder/mcap_reader.hpp"
#include "recorder/mcap_writer.hpp"
#include "render/image_file.hpp"
#include "ros2/messages.hpp"

namespace augrig::recorder {
namespace fs = std::filesystem;

namespace {

using mcap_names::kBodyFrame;
using mcap_names::kCameraFrames;
using mcap_names::kCameraNames;
using mcap_names::kReceiverFrame;

// offered_qos_profiles as rosbag2 (Humble's integer enums) records them: reliable, volatile (or
// transient_local for /tf_static, so that `ros2 bag play` latches it), keep-all history.
std::string qos(bool transient_local) {
  const char* inf = "    sec: 2147483647\n    nsec: 4294967295\n";
  return std::string("- history: 3\n  depth: 0\n  reliability: 1\n  durability: ") +
         (transient_local ? "1" : "2") + "\n  deadline:\n" + inf + "  lifespan:\n" + inf +
         "  liveliness: 1\n  liveliness_lease_duration:\n" + inf + "  avoid_ros_namespace_conventions: false";
}

// Channels by topic, made at their first message; schemas by type, shared.
class Channels {
 public:
  explicit Channels(McapWriter& w) : w_(w) {}
  Status write(const std::string& topic, const std::string& type, std::int64_t log_time_ns,
               const std::vector<std::uint8_t>& msg, McapExportReport& report) {
    auto it = channels_.find(topic);
    if (it == channels_.end()) {
      auto s = schemas_.find(type);
      if (s == schemas_.end())
        s = schemas_.emplace(type, w_.add_schema(type, "ros2msg", ros2::schema_text(type))).first;
      it = channels_
               .emplace(topic, w_.add_channel(s->second, topic, "cdr",
                                              {{"offered_qos_profiles", qos(topic == "/tf_static")}}))
               .first;
    }
    ++report.messages_by_topic[topic];
    return w_.write_message(it->second, static_cast<std::uint64_t>(log_time_ns), msg);
  }

 private:
  McapWriter& w_;
  std::map<std::string, std::uint16_t> schemas_, channels_;
};

// "tanker.imu" -> "tanker_body"; "imu" -> "tanker_body" (a plain stream is the tanker's, as in the export to
// EuRoC).
std::string aircraft_of(const std::string& stream) {
  const auto dot = stream.find('.');
  return dot == std::string::npos ? "tanker" : stream.substr(0, dot);
}

std::string nav_topic(const std::string& stream) {
  std::string t = "/nav/" + stream;
  for (char& c : t)
    if (c == '.') c = '/';
  return t;
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The nav inputs: each IMU increment as mean rates at the middle of its interval, each GPS epoch
// as a NavSatFix. Streams neither IMU nor GPS are left out (noted).
Status export_nav(const RecordingReader& reader, Channels& ch, McapExportReport& report) {
  auto all = reader.nav_inputs();
  if (!all) {
    report.problems.push_back("nav inputs: " + all.error().message);
    return {};
  }
  std::map<std::string, std::vector<const NavInputRecord*>> streams;
  for (const NavInputRecord& r : *all) streams[r.stream].push_back(&r);
  for (const auto& [name, rows] : streams) {
    const std::string topic = nav_topic(name);
    const std::string aircraft = aircraft_of(name);
    if (ends_with(name, "imu")) {
      std::vector<nav::ImuSample> samples;
      std::string text;
      std::size_t undecodable = 0;
      for (const NavInputRecord* r : rows) {
        if (!r->binary) {
          text += r->data + "\n";
          continue;
        }
        auto d = nav::decode_imu_datagram(std::span<const std::uint8_t>(
            reinterpret_cast<const std::uint8_t*>(r->data.data()), r->data.size()));
        if (!d) {
          ++undecodable;
          continue;
        }
        samples.insert(samples.end(), d->samples.begin(), d->samples.end());
      }
      if (!text.empty()) {
        std::istringstream in(std::string(imu_input_header()) + "\n" + text);
        auto log = nav::parse_imu_csv(in, name);
        if (!log) {
          report.problems.push_back("nav input stream '" + name + "': " + log.error().message);
        } else {
          samples.insert(samples.end(), log->samples.begin(), log->samples.end());
        }
      }
      if (undecodable)
        report.problems.push_back("nav input stream '" + name + "': " + std::to_string(undecodable) +
                                  " IMU datagram(s) could not be decoded, left out");
      std::stable_sort(samples.begin(), samples.end(),
                       [](const nav::ImuSample& a, const nav::ImuSample& b) { return a.t_ns < b.t_ns; });
      for (const nav::ImuSample& s : samples) {
        if (!(s.dt_s > 0)) continue;
        const std::int64_t t = s.t_ns - static_cast<std::int64_t>(std::llround(s.dt_s * 0.5e9));
        if (!ros2::check_stamp(t)) continue;
        if (Status st =
                ch.write(topic, "sensor_msgs/msg/Imu", t,
                         ros2::imu(t, aircraft + "_body", s.dtheta_rad / s.dt_s, s.dv_mps / s.dt_s), report);
            !st)
          return st;
      }
    } else if (ends_with(name, "gps")) {
      std::string text;
      for (const NavInputRecord* r : rows)
        if (!r->binary) text += r->data + "\n";
      std::istringstream in(text);
      nav::NmeaOptions no;
      auto log = nav::parse_nmea(in, name, no);
      if (!log) {
        report.problems.push_back("nav input stream '" + name + "': " + log.error().message);
        continue;
      }
      for (const nav::GpsFix& f : log->fixes) {
        if (!ros2::check_stamp(f.t_ns)) continue;
        int status = -1;
        switch (f.quality) {
          case nav::FixQuality::kInvalid:
            status = -1;
            break;
          case nav::FixQuality::kDgps:
            status = 1;
            break;
          case nav::FixQuality::kRtkFixed:
          case nav::FixQuality::kRtkFloat:
            status = 2;
            break;
          default:
            status = 0;
            break;
        }
        // GST gives north, east, down; NavSatFix's covariance is east, north, up.
        Eigen::Vector3d sigma_enu = Eigen::Vector3d::Zero();
        if (f.sigma_ned_m)
          sigma_enu = Eigen::Vector3d((*f.sigma_ned_m)[1], (*f.sigma_ned_m)[0], (*f.sigma_ned_m)[2]);
        if (Status st = ch.write(
                topic, "sensor_msgs/msg/NavSatFix", f.t_ns,
                ros2::nav_sat_fix(f.t_ns, aircraft + "_gps", status, f.antenna.lat_rad * 180.0 / M_PI,
                                  f.antenna.lon_rad * 180.0 / M_PI, f.antenna.h_m, sigma_enu),
                report);
            !st)
          return st;
      }
    } else {
      report.notes.push_back("nav input stream '" + name + "' is neither IMU nor GPS: left out");
    }
  }
  return {};
}

}  // namespace

McapFrame mcap_frame_of(const FrameRecord& f) {
  McapFrame m;
  m.raw = &f.raw;
  for (int c = 0; c < 2; ++c) {
    if (!f.augmented[c].empty()) m.augmented[c] = f.augmented[c].cview();
    if (!f.mask[c].empty()) m.mask[c] = f.mask[c].cview();
  }
  m.T_cam_receiver = f.T_cam_receiver;
  m.T_body_receiver = f.T_body_receiver;
  m.receiver_present = f.receiver_present;
  m.sigma_pos_m = f.sigma_pos_m;
  m.sigma_att_deg = f.sigma_att_deg;
  m.boom = f.boom;
  m.stats = f.stats ? &*f.stats : nullptr;
  return m;
}

struct McapFrameWriter::Impl {
  std::string out_path, part;
  McapExportOptions options;
  std::optional<Rig> rig;
  McapExportReport* report = nullptr;
  std::unique_ptr<McapWriter> writer;
  std::optional<Channels> ch;
  bool static_written = false;
  bool finished = false;

  Status put(const std::string& topic, const char* type, std::int64_t t_ns, const std::vector<std::uint8_t>& msg) {
    return ch->write(topic, type, t_ns, msg, *report);
  }
  std::map<std::string, std::unique_ptr<H264Encoder>> h264;  // by topic, made at its first image

  // An image on `topic` as it is, or with options.jpeg on topic + "/compressed" as JPEG, or with
  // options.h264 on topic + "/h264" as the next unit of that topic's H.264 stream.
  Status put_image(const std::string& topic, std::int64_t t_ns, const char* frame_id, ConstImageView im) {
    if (options.h264) return put_h264(topic, t_ns, frame_id, im);
    if (!options.jpeg) return put(topic, "sensor_msgs/msg/Image", t_ns, ros2::image(t_ns, frame_id, im));
    auto jpeg = encode_jpeg(im, options.jpeg_quality);
    if (!jpeg) return make_error("recorder::export_mcap(): ", out_path, ": ", topic, ": ", jpeg.error().message);
    return put(topic + "/compressed", "sensor_msgs/msg/CompressedImage", t_ns,
               ros2::compressed_image(t_ns, frame_id, "jpeg", *jpeg));
  }
  Status put_h264(const std::string& topic, std::int64_t t_ns, const char* frame_id, ConstImageView im) {
    auto& enc = h264[topic];
    // A new size (none in one recording, but a sink's source may change) starts a new stream.
    if (!enc || enc->width() != im.width || enc->height() != im.height) {
      H264Options o;
      o.gop_frames = options.h264_gop_frames;
      o.crf = options.h264_crf;
      auto made = H264Encoder::create(im.width, im.height, o);
      if (!made)
        return make_error("recorder::export_mcap(): ", out_path, ": ", topic, ": ", made.error().message);
      enc = std::move(*made);
    }
    auto unit = enc->encode(im, t_ns);
    if (!unit)
      return make_error("recorder::export_mcap(): ", out_path, ": ", topic, ": ", unit.error().message);
    return put(topic + "/h264", "foxglove_msgs/msg/CompressedVideo", t_ns,
               ros2::compressed_video(t_ns, frame_id, "h264", unit->data));
  }
  Status write_camera(const McapFrame& f, int c);
};

Expected<std::unique_ptr<McapFrameWriter>> McapFrameWriter::create(const std::string& out_path,
                                                                   const McapExportOptions& options,
                                                                   const std::map<std::string, std::string>& meta,
                                                                   std::optional<Rig> rig,
                                                                   McapExportReport& report) {
  if (rig && rig->cameras.size() < 2)
    return make_error("recorder::McapFrameWriter: ", out_path, ": the rig has fewer than 2 cameras");
  if (options.jpeg && options.h264)
    return make_error("recorder::McapFrameWriter: ", out_path, ": images as JPEG or as H.264, not both");
  if (options.h264 && (options.h264_gop_frames < 1 || options.h264_crf < 0 || options.h264_crf > 51))
    return make_error("recorder::McapFrameWriter: ", out_path, ": H.264 keyframe interval ",
                      options.h264_gop_frames, " and quality ", options.h264_crf,
                      ": expected >= 1 frames and crf 0..51");
  if (options.jpeg && (options.jpeg_quality < 1 || options.jpeg_quality > 100))
    return make_error("recorder::McapFrameWriter: ", out_path, ": JPEG quality ", options.jpeg_quality,
                      ": expected 1..100");
  std::unique_ptr<McapFrameWriter> w(new McapFrameWriter);
  w->impl_ = std::make_unique<Impl>();
  Impl& m = *w->impl_;
  m.out_path = out_path;
  m.part = out_path + ".part";
  m.options = options;
  m.rig = std::move(rig);
  m.report = &report;
  McapWriterOptions wo;
  wo.chunk_size_bytes = options.chunk_size_bytes;
  wo.zstd_level = options.zstd_level;
  wo.library = "augrig " AUGRIG_VERSION;
  auto writer = McapWriter::create(m.part, wo);
  if (!writer) return writer.error();
  m.writer = std::move(*writer);
  // The meta table first: what a replay needs (the rig) before any frame.
  if (Status s = m.writer->write_metadata(kMcapRecordingMetadata, meta); !s) return s.error();
  m.ch.emplace(*m.writer);
  return w;
}

McapFrameWriter::~McapFrameWriter() = default;

Status McapFrameWriter::Impl::write_camera(const McapFrame& f, int c) {
  const Frame& fr = c == 0 ? f.raw->left : f.raw->right;
  const std::string cam = std::string("/") + kCameraNames[c];
  const char* frame_id = kCameraFrames[c];
  if (Status s = put_image(cam + "/image_raw", fr.t_ns, frame_id, fr.image.cview()); !s) return s;
  if (rig)
    if (Status s = put(cam + "/camera_info", "sensor_msgs/msg/CameraInfo", fr.t_ns,
                       ros2::camera_info(fr.t_ns, frame_id, rig->cameras[static_cast<std::size_t>(c)].model));
        !s)
      return s;
  if (options.augmented && f.augmented[c].width > 0)
    if (Status s = put_image(cam + "/image_augmented", fr.t_ns, frame_id, f.augmented[c]); !s) return s;
  if (options.masks && f.mask[c].width > 0)
    if (Status s = put(cam + "/mask", "sensor_msgs/msg/Image", fr.t_ns, ros2::image(fr.t_ns, frame_id, f.mask[c]));
        !s)
      return s;
  if (!f.T_cam_receiver[c]) return {};
  const std::int64_t t = f.raw->t_key_ns;
  return put(cam + "/receiver_pose", "geometry_msgs/msg/PoseWithCovarianceStamped", t,
             ros2::pose_with_covariance(t, frame_id, *f.T_cam_receiver[c],
                                        ros2::pose_covariance(f.sigma_pos_m, f.sigma_att_deg)));
}

Status McapFrameWriter::write(const McapFrame& f, std::uint64_t index, const std::string& where) {
  Impl& m = *impl_;
  const StereoFrame& raw = *f.raw;
  for (std::int64_t t : {raw.t_key_ns, raw.left.t_ns, raw.right.t_ns})
    if (Status s = ros2::check_stamp(t); !s)
      return make_error("recorder::export_mcap(): ", m.out_path, ": ", where, ": ", s.error().message);
  // The cameras' poses on the tanker, once, at the first frame's time.
  if (m.rig && !m.static_written) {
    std::vector<ros2::Transform> tf;
    tf.reserve(2);
    for (int c = 0; c < 2; ++c)
      tf.push_back({raw.t_key_ns, kBodyFrame, kCameraFrames[c], m.rig->cameras[static_cast<std::size_t>(c)].T_body_cam});
    if (Status s = m.put("/tf_static", "tf2_msgs/msg/TFMessage", raw.t_key_ns, ros2::tf_message(tf)); !s) return s;
    m.static_written = true;
  }
  // /augrig/frame first: a reader starts a stereo frame at it (McapSource).
  ros2::StereoFrameInfo info = ros2::stereo_frame_info_of(raw, index);
  info.receiver_present = f.receiver_present ? (*f.receiver_present ? 1 : 0) : -1;
  info.boom = f.boom;
  info.sigma_pos_m = f.sigma_pos_m;
  info.sigma_att_deg = f.sigma_att_deg;
  if (Status s = m.put("/augrig/frame", "augrig_msgs/msg/StereoFrameInfo", raw.t_key_ns,
                       ros2::stereo_frame_info(raw.t_key_ns, info));
      !s)
    return s;
  for (int c = 0; c < 2; ++c)
    if (Status s = m.write_camera(f, c); !s) return s;
  if (f.T_body_receiver)
    if (Status s = m.put("/tf", "tf2_msgs/msg/TFMessage", raw.t_key_ns,
                         ros2::tf_message({{raw.t_key_ns, kBodyFrame, kReceiverFrame, *f.T_body_receiver}}));
        !s)
      return s;
  if (f.stats)
    if (Status s = m.put("/augrig/occlusion_stats", "augrig_msgs/msg/OcclusionStats", raw.t_key_ns,
                         ros2::occlusion_stats(raw.t_key_ns, *f.stats));
        !s)
      return s;
  ++m.report->frames_written;
  return {};
}

Status McapFrameWriter::write_message(const std::string& topic, const std::string& type, std::int64_t log_time_ns,
                                      const std::vector<std::uint8_t>& data) {
  return impl_->put(topic, type.c_str(), log_time_ns, data);
}

Status McapFrameWriter::write_nav(const RecordingReader& reader) {
  return export_nav(reader, *impl_->ch, *impl_->report);
}

Status McapFrameWriter::finish() {
  Impl& m = *impl_;
  if (m.finished) return {};
  m.finished = true;
  if (Status s = m.writer->close(); !s) return s;
  m.report->messages = m.writer->stats().messages;
  m.report->chunks = m.writer->stats().chunks;
  m.report->bytes = m.writer->stats().bytes_written;
  std::error_code ec;
  fs::rename(m.part, m.out_path, ec);
  if (ec)
    return make_error("recorder::export_mcap(): ", m.out_path, ": cannot rename ", m.part, " to it: ", ec.message());
  return {};
}

Status export_mcap(const RecordingReader& reader, const std::string& out_path,
                   const McapExportOptions& options, McapExportReport& report) {
  std::optional<Rig> rig = options.rig;
  if (!rig) {
    if (const std::string yaml = reader.meta("rig_yaml"); !yaml.empty()) {
      auto r = parse_rig(yaml, reader.path() + " (meta rig_yaml)");
      if (!r) return r.error();
      rig = *r;
    } else {
      report.notes.push_back("the recording stores no rig: no camera_info and no /tf_static (give --rig)");
    }
  }
  if (rig && rig->cameras.size() < 2)
    return make_error("recorder::export_mcap(): ", out_path, ": the rig has fewer than 2 cameras");
  for (const std::string& p : reader.problems()) report.problems.push_back(reader.path() + ": " + p);
  auto writer = McapFrameWriter::create(out_path, options, reader.meta(), rig, report);
  if (!writer) return writer.error();

  unsigned parts = kPartRaw;
  if (options.augmented) parts |= kPartAugmented;
  if (options.masks) parts |= kPartMasks;
  report.frames = reader.frame_count();
  for (std::size_t i = 0; i < report.frames; ++i) {
    auto f = reader.read_frame(i, parts);
    if (!f) {
      report.problems.push_back(f.error().message + "; frame " + std::to_string(i) + " left out");
      continue;
    }
    if (Status s = (*writer)->write(mcap_frame_of(*f), i, reader.path() + ": frame " + std::to_string(i)); !s)
      return s;
    if (options.progress) options.progress(i + 1, report.frames);
  }
  if (options.nav)
    if (Status s = (*writer)->write_nav(reader); !s) return s;
  return (*writer)->finish();
}

Status merge_mcap(const std::vector<std::string>& inputs, const std::string& out_path,
                  const RecordingReader* nav_from, McapExportReport& report) {
  if (inputs.empty()) return make_error("recorder::merge_mcap(): ", out_path, ": no files to join");
  std::unique_ptr<McapFrameWriter> writer;
  bool static_written = false;  // each shard's file has its /tf_static; the flight's, one
  for (const std::string& in : inputs) {
    auto r = McapReader::open(in);
    if (!r) return r.error();
    McapReader& reader = **r;
    if (!writer) {  // the first file's metadata stands for all
      auto meta = reader.metadata(kMcapRecordingMetadata);
      if (!meta) return meta.error();
      McapExportOptions o;
      auto w = McapFrameWriter::create(out_path, o, meta->value_or(std::map<std::string, std::string>{}),
                                       std::nullopt, report);
      if (!w) return w.error();
      writer = std::move(*w);
    }
    McapMessage m;
    while (true) {
      auto more = reader.next(m);
      if (!more) return more.error();
      if (!*more) break;
      const McapChannelInfo& ch = reader.channels().at(m.channel_id);
      const McapSchemaInfo& schema = reader.schemas().at(ch.schema_id);
      if (ch.topic == "/tf_static" && static_written && in != inputs.front()) continue;
      if (ch.topic == "/tf_static") static_written = true;
      if (ch.topic == "/augrig/frame") {
        ++report.frames;
        ++report.frames_written;
      }
      if (Status s = writer->write_message(ch.topic, schema.name, static_cast<std::int64_t>(m.log_time_ns), m.data);
          !s)
        return s;
    }
  }
  if (nav_from)
    if (Status s = writer->write_nav(*nav_from); !s) return s;
  return writer->finish();
}

}  // namespace augrig::recorder
