#include "nav/udp_socket.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <ctime>
#include <utility>

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include "core/clock.hpp"

namespace augrig::nav {
namespace {

std::string errno_text(int e) {
  return std::strerror(e);
}

// "ADDR:PORT" ("[ADDR]:PORT" for IPv6) of a socket address.
std::string address_text(const sockaddr* sa, socklen_t len) {
  char host[NI_MAXHOST] = {0};
  char serv[NI_MAXSERV] = {0};
  if (getnameinfo(sa, len, host, sizeof host, serv, sizeof serv, NI_NUMERICHOST | NI_NUMERICSERV) != 0) {
    return "?";
  }
  return sa->sa_family == AF_INET6 ? "[" + std::string(host) + "]:" + serv : std::string(host) + ":" + serv;
}

struct AddrInfo {
  addrinfo* list = nullptr;
  ~AddrInfo() {
    if (list) freeaddrinfo(list);
  }
};

// Resolves host:port for a UDP socket; `passive` for bind().
Expected<addrinfo*> resolve(AddrInfo& holder, const std::string& host, std::uint16_t port, bool passive,
                            const std::string& prefix) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_DGRAM;
  hints.ai_protocol = IPPROTO_UDP;
  hints.ai_flags = AI_NUMERICSERV | (passive ? AI_PASSIVE : 0);
  const std::string service = std::to_string(port);
  const int rc = getaddrinfo(host.empty() ? nullptr : host.c_str(), service.c_str(), &hints, &holder.list);
  if (rc != 0 || holder.list == nullptr) {
    return make_error(prefix, "cannot resolve the address '", host, "' (", gai_strerror(rc),
                      "): expected a numeric IPv4/IPv6 address or a host name");
  }
  return holder.list;
}

// Waits for `fd` to become readable within `timeout`; false on timeout.
Expected<bool> wait_readable(int fd, std::chrono::nanoseconds timeout, const std::string& prefix) {
  const TimestampNs deadline = monotonic_now_ns() + std::max<std::int64_t>(timeout.count(), 0);
  for (;;) {
    const TimestampNs left = std::max<TimestampNs>(deadline - monotonic_now_ns(), 0);
    timespec ts{static_cast<time_t>(left / 1'000'000'000), static_cast<long>(left % 1'000'000'000)};
    pollfd p{fd, POLLIN, 0};
    const int rc = ppoll(&p, 1, &ts, nullptr);
    if (rc > 0) return true;
    if (rc == 0) return false;
    if (errno != EINTR) return make_error(prefix, "poll() failed: ", errno_text(errno));
  }
}

}  // namespace

Expected<HostPort> parse_host_port(std::string_view text, const std::string& what) {
  const auto bad = [&](const std::string& why) -> Error {
    return make_error(what, "expected HOST:PORT (e.g. 0.0.0.0:10110 or [::1]:10110), got '",
                      std::string(text), "': ", why);
  };
  HostPort hp;
  std::string_view port_text;
  if (!text.empty() && text.front() == '[') {
    const std::size_t close = text.find(']');
    if (close == std::string_view::npos) return bad("no ']' after the IPv6 address");
    hp.host = std::string(text.substr(1, close - 1));
    if (close + 1 >= text.size() || text[close + 1] != ':') return bad("no ':PORT' after ']'");
    port_text = text.substr(close + 2);
  } else {
    const std::size_t colon = text.rfind(':');
    if (colon == std::string_view::npos) return bad("no ':PORT'");
    hp.host = std::string(text.substr(0, colon));
    if (hp.host.find(':') != std::string::npos) return bad("an IPv6 address must be written in [brackets]");
    port_text = text.substr(colon + 1);
  }
  if (hp.host.empty()) return bad("the host is empty");
  unsigned port = 0;
  const auto [p, ec] = std::from_chars(port_text.data(), port_text.data() + port_text.size(), port);
  if (port_text.empty() || ec != std::errc() || p != port_text.data() + port_text.size() || port > 65535) {
    return bad("the port must be a number 0..65535");
  }
  hp.port = static_cast<std::uint16_t>(port);
  return hp;
}

