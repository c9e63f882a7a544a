// nav/ubx: the UBX frame and checksum against the u-blox interface description's bytes (a poll of
// NAV-PVT is B5 62 01 07 00 00 08 19), NAV-PVT and NAV-RELPOSNED payloads laid out by hand at the
// documented offsets (not by the encoder) and decoded, the encoder's round trip, and the stream's
// resynchronisation: frames split anywhere, garbage, bad checksums, impossible lengths and a
// truncated end are counted, never thrown, and the counts add up.
#include "nav/ubx.hpp"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>

#include "tests/support/test_support.hpp"

namespace augrig::nav {
namespace {

void put(std::vector<std::uint8_t>& p, std::size_t at, std::uint64_t v, int n) {
  for (int i = 0; i < n; ++i) p[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
}

std::vector<std::uint8_t> frame_bytes(std::uint8_t cls, std::uint8_t id,
                                      const std::vector<std::uint8_t>& payload) {
  // Sync, header and checksum computed here, independently of ubx_checksum().
  std::vector<std::uint8_t> f = {0xB5,
                                 0x62,
                                 cls,
                                 id,
                                 static_cast<std::uint8_t>(payload.size()),
                                 static_cast<std::uint8_t>(payload.size() >> 8)};
  f.insert(f.end(), payload.begin(), payload.end());
  unsigned a = 0, b = 0;
  for (std::size_t i = 2; i < f.size(); ++i) a = (a + f[i]) & 0xFF, b = (b + a) & 0xFF;
  f.push_back(static_cast<std::uint8_t>(a));
  f.push_back(static_cast<std::uint8_t>(b));
  return f;
}

std::vector<UbxFrame> all_frames(UbxStream& s) {
  std::vector<UbxFrame> out;
  while (auto f = s.next()) out.push_back(*f);
  return out;
}

TEST(Ubx, ChecksumOfThePollOfNavPvt) {
  const std::vector<std::uint8_t> poll = encode_ubx(0x01, 0x07, {});
  EXPECT_EQ(poll, (std::vector<std::uint8_t>{0xB5, 0x62, 0x01, 0x07, 0x00, 0x00, 0x08, 0x19}));
  const std::vector<std::uint8_t> payload = {1, 2, 3, 250, 251};
  EXPECT_EQ(encode_ubx(0x0A, 0x04, payload), frame_bytes(0x0A, 0x04, payload));
}

// A NAV-RELPOSNED version 1 as an F9P rover sends it, laid out at the interface description's
// offsets: N = 1234 cm + 56 x 0.1 mm, E = -2 cm - 7 x 0.1 mm, D = 567 cm, carrier fixed.
TEST(Ubx, RelPosNedVersion1FromItsDocumentedLayout) {
  std::vector<std::uint8_t> p(64, 0);
  put(p, 0, 1, 1);                                              // version
  put(p, 2, 7, 2);                                              // refStationId
  put(p, 4, 345600123, 4);                                      // iTOW ms
  put(p, 8, 1234, 4);                                           // relPosN cm
  put(p, 12, static_cast<std::uint32_t>(-2), 4);                // relPosE cm
  put(p, 16, 567, 4);                                           // relPosD cm
  put(p, 20, 1372, 4);                                          // relPosLength cm
  put(p, 24, 35712345, 4);                                      // relPosHeading 1e-5 deg
  put(p, 32, 56, 1);                                            // relPosHPN 0.1 mm
  put(p, 33, static_cast<std::uint8_t>(-7), 1);                 // relPosHPE
  put(p, 34, 0, 1);                                             // relPosHPD
  put(p, 35, 3, 1);                                             // relPosHPLength
  put(p, 36, 100, 4), put(p, 40, 120, 4), put(p, 44, 250, 4);   // accN/E/D 0.1 mm
  put(p, 48, 130, 4);                                           // accLength
  put(p, 52, 50000, 4);                                         // accHeading 1e-5 deg
  put(p, 60, 0x01 | 0x02 | 0x04 | (2 << 3) | 0x20 | 0x100, 4);  // fixOK, diff, valid, fixed, moving, heading
  UbxStream s("t");
  const auto bytes = frame_bytes(0x01, 0x3C, p);
  s.push(bytes.data(), bytes.size());
  auto f = s.next();
  ASSERT_TRUE(f);
  auto m = decode_nav_relposned(*f);
  ASSERT_TRUE(m) << m.error().message;
  EXPECT_EQ(m->version, 1);
  EXPECT_EQ(m->ref_station_id, 7);
  EXPECT_EQ(m->itow_ms, 345600123u);
  EXPECT_NEAR(m->rel_pos_ned_m.x(), 12.3456, 1e-12);
  EXPECT_NEAR(m->rel_pos_ned_m.y(), -0.0207, 1e-12);
  EXPECT_NEAR(m->rel_pos_ned_m.z(), 5.67, 1e-12);
  EXPECT_NEAR(m->length_m, 13.7203, 1e-12);
  EXPECT_NEAR(m->heading_deg, 357.12345, 1e-9);
  EXPECT_NEAR(m->acc_ned_m.x(), 0.010, 1e-12);
  EXPECT_NEAR(m->acc_ned_m.z(), 0.025, 1e-12);
  EXPECT_NEAR(m->acc_heading_deg, 0.5, 1e-12);
  EXPECT_TRUE(m->gnss_fix_ok && m->diff_soln && m->rel_pos_valid && m->is_moving && m->heading_valid);
  EXPECT_FALSE(m->ref_pos_miss || m->ref_obs_miss || m->normalized);
  EXPECT_EQ(m->carr_soln, 2);
}

TEST(Ubx, RelPosNedVersion0AndLengthVersionMismatch) {
  std::vector<std::uint8_t> p(40, 0);
  put(p, 0, 0, 1);
  put(p, 4, 1000, 4);
  put(p, 8, static_cast<std::uint32_t>(-150), 4);  // N -150 cm
  put(p, 20, static_cast<std::uint8_t>(-5), 1);    // HPN -5 x 0.1 mm
  put(p, 24, 300, 4);                              // accN 0.1 mm
  put(p, 36, 0x04 | (1 << 3), 4);                  // valid, float
  UbxFrame f{0x01, 0x3C, p, 0};
  auto m = decode_nav_relposned(f);
  ASSERT_TRUE(m) << m.error().message;
  EXPECT_EQ(m->version, 0);
  EXPECT_NEAR(m->rel_pos_ned_m.x(), -1.5005, 1e-12);
  EXPECT_NEAR(m->acc_ned_m.x(), 0.03, 1e-12);
  EXPECT_TRUE(std::isnan(m->length_m));
  EXPECT_EQ(m->carr_soln, 1);
  EXPECT_TRUE(m->rel_pos_valid);
  // Version 1 in a 40-byte payload; a 52-byte payload; another message.
  f.payload[0] = 1;
  auto bad = decode_nav_relposned(f);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("version 1 with a payload of 40 bytes"), std::string::npos)
      << bad.error().message;
  f.payload.resize(52);
  EXPECT_FALSE(decode_nav_relposned(f));
  f.id = 0x07;
  bad = decode_nav_relposned(f);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("expected NAV-RELPOSNED"), std::string::npos) << bad.error().message;
}

TEST(Ubx, NavPvtFromItsDocumentedLayout) {
  std::vector<std::uint8_t> p(92, 0);
  put(p, 0, 302418000, 4);  // iTOW
  put(p, 4, 2016, 2), put(p, 6, 12, 1), put(p, 7, 31, 1), put(p, 8, 23, 1), put(p, 9, 59, 1),
      put(p, 10, 42, 1);
  put(p, 11, 0x07, 1);                               // validDate, validTime, fullyResolved
  put(p, 12, 25, 4);                                 // tAcc ns
  put(p, 16, static_cast<std::uint32_t>(-1200), 4);  // nano
  put(p, 20, 3, 1);                                  // 3D
  put(p, 21, 0x01 | 0x02 | (2 << 6), 1);
  put(p, 23, 17, 1);
  put(p, 24, static_cast<std::uint32_t>(-1177456789), 4);  // lon 1e-7 deg
  put(p, 28, 340123456, 4);                                // lat
  put(p, 32, 1523456, 4), put(p, 36, 1500000, 4);          // height, hMSL mm
  put(p, 40, 14, 4), put(p, 44, 20, 4);                    // hAcc, vAcc mm
  put(p, 48, 150123, 4), put(p, 52, static_cast<std::uint32_t>(-2000), 4), put(p, 56, 300, 4);  // vel mm/s
  put(p, 68, 30, 4);                                                                            // sAcc
  put(p, 76, 123, 2);                                                                           // pDOP 0.01
  auto m = decode_nav_pvt(UbxFrame{0x01, 0x07, p, 0});
  ASSERT_TRUE(m) << m.error().message;
  EXPECT_EQ(m->itow_ms, 302418000u);
  EXPECT_EQ(m->year, 2016);
  EXPECT_EQ(m->second, 42);
  EXPECT_EQ(m->nano_ns, -1200);
  EXPECT_TRUE(m->valid_date && m->valid_time && m->fully_resolved);
  EXPECT_EQ(m->fix_type, 3);
  EXPECT_EQ(m->carr_soln, 2);
  EXPECT_EQ(m->satellites, 17);
  EXPECT_NEAR(m->lon_deg, -117.7456789, 1e-12);
  EXPECT_NEAR(m->lat_deg, 34.0123456, 1e-12);
  EXPECT_NEAR(m->height_m, 1523.456, 1e-9);
  EXPECT_NEAR(m->h_acc_m, 0.014, 1e-12);
  EXPECT_NEAR(m->vel_ned_mps.x(), 150.123, 1e-9);
  EXPECT_NEAR(m->vel_ned_mps.y(), -2.0, 1e-12);
  EXPECT_NEAR(m->pdop, 1.23, 1e-12);
  EXPECT_FALSE(decode_nav_pvt(UbxFrame{0x01, 0x07, std::vector<std::uint8_t>(91), 0}));
}

TEST(Ubx, EncoderRoundTrips) {
  UbxRelPosNed r;
  r.version = 1;
  r.itow_ms = 99;
  r.rel_pos_ned_m = {-25.43217, 0.98765, 7.00049};
  r.length_m = r.rel_pos_ned_m.norm();
  r.heading_deg = 182.5;
  r.acc_ned_m = {0.0112, 0.0113, 0.0251};
  r.acc_length_m = 0.012;
  r.acc_heading_deg = 0.3;
  r.gnss_fix_ok = r.diff_soln = r.rel_pos_valid = r.is_moving = r.heading_valid = true;
  r.carr_soln = 1;
  for (int version : {0, 1}) {
    r.version = version;
    const auto bytes = encode_nav_relposned(r);
    EXPECT_EQ(bytes.size(), (version ? 64u : 40u) + 8u);
    UbxStream s("t");
    s.push(bytes.data(), bytes.size());
    auto f = s.next();
    ASSERT_TRUE(f);
    auto m = decode_nav_relposned(*f);
    ASSERT_TRUE(m) << m.error().message;
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(m->rel_pos_ned_m[k], r.rel_pos_ned_m[k], 0.5e-4) << "0.1 mm resolution";
      EXPECT_NEAR(m->acc_ned_m[k], r.acc_ned_m[k], 0.5e-4);
    }
    EXPECT_EQ(m->carr_soln, 1);
    EXPECT_TRUE(m->is_moving);
    if (version) {
      EXPECT_NEAR(m->length_m, r.length_m, 0.5e-4);
      EXPECT_NEAR(m->heading_deg, 182.5, 1e-9);
      EXPECT_TRUE(m->heading_valid);
    }
  }
  UbxNavPvt p;
  p.itow_ms = 5;
  p.year = 2026, p.month = 11, p.day = 26, p.hour = 1, p.minute = 2, p.second = 3, p.nano_ns = 400;
  p.valid_date = p.valid_time = true;
  p.fix_type = 3;
  p.gnss_fix_ok = true;
  p.lat_deg = 47.1234567, p.lon_deg = 8.7654321, p.height_m = 2000.123;
  p.h_acc_m = 1.5, p.v_acc_m = 2.5;
  p.vel_ned_mps = {120.5, -3.25, 0.5};
  const auto bytes = encode_nav_pvt(p);
  UbxStream s("t");
  s.push(bytes.data(), bytes.size());
  auto m = decode_nav_pvt(*s.next());
  ASSERT_TRUE(m) << m.error().message;
  EXPECT_NEAR(m->lat_deg, p.lat_deg, 1e-12);
  EXPECT_NEAR(m->lon_deg, p.lon_deg, 1e-12);
  EXPECT_NEAR(m->height_m, p.height_m, 1e-9);
  EXPECT_NEAR(m->h_acc_m, 1.5, 1e-12);
  EXPECT_EQ(m->day, 26);
  EXPECT_EQ(m->nano_ns, 400);
  EXPECT_TRUE(m->valid_date && !m->fully_resolved);
}

