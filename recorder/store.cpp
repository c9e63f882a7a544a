#include "recorder/store.hpp"

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <iterator>
#include <limits>

namespace augrig::recorder {

std::string database_path(const std::string& dir_or_file) {
  std::error_code ec;
  if (std::filesystem::is_directory(dir_or_file, ec))
    return (std::filesystem::path(dir_or_file) / kDatabaseFile).string();
  return dir_or_file;
}

namespace {

const char* code_name(int rc) {
  switch (rc) {
    case SQLITE_ERROR:
      return "SQLITE_ERROR";
    case SQLITE_PERM:
      return "SQLITE_PERM";
    case SQLITE_ABORT:
      return "SQLITE_ABORT";
    case SQLITE_BUSY:
      return "SQLITE_BUSY";
    case SQLITE_LOCKED:
      return "SQLITE_LOCKED";
    case SQLITE_NOMEM:
      return "SQLITE_NOMEM";
    case SQLITE_READONLY:
      return "SQLITE_READONLY";
    case SQLITE_IOERR:
      return "SQLITE_IOERR";
    case SQLITE_CORRUPT:
      return "SQLITE_CORRUPT";
    case SQLITE_FULL:
      return "SQLITE_FULL";
    case SQLITE_CANTOPEN:
      return "SQLITE_CANTOPEN";
    case SQLITE_TOOBIG:
      return "SQLITE_TOOBIG";
    case SQLITE_CONSTRAINT:
      return "SQLITE_CONSTRAINT";
    case SQLITE_MISUSE:
      return "SQLITE_MISUSE";
    case SQLITE_NOTADB:
      return "SQLITE_NOTADB";
    default:
      return nullptr;
  }
}

}  // namespace

std::string describe_sqlite_error(sqlite3* db, int rc) {
  std::string s;
  const int ext = db ? sqlite3_extended_errcode(db) : rc;
  // The connection's message when it belongs to this error, else SQLite's text for the code.
  if (db && (ext & 0xff) == (rc & 0xff))
    s = sqlite3_errmsg(db);
  else
    s = sqlite3_errstr(rc);
  s += " (";
  const char* name = code_name(rc & 0xff);
  s += name ? name : ("SQLite code " + std::to_string(rc & 0xff)).c_str();
  if ((rc & 0xff) == SQLITE_IOERR && db) {
    switch (ext) {
      case SQLITE_IOERR_READ:
        s += ", SQLITE_IOERR_READ";
        break;
      case SQLITE_IOERR_SHORT_READ:
        s += ", SQLITE_IOERR_SHORT_READ";
        break;
      case SQLITE_IOERR_WRITE:
        s += ", SQLITE_IOERR_WRITE";
        break;
      case SQLITE_IOERR_FSYNC:
        s += ", SQLITE_IOERR_FSYNC";
        break;
      case SQLITE_IOERR_TRUNCATE:
        s += ", SQLITE_IOERR_TRUNCATE";
        break;
      default:
        s += ", extended code " + std::to_string(ext);
    }
  }
  const int sys = db ? sqlite3_system_errno(db) : 0;
  if (sys != 0 &&
      ((rc & 0xff) == SQLITE_IOERR || (rc & 0xff) == SQLITE_FULL || (rc & 0xff) == SQLITE_CANTOPEN))
    s += ", errno " + std::to_string(sys) + ": " + std::strerror(sys);
  s += ")";
  return s;
}

std::string utc_now_iso8601() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

Database& Database::operator=(Database&& o) noexcept {
  if (this != &o) {
    close();
    db_ = o.db_;
    o.db_ = nullptr;
  }
  return *this;
}

Expected<Database> Database::open(const std::string& path, int flags) {
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &db, flags, nullptr);
  if (rc != SQLITE_OK) {
    std::string msg = describe_sqlite_error(db, rc);
    sqlite3_close(db);
    return make_error(path, ": cannot open: ", msg);
  }
  sqlite3_extended_result_codes(db, 0);
  Database d;
  d.db_ = db;
  return d;
}

Status Database::exec(std::string_view sql) {
  const std::string s(sql);
  const int rc = sqlite3_exec(db_, s.c_str(), nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) return Error{describe_sqlite_error(db_, rc)};
  return {};
}

