// The EuRoC export's frames: each camera's raw, augmented and mask images as PNG (core/png) and,
// with --ground-truth, the ground truth beside them, written by worker threads (core/worker)
// while the caller's thread reads the next frame; then each stream's data.csv and sensor.yaml.
#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>

#include "core/png.hpp"
#include "core/worker.hpp"
#include "recorder/euroc_export_detail.hpp"
#include "render/ground_truth.hpp"

namespace augrig::recorder::euroc_detail {

namespace {

// One output image stream: mav0/<name>/data/<t_ns>.png and data.csv.
struct StreamOut {
  fs::path dir;
  std::string csv;  // data.csv's text, in frame order
  std::set<TimestampNs> seen;
  std::size_t written = 0;
  PixelFormat format = PixelFormat::kMono8;
  ClockDomain clock = ClockDomain::kUnknown;
  int width = 0, height = 0;
  bool created = false;
};

constexpr const char* kStreamSuffix[3] = {"", "_augmented", "_mask"};
constexpr const char* kStreamName[3] = {"raw", "augmented", "mask"};

// The ground truth streams (EurocExportOptions::ground_truth), each a folder of mav0/ with data/
// and data.csv: per camera the depth (.npy) and its 16-bit mm PNG; for the left camera the
// correspondence into the right image (.npy) and the stereo classes (PNG).
enum GtStream { kGtDepth0, kGtDepth1, kGtDepthMm0, kGtDepthMm1, kGtRightPx, kGtStereoClass, kGtStreams };
constexpr const char* kGtFolder[kGtStreams] = {"cam0_depth",    "cam1_depth",    "cam0_depth_mm",
                                               "cam1_depth_mm", "cam0_right_px", "cam0_stereo_class"};
constexpr const char* kGtExt[kGtStreams] = {".npy", ".npy", ".png", ".png", ".npy", ".png"};
constexpr int kGtCamera[kGtStreams] = {0, 1, 0, 1, 0, 0};  // whose timestamp names the file
constexpr const char* kGtContent[kGtStreams] = {
    "receiver depth, float32 H x W .npy, metres along the optical axis (z), NaN where no receiver",
    "receiver depth, float32 H x W .npy, metres along the optical axis (z), NaN where no receiver",
    "receiver depth, 16-bit PNG, round(z * 1000) mm, 0 where no receiver, 65535 = 65.535 m or more",
    "receiver depth, 16-bit PNG, round(z * 1000) mm, 0 where no receiver, 65535 = 65.535 m or more",
    ("float32 H x W x 2 .npy: (u, v) in the right raw image of each left receiver pixel's surface point, NaN "
     "where none"),
    "8-bit PNG: stereo class per left pixel, 0 no receiver, 1 both, 2 left only, 3 right only, 4 neither"};

struct GtStreamOut {
  fs::path dir;
  std::string csv;
  std::set<TimestampNs> seen;
  std::size_t written = 0;
  bool created = false;
};

// sensor.yaml of a ground truth stream: what its files hold, on which clock.
std::string ground_truth_yaml(int k, const RigCamera& camera, double rate_hz, ClockDomain clock) {
  std::ostringstream o;
  o << "# augrig export --ground-truth: " << kGtFolder[k] << " (docs/GROUND_TRUTH.md), the "
    << (kGtCamera[k] ? "right" : "left") << " camera ('" << camera.name << "'); pixels are its raw pixels.\n"
    << "sensor_type: ground_truth\n"
    << "comment: \"" << kGtContent[k] << "\"\n"
    << "rate_hz: " << num(rate_hz) << "\n"
    << "resolution: [" << camera.model.width_px << ", " << camera.model.height_px << "]\n"
    << "augrig:\n  stream: " << (std::string(kGtFolder[k]).substr(5)) << "\n  clock: " << to_string(clock)
    << "\n";
  return o.str();
}

// The work of one camera of one frame: its raw, augmented and mask images encoded and written; or
// (camera kGroundTruthJob) the frame's ground truth, made from its depth, masks and the rig.
constexpr int kGroundTruthJob = 2;
struct CameraJob {
  std::shared_ptr<const FrameRecord> rec;
  int camera = 0;
  fs::path files[3];  // empty: not written
  const Rig* rig = nullptr;
  fs::path gt_files[kGtStreams];  // kGroundTruthJob; empty: not written
};

// What docs/GROUND_TRUTH.md's files beside a frame's images hold, from what a recording keeps:
// the depth as recorded, the correspondence (render/ground_truth.hpp) and the stereo classes
// (render/stats.hpp, the augmenter's own test) from the depth, the masks and the rig.
Status run_ground_truth_job(const CameraJob& job) {
  const FrameRecord& r = *job.rec;
  const Rig& rig = *job.rig;
  const DepthImage depth[2] = {r.receiver_depth[0].image(), r.receiver_depth[1].image()};
  for (int c = 0; c < 2; ++c) {
    if (!job.gt_files[kGtDepth0 + c].empty())
      if (Status s = write_depth_npy(job.gt_files[kGtDepth0 + c].string(), depth[c]); !s) return s;
    if (!job.gt_files[kGtDepthMm0 + c].empty())
      if (Status s = write_depth_mm_png(job.gt_files[kGtDepthMm0 + c].string(), depth[c]); !s) return s;
  }
  const CameraModel& left = rig.cameras[0].model;
  const CameraModel& right = rig.cameras[1].model;
  const Pose T_right_left = rig.T_right_left();
  const int w = depth[0].width, h = depth[0].height;
  if (!job.gt_files[kGtRightPx].empty())
    if (Status s = write_correspondence_npy(job.gt_files[kGtRightPx].string(),
                                            right_correspondence(depth[0], left, right, T_right_left), w, h);
        !s)
      return s;
  if (!job.gt_files[kGtStereoClass].empty()) {
    std::vector<std::uint8_t> classes;
    StereoClassOptions o;  // the augmenter's defaults, as every command runs it
    (void)compute_occlusion_stats(0, r.mask[0], r.mask[1], depth[0], depth[1], left, right, T_right_left, o,
                                  &classes);
    if (Status s = write_stereo_class_png(job.gt_files[kGtStereoClass].string(), classes, w, h); !s) return s;
  }
  return {};
}

// One thread's PNG encoders (a zlib stream each, reused from image to image).
struct Encoders {
  PngEncoder image, mask;
  explicit Encoders(int compression)
      : image(compression, PngKind::kImage), mask(compression, PngKind::kMask) {}
};

Status run_camera_job(const CameraJob& job, Encoders& enc) {
  if (job.camera == kGroundTruthJob) return run_ground_truth_job(job);
  const int c = job.camera;
  const Image* images[3] = {&job.rec->raw[static_cast<CameraId>(c)].image, &job.rec->augmented[c],
                            &job.rec->mask[c]};
  std::optional<PngImage> raw_png;
  for (int k = 0; k < 3; ++k) {
    if (job.files[k].empty()) continue;
    // The raw encoding is kept for the augmented image, which equals it outside the boom's rows.
    auto png = k == 2   ? enc.mask.encode(*images[k])
               : k == 1 ? enc.image.encode(*images[k], raw_png ? &*raw_png : nullptr, images[0])
                        : enc.image.encode(*images[k]);
    if (!png) return make_error(job.files[k].string(), ": ", png.error().message);
    if (auto s = write_binary_file(job.files[k].string(), png_file(*png)); !s) return s;
    if (k == 0 && !job.files[1].empty()) raw_png = std::move(*png);
  }
  return {};
}

// Camera jobs on core/worker threads, each with its own encoders, from one bounded queue: push()
// waits while `capacity` jobs are queued (the frames read ahead stay bounded) and starts an idle
// worker, which runs queued jobs until none is left. Results are kept by frame.
class EncodePool {
 public:
  EncodePool(int threads, int compression, std::size_t capacity) : capacity_(capacity) {
    for (int t = 0; t < threads; ++t)
      slots_.push_back(std::make_unique<Slot>("augrig-export" + std::to_string(t), compression));
  }
  ~EncodePool() { stop(); }
  EncodePool(const EncodePool&) = delete;
  EncodePool& operator=(const EncodePool&) = delete;

