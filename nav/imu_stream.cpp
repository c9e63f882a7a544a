#include "nav/imu_stream.hpp"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "nav/gps_time.hpp"

namespace augrig::nav {
namespace {

// ---- Little-endian fields ----

void put_u32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void put_u64(std::uint8_t* p, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void put_f64(std::uint8_t* p, double v) {
  put_u64(p, std::bit_cast<std::uint64_t>(v));
}
std::uint32_t get_u32(const std::uint8_t* p) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
std::uint64_t get_u64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
double get_f64(const std::uint8_t* p) {
  return std::bit_cast<double>(get_u64(p));
}

std::string hex32(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%08X", v);
  return buf;
}

std::string hex_bytes(std::span<const std::uint8_t> b) {
  std::string s;
  for (std::size_t i = 0; i < b.size(); ++i) {
    char buf[4];
    std::snprintf(buf, sizeof buf, i ? " %02X" : "%02X", b[i]);
    s += buf;
  }
  return s;
}

bool finite_sample(const ImuSample& s) {
  return std::isfinite(s.dt_s) && s.dtheta_rad.allFinite() && s.dv_mps.allFinite();
}

// As for the IMU CSV log (nav/logs.cpp): fusion turns dt_s into int64 ns, which 1e300 s would
// overflow, and differences of t_ns must stay inside int64 (nav/gps_time.hpp).
constexpr double kMaxImuDtS = 60.0;

// Why sample k cannot be sent or received, or "" when it can. The encoder and the decoder refuse
// the same samples.
std::string sample_problem(std::size_t k, const ImuSample& s) {
  const std::string at = "sample " + std::to_string(k) + " (t_ns " + std::to_string(s.t_ns) + "): ";
  if (!is_supported_timestamp(s.t_ns)) return at + "t_ns: expected a time in " + kTimestampRangeText;
  if (!finite_sample(s)) return at + "a value is not finite";
  if (!(s.dt_s > 0 && s.dt_s <= kMaxImuDtS)) {
    char dt[32];
    const auto r = std::to_chars(dt, dt + sizeof dt, s.dt_s);  // shortest text that reads back exactly
    return at + "expected dt_s > 0 and <= 60 s, got " + std::string(dt, r.ptr);
  }
  return {};
}

constexpr std::uint8_t kMaxClockDomain = static_cast<std::uint8_t>(ClockDomain::kSim);

}  // namespace

std::uint32_t crc32_ieee(std::span<const std::uint8_t> bytes) {
  static const auto table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::uint8_t b : bytes) c = table[(c ^ b) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

Expected<std::vector<std::uint8_t>> encode_imu_datagram(std::span<const ImuSample> samples,
                                                        std::uint64_t first_sequence, ClockDomain clock) {
  const std::string prefix = "nav::encode_imu_datagram(): ";
  if (samples.empty() || samples.size() > kImuMaxSamplesPerDatagram) {
    return make_error(prefix, "expected 1..", kImuMaxSamplesPerDatagram, " samples, got ", samples.size());
  }
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const ImuSample& s = samples[k];
    if (const std::string why = sample_problem(k, s); !why.empty()) return make_error(prefix, why);
    if (k > 0 && s.t_ns <= samples[k - 1].t_ns) {
      return make_error(prefix, "sample ", k, ": t_ns ", s.t_ns, " is not after the previous sample's");
    }
  }
  std::vector<std::uint8_t> out(imu_datagram_bytes(samples.size()));
  std::uint8_t* p = out.data();
  std::copy(kImuDatagramMagic.begin(), kImuDatagramMagic.end(), p);
  p[4] = kImuDatagramVersion;
  p[5] = kImuMessageIncrements;
  p[6] = static_cast<std::uint8_t>(clock);
  p[7] = static_cast<std::uint8_t>(samples.size());
  put_u64(p + 8, first_sequence);
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const ImuSample& s = samples[k];
    std::uint8_t* q = p + kImuHeaderBytes + k * kImuSampleBytes;
    put_u64(q, static_cast<std::uint64_t>(s.t_ns));
    put_f64(q + 8, s.dt_s);
    for (int i = 0; i < 3; ++i) put_f64(q + 16 + 8 * i, s.dtheta_rad[i]);
    for (int i = 0; i < 3; ++i) put_f64(q + 40 + 8 * i, s.dv_mps[i]);
  }
  const std::size_t body = out.size() - kImuCrcBytes;
  put_u32(p + body, crc32_ieee(std::span<const std::uint8_t>(out.data(), body)));
  return out;
}

Expected<ImuDatagram> decode_imu_datagram(std::span<const std::uint8_t> b) {
  if (b.size() < imu_datagram_bytes(1)) {
    return make_error("datagram of ", b.size(), " bytes: expected at least ", imu_datagram_bytes(1),
                      " (header, one sample, CRC)");
  }
  if (!std::equal(kImuDatagramMagic.begin(), kImuDatagramMagic.end(), b.begin())) {
    return make_error("bad magic ", hex_bytes(b.first(4)), ": expected 41 47 49 4D (\"AGIM\")");
  }
  if (b[4] != kImuDatagramVersion) {
    return make_error("version ", static_cast<int>(b[4]), ": expected ",
                      static_cast<int>(kImuDatagramVersion));
  }
  const std::size_t n = b[7];
  if (n == 0 || n > kImuMaxSamplesPerDatagram) {
    return make_error("sample count ", n, ": expected 1..", kImuMaxSamplesPerDatagram);
  }
  if (b.size() != imu_datagram_bytes(n)) {
    return make_error("length ", b.size(), " bytes: expected ", imu_datagram_bytes(n), " for ", n,
                      " samples");
  }
  const std::size_t body = b.size() - kImuCrcBytes;
  const std::uint32_t got = get_u32(b.data() + body);
  const std::uint32_t computed = crc32_ieee(b.first(body));
  if (got != computed) return make_error("bad CRC-32 ", hex32(got), " (computed ", hex32(computed), ")");
  if (b[5] != kImuMessageIncrements) {
    return make_error("message type ", static_cast<int>(b[5]), ": expected ",
                      static_cast<int>(kImuMessageIncrements), " (IMU increments)");
  }
  if (b[6] > kMaxClockDomain) {
    return make_error("clock domain ", static_cast<int>(b[6]), ": expected 0..",
                      static_cast<int>(kMaxClockDomain));
  }
  ImuDatagram d;
  d.clock = static_cast<ClockDomain>(b[6]);
  d.first_sequence = get_u64(b.data() + 8);
  d.samples.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint8_t* q = b.data() + kImuHeaderBytes + k * kImuSampleBytes;
    ImuSample& s = d.samples[k];
    s.t_ns = static_cast<TimestampNs>(get_u64(q));
    s.dt_s = get_f64(q + 8);
    for (int i = 0; i < 3; ++i) s.dtheta_rad[i] = get_f64(q + 16 + 8 * i);
    for (int i = 0; i < 3; ++i) s.dv_mps[i] = get_f64(q + 40 + 8 * i);
    // t_ns bounded like the logs' (a difference of two int64 must not overflow downstream).
    if (const std::string why = sample_problem(k, s); !why.empty()) return make_error(why);
    if (k > 0 && s.t_ns <= d.samples[k - 1].t_ns) {
      return make_error("sample ", k, ": t_ns ", s.t_ns, " is not after the previous sample's");
    }
  }
  return d;
}