Expected<std::string> Database::query_text(std::string_view sql) {
  auto st = Statement::prepare(db_, sql);
  if (!st) return st.error();
  const int rc = st->step();
  if (rc == SQLITE_ROW) {
    const unsigned char* t = sqlite3_column_text(st->get(), 0);
    return std::string(t ? reinterpret_cast<const char*>(t) : "");
  }
  if (rc == SQLITE_DONE) return std::string();
  return Error{describe_sqlite_error(db_, rc)};
}

int Database::close() {
  if (!db_) return 0;
  const int rc = sqlite3_close_v2(db_);  // statements still open keep it alive until finalized
  db_ = nullptr;
  return rc;
}

Statement& Statement::operator=(Statement&& o) noexcept {
  if (this != &o) {
    sqlite3_finalize(st_);
    st_ = o.st_;
    o.st_ = nullptr;
  }
  return *this;
}

Expected<Statement> Statement::prepare(sqlite3* db, std::string_view sql) {
  sqlite3_stmt* st = nullptr;
  const int rc = sqlite3_prepare_v2(db, sql.data(), static_cast<int>(sql.size()), &st, nullptr);
  if (rc != SQLITE_OK) {
    sqlite3_finalize(st);
    return Error{describe_sqlite_error(db, rc)};
  }
  Statement s;
  s.st_ = st;
  return s;
}

// ---------------------------------------------------------------------------------------------
// The frames row, defined once. visit_frame_row() walks every column in table order; the
// visitors below turn that walk into the CREATE TABLE column list, an INSERT binder and a reader.

