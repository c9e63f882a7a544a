#include "nav/ubx.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

namespace augrig::nav {

namespace {

constexpr std::size_t kMaxMessages = 1000;

// Little-endian fields at byte offsets of a payload (UBX is little endian throughout).
class Reader {
 public:
  explicit Reader(const std::vector<std::uint8_t>& p) : p_(p) {}
  std::uint64_t u(std::size_t at, int n) const {
    std::uint64_t v = 0;
    for (int i = n - 1; i >= 0; --i) v = (v << 8) | p_[at + static_cast<std::size_t>(i)];
    return v;
  }
  std::uint8_t u1(std::size_t at) const { return p_[at]; }
  std::uint16_t u2(std::size_t at) const { return static_cast<std::uint16_t>(u(at, 2)); }
  std::uint32_t u4(std::size_t at) const { return static_cast<std::uint32_t>(u(at, 4)); }
  std::int8_t i1(std::size_t at) const { return static_cast<std::int8_t>(p_[at]); }
  std::int32_t i4(std::size_t at) const { return static_cast<std::int32_t>(u4(at)); }

 private:
  const std::vector<std::uint8_t>& p_;
};

class Writer {
 public:
  explicit Writer(std::size_t n) : p_(n, 0) {}
  void u(std::size_t at, std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i)
      p_[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
  }
  void u1(std::size_t at, unsigned v) { u(at, v, 1); }
  void u2(std::size_t at, unsigned v) { u(at, v, 2); }
  void u4(std::size_t at, std::uint32_t v) { u(at, v, 4); }
  void i1(std::size_t at, int v) { u(at, static_cast<std::uint8_t>(static_cast<std::int8_t>(v)), 1); }
  void i4(std::size_t at, std::int32_t v) { u(at, static_cast<std::uint32_t>(v), 4); }
  std::vector<std::uint8_t>& data() { return p_; }

