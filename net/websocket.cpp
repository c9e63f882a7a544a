// WebSocketServer (websocket.hpp): the handshake's SHA-1 and base64, the frame writer, and the I/O
// thread (the request's checks and the frame decoder are websocket_protocol.cpp's). Each connection is a
// Conn, owned by the I/O thread; an open client also has a Shared part (its send queue and counters) that
// send() reaches under the server's mutex. The I/O thread moves a Shared queue into its Conn's outbox under
// the mutex and writes the outbox without it, so a sender waits at most for a few pointer moves.
#include "net/websocket.hpp"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <deque>
#include <map>
#include <mutex>
#include <thread>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include "core/clock.hpp"
#include "core/thread_name.hpp"
#include "net/websocket_protocol.hpp"

namespace augrig::net {

// ---- SHA-1 (FIPS 180-4 section 6.1) ---------------------------------------------------------------

namespace {

std::uint32_t rotl(std::uint32_t x, int n) {
  return (x << n) | (x >> (32 - n));
}

void sha1_block(std::uint32_t h[5], const std::uint8_t* p) {
  std::uint32_t w[80];
  for (int t = 0; t < 16; ++t)
    w[t] = (std::uint32_t{p[4 * t]} << 24) | (std::uint32_t{p[4 * t + 1]} << 16) |
           (std::uint32_t{p[4 * t + 2]} << 8) | std::uint32_t{p[4 * t + 3]};
  for (int t = 16; t < 80; ++t) w[t] = rotl(w[t - 3] ^ w[t - 8] ^ w[t - 14] ^ w[t - 16], 1);
  std::uint32_t a = h[0], b = h[1], c = h[2], d = h[3], e = h[4];
  for (int t = 0; t < 80; ++t) {
    std::uint32_t f, k;
    if (t < 20) {
      f = (b & c) | (~b & d);
      k = 0x5a827999;
    } else if (t < 40) {
      f = b ^ c ^ d;
      k = 0x6ed9eba1;
    } else if (t < 60) {
      f = (b & c) | (b & d) | (c & d);
      k = 0x8f1bbcdc;
    } else {
      f = b ^ c ^ d;
      k = 0xca62c1d6;
    }
    const std::uint32_t tmp = rotl(a, 5) + f + e + k + w[t];
    e = d;
    d = c;
    c = rotl(b, 30);
    b = a;
    a = tmp;
  }
  h[0] += a;
  h[1] += b;
  h[2] += c;
  h[3] += d;
  h[4] += e;
}

}  // namespace

std::array<std::uint8_t, 20> sha1(std::span<const std::uint8_t> data) {
  std::uint32_t h[5] = {0x67452301, 0xefcdab89, 0x98badcfe, 0x10325476, 0xc3d2e1f0};
  const std::size_t n = data.size();
  std::size_t i = 0;
  for (; n - i >= 64; i += 64) sha1_block(h, data.data() + i);
  // The tail, the 0x80 bit, zeros and the length in bits (big endian) in one or two blocks.
  std::uint8_t tail[128] = {};
  const std::size_t rest = n - i;
  if (rest) std::memcpy(tail, data.data() + i, rest);
  tail[rest] = 0x80;
  const std::size_t blocks = rest + 1 + 8 <= 64 ? 1 : 2;
  const std::uint64_t bits = static_cast<std::uint64_t>(n) * 8;
  for (int b = 0; b < 8; ++b)
    tail[blocks * 64 - 1 - static_cast<std::size_t>(b)] = static_cast<std::uint8_t>(bits >> (8 * b));
  for (std::size_t b = 0; b < blocks; ++b) sha1_block(h, tail + 64 * b);
  std::array<std::uint8_t, 20> out{};
  for (int k = 0; k < 5; ++k)
    for (int b = 0; b < 4; ++b)
      out[static_cast<std::size_t>(4 * k + b)] = static_cast<std::uint8_t>(h[k] >> (24 - 8 * b));
  return out;
}

std::array<std::uint8_t, 20> sha1(std::string_view text) {
  return sha1(std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

// ---- base64 (RFC 4648 section 4) ------------------------------------------------------------------

namespace {
constexpr char kBase64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
int base64_value(char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+') return 62;
  if (c == '/') return 63;
  return -1;
}
}  // namespace

std::string base64_encode(std::span<const std::uint8_t> data) {
  std::string out;
  out.reserve((data.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 3 <= data.size(); i += 3) {
    const std::uint32_t v = (std::uint32_t{data[i]} << 16) | (std::uint32_t{data[i + 1]} << 8) | data[i + 2];
    for (int s = 18; s >= 0; s -= 6) out += kBase64[(v >> s) & 63];
  }
  if (const std::size_t rest = data.size() - i) {
    std::uint32_t v = std::uint32_t{data[i]} << 16;
    if (rest == 2) v |= std::uint32_t{data[i + 1]} << 8;
    out += kBase64[(v >> 18) & 63];
    out += kBase64[(v >> 12) & 63];
    out += rest == 2 ? kBase64[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

std::optional<std::vector<std::uint8_t>> base64_decode(std::string_view text) {
  if (text.size() % 4) return std::nullopt;
  std::vector<std::uint8_t> out;
  out.reserve(text.size() / 4 * 3);
  for (std::size_t i = 0; i < text.size(); i += 4) {
    const bool last = i + 4 == text.size();
    const int pad = last ? (text[i + 3] == '=') + (text[i + 2] == '=') : 0;
    if (pad == 1 && text[i + 2] == '=') return std::nullopt;  // "x=y=" is not padding
    std::uint32_t v = 0;
    for (int k = 0; k < 4 - pad; ++k) {
      const int d = base64_value(text[i + static_cast<std::size_t>(k)]);
      if (d < 0) return std::nullopt;
      v |= static_cast<std::uint32_t>(d) << (18 - 6 * k);
    }
    // The bits below the last whole byte must be zero (canonical encoding).
    if ((pad == 1 && (v & 0xff)) || (pad == 2 && (v & 0xffff))) return std::nullopt;
    out.push_back(static_cast<std::uint8_t>(v >> 16));
    if (pad < 2) out.push_back(static_cast<std::uint8_t>(v >> 8));
    if (pad < 1) out.push_back(static_cast<std::uint8_t>(v));
  }
  return out;
}

std::string websocket_accept(std::string_view key) {
  std::string s(key);
  s += "258EAFA5-E914-47DA-95CA-C5AB0DC85B11";  // RFC 6455 section 1.3
  const auto h = sha1(s);
  return base64_encode(h);
}

bool valid_utf8(std::string_view text) {
  const auto* p = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  std::size_t i = 0;
  while (i < n) {
    const unsigned c = p[i];
    if (c < 0x80) {
      ++i;
      continue;
    }
    int len;
    std::uint32_t cp, min;
    if ((c & 0xe0) == 0xc0) {
      len = 2, cp = c & 0x1f, min = 0x80;
    } else if ((c & 0xf0) == 0xe0) {
      len = 3, cp = c & 0x0f, min = 0x800;
    } else if ((c & 0xf8) == 0xf0) {
      len = 4, cp = c & 0x07, min = 0x10000;
    } else {
      return false;
    }
    if (n - i < static_cast<std::size_t>(len)) return false;
    for (int k = 1; k < len; ++k) {
      const unsigned cc = p[i + static_cast<std::size_t>(k)];
      if ((cc & 0xc0) != 0x80) return false;
      cp = (cp << 6) | (cc & 0x3f);
    }
    if (cp < min || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff)) return false;
    i += static_cast<std::size_t>(len);
  }
  return true;
}

SharedBytes share_bytes(std::vector<std::uint8_t> bytes) {
  return std::make_shared<const std::vector<std::uint8_t>>(std::move(bytes));
}

SharedBytes share_bytes(std::string_view text) {
  return std::make_shared<const std::vector<std::uint8_t>>(text.begin(), text.end());
}

// ---- The server -----------------------------------------------------------------------------------

namespace {

constexpr std::uint8_t kOpText = 0x1, kOpBinary = 0x2, kOpClose = 0x8, kOpPong = 0xa;

// One frame on its way out: its header and prefix inline, the body shared.
struct OutMsg {
  std::array<std::uint8_t, 10 + WebSocketServer::kMaxPrefixBytes> head{};
  std::uint8_t head_len = 0;
  SharedBytes body;
  std::size_t sent = 0;  // bytes of head + body written
  bool counted = false;  // part of the client's queued_bytes (what send() queued)
  bool droppable = false;
  std::size_t size() const { return head_len + (body ? body->size() : 0); }
};

OutMsg make_frame(std::uint8_t opcode, SharedBytes body, std::span<const std::uint8_t> prefix) {
  OutMsg m;
  const std::uint64_t len = prefix.size() + (body ? body->size() : 0);
  std::size_t k = 0;
  m.head[k++] = static_cast<std::uint8_t>(0x80 | opcode);  // FIN: every message is one frame
  if (len < 126) {
    m.head[k++] = static_cast<std::uint8_t>(len);
  } else if (len <= 0xffff) {
    m.head[k++] = 126;
    m.head[k++] = static_cast<std::uint8_t>(len >> 8);
    m.head[k++] = static_cast<std::uint8_t>(len);
  } else {
    m.head[k++] = 127;
    for (int b = 7; b >= 0; --b) m.head[k++] = static_cast<std::uint8_t>(len >> (8 * b));
  }
  if (!prefix.empty()) std::memcpy(m.head.data() + k, prefix.data(), prefix.size());
  m.head_len = static_cast<std::uint8_t>(k + prefix.size());
  m.body = std::move(body);
  return m;
}

OutMsg raw_bytes(std::string_view text) {
  OutMsg m;
  m.body = share_bytes(text);
  return m;
}

OutMsg close_frame(std::uint16_t code, std::string_view reason) {
  std::vector<std::uint8_t> p;
  if (code != kCloseNoStatus) {
    p.push_back(static_cast<std::uint8_t>(code >> 8));
    p.push_back(static_cast<std::uint8_t>(code));
    // A control frame carries at most 125 bytes; cut the reason at a character boundary.
    std::size_t n = std::min<std::size_t>(reason.size(), 123);
    while (n > 0 && n < reason.size() && (static_cast<unsigned char>(reason[n]) & 0xc0) == 0x80) --n;
    p.insert(p.end(), reason.begin(), reason.begin() + static_cast<std::ptrdiff_t>(n));
  }
  return make_frame(kOpClose, share_bytes(std::move(p)), {});
}

std::string errno_text(int e) {
  char buf[256];
  return std::string(strerror_r(e, buf, sizeof buf));
}

std::string peer_name(const sockaddr_storage& a) {
  char host[INET6_ADDRSTRLEN] = "?";
  int port = 0;
  if (a.ss_family == AF_INET) {
    const auto* s = reinterpret_cast<const sockaddr_in*>(&a);
    inet_ntop(AF_INET, &s->sin_addr, host, sizeof host);
    port = ntohs(s->sin_port);
    return std::string(host) + ":" + std::to_string(port);
  }
  const auto* s = reinterpret_cast<const sockaddr_in6*>(&a);
  inet_ntop(AF_INET6, &s->sin6_addr, host, sizeof host);
  port = ntohs(s->sin6_port);
  return "[" + std::string(host) + "]:" + std::to_string(port);
}

// What send() and the I/O thread share about an open client (under Impl::mu).
struct Shared {
  std::deque<OutMsg> queue;      // accepted, not yet taken by the I/O thread
  std::size_t queued_bytes = 0;  // queue plus the counted outbox bytes not yet written
  bool kill = false;             // disconnect now (a message that must go did not fit)
  std::string kill_reason;
  std::optional<std::pair<std::uint16_t, std::string>> close_request;
  ClientStats stats;
};

enum class ConnState : std::uint8_t {
  kHandshake,  // reading the HTTP request
  kOpen,       // frames both ways
  kClosing,    // our close frame queued or sent; waiting for theirs
  kFinishing,  // flushing what is queued (an HTTP refusal, the last close frame), then shutdown(SHUT_WR)
  kDraining,   // shut for writing; reading until EOF so the peer sees our last bytes, not a reset
  kDead,       // the socket is closed; removed at the end of the loop
};

struct Conn {
  int fd = -1;
  ClientId id = 0;
  std::string peer;
  ConnState state = ConnState::kHandshake;
  std::int64_t deadline_ns = 0;        // handshake, closing, finishing or draining: when to give up
  std::string in;                      // received bytes not yet parsed
  std::optional<FrameDecoder> frames;  // once open
  std::deque<OutMsg> outbox;
  std::optional<std::string> pending_pong;
  std::int64_t last_progress_ns = 0;
  std::shared_ptr<Shared> shared;  // while open; kept until the socket closes
  bool opened = false, close_reported = false;
  CloseInfo close_info;
};

}  // namespace

struct WebSocketServer::Impl {
  WebSocketOptions opt;
  WebSocketHandler handler;
  int listen_fd = -1;
  int wake_fd = -1;
  std::thread thread;
  std::atomic<bool> stop_requested{false};
  std::atomic<bool> wake_pending{false};
  bool stopped = false;

  mutable std::mutex mu;
  std::map<ClientId, std::shared_ptr<Shared>> open;  // clients send() reaches
  WebSocketStats totals;                             // all but clients_now and clients (made in stats())

  // I/O thread only.
  std::map<ClientId, std::unique_ptr<Conn>> conns;
  ClientId next_id = 1;
  std::int64_t accept_paused_until_ns = 0;

  ~Impl() {
    for (auto& [id, c] : conns)
      if (c->fd >= 0) ::close(c->fd);
    if (listen_fd >= 0) ::close(listen_fd);
    if (wake_fd >= 0) ::close(wake_fd);
  }

  void wake() {
    if (!wake_pending.exchange(true)) {
      const std::uint64_t one = 1;
      [[maybe_unused]] ssize_t r = ::write(wake_fd, &one, sizeof one);
    }
  }

  // ---- Leaving the open state ----------------------------------------------------------------------

  // The client is no longer sendable: out of `open`, on_close called once.
  void report_close(Conn& c, CloseInfo info) {
    if (!c.opened || c.close_reported) return;
    c.close_reported = true;
    c.close_info = info;
    {
      std::lock_guard<std::mutex> lock(mu);
      open.erase(c.id);
      ++totals.disconnects;
    }
    if (handler.on_close) handler.on_close(c.id, info);
  }

  void kill(Conn& c, CloseInfo info) {
    report_close(c, std::move(info));
    if (c.fd >= 0) ::close(c.fd);
    c.fd = -1;
    if (c.state == ConnState::kHandshake) {
      std::lock_guard<std::mutex> lock(mu);
      ++totals.handshakes_abandoned;
    }
    c.state = ConnState::kDead;
    discard_unsent(c, true);
  }

  // Drops what is queued and not started (all of it with `everything`), keeping the queue's count right.
  void discard_unsent(Conn& c, bool everything) {
    std::size_t uncounted = 0;
    auto keep_end = c.outbox.begin();
    if (!everything && !c.outbox.empty() && c.outbox.front().sent > 0) ++keep_end;
    for (auto it = keep_end; it != c.outbox.end(); ++it)
      if (it->counted) uncounted += it->size() - it->sent;
    c.outbox.erase(keep_end, c.outbox.end());
    c.pending_pong.reset();
    if (c.shared) {
      std::lock_guard<std::mutex> lock(mu);
      for (const OutMsg& m : c.shared->queue) uncounted += m.size();
      c.shared->queue.clear();
      c.shared->queued_bytes -= std::min(c.shared->queued_bytes, uncounted);
    }
  }

  // Starts our side of the close handshake. `wait_for_peer`: wait for the client's close frame
  // (a normal close); otherwise (a protocol error) shut the socket once the frame is out.
  void start_close(Conn& c, std::uint16_t code, const std::string& reason, bool wait_for_peer) {
    if (c.state != ConnState::kOpen) return;
    report_close(c, CloseInfo{code, reason, true});
    discard_unsent(c, false);
    c.outbox.push_back(close_frame(code, reason));
    c.state = wait_for_peer ? ConnState::kClosing : ConnState::kFinishing;
    c.deadline_ns = monotonic_now_ns() + std::int64_t{opt.close_timeout_ms} * 1'000'000;
  }

  void protocol_error(Conn& c, std::uint16_t code, const std::string& reason) {
    {
      std::lock_guard<std::mutex> lock(mu);
      ++totals.protocol_errors;
    }
    c.in.clear();
    if (c.state == ConnState::kOpen) {
      start_close(c, code, reason, false);
    } else if (c.state == ConnState::kClosing) {
      c.state = ConnState::kFinishing;  // our close frame is out already: just end it
    }
  }

  // ---- The handshake ---------------------------------------------------------------------------------

  void refuse(Conn& c, int status, const std::string& text, const std::string& reason,
              const std::string& extra_headers = {}) {
    const std::string body = reason + "\n";
    std::string r =
        "HTTP/1.1 " + std::to_string(status) + " " + text + "\r\nServer: " + opt.server_header +
        "\r\nContent-Type: text/plain; charset=utf-8\r\nContent-Length: " + std::to_string(body.size()) +
        "\r\nConnection: close\r\n" + extra_headers + "\r\n" + body;
    c.outbox.push_back(raw_bytes(r));
    c.state = ConnState::kFinishing;
    c.deadline_ns = monotonic_now_ns() + std::int64_t{opt.close_timeout_ms} * 1'000'000;
    c.in.clear();
    std::lock_guard<std::mutex> lock(mu);
    ++totals.handshakes_refused;
  }

  // Answers the request in c.in[0, end) (websocket_protocol.hpp checks it). True when the
  // connection is now open.
  bool handshake(Conn& c, std::size_t end) {
    const HandshakeVerdict v =
        check_handshake(std::string_view(c.in.data(), end), opt.subprotocols, opt.server_header);
    if (!v.accepted()) {
      refuse(c, v.status, v.status_text, v.reason, v.extra_headers);
      return false;
    }
    const std::string& subprotocol = v.subprotocol;
    std::shared_ptr<Shared> shared;
    {
      std::lock_guard<std::mutex> lock(mu);
      if (open.size() >= opt.max_clients) {
        shared = nullptr;
      } else {
        shared = std::make_shared<Shared>();
        shared->stats.id = c.id;
        shared->stats.peer = c.peer;
        shared->stats.subprotocol = subprotocol;
        open.emplace(c.id, shared);
        ++totals.clients_ever;
      }
    }
    if (!shared) {
      refuse(c, 503, "Service Unavailable",
             "this server already has its maximum of " + std::to_string(opt.max_clients) + " clients");
      return false;
    }
    std::string r =
        "HTTP/1.1 101 Switching Protocols\r\nServer: " + opt.server_header +
        "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: " + websocket_accept(v.key) +
        "\r\n";
    if (!subprotocol.empty()) r += "Sec-WebSocket-Protocol: " + subprotocol + "\r\n";
    r += "\r\n";
    c.outbox.push_back(raw_bytes(r));
    c.shared = std::move(shared);
    c.state = ConnState::kOpen;
    c.frames.emplace(opt.max_message_bytes);
    c.opened = true;
    c.last_progress_ns = monotonic_now_ns();
    c.in.erase(0, end + 4);
    if (handler.on_open) handler.on_open(c.id, subprotocol, c.peer);
    return true;
  }

  // ---- Frames in ---------------------------------------------------------------------------------------

  void deliver(Conn& c, bool binary, std::string_view data) {
    if (!binary && !valid_utf8(data)) {
      protocol_error(c, kCloseInvalidData, "a text message that is not valid UTF-8");
      return;
    }
    {
      std::lock_guard<std::mutex> lock(mu);
      ++totals.messages_received;
      if (c.shared) ++c.shared->stats.messages_received;
    }
    if (handler.on_message) handler.on_message(c.id, binary, data);
  }

  // The client's close frame (checked by the decoder): `code` kCloseNoStatus when it had none.
  void on_close_frame(Conn& c, std::uint16_t code, const std::string& reason) {
    if (c.state == ConnState::kOpen) {
      // Their close first: ours echoes the code, then the server ends the TCP connection (RFC 6455 7.1.1).
      report_close(c, CloseInfo{code, reason, false});
      discard_unsent(c, false);
      c.outbox.push_back(close_frame(code == kCloseNoStatus ? std::uint16_t{kCloseNormal} : code, {}));
    }
    c.state = ConnState::kFinishing;
    c.deadline_ns = monotonic_now_ns() + std::int64_t{opt.close_timeout_ms} * 1'000'000;
  }

  // Acts on the complete frames in c.in (websocket_protocol.hpp decodes them); stops at an
  // incomplete one, a close frame or a protocol error.
  void parse_frames(Conn& c) {
    std::size_t pos = 0;
    while (c.frames && (c.state == ConnState::kOpen || c.state == ConnState::kClosing)) {
      const FrameStep f =
          c.frames->next(std::span<char>(c.in.data() + pos, c.in.size() - pos), c.state == ConnState::kOpen);
      if (f.kind == FrameStep::Kind::kNeedMore) break;
      if (f.kind == FrameStep::Kind::kError) return protocol_error(c, f.code, f.reason);
      pos += f.consumed;
      if (f.kind == FrameStep::Kind::kClose) {
        on_close_frame(c, f.code, f.reason);
        break;
      }
      if (f.kind == FrameStep::Kind::kPing && c.state == ConnState::kOpen)
        c.pending_pong = std::string(f.data);
      if (f.kind == FrameStep::Kind::kMessage) deliver(c, f.binary, f.data);
    }
    if (c.state == ConnState::kOpen || c.state == ConnState::kClosing)
      c.in.erase(0, pos);
    else
      c.in.clear();
  }

  void on_readable(Conn& c) {
    char buf[65536];
    std::size_t got = 0;
    // A bounded amount per turn, so one fast sender does not starve the others.
    while (got < 1024 * 1024) {
      const ssize_t n = ::recv(c.fd, buf, sizeof buf, MSG_DONTWAIT);
      if (n < 0) {
        if (errno == EINTR) continue;
        if (errno == EAGAIN || errno == EWOULDBLOCK) break;
        return kill(c, CloseInfo{kCloseAbnormal, "the connection failed: " + errno_text(errno), false});
      }
      if (n == 0) {
        if (c.state == ConnState::kDraining || c.state == ConnState::kFinishing)
          return kill(c, c.close_info);  // the peer saw our last bytes and closed: done
        return kill(
            c, CloseInfo{kCloseAbnormal,
                         c.state == ConnState::kHandshake ? "the connection closed during the handshake"
                                                          : "the connection closed without a close frame",
                         false});
      }
      got += static_cast<std::size_t>(n);
      if (c.state == ConnState::kDraining || c.state == ConnState::kFinishing) continue;  // discarded
      c.in.append(buf, static_cast<std::size_t>(n));
      if (c.state == ConnState::kHandshake) {
        const auto end = c.in.find("\r\n\r\n");
        if (end == std::string::npos) {
          if (c.in.size() > opt.max_header_bytes) {
            refuse(c, 431, "Request Header Fields Too Large",
                   "the request's headers exceed this server's limit of " +
                       std::to_string(opt.max_header_bytes) + " bytes");
          }
          continue;
        }
        if (end + 4 > opt.max_header_bytes) {
          refuse(c, 431, "Request Header Fields Too Large",
                 "the request's headers exceed this server's limit of " +
                     std::to_string(opt.max_header_bytes) + " bytes");
          continue;
        }
        if (!handshake(c, end)) continue;
      }
      parse_frames(c);
    }
  }

  // ---- Frames out ----------------------------------------------------------------------------------------

  // Moves what send() queued into the outbox; acts on kill and close requests.
  void collect(Conn& c) {
    if (!c.shared || c.state == ConnState::kDead) return;
    bool killed = false;
    std::string kill_reason;
    std::optional<std::pair<std::uint16_t, std::string>> close_request;
    {
      std::lock_guard<std::mutex> lock(mu);
      Shared& s = *c.shared;
      if (c.state == ConnState::kOpen)
        for (OutMsg& m : s.queue) c.outbox.push_back(std::move(m));
      s.queue.clear();
      killed = s.kill;
      kill_reason = s.kill_reason;
      close_request = std::move(s.close_request);
      s.close_request.reset();
    }
    if (killed) {
      {
        std::lock_guard<std::mutex> lock(mu);
        ++totals.disconnects_overflow;
      }
      return kill(c, CloseInfo{kCloseAbnormal, kill_reason, true});
    }
    if (close_request) start_close(c, close_request->first, close_request->second, true);
  }

  void flush(Conn& c) {
    std::uint64_t msgs = 0, bytes = 0, counted_bytes = 0;
    bool failed = false;
    int err = 0;
    while (c.fd >= 0) {
      if (c.pending_pong && (c.outbox.empty() || c.outbox.front().sent == 0)) {
        c.outbox.push_front(make_frame(kOpPong, share_bytes(*c.pending_pong), {}));
        c.pending_pong.reset();
      }
      if (c.outbox.empty()) break;
      iovec iov[64];
      int n = 0;
      for (const OutMsg& m : c.outbox) {
        if (n + 2 > 64) break;
        std::size_t off = m.sent;
        if (off < m.head_len) {
          iov[n++] = {const_cast<std::uint8_t*>(m.head.data() + off), m.head_len - off};
          off = m.head_len;
        }
        const std::size_t body = m.body ? m.body->size() : 0;
        if (off - m.head_len < body)
          iov[n++] = {const_cast<std::uint8_t*>(m.body->data() + (off - m.head_len)),
                      body - (off - m.head_len)};
      }
      msghdr mh{};
      mh.msg_iov = iov;
      mh.msg_iovlen = static_cast<std::size_t>(n);
      const ssize_t w = ::sendmsg(c.fd, &mh, MSG_NOSIGNAL | MSG_DONTWAIT);
      if (w < 0) {
        if (errno == EINTR) continue;
        if (errno == EAGAIN || errno == EWOULDBLOCK) break;
        failed = true;
        err = errno;
        break;
      }
      std::size_t left = static_cast<std::size_t>(w);
      bytes += left;
      c.last_progress_ns = monotonic_now_ns();
      while (left > 0 && !c.outbox.empty()) {
        OutMsg& m = c.outbox.front();
        const std::size_t take = std::min(left, m.size() - m.sent);
        m.sent += take;
        left -= take;
        if (m.counted) counted_bytes += take;
        if (m.sent == m.size()) {
          ++msgs;
          c.outbox.pop_front();
        }
      }
    }
    if (bytes) {
      std::lock_guard<std::mutex> lock(mu);
      totals.messages_sent += msgs;
      totals.bytes_sent += bytes;
      if (c.shared) {
        c.shared->stats.messages_sent += msgs;
        c.shared->stats.bytes_sent += bytes;
        c.shared->queued_bytes -= std::min(c.shared->queued_bytes, counted_bytes);
      }
    }
    if (failed)
      return kill(
          c, CloseInfo{kCloseAbnormal, "the connection failed while sending: " + errno_text(err), false});
    if (c.outbox.empty() && !c.pending_pong && c.state == ConnState::kFinishing) {
      ::shutdown(c.fd, SHUT_WR);
      c.state = ConnState::kDraining;
      c.deadline_ns = monotonic_now_ns() + std::int64_t{opt.close_timeout_ms} * 1'000'000;
    }
  }

  // ---- The loop -------------------------------------------------------------------------------------------

  void accept_all() {
    while (true) {
      sockaddr_storage addr{};
      socklen_t len = sizeof addr;
      const int fd =
          ::accept4(listen_fd, reinterpret_cast<sockaddr*>(&addr), &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
      if (fd < 0) {
        if (errno == EINTR || errno == ECONNABORTED) continue;
        if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM)
          accept_paused_until_ns = monotonic_now_ns() + 100'000'000;  // no descriptors: try again later
        return;
      }
      {
        std::lock_guard<std::mutex> lock(mu);
        ++totals.connections_accepted;
      }
      // Connections are bounded: a flood of idle ones cannot take every descriptor. At the bound the
      // oldest handshake gives way to the new connection, so idle sockets held open cannot lock real
      // clients out (they send their request within a round trip of connecting).
      if (!make_room()) {
        ::close(fd);
        std::lock_guard<std::mutex> lock(mu);
        ++totals.handshakes_abandoned;
        continue;
      }
      const int one = 1;
      ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
      auto c = std::make_unique<Conn>();
      c->fd = fd;
      c->id = next_id++;
      c->peer = peer_name(addr);
      c->deadline_ns = monotonic_now_ns() + std::int64_t{opt.handshake_timeout_ms} * 1'000'000;
      conns.emplace(c->id, std::move(c));
    }
  }

  // Below the bound of connections (2 * max_clients + 16), or brought below it by closing the one
  // that has waited longest for its request (connections are kept in accept order); false when
  // every connection is a client's.
  bool make_room() {
    std::size_t live = 0;
    Conn* oldest_handshake = nullptr;
    for (auto& [id, c] : conns) {
      if (c->state == ConnState::kDead) continue;
      ++live;
      if (!oldest_handshake && c->state == ConnState::kHandshake) oldest_handshake = c.get();
    }
    if (live < 2 * opt.max_clients + 16) return true;
    if (!oldest_handshake) return false;
    kill(
        *oldest_handshake,
        CloseInfo{kCloseAbnormal, "no complete request yet, and a newer connection needed its place", false});
    return true;
  }

  void timers(Conn& c, std::int64_t now) {
    if (c.state == ConnState::kDead) return;
    if (c.state == ConnState::kOpen) {
      if (opt.stall_timeout_ms > 0 && !c.outbox.empty() &&
          now - c.last_progress_ns > std::int64_t{opt.stall_timeout_ms} * 1'000'000) {
        {
          std::lock_guard<std::mutex> lock(mu);
          ++totals.disconnects_stalled;
        }
        kill(c,
             CloseInfo{kCloseAbnormal,
                       "the client took no data for " + std::to_string(opt.stall_timeout_ms) + " ms", true});
      }
      if (c.outbox.empty()) c.last_progress_ns = now;
      return;
    }
    if (now < c.deadline_ns) return;
    if (c.state == ConnState::kHandshake) {
      kill(c, CloseInfo{kCloseAbnormal, "no complete request within the handshake timeout", false});
    } else {
      kill(c, c.close_info);  // closing, finishing, draining: the peer had its time
    }
  }

  void run() {
    set_thread_name("augrig-ws");
    std::vector<pollfd> fds;
    std::vector<Conn*> polled;
    bool stopping = false;
    std::int64_t stop_deadline = 0;
    while (true) {
      if (stop_requested.load() && !stopping) {
        stopping = true;
        stop_deadline = monotonic_now_ns() + std::int64_t{opt.close_timeout_ms} * 1'000'000;
        ::close(listen_fd);
        listen_fd = -1;
        for (auto& [id, c] : conns) {
          if (c->state == ConnState::kHandshake)
            kill(*c, CloseInfo{kCloseAbnormal, "the server stopped", true});
          start_close(*c, kCloseGoingAway, "the server is stopping", true);
        }
      }
      for (auto& [id, c] : conns) {
        collect(*c);
        if (c->state != ConnState::kDead && c->state != ConnState::kHandshake &&
            c->state != ConnState::kDraining)
          flush(*c);
      }
      const std::int64_t now = monotonic_now_ns();
      for (auto& [id, c] : conns) timers(*c, now);
      for (auto it = conns.begin(); it != conns.end();)
        it = it->second->state == ConnState::kDead ? conns.erase(it) : std::next(it);
      if (stopping && (conns.empty() || now >= stop_deadline)) break;

      fds.clear();
      polled.clear();
      fds.push_back({wake_fd, POLLIN, 0});
      const bool accepting = listen_fd >= 0 && now >= accept_paused_until_ns;
      if (accepting) fds.push_back({listen_fd, POLLIN, 0});
      std::int64_t next_ns = now + 250'000'000;  // timers are checked at least this often
      for (auto& [id, c] : conns) {
        short ev = POLLIN;
        if (!c->outbox.empty() || c->pending_pong) ev |= POLLOUT;
        fds.push_back({c->fd, ev, 0});
        polled.push_back(c.get());
        if (c->state != ConnState::kOpen) next_ns = std::min(next_ns, c->deadline_ns);
      }
      if (stopping) next_ns = std::min(next_ns, stop_deadline);
      const int timeout_ms =
          static_cast<int>(std::clamp<std::int64_t>((next_ns - now) / 1'000'000 + 1, 0, 250));
      const int r = ::poll(fds.data(), fds.size(), timeout_ms);
      if (r < 0 && errno != EINTR) break;  // cannot happen with valid descriptors; do not spin
      if (r <= 0) continue;
      std::size_t k = 0;
      if (fds[k++].revents & POLLIN) {
        std::uint64_t v;
        [[maybe_unused]] ssize_t n = ::read(wake_fd, &v, sizeof v);
        wake_pending.store(false);
      }
      if (accepting && (fds[k++].revents & POLLIN)) accept_all();
      for (Conn* c : polled) {
        const short re = fds[k++].revents;
        if (c->state == ConnState::kDead) continue;
        if (re & (POLLIN | POLLHUP | POLLERR)) on_readable(*c);
        if (c->state != ConnState::kDead && (re & POLLERR)) {
          int e = 0;
          socklen_t el = sizeof e;
          ::getsockopt(c->fd, SOL_SOCKET, SO_ERROR, &e, &el);
          kill(*c, CloseInfo{kCloseAbnormal, "the connection failed: " + errno_text(e ? e : EIO), false});
          continue;
        }
        if (c->state != ConnState::kDead && (re & POLLOUT) && c->state != ConnState::kDraining &&
            c->state != ConnState::kHandshake)
          flush(*c);
      }
    }
    // Whatever is left after the stop's grace period is cut off.
    for (auto& [id, c] : conns)
      if (c->state != ConnState::kDead) kill(*c, CloseInfo{kCloseGoingAway, "the server stopped", true});
    conns.clear();
  }
};

WebSocketServer::WebSocketServer(const WebSocketOptions& options, WebSocketHandler handler)
    : options_(options), impl_(std::make_unique<Impl>()) {
  impl_->opt = options;
  impl_->handler = std::move(handler);
}

Expected<std::unique_ptr<WebSocketServer>> WebSocketServer::start(const WebSocketOptions& options,
                                                                  WebSocketHandler handler) {
  const std::string where = "net::WebSocketServer::start(): ";
  if (options.port < 0 || options.port > 65535)
    return Error{where + "port " + std::to_string(options.port) +
                 " is not a TCP port (0 to 65535; 0: any free one)"};
  if (options.max_clients == 0) return Error{where + "max_clients must be at least 1"};
  const std::string host = options.address == "localhost" ? "127.0.0.1" : options.address;
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_NUMERICHOST | AI_NUMERICSERV | AI_PASSIVE;
  addrinfo* ai = nullptr;
  const std::string port_text = std::to_string(options.port);
  if (getaddrinfo(host.c_str(), port_text.c_str(), &hints, &ai) != 0 || !ai)
    return Error{
        where + "'" + options.address +
        "' is not an address to listen on: expected a numeric IPv4 or IPv6 address (127.0.0.1, 0.0.0.0, ::1) "
        "or localhost"};
  const std::string shown = (ai->ai_family == AF_INET6 ? "[" + host + "]" : host) + ":" + port_text;
  const int fd = ::socket(ai->ai_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    const int e = errno;
    freeaddrinfo(ai);
    return Error{where + "cannot open a socket for " + shown + ": " + errno_text(e)};
  }
  const int one = 1;
  // A restarted server can take its port back while old connections sit in TIME_WAIT; a live
  // listener on it still makes bind() fail.
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  if (::bind(fd, ai->ai_addr, ai->ai_addrlen) != 0) {
    const int e = errno;
    freeaddrinfo(ai);
    ::close(fd);
    return Error{where + "cannot bind " + shown + ": " + errno_text(e)};
  }
  freeaddrinfo(ai);
  if (::listen(fd, 64) != 0) {
    const int e = errno;
    ::close(fd);
    return Error{where + "cannot listen on " + shown + ": " + errno_text(e)};
  }
  sockaddr_storage bound{};
  socklen_t len = sizeof bound;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&bound), &len);
  const int port = bound.ss_family == AF_INET ? ntohs(reinterpret_cast<sockaddr_in*>(&bound)->sin_port)
                                              : ntohs(reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port);
  const int wfd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (wfd < 0) {
    const int e = errno;
    ::close(fd);
    return Error{where + "cannot create an eventfd: " + errno_text(e)};
  }
  std::unique_ptr<WebSocketServer> s(new WebSocketServer(options, std::move(handler)));
  s->port_ = port;
  s->impl_->listen_fd = fd;
  s->impl_->wake_fd = wfd;
  Impl* impl = s->impl_.get();
  s->impl_->thread = std::thread([impl] { impl->run(); });
  return s;
}

WebSocketServer::~WebSocketServer() {
  stop();
}

void WebSocketServer::stop() {
  if (!impl_ || impl_->stopped) return;
  impl_->stopped = true;
  impl_->stop_requested.store(true);
  impl_->wake();
  if (impl_->thread.joinable()) impl_->thread.join();
}

SendResult WebSocketServer::send(ClientId client, bool binary, SharedBytes body,
                                 std::span<const std::uint8_t> prefix, bool droppable) {
  if (prefix.size() > kMaxPrefixBytes) prefix = prefix.first(kMaxPrefixBytes);
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    const auto it = impl_->open.find(client);
    if (it == impl_->open.end()) return SendResult::kNoClient;
    Shared& s = *it->second;
    const std::size_t size = 10 + prefix.size() + (body ? body->size() : 0);
    if (droppable && s.queued_bytes + size > impl_->opt.queue_bytes) {
      ++s.stats.messages_dropped;
      ++impl_->totals.messages_dropped;
      return SendResult::kDropped;
    }
    if (!droppable && s.queued_bytes + size > impl_->opt.queue_bytes + impl_->opt.control_reserve_bytes) {
      s.kill = true;
      s.kill_reason = "the client did not read: " + std::to_string(s.queued_bytes) +
                      " bytes queued, and a message that must not be dropped did not fit";
      impl_->open.erase(it);
    } else {
      OutMsg m = make_frame(binary ? kOpBinary : kOpText, std::move(body), prefix);
      m.counted = true;
      m.droppable = droppable;
      s.queued_bytes += m.size();
      s.queue.push_back(std::move(m));
    }
    if (s.kill) {
      impl_->wake();
      return SendResult::kDisconnected;
    }
  }
  impl_->wake();
  return SendResult::kQueued;
}

void WebSocketServer::close(ClientId client, std::uint16_t code, std::string reason) {
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    const auto it = impl_->open.find(client);
    if (it == impl_->open.end()) return;
    it->second->close_request = std::make_pair(code, std::move(reason));
    impl_->open.erase(it);
  }
  impl_->wake();
}

WebSocketStats WebSocketServer::stats() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  WebSocketStats s = impl_->totals;
  s.clients_now = impl_->open.size();
  for (const auto& [id, sh] : impl_->open) {
    ClientStats c = sh->stats;
    c.queued_bytes = sh->queued_bytes;
    s.clients.push_back(std::move(c));
  }
  return s;
}

std::vector<ClientId> WebSocketServer::clients() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  std::vector<ClientId> ids;
  for (const auto& [id, sh] : impl_->open) ids.push_back(id);
  return ids;
}

}  // namespace augrig::net