namespace {

constexpr const char* kCam[2] = {"left_", "right_"};

template <typename V>
void visit_pose(V& v, const std::string& prefix, Pose& p) {
  v.real(prefix + "x_m", p.translation_m.x());
  v.real(prefix + "y_m", p.translation_m.y());
  v.real(prefix + "z_m", p.translation_m.z());
  v.real(prefix + "qw", p.rotation.w());
  v.real(prefix + "qx", p.rotation.x());
  v.real(prefix + "qy", p.rotation.y());
  v.real(prefix + "qz", p.rotation.z());
}

// The statistics columns carry render/stats.hpp's (and stats.csv's) names; the stats' own t_ns,
// width and height get a "stats_" prefix since `frames` has a t_ns of its own. `since(N)`: the
// columns that follow were added by schema version N (the visitors other than the schema's ignore it).
template <typename V>
void visit_stats(V& v, OcclusionStats& s) {
  v.integer("stats_t_ns", s.t_ns);
  v.integer("stats_width", s.width);
  v.integer("stats_height", s.height);
#define AUGRIG_REC_INT(f) v.integer(#f, s.f)
#define AUGRIG_REC_REAL(f) v.real(#f, s.f)
  AUGRIG_REC_INT(receiver_px_left);
  AUGRIG_REC_INT(receiver_px_right);
  AUGRIG_REC_INT(boom_px_left);
  AUGRIG_REC_INT(boom_px_right);
  AUGRIG_REC_INT(boom_overlap_px);
  AUGRIG_REC_REAL(boom_overlap_pct_union);
  AUGRIG_REC_INT(occluded_px_left);
  AUGRIG_REC_INT(occluded_px_right);
  AUGRIG_REC_REAL(occluded_pct_left);
  AUGRIG_REC_REAL(occluded_pct_right);
  AUGRIG_REC_INT(stereo_both_px);
  AUGRIG_REC_INT(left_only_px);
  AUGRIG_REC_INT(right_only_px);
  AUGRIG_REC_INT(neither_px);
  AUGRIG_REC_REAL(receiver_pct_left);
  AUGRIG_REC_REAL(receiver_pct_right);
  AUGRIG_REC_REAL(boom_pct_left);
  AUGRIG_REC_REAL(boom_pct_right);
  // Appended by schema 3, as stats.csv appended them: an older recording reads them as 0.
  v.since(3);
  AUGRIG_REC_INT(shadow_px_left);
  AUGRIG_REC_INT(shadow_px_right);
  AUGRIG_REC_REAL(shadow_pct_left);
  AUGRIG_REC_REAL(shadow_pct_right);
  v.since(1);
#undef AUGRIG_REC_INT
#undef AUGRIG_REC_REAL
}

template <typename V>
void visit_frame_row(V& v, FrameRow& r) {
  v.integer("pair_sequence", r.pair_sequence);
  v.integer("t_ns", r.t_ns);
  v.integer("skew_ns", r.skew_ns);
  for (int c = 0; c < 2; ++c) {
    const std::string p = kCam[c];
    CameraRow& cr = r.cam[c];
    v.integer(p + "sequence", cr.sequence);
    v.integer(p + "t_ns", cr.t_ns);
    v.clock(p + "clock", cr.clock);
    v.integer(p + "t_host_ns", cr.t_host_ns);
    v.integer(p + "exposure_ns", cr.exposure_ns);
    v.format(p + "format", cr.format);
    v.integer(p + "width", cr.width);
    v.integer(p + "height", cr.height);
  }
  for (int c = 0; c < 2; ++c) {
    const std::string p = std::string(kCam[c]) + "cam_receiver_";
    v.group(r.T_cam_receiver[c], [&](Pose& pose) { visit_pose(v, p, pose); });
  }
  v.group(r.T_body_receiver, [&](Pose& pose) { visit_pose(v, "body_receiver_", pose); });
  v.group(r.receiver_present, [&](bool& b) { v.integer("receiver_present", b); });
  v.real("sigma_pos_m", r.sigma_pos_m);
  v.real("sigma_att_deg", r.sigma_att_deg);
  v.group(r.boom, [&](BoomArticulation& a) {
    v.real("boom_elevation_rad", a.elevation_rad);
    v.real("boom_azimuth_rad", a.azimuth_rad);
    v.real("boom_extension_m", a.extension_m);
  });
  v.group(r.stats, [&](OcclusionStats& s) { visit_stats(v, s); });
  for (int c = 0; c < 2; ++c) {
    const std::string p = std::string(kCam[c]) + "aug_";
    ChangedBox& b = r.cam[c].aug_box;
    v.integer(p + "x0", b.x0);
    v.integer(p + "y0", b.y0);
    v.integer(p + "x1", b.x1);
    v.integer(p + "y1", b.y1);
  }
  // Blobs last, so that reading the small columns never walks a blob's overflow pages.
  v.blob("left_mask", r.mask[0], kPartMasks);
  v.blob("right_mask", r.mask[1], kPartMasks);
  v.blob("left_aug", r.aug[0], kPartAugmented);
  v.blob("right_aug", r.aug[1], kPartAugmented);
  v.blob("left_raw", r.raw[0], kPartRaw | kPartAugmented);
  v.blob("right_raw", r.raw[1], kPartRaw | kPartAugmented);
}

// Collects "name TYPE" for CREATE TABLE, and the names.
struct SchemaVisitor {
  std::vector<std::string> names, defs;
  std::vector<unsigned> blob_parts;  // per column: parts that fetch it (0: not a blob)
  std::vector<int> added_in;         // per column: the schema version that added it
  std::vector<bool> is_real;
  bool nullable = false;
  int version = 1;
  void since(int v) { version = v; }
  void add(const std::string& name, const char* type, bool not_null, unsigned parts = 0) {
    names.push_back(name);
    defs.push_back(name + " " + type + (not_null && !nullable ? " NOT NULL" : ""));
    blob_parts.push_back(parts);
    added_in.push_back(version);
    is_real.push_back(std::string_view(type) == "REAL");
  }
  template <typename T>
  void integer(const std::string& name, T&) {
    add(name, "INTEGER", true);
  }
  void real(const std::string& name, double&) { add(name, "REAL", false); }
  void clock(const std::string& name, ClockDomain&) { add(name, "TEXT", true); }
  void format(const std::string& name, PixelFormat&) { add(name, "TEXT", true); }
  void blob(const std::string& name, BlobRef&, unsigned parts) { add(name, "BLOB", false, parts); }
  template <typename T, typename F>
  void group(std::optional<T>&, F&& body) {
    T dummy{};
    nullable = true;
    body(dummy);
    nullable = false;
  }
};

const SchemaVisitor& frame_schema() {
  static const SchemaVisitor s = [] {
    SchemaVisitor v;
    FrameRow r;
    visit_frame_row(v, r);
    return v;
  }();
  return s;
}

struct BindVisitor {
  sqlite3_stmt* st = nullptr;
  int i = 1;
  bool null_mode = false;
  int rc = SQLITE_OK;
  void since(int) {}
  void check(int r) {
    if (rc == SQLITE_OK) rc = r;
  }
  template <typename T>
  void integer(const std::string&, T& v) {
    if (null_mode)
      check(sqlite3_bind_null(st, i++));
    else
      check(sqlite3_bind_int64(st, i++, static_cast<sqlite3_int64>(v)));
  }
  void real(const std::string&, double& v) {
    // SQLite stores NaN as NULL; NULL reads back as NaN.
    if (null_mode || std::isnan(v))
      check(sqlite3_bind_null(st, i++));
    else
      check(sqlite3_bind_double(st, i++, v));
  }
  void text(std::string_view s) {
    check(sqlite3_bind_text(st, i++, s.data(), static_cast<int>(s.size()), SQLITE_STATIC));
  }
  void clock(const std::string&, ClockDomain& c) { text(to_string(c)); }
  void format(const std::string&, PixelFormat& f) { text(to_string(f)); }
  void blob(const std::string&, BlobRef& b, unsigned) {
    if (!b.present)
      check(sqlite3_bind_null(st, i++));
    else if (b.size == 0)
      check(sqlite3_bind_zeroblob(st, i++, 0));
    else
      check(sqlite3_bind_blob64(st, i++, b.data, b.size, SQLITE_STATIC));
  }
  template <typename T, typename F>
  void group(std::optional<T>& o, F&& body) {
    if (o) {
      body(*o);
      return;
    }
    T dummy{};
    null_mode = true;
    body(dummy);
    null_mode = false;
  }
};

struct ReadVisitor {
  sqlite3_stmt* st = nullptr;
  int i = 1;  // column 0 is id
  bool skip = false;
  std::string error;
  void since(int) {}
  bool is_null(int col) const { return sqlite3_column_type(st, col) == SQLITE_NULL; }
  void fail(const std::string& name, const std::string& what) {
    if (error.empty()) error = "column " + name + ": " + what;
  }
  template <typename T>
  void integer(const std::string& name, T& v) {
    const int col = i++;
    if (skip) return;
    if (sqlite3_column_type(st, col) != SQLITE_INTEGER) return fail(name, "expected an integer");
    const sqlite3_int64 x = sqlite3_column_int64(st, col);
    if constexpr (std::is_same_v<T, bool>)
      v = x != 0;
    else
      v = static_cast<T>(x);
  }
  void real(const std::string& name, double& v) {
    const int col = i++;
    if (skip) return;
    const int t = sqlite3_column_type(st, col);
    if (t == SQLITE_NULL)
      v = FrameRecord::kNaN;
    else if (t == SQLITE_FLOAT || t == SQLITE_INTEGER)
      v = sqlite3_column_double(st, col);
    else
      fail(name, "expected a number");
  }
  std::string_view text(const std::string& name, int col) {
    if (sqlite3_column_type(st, col) != SQLITE_TEXT) {
      fail(name, "expected text");
      return {};
    }
    const unsigned char* t = sqlite3_column_text(st, col);
    return {reinterpret_cast<const char*>(t), static_cast<std::size_t>(sqlite3_column_bytes(st, col))};
  }
  void clock(const std::string& name, ClockDomain& c) {
    const int col = i++;
    if (skip) return;
    const std::string_view t = text(name, col);
    if (error.empty() && !parse_clock_domain(t, c))
      fail(name, "unknown clock domain \"" + std::string(t) + "\"");
  }
  void format(const std::string& name, PixelFormat& f) {
    const int col = i++;
    if (skip) return;
    const std::string_view t = text(name, col);
    if (error.empty() && !parse_pixel_format(t, f))
      fail(name, "unknown pixel format \"" + std::string(t) + "\"");
  }
  void blob(const std::string& name, BlobRef& b, unsigned) {
    const int col = i++;
    if (skip) return;
    const int t = sqlite3_column_type(st, col);
    b = {};
    if (t == SQLITE_NULL) return;
    if (t != SQLITE_BLOB) return fail(name, "expected a blob");
    b.data = static_cast<const std::uint8_t*>(sqlite3_column_blob(st, col));
    b.size = static_cast<std::size_t>(sqlite3_column_bytes(st, col));
    b.present = true;
  }
  template <typename T, typename F>
  void group(std::optional<T>& o, F&& body) {
    if (is_null(i)) {
      o.reset();
      T dummy{};
      const bool was = skip;
      skip = true;
      body(dummy);
      skip = was;
      return;
    }
    o.emplace();
    body(*o);
  }
};

// The `look` table's columns after id, in table order: CREATE, INSERT and SELECT are all made from
// this one list. A noise row fills camera .. note, a light row direct_r .. sun_z; the rest are NULL.
struct LookColumn {
  const char* name;
  const char* type;
};
constexpr LookColumn kLookColumns[] = {
    {"t_ns", "INTEGER NOT NULL"},
    {"clock", "TEXT NOT NULL"},
    {"kind", "TEXT NOT NULL CHECK (kind IN ('noise', 'light'))"},
    {"source", "TEXT NOT NULL"},
    {"camera", "INTEGER"},
    {"channels", "INTEGER"},
    {"a0", "REAL"},
    {"a1", "REAL"},
    {"a2", "REAL"},
    {"b0", "REAL"},
    {"b1", "REAL"},
    {"b2", "REAL"},
    {"frames", "INTEGER"},
    {"note", "TEXT"},
    {"direct_r", "REAL"},
    {"direct_g", "REAL"},
    {"direct_b", "REAL"},
    {"sky_r", "REAL"},
    {"sky_g", "REAL"},
    {"sky_b", "REAL"},
    {"ground_r", "REAL"},
    {"ground_g", "REAL"},
    {"ground_b", "REAL"},
    {"samples", "INTEGER"},
    {"rms", "REAL"},
    {"sun_up", "INTEGER"},
    {"sun_x", "REAL"},
    {"sun_y", "REAL"},
    {"sun_z", "REAL"},
};
// Column indices into kLookColumns (the SELECT's result columns; the INSERT's parameters are + 1).
enum LookCol : int {
  kLookT,
  kLookClock,
  kLookKind,
  kLookSource,
  kLookCamera,
  kLookChannels,
  kLookA,
  kLookB = kLookA + 3,
  kLookFrames = kLookB + 3,
  kLookNote,
  kLookDirect,
  kLookSky = kLookDirect + 3,
  kLookGround = kLookSky + 3,
  kLookSamples = kLookGround + 3,
  kLookRms,
  kLookSunUp,
  kLookSun,
  kLookColumnCount = kLookSun + 3,
};
static_assert(std::size(kLookColumns) == kLookColumnCount, "kLookColumns and LookCol disagree");

// A noise row's `source`: the rig's or estimated from the frames.
constexpr std::string_view kNoiseConfigured = "configured", kNoiseEstimated = "estimated";

std::string look_table_sql() {
  std::string s = "CREATE TABLE look (id INTEGER PRIMARY KEY";
  for (const LookColumn& c : kLookColumns) s += std::string(", ") + c.name + " " + c.type;
  return s + ");\n";
}

std::string look_column_list() {
  std::string s;
  for (const LookColumn& c : kLookColumns) s += std::string(s.empty() ? "" : ", ") + c.name;
  return s;
}

std::string join(const std::vector<std::string>& v, const char* sep) {
  std::string s;
  for (std::size_t k = 0; k < v.size(); ++k) {
    if (k) s += sep;
    s += v[k];
  }
  return s;
}

}  // namespace

