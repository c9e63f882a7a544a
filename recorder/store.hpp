// store: the SQLite side of a recording, shared by the Recorder and the RecordingReader: the
// schema (version kSchemaVersion, docs/RECORDING.md), small RAII wrappers around sqlite3 handles,
// and the one definition of the `frames` row, from which the CREATE TABLE, the INSERT and the
// SELECT are all generated so that they cannot disagree; the `depth` row (schema version 2) and the
// `look` row (schema version 3) beside it.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <sqlite3.h>

#include "core/expected.hpp"
#include "recorder/codec.hpp"
#include "recorder/record.hpp"

namespace augrig::recorder {

// 2: the `depth` table (receiver depth per frame, when recorded). A version 1 recording has no
// such table and is read as holding no depth.
// 3: the four shadow counts of the statistics in `frames` (shadow_px_left ... shadow_pct_right) and
// the `look` table. An older recording has neither: its shadow counts read 0, its look updates none.
inline constexpr int kSchemaVersion = 3;
inline constexpr std::string_view kDatabaseFile = "recording.sqlite";

// Now in UTC, "2026-12-07T21:30:00Z" (meta created_utc, summary.closed_utc).
std::string utc_now_iso8601();

// DIR/recording.sqlite for a folder; a path that is not a folder is returned as it is.
std::string database_path(const std::string& dir_or_file);

// "database or disk is full (SQLITE_FULL)", with the OS error where SQLite saw one
// ("disk I/O error (SQLITE_IOERR_WRITE, errno 27: File too large)").
std::string describe_sqlite_error(sqlite3* db, int rc);

class Database {
 public:
  Database() = default;
  Database(Database&& o) noexcept : db_(o.db_) { o.db_ = nullptr; }
  Database& operator=(Database&& o) noexcept;
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;
  ~Database() { close(); }

  // SQLITE_OPEN_* flags. The error names the path.
  static Expected<Database> open(const std::string& path, int flags);
  sqlite3* get() const { return db_; }
  // Runs SQL without results; the error is describe_sqlite_error() of the failing statement.
  Status exec(std::string_view sql);
  // The text of a single-value query ("PRAGMA journal_mode=WAL" -> "wal").
  Expected<std::string> query_text(std::string_view sql);
  int close();  // sqlite3_close_v2's result; 0 when not open

 private:
  sqlite3* db_ = nullptr;
};

class Statement {
 public:
  Statement() = default;
  Statement(Statement&& o) noexcept : st_(o.st_) { o.st_ = nullptr; }
  Statement& operator=(Statement&& o) noexcept;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  ~Statement() { sqlite3_finalize(st_); }

  static Expected<Statement> prepare(sqlite3* db, std::string_view sql);
  sqlite3_stmt* get() const { return st_; }
  int step() { return sqlite3_step(st_); }
  void reset() {
    sqlite3_reset(st_);
    sqlite3_clear_bindings(st_);
  }

 private:
  sqlite3_stmt* st_ = nullptr;
};

// The CREATE statements of the schema (tables meta, frames, depth, nav_input, drops, events, look).
std::string schema_sql();
// Column names of `frames` in table order (without id), for docs and tests.
std::vector<std::string> frame_column_names();
// The columns of `frames` that a recording of `schema_version` lacks (added by a later version),
// in table order: frame_select_sql() reads them as 0 there.
std::vector<std::string> frame_columns_added_after(int schema_version);

// A blob in a row: for writing, the bytes to bind (`present` false: NULL); for reading, the
// bytes SQLite returned, valid until the statement steps or resets.
struct BlobRef {
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
  bool present = false;
};

struct CameraRow {
  std::uint64_t sequence = 0;
  TimestampNs t_ns = 0;
  ClockDomain clock = ClockDomain::kUnknown;
  TimestampNs t_host_ns = 0;
  std::int64_t exposure_ns = 0;
  PixelFormat format = PixelFormat::kMono8;
  int width = 0;
  int height = 0;
  ChangedBox aug_box;
};

// One row of `frames`: everything of a FrameRecord except the images, plus the blobs.
struct FrameRow {
  std::int64_t id = 0;  // read only
  std::uint64_t pair_sequence = 0;
  TimestampNs t_ns = 0;
  std::int64_t skew_ns = 0;
  std::array<CameraRow, 2> cam;
  std::array<std::optional<Pose>, 2> T_cam_receiver;
  std::optional<Pose> T_body_receiver;
  std::optional<bool> receiver_present;
  double sigma_pos_m = FrameRecord::kNaN;
  double sigma_att_deg = FrameRecord::kNaN;
  std::optional<BoomArticulation> boom;
  std::optional<OcclusionStats> stats;
  std::array<BlobRef, 2> mask, aug, raw;
};

// "INSERT INTO frames (...) VALUES (?, ...)" and the matching binder.
std::string frame_insert_sql();
Status bind_frame_row(sqlite3_stmt* st, const FrameRow& row);
// "SELECT id, ... FROM frames" (no WHERE), fetching the blobs of `parts` (FrameParts, record.hpp;
// the others come back NULL), and the matching reader for a row it returned. Errors name the column.
// `schema_version`: the recording's; the columns added after it are selected as 0 (an older
// recording's shadow counts read 0).
std::string frame_select_sql(unsigned parts, int schema_version = kSchemaVersion);
Status read_frame_row(sqlite3_stmt* st, FrameRow& row);

// One row of `depth`: a frame's receiver depth (record.hpp DepthRecord), in its own table so that
// reading the frames never walks the depth blobs and a recording made before it (version 1)
// reads as it did. `frame_id` is the frame's frames.id (inserted in the frame's transaction).
// Per camera (0 left, 1 right): the box [x0, x1) x [y0, y1) and the depth blob (codec.hpp), both
// NULL when that camera's depth was not recorded.
struct DepthRow {
  std::int64_t frame_id = 0;
  std::array<std::optional<PixelBox>, 2> box;
  std::array<BlobRef, 2> blob;
};
// "INSERT INTO depth (...) VALUES (...)" and its binder; "SELECT ... FROM depth WHERE frame_id = ?"
// and the reader of its row. Errors name the column.
std::string depth_insert_sql();
Status bind_depth_row(sqlite3_stmt* st, const DepthRow& row);
std::string depth_select_sql();
Status read_depth_row(sqlite3_stmt* st, DepthRow& row);

// The `look` table (schema version 3): one row per update of the camera look (record.hpp
// LookRecord), a camera's noise level function or the light measured on the receiver; the columns
// of the other kind are NULL. "INSERT INTO look (...) VALUES (...)" and its binder; "SELECT ... FROM
// look ORDER BY id" and the reader of its row, whose errors name the column and what it holds.
std::string look_insert_sql();
Status bind_look_row(sqlite3_stmt* st, const LookRecord& row);
std::string look_select_sql();
Status read_look_row(sqlite3_stmt* st, LookRecord& row);

}  // namespace augrig::recorder
