#include "recorder/recorder.hpp"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <csignal>
#include <cstring>
#include <ctime>
#include <deque>
#include <filesystem>
#include <map>
#include <mutex>
#include <thread>
#include <tuple>
#include <variant>
#include <vector>

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include "core/clock.hpp"
#include "core/thread_name.hpp"
#include "recorder/codec.hpp"
#include "recorder/replay_source.hpp"
#include "recorder/store.hpp"

#ifndef AUGRIG_VERSION
#define AUGRIG_VERSION "unknown"
#endif

namespace augrig::recorder {

namespace {

using Clock = std::chrono::steady_clock;

double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

constexpr int kPageSize = 65536;
// A checkpoint round that copied fewer WAL frames than this leaves the rest to the writer.
constexpr int kSmallCheckpointFrames = 256;

struct LedgerKey {
  DropStage stage;
  std::string item;
  std::string reason;
  bool operator<(const LedgerKey& o) const {
    return std::tie(stage, item, reason) < std::tie(o.stage, o.item, o.reason);
  }
};
struct Tally {
  std::uint64_t count = 0;
  TimestampNs first_t_ns = 0, last_t_ns = 0;
};

// A frame after compression, waiting for the writer. The FrameRow's blobs point into the vectors.
struct Encoded {
  std::uint64_t ticket = 0;
  FrameRow row;
  std::array<std::vector<std::uint8_t>, 2> raw, aug, mask, depth;
  DepthRow depth_row;  // blobs point into `depth`
  bool has_depth = false;
  // A raw blob copied from a replayed recording: the row points into the attachment's bytes,
  // kept alive here until the row is written.
  std::array<std::shared_ptr<const FrameAttachment>, 2> copied_from;
  int raw_copied = 0;  // raw blobs stored as they were (0..2)
  TimestampNs t_ns = 0;
  std::uint64_t image_bytes = 0, stored_bytes = 0;
  double encode_ms = 0;
  bool skipped = false;  // the recording had stopped: not encoded
  std::string error;     // encoding failed: dropped
};

struct PendingFrame {
  std::uint64_t ticket = 0;
  FrameRecord record;
};

// Nav inputs, events and look updates: written in push order, in the frames' transactions.
using SmallItem = std::variant<NavInputRecord, EventRecord, LookRecord>;
constexpr std::size_t kSmallKinds = std::variant_size_v<SmallItem>;
// Per SmallItem index: the ledger's item name, and the name in messages.
constexpr const char* kSmallItem[kSmallKinds] = {"nav_input", "event", "look"};
constexpr const char* kSmallWhat[kSmallKinds] = {"nav input", "event", "look update"};

TimestampNs small_t_ns(const SmallItem& item) {
  return std::visit([](const auto& x) { return x.t_ns; }, item);
}

// The writer's open transaction: what it holds, for the counters on its commit and the ledger on
// its rollback. The writer thread's alone.
struct WriterTxn {
  bool open = false;
  Clock::time_point start{};
  std::uint64_t frames = 0, image_bytes = 0, stored_bytes = 0, raw_copied = 0;
  std::array<std::uint64_t, kSmallKinds> small{};  // per SmallItem index
  TimestampNs first = 0, last = 0;
  void clear() {
    open = false;
    frames = image_bytes = stored_bytes = raw_copied = 0;
    small = {};
  }
};

std::size_t image_bytes_of(const Image& img) {
  return static_cast<std::size_t>(img.width()) * img.height() * bytes_per_pixel(img.format());
}

// Empty when the frame can be recorded, else what is wrong.
std::string validate(const FrameRecord& f) {
  for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
    const int c = index_of(id);
    const Image& raw = f.raw[id].image;
    const std::string cam(to_string(id));
    if (raw.empty()) return cam + " raw image is empty";
    const Image& aug = f.augmented[c];
    if (const auto& box = f.augmented_box[c]) {
      if (!box->inside(raw.width(), raw.height()))
        return cam + " augmented box [" + std::to_string(box->x0) + ", " + std::to_string(box->x1) + ") x [" +
               std::to_string(box->y0) + ", " + std::to_string(box->y1) + ") is not inside the raw image " +
               std::to_string(raw.width()) + "x" + std::to_string(raw.height());
      if (aug.width() != box->width() || aug.height() != box->height() ||
          (!box->empty() && aug.format() != raw.format()))
        return cam + " augmented part " + std::to_string(aug.width()) + "x" + std::to_string(aug.height()) +
               " " + std::string(to_string(aug.format())) + " differs from its box " +
               std::to_string(box->width()) + "x" + std::to_string(box->height()) + " of the raw image's " +
               std::string(to_string(raw.format()));
    } else if (!aug.empty() &&
               (aug.width() != raw.width() || aug.height() != raw.height() || aug.format() != raw.format()))
      return cam + " augmented image " + std::to_string(aug.width()) + "x" + std::to_string(aug.height()) +
             " " + std::string(to_string(aug.format())) + " differs from the raw image " +
             std::to_string(raw.width()) + "x" + std::to_string(raw.height()) + " " +
             std::string(to_string(raw.format()));
    const Image& mask = f.mask[c];
    if (!mask.empty() && (mask.width() != raw.width() || mask.height() != raw.height() ||
                          mask.format() != PixelFormat::kMono8))
      return cam + " mask " + std::to_string(mask.width()) + "x" + std::to_string(mask.height()) + " " +
             std::string(to_string(mask.format())) + " is not Mono8 of the raw image's size " +
             std::to_string(raw.width()) + "x" + std::to_string(raw.height());
    const DepthRecord& d = f.receiver_depth[c];
    if (!d.empty()) {
      if (d.width != raw.width() || d.height != raw.height())
        return cam + " receiver depth " + std::to_string(d.width) + "x" + std::to_string(d.height) +
               " differs from the raw image " + std::to_string(raw.width()) + "x" + std::to_string(raw.height());
      if (!d.box.inside(d.width, d.height) ||
          d.z_m.size() != static_cast<std::size_t>(d.box.width()) * static_cast<std::size_t>(d.box.height()))
        return cam + " receiver depth box [" + std::to_string(d.box.x0) + ", " + std::to_string(d.box.x1) +
               ") x [" + std::to_string(d.box.y0) + ", " + std::to_string(d.box.y1) + ") does not fit its " +
               std::to_string(d.z_m.size()) + " values or the image";
    }
  }
  return {};
}

// The stored blob of this very image when `fr` came from a replayed recording of this build's
// raw encoding (replay_source.hpp, RecordedFrame): size, format and t_ns must match and the
// image's raw_fingerprint() must equal the one taken when the blob was decoded. Null otherwise.
const StoredRawBlob* copyable_raw_blob(const Frame& fr, int c) {
  const RecordedFrame* rf = fr.attachment ? fr.attachment->recorded() : nullptr;
  if (rf == nullptr) return nullptr;
  const StoredRawBlob& b = rf->raw_blobs[static_cast<std::size_t>(c)];
  const Image& im = fr.image;
  if (b.empty() || b.format != im.format() || b.width != im.width() || b.height != im.height() ||
      b.t_ns != fr.t_ns)
    return nullptr;
  if (raw_fingerprint(im.cview()) != b.fingerprint) return nullptr;
  return &b;
}

TimestampNs clock_ns(clockid_t id) {
  timespec ts{};
  clock_gettime(id, &ts);
  return static_cast<TimestampNs>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// Why writing may have failed, beyond SQLite's code: a file size limit, a full file system, the
// size cap. Empty when none of them applies.
std::string diagnose_write_failure(const std::string& path, const std::string& sqlite_message,
                                   std::int64_t max_bytes) {
  namespace fs = std::filesystem;
  std::string s;
  std::error_code ec;
  rlimit lim{};
  if (getrlimit(RLIMIT_FSIZE, &lim) == 0 && lim.rlim_cur != RLIM_INFINITY) {
    std::uintmax_t biggest = 0;
    for (const char* suffix : {"", "-wal"}) {
      const std::uintmax_t n = fs::file_size(path + suffix, ec);
      if (!ec) biggest = std::max(biggest, n);
    }
    if (biggest + kPageSize + 64 > lim.rlim_cur)
      s += "; the file size limit (RLIMIT_FSIZE, " + std::to_string(lim.rlim_cur) +
           " bytes) was reached: write() failed with EFBIG (File too large)";
  }
  struct statvfs v {};
  const std::string folder = fs::path(path).parent_path().string();
  if (statvfs(folder.empty() ? "." : folder.c_str(), &v) == 0) {
    const std::uint64_t free_bytes = static_cast<std::uint64_t>(v.f_bavail) * v.f_frsize;
    if (free_bytes < 4u * kPageSize)
      s += "; the file system is full (" + std::to_string(free_bytes) + " bytes free)";
  }
  if (max_bytes > 0 && sqlite_message.find("SQLITE_FULL") != std::string::npos)
    s += "; the size cap (RecorderOptions::max_bytes = " + std::to_string(max_bytes) + " bytes) was reached";
  return s;
}

// Space held back for closing: a file of this size is allocated next to the database when the
// recording starts and deleted just before close() writes the drop ledger and the summary. On a
// full disk the last transaction's WAL pages (64 KiB each) then still fit, so that a recording
// stopped by a full disk is closed with its true ledger like any other.
constexpr char kReserveFile[] = "recording.reserve";
constexpr std::int64_t kReserveBytes = 2 << 20;

// Allocates `path` with `bytes` of real blocks (posix_fallocate, not a sparse file).
Status reserve_space(const std::string& path, std::int64_t bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Error{std::strerror(errno)};
  const int rc = posix_fallocate(fd, 0, bytes);
  ::close(fd);
  if (rc != 0) {
    ::unlink(path.c_str());
    return Error{std::strerror(rc)};
  }
  return {};
}

// The meta rows create() writes: what the recording is, how it was written, its blob encodings.
std::vector<std::pair<std::string, std::string>> initial_meta(const RecorderOptions& opt, const RecordingInfo& info) {
  std::vector<std::pair<std::string, std::string>> kv = {
      {"schema_version", std::to_string(kSchemaVersion)},
      {"software", std::string("augrig ") + AUGRIG_VERSION},
      {"created_utc", utc_now_iso8601()},
      {"created_host_realtime_ns", std::to_string(clock_ns(CLOCK_REALTIME))},
      {"created_host_monotonic_ns", std::to_string(clock_ns(CLOCK_MONOTONIC))},
      {"rig_yaml", info.rig_yaml},
      {"scene", info.scene},
      {"clock_domains", info.clock_domains},
      {"recorder_options",
       "queue_capacity=" + std::to_string(opt.queue_capacity) +
           " small_queue_capacity=" + std::to_string(opt.small_queue_capacity) +
           " commit_interval_ms=" + std::to_string(opt.commit_interval.count()) +
           " checkpoint_interval_ms=" + std::to_string(opt.checkpoint_interval.count()) +
           " zstd_level=" + std::to_string(opt.zstd_level) +
           " compression_threads=" + std::to_string(opt.compression_threads) +
           " max_bytes=" + std::to_string(opt.max_bytes) + " page_size=" + std::to_string(kPageSize) +
           " synchronous=NORMAL"},
      {"codec.raw", std::string(kRawCodec)},
      {"codec.aug",
       "zstd frame of (augmented XOR raw) inside [x0,x1) x [y0,y1), rows packed tight; "
       "empty blob: no change"},
      {"codec.mask", "zstd frame of the Mono8 mask, rows packed tight"},
      {"codec.depth", std::string(kDepthCodec)},
  };
  return kv;
}

}  // namespace

struct Recorder::Impl {
  std::string dir, path;
  std::string reserve_path;  // the space held back for close() (empty once released)
  RecorderOptions opt;
  Database db;       // the writer's connection (create/close on the caller's thread, else the writer's)
  Database ckpt_db;  // the checkpointer's
  Statement ins_frame, ins_depth, ins_nav, ins_event, ins_look, ins_drop, ins_meta;