std::vector<std::string> frame_column_names() {
  return frame_schema().names;
}

std::vector<std::string> frame_columns_added_after(int schema_version) {
  const SchemaVisitor& s = frame_schema();
  std::vector<std::string> out;
  for (std::size_t k = 0; k < s.names.size(); ++k)
    if (s.added_in[k] > schema_version) out.push_back(s.names[k]);
  return out;
}

std::string schema_sql() {
  std::string s;
  s += "CREATE TABLE meta (key TEXT PRIMARY KEY NOT NULL, value TEXT NOT NULL);\n";
  s += "CREATE TABLE frames (\n  id INTEGER PRIMARY KEY,\n  " + join(frame_schema().defs, ",\n  ") + "\n);\n";
  s += "CREATE INDEX frames_t_ns ON frames (t_ns);\n";
  s += "CREATE TABLE depth (frame_id INTEGER PRIMARY KEY, left_x0 INTEGER, left_y0 INTEGER, left_x1 INTEGER, "
       "left_y1 INTEGER, left_depth BLOB, right_x0 INTEGER, right_y0 INTEGER, right_x1 INTEGER, "
       "right_y1 INTEGER, right_depth BLOB);\n";
  s += "CREATE TABLE nav_input (id INTEGER PRIMARY KEY, stream TEXT NOT NULL, t_ns INTEGER NOT NULL, "
       "clock TEXT NOT NULL, arrival_ns INTEGER NOT NULL, data NOT NULL);\n";
  s += "CREATE INDEX nav_input_stream_t_ns ON nav_input (stream, t_ns);\n";
  s += "CREATE TABLE drops (id INTEGER PRIMARY KEY, stage TEXT NOT NULL CHECK (stage IN ('camera', "
       "'transport', 'pairing', 'processing', 'recorder')), item TEXT NOT NULL, count INTEGER NOT NULL, "
       "first_t_ns INTEGER NOT NULL, last_t_ns INTEGER NOT NULL, reason TEXT NOT NULL);\n";
  s += "CREATE TABLE events (id INTEGER PRIMARY KEY, t_ns INTEGER NOT NULL, clock TEXT NOT NULL, "
       "text TEXT NOT NULL);\n";
  s += look_table_sql();
  return s;
}

