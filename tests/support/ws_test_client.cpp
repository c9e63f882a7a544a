// TestWsClient (ws_test_client.hpp).
#include "tests/support/ws_test_client.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <random>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

namespace augrig::test {

std::uint16_t WsFrame::close_code() const {
  if (payload.size() < 2) return 0;
  return static_cast<std::uint16_t>((static_cast<unsigned char>(payload[0]) << 8) |
                                    static_cast<unsigned char>(payload[1]));
}

std::string WsFrame::close_reason() const {
  return payload.size() > 2 ? payload.substr(2) : std::string();
}

TestWsClient::TestWsClient(int port, int receive_buffer_bytes, const std::string& host) {
  const bool v6 = host.find(':') != std::string::npos;
  fd_ = ::socket(v6 ? AF_INET6 : AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd_ < 0) return;
  if (receive_buffer_bytes > 0)
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &receive_buffer_bytes, sizeof receive_buffer_bytes);
  const int one = 1;
  ::setsockopt(fd_, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  int r;
  if (v6) {
    sockaddr_in6 a{};
    a.sin6_family = AF_INET6;
    a.sin6_port = htons(static_cast<std::uint16_t>(port));
    inet_pton(AF_INET6, host.c_str(), &a.sin6_addr);
    r = ::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a);
  } else {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    inet_pton(AF_INET, host.c_str(), &a.sin_addr);
    r = ::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a);
  }
  if (r != 0) {
    ::close(fd_);
    fd_ = -1;
  }
}

TestWsClient::~TestWsClient() {
  close();
}

void TestWsClient::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void TestWsClient::abort() {
  if (fd_ < 0) return;
  linger l{1, 0};
  ::setsockopt(fd_, SOL_SOCKET, SO_LINGER, &l, sizeof l);
  close();
}

bool TestWsClient::send_raw(std::string_view bytes) {
  std::size_t off = 0;
  while (off < bytes.size()) {
    const ssize_t n = ::send(fd_, bytes.data() + off, bytes.size() - off, MSG_NOSIGNAL);
    if (n <= 0) {
      if (n < 0 && errno == EINTR) continue;
      return false;
    }
    off += static_cast<std::size_t>(n);
  }
  return true;
}

bool TestWsClient::fill(int timeout_ms) {
  if (fd_ < 0 || ended_) return false;
  pollfd p{fd_, POLLIN, 0};
  const int r = ::poll(&p, 1, timeout_ms);
  if (r <= 0) return false;
  char tmp[65536];
  const ssize_t n = ::recv(fd_, tmp, sizeof tmp, 0);
  if (n <= 0) {
    ended_ = true;
    return false;
  }
  buf_.append(tmp, static_cast<std::size_t>(n));
  return true;
}

namespace {
using Clock = std::chrono::steady_clock;
int left_ms(Clock::time_point end) {
  return static_cast<int>(std::max<long long>(
      0, std::chrono::duration_cast<std::chrono::milliseconds>(end - Clock::now()).count()));
}
}  // namespace

std::string TestWsClient::read_response_head(int timeout_ms) {
  const auto end = Clock::now() + std::chrono::milliseconds(timeout_ms);
  while (true) {
    const auto p = buf_.find("\r\n\r\n");
    if (p != std::string::npos) {
      std::string head = buf_.substr(0, p + 4);
      buf_.erase(0, p + 4);
      return head;
    }
    if (!fill(left_ms(end))) return "";
  }
}

std::string TestWsClient::read_body(const std::string& head, int timeout_ms) {
  const auto p = head.find("Content-Length: ");
  if (p == std::string::npos) return "";
  const std::size_t n = std::stoul(head.substr(p + 16));
  const auto end = Clock::now() + std::chrono::milliseconds(timeout_ms);
  while (buf_.size() < n)
    if (!fill(left_ms(end))) break;
  std::string body = buf_.substr(0, std::min(n, buf_.size()));
  buf_.erase(0, body.size());
  return body;
}