 private:
  std::vector<std::uint8_t> p_;
};

// round(v / unit) within the range of the field's integer type.
template <typename T>
T scaled(double v, double unit) {
  if (!std::isfinite(v)) return 0;
  const double x = std::round(v / unit);
  return static_cast<T>(std::clamp(x, static_cast<double>(std::numeric_limits<T>::min()),
                                   static_cast<double>(std::numeric_limits<T>::max())));
}
// An accuracy (unsigned); NaN: the largest value (unknown).
std::uint32_t accuracy(double v, double unit) {
  if (!std::isfinite(v)) return std::numeric_limits<std::uint32_t>::max();
  return scaled<std::uint32_t>(std::max(v, 0.0), unit);
}

Status expect_message(const UbxFrame& f, std::uint8_t id, const char* name) {
  if (f.cls != kUbxClassNav || f.id != id) {
    char got[32];
    std::snprintf(got, sizeof got, "0x%02X 0x%02X", f.cls, f.id);
    return make_error("nav::decode(): offset ", f.offset, ": expected ", name, ", got class/id ", got);
  }
  return {};
}

}  // namespace

std::pair<std::uint8_t, std::uint8_t> ubx_checksum(const std::uint8_t* p, std::size_t n) {
  std::uint8_t a = 0, b = 0;
  for (std::size_t i = 0; i < n; ++i) {
    a = static_cast<std::uint8_t>(a + p[i]);
    b = static_cast<std::uint8_t>(b + a);
  }
  return {a, b};
}

std::vector<std::uint8_t> encode_ubx(std::uint8_t cls, std::uint8_t id,
                                     const std::vector<std::uint8_t>& payload) {
  std::vector<std::uint8_t> f(payload.size() + 8);
  f[0] = kUbxSync1, f[1] = kUbxSync2, f[2] = cls, f[3] = id;
  f[4] = static_cast<std::uint8_t>(payload.size() & 0xFF),
  f[5] = static_cast<std::uint8_t>(payload.size() >> 8);
  std::copy(payload.begin(), payload.end(), f.begin() + 6);
  const auto [a, b] = ubx_checksum(f.data() + 2, payload.size() + 4);
  f[payload.size() + 6] = a;
  f[payload.size() + 7] = b;
  return f;
}

Expected<UbxNavPvt> decode_nav_pvt(const UbxFrame& f) {
  if (Status s = expect_message(f, kUbxIdNavPvt, "NAV-PVT (0x01 0x07)"); !s) return s.error();
  if (f.payload.size() != kUbxNavPvtLength)
    return make_error("nav::decode_nav_pvt(): offset ", f.offset, ": NAV-PVT payload of ", f.payload.size(),
                      " bytes, expected ", kUbxNavPvtLength);
  const Reader r(f.payload);
  UbxNavPvt m;
  m.itow_ms = r.u4(0);
  m.year = r.u2(4), m.month = r.u1(6), m.day = r.u1(7), m.hour = r.u1(8), m.minute = r.u1(9),
  m.second = r.u1(10);
  const std::uint8_t valid = r.u1(11);
  m.valid_date = valid & 0x01, m.valid_time = valid & 0x02, m.fully_resolved = valid & 0x04;
  m.time_accuracy_ns = r.u4(12);
  m.nano_ns = r.i4(16);
  m.fix_type = r.u1(20);
  const std::uint8_t flags = r.u1(21);
  m.gnss_fix_ok = flags & 0x01, m.diff_soln = flags & 0x02;
  m.carr_soln = (flags >> 6) & 0x03;
  m.satellites = r.u1(23);
  m.lon_deg = r.i4(24) * 1e-7, m.lat_deg = r.i4(28) * 1e-7;
  m.height_m = r.i4(32) * 1e-3, m.height_msl_m = r.i4(36) * 1e-3;
  m.h_acc_m = r.u4(40) * 1e-3, m.v_acc_m = r.u4(44) * 1e-3;
  m.vel_ned_mps = {r.i4(48) * 1e-3, r.i4(52) * 1e-3, r.i4(56) * 1e-3};
  m.speed_acc_mps = r.u4(68) * 1e-3;
  m.pdop = r.u2(76) * 0.01;
  return m;
}

Expected<UbxRelPosNed> decode_nav_relposned(const UbxFrame& f) {
  if (Status s = expect_message(f, kUbxIdNavRelPosNed, "NAV-RELPOSNED (0x01 0x3C)"); !s) return s.error();
  const std::size_t n = f.payload.size();
  if (n != kUbxRelPosNedLengthV0 && n != kUbxRelPosNedLengthV1)
    return make_error("nav::decode_nav_relposned(): offset ", f.offset, ": NAV-RELPOSNED payload of ", n,
                      " bytes, expected 40 (version 0) or 64 (version 1)");
  const Reader r(f.payload);
  UbxRelPosNed m;
  m.version = r.u1(0);
  if ((n == kUbxRelPosNedLengthV0) != (m.version == 0))
    return make_error("nav::decode_nav_relposned(): offset ", f.offset, ": NAV-RELPOSNED version ", m.version,
                      " with a payload of ", n, " bytes (version 0 has 40, version 1 has 64)");
  m.ref_station_id = r.u2(2);
  m.itow_ms = r.u4(4);
  std::uint32_t flags = 0;
  if (m.version == 0) {
    for (int k = 0; k < 3; ++k)
      m.rel_pos_ned_m[k] =
          r.i4(8 + 4 * static_cast<std::size_t>(k)) * 1e-2 + r.i1(20 + static_cast<std::size_t>(k)) * 1e-4;
    for (int k = 0; k < 3; ++k) m.acc_ned_m[k] = r.u4(24 + 4 * static_cast<std::size_t>(k)) * 1e-4;
    flags = r.u4(36);
  } else {
    for (int k = 0; k < 3; ++k)
      m.rel_pos_ned_m[k] =
          r.i4(8 + 4 * static_cast<std::size_t>(k)) * 1e-2 + r.i1(32 + static_cast<std::size_t>(k)) * 1e-4;
    m.length_m = r.i4(20) * 1e-2 + r.i1(35) * 1e-4;
    m.heading_deg = r.i4(24) * 1e-5;
    for (int k = 0; k < 3; ++k) m.acc_ned_m[k] = r.u4(36 + 4 * static_cast<std::size_t>(k)) * 1e-4;
    m.acc_length_m = r.u4(48) * 1e-4;
    m.acc_heading_deg = r.u4(52) * 1e-5;
    flags = r.u4(60);
  }
  m.gnss_fix_ok = flags & 0x01, m.diff_soln = flags & 0x02, m.rel_pos_valid = flags & 0x04;
  m.carr_soln = static_cast<int>((flags >> 3) & 0x03);
  m.is_moving = flags & 0x20, m.ref_pos_miss = flags & 0x40, m.ref_obs_miss = flags & 0x80;
  if (m.version == 1) m.heading_valid = flags & 0x100, m.normalized = flags & 0x200;
  return m;
}

std::vector<std::uint8_t> encode_nav_pvt(const UbxNavPvt& m) {
  Writer w(kUbxNavPvtLength);
  w.u4(0, m.itow_ms);
  w.u2(4, static_cast<unsigned>(m.year)), w.u1(6, static_cast<unsigned>(m.month)),
      w.u1(7, static_cast<unsigned>(m.day));
  w.u1(8, static_cast<unsigned>(m.hour)), w.u1(9, static_cast<unsigned>(m.minute)),
      w.u1(10, static_cast<unsigned>(m.second));
  w.u1(11, (m.valid_date ? 0x01u : 0u) | (m.valid_time ? 0x02u : 0u) | (m.fully_resolved ? 0x04u : 0u));
  w.u4(12, m.time_accuracy_ns);
  w.i4(16, m.nano_ns);
  w.u1(20, static_cast<unsigned>(m.fix_type));
  w.u1(21, (m.gnss_fix_ok ? 0x01u : 0u) | (m.diff_soln ? 0x02u : 0u) |
               (static_cast<unsigned>(m.carr_soln & 3) << 6));
  w.u1(23, static_cast<unsigned>(std::clamp(m.satellites, 0, 255)));
  w.i4(24, scaled<std::int32_t>(m.lon_deg, 1e-7)), w.i4(28, scaled<std::int32_t>(m.lat_deg, 1e-7));
  w.i4(32, scaled<std::int32_t>(m.height_m, 1e-3)), w.i4(36, scaled<std::int32_t>(m.height_msl_m, 1e-3));
  w.u4(40, accuracy(m.h_acc_m, 1e-3)), w.u4(44, accuracy(m.v_acc_m, 1e-3));
  for (int k = 0; k < 3; ++k)
    w.i4(48 + 4 * static_cast<std::size_t>(k), scaled<std::int32_t>(m.vel_ned_mps[k], 1e-3));
  w.i4(60, scaled<std::int32_t>(m.vel_ned_mps.head<2>().norm(), 1e-3));  // ground speed
  w.u4(68, accuracy(m.speed_acc_mps, 1e-3));
  w.u2(76, scaled<std::uint16_t>(m.pdop, 0.01));
  return encode_ubx(kUbxClassNav, kUbxIdNavPvt, w.data());
}

std::vector<std::uint8_t> encode_nav_relposned(const UbxRelPosNed& m) {
  const bool v1 = m.version != 0;
  Writer w(v1 ? kUbxRelPosNedLengthV1 : kUbxRelPosNedLengthV0);
  w.u1(0, v1 ? 1 : 0);
  w.u2(2, static_cast<unsigned>(m.ref_station_id));
  w.u4(4, m.itow_ms);
  // Whole cm, and the rest in 0.1 mm (-99..99), as the receiver splits them.
  auto split = [](double v_m, std::int32_t& cm, int& hp) {
    cm = scaled<std::int32_t>(v_m, 1e-2);
    if (!std::isfinite(v_m)) cm = 0;
    hp = std::clamp(static_cast<int>(std::lround((v_m - cm * 1e-2) / 1e-4)), -99, 99);
  };
  for (int k = 0; k < 3; ++k) {
    std::int32_t cm = 0;
    int hp = 0;
    split(m.rel_pos_ned_m[k], cm, hp);
    w.i4(8 + 4 * static_cast<std::size_t>(k), cm);
    w.i1((v1 ? 32 : 20) + static_cast<std::size_t>(k), hp);
    w.u4((v1 ? 36 : 24) + 4 * static_cast<std::size_t>(k), accuracy(m.acc_ned_m[k], 1e-4));
  }
  std::uint32_t flags = (m.gnss_fix_ok ? 0x01u : 0u) | (m.diff_soln ? 0x02u : 0u) |
                        (m.rel_pos_valid ? 0x04u : 0u) | (static_cast<std::uint32_t>(m.carr_soln & 3) << 3) |
                        (m.is_moving ? 0x20u : 0u) | (m.ref_pos_miss ? 0x40u : 0u) |
                        (m.ref_obs_miss ? 0x80u : 0u);
  if (v1) {
    std::int32_t cm = 0;
    int hp = 0;
    split(std::isfinite(m.length_m) ? m.length_m : m.rel_pos_ned_m.norm(), cm, hp);
    w.i4(20, cm);
    w.i1(35, hp);
    w.i4(24, scaled<std::int32_t>(m.heading_deg, 1e-5));
    w.u4(48, accuracy(m.acc_length_m, 1e-4));
    w.u4(52, accuracy(m.acc_heading_deg, 1e-5));
    flags |= (m.heading_valid ? 0x100u : 0u) | (m.normalized ? 0x200u : 0u);
    w.u4(60, flags);
  } else {
    w.u4(36, flags);
  }
  return encode_ubx(kUbxClassNav, kUbxIdNavRelPosNed, w.data());
}

// ---- UbxStream -----------------------------------------------------------------------------------

UbxStream::UbxStream(std::string name, std::size_t max_payload)
    : name_(std::move(name)), max_payload_(max_payload) {}

void UbxStream::note(std::uint64_t offset, const std::string& what) {
  if (messages_.size() < kMaxMessages)
    messages_.push_back(name_ + ": offset " + std::to_string(offset) + ": " + what);
}

void UbxStream::push(const std::uint8_t* data, std::size_t n) {
  // Drop what was consumed before growing, so the buffer holds at most one frame and a chunk.
  if (start_ > 0 && start_ >= buffer_.size() / 2) {
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(start_));
    buffer_offset_ += start_;
    start_ = 0;
  }
  buffer_.insert(buffer_.end(), data, data + n);
  counts_.bytes += n;
}

