#include "recorder/reader.hpp"

#include <algorithm>
#include <charconv>
#include <filesystem>
#include <sstream>

#include <unistd.h>

#include "recorder/codec.hpp"
#include "recorder/store.hpp"

namespace augrig::recorder {

namespace {

constexpr std::size_t kMaxProblems = 50;

std::string column_text(sqlite3_stmt* st, int col) {
  const unsigned char* t = sqlite3_column_text(st, col);
  return t ? std::string(reinterpret_cast<const char*>(t),
                         static_cast<std::size_t>(sqlite3_column_bytes(st, col)))
           : std::string();
}

}  // namespace

struct RecordingReader::Impl {
  std::string path;
  Database db;
  int schema_version = 0;
  std::map<std::string, std::string> meta;
  std::vector<std::int64_t> ids;  // frame i -> frames.id
  std::vector<std::string> problems;
  mutable std::map<unsigned, Statement> selects;  // per FrameParts
  bool depth_table = false;                        // schema 2: the depth table is there
  bool look_table = false;                         // schema 3: the look table is there
  mutable Statement depth_select, depth_exists;
  mutable Decoder decoder;
  bool raw_codec_current = false;  // meta codec.raw is this build's kRawCodec: raw blobs may be copied

  Error frame_error(std::size_t i, const std::string& what) const {
    return make_error("recorder::RecordingReader::read_frame(): ", path, ": frame ", i, ": ", what);
  }
};

RecordingReader::RecordingReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
RecordingReader::~RecordingReader() = default;

Expected<std::unique_ptr<RecordingReader>> RecordingReader::open(const std::string& dir_or_file) {
  namespace fs = std::filesystem;
  const std::string where = "recorder::RecordingReader::open(): ";
  auto impl = std::make_unique<Impl>();
  impl->path = database_path(dir_or_file);
  const std::string& path = impl->path;
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    if (fs::is_directory(dir_or_file, ec))
      return make_error(where, path, ": no such file (a recording folder holds ", kDatabaseFile, ")");
    return make_error(where, path, ": no such file");
  }
  if (!fs::is_regular_file(path, ec)) return make_error(where, path, ": not a regular file");
  if (fs::file_size(path, ec) == 0) return make_error(where, path, ": the file is empty");

  // Read-write where allowed, so that SQLite can recover the WAL of a killed writer.
  const std::string folder =
      fs::path(path).parent_path().empty() ? "." : fs::path(path).parent_path().string();
  const bool writable = ::access(path.c_str(), W_OK) == 0 && ::access(folder.c_str(), W_OK) == 0;
  auto db = Database::open(path, writable ? SQLITE_OPEN_READWRITE : SQLITE_OPEN_READONLY);
  if (!db) return make_error(where, db.error().message);
  impl->db = std::move(*db);
  sqlite3_busy_timeout(impl->db.get(), 2000);
  (void)impl->db.exec("PRAGMA query_only=1");