// Frames pushed one byte at a time, or in any chunks, come out the same; garbage before, between
// and after is skipped and counted; bytes add up.
TEST(UbxStream, ChunksGarbageAndCountsAddUp) {
  UbxRelPosNed r;
  std::vector<std::uint8_t> bytes = {0x00, 0xB5, 0x00, 0x62, 0xB5};  // garbage, a false sync start
  std::vector<std::uint64_t> offsets;
  for (int i = 0; i < 20; ++i) {
    r.itow_ms = static_cast<std::uint32_t>(i);
    r.rel_pos_ned_m.x() = i * 0.25;
    const auto f = encode_nav_relposned(r);
    offsets.push_back(bytes.size());
    bytes.insert(bytes.end(), f.begin(), f.end());
    if (i % 3 == 0) bytes.insert(bytes.end(), {0x11, 0x22, 0x33});
  }
  bytes.push_back(0xB5);  // a lone sync byte at the end: pending
  std::mt19937 rng(3);
  for (int trial = 0; trial < 3; ++trial) {
    UbxStream s("t");
    std::vector<UbxFrame> frames;
    for (std::size_t at = 0; at < bytes.size();) {
      const std::size_t n = trial == 0 ? 1 : std::min<std::size_t>(bytes.size() - at, 1 + rng() % 97);
      s.push(bytes.data() + at, n);
      at += n;
      for (auto& f : all_frames(s)) frames.push_back(f);
    }
    ASSERT_EQ(frames.size(), 20u) << "trial " << trial;
    for (int i = 0; i < 20; ++i) {
      EXPECT_EQ(frames[static_cast<std::size_t>(i)].offset, offsets[static_cast<std::size_t>(i)]);
      EXPECT_EQ(decode_nav_relposned(frames[static_cast<std::size_t>(i)])->itow_ms,
                static_cast<std::uint32_t>(i));
    }
    const UbxStreamCounts& c = s.counts();
    EXPECT_EQ(c.bytes, bytes.size());
    EXPECT_EQ(c.bytes, c.frame_bytes + c.skipped_bytes + s.pending_bytes());
    EXPECT_EQ(s.pending_bytes(), 1u);
    EXPECT_EQ(c.skipped_bytes, 5u + 7u * 3u);
  }
}