  void push(std::size_t frame, CameraJob job) {
    Slot* idle = nullptr;
    {
      std::unique_lock lk(m_);
      cv_.wait(lk, [&] { return queue_.size() < capacity_; });
      queue_.emplace_back(frame, std::move(job));
      for (auto& s : slots_)
        if (!s->busy) {
          idle = s.get();
          idle->busy = true;
          break;
        }
    }
    if (!idle) return;    // every worker is running and takes the job from the queue
    idle->worker.wait();  // its last run has said it is done; now the Worker is free
    idle->worker.start([this, idle] { run_queue(*idle); });
  }

  // Waits (when `wait`) until `jobs` jobs of `frame` are done; their status, or nullopt when not yet.
  std::optional<Status> take(std::size_t frame, int jobs, bool wait) {
    std::unique_lock lk(m_);
    auto ready = [&] {
      auto it = done_.find(frame);
      return it != done_.end() && it->second.jobs >= jobs;
    };
    if (wait)
      cv_.wait(lk, ready);
    else if (!ready())
      return std::nullopt;
    Status s = done_[frame].status;
    done_.erase(frame);
    return s;
  }

  // The queued jobs are dropped; returns when the running ones have finished.
  void stop() {
    {
      std::lock_guard lk(m_);
      queue_.clear();
    }
    cv_.notify_all();
    for (auto& slot : slots_) Worker::Join join{slot->worker};
  }