std::string TestWsClient::handshake(const std::string& subprotocols, int timeout_ms) {
  std::string req =
      "GET /chat HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n";
  if (!subprotocols.empty()) req += "Sec-WebSocket-Protocol: " + subprotocols + "\r\n";
  req += "\r\n";
  if (!send_raw(req)) return "";
  return read_response_head(timeout_ms);
}

std::string TestWsClient::frame(std::uint8_t opcode, std::string_view payload, bool fin, bool masked,
                                std::uint8_t rsv) {
  std::string f;
  f += static_cast<char>((fin ? 0x80 : 0) | (rsv & 0x70) | (opcode & 0x0f));
  const std::uint64_t n = payload.size();
  const char m = masked ? static_cast<char>(0x80) : 0;
  if (n < 126) {
    f += static_cast<char>(m | static_cast<char>(n));
  } else if (n <= 0xffff) {
    f += static_cast<char>(m | 126);
    f += static_cast<char>(n >> 8);
    f += static_cast<char>(n);
  } else {
    f += static_cast<char>(m | 127);
    for (int b = 7; b >= 0; --b) f += static_cast<char>(n >> (8 * b));
  }
  if (!masked) return f + std::string(payload);
  static thread_local std::mt19937 rng(12345);
  char key[4];
  for (char& k : key) k = static_cast<char>(rng());
  f.append(key, 4);
  const std::size_t start = f.size();
  f += payload;
  for (std::size_t i = 0; i < payload.size(); ++i)
    f[start + i] = static_cast<char>(f[start + i] ^ key[i & 3]);
  return f;
}

bool TestWsClient::send_frame(std::uint8_t opcode, std::string_view payload, bool fin) {
  return send_raw(frame(opcode, payload, fin));
}

bool TestWsClient::send_close(std::uint16_t code, std::string_view reason) {
  std::string p;
  p += static_cast<char>(code >> 8);
  p += static_cast<char>(code & 0xff);
  p += reason;
  return send_frame(0x8, p);
}

bool TestWsClient::read_bytes(std::size_t n, int timeout_ms) {
  const auto end = Clock::now() + std::chrono::milliseconds(timeout_ms);
  while (buf_.size() < n)
    if (!fill(left_ms(end))) return false;
  buf_.erase(0, n);
  return true;
}

std::optional<WsFrame> TestWsClient::read_frame(int timeout_ms) {
  const auto end = Clock::now() + std::chrono::milliseconds(timeout_ms);
  auto need = [&](std::size_t n) {
    while (buf_.size() < n)
      if (!fill(left_ms(end))) return false;
    return true;
  };
  if (!need(2)) return std::nullopt;
  const auto* p = reinterpret_cast<const unsigned char*>(buf_.data());
  std::size_t header = 2;
  std::uint64_t len = p[1] & 0x7f;
  const bool masked = p[1] & 0x80;
  if (len == 126) header += 2;
  if (len == 127) header += 8;
  if (masked) header += 4;  // servers must not mask; parsed anyway so a test can say so
  if (!need(header)) return std::nullopt;
  p = reinterpret_cast<const unsigned char*>(buf_.data());
  if (len >= 126) {
    const std::size_t k = len == 126 ? 2 : 8;
    len = 0;
    for (std::size_t i = 0; i < k; ++i) len = (len << 8) | p[2 + i];
  }
  if (!need(header + len)) return std::nullopt;
  WsFrame f;
  f.fin = buf_[0] & 0x80;
  f.opcode = static_cast<std::uint8_t>(buf_[0] & 0x0f);
  f.payload = buf_.substr(header, len);
  buf_.erase(0, header + len);
  return f;
}

bool TestWsClient::wait_closed(int timeout_ms) {
  const auto end = Clock::now() + std::chrono::milliseconds(timeout_ms);
  while (!ended_) {
    buf_.clear();
    if (!fill(left_ms(end)) && !ended_) return false;
  }
  return true;
}

}  // namespace augrig::test