// ---- UdpReceiver --------------------------------------------------------------------------------

Expected<UdpReceiver> UdpReceiver::bind(const std::string& host, std::uint16_t port,
                                        const UdpReceiverOptions& options) {
  const std::string prefix = "nav::UdpReceiver::bind(): " + host + ":" + std::to_string(port) + ": ";
  if (options.max_datagram_bytes == 0 || options.max_datagram_bytes > 65507) {
    return make_error(prefix, "max_datagram_bytes must be 1..65507 (the largest UDP payload), got ",
                      options.max_datagram_bytes);
  }
  AddrInfo holder;
  auto ai = resolve(holder, host, port, true, prefix);
  if (!ai) return ai.error();
  const addrinfo* a = *ai;
  UdpReceiver r;
  r.options_ = options;
  r.fd_ = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
  if (r.fd_ < 0) return make_error(prefix, "socket() failed: ", errno_text(errno));
  if (options.receive_buffer_bytes > 0) {
    const int size = options.receive_buffer_bytes;
    if (setsockopt(r.fd_, SOL_SOCKET, SO_RCVBUF, &size, sizeof size) != 0) {
      return make_error(prefix, "setsockopt(SO_RCVBUF, ", size, ") failed: ", errno_text(errno));
    }
  }
  const int on = 1;
  // The kernel's count of datagrams dropped for a full buffer comes with each datagram read.
  if (setsockopt(r.fd_, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) != 0) {
    return make_error(prefix, "setsockopt(SO_RXQ_OVFL) failed: ", errno_text(errno));
  }
  if (::bind(r.fd_, a->ai_addr, a->ai_addrlen) != 0) {
    const int e = errno;
    return make_error(prefix, "cannot bind (", errno_text(e), ")",
                      e == EADDRINUSE      ? ": another socket has this port; pick another port"
                      : e == EADDRNOTAVAIL ? ": no interface of this host has that address"
                                           : "");
  }
  sockaddr_storage ss{};
  socklen_t len = sizeof ss;
  if (getsockname(r.fd_, reinterpret_cast<sockaddr*>(&ss), &len) != 0) {
    return make_error(prefix, "getsockname() failed: ", errno_text(errno));
  }
  r.address_ = address_text(reinterpret_cast<sockaddr*>(&ss), len);
  r.port_ = ntohs(ss.ss_family == AF_INET6 ? reinterpret_cast<sockaddr_in6*>(&ss)->sin6_port
                                           : reinterpret_cast<sockaddr_in*>(&ss)->sin_port);
  socklen_t optlen = sizeof r.rcvbuf_;
  getsockopt(r.fd_, SOL_SOCKET, SO_RCVBUF, &r.rcvbuf_, &optlen);
  // One byte more than the largest datagram kept, so that a longer one shows as truncated.
  r.buffer_.resize(options.max_datagram_bytes + 1);
  return r;
}

UdpReceiver::UdpReceiver(UdpReceiver&& o) noexcept
    : fd_(std::exchange(o.fd_, -1)),
      port_(o.port_),
      address_(std::move(o.address_)),
      rcvbuf_(o.rcvbuf_),
      options_(o.options_),
      last_overflow_(o.last_overflow_),
      buffer_(std::move(o.buffer_)) {}

UdpReceiver& UdpReceiver::operator=(UdpReceiver&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(o.fd_, -1);
    port_ = o.port_;
    address_ = std::move(o.address_);
    rcvbuf_ = o.rcvbuf_;
    options_ = o.options_;
    last_overflow_ = o.last_overflow_;
    buffer_ = std::move(o.buffer_);
  }
  return *this;
}

UdpReceiver::~UdpReceiver() {
  if (fd_ >= 0) ::close(fd_);
}