 private:
  struct Slot {
    Slot(const std::string& name, int compression) : enc(compression), worker(name) {}
    Encoders enc;
    bool busy = false;  // under m_: running run_queue()
    Worker worker;      // last: its thread goes first
  };
  struct Done {
    int jobs = 0;
    Status status;
  };

  void run_queue(Slot& slot) {
    std::unique_lock lk(m_);
    while (!queue_.empty()) {
      auto [frame, job] = std::move(queue_.front());
      queue_.pop_front();
      lk.unlock();
      cv_.notify_all();  // room in the queue
      Status s = run_job(slot, frame, job);
      job.rec.reset();  // the images go as soon as they are written
      lk.lock();
      Done& d = done_[frame];
      ++d.jobs;
      if (!s && d.status) d.status = s;
      cv_.notify_all();
    }
    slot.busy = false;
  }

  static Status run_job(Slot& slot, std::size_t frame, const CameraJob& job) {
    try {
      return run_camera_job(job, slot.enc);
    } catch (const std::exception& e) {  // a job that throws fails the export, not the process
      return make_error("frame ", frame, ": ", e.what());
    } catch (...) {
      return make_error("frame ", frame, ": an unknown exception");
    }
  }

  std::size_t capacity_;
  std::mutex m_;
  std::condition_variable cv_;
  std::deque<std::pair<std::size_t, CameraJob>> queue_;
  std::map<std::size_t, Done> done_;
  std::vector<std::unique_ptr<Slot>> slots_;
};

// Per frame, what the export writes once its images are on disk (in frame order).
struct PendingFrame {
  std::size_t index = 0;
  int jobs = 0;
  bool readable = false;
  TimestampNs t_ns[2] = {0, 0};  // on the export's clock
  bool write[3][2] = {};
  bool write_gt[kGtStreams] = {};
  std::uint64_t sequence[2] = {0, 0};
};

// A recorded T_cam_receiver as a poses.csv row (nav/logs.hpp).
nav::CameraPoseRow pose_row(const FrameRecord& r, const Frame& f, int c, TimestampNs t_ns, const Pose& T) {
  nav::CameraPoseRow p;
  p.sequence = f.sequence;
  p.camera = c;
  p.t_ns = t_ns;
  p.t_nav_ns = t_ns;
  p.x_m = T.translation_m.x();
  p.y_m = T.translation_m.y();
  p.z_m = T.translation_m.z();
  const Eigen::Quaterniond q = T.rotation.normalized();
  p.qw = q.w();
  p.qx = q.x();
  p.qy = q.y();
  p.qz = q.z();
  p.sigma_pos_m = r.sigma_pos_m;
  p.sigma_att_deg = r.sigma_att_deg;
  if (r.boom) {
    p.boom_elevation_deg = rad_to_deg(r.boom->elevation_rad);
    p.boom_azimuth_deg = rad_to_deg(r.boom->azimuth_rad);
    p.boom_extension_m = r.boom->extension_m;
  }
  return p;
}

Status create_data_folder(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir / "data", ec);
  if (ec) return make_error((dir / "data").string(), ": cannot create the folder (", ec.message(), ")");
  return {};
}

}  // namespace