std::string frame_insert_sql() {
  const auto& names = frame_schema().names;
  std::string q = "INSERT INTO frames (" + join(names, ", ") + ") VALUES (";
  for (std::size_t k = 0; k < names.size(); ++k) q += k ? ", ?" : "?";
  return q + ")";
}

Status bind_frame_row(sqlite3_stmt* st, const FrameRow& row) {
  BindVisitor v;
  v.st = st;
  visit_frame_row(v, const_cast<FrameRow&>(row));  // the binder only reads
  if (v.rc != SQLITE_OK) return make_error("binding frame columns: ", sqlite3_errstr(v.rc));
  return {};
}

std::string frame_select_sql(unsigned parts, int schema_version) {
  const SchemaVisitor& s = frame_schema();
  std::string q = "SELECT id";
  for (std::size_t k = 0; k < s.names.size(); ++k) {
    q += ", ";
    if (s.blob_parts[k] != 0 && (s.blob_parts[k] & parts) == 0)
      q += "NULL AS " + s.names[k];
    else if (s.added_in[k] > schema_version)
      q += std::string(s.is_real[k] ? "0.0" : "0") + " AS " + s.names[k];  // not in an older recording
    else
      q += s.names[k];
  }
  return q + " FROM frames";
}

Status read_frame_row(sqlite3_stmt* st, FrameRow& row) {
  row.id = sqlite3_column_int64(st, 0);
  ReadVisitor v;
  v.st = st;
  visit_frame_row(v, row);
  if (!v.error.empty()) return Error{v.error};
  return {};
}