// A damaged frame is skipped and the next one still found, even when the damage is in the length
// (the bad frame would otherwise swallow the good one after it); an impossible length likewise.
TEST(UbxStream, DamagedFramesDoNotSwallowTheNext) {
  UbxRelPosNed r;
  const auto good = encode_nav_relposned(r);
  for (std::size_t flip = 2; flip < good.size(); ++flip) {
    std::vector<std::uint8_t> bytes = good;
    bytes[flip] ^= 0x5A;
    bytes.insert(bytes.end(), good.begin(), good.end());
    UbxStream s("t", 512);
    s.push(bytes.data(), bytes.size());
    std::vector<UbxFrame> frames = all_frames(s);
    ASSERT_GE(frames.size(), 1u) << "flip at " << flip;
    EXPECT_EQ(frames.back().offset, good.size()) << "flip at " << flip;
    const UbxStreamCounts& c = s.counts();
    EXPECT_GE(c.bad_checksums + c.oversized, 1u) << "flip at " << flip;
    EXPECT_EQ(c.bytes, c.frame_bytes + c.skipped_bytes + s.pending_bytes());
    ASSERT_FALSE(s.messages().empty());
    EXPECT_EQ(s.messages().front().rfind("t: offset 0: ", 0), 0u) << s.messages().front();
  }
}