// The frames of one export, in order: images queued to the pool, their data.csv rows added once
// written (drain), the tables for the later files gathered on the way.
class FrameWriter::Impl {
 public:
  Impl(const ExportContext& cx, const ExportClock& clk, ExportProgress& progress, FrameTables& tables);
  Status add_frame(std::size_t i, Expected<FrameRecord> frame);
  Status finish();
  unsigned parts() const { return parts_; }

 private:
  Status queue_camera(std::size_t i, const std::shared_ptr<const FrameRecord>& rec, CameraId id,
                      PendingFrame& pf);
  Status check_depth(std::size_t i, const FrameRecord& r) const;
  Status queue_ground_truth(std::size_t i, const std::shared_ptr<const FrameRecord>& rec, PendingFrame& pf);
  Status submit(std::size_t i, CameraJob job, PendingFrame& pf);
  void gather(const FrameRecord& r);
  Status drain(bool wait);
  void add_rows(const PendingFrame& pf);
  Status write_stream_files();

  const ExportContext& cx_;
  const ExportClock& clk_;
  ExportProgress& progress_;
  FrameTables& tables_;
  StreamOut streams_[3][2];
  GtStreamOut gt_[kGtStreams];
  unsigned parts_ = kPartRaw;
  std::unique_ptr<EncodePool> pool_;      // threads > 1
  std::unique_ptr<Encoders> inline_enc_;  // threads == 1: on the caller's thread
  std::deque<PendingFrame> pending_;
  std::int64_t max_skew_ns_ = 0;
  bool no_class_noted_ = false;
};

FrameWriter::Impl::Impl(const ExportContext& cx, const ExportClock& clk, ExportProgress& progress,
                         FrameTables& tables)
    : cx_(cx), clk_(clk), progress_(progress), tables_(tables) {
  const EurocExportOptions& o = cx.options;
  for (int k = 0; k < 3; ++k)
    for (int c = 0; c < 2; ++c) streams_[k][c].dir = cx.mav0 / ("cam" + std::to_string(c) + kStreamSuffix[k]);
  for (int k = 0; k < kGtStreams; ++k) gt_[k].dir = cx.mav0 / kGtFolder[k];
  if (o.augmented) parts_ |= kPartAugmented;
  if (o.masks) parts_ |= kPartMasks;
  // The ground truth needs the depth, and the masks for the stereo classes.
  if (o.ground_truth) parts_ |= kPartDepth | kPartMasks;
  int threads = o.threads;
  if (threads <= 0) threads = std::max(2, static_cast<int>(std::thread::hardware_concurrency()));
  if (threads > 1)
    pool_ = std::make_unique<EncodePool>(threads, o.png_compression, static_cast<std::size_t>(2 * threads));
  else
    inline_enc_ = std::make_unique<Encoders>(o.png_compression);
  tables_.index.clock = clk.clock;
  tables_.index.metadata["content"] = "the exported raw frames (augrig export); t_ns on the export's clock";
}