  mutable std::mutex m;
  std::condition_variable cv_work, cv_writer, cv_ckpt;
  std::deque<PendingFrame> input;
  std::map<std::uint64_t, std::unique_ptr<Encoded>> ready;
  std::vector<std::unique_ptr<Encoded>> spare;  // recycled, with their buffers
  std::deque<SmallItem> small;
  std::uint64_t next_ticket = 0, next_write = 0;
  std::size_t in_flight = 0;
  std::map<LedgerKey, Tally> ledger;  // drops not yet written to the table
  std::array<std::uint64_t, 5> drops_total{};
  bool stop_workers = false, stop_writer = false, stop_ckpt = false, closed = false;
  std::optional<Status> close_result;
  std::atomic<bool> failed{false};
  // Set by the checkpointer when it has copied the WAL: the writer then copies the few frames
  // appended meanwhile between two transactions, so that its next transaction restarts the WAL from
  // its beginning (SQLite restarts it only when every frame is in the database).
  std::atomic<bool> restart_wanted{false};
  std::string error;        // set once, with failed
  std::string error_brief;  // the same without the path and the consequences, for the ledger
  RecorderStats st;

  std::vector<std::thread> workers;
  std::thread writer, checkpointer;
  WriterTxn tx;  // the writer thread's

  // ---- under m -------------------------------------------------------------------------------
  void drop_locked(DropStage stage, const std::string& item, const std::string& reason, std::uint64_t count,
                   TimestampNs first, TimestampNs last) {
    if (count == 0) return;
    Tally& t = ledger[{stage, item, reason}];
    if (t.count == 0) t.first_t_ns = first;
    t.count += count;
    t.last_t_ns = last;
    drops_total[static_cast<int>(stage)] += count;
    if (stage == DropStage::kRecorder) {
      if (item == "frame")
        st.frames_dropped += count;
      else
        st.small_items_dropped += count;
    }
  }
  std::string stopped_reason() const { return "recording stopped: " + error_brief; }
  void fail_locked(const std::string& what, const std::string& brief) {
    if (failed.load()) return;
    error = what;
    error_brief = brief;
    failed.store(true);
  }