namespace {
constexpr const char* kDepthColumns =
    "left_x0, left_y0, left_x1, left_y1, left_depth, right_x0, right_y0, right_x1, right_y1, right_depth";
}  // namespace

std::string depth_insert_sql() {
  return std::string("INSERT INTO depth (frame_id, ") + kDepthColumns +
         ") VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)";
}

Status bind_depth_row(sqlite3_stmt* st, const DepthRow& row) {
  int rc = sqlite3_bind_int64(st, 1, row.frame_id);
  for (int c = 0; c < 2; ++c) {
    const int col = 2 + 5 * c;
    const auto& b = row.box[c];
    const int v[4] = {b ? b->x0 : 0, b ? b->y0 : 0, b ? b->x1 : 0, b ? b->y1 : 0};
    for (int k = 0; k < 4; ++k)
      if (rc == SQLITE_OK) rc = b ? sqlite3_bind_int64(st, col + k, v[k]) : sqlite3_bind_null(st, col + k);
    const BlobRef& blob = row.blob[c];
    if (rc != SQLITE_OK) break;
    if (!b || !blob.present)
      rc = sqlite3_bind_null(st, col + 4);
    else if (blob.size == 0)
      rc = sqlite3_bind_zeroblob(st, col + 4, 0);
    else
      rc = sqlite3_bind_blob64(st, col + 4, blob.data, blob.size, SQLITE_STATIC);
  }
  if (rc != SQLITE_OK) return make_error("binding depth columns: ", sqlite3_errstr(rc));
  return {};
}

std::string depth_select_sql() {
  return std::string("SELECT frame_id, ") + kDepthColumns + " FROM depth WHERE frame_id = ?";
}

