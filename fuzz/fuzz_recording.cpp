// RecordingReader (recorder/reader.hpp) on damaged rows: every run builds a recording with the
// real schema (recorder/store.hpp) whose one frame, nav input, drop, event and look rows hold values the
// input picks, then opens it, reads everything back and checks it. SQLite's own file format is
// not the target (SQLite is fuzzed upstream); what a row can say to augrig is.
//
// Input: per column (the frames table's, then nav_input's, drops', events' and look's), a tag byte
// and its value: 0 NULL, 1 i64, 2 i16, 3 f64, 4 a known name (pixel format, clock, drop stage, look
// kind or source; index byte), 5 text (length byte), 6 blob (u16 length), 7 blob compressed to a valid zstd frame
// (u16 length), so that the image decoders see frames that pass their header checks.
#include <cstdio>
#include <string>
#include <vector>

#include <sqlite3.h>
#include <zstd.h>

#include "fuzz/fuzz_common.hpp"
#include "recorder/reader.hpp"
#include "recorder/store.hpp"

using namespace augrig;

namespace {

const std::vector<std::string>& known_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v;
    for (PixelFormat f :
         {PixelFormat::kMono8, PixelFormat::kRGB8, PixelFormat::kRGBA8, PixelFormat::kBayerRG8,
          PixelFormat::kBayerGR8, PixelFormat::kBayerGB8, PixelFormat::kBayerBG8})
      v.emplace_back(to_string(f));
    for (ClockDomain c : {ClockDomain::kUnknown, ClockDomain::kHostMonotonic, ClockDomain::kHostRealtime,
                          ClockDomain::kDevice, ClockDomain::kGps, ClockDomain::kSim})
      v.emplace_back(to_string(c));
    for (const char* s : {"camera", "transport", "pairing", "processing", "recorder"}) v.emplace_back(s);
    for (const char* s : {"noise", "light", "estimated", "configured", "ephemeris", "default sun"}) v.emplace_back(s);
    return v;
  }();
  return names;
}

std::vector<std::uint8_t> zstd_frame(std::string_view bytes) {
  std::vector<std::uint8_t> z(ZSTD_compressBound(bytes.size()));
  ZSTD_CCtx* c = ZSTD_createCCtx();
  ZSTD_CCtx_setParameter(c, ZSTD_c_checksumFlag, 1);
  const std::size_t n = ZSTD_compress2(c, z.data(), z.size(), bytes.data(), bytes.size());
  ZSTD_freeCCtx(c);
  z.resize(ZSTD_isError(n) ? 0 : n);
  return z;
}

// Binds parameters 1..count of `st` from the input.
void bind_from(fuzz::Input& in, sqlite3_stmt* st, int count) {
  for (int i = 1; i <= count; ++i) {
    const std::uint8_t tag = in.byte();
    switch (tag % 8) {
      case 0:
        sqlite3_bind_null(st, i);
        break;
      case 1:
        sqlite3_bind_int64(st, i, in.value<std::int64_t>());
        break;
      case 2:
        sqlite3_bind_int64(st, i, in.value<std::int16_t>());
        break;
      case 3:
        sqlite3_bind_double(st, i, in.value<double>());
        break;
      case 4: {
        const std::string& s = known_names()[in.byte() % known_names().size()];
        sqlite3_bind_text(st, i, s.data(), static_cast<int>(s.size()), SQLITE_TRANSIENT);
        break;
      }
      case 5: {
        const std::string_view s = in.bytes(in.byte());
        sqlite3_bind_text(st, i, s.data(), static_cast<int>(s.size()), SQLITE_TRANSIENT);
        break;
      }
      case 6: {
        const std::string_view s = in.bytes(in.value<std::uint16_t>());
        sqlite3_bind_blob(st, i, s.data(), static_cast<int>(s.size()), SQLITE_TRANSIENT);
        break;
      }
      default: {
        const std::vector<std::uint8_t> z = zstd_frame(in.bytes(in.value<std::uint16_t>()));
        sqlite3_bind_blob(st, i, z.data(), static_cast<int>(z.size()), SQLITE_TRANSIENT);
        break;
      }
    }
  }
}

// Inserts one row with `sql`'s parameters from the input; a row SQLite refuses (NOT NULL, CHECK)
// is left out, as a recording could not hold it either.
void insert(fuzz::Input& in, sqlite3* db, const std::string& sql) {
  sqlite3_stmt* st = nullptr;
  if (sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) std::abort();
  bind_from(in, st, sqlite3_bind_parameter_count(st));
  (void)sqlite3_step(st);
  sqlite3_finalize(st);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fuzz::Input in(data, size);
  static const std::string path = fuzz::write_temp("recording.sqlite", "");
  ::unlink(path.c_str());
  sqlite3* db = nullptr;
  if (sqlite3_open(path.c_str(), &db) != SQLITE_OK) std::abort();
  // A scratch file: no journal, no syncs.
  sqlite3_exec(db, "PRAGMA journal_mode=OFF; PRAGMA synchronous=OFF", nullptr, nullptr, nullptr);
  if (sqlite3_exec(db, recorder::schema_sql().c_str(), nullptr, nullptr, nullptr) != SQLITE_OK) std::abort();
  const std::string version = "INSERT INTO meta VALUES ('schema_version', '" + std::to_string(recorder::kSchemaVersion) + "')";
  sqlite3_exec(db, version.c_str(), nullptr, nullptr, nullptr);
  insert(in, db, recorder::frame_insert_sql());
  insert(in, db, "INSERT INTO nav_input (stream, t_ns, clock, arrival_ns, data) VALUES (?, ?, ?, ?, ?)");
  insert(in, db,
         "INSERT INTO drops (stage, item, count, first_t_ns, last_t_ns, reason) VALUES (?, ?, ?, ?, ?, ?)");
  insert(in, db, "INSERT INTO events (t_ns, clock, text) VALUES (?, ?, ?)");
  insert(in, db, recorder::look_insert_sql());
  sqlite3_close(db);

  auto reader = recorder::RecordingReader::open(path);
  if (!reader) {
    if (fuzz::verbose()) std::fprintf(stderr, "open: %s\n", reader.error().message.c_str());
    return 0;
  }
  for (std::size_t i = 0; i < (*reader)->frame_count(); ++i) {
    const auto f = (*reader)->read_frame(i, recorder::kPartsAll);
    if (fuzz::verbose()) std::fprintf(stderr, "frame %zu: %s\n", i, f ? "ok" : f.error().message.c_str());
    (void)(*reader)->read_frame_info(i);
  }
  const auto nav = (*reader)->nav_inputs();
  const auto drops = (*reader)->drops();
  const auto events = (*reader)->events();
  const auto look = (*reader)->look();
  if (fuzz::verbose() && !look) std::fprintf(stderr, "look: %s\n", look.error().message.c_str());
  const std::string report = (*reader)->check().to_string();
  if (fuzz::verbose())
    std::fprintf(stderr, "nav inputs %zu, drops %zu, events %zu\n%s\n", nav ? nav->size() : 0,
                 drops ? drops->size() : 0, events ? events->size() : 0, report.c_str());
  return 0;
}
