// The Recorder against real SQLite files on disk: bit-exact round trips of everything a frame
// carries in every pixel format; kill -9 at random moments loses nothing that was committed; a file
// size limit and a size cap stop the recording cleanly; an overflowing queue and invalid frames are
// counted in the drop ledger; a recording can be read while it is written.
#include "recorder/recorder.hpp"

#include <chrono>
#include <cmath>
#include <cstring>
#include <iterator>
#include <limits>
#include <filesystem>
#include <map>
#include <random>
#include <set>
#include <thread>

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "recorder/codec.hpp"
#include "recorder/reader.hpp"
#include "recorder/replay_source.hpp"
#include "recorder/store.hpp"
#include "tests/support/test_support.hpp"
#include "tests/support/tmpfs.hpp"

namespace augrig::recorder {
namespace {

using namespace std::chrono_literals;

constexpr PixelFormat kAllFormats[] = {PixelFormat::kMono8,    PixelFormat::kRGB8,     PixelFormat::kRGBA8,
                                       PixelFormat::kBayerRG8, PixelFormat::kBayerGR8, PixelFormat::kBayerGB8,
                                       PixelFormat::kBayerBG8};

TimestampNs now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<TimestampNs>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// A camera-like image (smooth shading, colour-site offsets, edges, noise) or uniform random bytes.
Image synth_image(int w, int h, PixelFormat f, std::uint64_t seed, bool random) {
  Image img(w, h, f);
  std::mt19937_64 rng(seed);
  const int bpp = bytes_per_pixel(f);
  if (random) {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w * bpp; ++x) img.row(y)[x] = static_cast<std::uint8_t>(rng());
    return img;
  }
  const double phase = static_cast<double>(seed % 1000) * 0.01;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < bpp; ++c) {
        const int ch = is_bayer(f) ? bayer_channel(f, x, y) : c;
        int v = 100 + static_cast<int>(50 * std::sin(x * 0.02 + phase) * std::cos(y * 0.03)) + 30 * ch +
                static_cast<int>(rng() % 5) - 2;
        if (((x + static_cast<int>(seed)) / 23 + y / 17) % 4 == 0) v += 60;
        img.row(y)[x * bpp + c] = static_cast<std::uint8_t>(std::clamp(v, 0, 255));
      }
    }
  }
  return img;
}

// Frame i of a test recording: everything a FrameRecord can carry, all derived from i.
FrameRecord make_frame(std::uint64_t i, PixelFormat f, int w, int h, bool random, bool extras = true) {
  FrameRecord r;
  StereoFrame& s = r.raw;
  s.pair_sequence = i;
  s.left.t_ns = 1'000'000'000 + static_cast<TimestampNs>(i) * 33'333'333;
  s.right.t_ns = s.left.t_ns + 17;
  s.t_key_ns = s.left.t_ns + 8;
  s.skew_ns = 17;
  for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
    Frame& fr = s[id];
    fr.camera = id;
    fr.clock = id == CameraId::kLeft ? ClockDomain::kDevice : ClockDomain::kHostMonotonic;
    fr.sequence = 1000 + i * 2 + index_of(id);
    fr.t_host_ns = fr.t_ns + 5'000'000;
    fr.exposure_ns = 2'000'000 + static_cast<std::int64_t>(i);
    fr.image = synth_image(w, h, f, i * 2 + index_of(id), random);
  }
  if (!extras) return r;
  const int bpp = bytes_per_pixel(f);
  for (int c = 0; c < 2; ++c) {
    const Image& raw = s[static_cast<CameraId>(c)].image;
    r.augmented[c] = raw;
    Image& mask = r.mask[c] = Image(w, h, PixelFormat::kMono8);
    // A diagonal "boom" band; on some frames nothing changes at all.
    if (i % 5 == 4) continue;
    const int x0 = static_cast<int>(i % 7) * w / 16;
    for (int y = h / 4; y < h * 3 / 4; ++y) {
      for (int x = x0 + y / 3; x < std::min(w, x0 + y / 3 + w / 8); ++x) {
        for (int k = 0; k < bpp; ++k)
          r.augmented[c].row(y)[x * bpp + k] = static_cast<std::uint8_t>(200 + (x + k) % 50);
        mask.row(y)[x] = kMaskBoom | ((y > h / 2) ? kMaskReceiver : 0);
      }
    }
  }
  r.T_cam_receiver[0] =
      pose_from_ypr({0.25, 1.0 / 3.0, 22.0 + 1e-3 * static_cast<double>(i)}, 0.01, -0.02, 0.03);
  r.T_cam_receiver[1] =
      pose_from_ypr({-0.25, 1.0 / 3.0, 22.0 + 1e-3 * static_cast<double>(i)}, 0.011, -0.02, 0.03);
  r.T_body_receiver = pose_from_ypr({-22.0, 0.1, 9.0 - 1e-4 * static_cast<double>(i)}, 0.0, 0.02, 0.0);
  r.receiver_present = i % 3 != 0;
  r.sigma_pos_m = 0.015;
  if (i % 2) r.sigma_att_deg = 0.05;
  r.boom = BoomArticulation{0.5 + 1e-3 * static_cast<double>(i), 0.02, 3.0};
  OcclusionStats st;
  st.t_ns = s.t_key_ns;
  st.width = w;
  st.height = h;
  st.receiver_px_left = 1000 + static_cast<std::int64_t>(i);
  st.boom_px_right = 77;
  st.boom_overlap_pct_union = 100.0 / 3.0;
  st.occluded_pct_left = std::nextafter(12.5, 13.0);
  st.neither_px = 3;
  st.shadow_px_left = 40 + static_cast<std::int64_t>(i);
  st.shadow_pct_right = std::nextafter(2.5, 3.0);
  r.stats = st;
  return r;
}

void expect_same_pose(const std::optional<Pose>& a, const std::optional<Pose>& b) {
  ASSERT_EQ(a.has_value(), b.has_value());
  if (!a) return;
  EXPECT_EQ(a->translation_m, b->translation_m);
  EXPECT_EQ(a->rotation.coeffs(), b->rotation.coeffs());
}

bool same_double(double a, double b) {
  return (std::isnan(a) && std::isnan(b)) || std::memcmp(&a, &b, sizeof a) == 0;
}