  auto st = Statement::prepare(impl->db.get(), "SELECT key, value FROM meta");
  if (!st && sqlite3_errcode(impl->db.get()) == SQLITE_CORRUPT) {
    // SQLite refuses a file shorter than its header says (truncated) unless writable_schema is on,
    // which makes it read the pages that are there. query_only keeps it from writing.
    const std::string first = st.error().message;
    (void)impl->db.exec("PRAGMA writable_schema=1");
    st = Statement::prepare(impl->db.get(), "SELECT key, value FROM meta");
    if (st)
      impl->problems.push_back(path + ": " + first +
                               " on open; reading it as far as it is intact (a truncated "
                               "file, or its first pages damaged)");
  }
  if (!st) return make_error(where, path, ": not a readable augrig recording: ", st.error().message);
  for (;;) {
    const int rc = st->step();
    if (rc == SQLITE_DONE) break;
    if (rc != SQLITE_ROW) {
      if (impl->meta.empty())
        return make_error(where, path,
                          ": the meta table cannot be read: ", describe_sqlite_error(impl->db.get(), rc));
      impl->problems.push_back("meta: read stopped after " + std::to_string(impl->meta.size()) +
                               " keys: " + describe_sqlite_error(impl->db.get(), rc));
      break;
    }
    impl->meta[column_text(st->get(), 0)] = column_text(st->get(), 1);
  }
  const auto v = impl->meta.find("schema_version");
  if (v == impl->meta.end()) return make_error(where, path, ": no schema_version in the meta table");
  const std::string& vs = v->second;
  const auto [ptr, perr] = std::from_chars(vs.data(), vs.data() + vs.size(), impl->schema_version);
  if (perr != std::errc() || ptr != vs.data() + vs.size() || impl->schema_version < 1)
    return make_error(where, path, ": schema_version \"", vs, "\" is not a positive integer");
  if (impl->schema_version > kSchemaVersion)
    return make_error(where, path, ": schema version ", impl->schema_version,
                      " is newer than this reader's (", kSchemaVersion, "); use a newer augrig");

  impl->raw_codec_current = impl->meta.count("codec.raw") && impl->meta["codec.raw"] == kRawCodec;
  // Recordings of schema 1 have no depth table: they hold no depth; before schema 3 no look table.
  if (auto t = impl->db.query_text("SELECT name FROM sqlite_master WHERE type = 'table' AND name = 'depth'"))
    impl->depth_table = *t == "depth";
  if (auto t = impl->db.query_text("SELECT name FROM sqlite_master WHERE type = 'table' AND name = 'look'"))
    impl->look_table = *t == "look";

  auto ids = Statement::prepare(impl->db.get(), "SELECT id FROM frames ORDER BY id");
  if (!ids) return make_error(where, path, ": the frames table cannot be read: ", ids.error().message);
  for (;;) {
    const int rc = ids->step();
    if (rc == SQLITE_DONE) break;
    if (rc != SQLITE_ROW) {
      impl->problems.push_back(
          "frames: the table is damaged after " + std::to_string(impl->ids.size()) +
          " frames; later frames cannot be listed: " + describe_sqlite_error(impl->db.get(), rc));
      break;
    }
    impl->ids.push_back(sqlite3_column_int64(ids->get(), 0));
  }
  // A closed recording says how many frames it committed: fewer listed means frames are missing
  // (a truncated or damaged file), even where SQLite itself found nothing wrong.
  if (const auto n = impl->meta.find("summary.frames"); n != impl->meta.end()) {
    std::uint64_t want = 0;
    const std::string& t = n->second;
    const auto [p, e] = std::from_chars(t.data(), t.data() + t.size(), want);
    if (e != std::errc() || p != t.data() + t.size())
      impl->problems.push_back("meta: summary.frames \"" + t + "\" is not a count");
    else if (want != impl->ids.size())
      impl->problems.push_back(
          "frames: the recording's summary says " + t + " frames were recorded, " +
          std::to_string(impl->ids.size()) + " can be read: " +
          std::to_string(want > impl->ids.size() ? want - impl->ids.size() : impl->ids.size() - want) +
          (want > impl->ids.size() ? " missing" : " more than it says"));
  }
  return std::unique_ptr<RecordingReader>(new RecordingReader(std::move(impl)));
}

const std::string& RecordingReader::path() const {
  return impl_->path;
}
int RecordingReader::schema_version() const {
  return impl_->schema_version;
}
const std::map<std::string, std::string>& RecordingReader::meta() const {
  return impl_->meta;
}
std::string RecordingReader::meta(const std::string& key) const {
  const auto it = impl_->meta.find(key);
  return it == impl_->meta.end() ? std::string() : it->second;
}
std::size_t RecordingReader::frame_count() const {
  return impl_->ids.size();
}
const std::vector<std::string>& RecordingReader::problems() const {
  return impl_->problems;
}

