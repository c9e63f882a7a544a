// The RecordingReader on damaged and foreign files: bytes overwritten in the middle of the
// database and a truncated database give per-frame errors naming the file and the frame while the
// intact frames still read bit-exact; files that are no recording at all fail open() with an error
// naming the file; check() reports what a recording holds. Recorded receiver depth: damage is
// reported naming the frame; a recording of schema 1 (no depth table) still reads and checks. The
// look table reads back in order and is counted; a recording of schema 2 (no shadow columns, no
// look table) reads its shadow as 0; a damaged look row is an error naming the row and the column.
#include "recorder/reader.hpp"

#include <filesystem>
#include <fstream>
#include <cstring>
#include <random>

#include <gtest/gtest.h>

#include "recorder/recorder.hpp"
#include "recorder/store.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::recorder {
namespace {

namespace fs = std::filesystem;

Image random_bayer(int w, int h, std::uint64_t seed) {
  Image img(w, h, PixelFormat::kBayerRG8);
  std::mt19937_64 rng(seed);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img.row(y)[x] = static_cast<std::uint8_t>(rng());
  return img;
}

FrameRecord frame(std::uint64_t i) {
  FrameRecord r;
  r.raw.pair_sequence = i;
  r.raw.t_key_ns = 1'000'000'000 + static_cast<TimestampNs>(i) * 40'000'000;
  r.raw.left.t_ns = r.raw.right.t_ns = r.raw.t_key_ns;
  r.raw.left.clock = r.raw.right.clock = ClockDomain::kSim;
  r.raw.right.camera = CameraId::kRight;
  // Incompressible 256x256 images: each frame spans a few 64 KiB pages, so damage stays local.
  r.raw.left.image = random_bayer(256, 256, 2 * i);
  r.raw.right.image = random_bayer(256, 256, 2 * i + 1);
  r.mask[0] = Image(256, 256, PixelFormat::kMono8);
  r.mask[0].row(100)[100] = kMaskBoom;
  return r;
}

// A closed recording of `n` frames (about 128 KiB each) in test-output/reader/<name>.
std::string make_recording(const std::string& name, int n) {
  const std::string dir = test::output_dir("reader/" + name);
  auto rec = Recorder::create(dir, RecordingInfo{});
  EXPECT_TRUE(rec) << rec.error().message;
  for (int i = 0; i < n; ++i) EXPECT_TRUE((*rec)->push(frame(static_cast<std::uint64_t>(i))));
  (*rec)->push(NavInputRecord{"gps", 5, ClockDomain::kGps, 6, "$GPHDT,274.07,T*03", false});
  (*rec)->push(EventRecord{7, ClockDomain::kHostMonotonic, "start"});
  EXPECT_TRUE((*rec)->close());
  EXPECT_FALSE(fs::exists(dir + "/recording.sqlite-wal"));
  return dir;
}

// Every frame either reads bit-exact or fails with an error naming the file and the frame.
// Returns how many read.
std::size_t read_all(const RecordingReader& rd, std::vector<std::string>* errors) {
  std::size_t good = 0;
  for (std::size_t i = 0; i < rd.frame_count(); ++i) {
    auto f = rd.read_frame(i);
    if (!f) {
      EXPECT_EQ(f.error().message.rfind("recorder::RecordingReader::read_frame(): " + rd.path() + ": frame " +
                                            std::to_string(i) + ": ",
                                        0),
                0u)
          << f.error().message;
      errors->push_back(f.error().message);
      continue;
    }
    const FrameRecord want = frame(f->raw.pair_sequence);
    EXPECT_TRUE(pixels_equal(f->raw.left.image, want.raw.left.image)) << "frame " << i;
    EXPECT_TRUE(pixels_equal(f->raw.right.image, want.raw.right.image)) << "frame " << i;
    EXPECT_TRUE(pixels_equal(f->mask[0], want.mask[0])) << "frame " << i;
    ++good;
  }
  return good;
}

TEST(RecordingReader, BytesOverwrittenInTheMiddle) {
  const std::string dir = make_recording("overwritten", 40);
  const std::string db = dir + "/recording.sqlite";
  const auto size = fs::file_size(db);
  ASSERT_GT(size, 4u << 20);
  {
    std::fstream f(db, std::ios::in | std::ios::out | std::ios::binary);
    std::mt19937 rng(3);
    std::string junk(3000, '\0');
    for (char& c : junk) c = static_cast<char>(rng());
    f.seekp(static_cast<std::streamoff>(size / 2));
    f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
  }
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  std::vector<std::string> errors;
  const std::size_t good = read_all(**rd, &errors);
  EXPECT_GE(good, 30u) << "the damage covers 3000 bytes, at most a frame or two";
  EXPECT_GE(errors.size() + (*rd)->problems().size(), 1u) << "the damage must be found";
  const CheckReport report = (*rd)->check();
  EXPECT_FALSE(report.ok());
  EXPECT_EQ(report.frames_ok, good);
  EXPECT_NE(report.to_string().find(db), std::string::npos) << report.to_string();
}

TEST(RecordingReader, DamagedBlobIsAnErrorForThatFrameOnly) {
  const std::string dir = make_recording("blob", 6);
  const std::string db = dir + "/recording.sqlite";
  {
    // Damage frame 3's right raw blob in place through SQLite (a bit flip in its zstd payload).
    auto d = Database::open(db, SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(d);
    ASSERT_TRUE(
        d->exec("UPDATE frames SET right_raw = CAST(substr(right_raw, 1, 5000) || x'00' || "
                "substr(right_raw, 5002) AS BLOB) WHERE pair_sequence = 3"));
  }
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  std::vector<std::string> errors;
  EXPECT_EQ(read_all(**rd, &errors), 5u);
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("frame 3: right raw blob (pair_sequence 3): zstd"), std::string::npos)
      << errors[0];
  const CheckReport report = (*rd)->check();
  ASSERT_EQ(report.problems.size(), 1u) << report.to_string();
  EXPECT_EQ(report.problems[0], errors[0]);
  EXPECT_EQ(report.frames, 6u);
  EXPECT_EQ(report.frames_ok, 5u);
  // Metadata of the damaged frame still reads.
  auto info = (*rd)->read_frame_info(3);
  ASSERT_TRUE(info) << info.error().message;
  EXPECT_EQ(info->raw.pair_sequence, 3u);
}

TEST(RecordingReader, TruncatedFile) {
  const std::string dir = make_recording("truncated", 40);
  const std::string db = dir + "/recording.sqlite";
  const auto size = fs::file_size(db);
  fs::resize_file(db, size * 6 / 10);
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  std::vector<std::string> errors;
  const std::size_t good = read_all(**rd, &errors);
  EXPECT_GE(good, 15u) << "the first half of the file holds the first frames";
  EXPECT_LT(good, 40u);
  const CheckReport report = (*rd)->check();
  EXPECT_FALSE(report.ok());
  EXPECT_EQ(report.frames_ok, good);
  bool named = false;
  for (const std::string& p : report.problems) named |= p.find(db) != std::string::npos;
  EXPECT_TRUE(named) << report.to_string();
}

TEST(RecordingReader, TruncatedToAFewPagesOrEmpty) {
  const std::string dir = make_recording("stub", 4);
  const std::string db = dir + "/recording.sqlite";
  fs::resize_file(db, 100);  // less than the SQLite header page
  auto rd = RecordingReader::open(dir);
  ASSERT_FALSE(rd);
  EXPECT_EQ(rd.error().message.rfind("recorder::RecordingReader::open(): " + db + ": ", 0), 0u)
      << rd.error().message;
  fs::resize_file(db, 0);
  rd = RecordingReader::open(dir);
  ASSERT_FALSE(rd);
  EXPECT_EQ(rd.error().message, "recorder::RecordingReader::open(): " + db + ": the file is empty");
}

TEST(RecordingReader, NotARecording) {
  const std::string dir = test::output_dir("reader/foreign");
  // Missing.
  auto rd = RecordingReader::open(dir);
  ASSERT_FALSE(rd);
  EXPECT_EQ(rd.error().message,
            "recorder::RecordingReader::open(): " + dir +
                "/recording.sqlite: no such file (a recording folder holds recording.sqlite)");
  // Not SQLite.
  { std::ofstream(dir + "/recording.sqlite") << std::string(5000, 'x'); }
  rd = RecordingReader::open(dir);
  ASSERT_FALSE(rd);
  EXPECT_NE(rd.error().message.find(dir + "/recording.sqlite: not a readable augrig recording: "),
            std::string::npos)
      << rd.error().message;
  EXPECT_NE(rd.error().message.find("SQLITE_NOTADB"), std::string::npos) << rd.error().message;
  // SQLite, but not a recording.
  fs::remove(dir + "/recording.sqlite");
  {
    auto d = Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->exec("CREATE TABLE t (x)"));
  }
  rd = RecordingReader::open(dir + "/recording.sqlite");
  ASSERT_FALSE(rd);
  EXPECT_NE(rd.error().message.find("not a readable augrig recording: no such table: meta"),
            std::string::npos)
      << rd.error().message;
}