  // ---- pipeline ------------------------------------------------------------------------------
  void worker_main();
  void writer_main();
  void checkpointer_main();
  void encode(Encoder& enc, FrameRecord& f, Encoded& e);
  Status insert_frame(const Encoded& e);
  Status insert_small(const SmallItem& item);
  // ---- the writer's transaction (writer thread) -----------------------------------------------
  // `failing`: frames of the failed statement itself (not counted as written), lost with the rest.
  void rollback_txn(const std::string& what, std::uint64_t failing = 0);
  bool begin_txn();
  void commit_txn();
  // Between transactions: the checkpoint that lets the next transaction restart the WAL.
  void restart_checkpoint();
  void write_smalls(const std::deque<SmallItem>& smalls);
  void write_frames(std::vector<std::unique_ptr<Encoded>>& frames);
  Status insert_ledger(std::map<LedgerKey, Tally>& rows);
  Status put_meta(const std::string& key, const std::string& value);
  Status write_summary();
  void release_reserve() {
    if (!reserve_path.empty()) ::unlink(reserve_path.c_str());
    reserve_path.clear();
  }
};

void Recorder::Impl::encode(Encoder& enc, FrameRecord& f, Encoded& e) {
  const double cpu0 = thread_cpu_ms();
  FrameRow& r = e.row;
  r = FrameRow{};
  r.pair_sequence = f.raw.pair_sequence;
  r.t_ns = f.raw.t_key_ns;
  r.skew_ns = f.raw.skew_ns;
  e.t_ns = f.raw.t_key_ns;
  e.image_bytes = e.stored_bytes = 0;
  e.raw_copied = 0;
  e.copied_from = {};
  e.error.clear();
  e.has_depth = false;
  e.depth_row = DepthRow{};
  for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
    const int c = index_of(id);
    const Frame& fr = f.raw[id];
    CameraRow& cr = r.cam[c];
    cr.sequence = fr.sequence;
    cr.t_ns = fr.t_ns;
    cr.clock = fr.clock;
    cr.t_host_ns = fr.t_host_ns;
    cr.exposure_ns = fr.exposure_ns;
    cr.format = fr.image.format();
    cr.width = fr.image.width();
    cr.height = fr.image.height();
    const std::string cam(to_string(id));
    if (const StoredRawBlob* blob = copyable_raw_blob(fr, c)) {
      // The replayed image's own blob: the same bytes encode_image() would make, without the work.
      r.raw[c] = {blob->bytes.data(), blob->bytes.size(), true};
      e.copied_from[c] = fr.attachment;
      ++e.raw_copied;
    } else {
      if (auto s = enc.encode_image(fr.image.view(), e.raw[c]); !s) {
        e.error = cam + " raw: " + s.error().message;
        return;
      }
      r.raw[c] = {e.raw[c].data(), e.raw[c].size(), true};
    }
    e.image_bytes += image_bytes_of(fr.image);
    // The augmented image, whole or as its changed box: stored the same way.
    const bool aug_present = !f.augmented[c].empty() || f.augmented_box[c].has_value();
    if (aug_present) {
      // A whole augmented image is its part inside the whole image's box.
      const PixelBox within =
          f.augmented_box[c].value_or(PixelBox{0, 0, fr.image.width(), fr.image.height()});
      const Status s =
          enc.encode_difference(fr.image.view(), f.augmented[c].cview(), within, cr.aug_box, e.aug[c]);
      if (!s) {
        e.error = cam + " augmented: " + s.error().message;
        return;
      }
      e.image_bytes += image_bytes_of(fr.image);
    }
    if (!f.mask[c].empty()) {
      if (auto s = enc.encode_mask(f.mask[c].cview(), e.mask[c]); !s) {
        e.error = cam + " mask: " + s.error().message;
        return;
      }
      e.image_bytes += image_bytes_of(f.mask[c]);
    }
    if (const DepthRecord& d = f.receiver_depth[c]; !d.empty()) {
      if (auto s = enc.encode_depth(d.z_m.data(), d.box.width(), d.box.height(), e.depth[c]); !s) {
        e.error = cam + " receiver depth: " + s.error().message;
        return;
      }
      e.has_depth = true;
      e.depth_row.box[c] = d.box.empty() ? PixelBox{} : d.box;
      e.depth_row.blob[c] = {e.depth[c].data(), e.depth[c].size(), true};
      e.image_bytes += static_cast<std::uint64_t>(d.width) * static_cast<std::uint64_t>(d.height) * sizeof(float);
      e.stored_bytes += e.depth[c].size();
    }
    r.aug[c] = {e.aug[c].data(), e.aug[c].size(), aug_present};
    r.mask[c] = {e.mask[c].data(), e.mask[c].size(), !f.mask[c].empty()};
    e.stored_bytes +=
        r.raw[c].size + (r.aug[c].present ? r.aug[c].size : 0) + (r.mask[c].present ? r.mask[c].size : 0);
  }
  r.T_cam_receiver = f.T_cam_receiver;
  r.T_body_receiver = f.T_body_receiver;
  r.receiver_present = f.receiver_present;
  r.sigma_pos_m = f.sigma_pos_m;
  r.sigma_att_deg = f.sigma_att_deg;
  r.boom = f.boom;
  r.stats = f.stats;
  e.encode_ms = thread_cpu_ms() - cpu0;
}