Expected<FrameRecord> RecordingReader::read_frame(std::size_t i, unsigned parts) const {
  return read_frame(i, parts, nullptr);
}

Expected<FrameRecord> RecordingReader::read_frame(std::size_t i, unsigned parts,
                                                  std::array<StoredRawBlob, 2>* raw_blobs) const {
  Impl& I = *impl_;
  if (raw_blobs) *raw_blobs = {};
  if (i >= I.ids.size())
    return I.frame_error(i, "out of range (" + std::to_string(I.ids.size()) + " frames)");
  if (parts & kPartAugmented) parts |= kPartRaw;
  auto it = I.selects.find(parts);
  if (it == I.selects.end()) {
    auto st = Statement::prepare(I.db.get(), frame_select_sql(parts, I.schema_version) + " WHERE id = ?");
    if (!st) return I.frame_error(i, st.error().message);
    it = I.selects.emplace(parts, std::move(*st)).first;
  }
  Statement& st = it->second;
  struct Reset {
    Statement& s;
    ~Reset() { s.reset(); }
  } reset{st};
  sqlite3_bind_int64(st.get(), 1, I.ids[i]);
  const int rc = st.step();
  if (rc == SQLITE_DONE) return I.frame_error(i, "row id " + std::to_string(I.ids[i]) + " is gone");
  if (rc != SQLITE_ROW) return I.frame_error(i, describe_sqlite_error(I.db.get(), rc));
  FrameRow row;
  if (auto s = read_frame_row(st.get(), row); !s) return I.frame_error(i, s.error().message);

  FrameRecord f;
  f.raw.pair_sequence = row.pair_sequence;
  f.raw.t_key_ns = row.t_ns;
  f.raw.skew_ns = row.skew_ns;
  for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
    const CameraRow& c = row.cam[index_of(id)];
    Frame& fr = f.raw[id];
    fr.camera = id;
    fr.sequence = c.sequence;
    fr.t_ns = c.t_ns;
    fr.clock = c.clock;
    fr.t_host_ns = c.t_host_ns;
    fr.exposure_ns = c.exposure_ns;
  }
  f.T_cam_receiver = row.T_cam_receiver;
  f.T_body_receiver = row.T_body_receiver;
  f.receiver_present = row.receiver_present;
  f.sigma_pos_m = row.sigma_pos_m;
  f.sigma_att_deg = row.sigma_att_deg;
  f.boom = row.boom;
  f.stats = row.stats;

  const std::string seq = " (pair_sequence " + std::to_string(row.pair_sequence) + ")";
  for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
    const int c = index_of(id);
    const CameraRow& cr = row.cam[c];
    const std::string cam(to_string(id));
    if (parts & kPartRaw) {
      const BlobRef& b = row.raw[c];
      if (!b.present) return I.frame_error(i, cam + " raw blob is missing" + seq);
      if (auto s = I.decoder.decode_image(b.data, b.size, cr.width, cr.height, cr.format, f.raw[id].image);
          !s)
        return I.frame_error(i, cam + " raw blob" + seq + ": " + s.error().message);
    }
    // Only with the image decoded: a blob is kept with its image's fingerprint, and a blob
    // that decoded without error is known to be intact.
    if (raw_blobs && I.raw_codec_current && (parts & kPartRaw)) {
      StoredRawBlob& sb = (*raw_blobs)[c];
      sb.bytes.assign(row.raw[c].data, row.raw[c].data + row.raw[c].size);
      sb.format = cr.format;
      sb.width = cr.width;
      sb.height = cr.height;
      sb.t_ns = cr.t_ns;
      sb.fingerprint = raw_fingerprint(f.raw[id].image.cview());
    }
    if ((parts & kPartAugmented) && row.aug[c].present) {
      const BlobRef& b = row.aug[c];
      if (auto s = I.decoder.decode_difference(b.data, b.size, cr.aug_box, f.raw[id].image, f.augmented[c]);
          !s)
        return I.frame_error(i, cam + " augmented blob" + seq + ": " + s.error().message);
    }
    if ((parts & kPartMasks) && row.mask[c].present) {
      const BlobRef& b = row.mask[c];
      if (auto s = I.decoder.decode_mask(b.data, b.size, cr.width, cr.height, f.mask[c]); !s)
        return I.frame_error(i, cam + " mask blob" + seq + ": " + s.error().message);
    }
  }
  if ((parts & kPartDepth) && I.depth_table) {
    if (!I.depth_select.get()) {
      auto st = Statement::prepare(I.db.get(), depth_select_sql());
      if (!st) return I.frame_error(i, "depth: " + st.error().message);
      I.depth_select = std::move(*st);
    }
    Statement& ds = I.depth_select;
    struct Reset {
      Statement& s;
      ~Reset() { s.reset(); }
    } reset_depth{ds};
    sqlite3_bind_int64(ds.get(), 1, I.ids[i]);
    const int drc = ds.step();
    if (drc != SQLITE_ROW && drc != SQLITE_DONE)
      return I.frame_error(i, "depth row" + seq + ": " + describe_sqlite_error(I.db.get(), drc));
    if (drc == SQLITE_ROW) {
      DepthRow d;
      if (auto s = read_depth_row(ds.get(), d); !s) return I.frame_error(i, "depth row" + seq + ": " + s.error().message);
      for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
        const int c = index_of(id);
        if (!d.box[c]) continue;
        const CameraRow& cr = row.cam[c];
        const std::string what = std::string(to_string(id)) + " depth blob" + seq + ": ";
        PixelBox box = *d.box[c];
        if (box.empty()) box = {};
        if (!box.inside(cr.width, cr.height))
          return I.frame_error(i, what + "box [" + std::to_string(box.x0) + ", " + std::to_string(box.x1) + ") x [" +
                                      std::to_string(box.y0) + ", " + std::to_string(box.y1) + ") outside the " +
                                      std::to_string(cr.width) + "x" + std::to_string(cr.height) + " image");
        DepthRecord& out = f.receiver_depth[c];
        if (auto s = I.decoder.decode_depth(d.blob[c].data, d.blob[c].size, box.width(), box.height(), out.z_m); !s)
          return I.frame_error(i, what + s.error().message);
        out.width = cr.width;
        out.height = cr.height;
        out.box = box;
      }
    }
  }
  return f;
}

