// Tests for nav/imu_stream.hpp. Oracles: the CRC-32 check value of "123456789" (0xCBF43926, as
// published for CRC-32/ISO-HDLC) and a bit-at-a-time CRC written here; a datagram laid out by hand
// from the byte table; the simulator's IMU samples sent over real UDP and compared bit for bit.
#include "nav/imu_stream.hpp"

#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "sim/flight.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"

namespace augrig::nav {
namespace {

using namespace std::chrono_literals;

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// Bit at a time, straight from the definition (reflected, polynomial 0x04C11DB7 reversed).
std::uint32_t crc32_bitwise(const std::vector<std::uint8_t>& bytes) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::uint8_t b : bytes) {
    c ^= b;
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return ~c;
}

std::vector<ImuSample> sim_imu(double duration_s) {
  sim::Scenario s = *sim::builtin_scenario("demo");
  s.duration_s = duration_s;
  const sim::Flight f = *sim::Flight::create(s);
  return sim::simulate_sensors(s, f).tanker_imu;
}

bool bit_equal(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

void expect_bit_equal(const ImuSample& a, const ImuSample& b, const std::string& where) {
  EXPECT_EQ(a.t_ns, b.t_ns) << where;
  EXPECT_TRUE(bit_equal(a.dt_s, b.dt_s)) << where;
  for (int i = 0; i < 3; ++i) {
    EXPECT_TRUE(bit_equal(a.dtheta_rad[i], b.dtheta_rad[i])) << where << " dtheta " << i;
    EXPECT_TRUE(bit_equal(a.dv_mps[i], b.dv_mps[i])) << where << " dv " << i;
  }
}

// Rewrites the CRC after a deliberate change, so that the checks behind it are reached.
void fix_crc(std::vector<std::uint8_t>& d) {
  const std::uint32_t c = crc32_bitwise(std::vector<std::uint8_t>(d.begin(), d.end() - 4));
  for (int i = 0; i < 4; ++i) d[d.size() - 4 + i] = static_cast<std::uint8_t>(c >> (8 * i));
}

TEST(ImuStream, Crc32) {
  const std::string check = "123456789";
  const std::vector<std::uint8_t> bytes(check.begin(), check.end());
  EXPECT_EQ(crc32_ieee(bytes), 0xCBF43926u);
  EXPECT_EQ(crc32_bitwise(bytes), 0xCBF43926u);
  EXPECT_EQ(crc32_ieee({}), 0u);
  std::vector<std::uint8_t> junk(1000);
  for (std::size_t i = 0; i < junk.size(); ++i) junk[i] = static_cast<std::uint8_t>(i * 131 + 7);
  EXPECT_EQ(crc32_ieee(junk), crc32_bitwise(junk));
}

TEST(ImuStream, DatagramLayoutMatchesTheByteTable) {
  ImuSample s;
  s.t_ns = 0x0102030405060708;
  s.dt_s = 0.5;
  s.dtheta_rad = Eigen::Vector3d(1.0, -2.0, 0.25);
  s.dv_mps = Eigen::Vector3d(0.0, 1.5, -0.0);
  auto d = encode_imu_datagram(std::span<const ImuSample>(&s, 1), 0x1122334455667788, ClockDomain::kGps);
  ASSERT_TRUE(d) << d.error().message;
  std::vector<std::uint8_t> expect = {'A',  'G',  'I',  'M',  1,    1,    4,    1,      // magic .. count
                                      0x88, 0x77, 0x66, 0x55, 0x44, 0x33, 0x22, 0x11,   // sequence
                                      0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01};  // t_ns
  const auto f64 = [&](std::uint64_t bits) {
    for (int i = 0; i < 8; ++i) expect.push_back(static_cast<std::uint8_t>(bits >> (8 * i)));
  };
  f64(0x3FE0000000000000);  // dt_s 0.5
  f64(0x3FF0000000000000);  // 1.0
  f64(0xC000000000000000);  // -2.0
  f64(0x3FD0000000000000);  // 0.25
  f64(0x0000000000000000);  // 0.0
  f64(0x3FF8000000000000);  // 1.5
  f64(0x8000000000000000);  // -0.0
  const std::uint32_t crc = crc32_bitwise(expect);
  for (int i = 0; i < 4; ++i) expect.push_back(static_cast<std::uint8_t>(crc >> (8 * i)));
  EXPECT_EQ(*d, expect);
  EXPECT_EQ(d->size(), imu_datagram_bytes(1));
  EXPECT_EQ(imu_datagram_bytes(1), 84u);
  EXPECT_EQ(imu_datagram_bytes(kImuMaxSamplesPerDatagram), 1428u);
  auto back = decode_imu_datagram(*d);
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(back->first_sequence, 0x1122334455667788u);
  EXPECT_EQ(back->clock, ClockDomain::kGps);
  ASSERT_EQ(back->samples.size(), 1u);
  expect_bit_equal(back->samples[0], s, "hand");
  EXPECT_TRUE(std::signbit(back->samples[0].dv_mps.z()));
}

TEST(ImuStream, SimulatedSamplesRoundTripBitExact) {
  const std::vector<ImuSample> samples = sim_imu(2.0);
  ASSERT_GT(samples.size(), 300u);
  std::size_t at = 0;
  std::uint64_t seq = 1000;
  for (std::size_t n = 1; at < samples.size(); n = n % kImuMaxSamplesPerDatagram + 1) {
    const std::size_t take = std::min(n, samples.size() - at);
    const auto chunk = std::span<const ImuSample>(samples).subspan(at, take);
    auto d = encode_imu_datagram(chunk, seq, ClockDomain::kSim);
    ASSERT_TRUE(d) << d.error().message;
    auto back = decode_imu_datagram(*d);
    ASSERT_TRUE(back) << back.error().message;
    EXPECT_EQ(back->first_sequence, seq);
    EXPECT_EQ(back->clock, ClockDomain::kSim);
    ASSERT_EQ(back->samples.size(), take);
    for (std::size_t k = 0; k < take; ++k) {
      expect_bit_equal(back->samples[k], chunk[k], std::to_string(at + k));
      EXPECT_EQ(back->samples[k].arrival_ns, 0);  // not sent
    }
    at += take;
    seq += take;
  }
}

TEST(ImuStream, EveryBadDatagramIsRefusedWithItsReason) {
  const std::vector<ImuSample> samples = sim_imu(0.1);
  ASSERT_GE(samples.size(), 3u);
  const auto three = std::span<const ImuSample>(samples).first(3);
  const std::vector<std::uint8_t> good = *encode_imu_datagram(three, 5);
  ASSERT_TRUE(decode_imu_datagram(good));
  struct Case {
    const char* name;
    std::function<void(std::vector<std::uint8_t>&)> change;
    bool recrc;
    const char* message;
  };
  const auto put_f64 = [](std::vector<std::uint8_t>& d, std::size_t at, double v) {
    const auto bits = std::bit_cast<std::uint64_t>(v);
    for (int i = 0; i < 8; ++i) d[at + i] = static_cast<std::uint8_t>(bits >> (8 * i));
  };
  const std::vector<Case> cases = {
      {"short", [](auto& d) { d.resize(83); }, false, "datagram of 83 bytes: expected at least 84"},
      {"empty", [](auto& d) { d.clear(); }, false, "datagram of 0 bytes"},
      {"magic", [](auto& d) { d[0] = 'X'; }, true, "bad magic 58 47 49 4D: expected 41 47 49 4D"},
      {"version", [](auto& d) { d[4] = 2; }, true, "version 2: expected 1"},
      {"count 0", [](auto& d) { d[7] = 0; }, true, "sample count 0: expected 1..22"},
      {"count 23", [](auto& d) { d[7] = 23; }, true, "sample count 23: expected 1..22"},
      {"length", [](auto& d) { d[7] = 2; }, true, "length 212 bytes: expected 148 for 2 samples"},
      {"truncated", [](auto& d) { d.resize(d.size() - 1); }, false, "length 211 bytes: expected 212"},
      {"crc", [](auto& d) { d[40] ^= 1; }, false, "bad CRC-32"},
      {"type", [](auto& d) { d[5] = 7; }, true, "message type 7: expected 1 (IMU increments)"},
      {"clock", [](auto& d) { d[6] = 9; }, true, "clock domain 9: expected 0..5"},
      {"nan", [&](auto& d) { put_f64(d, 16 + 64 + 16, NAN); }, true, "sample 1 "},
      {"dt", [&](auto& d) { put_f64(d, 16 + 8, 0.0); }, true, "expected dt_s > 0"},
      {"order", [&](auto& d) { std::copy(d.begin() + 16, d.begin() + 24, d.begin() + 16 + 128); }, true,
       "sample 2: t_ns"},
  };
  for (const Case& c : cases) {
    std::vector<std::uint8_t> d = good;
    c.change(d);
    if (c.recrc) fix_crc(d);
    auto r = decode_imu_datagram(d);
    ASSERT_FALSE(r) << c.name;
    EXPECT_TRUE(contains(r.error().message, c.message)) << c.name << ": " << r.error().message;
  }
  // The encoder refuses what the decoder would.
  EXPECT_FALSE(encode_imu_datagram({}, 0));
  std::vector<ImuSample> many(23, samples[0]);
  for (std::size_t i = 0; i < many.size(); ++i) many[i].t_ns += static_cast<TimestampNs>(i);
  auto too_many = encode_imu_datagram(many, 0);
  ASSERT_FALSE(too_many);
  EXPECT_TRUE(contains(too_many.error().message, "expected 1..22 samples, got 23"))
      << too_many.error().message;
  ImuSample bad = samples[0];
  bad.dv_mps.x() = INFINITY;
  EXPECT_FALSE(encode_imu_datagram(std::span<const ImuSample>(&bad, 1), 0));
  bad = samples[0];
  bad.dt_s = -0.005;
  EXPECT_FALSE(encode_imu_datagram(std::span<const ImuSample>(&bad, 1), 0));
  const std::vector<ImuSample> backwards = {samples[1], samples[0]};
  EXPECT_FALSE(encode_imu_datagram(backwards, 0));
}

// t_ns is bounded as in the IMU CSV log (later differences of two timestamps must not overflow
// int64) and dt_s too (fusion turns it into int64 ns): such a datagram is malformed, with a reason.
TEST(ImuStream, TimeAndIntervalOutOfRangeAreMalformed) {
  const std::vector<ImuSample> samples = sim_imu(0.1);
  ASSERT_FALSE(samples.empty());
  const std::vector<std::uint8_t> good =
      *encode_imu_datagram(std::span<const ImuSample>(samples).first(1), 0);
  const auto with = [&](std::size_t at, std::uint64_t bits) {
    std::vector<std::uint8_t> d = good;
    for (int i = 0; i < 8; ++i) d[at + i] = static_cast<std::uint8_t>(bits >> (8 * i));
    fix_crc(d);
    return d;
  };
  struct Case {
    std::vector<std::uint8_t> datagram;
    const char* message;
  };
  const std::vector<Case> cases = {
      {with(16, static_cast<std::uint64_t>(INT64_MAX)),
       "sample 0 (t_ns 9223372036854775807): t_ns: expected a time in -4e18..4e18 ns"},
      {with(16, static_cast<std::uint64_t>(INT64_MIN)), "t_ns: expected a time in -4e18..4e18 ns"},
      {with(16, 4'000'000'000'000'000'001ULL), "t_ns: expected a time in -4e18..4e18 ns"},
      {with(24, std::bit_cast<std::uint64_t>(1e300)), "expected dt_s > 0 and <= 60 s, got 1e+300"},
      {with(24, std::bit_cast<std::uint64_t>(60.5)), "expected dt_s > 0 and <= 60 s, got 60.5"},
      {with(24, std::bit_cast<std::uint64_t>(std::numeric_limits<double>::infinity())), "a value is not finite"},
  };
  ImuStreamDecoder dec("imu");
  for (const Case& c : cases) {
    auto r = decode_imu_datagram(c.datagram);
    ASSERT_FALSE(r) << c.message;
    EXPECT_TRUE(contains(r.error().message, c.message)) << r.error().message;
    dec.push(c.datagram, 1);
    EXPECT_TRUE(contains(dec.stats().last_errors.back(), c.message)) << dec.stats().last_errors.back();
  }
  EXPECT_EQ(dec.stats().malformed, cases.size());
  NavEvent e;
  EXPECT_FALSE(dec.pop(e));
  // The bounds themselves pass; the encoder refuses what the decoder would.
  EXPECT_TRUE(decode_imu_datagram(with(16, 4'000'000'000'000'000'000ULL)));
  EXPECT_TRUE(decode_imu_datagram(with(16, static_cast<std::uint64_t>(-4'000'000'000'000'000'000LL))));
  EXPECT_TRUE(decode_imu_datagram(with(24, std::bit_cast<std::uint64_t>(60.0))));
  ImuSample bad = samples[0];
  bad.t_ns = INT64_MAX;
  EXPECT_FALSE(encode_imu_datagram(std::span<const ImuSample>(&bad, 1), 0));
  bad = samples[0];
  bad.dt_s = 61;
  EXPECT_FALSE(encode_imu_datagram(std::span<const ImuSample>(&bad, 1), 0));
}

TEST(ImuStream, DecoderCountsGapsLateSamplesRestartsAndMalformed) {
  const std::vector<ImuSample> s = sim_imu(0.5);
  ASSERT_GE(s.size(), 60u);
  const auto dg = [&](std::size_t from, std::size_t n, std::uint64_t seq) {
    return *encode_imu_datagram(std::span<const ImuSample>(s).subspan(from, n), seq);
  };
  ImuStreamOptions o;
  o.restart_after_samples = 50;
  ImuStreamDecoder dec("imu", o);
  std::vector<TimestampNs> got;
  const auto drain = [&] {
    NavEvent e;
    while (dec.pop(e)) {
      EXPECT_TRUE(e.is_imu());
      got.push_back(e.t_ns());
    }
  };
  dec.push(dg(0, 4, 100), 11, "a:1");  // 100..103
  dec.push(dg(4, 2, 104), 12);         // 104..105
  dec.push(dg(10, 3, 110), 13);        // gap: 106..109 missing
  drain();
  EXPECT_EQ(dec.stats().sequence_gaps, 4u);
  EXPECT_EQ(dec.stats().dropped, 4u);
  EXPECT_TRUE(contains(dec.stats().last_errors.back(), "4 samples missing (sequence 106 to 109)"))
      << dec.stats().last_errors.back();
  dec.push(dg(7, 2, 107), 14);   // late: already passed
  dec.push(dg(12, 3, 112), 15);  // overlaps: 112 is a duplicate, 113..114 new
  drain();
  EXPECT_EQ(dec.stats().out_of_order, 3u);
  EXPECT_EQ(dec.stats().dropped, 7u);
  EXPECT_EQ(dec.expected_sequence(), 115u);
  std::vector<std::uint8_t> junk = dg(15, 1, 115);
  junk[20] ^= 0x40;
  dec.push(junk, 16, "b:2");
  EXPECT_EQ(dec.stats().malformed, 1u);
  EXPECT_TRUE(contains(dec.stats().last_errors.back(), "imu: datagram 6 from b:2: bad CRC-32"))
      << dec.stats().last_errors.back();
  // A sender restart: the sequence starts again far behind, and so may the time.
  dec.push(dg(0, 2, 0), 17);
  drain();
  EXPECT_EQ(dec.stats().restarts, 1u);
  EXPECT_EQ(dec.expected_sequence(), 2u);
  std::vector<TimestampNs> expect;
  for (std::size_t i : {0, 1, 2, 3, 4, 5, 10, 11, 12, 13, 14, 0, 1}) expect.push_back(s[i].t_ns);
  EXPECT_EQ(got, expect);
  EXPECT_EQ(dec.stats().events, expect.size());
  EXPECT_EQ(dec.stats().datagrams, 7u);
  EXPECT_LE(dec.stats().last_errors.size(), NavInputStats::kMaxErrors);
}

TEST(ImuStream, OverUdpFromTheSimulator) {
  auto opened = open_nav_input("udp://127.0.0.1:0?format=imu");
  ASSERT_TRUE(opened) << opened.error().message;
  auto* in = dynamic_cast<UdpImuInput*>(opened->get());
  ASSERT_NE(in, nullptr);
  ASSERT_NE(in->port(), 0);
  EXPECT_EQ(in->uri(), "udp://127.0.0.1:0?format=imu");
  const std::vector<ImuSample> samples = sim_imu(3.0);
  auto tx = ImuUdpSender::open("127.0.0.1", in->port(), ClockDomain::kGps, 7, 5);
  ASSERT_TRUE(tx) << tx.error().message;
  auto raw = UdpSender::open("127.0.0.1", in->port());
  ASSERT_TRUE(raw);

  std::vector<NavEvent> got;
  const auto drain = [&] {
    NavEvent e;
    for (;;) {
      auto r = (*opened)->read(e, 0ns);
      ASSERT_TRUE(r) << r.error().message;
      if (*r != NavReadStatus::kEvent) break;
      got.push_back(e);
    }
  };
  const TimestampNs start = monotonic_now_ns();
  std::vector<ImuSample> sent;
  std::size_t skipped = 0;
  for (std::size_t at = 0; at < samples.size(); at += 5) {
    const auto chunk =
        std::span<const ImuSample>(samples).subspan(at, std::min<std::size_t>(5, samples.size() - at));
    if (at / 5 == 20) {  // a lost datagram
      tx->skip(chunk.size());
      skipped += chunk.size();
    } else {
      ASSERT_TRUE(tx->send(chunk));
      sent.insert(sent.end(), chunk.begin(), chunk.end());
    }
    if (at / 5 == 30) {
      ASSERT_TRUE(raw->send(std::string_view("AGIM but not really a datagram of the format")));
      std::vector<std::uint8_t> big = *encode_imu_datagram(chunk, 0);
      big.resize(1500, 0);  // more than max_datagram (1472)
      ASSERT_TRUE(raw->send(big));
    }
    drain();
  }
  NavEvent e;
  auto r = (*opened)->read(e, 200ms);
  ASSERT_TRUE(r);
  if (*r == NavReadStatus::kEvent) got.push_back(e);
  drain();
  ASSERT_EQ(got.size(), sent.size());
  TimestampNs prev_arrival = start;
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_TRUE(got[i].is_imu());
    EXPECT_EQ(got[i].sensor_clock, ClockDomain::kGps);
    expect_bit_equal(got[i].imu(), sent[i], std::to_string(i));
    EXPECT_GE(got[i].arrival_ns(), prev_arrival) << i;  // CLOCK_MONOTONIC, in arrival order
    prev_arrival = got[i].arrival_ns();
  }
  EXPECT_LE(prev_arrival, monotonic_now_ns());
  const NavInputStats st = (*opened)->stats();
  EXPECT_EQ(st.events, sent.size());
  EXPECT_EQ(st.sequence_gaps, skipped);
  EXPECT_EQ(st.malformed, 1u);
  EXPECT_EQ(st.oversized, 1u);
  EXPECT_EQ(st.datagrams, (samples.size() + 4) / 5 - 1 + 2);
  bool named = false;
  for (const std::string& m : st.last_errors)
    named |= contains(m, "1500 bytes, more than max_datagram 1472: dropped");
  EXPECT_TRUE(named);
}

}  // namespace
}  // namespace augrig::nav