void Recorder::Impl::worker_main() {
  Encoder enc(opt.zstd_level);
  for (;;) {
    PendingFrame p;
    std::unique_ptr<Encoded> e;
    {
      std::unique_lock lk(m);
      cv_work.wait(lk, [&] { return !input.empty() || stop_workers; });
      if (input.empty()) return;
      p = std::move(input.front());
      input.pop_front();
      if (!spare.empty()) {
        e = std::move(spare.back());
        spare.pop_back();
      }
    }
    if (!e) e = std::make_unique<Encoded>();
    e->ticket = p.ticket;
    e->error.clear();
    e->skipped = failed.load();
    if (e->skipped)
      e->t_ns = p.record.raw.t_key_ns;
    else
      encode(enc, p.record, *e);
    p = PendingFrame{};  // the caller's images are freed here, outside the lock
    {
      std::lock_guard lk(m);
      st.encode_ms += e->encode_ms;
      ready[e->ticket] = std::move(e);
    }
    cv_writer.notify_one();
  }
}

Status Recorder::Impl::insert_frame(const Encoded& e) {
  sqlite3_stmt* s = ins_frame.get();
  if (auto b = bind_frame_row(s, e.row); !b) return b;
  const int rc = sqlite3_step(s);
  ins_frame.reset();
  if (rc != SQLITE_DONE) return Error{describe_sqlite_error(db.get(), rc)};
  if (!e.has_depth) return {};
  // In the frame's transaction: a frame and its depth are committed (or rolled back) together.
  DepthRow d = e.depth_row;
  d.frame_id = sqlite3_last_insert_rowid(db.get());
  sqlite3_stmt* sd = ins_depth.get();
  if (auto b = bind_depth_row(sd, d); !b) return b;
  const int rd = sqlite3_step(sd);
  ins_depth.reset();
  if (rd != SQLITE_DONE) return make_error("depth: ", describe_sqlite_error(db.get(), rd));
  return {};
}

Status Recorder::Impl::insert_small(const SmallItem& item) {
  int rc = SQLITE_DONE;
  if (const auto* n = std::get_if<NavInputRecord>(&item)) {
    sqlite3_stmt* s = ins_nav.get();
    sqlite3_bind_text(s, 1, n->stream.data(), static_cast<int>(n->stream.size()), SQLITE_STATIC);
    sqlite3_bind_int64(s, 2, n->t_ns);
    const std::string_view clock = to_string(n->clock);
    sqlite3_bind_text(s, 3, clock.data(), static_cast<int>(clock.size()), SQLITE_STATIC);
    sqlite3_bind_int64(s, 4, n->arrival_ns);
    if (n->binary)
      sqlite3_bind_blob64(s, 5, n->data.data(), n->data.size(), SQLITE_STATIC);
    else
      sqlite3_bind_text64(s, 5, n->data.data(), n->data.size(), SQLITE_STATIC, SQLITE_UTF8);
    rc = sqlite3_step(s);
    ins_nav.reset();
  } else if (const auto* look = std::get_if<LookRecord>(&item)) {
    if (auto b = bind_look_row(ins_look.get(), *look); !b) {
      ins_look.reset();
      return b;
    }
    rc = sqlite3_step(ins_look.get());
    ins_look.reset();
  } else {
    const auto& ev = std::get<EventRecord>(item);
    sqlite3_stmt* s = ins_event.get();
    sqlite3_bind_int64(s, 1, ev.t_ns);
    const std::string_view clock = to_string(ev.clock);
    sqlite3_bind_text(s, 2, clock.data(), static_cast<int>(clock.size()), SQLITE_STATIC);
    sqlite3_bind_text64(s, 3, ev.text.data(), ev.text.size(), SQLITE_STATIC, SQLITE_UTF8);
    rc = sqlite3_step(s);
    ins_event.reset();
  }
  if (rc != SQLITE_DONE) return Error{describe_sqlite_error(db.get(), rc)};
  return {};
}

Status Recorder::Impl::insert_ledger(std::map<LedgerKey, Tally>& rows) {
  for (const auto& [k, t] : rows) {
    sqlite3_stmt* s = ins_drop.get();
    const std::string_view stage = to_string(k.stage);
    sqlite3_bind_text(s, 1, stage.data(), static_cast<int>(stage.size()), SQLITE_STATIC);
    sqlite3_bind_text(s, 2, k.item.data(), static_cast<int>(k.item.size()), SQLITE_STATIC);
    sqlite3_bind_int64(s, 3, static_cast<sqlite3_int64>(t.count));
    sqlite3_bind_int64(s, 4, t.first_t_ns);
    sqlite3_bind_int64(s, 5, t.last_t_ns);
    sqlite3_bind_text(s, 6, k.reason.data(), static_cast<int>(k.reason.size()), SQLITE_STATIC);
    const int rc = sqlite3_step(s);
    ins_drop.reset();
    if (rc != SQLITE_DONE) return Error{describe_sqlite_error(db.get(), rc)};
  }
  return {};
}