TEST(UbxStream, RandomBytesNeverCrashAndAddUp) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<std::uint8_t> bytes(1 + rng() % 3000);
    for (auto& b : bytes)
      b = static_cast<std::uint8_t>(rng() % 4 == 0 ? 0xB5 : rng() % 4 == 0 ? 0x62 : rng());
    UbxStream s("t", 1 + rng() % 100);
    for (std::size_t at = 0; at < bytes.size();) {
      const std::size_t n = std::min<std::size_t>(bytes.size() - at, 1 + rng() % 300);
      s.push(bytes.data() + at, n);
      at += n;
      all_frames(s);
    }
    EXPECT_EQ(s.counts().bytes, s.counts().frame_bytes + s.counts().skipped_bytes + s.pending_bytes());
  }
}

TEST(UbxLog, ReadsTheNavMessagesAndSaysWhatItSkipped) {
  const std::string dir = test::output_dir("ubx_log");
  UbxRelPosNed r;
  UbxNavPvt p;
  std::vector<std::uint8_t> bytes;
  for (int i = 0; i < 5; ++i) {
    r.itow_ms = p.itow_ms = static_cast<std::uint32_t>(200 * i);
    for (const auto& f : {encode_nav_pvt(p), encode_nav_relposned(r), encode_ubx(0x01, 0x35, {1, 2, 3})})
      bytes.insert(bytes.end(), f.begin(), f.end());
  }
  bytes[10] ^= 1;  // the first NAV-PVT's payload: a bad checksum
  const auto last = encode_nav_relposned(r);
  bytes.insert(bytes.end(), last.begin(), last.begin() + 20);  // cut off
  std::ofstream(dir + "/log.ubx", std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  auto log = read_ubx_file(dir + "/log.ubx");
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_EQ(log->pvt.size(), 4u);
  EXPECT_EQ(log->relposned.size(), 5u);
  EXPECT_EQ((log->other_frames[{0x01, 0x35}]), 5u);
  EXPECT_EQ(log->counts.bad_checksums, 1u);
  EXPECT_EQ(log->truncated_bytes, 20u);
  EXPECT_EQ(log->issues.malformed, 1u);
  bool named = false;
  for (const std::string& m : log->issues.messages)
    named = named || m.find("log.ubx: offset 0: bad checksum") != std::string::npos;
  EXPECT_TRUE(named);
  // Not UBX at all; no file.
  std::ofstream(dir + "/text.ubx") << "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\n";
  auto text = read_ubx_file(dir + "/text.ubx");
  ASSERT_FALSE(text);
  EXPECT_NE(text.error().message.find("text.ubx: no UBX frame"), std::string::npos) << text.error().message;
  auto none = read_ubx_file(dir + "/missing.ubx");
  ASSERT_FALSE(none);
  EXPECT_NE(none.error().message.find("missing.ubx: cannot open"), std::string::npos);
}

}  // namespace
}  // namespace augrig::nav