Status read_depth_row(sqlite3_stmt* st, DepthRow& row) {
  row = DepthRow{};
  row.frame_id = sqlite3_column_int64(st, 0);
  for (int c = 0; c < 2; ++c) {
    const int col = 1 + 5 * c;
    const std::string p = c ? "right_" : "left_";
    if (sqlite3_column_type(st, col + 4) == SQLITE_NULL) continue;
    if (sqlite3_column_type(st, col + 4) != SQLITE_BLOB)
      return make_error("column ", p, "depth: expected a blob");
    int v[4];
    const char* names[4] = {"x0", "y0", "x1", "y1"};
    for (int k = 0; k < 4; ++k) {
      if (sqlite3_column_type(st, col + k) != SQLITE_INTEGER)
        return make_error("column ", p, names[k], ": expected an integer");
      const sqlite3_int64 x = sqlite3_column_int64(st, col + k);
      if (x < 0 || x > 65535)
        return make_error("column ", p, names[k], ": ", x, " is not a pixel coordinate");
      v[k] = static_cast<int>(x);
    }
    row.box[c] = PixelBox{v[0], v[1], v[2], v[3]};
    row.blob[c] = {static_cast<const std::uint8_t*>(sqlite3_column_blob(st, col + 4)),
                   static_cast<std::size_t>(sqlite3_column_bytes(st, col + 4)), true};
  }
  return {};
}

}  // namespace augrig::recorder

namespace augrig::recorder {

std::string look_insert_sql() {
  std::string q = "INSERT INTO look (" + look_column_list() + ") VALUES (";
  for (int k = 0; k < kLookColumnCount; ++k) q += k ? ", ?" : "?";
  return q + ")";
}

Status bind_look_row(sqlite3_stmt* st, const LookRecord& row) {
  int rc = SQLITE_OK;
  auto check = [&](int r) {
    if (rc == SQLITE_OK) rc = r;
  };
  auto integer = [&](int col, std::int64_t v) { check(sqlite3_bind_int64(st, col + 1, v)); };
  // NaN is stored as NULL, as in `frames`.
  auto real = [&](int col, double v) {
    check(std::isnan(v) ? sqlite3_bind_null(st, col + 1) : sqlite3_bind_double(st, col + 1, v));
  };
  auto text = [&](int col, std::string_view t) {
    check(sqlite3_bind_text(st, col + 1, t.data(), static_cast<int>(t.size()), SQLITE_TRANSIENT));
  };
  for (int col = 0; col < kLookColumnCount; ++col) check(sqlite3_bind_null(st, col + 1));
  integer(kLookT, row.t_ns);
  text(kLookClock, to_string(row.clock));
  text(kLookKind, look_kind(row));
  if (const auto* n = std::get_if<LookNoise>(&row.update)) {
    if (n->nlf.channels != 1 && n->nlf.channels != 3)
      return make_error("binding look columns: a noise level function of ", n->nlf.channels,
                        " channels (expected 1 or 3)");
    text(kLookSource, n->configured ? kNoiseConfigured : kNoiseEstimated);
    integer(kLookCamera, n->camera);
    integer(kLookChannels, n->nlf.channels);
    for (int k = 0; k < n->nlf.channels; ++k) {
      real(kLookA + k, n->nlf.a[static_cast<std::size_t>(k)]);
      real(kLookB + k, n->nlf.b[static_cast<std::size_t>(k)]);
    }
    integer(kLookFrames, static_cast<std::int64_t>(n->frames));
    text(kLookNote, n->note);
  } else {
    const LookLight& l = std::get<LookLight>(row.update);
    text(kLookSource, to_string(l.source));
    for (int k = 0; k < 3; ++k) {
      real(kLookDirect + k, l.direct[k]);
      real(kLookSky + k, l.sky[k]);
      real(kLookGround + k, l.ground[k]);
      real(kLookSun + k, l.towards_sun_body[k]);
    }
    integer(kLookSamples, static_cast<std::int64_t>(l.samples));
    real(kLookRms, l.rms);
    integer(kLookSunUp, l.sun_up ? 1 : 0);
  }
  if (rc != SQLITE_OK) return make_error("binding look columns: ", sqlite3_errstr(rc));
  return {};
}

std::string look_select_sql() {
  return "SELECT " + look_column_list() + " FROM look ORDER BY id";
}

namespace {

// Reads one `look` row's columns, keeping the first error ("column a1: expected a number, got NULL").
struct LookReader {
  sqlite3_stmt* st;
  std::string error;

