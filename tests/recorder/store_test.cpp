// The SQLite side: the schema as documented (the statistics columns carry render/stats' names),
// a frames row through INSERT and SELECT unchanged (optional groups, NaN), a recording of schema 2
// (no shadow columns) read with its shadow as 0, the `look` row both ways and its errors naming the
// column, and SQLite errors described with their code.
#include "recorder/store.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>

#include <gtest/gtest.h>

#include "tests/support/test_support.hpp"

namespace augrig::recorder {
namespace {

Database fresh_db(const std::string& name) {
  const std::string dir = test::output_dir("recorder_store/" + name);
  auto db = Database::open(dir + "/t.sqlite", SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
  EXPECT_TRUE(db) << db.error().message;
  return std::move(*db);
}

std::vector<std::string> table_columns(Database& db, const std::string& table) {
  auto st = Statement::prepare(db.get(), "PRAGMA table_info(" + table + ")");
  EXPECT_TRUE(st);
  std::vector<std::string> cols;
  while (st->step() == SQLITE_ROW)
    cols.emplace_back(reinterpret_cast<const char*>(sqlite3_column_text(st->get(), 1)));
  return cols;
}

TEST(Store, DatabasePath) {
  const std::string dir = test::output_dir("recorder_store/path");
  EXPECT_EQ(database_path(dir), dir + "/recording.sqlite");
  EXPECT_EQ(database_path(dir + "/x.sqlite"), dir + "/x.sqlite");
}

TEST(Store, SchemaHasTheDocumentedTables) {
  Database db = fresh_db("schema");
  ASSERT_TRUE(db.exec(schema_sql()));
  EXPECT_EQ(table_columns(db, "meta"), (std::vector<std::string>{"key", "value"}));
  EXPECT_EQ(table_columns(db, "nav_input"),
            (std::vector<std::string>{"id", "stream", "t_ns", "clock", "arrival_ns", "data"}));
  EXPECT_EQ(table_columns(db, "drops"),
            (std::vector<std::string>{"id", "stage", "item", "count", "first_t_ns", "last_t_ns", "reason"}));
  EXPECT_EQ(table_columns(db, "events"), (std::vector<std::string>{"id", "t_ns", "clock", "text"}));
  EXPECT_EQ(table_columns(db, "look"),
            (std::vector<std::string>{"id",       "t_ns",     "clock",    "kind",     "source",  "camera",
                                      "channels", "a0",       "a1",       "a2",       "b0",      "b1",
                                      "b2",       "frames",   "note",     "direct_r", "direct_g", "direct_b",
                                      "sky_r",    "sky_g",    "sky_b",    "ground_r", "ground_g", "ground_b",
                                      "samples",  "rms",      "sun_up",   "sun_x",    "sun_y",   "sun_z"}));
  std::vector<std::string> frames = frame_column_names();
  frames.insert(frames.begin(), "id");
  EXPECT_EQ(table_columns(db, "frames"), frames);
  EXPECT_EQ(table_columns(db, "depth"),
            (std::vector<std::string>{"frame_id", "left_x0", "left_y0", "left_x1", "left_y1", "left_depth",
                                      "right_x0", "right_y0", "right_x1", "right_y1", "right_depth"}));
  // The blobs come last, so that the small columns never need a blob's overflow pages.
  const std::vector<std::string> tail(frames.end() - 6, frames.end());
  EXPECT_EQ(tail, (std::vector<std::string>{"left_mask", "right_mask", "left_aug", "right_aug", "left_raw",
                                            "right_raw"}));
  // A stage outside the five is refused.
  EXPECT_FALSE(
      db.exec("INSERT INTO drops (stage, item, count, first_t_ns, last_t_ns, reason) "
              "VALUES ('elsewhere', 'frame', 1, 0, 0, 'x')"));
}

TEST(Store, StatisticsColumnsAreNamedAsInStatsCsv) {
  std::ostringstream header;
  write_stats_csv_header(header);
  std::string h = header.str();
  h.pop_back();  // '\n'
  const std::vector<std::string> names = frame_column_names();
  const std::set<std::string> have(names.begin(), names.end());
  std::istringstream in(h);
  std::string col;
  int n = 0;
  while (std::getline(in, col, ',')) {
    const std::string expect = col == "t_ns" ? "stats_t_ns" : col;  // frames has its own t_ns
    EXPECT_TRUE(have.count(expect)) << expect;
    ++n;
  }
  EXPECT_EQ(n, 23);
  // The shadow counts came with schema 3, appended as in stats.csv.
  const std::vector<std::string> shadow = {"shadow_px_left", "shadow_px_right", "shadow_pct_left",
                                           "shadow_pct_right"};
  EXPECT_EQ(frame_columns_added_after(2), shadow);
  EXPECT_EQ(frame_columns_added_after(1), shadow);
  EXPECT_TRUE(frame_columns_added_after(kSchemaVersion).empty());
  const auto at = std::find(names.begin(), names.end(), "boom_pct_right");
  ASSERT_NE(at, names.end());
  EXPECT_EQ(std::vector<std::string>(at + 1, at + 5), shadow);
}

TEST(Store, FrameRowRoundTrip) {
  Database db = fresh_db("row");
  ASSERT_TRUE(db.exec(schema_sql()));
  auto ins = Statement::prepare(db.get(), frame_insert_sql());
  ASSERT_TRUE(ins) << ins.error().message;

  const std::vector<std::uint8_t> bytes = {1, 2, 3, 0, 255};
  FrameRow full;
  full.pair_sequence = 0x7fffffffffffffffull;
  full.t_ns = -5;
  full.skew_ns = 123;
  full.cam[0] = {7, 1000, ClockDomain::kDevice, 2000, 3000, PixelFormat::kBayerGB8, 1280, 960, {1, 2, 3, 4}};
  full.cam[1] = {8, 1001, ClockDomain::kGps, 0, 0, PixelFormat::kRGBA8, 640, 480, {}};
  full.T_cam_receiver[0] = Pose::from(Eigen::Matrix3d::Identity(), {1.0 / 3, -2.5, 1e-17});
  full.T_body_receiver = pose_from_ypr({-22, 0.5, 9}, 0.1, -0.2, 0.3);
  full.receiver_present = false;
  full.sigma_pos_m = 0.02;  // sigma_att_deg stays NaN
  full.boom = BoomArticulation{0.5, -0.01, 3.25};
  full.stats = OcclusionStats{};
  full.stats->t_ns = 42;
  full.stats->boom_px_left = 99;
  full.stats->occluded_pct_right = 12.5;
  full.stats->shadow_px_left = 321;
  full.stats->shadow_px_right = 7;
  full.stats->shadow_pct_left = 100.0 / 3.0;
  full.stats->shadow_pct_right = 0.25;
  full.raw[0] = {bytes.data(), bytes.size(), true};
  full.raw[1] = {bytes.data(), 2, true};
  full.aug[0] = {nullptr, 0, true};  // empty blob: nothing changed
  full.mask[1] = {bytes.data() + 1, 3, true};
  ASSERT_TRUE(bind_frame_row(ins->get(), full));
  ASSERT_EQ(ins->step(), SQLITE_DONE);
  ins->reset();
  FrameRow bare;
  bare.cam[0].format = bare.cam[1].format = PixelFormat::kMono8;
  bare.raw[0] = bare.raw[1] = {bytes.data(), 1, true};
  ASSERT_TRUE(bind_frame_row(ins->get(), bare));
  ASSERT_EQ(ins->step(), SQLITE_DONE);

  auto sel = Statement::prepare(db.get(), frame_select_sql(kPartsAll) + " ORDER BY id");
  ASSERT_TRUE(sel);
  ASSERT_EQ(sel->step(), SQLITE_ROW);
  FrameRow r;
  ASSERT_TRUE(read_frame_row(sel->get(), r));
  EXPECT_EQ(r.id, 1);
  EXPECT_EQ(r.pair_sequence, full.pair_sequence);
  EXPECT_EQ(r.t_ns, -5);
  EXPECT_EQ(r.skew_ns, 123);
  for (int c = 0; c < 2; ++c) {
    EXPECT_EQ(r.cam[c].sequence, full.cam[c].sequence);
    EXPECT_EQ(r.cam[c].t_ns, full.cam[c].t_ns);
    EXPECT_EQ(r.cam[c].clock, full.cam[c].clock);
    EXPECT_EQ(r.cam[c].t_host_ns, full.cam[c].t_host_ns);
    EXPECT_EQ(r.cam[c].exposure_ns, full.cam[c].exposure_ns);
    EXPECT_EQ(r.cam[c].format, full.cam[c].format);
    EXPECT_EQ(r.cam[c].width, full.cam[c].width);
    EXPECT_EQ(r.cam[c].height, full.cam[c].height);
    EXPECT_EQ(r.cam[c].aug_box, full.cam[c].aug_box);
  }
  ASSERT_TRUE(r.T_cam_receiver[0]);
  EXPECT_FALSE(r.T_cam_receiver[1]);
  EXPECT_EQ(r.T_cam_receiver[0]->translation_m, full.T_cam_receiver[0]->translation_m);
  ASSERT_TRUE(r.T_body_receiver);
  EXPECT_EQ(r.T_body_receiver->rotation.coeffs(), full.T_body_receiver->rotation.coeffs());
  EXPECT_EQ(r.T_body_receiver->translation_m, full.T_body_receiver->translation_m);
  ASSERT_TRUE(r.receiver_present);
  EXPECT_FALSE(*r.receiver_present);
  EXPECT_EQ(r.sigma_pos_m, 0.02);
  EXPECT_TRUE(std::isnan(r.sigma_att_deg));
  ASSERT_TRUE(r.boom);
  EXPECT_EQ(r.boom->extension_m, 3.25);
  EXPECT_EQ(r.boom->azimuth_rad, -0.01);
  ASSERT_TRUE(r.stats);
  EXPECT_EQ(r.stats->t_ns, 42);
  EXPECT_EQ(r.stats->boom_px_left, 99);
  EXPECT_EQ(r.stats->occluded_pct_right, 12.5);
  EXPECT_EQ(*r.stats, *full.stats);
  ASSERT_TRUE(r.raw[0].present);
  EXPECT_EQ(std::vector<std::uint8_t>(r.raw[0].data, r.raw[0].data + r.raw[0].size), bytes);
  EXPECT_EQ(r.raw[1].size, 2u);
  EXPECT_TRUE(r.aug[0].present);
  EXPECT_EQ(r.aug[0].size, 0u);
  EXPECT_FALSE(r.aug[1].present);
  EXPECT_FALSE(r.mask[0].present);
  EXPECT_EQ(r.mask[1].size, 3u);

  ASSERT_EQ(sel->step(), SQLITE_ROW);
  ASSERT_TRUE(read_frame_row(sel->get(), r));
  EXPECT_EQ(r.id, 2);
  EXPECT_FALSE(r.T_cam_receiver[0] || r.T_cam_receiver[1] || r.T_body_receiver || r.receiver_present ||
               r.boom || r.stats);
  EXPECT_TRUE(std::isnan(r.sigma_pos_m));
  EXPECT_FALSE(r.mask[0].present || r.aug[1].present);

  // Selecting without blobs leaves them NULL and keeps every other column.
  auto meta_only = Statement::prepare(db.get(), frame_select_sql(kPartsNone) + " WHERE id = 1");
  ASSERT_TRUE(meta_only);
  ASSERT_EQ(meta_only->step(), SQLITE_ROW);
  ASSERT_TRUE(read_frame_row(meta_only->get(), r));
  EXPECT_FALSE(r.raw[0].present);
  EXPECT_EQ(r.cam[0].width, 1280);
}

// A recording of schema 2 has no shadow columns: its frames read with the shadow counts 0 and
// everything else as stored; read as the current schema it fails naming the missing column.
TEST(Store, SchemaTwoFramesReadTheShadowAsZero) {
  Database db = fresh_db("schema2");
  ASSERT_TRUE(db.exec(schema_sql()));
  auto ins = Statement::prepare(db.get(), frame_insert_sql());
  ASSERT_TRUE(ins) << ins.error().message;
  const std::vector<std::uint8_t> bytes = {9, 8, 7};
  FrameRow row;
  row.cam[0].format = row.cam[1].format = PixelFormat::kMono8;
  row.raw[0] = row.raw[1] = {bytes.data(), bytes.size(), true};
  row.stats = OcclusionStats{};
  row.stats->receiver_px_left = 1234;
  row.stats->boom_pct_right = 2.5;
  row.stats->shadow_px_left = 55;
  row.stats->shadow_pct_right = 4.5;
  ASSERT_TRUE(bind_frame_row(ins->get(), row));
  ASSERT_EQ(ins->step(), SQLITE_DONE);
  for (const std::string& c : frame_columns_added_after(2))
    ASSERT_TRUE(db.exec("ALTER TABLE frames DROP COLUMN " + c)) << c;

  auto sel = Statement::prepare(db.get(), frame_select_sql(kPartsAll, 2));
  ASSERT_TRUE(sel) << sel.error().message;
  ASSERT_EQ(sel->step(), SQLITE_ROW);
  FrameRow r;
  ASSERT_TRUE(read_frame_row(sel->get(), r));
  ASSERT_TRUE(r.stats);
  OcclusionStats want = *row.stats;
  want.shadow_px_left = 0;
  want.shadow_pct_right = 0;
  EXPECT_EQ(*r.stats, want);
  EXPECT_EQ(std::vector<std::uint8_t>(r.raw[1].data, r.raw[1].data + r.raw[1].size), bytes);

  auto current = Statement::prepare(db.get(), frame_select_sql(kPartsAll));
  ASSERT_FALSE(current);
  EXPECT_NE(current.error().message.find("no such column: shadow_px_left"), std::string::npos)
      << current.error().message;
}

// The single value of a query ("" when it fails).
std::string query(Database& db, const std::string& sql) {
  auto v = db.query_text(sql);
  EXPECT_TRUE(v) << sql << ": " << v.error().message;
  return v ? *v : std::string();
}

LookRecord noise_update() {
  LookNoise n;
  n.camera = 1;
  n.nlf = {3, {0.21, 0.19, 1.0 / 3.0}, {1.9, 2.0, 0.0}};
  n.frames = 12;
  n.note = "one level only";
  return {1'000'000'007, ClockDomain::kGps, n};
}

LookRecord light_update() {
  LookLight l;
  l.direct = {0.61, 0.62, 0.63};
  l.sky = {0.2, 0.25, 0.4};
  l.ground = {0.3, 0.28, 0.2};
  l.samples = 648;
  l.rms = 0.012;
  l.source = LightSource::kEphemeris;
  l.sun_up = true;
  l.towards_sun_body = Eigen::Vector3d(0.3, -0.2, -1.0).normalized();
  return {-5, ClockDomain::kSim, l};
}

void expect_same_look(const LookRecord& a, const LookRecord& b) {
  EXPECT_EQ(a.t_ns, b.t_ns);
  EXPECT_EQ(a.clock, b.clock);
  ASSERT_EQ(a.update.index(), b.update.index());
  if (const auto* n = std::get_if<LookNoise>(&a.update)) {
    const LookNoise& m = std::get<LookNoise>(b.update);
    EXPECT_EQ(n->camera, m.camera);
    EXPECT_EQ(n->nlf, m.nlf);
    EXPECT_EQ(n->configured, m.configured);
    EXPECT_EQ(n->frames, m.frames);
    EXPECT_EQ(n->note, m.note);
  } else {
    const LookLight& l = std::get<LookLight>(a.update);
    const LookLight& k = std::get<LookLight>(b.update);
    EXPECT_EQ(l.direct, k.direct);
    EXPECT_EQ(l.sky, k.sky);
    EXPECT_EQ(l.ground, k.ground);
    EXPECT_EQ(l.samples, k.samples);
    EXPECT_TRUE(l.rms == k.rms || (std::isnan(l.rms) && std::isnan(k.rms)));
    EXPECT_EQ(l.source, k.source);
    EXPECT_EQ(l.sun_up, k.sun_up);
    EXPECT_EQ(l.towards_sun_body, k.towards_sun_body);
  }
}

// Both kinds of `look` row through INSERT and SELECT unchanged, the other kind's columns NULL.
TEST(Store, LookRowRoundTrip) {
  Database db = fresh_db("look");
  ASSERT_TRUE(db.exec(schema_sql()));
  auto ins = Statement::prepare(db.get(), look_insert_sql());
  ASSERT_TRUE(ins) << ins.error().message;
  LookRecord grey = noise_update();
  std::get<LookNoise>(grey.update) = {0, {1, {0.5, 0, 0}, {3.0, 0, 0}}, true, 0, ""};
  LookRecord dark = light_update();
  auto& l = std::get<LookLight>(dark.update);
  l.sun_up = false;
  l.direct = Eigen::Vector3d::Zero();
  l.source = LightSource::kDefaultSun;
  l.rms = FrameRecord::kNaN;
  const std::vector<LookRecord> sent = {noise_update(), light_update(), grey, dark};
  for (const LookRecord& r : sent) {
    ASSERT_TRUE(bind_look_row(ins->get(), r));
    ASSERT_EQ(ins->step(), SQLITE_DONE);
    ins->reset();
  }
  EXPECT_EQ(query(db, "SELECT count(*) FROM look WHERE kind = 'noise' AND direct_r IS NULL AND sun_up IS NULL"),
            "2");
  EXPECT_EQ(query(db, "SELECT count(*) FROM look WHERE kind = 'light' AND camera IS NULL AND a0 IS NULL"), "2");
  EXPECT_EQ(query(db, "SELECT a1 IS NULL FROM look WHERE channels = 1"), "1");  // grey: one channel
  EXPECT_EQ(query(db, "SELECT group_concat(source, ',') FROM look"), "estimated,ephemeris,configured,default sun");

  auto sel = Statement::prepare(db.get(), look_select_sql());
  ASSERT_TRUE(sel) << sel.error().message;
  for (const LookRecord& want : sent) {
    ASSERT_EQ(sel->step(), SQLITE_ROW);
    LookRecord got;
    ASSERT_TRUE(read_look_row(sel->get(), got));
    expect_same_look(want, got);
  }
  EXPECT_EQ(sel->step(), SQLITE_DONE);
  // A noise level function of 2 channels is not one.
  LookRecord two = noise_update();
  std::get<LookNoise>(two.update).nlf.channels = 2;
  const Status s = bind_look_row(ins->get(), two);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message, "binding look columns: a noise level function of 2 channels (expected 1 or 3)");
}

// A `look` row that is not what the recorder writes fails with the column and what it holds.
TEST(Store, BadLookValuesAreNamed) {
  Database db = fresh_db("look_bad");
  ASSERT_TRUE(db.exec(schema_sql()));
  auto ins = Statement::prepare(db.get(), look_insert_sql());
  for (const LookRecord& r : {noise_update(), light_update()}) {
    ASSERT_TRUE(bind_look_row(ins->get(), r));
    ASSERT_EQ(ins->step(), SQLITE_DONE);
    ins->reset();
  }
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"UPDATE look SET channels = 2 WHERE kind = 'noise'", "column channels: 2 channels (expected 1 or 3)"},
      {"UPDATE look SET channels = 4 WHERE kind = 'noise'", "column channels: 4 is outside 1..3"},
      {"UPDATE look SET a2 = NULL WHERE kind = 'noise'", "column a2: expected a number, got NULL"},
      {"UPDATE look SET source = 'guessed' WHERE kind = 'noise'",
       "column source: \"guessed\" is neither configured nor estimated"},
      {"UPDATE look SET camera = 'left' WHERE kind = 'noise'", "column camera: expected an integer, got text"},
      {"UPDATE look SET clock = 'mars' WHERE kind = 'noise'", "column clock: unknown clock domain \"mars\""},
      {"UPDATE look SET source = 'moon' WHERE kind = 'light'", "column source: unknown light source \"moon\""},
      {"UPDATE look SET sky_g = 'bright' WHERE kind = 'light'", "column sky_g: expected a number, got text"},
      {"UPDATE look SET sun_up = 2 WHERE kind = 'light'", "column sun_up: 2 is outside 0..1"},
  };
  for (const auto& [sql, want] : cases) {
    SCOPED_TRACE(sql);
    ASSERT_TRUE(db.exec("BEGIN"));
    ASSERT_TRUE(db.exec(sql));
    std::string got;
    {
      auto sel = Statement::prepare(db.get(), look_select_sql());
      ASSERT_TRUE(sel);
      while (sel->step() == SQLITE_ROW && got.empty()) {
        LookRecord r;
        if (const Status s = read_look_row(sel->get(), r); !s) got = s.error().message;
      }
    }
    EXPECT_EQ(got, want);
    ASSERT_TRUE(db.exec("ROLLBACK"));
  }
  // The table refuses a kind it does not know.
  EXPECT_FALSE(db.exec("UPDATE look SET kind = 'exposure'"));
}

TEST(Store, BadColumnValuesAreNamed) {
  Database db = fresh_db("bad");
  ASSERT_TRUE(db.exec(schema_sql()));
  auto ins = Statement::prepare(db.get(), frame_insert_sql());
  FrameRow row;
  ASSERT_TRUE(bind_frame_row(ins->get(), row));
  ASSERT_EQ(ins->step(), SQLITE_DONE);
  ASSERT_TRUE(db.exec("UPDATE frames SET right_format = 'YUV422'"));
  auto sel = Statement::prepare(db.get(), frame_select_sql(kPartsAll));
  ASSERT_EQ(sel->step(), SQLITE_ROW);
  FrameRow r;
  const Status s = read_frame_row(sel->get(), r);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message, "column right_format: unknown pixel format \"YUV422\"");
}

TEST(Store, ErrorsNameTheSqliteCode) {
  Database db = fresh_db("full");
  ASSERT_TRUE(db.exec("PRAGMA page_size=4096; CREATE TABLE t (b BLOB); PRAGMA max_page_count=4;"));
  const Status s = db.exec("INSERT INTO t VALUES (zeroblob(100000))");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("SQLITE_FULL"), std::string::npos) << s.error().message;
  auto bad = Database::open(test::output_dir("recorder_store/none") + "/no/such/dir/x.sqlite",
                            SQLITE_OPEN_READWRITE);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("x.sqlite: cannot open: "), std::string::npos) << bad.error().message;
  EXPECT_NE(bad.error().message.find("SQLITE_CANTOPEN"), std::string::npos) << bad.error().message;
}

}  // namespace
}  // namespace augrig::recorder