bool RecordingReader::has_depth(std::size_t i) const {
  Impl& I = *impl_;
  if (!I.depth_table || i >= I.ids.size()) return false;
  if (!I.depth_exists.get()) {
    auto st = Statement::prepare(
        I.db.get(), "SELECT left_depth IS NOT NULL AND right_depth IS NOT NULL FROM depth WHERE frame_id = ?");
    if (!st) return false;
    I.depth_exists = std::move(*st);
  }
  Statement& st = I.depth_exists;
  sqlite3_bind_int64(st.get(), 1, I.ids[i]);
  const bool yes = st.step() == SQLITE_ROW && sqlite3_column_int(st.get(), 0) != 0;
  st.reset();
  return yes;
}

// Steps a prepared statement to its end, turning each row into a T with `row(stmt, index)` (an
// Expected<T>); errors name where and the row.
template <typename T, typename Row>
Expected<std::vector<T>> read_rows(sqlite3* db, Statement& st, const std::string& where, Row&& row) {
  std::vector<T> out;
  for (;;) {
    const int rc = st.step();
    if (rc == SQLITE_DONE) return out;
    if (rc != SQLITE_ROW)
      return make_error(where, "read stopped after ", out.size(), " rows: ", describe_sqlite_error(db, rc));
    Expected<T> t = row(st.get(), out.size());
    if (!t) return t.error();
    out.push_back(std::move(*t));
  }
}

