// imu_stream: IMU increments over UDP in a small binary datagram (augrig IMU datagram, version 1),
// its encoder and decoder, the live input that receives it (udp://ADDR:PORT?format=imu) and a sender.
//
// Datagram, all little-endian, doubles IEEE-754 binary64 (byte table in docs/NAV_LIVE.md):
//   offset  size  field
//   0       4     magic "AGIM" (41 47 49 4D)
//   4       1     version, 1
//   5       1     message type, 1 = IMU increments
//   6       1     clock domain of t_ns (core/conventions.hpp ClockDomain value)
//   7       1     sample count n, 1..kImuMaxSamplesPerDatagram
//   8       8     u64 sequence number of the first sample (the others follow: +1 per sample)
//   16+64k  64    sample k: i64 t_ns, f64 dt_s, f64 dtheta_rad[3], f64 dv_mps[3] (body FRD)
//   16+64n  4     u32 CRC-32 (IEEE 802.3 / zlib) of bytes [0, 16+64n)
// The sequence numbers count samples, so a lost datagram shows as a gap of its sample count.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "nav/live_input.hpp"
#include "nav/types.hpp"
#include "nav/udp_socket.hpp"

namespace augrig::nav {

inline constexpr std::array<std::uint8_t, 4> kImuDatagramMagic = {'A', 'G', 'I', 'M'};
inline constexpr std::uint8_t kImuDatagramVersion = 1;
inline constexpr std::uint8_t kImuMessageIncrements = 1;
inline constexpr std::size_t kImuHeaderBytes = 16;
inline constexpr std::size_t kImuSampleBytes = 64;
inline constexpr std::size_t kImuCrcBytes = 4;
// 22 samples make 1428 bytes: with IP and UDP headers within a 1500-byte Ethernet MTU.
inline constexpr std::size_t kImuMaxSamplesPerDatagram = 22;

constexpr std::size_t imu_datagram_bytes(std::size_t samples) {
  return kImuHeaderBytes + samples * kImuSampleBytes + kImuCrcBytes;
}

// CRC-32 as in IEEE 802.3, zlib and PNG (reflected, polynomial 0xEDB88320, init and final xor
// 0xFFFFFFFF): "123456789" -> 0xCBF43926.
std::uint32_t crc32_ieee(std::span<const std::uint8_t> bytes);

// One datagram of 1..kImuMaxSamplesPerDatagram samples; the sequence of samples[k] is
// first_sequence + k. An Error for no samples, too many, or values the decoder would refuse
// (t_ns outside nav/gps_time.hpp's -4e18..4e18 ns, non-finite, dt_s outside (0, 60] s, t_ns not
// increasing). arrival_ns is not sent.
Expected<std::vector<std::uint8_t>> encode_imu_datagram(std::span<const ImuSample> samples,
                                                        std::uint64_t first_sequence,
                                                        ClockDomain clock = ClockDomain::kGps);

struct ImuDatagram {
  std::uint64_t first_sequence = 0;
  ClockDomain clock = ClockDomain::kUnknown;
  std::vector<ImuSample> samples;  // arrival_ns = 0
};
// Checks, in this order: size, magic, version, length against the count, CRC, message type, clock
// domain, values. The Error says which check failed and what was expected.
Expected<ImuDatagram> decode_imu_datagram(std::span<const std::uint8_t> bytes);

struct ImuStreamOptions {
  // A sequence number this far or more behind the expected one is a sender restart (the stream
  // starts anew) rather than a late datagram.
  std::uint64_t restart_after_samples = 1000;
};

// The receiving logic without the socket: datagrams in, samples out in sequence, with gaps,
// late/duplicate samples and restarts counted.
class ImuStreamDecoder {
 public:
  ImuStreamDecoder(std::string name, const ImuStreamOptions& options = {});
  // One received datagram (its payload, the time it arrived, who sent it for messages).
  void push(std::span<const std::uint8_t> bytes, TimestampNs arrival_ns, const std::string& source = {});
  bool pop(NavEvent& out);
  std::size_t ready() const { return ready_.size(); }
  NavInputStats& stats() { return stats_; }
  const NavInputStats& stats() const { return stats_; }
  // The sequence number expected next; nullopt before the first datagram.
  std::optional<std::uint64_t> expected_sequence() const { return expected_; }

 private:
  std::string name_;
  ImuStreamOptions options_;
  NavInputStats stats_;
  std::optional<std::uint64_t> expected_;
  std::optional<TimestampNs> last_t_ns_;
  std::optional<ClockDomain> clock_;
  std::deque<NavEvent> ready_;
};

struct UdpImuOptions {
  std::size_t max_datagram_bytes = 1472;  // larger datagrams are counted as oversized and dropped
  int receive_buffer_bytes = 1 << 20;     // SO_RCVBUF asked for (the kernel may cap it)
  ImuStreamOptions stream;
};

// udp://BIND_ADDR:PORT?format=imu
class UdpImuInput : public NavInput {
 public:
  static Expected<std::unique_ptr<UdpImuInput>> open(const std::string& bind_host, std::uint16_t port,
                                                     const UdpImuOptions& options = {}, std::string uri = {});
  std::string uri() const override { return uri_; }
  Expected<NavReadStatus> read(NavEvent& out, std::chrono::nanoseconds timeout) override;
  NavInputStats stats() const override { return decoder_.stats(); }
  std::uint16_t port() const { return socket_.port(); }
  std::uint16_t udp_port() const override { return port(); }
  const UdpReceiver& socket() const { return socket_; }

 private:
  UdpImuInput(UdpReceiver socket, std::string uri, const UdpImuOptions& options);
  UdpReceiver socket_;
  std::string uri_;
  ImuStreamDecoder decoder_;
  UdpDatagram datagram_;
};

// Sends IMU samples as datagrams of at most samples_per_datagram, numbering them from
// first_sequence: what an INS or a replaying simulator does.
class ImuUdpSender {
 public:
  // broadcast: host may be a broadcast address (SO_BROADCAST).
  static Expected<ImuUdpSender> open(const std::string& host, std::uint16_t port,
                                     ClockDomain clock = ClockDomain::kGps, std::uint64_t first_sequence = 0,
                                     std::size_t samples_per_datagram = 1, bool broadcast = false);
  // Splits `samples` into datagrams and sends them in order.
  Status send(std::span<const ImuSample> samples);
  std::uint64_t next_sequence() const { return next_sequence_; }
  // Skips sequence numbers (as if samples were lost), for tests of the receiver.
  void skip(std::uint64_t samples) { next_sequence_ += samples; }
  UdpSender& socket() { return sender_; }

 private:
  ImuUdpSender(UdpSender sender, ClockDomain clock, std::uint64_t first_sequence, std::size_t per_datagram)
      : sender_(std::move(sender)),
        clock_(clock),
        next_sequence_(first_sequence),
        per_datagram_(per_datagram) {}
  UdpSender sender_;
  ClockDomain clock_;
  std::uint64_t next_sequence_;
  std::size_t per_datagram_;
};

}  // namespace augrig::nav