void expect_same_frame(const FrameRecord& a, const FrameRecord& b) {
  EXPECT_EQ(a.raw.pair_sequence, b.raw.pair_sequence);
  EXPECT_EQ(a.raw.t_key_ns, b.raw.t_key_ns);
  EXPECT_EQ(a.raw.skew_ns, b.raw.skew_ns);
  for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
    const Frame& fa = a.raw[id];
    const Frame& fb = b.raw[id];
    EXPECT_EQ(fa.camera, fb.camera);
    EXPECT_EQ(fa.t_ns, fb.t_ns);
    EXPECT_EQ(fa.clock, fb.clock);
    EXPECT_EQ(fa.t_host_ns, fb.t_host_ns);
    EXPECT_EQ(fa.sequence, fb.sequence);
    EXPECT_EQ(fa.exposure_ns, fb.exposure_ns);
    EXPECT_TRUE(pixels_equal(fa.image, fb.image)) << to_string(id) << " raw";
    const int c = index_of(id);
    EXPECT_TRUE(pixels_equal(a.augmented[c], b.augmented[c])) << to_string(id) << " augmented";
    EXPECT_TRUE(pixels_equal(a.mask[c], b.mask[c])) << to_string(id) << " mask";
    expect_same_pose(a.T_cam_receiver[c], b.T_cam_receiver[c]);
  }
  expect_same_pose(a.T_body_receiver, b.T_body_receiver);
  EXPECT_EQ(a.receiver_present, b.receiver_present);
  EXPECT_TRUE(same_double(a.sigma_pos_m, b.sigma_pos_m));
  EXPECT_TRUE(same_double(a.sigma_att_deg, b.sigma_att_deg));
  ASSERT_EQ(a.boom.has_value(), b.boom.has_value());
  if (a.boom) {
    EXPECT_EQ(a.boom->elevation_rad, b.boom->elevation_rad);
    EXPECT_EQ(a.boom->azimuth_rad, b.boom->azimuth_rad);
    EXPECT_EQ(a.boom->extension_m, b.boom->extension_m);
  }
  ASSERT_EQ(a.stats.has_value(), b.stats.has_value());
  if (a.stats) {
    std::ostringstream sa, sb;
    write_stats_csv_row(sa, *a.stats);
    write_stats_csv_row(sb, *b.stats);
    EXPECT_EQ(sa.str(), sb.str());
    EXPECT_EQ(a.stats->width, b.stats->width);
    EXPECT_EQ(a.stats->height, b.stats->height);
    EXPECT_TRUE(same_double(a.stats->occluded_pct_left, b.stats->occluded_pct_left));
    EXPECT_TRUE(same_double(a.stats->boom_overlap_pct_union, b.stats->boom_overlap_pct_union));
    EXPECT_EQ(*a.stats, *b.stats);  // every field, the shadow counts too
  }
}

RecordingInfo test_info() {
  RecordingInfo info;
  info.rig_yaml = "cameras:\n  - name: left\n";
  info.scene = "scenario: test\n";
  info.clock_domains = "frames: device (left), host_monotonic (right); nav: gps";
  info.extra["operator"] = "unit test";
  return info;
}