Expected<std::vector<NavInputRecord>> RecordingReader::nav_inputs(
    const std::optional<std::string>& stream) const {
  const std::string where = "recorder::RecordingReader::nav_inputs(): " + impl_->path + ": ";
  std::string sql = "SELECT stream, t_ns, clock, arrival_ns, data FROM nav_input";
  if (stream) sql += " WHERE stream = ?";
  sql += " ORDER BY id";
  auto st = Statement::prepare(impl_->db.get(), sql);
  if (!st) return make_error(where, st.error().message);
  if (stream)
    sqlite3_bind_text(st->get(), 1, stream->data(), static_cast<int>(stream->size()), SQLITE_TRANSIENT);
  return read_rows<NavInputRecord>(
      impl_->db.get(), *st, where, [&](sqlite3_stmt* s, std::size_t i) -> Expected<NavInputRecord> {
        NavInputRecord n;
        n.stream = column_text(s, 0);
        n.t_ns = sqlite3_column_int64(s, 1);
        if (!parse_clock_domain(column_text(s, 2), n.clock))
          return make_error(where, "row ", i, ": unknown clock domain \"", column_text(s, 2), "\"");
        n.arrival_ns = sqlite3_column_int64(s, 3);
        n.binary = sqlite3_column_type(s, 4) == SQLITE_BLOB;
        const void* p =
            n.binary ? sqlite3_column_blob(s, 4) : static_cast<const void*>(sqlite3_column_text(s, 4));
        n.data.assign(static_cast<const char*>(p), static_cast<std::size_t>(sqlite3_column_bytes(s, 4)));
        return n;
      });
}

Expected<std::vector<DropRecord>> RecordingReader::drops() const {
  const std::string where = "recorder::RecordingReader::drops(): " + impl_->path + ": ";
  auto st = Statement::prepare(
      impl_->db.get(), "SELECT stage, item, count, first_t_ns, last_t_ns, reason FROM drops ORDER BY id");
  if (!st) return make_error(where, st.error().message);
  return read_rows<DropRecord>(
      impl_->db.get(), *st, where, [&](sqlite3_stmt* s, std::size_t i) -> Expected<DropRecord> {
        DropRecord d;
        if (!parse_drop_stage(column_text(s, 0), d.stage))
          return make_error(where, "row ", i, ": unknown stage \"", column_text(s, 0), "\"");
        d.item = column_text(s, 1);
        d.count = static_cast<std::uint64_t>(sqlite3_column_int64(s, 2));
        d.first_t_ns = sqlite3_column_int64(s, 3);
        d.last_t_ns = sqlite3_column_int64(s, 4);
        d.reason = column_text(s, 5);
        return d;
      });
}

Expected<std::vector<EventRecord>> RecordingReader::events() const {
  const std::string where = "recorder::RecordingReader::events(): " + impl_->path + ": ";
  auto st = Statement::prepare(impl_->db.get(), "SELECT t_ns, clock, text FROM events ORDER BY id");
  if (!st) return make_error(where, st.error().message);
  return read_rows<EventRecord>(
      impl_->db.get(), *st, where, [&](sqlite3_stmt* s, std::size_t i) -> Expected<EventRecord> {
        EventRecord e;
        e.t_ns = sqlite3_column_int64(s, 0);
        if (!parse_clock_domain(column_text(s, 1), e.clock))
          return make_error(where, "row ", i, ": unknown clock domain \"", column_text(s, 1), "\"");
        e.text = column_text(s, 2);
        return e;
      });
}

Expected<std::vector<LookRecord>> RecordingReader::look() const {
  const std::string where = "recorder::RecordingReader::look(): " + impl_->path + ": ";
  if (!impl_->look_table) return std::vector<LookRecord>{};  // recorded before schema 3
  auto st = Statement::prepare(impl_->db.get(), look_select_sql());
  if (!st) return make_error(where, st.error().message);
  return read_rows<LookRecord>(impl_->db.get(), *st, where,
                               [&](sqlite3_stmt* s, std::size_t i) -> Expected<LookRecord> {
                                 LookRecord r;
                                 if (auto ok = read_look_row(s, r); !ok)
                                   return make_error(where, "look row ", i, ": ", ok.error().message);
                                 return r;
                               });
}