std::optional<UbxFrame> UbxStream::next() {
  for (;;) {
    const std::size_t avail = buffer_.size() - start_;
    const std::uint8_t* p = buffer_.data() + start_;
    // The next sync pair; everything before it is garbage (a lone 0xB5 at the end may start one).
    std::size_t k = 0;
    while (k + 1 < avail && !(p[k] == kUbxSync1 && p[k + 1] == kUbxSync2)) ++k;
    if (k + 1 >= avail && !(avail > 0 && p[avail - 1] == kUbxSync1)) k = avail;
    if (k > 0) {
      note(buffer_offset_ + start_, std::to_string(k) + " byte(s) outside any UBX frame skipped");
      counts_.skipped_bytes += k;
      start_ += k;
      continue;
    }
    if (avail < 6) return std::nullopt;  // the header is not all here yet
    const std::uint64_t offset = buffer_offset_ + start_;
    const std::size_t len = static_cast<std::size_t>(p[4]) | (static_cast<std::size_t>(p[5]) << 8);
    if (len > max_payload_) {
      ++counts_.oversized;
      note(offset, "header announces a payload of " + std::to_string(len) + " bytes (at most " +
                       std::to_string(max_payload_) + "): not a frame, searching on");
      ++counts_.skipped_bytes;
      ++start_;
      continue;
    }
    if (avail < len + 8) return std::nullopt;  // wait for the rest
    const auto [a, b] = ubx_checksum(p + 2, len + 4);
    if (a != p[len + 6] || b != p[len + 7]) {
      ++counts_.bad_checksums;
      char what[96];
      std::snprintf(what, sizeof what,
                    "bad checksum in a frame of class 0x%02X id 0x%02X (got %02X %02X, computed %02X %02X)",
                    p[2], p[3], p[len + 6], p[len + 7], a, b);
      note(offset, what);
      ++counts_.skipped_bytes;
      ++start_;  // the frame's other bytes may hold the next good frame's start
      continue;
    }
    UbxFrame f;
    f.cls = p[2];
    f.id = p[3];
    f.payload.assign(p + 6, p + 6 + len);
    f.offset = offset;
    start_ += len + 8;
    ++counts_.frames;
    counts_.frame_bytes += len + 8;
    return f;
  }
}