Status Recorder::Impl::put_meta(const std::string& key, const std::string& value) {
  sqlite3_stmt* s = ins_meta.get();
  sqlite3_bind_text(s, 1, key.data(), static_cast<int>(key.size()), SQLITE_STATIC);
  sqlite3_bind_text(s, 2, value.data(), static_cast<int>(value.size()), SQLITE_STATIC);
  const int rc = sqlite3_step(s);
  ins_meta.reset();
  if (rc != SQLITE_DONE) return Error{describe_sqlite_error(db.get(), rc)};
  return {};
}

void Recorder::Impl::rollback_txn(const std::string& what, std::uint64_t failing) {
  // SQLite may have rolled back already (SQLITE_FULL, SQLITE_IOERR); make sure.
  if (!sqlite3_get_autocommit(db.get())) sqlite3_exec(db.get(), "ROLLBACK", nullptr, nullptr, nullptr);
  const std::string why = diagnose_write_failure(path, what, opt.max_bytes);
  std::string held = std::to_string(tx.frames + failing) + " frames, " + std::to_string(tx.small[0]) +
                     " nav inputs, " + std::to_string(tx.small[1]) + " events";
  if (tx.small[2]) held += ", " + std::to_string(tx.small[2]) + " look updates";
  std::lock_guard lk(m);
  fail_locked("recorder::Recorder: " + path + ": " + what + why +
                  "; the recording stopped there, the transaction in progress (" + held + ") was rolled back",
              what);
  const std::string reason = "rolled back: " + what;
  drop_locked(DropStage::kRecorder, "frame", reason, tx.frames + failing, tx.first, tx.last);
  for (std::size_t k = 0; k < kSmallKinds; ++k) drop_locked(DropStage::kRecorder, kSmallItem[k], reason, tx.small[k], 0, 0);
  st.frames_written -= std::min(st.frames_written, tx.frames);
  tx.clear();
}

bool Recorder::Impl::begin_txn() {
  if (tx.open) return true;
  if (auto s = db.exec("BEGIN"); !s) {
    rollback_txn("BEGIN failed: " + s.error().message);
    return false;
  }
  tx.open = true;
  tx.start = Clock::now();
  tx.first = tx.last = 0;
  return true;
}

void Recorder::Impl::commit_txn() {
  std::map<LedgerKey, Tally> rows;
  {
    std::lock_guard lk(m);
    rows.swap(ledger);
  }
  const auto t0 = Clock::now();
  Status s = insert_ledger(rows);
  if (s) s = db.exec("COMMIT");
  if (!s) {
    {
      std::lock_guard lk(m);  // keep them for the summary's attempt
      for (auto& [k, t] : rows) {
        Tally& d = ledger[k];
        if (d.count == 0) d.first_t_ns = t.first_t_ns;
        d.count += t.count;
        d.last_t_ns = t.last_t_ns;
      }
    }
    rollback_txn("COMMIT failed: " + s.error().message);
    return;
  }
  const double ms = ms_between(t0, Clock::now());
  std::lock_guard lk(m);
  st.frames_committed += tx.frames;
  st.nav_inputs_committed += tx.small[0];
  st.events_committed += tx.small[1];
  st.look_updates_committed += tx.small[2];
  st.image_bytes += tx.image_bytes;
  st.stored_bytes += tx.stored_bytes;
  st.raw_blobs_copied += tx.raw_copied;
  st.commits += 1;
  st.commit_ms += ms;
  tx.clear();
}

void Recorder::Impl::restart_checkpoint() {
  if (tx.open || failed.load() || !restart_wanted.exchange(false)) return;
  const auto t0 = Clock::now();
  int log = 0, done = 0;
  const int rc = sqlite3_wal_checkpoint_v2(db.get(), nullptr, SQLITE_CHECKPOINT_PASSIVE, &log, &done);
  const double ms = ms_between(t0, Clock::now());
  if (rc != SQLITE_OK && rc != SQLITE_BUSY && rc != SQLITE_LOCKED) {
    const std::string e = describe_sqlite_error(db.get(), rc);
    const std::string why = diagnose_write_failure(path, e, 0);
    std::lock_guard lk(m);
    fail_locked("recorder::Recorder: " + path + ": checkpointing the WAL into the database failed: " + e + why +
                    "; the recording stopped there (everything committed is in the WAL and stays readable)",
                "checkpoint failed: " + e);
    return;
  }
  std::lock_guard lk(m);
  st.checkpoints += 1;
  st.checkpoint_ms += ms;
}

void Recorder::Impl::write_smalls(const std::deque<SmallItem>& smalls) {
  for (const SmallItem& item : smalls) {
    const std::size_t kind = item.index();
    if (!failed.load() && begin_txn()) {
      tx.small[kind] += 1;  // a failing item goes with its transaction
      if (auto s = insert_small(item); !s)
        rollback_txn(std::string("writing a ") + kSmallWhat[kind] + " failed: " + s.error().message);
      continue;
    }
    std::lock_guard lk(m);
    const TimestampNs t = small_t_ns(item);
    drop_locked(DropStage::kRecorder, kSmallItem[kind], stopped_reason(), 1, t, t);
  }
}

void Recorder::Impl::write_frames(std::vector<std::unique_ptr<Encoded>>& frames) {
  for (auto& e : frames) {
    if (opt.writer_delay_for_testing.count() > 0) std::this_thread::sleep_for(opt.writer_delay_for_testing);
    bool written = false, lost_in_rollback = false;
    std::string reason;  // empty: dropped because the recording has stopped
    if (!e->error.empty()) {
      reason = "encoding failed: " + e->error;
    } else if (!e->skipped && !failed.load() && begin_txn()) {
      const double cpu0 = thread_cpu_ms();
      if (tx.first == 0) tx.first = e->t_ns;
      tx.last = e->t_ns;
      if (auto s = insert_frame(*e); !s) {
        rollback_txn("writing frame " + std::to_string(e->row.pair_sequence) + " failed: " + s.error().message, 1);
        lost_in_rollback = true;
      } else {
        written = true;
        tx.frames += 1;
        tx.raw_copied += static_cast<std::uint64_t>(e->raw_copied);
        tx.image_bytes += e->image_bytes;
        tx.stored_bytes += e->stored_bytes;
        std::lock_guard lk(m);
        st.insert_ms += thread_cpu_ms() - cpu0;
      }
    }
    e->copied_from = {};  // the replayed frame's blobs are freed here, outside the lock
    std::lock_guard lk(m);
    if (written)
      st.frames_written += 1;
    else if (!reason.empty())
      drop_locked(DropStage::kRecorder, "frame", reason, 1, e->t_ns, e->t_ns);
    else if (!lost_in_rollback)
      drop_locked(DropStage::kRecorder, "frame", stopped_reason(), 1, e->t_ns, e->t_ns);
    --in_flight;
    e->row = FrameRow{};
    if (spare.size() < workers.size() + 2) spare.push_back(std::move(e));
  }
}