  void fail(int col, const std::string& what) {
    if (error.empty()) error = std::string("column ") + kLookColumns[col].name + ": " + what;
  }
  static const char* type_name(int t) {
    switch (t) {
      case SQLITE_INTEGER:
        return "an integer";
      case SQLITE_FLOAT:
        return "a real";
      case SQLITE_TEXT:
        return "text";
      case SQLITE_BLOB:
        return "a blob";
      default:
        return "NULL";
    }
  }
  std::int64_t integer(int col, std::int64_t lo, std::int64_t hi) {
    const int t = sqlite3_column_type(st, col);
    if (t != SQLITE_INTEGER) {
      fail(col, std::string("expected an integer, got ") + type_name(t));
      return lo;
    }
    const std::int64_t v = sqlite3_column_int64(st, col);
    if (v < lo || v > hi)
      fail(col, std::to_string(v) + " is outside " + std::to_string(lo) + ".." + std::to_string(hi));
    return v;
  }
  // `nullable`: NULL reads as NaN (stored from a NaN).
  double real(int col, bool nullable = false) {
    const int t = sqlite3_column_type(st, col);
    if (t == SQLITE_FLOAT || t == SQLITE_INTEGER) return sqlite3_column_double(st, col);
    if (t == SQLITE_NULL && nullable) return FrameRecord::kNaN;
    fail(col, std::string("expected a number, got ") + type_name(t));
    return FrameRecord::kNaN;
  }
  Eigen::Vector3d rgb(int col) { return {real(col), real(col + 1), real(col + 2)}; }
  std::string text(int col, bool nullable = false) {
    const int t = sqlite3_column_type(st, col);
    if (t == SQLITE_NULL && nullable) return {};
    if (t != SQLITE_TEXT) {
      fail(col, std::string("expected text, got ") + type_name(t));
      return {};
    }
    return {reinterpret_cast<const char*>(sqlite3_column_text(st, col)),
            static_cast<std::size_t>(sqlite3_column_bytes(st, col))};
  }

  LookNoise noise() {
    LookNoise n;
    const std::string source = text(kLookSource);
    if (error.empty() && source != kNoiseConfigured && source != kNoiseEstimated)
      fail(kLookSource, "\"" + source + "\" is neither configured nor estimated");
    n.configured = source == kNoiseConfigured;
    n.camera = static_cast<int>(integer(kLookCamera, 0, 255));
    n.nlf.channels = static_cast<int>(integer(kLookChannels, 1, 3));
    if (error.empty() && n.nlf.channels == 2) fail(kLookChannels, "2 channels (expected 1 or 3)");
    for (int k = 0; k < n.nlf.channels && error.empty(); ++k) {
      n.nlf.a[static_cast<std::size_t>(k)] = real(kLookA + k);
      n.nlf.b[static_cast<std::size_t>(k)] = real(kLookB + k);
    }
    n.frames = static_cast<std::uint64_t>(integer(kLookFrames, 0, std::numeric_limits<std::int64_t>::max()));
    n.note = text(kLookNote, true);
    return n;
  }
  LookLight light() {
    LookLight l;
    const std::string source = text(kLookSource);
    if (error.empty() && !parse_light_source(source, l.source))
      fail(kLookSource, "unknown light source \"" + source + "\"");
    l.direct = rgb(kLookDirect);
    l.sky = rgb(kLookSky);
    l.ground = rgb(kLookGround);
    l.samples =
        static_cast<std::uint64_t>(integer(kLookSamples, 0, std::numeric_limits<std::int64_t>::max()));
    l.rms = real(kLookRms, true);
    l.sun_up = integer(kLookSunUp, 0, 1) != 0;
    l.towards_sun_body = rgb(kLookSun);
    return l;
  }
};

}  // namespace

Status read_look_row(sqlite3_stmt* st, LookRecord& row) {
  row = LookRecord{};
  LookReader r{st, {}};
  row.t_ns =
      r.integer(kLookT, std::numeric_limits<std::int64_t>::min(), std::numeric_limits<std::int64_t>::max());
  const std::string clock = r.text(kLookClock);
  if (r.error.empty() && !parse_clock_domain(clock, row.clock))
    r.fail(kLookClock, "unknown clock domain \"" + clock + "\"");
  const std::string kind = r.text(kLookKind);
  if (kind == "noise")
    row.update = r.noise();
  else if (kind == "light")
    row.update = r.light();
  else
    r.fail(kLookKind, "unknown kind \"" + kind + "\" (expected noise or light)");
  if (!r.error.empty()) return Error{r.error};
  return {};
}

}  // namespace augrig::recorder