CheckReport RecordingReader::check() const {
  const Impl& I = *impl_;
  CheckReport r;
  r.path = I.path;
  r.schema_version = I.schema_version;
  r.software = meta("software");
  r.summary_status = meta("summary.status");
  r.closed_cleanly = !r.summary_status.empty();
  std::size_t more = 0;
  auto problem = [&](const std::string& p) {
    if (r.problems.size() < kMaxProblems)
      r.problems.push_back(p);
    else
      ++more;
  };
  for (const std::string& p : I.problems) problem(p);

  r.frames = I.ids.size();
  bool have_t = false;
  for (std::size_t i = 0; i < I.ids.size(); ++i) {
    auto f = read_frame(i, kPartsAll);
    if (!f) {
      problem(f.error().message);
      f = read_frame_info(i);
      if (!f) continue;
    } else {
      ++r.frames_ok;
      bool aug = false, masks = false, depth = false;
      for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
        const int c = index_of(id);
        const Image& raw = f->raw[id].image;
        r.image_bytes +=
            static_cast<std::uint64_t>(raw.width()) * raw.height() * bytes_per_pixel(raw.format());
        if (!f->augmented[c].empty()) {
          aug = true;
          r.image_bytes +=
              static_cast<std::uint64_t>(raw.width()) * raw.height() * bytes_per_pixel(raw.format());
        }
        if (!f->mask[c].empty()) {
          masks = true;
          r.image_bytes += static_cast<std::uint64_t>(raw.width()) * raw.height();
        }
        if (!f->receiver_depth[c].empty()) {
          depth = true;
          r.image_bytes += static_cast<std::uint64_t>(raw.width()) * raw.height() * sizeof(float);
        }
        r.cameras[std::string(to_string(id)) + ": " + std::string(to_string(raw.format())) + " " +
                  std::to_string(raw.width()) + "x" + std::to_string(raw.height()) + ", clock " +
                  std::string(to_string(f->raw[id].clock))] += 1;
      }
      r.frames_augmented += aug;
      r.frames_with_masks += masks;
      r.frames_with_depth += depth;
    }
    r.frames_with_stats += f->stats.has_value();
    const TimestampNs t = f->raw.t_key_ns;
    r.t_first_ns = have_t ? std::min(r.t_first_ns, t) : t;
    r.t_last_ns = have_t ? std::max(r.t_last_ns, t) : t;
    have_t = true;
  }

  Database& db = const_cast<Database&>(I.db);
  auto each_row = [&](const std::string& sql, const std::string& what, auto&& fn) {
    auto st = Statement::prepare(db.get(), sql);
    if (!st) return problem(what + ": " + st.error().message);
    for (;;) {
      const int rc = st->step();
      if (rc == SQLITE_DONE) break;
      if (rc != SQLITE_ROW) return problem(what + ": " + describe_sqlite_error(db.get(), rc));
      fn(st->get());
    }
  };
  each_row(
      "SELECT coalesce(sum(coalesce(length(left_raw), 0) + coalesce(length(right_raw), 0) + "
      "coalesce(length(left_aug), 0) + coalesce(length(right_aug), 0) + coalesce(length(left_mask), 0) + "
      "coalesce(length(right_mask), 0)), 0) FROM frames",
      "frames (blob sizes)",
      [&](sqlite3_stmt* s) { r.stored_bytes = static_cast<std::uint64_t>(sqlite3_column_int64(s, 0)); });
  if (I.depth_table)
    each_row("SELECT coalesce(sum(coalesce(length(left_depth), 0) + coalesce(length(right_depth), 0)), 0) FROM depth",
             "depth (blob sizes)",
             [&](sqlite3_stmt* s) { r.stored_bytes += static_cast<std::uint64_t>(sqlite3_column_int64(s, 0)); });
  for (DropStage s : kAllDropStages) r.drops_by_stage[std::string(to_string(s))] = 0;
  each_row("SELECT stage, sum(count) FROM drops GROUP BY stage", "drops", [&](sqlite3_stmt* s) {
    r.drops_by_stage[column_text(s, 0)] = static_cast<std::uint64_t>(sqlite3_column_int64(s, 1));
  });
  each_row("SELECT stream, count(*) FROM nav_input GROUP BY stream", "nav_input", [&](sqlite3_stmt* s) {
    r.nav_inputs_by_stream[column_text(s, 0)] = static_cast<std::size_t>(sqlite3_column_int64(s, 1));
  });
  each_row("SELECT count(*) FROM events", "events",
           [&](sqlite3_stmt* s) { r.events = static_cast<std::size_t>(sqlite3_column_int64(s, 0)); });
  if (auto look_rows = look(); !look_rows) {
    problem(look_rows.error().message);
  } else {
    for (const LookRecord& l : *look_rows) ++(std::holds_alternative<LookNoise>(l.update) ? r.look_noise : r.look_light);
  }
  each_row("PRAGMA quick_check(20)", "SQLite quick_check", [&](sqlite3_stmt* s) {
    const std::string line = column_text(s, 0);
    if (line != "ok") problem(I.path + ": SQLite quick_check: " + line);
  });
  if (more > 0) r.problems.push_back("... and " + std::to_string(more) + " more problems");
  return r;
}