// ---- ImuStreamDecoder -----------------------------------------------------------------------------

ImuStreamDecoder::ImuStreamDecoder(std::string name, const ImuStreamOptions& options)
    : name_(std::move(name)), options_(options) {}

void ImuStreamDecoder::push(std::span<const std::uint8_t> bytes, TimestampNs arrival_ns,
                            const std::string& source) {
  ++stats_.datagrams;
  stats_.bytes += bytes.size();
  const std::string from = name_ + ": datagram " + std::to_string(stats_.datagrams) +
                           (source.empty() ? "" : " from " + source) + ": ";
  auto d = decode_imu_datagram(bytes);
  if (!d) {
    ++stats_.malformed;
    stats_.note(from + d.error().message + ": dropped");
    return;
  }
  if (clock_ && *clock_ != d->clock) {
    stats_.note(from + "clock domain changed from " + std::string(to_string(*clock_)) + " to " +
                std::string(to_string(d->clock)));
  }
  clock_ = d->clock;
  const std::uint64_t first = d->first_sequence;
  const std::uint64_t n = d->samples.size();
  std::uint64_t skip = 0;  // leading samples already delivered or passed
  if (expected_) {
    if (first > *expected_) {
      const std::uint64_t gap = first - *expected_;
      stats_.sequence_gaps += gap;
      stats_.dropped += gap;
      stats_.note(from + std::to_string(gap) + " samples missing (sequence " + std::to_string(*expected_) +
                  " to " + std::to_string(first - 1) + ")");
    } else if (first < *expected_) {
      const std::uint64_t back = *expected_ - first;
      if (back >= options_.restart_after_samples) {
        ++stats_.restarts;
        stats_.note(from + "sequence restarted at " + std::to_string(first) + " (expected " +
                    std::to_string(*expected_) + ")");
        last_t_ns_.reset();
        expected_.reset();
      } else {
        skip = std::min(back, n);
        stats_.out_of_order += skip;
        stats_.dropped += skip;
        stats_.note(from + "sequence " + std::to_string(first) + " is behind the expected " +
                    std::to_string(*expected_) + ": " + std::to_string(skip) +
                    " late or duplicate samples dropped");
      }
    }
  }
  for (std::uint64_t k = skip; k < n; ++k) {
    ImuSample& s = d->samples[k];
    if (last_t_ns_ && s.t_ns <= *last_t_ns_) {
      ++stats_.out_of_order;
      ++stats_.dropped;
      stats_.note(from + "sample " + std::to_string(first + k) + ": t_ns " + std::to_string(s.t_ns) +
                  " is not after the previous sample's " + std::to_string(*last_t_ns_) + ": dropped");
      continue;
    }
    last_t_ns_ = s.t_ns;
    s.arrival_ns = arrival_ns;
    NavEvent& e = ready_.emplace_back();
    e.sample.emplace<ImuSample>(s);
    e.sensor_clock = d->clock;
  }
  expected_ = std::max(expected_.value_or(0), first + n);
}