TEST(Recorder, RoundTripIsBitExactForEveryFormat) {
  const std::string dir = test::output_dir("recorder/round_trip");
  auto rec = Recorder::create(dir, test_info());
  ASSERT_TRUE(rec) << rec.error().message;
  std::vector<FrameRecord> sent;
  std::uint64_t i = 0;
  for (PixelFormat f : kAllFormats) {
    for (bool random : {false, true}) {
      for (int k = 0; k < 3; ++k, ++i) {
        // Odd sizes too: the predictor's row starts and the SIMD tails.
        const int w = k == 2 ? 97 : 160, h = k == 2 ? 33 : 120;
        FrameRecord fr = make_frame(i, f, w, h, random, /*extras=*/k != 1);
        sent.push_back(fr);
        ASSERT_TRUE((*rec)->push(std::move(fr)));
      }
    }
  }
  // A raw frame with padded rows reads back with tight rows and the same pixels.
  {
    FrameRecord fr = make_frame(i++, PixelFormat::kRGB8, 50, 40, true, false);
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      Image padded(50, 40, PixelFormat::kRGB8, 50 * 3 + 7);
      for (int y = 0; y < 40; ++y) std::memcpy(padded.row(y), fr.raw[id].image.row(y), 150);
      fr.raw[id].image = padded;
    }
    sent.push_back(fr);
    ASSERT_TRUE((*rec)->push(std::move(fr)));
  }
  // The augmented images as the pipeline hands them over, their part inside the augmenter's changed
  // box (left: a box larger than the change; right: the change's own box, empty on some frames):
  // they read back whole.
  for (PixelFormat f : kAllFormats) {
    for (int k = 0; k < 2; ++k) {
      FrameRecord fr = make_frame(i++, f, 160, 120, false);
      sent.push_back(fr);
      for (int c = 0; c < 2; ++c) {
        const Image& raw = fr.raw[static_cast<CameraId>(c)].image;
        const PixelBox box =
            c == 0 ? PixelBox{0, 30, 160, 90} : changed_box(raw.cview(), fr.augmented[c].cview());
        fr.augmented[c] = box.empty() ? Image() : Image::copy_of(sub_view(fr.augmented[c].cview(), box));
        fr.augmented_box[c] = box;
      }
      ASSERT_TRUE((*rec)->push(std::move(fr)));
    }
  }
  std::vector<NavInputRecord> nav;
  nav.push_back({"tanker.gps", 5'000'000'000, ClockDomain::kGps, 123,
                 "$GNGGA,123519.00,4807.038,N,01131.000,E,4,12,0.9,545.4,M,46.9,M,,*5C", false});
  nav.push_back(imu_input(nav::ImuSample{5'001'000'000, 0.005, {1e-5, 2e-5, 3e-5}, {0.01, 0.02, 9.81}, 456}));
  nav.push_back({"tanker.imu.raw", 5'002'000'000, ClockDomain::kDevice, 789,
                 std::string("\x00\xff\x10\x00zz", 6), true});
  for (NavInputRecord n : nav) ASSERT_TRUE((*rec)->push(std::move(n)));
  ASSERT_TRUE((*rec)->push(EventRecord{42, ClockDomain::kHostMonotonic, "contact"}));
  LookLight light;
  light.direct = {0.6, 0.61, 0.62};
  light.sky = {0.1, 0.2, 1.0 / 3.0};
  light.ground = {0.3, 0.3, 0.25};
  light.samples = 648;
  light.rms = 0.02;
  light.source = LightSource::kEphemeris;
  light.sun_up = true;
  light.towards_sun_body = Eigen::Vector3d(1, 2, -3).normalized();
  const std::vector<LookRecord> look = {
      {43, ClockDomain::kDevice, LookNoise{1, {3, {0.2, 0.21, 0.22}, {1.5, 1.6, 1.7}}, false, 7, "note"}},
      {44, ClockDomain::kDevice, light}};
  for (LookRecord l : look) ASSERT_TRUE((*rec)->push(std::move(l)));
  ASSERT_TRUE((*rec)->push(DropRecord{DropStage::kPairing, 3, 10, 20, "no partner within 5 ms", "frame"}));
  ASSERT_TRUE((*rec)->push(DropRecord{DropStage::kCamera, 2, 30, 40, "sequence gap", "frame"}));
  ASSERT_TRUE((*rec)->push(DropRecord{DropStage::kPairing, 1, 50, 50, "no partner within 5 ms", "frame"}));
  ASSERT_TRUE((*rec)->status());
  const Status closed = (*rec)->close();
  ASSERT_TRUE(closed) << closed.error().message;
  const RecorderStats st = (*rec)->stats();
  EXPECT_EQ(st.frames_pushed, sent.size());
  EXPECT_EQ(st.frames_committed, sent.size());
  EXPECT_EQ(st.frames_dropped, 0u);
  EXPECT_EQ(st.nav_inputs_committed, 3u);
  EXPECT_EQ(st.events_committed, 1u);
  EXPECT_EQ(st.look_updates_committed, 2u);
  EXPECT_FALSE((*rec)->push(EventRecord{1, ClockDomain::kHostMonotonic, "after close"}));
  // Closed: only the database is left, the WAL was checkpointed away.
  EXPECT_TRUE(std::filesystem::exists(dir + "/recording.sqlite"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/recording.sqlite-wal"));

  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  EXPECT_EQ((*rd)->schema_version(), kSchemaVersion);
  EXPECT_EQ((*rd)->meta("rig_yaml"), test_info().rig_yaml);
  EXPECT_EQ((*rd)->meta("scene"), test_info().scene);
  EXPECT_EQ((*rd)->meta("clock_domains"), test_info().clock_domains);
  EXPECT_EQ((*rd)->meta("operator"), "unit test");
  EXPECT_EQ((*rd)->meta("summary.status"), "ok");
  EXPECT_EQ((*rd)->meta("summary.frames"), std::to_string(sent.size()));
  EXPECT_EQ((*rd)->meta("summary.drops.pairing"), "4");
  EXPECT_NE((*rd)->meta("software").find("augrig"), std::string::npos);
  ASSERT_EQ((*rd)->frame_count(), sent.size());
  for (std::size_t k = 0; k < sent.size(); ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    auto f = (*rd)->read_frame(k);
    ASSERT_TRUE(f) << f.error().message;
    expect_same_frame(sent[k], *f);
  }
  // Parts: metadata only, raw only.
  {
    auto info = (*rd)->read_frame_info(0);
    ASSERT_TRUE(info);
    EXPECT_TRUE(info->raw.left.image.empty());
    EXPECT_EQ(info->raw.left.t_ns, sent[0].raw.left.t_ns);
    ASSERT_TRUE(info->stats);
    auto raw = (*rd)->read_frame(0, kPartRaw);
    ASSERT_TRUE(raw);
    EXPECT_TRUE(pixels_equal(raw->raw.right.image, sent[0].raw.right.image));
    EXPECT_TRUE(raw->augmented[0].empty());
    EXPECT_TRUE(raw->mask[1].empty());
  }
  auto look_back = (*rd)->look();
  ASSERT_TRUE(look_back) << look_back.error().message;
  ASSERT_EQ(look_back->size(), 2u);
  EXPECT_EQ((*look_back)[0].t_ns, 43);
  EXPECT_EQ((*look_back)[0].clock, ClockDomain::kDevice);
  const auto* noise_back = std::get_if<LookNoise>(&(*look_back)[0].update);
  ASSERT_TRUE(noise_back);
  EXPECT_EQ(noise_back->nlf, std::get<LookNoise>(look[0].update).nlf);
  EXPECT_EQ(noise_back->frames, 7u);
  EXPECT_EQ(noise_back->note, "note");
  const auto* light_back = std::get_if<LookLight>(&(*look_back)[1].update);
  ASSERT_TRUE(light_back);
  EXPECT_EQ(light_back->direct, light.direct);
  EXPECT_EQ(light_back->sky, light.sky);
  EXPECT_EQ(light_back->ground, light.ground);
  EXPECT_EQ(light_back->towards_sun_body, light.towards_sun_body);
  EXPECT_EQ(light_back->rms, light.rms);
  auto nav_back = (*rd)->nav_inputs();
  ASSERT_TRUE(nav_back) << nav_back.error().message;
  ASSERT_EQ(nav_back->size(), nav.size());
  for (std::size_t k = 0; k < nav.size(); ++k) {
    EXPECT_EQ((*nav_back)[k].stream, nav[k].stream);
    EXPECT_EQ((*nav_back)[k].t_ns, nav[k].t_ns);
    EXPECT_EQ((*nav_back)[k].clock, nav[k].clock);
    EXPECT_EQ((*nav_back)[k].arrival_ns, nav[k].arrival_ns);
    EXPECT_EQ((*nav_back)[k].data, nav[k].data);
    EXPECT_EQ((*nav_back)[k].binary, nav[k].binary);
  }
  auto gps = (*rd)->nav_inputs("tanker.gps");
  ASSERT_TRUE(gps);
  ASSERT_EQ(gps->size(), 1u);
  auto events = (*rd)->events();
  ASSERT_TRUE(events);
  ASSERT_EQ(events->size(), 1u);
  EXPECT_EQ((*events)[0].text, "contact");
  EXPECT_EQ((*events)[0].t_ns, 42);
  auto drops = (*rd)->drops();
  ASSERT_TRUE(drops);
  std::uint64_t pairing = 0, camera = 0;
  for (const DropRecord& d : *drops) {
    if (d.stage == DropStage::kPairing) {
      pairing += d.count;
      EXPECT_EQ(d.reason, "no partner within 5 ms");
      EXPECT_EQ(d.item, "frame");
    }
    if (d.stage == DropStage::kCamera) camera += d.count;
  }
  EXPECT_EQ(pairing, 4u);
  EXPECT_EQ(camera, 2u);

  const CheckReport report = (*rd)->check();
  EXPECT_TRUE(report.ok()) << report.to_string();
  EXPECT_TRUE(report.closed_cleanly);
  EXPECT_EQ(report.frames, sent.size());
  EXPECT_EQ(report.frames_ok, sent.size());
  EXPECT_EQ(report.t_first_ns, sent.front().raw.t_key_ns);
  EXPECT_EQ(report.t_last_ns, sent.back().raw.t_key_ns);
  EXPECT_EQ(report.drops_by_stage.at("pairing"), 4u);
  EXPECT_EQ(report.drops_by_stage.at("recorder"), 0u);
  EXPECT_EQ(report.nav_inputs_by_stream.at("imu"), 1u);
  EXPECT_EQ(report.events, 1u);
  EXPECT_EQ(report.cameras.at("left: BayerRG8 160x120, clock device"), 4u + 2u);  // + 2 with boxes
  EXPECT_GT(report.stored_bytes, 0u);
  const std::string text = report.to_string();
  EXPECT_NE(text.find("problems: none"), std::string::npos) << text;

  // The database is plain SQLite: the sqlite3 shell reads it.
  std::string out;
  if (test::run_command("command -v sqlite3", &out) == 0) {
    ASSERT_EQ(test::run_command(
                  "sqlite3 " + dir +
                      "/recording.sqlite \"SELECT count(*), min(pair_sequence), "
                      "max(left_width) FROM frames; SELECT value FROM meta WHERE key='schema_version'\"",
                  &out),
              0)
        << out;
    EXPECT_EQ(out, std::to_string(sent.size()) + "|0|160\n" + std::to_string(kSchemaVersion) + "\n");
  }
}

// Receiver depth (record.hpp DepthRecord): every float inside the box, NaN, -inf, -0, denormals and
// +inf holes included, reads back with the same bits, and +inf everywhere outside it.
DepthImage special_depth(int w, int h, std::uint64_t seed) {
  DepthImage d;
  d.width = w;
  d.height = h;
  d.z_m.assign(static_cast<std::size_t>(w) * h, DepthImage::kNone);
  std::mt19937_64 rng(seed);
  const int x0 = static_cast<int>(rng() % static_cast<std::uint64_t>(w / 2)), y0 = static_cast<int>(rng() % static_cast<std::uint64_t>(h / 2));
  const float specials[] = {std::numeric_limits<float>::quiet_NaN(), -std::numeric_limits<float>::infinity(), -0.0f,
                            std::numeric_limits<float>::denorm_min(), DepthImage::kNone, 65.535f, 1e-30f};
  for (int y = y0; y < std::min(h, y0 + 25); ++y)
    for (int x = x0; x < std::min(w, x0 + 31); ++x) {
      float& z = d.z_m[static_cast<std::size_t>(y) * w + x];
      z = 18.0f + 0.01f * static_cast<float>(x) + 0.003f * static_cast<float>(y);  // a tilted surface
      if (rng() % 13 == 0) z = specials[rng() % std::size(specials)];
    }
  return d;
}

bool same_bits(const DepthImage& a, const DepthImage& b) {
  return a.width == b.width && a.height == b.height && a.z_m.size() == b.z_m.size() &&
         std::memcmp(a.z_m.data(), b.z_m.data(), a.z_m.size() * sizeof(float)) == 0;
}

TEST(Recorder, ReceiverDepthRoundTripsBitExact) {
  const std::string dir = test::output_dir("recorder/depth_round_trip");
  auto rec = Recorder::create(dir, test_info());
  ASSERT_TRUE(rec) << rec.error().message;
  std::vector<FrameRecord> sent;
  std::vector<std::array<DepthImage, 2>> depth;
  for (std::uint64_t i = 0; i < 8; ++i) {
    FrameRecord fr = make_frame(i, PixelFormat::kBayerRG8, 160, 120, false);
    std::array<DepthImage, 2> d = {special_depth(160, 120, 2 * i), special_depth(160, 120, 2 * i + 1)};
    if (i == 1) d[1].z_m.assign(d[1].z_m.size(), DepthImage::kNone);  // no receiver: an empty box
    if (i == 2) {  // values in the corners: the box is the whole image
      d[0].z_m.front() = 5.0f;
      d[0].z_m.back() = std::numeric_limits<float>::quiet_NaN();
    }
    for (int c = 0; c < 2; ++c)
      if (i != 3 || c == 0) fr.receiver_depth[c] = DepthRecord::from(d[c]);  // frame 3: left only
    if (i == 4) fr.receiver_depth = {};                                       // frame 4: none
    if (i == 1) {
      EXPECT_TRUE(fr.receiver_depth[1].box.empty());
    }
    if (i == 2) {
      EXPECT_EQ(fr.receiver_depth[0].box, (PixelBox{0, 0, 160, 120}));
    }
    sent.push_back(fr);
    depth.push_back(d);
    ASSERT_TRUE((*rec)->push(std::move(fr)));
  }
  // A depth of another size than the raw image is refused (into the ledger), like a wrong mask.
  {
    FrameRecord bad = make_frame(99, PixelFormat::kMono8, 160, 120, false);
    bad.receiver_depth[0] = DepthRecord::from(special_depth(80, 60, 5));
    EXPECT_FALSE((*rec)->push(std::move(bad)));
  }
  ASSERT_TRUE((*rec)->close());
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  EXPECT_EQ((*rd)->meta("codec.depth"), kDepthCodec);
  ASSERT_EQ((*rd)->frame_count(), sent.size());
  for (std::size_t k = 0; k < sent.size(); ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    auto f = (*rd)->read_frame(k);
    ASSERT_TRUE(f) << f.error().message;
    expect_same_frame(sent[k], *f);
    for (int c = 0; c < 2; ++c) {
      const bool recorded = k != 4 && (k != 3 || c == 0);
      ASSERT_EQ(f->receiver_depth[c].empty(), !recorded) << c;
      if (!recorded) continue;
      EXPECT_EQ(f->receiver_depth[c].box, sent[k].receiver_depth[c].box);
      EXPECT_TRUE(same_bits(f->receiver_depth[c].image(), depth[k][c])) << "camera " << c;
    }
    // Not asked for: not read.
    auto raw = (*rd)->read_frame(k, kPartRaw);
    ASSERT_TRUE(raw);
    EXPECT_TRUE(raw->receiver_depth[0].empty());
  }
  const CheckReport report = (*rd)->check();
  EXPECT_TRUE(report.ok()) << report.to_string();
  EXPECT_EQ(report.frames_with_depth, 7u);
  EXPECT_NE(report.to_string().find("receiver depth: 7 frames\n"), std::string::npos) << report.to_string();
  // Only the box is stored, compressed: far below the whole image's float32 bytes.
  std::string out;
  if (test::run_command("command -v sqlite3", &out) == 0) {
    ASSERT_EQ(test::run_command("sqlite3 " + dir + "/recording.sqlite \"SELECT max(length(left_depth)) FROM depth\"", &out),
              0);
    EXPECT_LT(std::stoul(out), 160u * 120u * 4u / 4u) << out;
  }
}

TEST(Recorder, DepthRecordIsTheSmallestBoxOfValues) {
  DepthImage d;
  d.width = 7;
  d.height = 5;
  d.z_m.assign(35, DepthImage::kNone);
  EXPECT_TRUE(DepthRecord::from(d).box.empty());
  EXPECT_TRUE(same_bits(DepthRecord::from(d).image(), d));
  d.z_m[1 * 7 + 2] = 3.0f;
  d.z_m[3 * 7 + 5] = -0.0f;  // a value, not "none"
  const DepthRecord r = DepthRecord::from(d);
  EXPECT_EQ(r.box, (PixelBox{2, 1, 6, 4}));
  ASSERT_EQ(r.z_m.size(), 12u);
  EXPECT_EQ(r.z_m[0], 3.0f);
  EXPECT_TRUE(std::signbit(r.z_m[11]));
  EXPECT_TRUE(same_bits(r.image(), d));
  EXPECT_TRUE(DepthRecord::from(DepthImage{}).empty());
}

// Every frame's raw blobs as stored, straight from SQLite: [frame][camera] -> bytes.
std::vector<std::array<std::vector<std::uint8_t>, 2>> stored_raw_blobs(const std::string& dir) {
  std::vector<std::array<std::vector<std::uint8_t>, 2>> out;
  auto db = Database::open(database_path(dir), SQLITE_OPEN_READONLY);
  EXPECT_TRUE(db) << db.error().message;
  if (!db) return out;
  auto st = Statement::prepare(db->get(), "SELECT left_raw, right_raw FROM frames ORDER BY id");
  EXPECT_TRUE(st) << st.error().message;
  if (!st) return out;
  while (st->step() == SQLITE_ROW) {
    auto& row = out.emplace_back();
    for (int c = 0; c < 2; ++c) {
      const auto* p = static_cast<const std::uint8_t*>(sqlite3_column_blob(st->get(), c));
      row[c].assign(p, p + sqlite3_column_bytes(st->get(), c));
    }
  }
  return out;
}

// A recording of `n` frames of every format, written with zstd level 3: a blob copied from it
// differs from what the copy's own level 1 would make, so equal bytes prove the copy.
std::string make_source_recording(const std::string& name, int n) {
  const std::string dir = test::output_dir("recorder/" + name);
  RecorderOptions o;
  o.zstd_level = 3;
  auto rec = Recorder::create(dir, test_info(), o);
  EXPECT_TRUE(rec) << rec.error().message;
  for (int i = 0; i < n; ++i) {
    const PixelFormat f = kAllFormats[static_cast<std::size_t>(i) % std::size(kAllFormats)];
    EXPECT_TRUE((*rec)->push(make_frame(static_cast<std::uint64_t>(i), f, 160, 120, false)));
  }
  EXPECT_TRUE((*rec)->close());
  return dir;
}

// Replays `src` and pushes every stereo frame to a new recording at `dst` (level 1), with
// `change(i, frame)` applied to each before the push.
template <typename Change>
RecorderStats re_record(const std::string& src, const std::string& dst, Change&& change) {
  auto replay = ReplaySource::open(src);
  EXPECT_TRUE(replay) << replay.error().message;
  auto rec = Recorder::create(dst, test_info());
  EXPECT_TRUE(rec) << rec.error().message;
  if (!replay || !rec) return {};
  for (std::size_t i = 0;; ++i) {
    FrameRecord fr;
    auto a = (*replay)->read(fr.raw.left, 1s);
    EXPECT_TRUE(a) << a.error().message;
    if (!a || *a != ReadStatus::kFrame) break;
    auto b = (*replay)->read(fr.raw.right, 1s);
    EXPECT_TRUE(b && *b == ReadStatus::kFrame);
    const FrameRecord& cur = (*replay)->current();
    fr.raw.t_key_ns = cur.raw.t_key_ns;
    fr.raw.skew_ns = cur.raw.skew_ns;
    fr.raw.pair_sequence = cur.raw.pair_sequence;
    change(i, fr);
    EXPECT_TRUE((*rec)->push(std::move(fr)));
  }
  EXPECT_TRUE((*rec)->close());
  return (*rec)->stats();
}

TEST(Recorder, ReplayedRawImagesAreStoredByCopyingTheirBlobs) {
  constexpr int kFrames = 14;  // every format twice
  const std::string src = make_source_recording("copy_source", kFrames);
  const std::string dst = test::output_dir("recorder/copy_dest");
  const RecorderStats st = re_record(src, dst, [](std::size_t, FrameRecord&) {});
  EXPECT_EQ(st.frames_committed, static_cast<std::uint64_t>(kFrames));
  EXPECT_EQ(st.raw_blobs_copied, 2u * kFrames) << "every raw image takes the copy path";

  // The stored bytes are the source's, byte for byte (level 3 there, level 1 here: a recompressed
  // blob would differ), and they decode to the same images.
  const auto a = stored_raw_blobs(src), b = stored_raw_blobs(dst);
  ASSERT_EQ(a.size(), static_cast<std::size_t>(kFrames));
  ASSERT_EQ(b.size(), a.size());
  for (std::size_t i = 0; i < a.size(); ++i)
    for (int c = 0; c < 2; ++c) EXPECT_EQ(a[i][c], b[i][c]) << "frame " << i << " camera " << c;
  auto ra = RecordingReader::open(src), rb = RecordingReader::open(dst);
  ASSERT_TRUE(ra && rb);
  for (std::size_t i = 0; i < a.size(); ++i) {
    auto fa = (*ra)->read_frame(i, kPartRaw), fb = (*rb)->read_frame(i, kPartRaw);
    ASSERT_TRUE(fa && fb);
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      EXPECT_TRUE(pixels_equal(fa->raw[id].image, fb->raw[id].image)) << "frame " << i;
      EXPECT_EQ(fa->raw[id].t_ns, fb->raw[id].t_ns);
      EXPECT_EQ(fa->raw[id].sequence, fb->raw[id].sequence);
    }
  }
  const CheckReport report = (*rb)->check();
  EXPECT_TRUE(report.ok()) << report.to_string();
}

TEST(Recorder, AFrameThatDoesNotMatchItsAttachmentIsCompressed) {
  constexpr int kFrames = 6;
  const std::string src = make_source_recording("mismatch_source", kFrames);
  const std::string dst = test::output_dir("recorder/mismatch_dest");
  std::vector<Image> sent_left(kFrames);
  // Frame 0: the left image edited over 16 rows; 1: the left t_ns moved; 2: left and right swapped
  // (each carries the other's blob); 3: the left image replaced by another of the same size and
  // format; 4: the attachment dropped; 5: unchanged. Only the unchanged images are copied.
  const RecorderStats st = re_record(src, dst, [&](std::size_t i, FrameRecord& fr) {
    Image& left = fr.raw.left.image;
    const int bpp = bytes_per_pixel(left.format());
    switch (i) {
      case 0:
        for (int y = 40; y < 56; ++y)
          for (int x = 0; x < 16 * bpp; ++x) left.row(y)[x] ^= 0x5A;
        break;
      case 1:
        fr.raw.left.t_ns += 1;
        break;
      case 2:
        std::swap(fr.raw.left.image, fr.raw.right.image);
        break;
      case 3:
        for (int y = 0; y < left.height(); ++y)
          for (int x = 0; x < left.width() * bpp; ++x) left.row(y)[x] = static_cast<std::uint8_t>(x * 7 + y);
        break;
      case 4:
        fr.raw.left.attachment.reset();
        break;
      default:
        break;
    }
    sent_left[i] = fr.raw.left.image;
  });
  EXPECT_EQ(st.frames_committed, static_cast<std::uint64_t>(kFrames));
  // Copied: the right images of frames 0, 1, 3, 4 and both of frame 5.
  EXPECT_EQ(st.raw_blobs_copied, 6u);
  auto rd = RecordingReader::open(dst);
  ASSERT_TRUE(rd);
  for (std::size_t i = 0; i < kFrames; ++i) {
    auto f = (*rd)->read_frame(i, kPartRaw);
    ASSERT_TRUE(f) << f.error().message;
    EXPECT_TRUE(pixels_equal(f->raw.left.image, sent_left[i])) << "frame " << i << ": what was pushed is stored";
  }
  EXPECT_TRUE((*rd)->check().ok());
}

TEST(Recorder, RefusesToOverwriteUnlessAsked) {
  const std::string dir = test::output_dir("recorder/overwrite");
  {
    auto rec = Recorder::create(dir, test_info());
    ASSERT_TRUE(rec) << rec.error().message;
    ASSERT_TRUE((*rec)->push(make_frame(0, PixelFormat::kMono8, 8, 8, true)));
    ASSERT_TRUE((*rec)->close());
  }
  auto again = Recorder::create(dir, test_info());
  ASSERT_FALSE(again);
  EXPECT_EQ(again.error().message,
            "recorder::Recorder::create(): " + dir +
                "/recording.sqlite: exists; a recording is never overwritten unless asked "
                "(RecorderOptions::overwrite)");
  RecorderOptions opt;
  opt.overwrite = true;
  auto fresh = Recorder::create(dir, test_info(), opt);
  ASSERT_TRUE(fresh) << fresh.error().message;
  ASSERT_TRUE((*fresh)->close());
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd);
  EXPECT_EQ((*rd)->frame_count(), 0u);
  // Reserved meta keys.
  RecordingInfo bad = test_info();
  bad.extra["summary.frames"] = "7";
  auto refused = Recorder::create(test::output_dir("recorder/overwrite2"), bad);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("\"summary.\" keys are reserved"), std::string::npos);
}

TEST(Recorder, InvalidFramesAreDroppedAndCounted) {
  const std::string dir = test::output_dir("recorder/invalid");
  auto rec = Recorder::create(dir, test_info());
  ASSERT_TRUE(rec) << rec.error().message;
  FrameRecord bad_mask = make_frame(0, PixelFormat::kBayerRG8, 64, 48, false);
  bad_mask.mask[0] = Image(10, 10, PixelFormat::kMono8);
  EXPECT_FALSE((*rec)->push(std::move(bad_mask)));
  FrameRecord bad_aug = make_frame(1, PixelFormat::kBayerRG8, 64, 48, false);
  bad_aug.augmented[1] = Image(64, 48, PixelFormat::kRGB8);
  EXPECT_FALSE((*rec)->push(std::move(bad_aug)));
  FrameRecord no_raw = make_frame(2, PixelFormat::kBayerRG8, 64, 48, false);
  no_raw.raw.right.image = Image();
  EXPECT_FALSE((*rec)->push(std::move(no_raw)));
  FrameRecord box_outside = make_frame(4, PixelFormat::kBayerRG8, 64, 48, false);
  box_outside.augmented[0] = Image(20, 10, PixelFormat::kBayerRG8);
  box_outside.augmented_box[0] = PixelBox{50, 40, 70, 50};
  EXPECT_FALSE((*rec)->push(std::move(box_outside)));
  FrameRecord box_mismatch = make_frame(5, PixelFormat::kBayerRG8, 64, 48, false);
  box_mismatch.augmented[1] = Image(20, 10, PixelFormat::kBayerRG8);
  box_mismatch.augmented_box[1] = PixelBox{0, 0, 20, 11};
  EXPECT_FALSE((*rec)->push(std::move(box_mismatch)));
  EXPECT_TRUE((*rec)->push(make_frame(3, PixelFormat::kBayerRG8, 64, 48, false)));
  ASSERT_TRUE((*rec)->close());
  EXPECT_EQ((*rec)->stats().frames_dropped, 5u);
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd);
  EXPECT_EQ((*rd)->frame_count(), 1u);
  auto drops = (*rd)->drops();
  ASSERT_TRUE(drops);
  std::set<std::string> reasons;
  for (const DropRecord& d : *drops) {
    EXPECT_EQ(d.stage, DropStage::kRecorder);
    reasons.insert(d.reason);
  }
  EXPECT_EQ(reasons,
            (std::set<std::string>{
                "invalid frame: left mask 10x10 Mono8 is not Mono8 of the raw image's size 64x48",
                "invalid frame: right augmented image 64x48 RGB8 differs from the raw image 64x48 BayerRG8",
                "invalid frame: right raw image is empty",
                "invalid frame: left augmented box [50, 70) x [40, 50) is not inside the raw image 64x48",
                "invalid frame: right augmented part 20x10 BayerRG8 differs from its box 20x11 of the raw "
                "image's BayerRG8"}));
}