void Recorder::Impl::writer_main() {
  for (;;) {
    std::vector<std::unique_ptr<Encoded>> frames;
    std::deque<SmallItem> smalls;
    bool stopping = false;
    {
      std::unique_lock lk(m);
      auto have_work = [&] { return ready.count(next_write) > 0 || !small.empty(); };
      auto finished = [&] { return stop_writer && in_flight == 0 && small.empty(); };
      // Without a transaction the writer still wakes every commit_interval, for ledger entries
      // (push() of a DropRecord wakes nobody).
      const Clock::time_point deadline =
          tx.open ? tx.start + opt.commit_interval : Clock::now() + opt.commit_interval;
      cv_writer.wait_until(lk, deadline, [&] { return have_work() || finished(); });
      for (auto it = ready.find(next_write); it != ready.end() && frames.size() < 8;
           it = ready.find(next_write)) {
        frames.push_back(std::move(it->second));
        ready.erase(it);
        ++next_write;
      }
      smalls.swap(small);
      stopping = stop_writer;
    }

    const bool was_failed = failed.load();
    if (was_failed && tx.open) commit_txn();  // stopped by the checkpointer: keep what this transaction holds
    write_smalls(smalls);
    write_frames(frames);

    bool finished;
    {
      std::lock_guard lk(m);
      finished = stopping && in_flight == 0 && small.empty() && ready.empty();
    }
    if (tx.open && (finished || stopping || Clock::now() - tx.start >= opt.commit_interval)) commit_txn();
    restart_checkpoint();
    if (!tx.open && !failed.load()) {
      // Ledger entries that arrived while nothing else did.
      bool pending;
      {
        std::lock_guard lk(m);
        pending = !ledger.empty();
      }
      if (pending && begin_txn()) commit_txn();
    }
    if (finished && !tx.open) return;
  }
}

void Recorder::Impl::checkpointer_main() {
  for (;;) {
    {
      std::unique_lock lk(m);
      cv_ckpt.wait_for(lk, opt.checkpoint_interval, [&] { return stop_ckpt; });
      if (stop_ckpt) return;
    }
    if (failed.load()) continue;
    // Rounds until one copies only a few frames (those the writer appended during the round before);
    // the writer copies the rest between two transactions (restart_wanted).
    int rc = SQLITE_OK, prev_done = -1;
    for (int round = 0; round < 4; ++round) {
      const auto t0 = Clock::now();
      int log = 0, done = 0;
      rc = sqlite3_wal_checkpoint_v2(ckpt_db.get(), nullptr, SQLITE_CHECKPOINT_PASSIVE, &log, &done);
      const double ms = ms_between(t0, Clock::now());
      if (rc != SQLITE_OK) break;
      {
        std::lock_guard lk(m);
        st.checkpoints += 1;
        st.checkpoint_ms += ms;
      }
      const bool small = prev_done >= 0 && done >= prev_done && done - prev_done < kSmallCheckpointFrames;
      prev_done = done;
      if (small || done == log) break;
    }
    if (rc == SQLITE_OK) {
      restart_wanted.store(true);
      continue;
    }
    if (rc == SQLITE_BUSY || rc == SQLITE_LOCKED) continue;
    const std::string e = describe_sqlite_error(ckpt_db.get(), rc);
    const std::string why = diagnose_write_failure(path, e, 0);
    std::lock_guard lk(m);
    fail_locked("recorder::Recorder: " + path + ": checkpointing the WAL into the database failed: " + e +
                    why +
                    "; the recording stopped there (everything committed is in the WAL and stays readable)",
                "checkpoint failed: " + e);
    cv_writer.notify_one();
  }
}

Status Recorder::Impl::write_summary() {
  if (auto s = db.exec("BEGIN"); !s) return s;
  std::map<LedgerKey, Tally> rows;
  RecorderStats s;
  std::array<std::uint64_t, 5> drops{};
  std::string status;
  {
    std::lock_guard lk(m);
    rows.swap(ledger);
    s = st;
    drops = drops_total;
    status = failed.load() ? error : "ok";
  }
  Status r = insert_ledger(rows);
  auto put = [&](const std::string& k, const std::string& v) {
    if (r) r = put_meta(k, v);
  };
  put("summary.closed_utc", utc_now_iso8601());
  put("summary.status", status);
  put("summary.frames", std::to_string(s.frames_committed));
  put("summary.nav_inputs", std::to_string(s.nav_inputs_committed));
  put("summary.events", std::to_string(s.events_committed));
  put("summary.look_updates", std::to_string(s.look_updates_committed));
  for (DropStage stage : kAllDropStages)
    put("summary.drops." + std::string(to_string(stage)), std::to_string(drops[static_cast<int>(stage)]));
  put("summary.image_bytes", std::to_string(s.image_bytes));
  put("summary.stored_bytes", std::to_string(s.stored_bytes));
  if (r) r = db.exec("COMMIT");
  if (!r) {
    if (!sqlite3_get_autocommit(db.get())) sqlite3_exec(db.get(), "ROLLBACK", nullptr, nullptr, nullptr);
    return r;
  }
  return {};
}

Recorder::Recorder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Recorder::~Recorder() {
  if (impl_) (void)close();
}