TEST(RecordingReader, NewerSchemaIsRefused) {
  const std::string dir = make_recording("newer", 1);
  {
    auto d = Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->exec("UPDATE meta SET value = '99' WHERE key = 'schema_version'"));
  }
  auto rd = RecordingReader::open(dir);
  ASSERT_FALSE(rd);
  EXPECT_EQ(rd.error().message,
            "recorder::RecordingReader::open(): " + dir +
                "/recording.sqlite: schema version 99 is newer than this reader's (" +
                std::to_string(kSchemaVersion) + "); use a newer augrig");
}

TEST(RecordingReader, CheckReportsWhatTheRecordingHolds) {
  const std::string dir = make_recording("report", 5);
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  EXPECT_EQ((*rd)->read_frame(5).error().message, "recorder::RecordingReader::read_frame(): " +
                                                      (*rd)->path() + ": frame 5: out of range (5 frames)");
  const CheckReport r = (*rd)->check();
  EXPECT_TRUE(r.ok()) << r.to_string();
  EXPECT_TRUE(r.closed_cleanly);
  EXPECT_EQ(r.summary_status, "ok");
  EXPECT_EQ(r.schema_version, kSchemaVersion);
  EXPECT_EQ(r.frames, 5u);
  EXPECT_EQ(r.frames_ok, 5u);
  EXPECT_EQ(r.frames_with_masks, 5u);
  EXPECT_EQ(r.frames_augmented, 0u);
  EXPECT_EQ(r.t_first_ns, 1'000'000'000);
  EXPECT_EQ(r.t_last_ns, 1'160'000'000);
  EXPECT_EQ(r.cameras.size(), 2u);
  EXPECT_EQ(r.cameras.at("right: BayerRG8 256x256, clock sim"), 5u);
  EXPECT_EQ(r.nav_inputs_by_stream.at("gps"), 1u);
  EXPECT_EQ(r.events, 1u);
  EXPECT_EQ(r.drops_by_stage.size(), 5u);
  EXPECT_EQ(r.image_bytes, 5u * 3 * 256 * 256);
  const std::string text = r.to_string();
  EXPECT_NE(text.find("frames: 5 (5 intact, 0 augmented, 5 with masks, 0 with statistics)"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("time span: 1000000000 .. 1160000000 ns (0.160 s)"), std::string::npos) << text;
  EXPECT_NE(text.find("drops: camera 0 pairing 0 processing 0 recorder 0 transport 0"), std::string::npos)
      << text;
  EXPECT_NE(text.find("nav inputs: gps 1"), std::string::npos) << text;
  EXPECT_NE(text.find("look updates: 0 noise, 0 light\n"), std::string::npos) << text;
}

// A depth image of w x h: +inf except a disc of a tilted plane (a receiver), with a hole.
DepthImage receiver_depth(int w, int h, std::uint64_t i) {
  DepthImage d;
  d.width = w;
  d.height = h;
  d.z_m.assign(static_cast<std::size_t>(w) * h, DepthImage::kNone);
  const int cx = 60 + static_cast<int>(i) * 7, cy = 90;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if ((x - cx) * (x - cx) + (y - cy) * (y - cy) < 40 * 40 && (x != cx || y != cy))
        d.z_m[static_cast<std::size_t>(y) * w + x] = 20.0f + 0.013f * static_cast<float>(x) - 0.007f * static_cast<float>(y);
  return d;
}

// make_recording() with the receiver depth recorded for both cameras of every frame.
std::string make_depth_recording(const std::string& name, int n) {
  const std::string dir = test::output_dir("reader/" + name);
  auto rec = Recorder::create(dir, RecordingInfo{});
  EXPECT_TRUE(rec) << rec.error().message;
  for (int i = 0; i < n; ++i) {
    FrameRecord f = frame(static_cast<std::uint64_t>(i));
    for (int c = 0; c < 2; ++c) f.receiver_depth[c] = DepthRecord::from(receiver_depth(256, 256, 2 * i + c));
    EXPECT_TRUE((*rec)->push(std::move(f)));
  }
  EXPECT_TRUE((*rec)->close());
  return dir;
}

bool same_bits(const DepthImage& a, const DepthImage& b) {
  return a.width == b.width && a.height == b.height && a.z_m.size() == b.z_m.size() &&
         std::memcmp(a.z_m.data(), b.z_m.data(), a.z_m.size() * sizeof(float)) == 0;
}

TEST(RecordingReader, DamagedDepthIsReportedNamingTheFrame) {
  const std::string dir = make_depth_recording("depth_damaged", 5);
  {
    // Frame 2's left depth blob: one byte flipped inside its zstd payload.
    auto d = Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->exec(
        "UPDATE depth SET left_depth = CAST(substr(left_depth, 1, 40) || x'ff' || substr(left_depth, 42) AS BLOB) "
        "WHERE frame_id = (SELECT id FROM frames WHERE pair_sequence = 2)"));
  }
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  for (std::size_t i = 0; i < 5; ++i) {
    auto f = (*rd)->read_frame(i);
    if (i == 2) {
      ASSERT_FALSE(f);
      EXPECT_NE(f.error().message.find(": frame 2: left depth blob (pair_sequence 2): "), std::string::npos)
          << f.error().message;
      // The images of that frame still read; only the depth is damaged.
      EXPECT_TRUE((*rd)->read_frame(i, kPartRaw | kPartMasks));
      continue;
    }
    ASSERT_TRUE(f) << f.error().message;
    EXPECT_TRUE(same_bits(f->receiver_depth[0].image(), receiver_depth(256, 256, 2 * i))) << i;
    EXPECT_TRUE(same_bits(f->receiver_depth[1].image(), receiver_depth(256, 256, 2 * i + 1))) << i;
  }
  const CheckReport r = (*rd)->check();
  ASSERT_EQ(r.problems.size(), 1u) << r.to_string();
  EXPECT_NE(r.problems[0].find((*rd)->path() + ": frame 2: left depth blob"), std::string::npos) << r.problems[0];
  EXPECT_EQ(r.frames_ok, 4u);
  EXPECT_EQ(r.frames_with_depth, 4u);

  // A box that does not fit the image is damage too, named the same way.
  {
    auto d = Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->exec("UPDATE depth SET right_x1 = 300 WHERE frame_id = (SELECT id FROM frames WHERE pair_sequence = 4)"));
  }
  auto rd2 = RecordingReader::open(dir);
  ASSERT_TRUE(rd2);
  auto f4 = (*rd2)->read_frame(4);
  ASSERT_FALSE(f4);
  EXPECT_NE(f4.error().message.find("frame 4: right depth blob (pair_sequence 4): box [84, 300)"), std::string::npos)
      << f4.error().message;
}

// A recording as schema 1 wrote it: no depth table, schema_version 1, no codec.depth.
TEST(RecordingReader, SchemaOneRecordingWithoutDepthStillReadsAndChecks) {
  const std::string dir = make_recording("schema1", 4);
  {
    auto d = Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->exec("DROP TABLE depth; DROP TABLE look; UPDATE meta SET value = '1' WHERE key = "
                        "'schema_version'; DELETE FROM meta WHERE key = 'codec.depth'"));
    for (const std::string& c : frame_columns_added_after(1)) ASSERT_TRUE(d->exec("ALTER TABLE frames DROP COLUMN " + c));
    ASSERT_TRUE(d->exec("VACUUM"));
  }
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  EXPECT_EQ((*rd)->schema_version(), 1);
  std::vector<std::string> errors;
  EXPECT_EQ(read_all(**rd, &errors), 4u);
  auto f = (*rd)->read_frame(0);
  ASSERT_TRUE(f);
  EXPECT_TRUE(f->receiver_depth[0].empty());
  EXPECT_TRUE(f->receiver_depth[1].empty());
  const CheckReport r = (*rd)->check();
  EXPECT_TRUE(r.ok()) << r.to_string();
  EXPECT_EQ(r.frames_with_depth, 0u);
  EXPECT_NE(r.to_string().find("receiver depth: 0 frames (record with --ground-truth to store it)"),
            std::string::npos)
      << r.to_string();
}