Status FrameWriter::Impl::finish() {
  if (Status s = drain(true); !s) return s;
  if (pool_) pool_->stop();
  return write_stream_files();
}

Status FrameWriter::Impl::add_frame(std::size_t i, Expected<FrameRecord> rec) {
  PendingFrame pf;
  pf.index = i;
  if (!rec) {
    cx_.report.problems.push_back(strip_function(rec.error().message) + "; frame not exported");
    pending_.push_back(pf);
    return drain(false);
  }
  pf.readable = true;
  auto shared = std::make_shared<const FrameRecord>(std::move(*rec));
  for (CameraId id : {CameraId::kLeft, CameraId::kRight})
    if (Status s = queue_camera(i, shared, id, pf); !s) return s;
  const FrameRecord& r = *shared;
  if (cx_.options.ground_truth && !r.raw.left.image.empty() && !r.raw.right.image.empty()) {
    if (Status s = check_depth(i, r); !s) return s;
    if (Status s = queue_ground_truth(i, shared, pf); !s) return s;
  }
  gather(r);
  shared.reset();
  pending_.push_back(pf);
  return drain(false);
}

// One camera's images of frame i queued (each stream's folder made at its first image), and its
// poses gathered.
Status FrameWriter::Impl::queue_camera(std::size_t i, const std::shared_ptr<const FrameRecord>& rec, CameraId id,
                                   PendingFrame& pf) {
  const FrameRecord& r = *rec;
  const int c = index_of(id);
  const Frame& f = r.raw[id];
  if (f.image.empty()) return {};
  pf.t_ns[c] = clk_.map(c, f.t_ns);
  pf.sequence[c] = f.sequence;
  const Image* images[3] = {&f.image, &r.augmented[c], &r.mask[c]};
  CameraJob job;
  job.rec = rec;
  job.camera = c;
  bool any = false;
  for (int k = 0; k < 3; ++k) {
    if (images[k]->empty() || (k == 2 && !cx_.options.masks))
      continue;  // masks read for the ground truth only
    StreamOut& so = streams_[k][c];
    if (!so.created) {
      if (Status s = create_data_folder(so.dir); !s) return s;
      so.created = true;
      so.format = images[k]->format();
      so.clock = clk_.clock;
      so.width = images[k]->width();
      so.height = images[k]->height();
    }
    if (!so.seen.insert(pf.t_ns[c]).second) {
      cx_.report.problems.push_back("frame " + std::to_string(i) + ": " + so.dir.filename().string() +
                                    ": timestamp " + std::to_string(pf.t_ns[c]) +
                                    " repeats; the later image is not written");
      continue;
    }
    job.files[k] = so.dir / "data" / (std::to_string(pf.t_ns[c]) + ".png");
    pf.write[k][c] = any = true;
  }
  if (!any) return {};
  if (Status s = submit(i, std::move(job), pf); !s) return s;
  if (c == 0 && r.T_body_receiver && r.receiver_present.value_or(true))
    tables_.receiver_states.emplace_back(pf.t_ns[0], *r.T_body_receiver);
  // A frame augmented without the receiver (no nav pose yet) has no pose to export.
  if (const auto& T = r.T_cam_receiver[c]; T && r.receiver_present.value_or(true))
    tables_.poses.push_back(pose_row(r, f, c, pf.t_ns[c], *T));
  return {};
}

// The ground truth needs both depths, each of the rig's size.
Status FrameWriter::Impl::check_depth(std::size_t i, const FrameRecord& r) const {
  if (r.receiver_depth[0].empty() || r.receiver_depth[1].empty())
    return cx_.reader ? no_depth_error(*cx_.reader, i, r.raw.pair_sequence)
                      : make_error(cx_.from, ": pair ", i, " has no receiver depth: the ground truth needs it");
  for (int c = 0; c < 2; ++c) {
    const RigCamera& cam = cx_.rig.cameras[static_cast<std::size_t>(c)];
    const CameraModel& m = cam.model;
    if (r.receiver_depth[c].width != m.width_px || r.receiver_depth[c].height != m.height_px)
      return make_error(cx_.from, ": frame ", i, ": the ", c ? "right" : "left",
                        " receiver depth is ", r.receiver_depth[c].width, "x", r.receiver_depth[c].height,
                        ", the rig's ", cam.name, " camera ", m.width_px, "x", m.height_px,
                        ": the ground truth needs the rig the recording was made with");
  }
  return {};
}