TEST(Recorder, OverflowingQueueCountsDropsInTheLedger) {
  const std::string dir = test::output_dir("recorder/overflow");
  RecorderOptions opt;
  opt.queue_capacity = 2;
  opt.writer_delay_for_testing = 20ms;
  auto rec = Recorder::create(dir, test_info(), opt);
  ASSERT_TRUE(rec) << rec.error().message;
  std::vector<std::uint64_t> accepted;
  std::uint64_t refused = 0;
  double max_push_ms = 0;
  for (std::uint64_t i = 0; i < 60; ++i) {
    FrameRecord f = make_frame(i, PixelFormat::kBayerBG8, 64, 48, false);
    const auto t0 = std::chrono::steady_clock::now();
    const bool ok = (*rec)->push(std::move(f));
    max_push_ms =
        std::max(max_push_ms,
                 std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    if (ok)
      accepted.push_back(i);
    else
      ++refused;
    std::this_thread::sleep_for(1ms);
  }
  EXPECT_GT(refused, 20u);
  EXPECT_GE(accepted.size(), 2u);
  EXPECT_LT(max_push_ms, 50.0) << "push() must not wait for the writer";
  ASSERT_TRUE((*rec)->close());
  const RecorderStats st = (*rec)->stats();
  EXPECT_EQ(st.frames_dropped, refused);
  EXPECT_EQ(st.frames_committed, accepted.size());

  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  ASSERT_EQ((*rd)->frame_count(), accepted.size());
  for (std::size_t k = 0; k < accepted.size(); ++k) {
    auto f = (*rd)->read_frame_info(k);
    ASSERT_TRUE(f);
    EXPECT_EQ(f->raw.pair_sequence, accepted[k]);  // in push order
  }
  auto drops = (*rd)->drops();
  ASSERT_TRUE(drops);
  std::uint64_t counted = 0;
  for (const DropRecord& d : *drops) {
    EXPECT_EQ(d.stage, DropStage::kRecorder);
    EXPECT_EQ(d.item, "frame");
    EXPECT_EQ(d.reason, "queue full (capacity 2 frames)");
    EXPECT_LE(d.first_t_ns, d.last_t_ns);
    counted += d.count;
  }
  EXPECT_EQ(counted, refused);
  const CheckReport report = (*rd)->check();
  EXPECT_TRUE(report.ok()) << report.to_string();
  EXPECT_EQ(report.drops_by_stage.at("recorder"), refused);
  EXPECT_EQ((*rd)->meta("summary.drops.recorder"), std::to_string(refused));
}

TEST(Recorder, ReadableWhileRecording) {
  const std::string dir = test::output_dir("recorder/live");
  auto rec = Recorder::create(dir, test_info());
  ASSERT_TRUE(rec) << rec.error().message;
  for (std::uint64_t i = 0; i < 20; ++i)
    ASSERT_TRUE((*rec)->push(make_frame(i, PixelFormat::kBayerGR8, 96, 64, false)));
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while ((*rec)->stats().frames_committed < 20 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(10ms);
  ASSERT_EQ((*rec)->stats().frames_committed, 20u);
  {
    auto rd = RecordingReader::open(dir);
    ASSERT_TRUE(rd) << rd.error().message;
    EXPECT_EQ((*rd)->frame_count(), 20u);
    auto f = (*rd)->read_frame(19);
    ASSERT_TRUE(f) << f.error().message;
    expect_same_frame(make_frame(19, PixelFormat::kBayerGR8, 96, 64, false), *f);
    EXPECT_TRUE((*rd)->meta("summary.status").empty());  // not closed yet
  }
  for (std::uint64_t i = 20; i < 30; ++i)
    ASSERT_TRUE((*rec)->push(make_frame(i, PixelFormat::kBayerGR8, 96, 64, false)));
  // Someone holds a read transaction on the live recording while it is closed: the WAL cannot be
  // truncated then, which is no error.
  auto other = Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READONLY);
  ASSERT_TRUE(other) << other.error().message;
  ASSERT_TRUE(other->exec("BEGIN"));
  ASSERT_TRUE(other->query_text("SELECT count(*) FROM frames"));
  const Status closed = (*rec)->close();
  EXPECT_TRUE(closed) << closed.error().message;
  ASSERT_TRUE(other->exec("COMMIT"));
  other->close();
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd);
  EXPECT_EQ((*rd)->frame_count(), 30u);
  EXPECT_EQ((*rd)->meta("summary.status"), "ok");
  EXPECT_TRUE((*rd)->check().ok());
}

