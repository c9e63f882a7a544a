// merge_recordings() (recording_merge.hpp): SQL from the parts straight into the new database, the
// blobs never leaving SQLite, in one transaction.
#include "recorder/recording_merge.hpp"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <map>
#include <system_error>

#include <fcntl.h>
#include <unistd.h>

#include "recorder/reader.hpp"
#include "recorder/store.hpp"

namespace augrig::recorder {

namespace fs = std::filesystem;

namespace {

constexpr const char* kWhere = "recorder::merge_recordings(): ";

// One part, as its database says.
struct Part {
  std::string path;  // DIR/recording.sqlite
  std::map<std::string, std::string> meta;
  std::int64_t first_id = 0, last_id = 0;
  TimestampNs t_first_ns = 0, t_last_ns = 0;
  std::size_t frames = 0;
};

Expected<std::map<std::string, std::string>> read_meta(sqlite3* db) {
  auto st = Statement::prepare(db, "SELECT key, value FROM meta");
  if (!st) return st.error();
  std::map<std::string, std::string> m;
  while (st->step() == SQLITE_ROW) {
    const auto* k = sqlite3_column_text(st->get(), 0);
    const auto* v = sqlite3_column_text(st->get(), 1);
    m[k ? reinterpret_cast<const char*>(k) : ""] = v ? reinterpret_cast<const char*>(v) : "";
  }
  return m;
}

std::string value_of(const std::map<std::string, std::string>& m, const std::string& k) {
  const auto it = m.find(k);
  return it == m.end() ? std::string() : it->second;
}

// A part opened and described; errors name it and say what is wrong.
Expected<Part> open_part(const std::string& dir_or_file) {
  Part p;
  p.path = database_path(dir_or_file);
  auto reader = RecordingReader::open(dir_or_file);  // is a recording, of a schema this build reads
  if (!reader) return make_error(kWhere, reader.error().message);
  auto db = Database::open(p.path, SQLITE_OPEN_READONLY);
  if (!db) return make_error(kWhere, db.error().message);
  auto meta = read_meta(db->get());
  if (!meta) return make_error(kWhere, p.path, ": meta: ", meta.error().message);
  p.meta = std::move(*meta);
  if (value_of(p.meta, "schema_version") != std::to_string(kSchemaVersion))
    return make_error(kWhere, p.path, ": schema version ", value_of(p.meta, "schema_version"), ", expected ",
                      kSchemaVersion, " (record the shards with this augrig)");
  if (value_of(p.meta, "summary.status").empty())
    return make_error(kWhere, p.path,
                      ": not closed (no summary): a shard still running or stopped; see `augrig check`");
  auto st =
      Statement::prepare(db->get(), "SELECT count(*), min(id), max(id), min(t_ns), max(t_ns) FROM frames");
  if (!st) return make_error(kWhere, p.path, ": ", st.error().message);
  if (st->step() != SQLITE_ROW) return make_error(kWhere, p.path, ": the frames table cannot be read");
  p.frames = static_cast<std::size_t>(sqlite3_column_int64(st->get(), 0));
  p.first_id = sqlite3_column_int64(st->get(), 1);
  p.last_id = sqlite3_column_int64(st->get(), 2);
  p.t_first_ns = sqlite3_column_int64(st->get(), 3);
  p.t_last_ns = sqlite3_column_int64(st->get(), 4);
  return p;
}

// The parts, each against the first and its predecessor: one rig, times in order.
Expected<std::vector<Part>> open_parts(const std::vector<std::string>& paths) {
  if (paths.empty()) return make_error(kWhere, "no parts to join");
  std::vector<Part> parts;
  for (const std::string& path : paths) {
    auto p = open_part(path);
    if (!p) return p.error();
    if (!parts.empty()) {
      if (value_of(p->meta, "rig_yaml") != value_of(parts.front().meta, "rig_yaml"))
        return make_error(kWhere, p->path, ": another rig than ", parts.front().path,
                          "'s (the parts of one flight and variant share theirs)");
      const Part* before = nullptr;
      for (const Part& q : parts)
        if (q.frames > 0) before = &q;
      if (p->frames > 0 && before && p->t_first_ns <= before->t_last_ns)
        return make_error(kWhere, p->path, ": its first frame (t_ns ", p->t_first_ns, ") is not after ",
                          before->path, "'s last (", before->t_last_ns,
                          "): the parts overlap or are out of order");
    }
    parts.push_back(std::move(*p));
  }
  return parts;
}

// The columns of a table of the new database, comma-separated, without `skip`.
Expected<std::string> columns(sqlite3* db, const std::string& table, const std::string& skip) {
  auto st = Statement::prepare(db, "PRAGMA main.table_info(" + table + ")");
  if (!st) return st.error();
  std::string out;
  while (st->step() == SQLITE_ROW) {
    const std::string name = reinterpret_cast<const char*>(sqlite3_column_text(st->get(), 1));
    if (name == skip) continue;
    out += (out.empty() ? "" : ", ") + name;
  }
  return out;
}

// Part `p`, attached as `part`, into the new database: frames and depth renumbered by `shift`, the
// rest appended in the part's order (their ids given anew); nav inputs only when `with_nav`.
Status copy_part(Database& db, std::int64_t shift, bool with_nav) {
  const std::string shift_s = std::to_string(shift);
  auto frame_cols = columns(db.get(), "frames", "id");
  auto depth_cols = columns(db.get(), "depth", "frame_id");
  if (!frame_cols) return frame_cols.error();
  if (!depth_cols) return depth_cols.error();
  std::string sql = "INSERT INTO main.frames (id, " + *frame_cols + ") SELECT id + " + shift_s + ", " +
                    *frame_cols + " FROM part.frames ORDER BY id;\n";
  sql += "INSERT INTO main.depth (frame_id, " + *depth_cols + ") SELECT frame_id + " + shift_s + ", " +
         *depth_cols + " FROM part.depth ORDER BY frame_id;\n";
  for (const char* table : {"events", "drops", "look", "nav_input"}) {
    if (std::string(table) == "nav_input" && !with_nav) continue;
    auto cols = columns(db.get(), table, "id");
    if (!cols) return cols.error();
    sql += std::string("INSERT INTO main.") + table + " (" + *cols + ") SELECT " + *cols + " FROM part." +
           table + " ORDER BY id;\n";
  }
  return db.exec(sql);
}

Status attach(Database& db, const std::string& path) {
  auto st = Statement::prepare(db.get(), "ATTACH DATABASE ?1 AS part");
  if (!st) return st.error();
  sqlite3_bind_text(st->get(), 1, path.c_str(), -1, SQLITE_TRANSIENT);
  if (const int rc = st->step(); rc != SQLITE_DONE) return Error{describe_sqlite_error(db.get(), rc)};
  return {};
}

// `path` attached as `part` while `work` runs in a transaction; errors name `path`.
template <typename Work>
Status in_part_transaction(Database& db, const std::string& path, Work work) {
  if (Status s = attach(db, path); !s) return make_error(path, ": ", s.error().message);
  Status s = db.exec("BEGIN");
  if (s) s = work();
  if (s) s = db.exec("COMMIT");
  if (!s) static_cast<void>(db.exec("ROLLBACK"));  // the first error is the one to tell
  Status detached = db.exec("DETACH DATABASE part");
  if (!s) return make_error(path, ": ", s.error().message);
  return detached;
}

Expected<std::int64_t> count(Database& db, const std::string& table) {
  auto t = db.query_text("SELECT count(*) FROM main." + table);
  if (!t) return t.error();
  return std::stoll(*t);
}

// meta: the first part's without its summary, `merged_from`, and the summary of the whole.
Status write_meta(Database& db, const std::vector<Part>& parts, RecordingMergeReport& report) {
  std::map<std::string, std::string> m;
  for (const auto& [k, v] : parts.front().meta)
    if (k.rfind("summary.", 0) != 0) m[k] = v;
  std::string from = std::to_string(parts.size()) + " part(s), in order:";
  for (const Part& p : parts) from += " " + p.path;
  m["merged_from"] = from;
  std::string status = "ok";
  std::map<std::string, std::uint64_t> sums;
  for (const Part& p : parts) {
    const std::string s = value_of(p.meta, "summary.status");
    if (status == "ok" && s != "ok") status = p.path + ": " + s;
    for (const auto& [k, v] : p.meta)
      if (k.rfind("summary.drops.", 0) == 0 || k == "summary.image_bytes" || k == "summary.stored_bytes")
        sums[k] += std::stoull(v.empty() ? "0" : v);
  }
  for (const auto& [k, v] : sums) m[k] = std::to_string(v);
  m["summary.status"] = status;
  m["summary.closed_utc"] = utc_now_iso8601();
  for (const auto& [key, table] : {std::pair<const char*, const char*>{"summary.frames", "frames"},
                                   {"summary.nav_inputs", "nav_input"},
                                   {"summary.events", "events"},
                                   {"summary.look_updates", "look"}}) {
    auto n = count(db, table);
    if (!n) return n.error();
    m[key] = std::to_string(*n);
  }
  report.frames = std::stoull(m["summary.frames"]);
  report.nav_inputs = std::stoull(m["summary.nav_inputs"]);
  report.events = std::stoull(m["summary.events"]);
  report.look_updates = std::stoull(m["summary.look_updates"]);
  auto st = Statement::prepare(db.get(), "INSERT INTO meta (key, value) VALUES (?1, ?2)");
  if (!st) return st.error();
  for (const auto& [k, v] : m) {
    st->reset();
    sqlite3_bind_text(st->get(), 1, k.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(st->get(), 2, v.c_str(), -1, SQLITE_TRANSIENT);
    if (const int rc = st->step(); rc != SQLITE_DONE) return Error{describe_sqlite_error(db.get(), rc)};
  }
  return {};
}

// Everything into `tmp`, in one transaction.
Status write_merged(const std::string& tmp, const std::vector<Part>& parts, const RecordingReader* nav_from,
                    RecordingMergeReport& report) {
  auto db = Database::open(tmp, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
  if (!db) return db.error();
  // The temporary file is the atomicity (renamed only when complete): no journal, a transaction
  // per part (SQLite detaches a database only outside one).
  if (Status s = db->exec("PRAGMA journal_mode = OFF; PRAGMA synchronous = OFF;"); !s) return s;
  if (Status s = db->exec(schema_sql()); !s) return s;
  std::int64_t next_id = 1;  // frames numbered on from the previous part's
  for (const Part& p : parts) {
    const std::int64_t shift = p.frames > 0 ? next_id - p.first_id : 0;
    if (Status s =
            in_part_transaction(*db, p.path, [&] { return copy_part(*db, shift, nav_from == nullptr); });
        !s)
      return s;
    if (p.frames > 0) next_id = p.last_id + shift + 1;
  }
  if (nav_from) {
    const std::string nav_path = database_path(nav_from->path());
    Status s = in_part_transaction(*db, nav_path, [&]() -> Status {
      auto cols = columns(db->get(), "nav_input", "id");
      if (!cols) return cols.error();
      return db->exec("INSERT INTO main.nav_input (" + *cols + ") SELECT " + *cols +
                      " FROM part.nav_input ORDER BY id");
    });
    if (!s) return s;
  }
  if (Status s = db->exec("BEGIN"); !s) return s;
  if (Status s = write_meta(*db, parts, report); !s) return s;
  return db->exec("COMMIT");  // the database closes as this returns, before the sync
}

// The file's bytes on disk before the rename makes it the recording (the writes above are not
// synced: synchronous is off).
Status sync_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return make_error("cannot open to sync: ", std::strerror(errno));
  const int rc = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  if (rc != 0) return make_error("fsync failed: ", std::strerror(err));
  return {};
}

}  // namespace

Status merge_recordings(const std::vector<std::string>& paths, const std::string& out_dir,
                        const RecordingReader* nav_from, RecordingMergeReport& report) {
  report = {};
  auto parts = open_parts(paths);
  if (!parts) return parts.error();
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) return make_error(kWhere, out_dir, ": cannot create the folder: ", ec.message());
  const std::string final_path = database_path(out_dir);
  const std::string tmp = final_path + ".merging";
  fs::remove(tmp, ec);
  Status written = write_merged(tmp, *parts, nav_from, report);
  if (written) written = sync_file(tmp);
  if (Status s = written; !s) {
    fs::remove(tmp, ec);
    return make_error(kWhere, tmp, ": ", s.error().message);
  }
  // An earlier merge's database and its WAL go; the new one takes their place whole.
  for (const char* suffix : {"-wal", "-shm"}) fs::remove(final_path + suffix, ec);
  fs::rename(tmp, final_path, ec);
  if (ec)
    return make_error(kWhere, final_path, ": cannot rename the merged database into place: ", ec.message());
  report.parts = parts->size();
  return {};
}

}  // namespace augrig::recorder