Status FrameWriter::Impl::queue_ground_truth(std::size_t i, const std::shared_ptr<const FrameRecord>& rec,
                                         PendingFrame& pf) {
  const FrameRecord& r = *rec;
  CameraJob job;
  job.rec = rec;
  job.camera = kGroundTruthJob;
  job.rig = &cx_.rig;
  bool any = false;
  for (int k = 0; k < kGtStreams; ++k) {
    // The stereo classes come from both masks; a frame recorded without them has none.
    if (k == kGtStereoClass && (r.mask[0].empty() || r.mask[1].empty())) {
      if (!no_class_noted_)
        cx_.report.notes.push_back("frame " + std::to_string(i) + " (and maybe others) has no masks: " +
                                   kGtFolder[k] + " is not written for such frames");
      no_class_noted_ = true;
      continue;
    }
    GtStreamOut& so = gt_[k];
    const TimestampNs t = pf.t_ns[kGtCamera[k]];
    if (!so.created) {
      if (Status s = create_data_folder(so.dir); !s) return s;
      so.created = true;
    }
    if (!so.seen.insert(t).second) continue;  // a repeated time: reported with the images
    job.gt_files[k] = so.dir / "data" / (std::to_string(t) + kGtExt[k]);
    pf.write_gt[k] = any = true;
  }
  return any ? submit(i, std::move(job), pf) : Status{};
}

Status FrameWriter::Impl::submit(std::size_t i, CameraJob job, PendingFrame& pf) {
  if (!pool_) return run_camera_job(job, *inline_enc_);
  ++pf.jobs;
  pool_->push(i, std::move(job));
  return {};
}

// What the later files and the report take from frame `r`: skew, counts, statistics.
void FrameWriter::Impl::gather(const FrameRecord& r) {
  EurocExportReport& report = cx_.report;
  if (!r.raw.left.image.empty() && !r.raw.right.image.empty())
    max_skew_ns_ = std::max(max_skew_ns_, std::abs(r.raw.right.t_ns - r.raw.left.t_ns));
  if (!r.augmented[0].empty() || !r.augmented[1].empty()) ++report.augmented_written;
  if (cx_.options.masks && (!r.mask[0].empty() || !r.mask[1].empty())) ++report.masks_written;
  if (r.stats) {
    OcclusionStats s = *r.stats;
    // The statistics' time is the pair's, on the left camera's clock.
    s.t_ns = clk_.map(0, s.t_ns == 0 ? r.raw.t_key_ns : s.t_ns);
    tables_.stats.push_back(s);
  }
}

// Frames whose images are written: their data.csv rows, in frame order.
Status FrameWriter::Impl::drain(bool wait) {
  while (!pending_.empty()) {
    PendingFrame& pf = pending_.front();
    if (pf.jobs > 0 && pool_) {
      auto s = pool_->take(pf.index, pf.jobs, wait);
      if (!s) return {};
      if (!*s) return *s;
    }
    if (pf.readable)
      add_rows(pf);
    else
      ++tables_.skipped;
    pending_.pop_front();
    progress_.update(cx_.report, tables_.skipped, false);
  }
  return {};
}