bool ImuStreamDecoder::pop(NavEvent& out) {
  if (ready_.empty()) return false;
  out = std::move(ready_.front());
  ready_.pop_front();
  ++stats_.events;
  return true;
}

// ---- UdpImuInput ----------------------------------------------------------------------------------

UdpImuInput::UdpImuInput(UdpReceiver socket, std::string uri, const UdpImuOptions& options)
    : socket_(std::move(socket)), uri_(std::move(uri)), decoder_(uri_, options.stream) {}

Expected<std::unique_ptr<UdpImuInput>> UdpImuInput::open(const std::string& bind_host, std::uint16_t port,
                                                         const UdpImuOptions& options, std::string uri) {
  if (uri.empty()) uri = "udp://" + bind_host + ":" + std::to_string(port) + "?format=imu";
  UdpReceiverOptions ro;
  ro.max_datagram_bytes = options.max_datagram_bytes;
  ro.receive_buffer_bytes = options.receive_buffer_bytes;
  auto socket = UdpReceiver::bind(bind_host, port, ro);
  if (!socket) return socket.error();
  return std::unique_ptr<UdpImuInput>(new UdpImuInput(std::move(*socket), std::move(uri), options));
}

Expected<NavReadStatus> UdpImuInput::read(NavEvent& out, std::chrono::nanoseconds timeout) {
  const TimestampNs deadline = monotonic_now_ns() + std::max<std::int64_t>(timeout.count(), 0);
  for (;;) {
    if (decoder_.pop(out)) return NavReadStatus::kEvent;
    const TimestampNs left = std::max<TimestampNs>(deadline - monotonic_now_ns(), 0);
    auto got = socket_.receive(datagram_, std::chrono::nanoseconds(left));
    if (!got) return got.error();
    if (!*got) return NavReadStatus::kTimeout;
    NavInputStats& st = decoder_.stats();
    if (datagram_.oversized) {  // the decoder counts the others
      ++st.datagrams;
      st.bytes += datagram_.size;
    }
    if (!udp_datagram_usable(st, datagram_, uri_, socket_.options().max_datagram_bytes)) continue;
    tap(std::string_view(reinterpret_cast<const char*>(datagram_.bytes.data()), datagram_.bytes.size()),
        datagram_.arrival_ns, true);
    decoder_.push(datagram_.bytes, datagram_.arrival_ns, datagram_.source);
  }
}

// ---- ImuUdpSender ---------------------------------------------------------------------------------

Expected<ImuUdpSender> ImuUdpSender::open(const std::string& host, std::uint16_t port, ClockDomain clock,
                                          std::uint64_t first_sequence, std::size_t samples_per_datagram,
                                          bool broadcast) {
  if (samples_per_datagram == 0 || samples_per_datagram > kImuMaxSamplesPerDatagram) {
    return make_error("nav::ImuUdpSender::open(): ", host, ":", port, ": samples_per_datagram must be 1..",
                      kImuMaxSamplesPerDatagram, ", got ", samples_per_datagram);
  }
  auto sender = UdpSender::open(host, port, broadcast);
  if (!sender) return sender.error();
  return ImuUdpSender(std::move(*sender), clock, first_sequence, samples_per_datagram);
}

Status ImuUdpSender::send(std::span<const ImuSample> samples) {
  for (std::size_t i = 0; i < samples.size(); i += per_datagram_) {
    const auto chunk = samples.subspan(i, std::min(per_datagram_, samples.size() - i));
    auto bytes = encode_imu_datagram(chunk, next_sequence_, clock_);
    if (!bytes) return bytes.error();
    if (auto s = sender_.send(*bytes); !s) return s;
    next_sequence_ += chunk.size();
  }
  return {};
}

}  // namespace augrig::nav