Expected<std::unique_ptr<Recorder>> Recorder::create(const std::string& dir, const RecordingInfo& info,
                                                     const RecorderOptions& options) {
  namespace fs = std::filesystem;
  const std::string where = "recorder::Recorder::create(): ";
  auto impl = std::make_unique<Impl>();
  impl->dir = dir;
  impl->opt = options;
  impl->opt.compression_threads = std::max(1, options.compression_threads);
  impl->opt.queue_capacity = std::max<std::size_t>(1, options.queue_capacity);
  impl->opt.zstd_level = std::clamp(options.zstd_level, 1, 19);
  if (impl->opt.commit_interval.count() <= 0) impl->opt.commit_interval = std::chrono::milliseconds(1);
  if (impl->opt.checkpoint_interval.count() <= 0)
    impl->opt.checkpoint_interval = std::chrono::milliseconds(1);
  for (const auto& [k, v] : info.extra)
    if (k.rfind("summary.", 0) == 0)
      return make_error(where, "meta key \"", k, "\": \"summary.\" keys are reserved");

  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    return make_error(where, dir, ": cannot create the folder: ", ec.message());
  impl->path = (fs::path(dir) / kDatabaseFile).string();
  const std::string& path = impl->path;
  const std::string reserve_path = (fs::path(dir) / kReserveFile).string();
  for (const std::string& p : {path, path + "-wal", path + "-shm", path + "-journal", reserve_path}) {
    if (!fs::exists(p, ec)) continue;
    if (!options.overwrite)
      return make_error(
          where, p, ": exists; a recording is never overwritten unless asked (RecorderOptions::overwrite)");
    fs::remove(p, ec);
    if (ec) return make_error(where, p, ": cannot remove: ", ec.message());
  }

  // A file size limit (RLIMIT_FSIZE) must fail a write (EFBIG), not kill the process.
  struct sigaction sa {};
  if (sigaction(SIGXFSZ, nullptr, &sa) == 0 && sa.sa_handler == SIG_DFL) signal(SIGXFSZ, SIG_IGN);

  // The space close() needs, first: on a disk already full the recording is refused here, before
  // any of its files exist.
  if (auto s = reserve_space(reserve_path, kReserveBytes); !s) {
    std::string why = s.error().message;
    struct statvfs v {};
    if (statvfs(dir.c_str(), &v) == 0)
      why += " (" + std::to_string(static_cast<std::uint64_t>(v.f_bavail) * v.f_frsize) + " bytes free)";
    return make_error(where, reserve_path, ": cannot set aside the ", kReserveBytes >> 20,
                      " MiB a recording keeps for closing: ", why);
  }
  impl->reserve_path = reserve_path;

  // A recording either is created whole (schema and meta) or leaves no file behind.
  auto remove_files = [&] {
    impl->ckpt_db.close();
    impl->db.close();
    for (const std::string& p : {path, path + "-wal", path + "-shm", path + "-journal"}) fs::remove(p, ec);
    impl->release_reserve();
  };
  auto db = Database::open(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
  if (!db) {
    remove_files();
    return make_error(where, db.error().message);
  }
  impl->db = std::move(*db);
  Database& d = impl->db;
  auto fail = [&](const std::string& what, const Error& e) -> Error {
    std::string why = e.message;
    struct statvfs v {};
    if (statvfs(dir.c_str(), &v) == 0 && static_cast<std::uint64_t>(v.f_bavail) * v.f_frsize < 4u * kPageSize)
      why += " (the file system is full)";
    remove_files();
    return make_error(where, path, ": ", what, ": ", why, "; nothing was left behind");
  };
  sqlite3_busy_timeout(d.get(), 5000);
  if (auto s = d.exec("PRAGMA page_size=" + std::to_string(kPageSize)); !s)
    return fail("PRAGMA page_size", s.error());
  auto mode = d.query_text("PRAGMA journal_mode=WAL");
  if (!mode) return fail("PRAGMA journal_mode=WAL", mode.error());
  if (*mode != "wal")
    return fail("PRAGMA journal_mode=WAL", Error{"the journal mode stayed \"" + *mode + "\""});
  for (const char* pragma : {"PRAGMA synchronous=NORMAL", "PRAGMA wal_autocheckpoint=0",
                             "PRAGMA journal_size_limit=268435456", "PRAGMA cache_size=-32768"}) {
    if (auto s = d.exec(pragma); !s) return fail(pragma, s.error());
  }
  if (options.max_bytes > 0) {
    const std::int64_t pages = std::max<std::int64_t>(1, options.max_bytes / kPageSize);
    if (auto s = d.exec("PRAGMA max_page_count=" + std::to_string(pages)); !s)
      return fail("PRAGMA max_page_count", s.error());
  }

  // Schema and meta in one transaction: a recording either has both or does not exist.
  if (auto s = d.exec("BEGIN"); !s) return fail("BEGIN", s.error());
  if (auto s = d.exec(schema_sql()); !s) return fail("creating the schema", s.error());
  auto meta = Statement::prepare(d.get(), "INSERT OR REPLACE INTO meta (key, value) VALUES (?, ?)");
  if (!meta) return fail("preparing", meta.error());
  impl->ins_meta = std::move(*meta);
  std::vector<std::pair<std::string, std::string>> kv = initial_meta(impl->opt, info);
  for (const auto& [k, v] : info.extra) kv.emplace_back(k, v);
  for (const auto& [k, v] : kv)
    if (auto s = impl->put_meta(k, v); !s) return fail("writing meta", s.error());
  if (auto s = d.exec("COMMIT"); !s) return fail("COMMIT", s.error());

  auto prep = [&](Statement& out, const std::string& sql) -> Status {
    auto st = Statement::prepare(d.get(), sql);
    if (!st) return st.error();
    out = std::move(*st);
    return {};
  };
  for (auto [stmt, sql] :
       {std::pair<Statement*, std::string>{&impl->ins_frame, frame_insert_sql()},
        {&impl->ins_depth, depth_insert_sql()},
        {&impl->ins_nav,
         "INSERT INTO nav_input (stream, t_ns, clock, arrival_ns, data) VALUES (?, ?, ?, ?, ?)"},
        {&impl->ins_event, "INSERT INTO events (t_ns, clock, text) VALUES (?, ?, ?)"},
        {&impl->ins_look, look_insert_sql()},
        {&impl->ins_drop,
         "INSERT INTO drops (stage, item, count, first_t_ns, last_t_ns, reason) VALUES (?, ?, ?, ?, ?, "
         "?)"}}) {
    if (auto s = prep(*stmt, sql); !s) return fail("preparing", s.error());
  }

  auto ck = Database::open(path, SQLITE_OPEN_READWRITE);
  if (!ck) return fail("opening the checkpoint connection", ck.error());
  impl->ckpt_db = std::move(*ck);
  (void)impl->ckpt_db.exec("PRAGMA synchronous=NORMAL");

  Impl* p = impl.get();
  for (int i = 0; i < impl->opt.compression_threads; ++i)
    impl->workers.emplace_back([p] {
      set_thread_name("augrig-rec-zstd");
      p->worker_main();
    });
  impl->writer = std::thread([p] {
    set_thread_name("augrig-rec-write");
    p->writer_main();
  });
  impl->checkpointer = std::thread([p] {
    set_thread_name("augrig-rec-ckpt");
    p->checkpointer_main();
  });
  return std::unique_ptr<Recorder>(new Recorder(std::move(impl)));
}

bool Recorder::push(RecordItem&& item) {
  Impl& I = *impl_;
  if (auto* f = std::get_if<FrameRecord>(&item)) {
    const TimestampNs t = f->raw.t_key_ns;
    const std::string bad = validate(*f);
    std::unique_lock lk(I.m);
    if (I.closed) return false;
    if (!bad.empty()) {
      I.drop_locked(DropStage::kRecorder, "frame", "invalid frame: " + bad, 1, t, t);
      return false;
    }
    if (I.failed.load()) {
      I.drop_locked(DropStage::kRecorder, "frame", I.stopped_reason(), 1, t, t);
      return false;
    }
    if (I.in_flight >= I.opt.queue_capacity) {
      I.drop_locked(DropStage::kRecorder, "frame",
                    "queue full (capacity " + std::to_string(I.opt.queue_capacity) + " frames)", 1, t, t);
      return false;
    }
    I.input.push_back({I.next_ticket++, std::move(*f)});
    ++I.in_flight;
    ++I.st.frames_pushed;
    lk.unlock();
    I.cv_work.notify_one();
    return true;
  }
  if (auto* d = std::get_if<DropRecord>(&item)) {
    std::lock_guard lk(I.m);
    if (I.closed) return false;
    I.drop_locked(d->stage, d->item, d->reason, d->count, d->first_t_ns, d->last_t_ns);
    return true;
  }
  SmallItem small_item;
  if (auto* n = std::get_if<NavInputRecord>(&item))
    small_item = std::move(*n);
  else if (auto* ev = std::get_if<EventRecord>(&item))
    small_item = std::move(*ev);
  else
    small_item = std::move(std::get<LookRecord>(item));
  const TimestampNs t = small_t_ns(small_item);
  const char* kind = kSmallItem[small_item.index()];
  std::unique_lock lk(I.m);
  if (I.closed) return false;
  if (I.failed.load()) {
    I.drop_locked(DropStage::kRecorder, kind, I.stopped_reason(), 1, t, t);
    return false;
  }
  if (I.small.size() >= I.opt.small_queue_capacity) {
    I.drop_locked(DropStage::kRecorder, kind,
                  "queue full (capacity " + std::to_string(I.opt.small_queue_capacity) +
                      " nav inputs, events and look updates)",
                  1, t, t);
    return false;
  }
  I.small.push_back(std::move(small_item));
  lk.unlock();
  I.cv_writer.notify_one();
  return true;
}

Status Recorder::status() const {
  std::lock_guard lk(impl_->m);
  if (impl_->failed.load()) return Error{impl_->error};
  return {};
}

RecorderStats Recorder::stats() const {
  std::lock_guard lk(impl_->m);
  RecorderStats s = impl_->st;
  s.frames_in_flight = impl_->in_flight;
  return s;
}

const std::string& Recorder::path() const {
  return impl_->path;
}

Status Recorder::close() {
  Impl& I = *impl_;
  {
    std::lock_guard lk(I.m);
    if (I.close_result) return *I.close_result;
    I.closed = true;
    I.stop_workers = true;
  }
  I.cv_work.notify_all();
  for (std::thread& t : I.workers) t.join();
  {
    std::lock_guard lk(I.m);
    I.stop_writer = true;
  }
  I.cv_writer.notify_all();
  I.writer.join();
  {
    std::lock_guard lk(I.m);
    I.stop_ckpt = true;
  }
  I.cv_ckpt.notify_all();
  I.checkpointer.join();
  I.ckpt_db.close();

  // The reserved space becomes the room for the ledger, the summary and the final checkpoint.
  I.release_reserve();
  Status result;
  Status summary = I.write_summary();
  if (!I.failed.load() && !summary) {
    std::lock_guard lk(I.m);
    I.fail_locked(
        "recorder::Recorder::close(): " + I.path + ": writing the summary failed: " + summary.error().message,
        "writing the summary failed");
  }
  if (!I.failed.load()) {
    // A reader holding a snapshot (a RecordingReader on the live recording) keeps the WAL from
    // being truncated: that is no error, the WAL then stays next to the database until the next open.
    sqlite3_busy_timeout(I.db.get(), 500);
    int log = 0, done = 0;
    const int rc = sqlite3_wal_checkpoint_v2(I.db.get(), nullptr, SQLITE_CHECKPOINT_TRUNCATE, &log, &done);
    if (rc != SQLITE_OK && rc != SQLITE_BUSY && rc != SQLITE_LOCKED) {
      std::lock_guard lk(I.m);
      I.fail_locked("recorder::Recorder::close(): " + I.path +
                        ": the final checkpoint failed: " + describe_sqlite_error(I.db.get(), rc) +
                        " (the recording is complete in its WAL file)",
                    "the final checkpoint failed");
    }
  }
  I.ins_frame = {};
  I.ins_depth = {};
  I.ins_nav = {};
  I.ins_event = {};
  I.ins_look = {};
  I.ins_drop = {};
  I.ins_meta = {};
  I.db.close();
  std::lock_guard lk(I.m);
  if (I.failed.load()) result = Error{I.error};
  I.close_result = result;
  return result;
}

}  // namespace augrig::recorder