void FrameWriter::Impl::add_rows(const PendingFrame& pf) {
  for (int c = 0; c < 2; ++c)
    for (int k = 0; k < 3; ++k) {
      if (!pf.write[k][c]) continue;
      StreamOut& so = streams_[k][c];
      const std::string name = std::to_string(pf.t_ns[c]) + ".png";
      so.csv += std::to_string(pf.t_ns[c]) + "," + name + "\n";
      ++so.written;
      if (k != 0) continue;
      nav::FrameIndexRow row;
      row.sequence = pf.sequence[c];
      row.camera = c;
      row.t_ns = pf.t_ns[c];
      row.file = "mav0/cam" + std::to_string(c) + "/data/" + name;
      tables_.index.rows.push_back(std::move(row));
    }
  for (int k = 0; k < kGtStreams; ++k) {
    if (!pf.write_gt[k]) continue;
    const TimestampNs t = pf.t_ns[kGtCamera[k]];
    gt_[k].csv += std::to_string(t) + "," + std::to_string(t) + kGtExt[k] + "\n";
    ++gt_[k].written;
  }
  if (pf.write_gt[kGtDepth0] || pf.write_gt[kGtDepth1]) ++cx_.report.ground_truth_written;
  ++cx_.report.frames_written;
}

// data.csv and sensor.yaml of every stream written, and the notes on what was not.
Status FrameWriter::Impl::write_stream_files() {
  EurocExportReport& report = cx_.report;
  for (int k = 0; k < 3; ++k)
    for (int c = 0; c < 2; ++c) {
      const StreamOut& w = streams_[k][c];
      if (!w.created) continue;
      if (auto s = write_text(w.dir / "data.csv", std::string(kCameraCsvHeader) + "\n" + w.csv); !s) return s;
      const RigCamera& cam = cx_.rig.cameras[static_cast<std::size_t>(c)];
      if (w.width != cam.model.width_px || w.height != cam.model.height_px)
        report.notes.push_back(w.dir.filename().string() + ": images are " + std::to_string(w.width) + "x" +
                               std::to_string(w.height) + ", the rig's " + cam.name + " camera is " +
                               std::to_string(cam.model.width_px) + "x" +
                               std::to_string(cam.model.height_px));
      const std::string yaml = euroc_camera_yaml(cam, c == 0 ? "left" : "right", kStreamName[k],
                                                 report.rate_hz, w.format, w.clock);
      if (auto s = write_text(w.dir / "sensor.yaml", yaml); !s) return s;
    }
  for (int k = 0; k < kGtStreams; ++k) {
    const GtStreamOut& g = gt_[k];
    if (!g.created) continue;
    if (auto s = write_text(g.dir / "data.csv", std::string(kCameraCsvHeader) + "\n" + g.csv); !s) return s;
    const RigCamera& cam = cx_.rig.cameras[static_cast<std::size_t>(kGtCamera[k])];
    if (auto s = write_text(g.dir / "sensor.yaml", ground_truth_yaml(k, cam, report.rate_hz, clk_.clock)); !s)
      return s;
  }
  if (max_skew_ns_ > 0)
    report.notes.push_back("left and right timestamps differ (up to " + std::to_string(max_skew_ns_) +
                           " ns): readers that pair cam0 and cam1 by identical timestamps need a tolerance");
  if (cx_.options.augmented && streams_[1][0].written + streams_[1][1].written == 0)
    report.notes.push_back(
        "no augmented images in the recording: cam0_augmented, cam1_augmented not written");
  if (cx_.options.masks && streams_[2][0].written + streams_[2][1].written == 0)
    report.notes.push_back("no masks in the recording: cam0_mask, cam1_mask not written");
  return {};
}

FrameWriter::FrameWriter(const ExportContext& cx, const ExportClock& clk, ExportProgress& progress,
                         FrameTables& tables)
    : impl_(std::make_unique<Impl>(cx, clk, progress, tables)) {}
FrameWriter::~FrameWriter() = default;
unsigned FrameWriter::parts() const { return impl_->parts(); }
Status FrameWriter::add(std::size_t i, Expected<FrameRecord> frame) { return impl_->add_frame(i, std::move(frame)); }
Status FrameWriter::finish() { return impl_->finish(); }

}  // namespace augrig::recorder::euroc_detail
