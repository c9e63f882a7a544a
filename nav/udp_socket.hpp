// udp_socket: the UDP ends of the live nav inputs. UdpReceiver binds to a configured address
// (IPv4 or IPv6; port 0 picks a free one), waits with poll(), stamps each datagram with
// CLOCK_MONOTONIC on arrival and detects datagrams longer than the maximum (MSG_TRUNC on a buffer
// one byte larger), and reads the kernel's count of datagrams dropped for a full receive buffer
// (SO_RXQ_OVFL). UdpSender sends datagrams to one address: for tests, and for a simulator or a
// bridge that replays a dataset in real time.
#pragma once

#include <chrono>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/conventions.hpp"
#include "core/expected.hpp"

namespace augrig::nav {

// A host:port pair: "127.0.0.1:5000", "[::1]:5000", "localhost:5000" (the port may be 0).
struct HostPort {
  std::string host;
  std::uint16_t port = 0;
};
// Parses "HOST:PORT"; `what` names the text in the error ("udp://...: ").
Expected<HostPort> parse_host_port(std::string_view text, const std::string& what);

struct UdpReceiverOptions {
  std::size_t max_datagram_bytes = 1472;  // longer datagrams are reported oversized, their bytes dropped
  int receive_buffer_bytes = 1 << 20;     // SO_RCVBUF asked for; 0: leave the system default
};

struct UdpDatagram {
  std::vector<std::uint8_t> bytes;  // the payload (empty when oversized)
  std::size_t size = 0;             // its full size on the wire, also when oversized
  bool oversized = false;           // size > max_datagram_bytes: bytes were not kept
  TimestampNs arrival_ns = 0;       // CLOCK_MONOTONIC right after it was read
  std::string source;               // "ADDR:PORT" of the sender
  // Datagrams the kernel dropped (full receive buffer) since the previous datagram read.
  std::uint32_t overflow_drops = 0;
};

class UdpReceiver {
 public:
  // Binds a UDP socket to host:port (host: a numeric address or a name that resolves to one;
  // "0.0.0.0" / "::" for all interfaces). Errors name the address and the reason.
  static Expected<UdpReceiver> bind(const std::string& host, std::uint16_t port,
                                    const UdpReceiverOptions& options = {});
  UdpReceiver(UdpReceiver&& o) noexcept;
  UdpReceiver& operator=(UdpReceiver&& o) noexcept;
  UdpReceiver(const UdpReceiver&) = delete;
  UdpReceiver& operator=(const UdpReceiver&) = delete;
  ~UdpReceiver();

  // Waits at most `timeout` for one datagram; true with `out` filled, false on timeout.
  Expected<bool> receive(UdpDatagram& out, std::chrono::nanoseconds timeout);

  std::uint16_t port() const { return port_; }             // the bound port (useful after port 0)
  const std::string& address() const { return address_; }  // "ADDR:PORT" bound
  int receive_buffer_bytes() const { return rcvbuf_; }     // as the kernel reports it (Linux: doubled)
  int fd() const { return fd_; }
  const UdpReceiverOptions& options() const { return options_; }

 private:
  UdpReceiver() = default;
  int fd_ = -1;
  std::uint16_t port_ = 0;
  std::string address_;
  int rcvbuf_ = 0;
  UdpReceiverOptions options_;
  std::uint32_t last_overflow_ = 0;
  std::vector<std::uint8_t> buffer_;
};

class UdpSender {
 public:
  // A socket connected to host:port. broadcast: allow a broadcast destination (SO_BROADCAST).
  static Expected<UdpSender> open(const std::string& host, std::uint16_t port, bool broadcast = false);
  UdpSender(UdpSender&& o) noexcept;
  UdpSender& operator=(UdpSender&& o) noexcept;
  UdpSender(const UdpSender&) = delete;
  UdpSender& operator=(const UdpSender&) = delete;
  ~UdpSender();

  // One datagram; an Error when it could not be sent whole.
  Status send(std::span<const std::uint8_t> bytes);
  Status send(std::string_view text);
  const std::string& destination() const { return destination_; }

 private:
  UdpSender() = default;
  int fd_ = -1;
  std::string destination_;
};

}  // namespace augrig::nav