std::string CheckReport::to_string() const {
  std::ostringstream o;
  o << "recording: " << path << "\n";
  o << "schema version: " << schema_version << ", written by " << (software.empty() ? "?" : software) << "\n";
  o << "closed: "
    << (closed_cleanly ? "yes, status " + summary_status
                       : std::string("no (no summary: the writer "
                                     "stopped without closing)"))
    << "\n";
  o << "frames: " << frames << " (" << frames_ok << " intact, " << frames_augmented << " augmented, "
    << frames_with_masks << " with masks, " << frames_with_stats << " with statistics)\n";
  o << "receiver depth: " << frames_with_depth << " frames"
    << (frames_with_depth ? "" : " (record with --ground-truth to store it)") << "\n";
  if (frames > 0) {
    char span[64];
    std::snprintf(span, sizeof span, "%.3f", ns_to_s(t_last_ns - t_first_ns));
    o << "time span: " << t_first_ns << " .. " << t_last_ns << " ns (" << span << " s)\n";
  }
  for (const auto& [cam, n] : cameras) o << "camera " << cam << ": " << n << " frames\n";
  if (stored_bytes > 0 && image_bytes > 0) {
    char ratio[64];
    std::snprintf(ratio, sizeof ratio, "%.2f",
                  static_cast<double>(image_bytes) / static_cast<double>(stored_bytes));
    o << "images: " << image_bytes << " bytes stored in " << stored_bytes << " (ratio " << ratio << ")\n";
  }
  o << "drops:";
  for (const auto& [stage, n] : drops_by_stage) o << " " << stage << " " << n;
  o << "\n";
  o << "nav inputs:";
  if (nav_inputs_by_stream.empty()) o << " none";
  for (const auto& [s, n] : nav_inputs_by_stream) o << " " << s << " " << n;
  o << "\n";
  o << "events: " << events << "\n";
  o << "look updates: " << look_noise << " noise, " << look_light << " light\n";
  o << "problems: " << (problems.empty() ? "none" : std::to_string(problems.size())) << "\n";
  for (const std::string& p : problems) o << "  " << p << "\n";
  return o.str();
}

}  // namespace augrig::recorder