Expected<bool> UdpReceiver::receive(UdpDatagram& out, std::chrono::nanoseconds timeout) {
  const std::string prefix = "nav::UdpReceiver::receive(): " + address_ + ": ";
  const TimestampNs deadline = monotonic_now_ns() + std::max<std::int64_t>(timeout.count(), 0);
  for (;;) {
    sockaddr_storage from{};
    iovec iov{buffer_.data(), buffer_.size()};
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(std::uint32_t))];
    msghdr msg{};
    msg.msg_name = &from;
    msg.msg_namelen = sizeof from;
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    // MSG_TRUNC: the return value is the datagram's real length, even when it did not fit.
    const ssize_t n = ::recvmsg(fd_, &msg, MSG_TRUNC);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) {
        return make_error(prefix, "recvmsg() failed: ", errno_text(errno));
      }
      const TimestampNs left = deadline - monotonic_now_ns();
      if (left <= 0) return false;
      auto ready = wait_readable(fd_, std::chrono::nanoseconds(left), prefix);
      if (!ready) return ready.error();
      if (!*ready) return false;
      continue;
    }
    out.arrival_ns = monotonic_now_ns();
    out.size = static_cast<std::size_t>(n);
    out.oversized = out.size > options_.max_datagram_bytes;
    if (out.oversized) {
      out.bytes.clear();
    } else {
      out.bytes.assign(buffer_.begin(), buffer_.begin() + n);
    }
    out.source = address_text(reinterpret_cast<sockaddr*>(&from), msg.msg_namelen);
    out.overflow_drops = 0;
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
        std::uint32_t total = 0;
        std::memcpy(&total, CMSG_DATA(c), sizeof total);
        out.overflow_drops = total - last_overflow_;  // a running count; unsigned wrap is fine
        last_overflow_ = total;
      }
    }
    return true;
  }
}

// ---- UdpSender ----------------------------------------------------------------------------------

Expected<UdpSender> UdpSender::open(const std::string& host, std::uint16_t port, bool broadcast) {
  const std::string prefix = "nav::UdpSender::open(): " + host + ":" + std::to_string(port) + ": ";
  if (port == 0) return make_error(prefix, "expected a destination port 1..65535, got 0");
  AddrInfo holder;
  auto ai = resolve(holder, host, port, false, prefix);
  if (!ai) return ai.error();
  const addrinfo* a = *ai;
  UdpSender s;
  s.fd_ = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
  if (s.fd_ < 0) return make_error(prefix, "socket() failed: ", errno_text(errno));
  if (broadcast) {
    const int on = 1;
    if (setsockopt(s.fd_, SOL_SOCKET, SO_BROADCAST, &on, sizeof on) != 0) {
      return make_error(prefix, "setsockopt(SO_BROADCAST) failed: ", errno_text(errno));
    }
  }
  if (::connect(s.fd_, a->ai_addr, a->ai_addrlen) != 0) {
    return make_error(prefix, "connect() failed: ", errno_text(errno),
                      errno == EACCES ? " (a broadcast address needs broadcast = true)" : "");
  }
  s.destination_ = address_text(a->ai_addr, a->ai_addrlen);
  return s;
}

UdpSender::UdpSender(UdpSender&& o) noexcept
    : fd_(std::exchange(o.fd_, -1)), destination_(std::move(o.destination_)) {}

UdpSender& UdpSender::operator=(UdpSender&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(o.fd_, -1);
    destination_ = std::move(o.destination_);
  }
  return *this;
}

UdpSender::~UdpSender() {
  if (fd_ >= 0) ::close(fd_);
}

Status UdpSender::send(std::span<const std::uint8_t> bytes) {
  for (;;) {
    const ssize_t n = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL);
    if (n == static_cast<ssize_t>(bytes.size())) return {};
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int e = errno;
      return make_error("nav::UdpSender::send(): ", destination_, ": ", bytes.size(), " bytes not sent (",
                        errno_text(e), ")",
                        e == ECONNREFUSED ? ": nothing listens there (an earlier datagram was refused)"
                        : e == EMSGSIZE   ? ": larger than a UDP datagram can be"
                                          : "");
    }
    return make_error("nav::UdpSender::send(): ", destination_, ": only ", n, " of ", bytes.size(),
                      " bytes sent");
  }
}

Status UdpSender::send(std::string_view text) {
  return send(std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

}  // namespace augrig::nav