TEST(Recorder, SizeCapStopsTheRecordingCleanly) {
  const std::string dir = test::output_dir("recorder/max_bytes");
  RecorderOptions opt;
  opt.max_bytes = 3 << 20;
  opt.commit_interval = 20ms;  // several commits before the cap: only the last transaction is lost
  auto rec = Recorder::create(dir, test_info(), opt);
  ASSERT_TRUE(rec) << rec.error().message;
  int pushed = 0;
  for (std::uint64_t i = 0; i < 400 && (*rec)->status(); ++i) {
    if ((*rec)->push(make_frame(i, PixelFormat::kBayerRG8, 160, 120, /*random=*/true))) ++pushed;
    std::this_thread::sleep_for(2ms);
  }
  const Status st = (*rec)->status();
  ASSERT_FALSE(st) << "a 3 MiB cap must stop a recording of " << pushed << " incompressible frames";
  EXPECT_NE(st.error().message.find("SQLITE_FULL"), std::string::npos) << st.error().message;
  EXPECT_NE(st.error().message.find(dir + "/recording.sqlite"), std::string::npos) << st.error().message;
  EXPECT_NE(st.error().message.find("rolled back"), std::string::npos) << st.error().message;
  EXPECT_NE(st.error().message.find("the size cap (RecorderOptions::max_bytes = 3145728 bytes) was reached"),
            std::string::npos)
      << st.error().message;
  // The pipeline goes on: push() answers at once and counts the drop.
  double max_push_ms = 0;
  for (std::uint64_t i = 1000; i < 1020; ++i) {
    FrameRecord f = make_frame(i, PixelFormat::kBayerRG8, 160, 120, true);
    const auto t0 = std::chrono::steady_clock::now();
    EXPECT_FALSE((*rec)->push(std::move(f)));
    max_push_ms =
        std::max(max_push_ms,
                 std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  EXPECT_LT(max_push_ms, 20.0);
  const std::uint64_t committed = (*rec)->stats().frames_committed;
  const Status closed = (*rec)->close();
  ASSERT_FALSE(closed);
  EXPECT_EQ(closed.error().message, st.error().message);
  EXPECT_GE((*rec)->stats().frames_dropped, 20u);

  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  EXPECT_EQ((*rd)->frame_count(), committed);
  EXPECT_GT(committed, 5u);
  const CheckReport report = (*rd)->check();
  EXPECT_TRUE(report.ok()) << report.to_string();
  for (std::size_t k = 0; k < (*rd)->frame_count(); k += 7) {
    auto f = (*rd)->read_frame(k);
    ASSERT_TRUE(f) << f.error().message;
    expect_same_frame(make_frame(f->raw.pair_sequence, PixelFormat::kBayerRG8, 160, 120, true), *f);
  }
}

// A full disk (a real tmpfs) stops the recording either in a transaction (rolled back) or in a
// WAL checkpoint (the database cannot grow). Either way close() writes the summary and the whole
// drop ledger, the ledger rows pushed after the stop included, into the space the recorder held
// back at create(). Rounds with different checkpoint intervals meet both kinds of stop.
TEST(Recorder, FullDiskClosesWithTheTrueLedger) {
  int stopped_by_checkpoint = 0, stopped_in_transaction = 0;
  for (int round = 0; round < 6; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    const test::ScopedTmpfs fs(test::output_dir("recorder/disk_full_mnt"), 6u << 20);
    if (!fs.mounted()) GTEST_SKIP() << fs.error();
    const std::string dir = fs.dir() + "/rec";
    RecorderOptions opt;
    opt.commit_interval = std::chrono::milliseconds(10 + 20 * round);
    opt.checkpoint_interval = std::chrono::milliseconds(round % 2 ? 5 : 300);
    auto rec = Recorder::create(dir, test_info(), opt);
    ASSERT_TRUE(rec) << rec.error().message;
    EXPECT_TRUE(std::filesystem::exists(dir + "/recording.reserve"));
    (*rec)->push(DropRecord{DropStage::kCamera, 3, 100, 200, "frame-id gaps", "frame"});
    std::uint64_t i = 0;
    for (; i < 3000 && (*rec)->status(); ++i) {
      (*rec)->push(make_frame(i, PixelFormat::kBayerRG8, 160, 120, /*random=*/true));
      std::this_thread::sleep_for(1ms);
    }
    ASSERT_FALSE((*rec)->status()) << "a 6 MiB file system must fill up";
    const std::string why = (*rec)->status().error().message;
    (why.find("checkpoint") != std::string::npos ? stopped_by_checkpoint : stopped_in_transaction) += 1;
    // After the stop: more frames (dropped by the recorder) and the pipeline's own ledger rows.
    for (int k = 0; k < 10; ++k)
      EXPECT_FALSE((*rec)->push(make_frame(i++, PixelFormat::kBayerRG8, 160, 120, true)));
    (*rec)->push(DropRecord{DropStage::kPairing, 42, 300, 400, "frames without a stereo partner", "frame"});
    (*rec)->push(DropRecord{DropStage::kProcessing, 5, 500, 600, "pending when the run stopped", "frame"});
    const Status closed = (*rec)->close();
    EXPECT_FALSE(closed);
    const RecorderStats st = (*rec)->stats();
    EXPECT_FALSE(std::filesystem::exists(dir + "/recording.reserve"));

    auto rd = RecordingReader::open(dir);
    ASSERT_TRUE(rd) << rd.error().message;
    EXPECT_EQ((*rd)->meta("summary.status"), why) << "the recording was not closed";
    EXPECT_EQ((*rd)->meta("summary.frames"), std::to_string(st.frames_committed));
    EXPECT_EQ((*rd)->meta("summary.drops.camera"), "3");
    EXPECT_EQ((*rd)->meta("summary.drops.pairing"), "42");
    EXPECT_EQ((*rd)->meta("summary.drops.processing"), "5");
    EXPECT_EQ((*rd)->meta("summary.drops.recorder"),
              std::to_string(st.frames_dropped + st.small_items_dropped));
    EXPECT_GE(st.frames_dropped, 10u);
    const CheckReport report = (*rd)->check();
    EXPECT_TRUE(report.ok()) << report.to_string();
    EXPECT_EQ(report.drops_by_stage.at("camera"), 3u);
    EXPECT_EQ(report.drops_by_stage.at("pairing"), 42u);
    EXPECT_EQ(report.drops_by_stage.at("processing"), 5u);
    EXPECT_EQ(report.drops_by_stage.at("recorder"), st.frames_dropped + st.small_items_dropped);
    EXPECT_EQ(report.frames, st.frames_committed);
    auto drops = (*rd)->drops();
    ASSERT_TRUE(drops) << drops.error().message;
    for (const DropRecord& d : *drops)
      if (d.stage == DropStage::kPairing) {
        EXPECT_EQ(d.first_t_ns, 300);
        EXPECT_EQ(d.last_t_ns, 400);
      }
  }
  std::printf("stops by checkpoint %d, in a transaction %d\n", stopped_by_checkpoint, stopped_in_transaction);
}

// On a disk already full the recording is refused at create(), naming the file and the space, and
// leaves no file behind (it once left a 64 KiB database without tables).
TEST(Recorder, CreateOnAFullDiskFailsAndLeavesNothing) {
  const test::ScopedTmpfs fs(test::output_dir("recorder/full_at_create_mnt"), 1u << 20);
  if (!fs.mounted()) GTEST_SKIP() << fs.error();
  fs.fill(64 << 10);
  const std::string dir = fs.dir() + "/rec";
  auto rec = Recorder::create(dir, test_info());
  ASSERT_FALSE(rec);
  EXPECT_NE(rec.error().message.find(dir + "/recording.reserve"), std::string::npos) << rec.error().message;
  EXPECT_NE(rec.error().message.find("No space left on device"), std::string::npos) << rec.error().message;
  for (const char* f :
       {"recording.sqlite", "recording.sqlite-wal", "recording.sqlite-shm", "recording.reserve"})
    EXPECT_FALSE(std::filesystem::exists(dir + "/" + f)) << f;
}

// ---- child processes ----------------------------------------------------------------------------

struct Msg {
  char kind;  // 'S' started, 'P' pushed (value: pair_sequence), 'C' committed (value: count)
  std::uint64_t value;
  TimestampNs t_ns;  // CLOCK_MONOTONIC
};

void send(int fd, char kind, std::uint64_t value) {
  const Msg m{kind, value, now_ns()};
  (void)!write(fd, &m, sizeof m);
}

[[noreturn]] void record_until_killed(const std::string& dir, int fd) {
  RecorderOptions opt;  // the defaults: commit_interval 250 ms
  auto rec = Recorder::create(dir, test_info(), opt);
  if (!rec) _exit(2);
  send(fd, 'S', 0);
  std::uint64_t committed = 0;
  for (std::uint64_t i = 0;; ++i) {
    if ((*rec)->push(make_frame(i, PixelFormat::kBayerRG8, 128, 96, false))) send(fd, 'P', i);
    if (i % 16 == 0) (*rec)->push(imu_input(nav::ImuSample{static_cast<TimestampNs>(i), 0.005, {}, {}, 0}));
    const std::uint64_t c = (*rec)->stats().frames_committed;
    if (c != committed) send(fd, 'C', committed = c);
    usleep(1500);
  }
}

TEST(Recorder, KillNineAtRandomMomentsLosesNothingCommitted) {
  std::mt19937 rng(20240611);
  std::uniform_int_distribution<int> delay_ms(50, 800);
  for (int round = 0; round < 20; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    const std::string dir = test::output_dir("recorder/kill9/" + std::to_string(round));
    int fds[2];
    ASSERT_EQ(pipe(fds), 0);
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      close(fds[0]);
      record_until_killed(dir, fds[1]);
    }
    close(fds[1]);
    Msg m{};
    ASSERT_EQ(read(fds[0], &m, sizeof m), static_cast<ssize_t>(sizeof m));
    ASSERT_EQ(m.kind, 'S');
    const int wait_ms = delay_ms(rng);
    std::this_thread::sleep_for(std::chrono::milliseconds(wait_ms));
    const TimestampNs t_kill = now_ns();
    ASSERT_EQ(kill(pid, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
    std::uint64_t committed = 0;
    std::vector<std::uint64_t> pushed_before;  // pushed more than 1 s before the kill
    std::uint64_t pushed = 0;
    while (read(fds[0], &m, sizeof m) == static_cast<ssize_t>(sizeof m)) {
      if (m.kind == 'C') committed = std::max(committed, m.value);
      if (m.kind == 'P') {
        ++pushed;
        if (m.t_ns <= t_kill - 1'000'000'000) pushed_before.push_back(m.value);
      }
    }
    close(fds[0]);

    auto rd = RecordingReader::open(dir);
    ASSERT_TRUE(rd) << rd.error().message;
    const CheckReport report = (*rd)->check();
    EXPECT_TRUE(report.ok()) << report.to_string();
    EXPECT_FALSE(report.closed_cleanly);
    const std::size_t n = (*rd)->frame_count();
    EXPECT_GE(n, committed) << "killed after " << wait_ms << " ms, " << pushed << " frames pushed";
    std::set<std::uint64_t> have;
    for (std::size_t k = 0; k < n; ++k) {
      auto f = (*rd)->read_frame_info(k);
      ASSERT_TRUE(f) << f.error().message;
      have.insert(f->raw.pair_sequence);
    }
    for (std::uint64_t s : pushed_before)
      EXPECT_TRUE(have.count(s)) << "frame " << s << " pushed > 1 s before the kill is missing";
    if (n > 0) {
      auto f = (*rd)->read_frame(n - 1);
      ASSERT_TRUE(f) << f.error().message;
      expect_same_frame(make_frame(f->raw.pair_sequence, PixelFormat::kBayerRG8, 128, 96, false), *f);
    }
  }
}

TEST(Recorder, FileSizeLimitStopsTheRecordingCleanly) {
  const std::string dir = test::output_dir("recorder/rlimit_fsize");
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    close(fds[0]);
    // 4 MiB per file: the WAL or the database reaches it after a few dozen incompressible frames.
    rlimit lim{4 << 20, 4 << 20};
    if (setrlimit(RLIMIT_FSIZE, &lim) != 0) _exit(3);
    RecorderOptions opt;
    opt.commit_interval = 20ms;  // several commits before the limit: only the last transaction is lost
    auto rec = Recorder::create(dir, test_info(), opt);
    if (!rec) _exit(2);
    std::uint64_t i = 0;
    for (; i < 2000 && (*rec)->status(); ++i) {
      (*rec)->push(make_frame(i, PixelFormat::kBayerGB8, 160, 120, true));
      usleep(2000);
    }
    double max_push_ms = 0;
    int refused = 0;
    for (int k = 0; k < 20; ++k, ++i) {
      FrameRecord f = make_frame(i, PixelFormat::kBayerGB8, 160, 120, true);
      const auto t0 = std::chrono::steady_clock::now();
      refused += !(*rec)->push(std::move(f));
      max_push_ms =
          std::max(max_push_ms,
                   std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    }
    const std::uint64_t committed = (*rec)->stats().frames_committed;
    const Status st = (*rec)->status();
    const Status closed = (*rec)->close();
    const std::string report =
        "committed=" + std::to_string(committed) + "\nrefused=" + std::to_string(refused) +
        "\nmax_push_ms=" + std::to_string(max_push_ms) + "\nclose_failed=" + std::to_string(!closed) +
        "\nstatus=" + (st ? std::string("ok") : st.error().message) + "\n";
    (void)!write(fds[1], report.data(), report.size());
    _exit(0);
  }
  close(fds[1]);
  std::string report;
  char buf[4096];
  for (ssize_t n; (n = read(fds[0], buf, sizeof buf)) > 0;) report.append(buf, static_cast<std::size_t>(n));
  close(fds[0]);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "the child died of signal "
                                 << (WIFSIGNALED(status) ? WTERMSIG(status) : 0) << " (SIGXFSZ = " << SIGXFSZ
                                 << ")";
  ASSERT_EQ(WEXITSTATUS(status), 0);
  std::map<std::string, std::string> kv;
  for (std::size_t p = 0; p < report.size();) {
    const std::size_t e = report.find('\n', p), eq = report.find('=', p);
    kv[report.substr(p, eq - p)] = report.substr(eq + 1, e - eq - 1);
    p = e + 1;
  }
  EXPECT_NE(kv["status"].find("the file size limit (RLIMIT_FSIZE, 4194304 bytes) was reached"),
            std::string::npos)
      << report;
  EXPECT_NE(kv["status"].find("recording.sqlite"), std::string::npos) << report;
  EXPECT_EQ(kv["refused"], "20") << report;
  EXPECT_LT(std::stod(kv["max_push_ms"]), 20.0) << report;
  EXPECT_EQ(kv["close_failed"], "1") << report;
  const std::uint64_t committed = std::stoull(kv["committed"]);
  EXPECT_GT(committed, 5u) << report;

  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd) << rd.error().message;
  EXPECT_GE((*rd)->frame_count(), committed);
  const CheckReport check = (*rd)->check();
  EXPECT_TRUE(check.ok()) << check.to_string();
  auto f = (*rd)->read_frame((*rd)->frame_count() - 1);
  ASSERT_TRUE(f) << f.error().message;
  expect_same_frame(make_frame(f->raw.pair_sequence, PixelFormat::kBayerGB8, 160, 120, true), *f);
}

}  // namespace
}  // namespace augrig::recorder