// The camera look's updates come back in push order, counted by check().
TEST(RecordingReader, LookUpdatesReadBackAndAreCounted) {
  const std::string dir = test::output_dir("reader/look");
  {
    auto rec = Recorder::create(dir, RecordingInfo{});
    ASSERT_TRUE(rec) << rec.error().message;
    ASSERT_TRUE((*rec)->push(frame(0)));
    for (int c = 0; c < 2; ++c)
      ASSERT_TRUE((*rec)->push(
          LookRecord{1'000'000'000, ClockDomain::kSim, LookNoise{c, {1, {0.2 + c, 0, 0}, {2.0, 0, 0}}, false, 4, ""}}));
    LookLight l;
    l.direct = {0.6, 0.6, 0.6};
    l.samples = 200;
    l.source = LightSource::kEphemeris;
    l.sun_up = true;
    l.towards_sun_body = {0, 0, -1};
    ASSERT_TRUE((*rec)->push(LookRecord{1'040'000'000, ClockDomain::kSim, l}));
    ASSERT_TRUE((*rec)->close());
    EXPECT_EQ((*rec)->stats().look_updates_committed, 3u);
  }
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  EXPECT_EQ((*rd)->meta("summary.look_updates"), "3");
  auto look = (*rd)->look();
  ASSERT_TRUE(look) << look.error().message;
  ASSERT_EQ(look->size(), 3u);
  for (int c = 0; c < 2; ++c) {
    const auto* n = std::get_if<LookNoise>(&(*look)[static_cast<std::size_t>(c)].update);
    ASSERT_TRUE(n) << c;
    EXPECT_EQ(n->camera, c);
    EXPECT_EQ(n->nlf.a[0], 0.2 + c);
    EXPECT_EQ(n->frames, 4u);
  }
  const auto* l = std::get_if<LookLight>(&(*look)[2].update);
  ASSERT_TRUE(l);
  EXPECT_EQ((*look)[2].t_ns, 1'040'000'000);
  EXPECT_EQ((*look)[2].clock, ClockDomain::kSim);
  EXPECT_EQ(l->samples, 200u);
  EXPECT_EQ(l->source, LightSource::kEphemeris);
  const CheckReport r = (*rd)->check();
  EXPECT_TRUE(r.ok()) << r.to_string();
  EXPECT_EQ(r.look_noise, 2u);
  EXPECT_EQ(r.look_light, 1u);
  EXPECT_NE(r.to_string().find("look updates: 2 noise, 1 light\n"), std::string::npos) << r.to_string();

  // A damaged row: an error naming the file, the row and the column, in look() and in check().
  {
    auto d = Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->exec("UPDATE look SET b0 = 'loud' WHERE id = 2"));
  }
  auto rd2 = RecordingReader::open(dir);
  ASSERT_TRUE(rd2);
  auto bad = (*rd2)->look();
  ASSERT_FALSE(bad);
  const std::string want = "recorder::RecordingReader::look(): " + (*rd2)->path() +
                           ": look row 1: column b0: expected a number, got text";
  EXPECT_EQ(bad.error().message, want);
  const CheckReport r2 = (*rd2)->check();
  ASSERT_FALSE(r2.ok());
  EXPECT_EQ(r2.problems.front(), want);
}

// A recording as schema 2 wrote it: frames without the shadow columns, no look table. Its frames
// read as recorded with the shadow counts 0, it has no look updates, and it checks clean.
TEST(RecordingReader, SchemaTwoRecordingReadsItsShadowAsZero) {
  const std::string dir = test::output_dir("reader/schema2");
  std::vector<OcclusionStats> sent;
  {
    auto rec = Recorder::create(dir, RecordingInfo{});
    ASSERT_TRUE(rec) << rec.error().message;
    for (std::uint64_t i = 0; i < 3; ++i) {
      FrameRecord f = frame(i);
      OcclusionStats st;
      st.t_ns = f.raw.t_key_ns;
      st.receiver_px_left = 1000 + static_cast<std::int64_t>(i);
      st.occluded_pct_right = 12.5;
      st.boom_pct_right = 1.0 / 3.0;
      st.shadow_px_left = 77;  // not in a schema 2 recording
      st.shadow_pct_right = 3.5;
      f.stats = st;
      sent.push_back(st);
      ASSERT_TRUE((*rec)->push(std::move(f)));
    }
    ASSERT_TRUE((*rec)->push(LookRecord{5, ClockDomain::kSim, LookNoise{0, {1, {0.1, 0, 0}, {1, 0, 0}}, true, 0, ""}}));
    ASSERT_TRUE((*rec)->close());
  }
  {
    auto d = Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->exec("DROP TABLE look; UPDATE meta SET value = '2' WHERE key = 'schema_version'; "
                        "DELETE FROM meta WHERE key = 'summary.look_updates'"));
    for (const std::string& c : frame_columns_added_after(2)) ASSERT_TRUE(d->exec("ALTER TABLE frames DROP COLUMN " + c));
    ASSERT_TRUE(d->exec("VACUUM"));
  }
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  EXPECT_EQ((*rd)->schema_version(), 2);
  ASSERT_EQ((*rd)->frame_count(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    auto f = (*rd)->read_frame(i);
    ASSERT_TRUE(f) << f.error().message;
    ASSERT_TRUE(f->stats);
    OcclusionStats want = sent[i];
    want.shadow_px_left = 0;
    want.shadow_pct_right = 0;
    EXPECT_EQ(*f->stats, want) << i;
    EXPECT_TRUE(pixels_equal(f->raw.left.image, frame(i).raw.left.image)) << i;
  }
  auto look = (*rd)->look();
  ASSERT_TRUE(look) << look.error().message;
  EXPECT_TRUE(look->empty());
  const CheckReport r = (*rd)->check();
  EXPECT_TRUE(r.ok()) << r.to_string();
  EXPECT_EQ(r.frames_with_stats, 3u);
  EXPECT_NE(r.to_string().find("look updates: 0 noise, 0 light"), std::string::npos) << r.to_string();
}

}  // namespace
}  // namespace augrig::recorder