// ---- Log files -----------------------------------------------------------------------------------

Expected<UbxLog> read_ubx_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return make_error("nav::read_ubx_file(): ", path, ": cannot open the file");
  UbxStream stream(path);
  UbxLog log;
  std::vector<std::uint8_t> chunk(1 << 16);
  auto drain = [&] {
    while (auto f = stream.next()) {
      if (f->cls == kUbxClassNav && f->id == kUbxIdNavPvt) {
        if (auto m = decode_nav_pvt(*f))
          log.pvt.push_back(*m);
        else
          ++log.issues.malformed, log.issues.messages.push_back(path + ": " + m.error().message);
      } else if (f->cls == kUbxClassNav && f->id == kUbxIdNavRelPosNed) {
        if (auto m = decode_nav_relposned(*f))
          log.relposned.push_back(*m);
        else
          ++log.issues.malformed, log.issues.messages.push_back(path + ": " + m.error().message);
      } else {
        ++log.other_frames[{f->cls, f->id}];
      }
    }
  };
  while (in) {
    in.read(reinterpret_cast<char*>(chunk.data()), static_cast<std::streamsize>(chunk.size()));
    const auto got = static_cast<std::size_t>(in.gcount());
    if (got == 0) break;
    stream.push(chunk.data(), got);
    drain();
  }
  if (in.bad()) return make_error("nav::read_ubx_file(): ", path, ": read error");
  log.counts = stream.counts();
  log.truncated_bytes = stream.pending_bytes();
  log.issues.malformed += log.counts.bad_checksums + log.counts.oversized;
  for (const std::string& m : stream.messages()) log.issues.messages.push_back(m);
  if (log.truncated_bytes)
    log.issues.messages.push_back(path + ": the last " + std::to_string(log.truncated_bytes) +
                                  " byte(s) are a frame cut off at the end of the file");
  if (log.counts.bytes > 0 && log.counts.frames == 0)
    return make_error("nav::read_ubx_file(): ", path, ": no UBX frame in ", log.counts.bytes,
                      " bytes (expected u-blox binary: 0xB5 0x62, class, id, length, payload, checksum)");
  return log;
}

}  // namespace augrig::nav
