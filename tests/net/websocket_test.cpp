// net/websocket.hpp: SHA-1, base64 and the accept key against the FIPS 180 / RFC 4648 / RFC 6455
// vectors; the server against a raw-socket client (tests/support/ws_test_client.hpp) that sends
// exactly the bytes each case needs: the handshake and its refusals, echo of text and binary
// messages with 16- and 64-bit lengths, fragments with a ping between them, the close handshake
// both ways, protocol errors (1002, 1007, 1009), a client that does not read (drops counted, the
// sender never blocks, a fast client beside it gets everything), clients that vanish mid-handshake
// and mid-frame either way, and many connections coming and going without leaking a descriptor.
#include "net/websocket.hpp"

#include <chrono>
#include <condition_variable>
#include <cstring>
#include <functional>
#include <mutex>
#include <thread>

#include <dirent.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include "tests/support/ws_test_client.hpp"

namespace augrig::net {
namespace {

using test::TestWsClient;
using Clock = std::chrono::steady_clock;

std::string hex(std::span<const std::uint8_t> b) {
  static const char* d = "0123456789abcdef";
  std::string s;
  for (std::uint8_t v : b) {
    s += d[v >> 4];
    s += d[v & 15];
  }
  return s;
}

TEST(Sha1, Fips180Vectors) {
  EXPECT_EQ(hex(sha1("abc")), "a9993e364706816aba3e25717850c26c9cd0d89d");
  EXPECT_EQ(hex(sha1("")), "da39a3ee5e6b4b0d3255bfef95601890afd80709");
  EXPECT_EQ(hex(sha1("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq")),
            "84983e441c3bd26ebaae4aa1f95129e5e54670f1");
  EXPECT_EQ(
      hex(sha1(
          "abcdefghbcdefghicdefghijdefghijkefghijklfghijklmghijklmnhijklmnoijklmnopjklmnopqklmnopqrlmnopqrs"
          "mnopqrstnopqrstu")),
      "a49b2446a02c645bf419f995b67091253a04a259");
  EXPECT_EQ(hex(sha1(std::string(1000000, 'a'))), "34aa973cd4c4daa4f61eeb2bdbad27316534016f");
  // The padding's edges (55 bytes: one block; 56 and 63: two; 64: a whole block, then padding),
  // checked against Python's hashlib.
  EXPECT_EQ(hex(sha1(std::string(55, 'a'))), "c1c8bbdc22796e28c0e15163d20899b65621d65a");
  EXPECT_EQ(hex(sha1(std::string(56, 'a'))), "c2db330f6083854c99d4b5bfb6e8f29f201be699");
  EXPECT_EQ(hex(sha1(std::string(63, 'a'))), "03f09f5b158a7a8cdad920bddc29b81c18a551f5");
  EXPECT_EQ(hex(sha1(std::string(64, 'a'))), "0098ba824b5c16427bd7a1122a5a442a25ec644d");
  EXPECT_EQ(hex(sha1("The quick brown fox jumps over the lazy dog")),
            "2fd4e1c67a2d28fced849ee1bb76e7391b93eb12");
}

TEST(Base64, Rfc4648VectorsBothWays) {
  const std::pair<const char*, const char*> v[] = {{"", ""},
                                                   {"f", "Zg=="},
                                                   {"fo", "Zm8="},
                                                   {"foo", "Zm9v"},
                                                   {"foob", "Zm9vYg=="},
                                                   {"fooba", "Zm9vYmE="},
                                                   {"foobar", "Zm9vYmFy"}};
  for (const auto& [plain, coded] : v) {
    const std::string p(plain);
    EXPECT_EQ(base64_encode(
                  std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(p.data()), p.size())),
              coded);
    const auto back = base64_decode(coded);
    ASSERT_TRUE(back) << coded;
    EXPECT_EQ(std::string(back->begin(), back->end()), p);
  }
  for (const char* bad : {"Zg=", "Zg", "Z===", "Zm9v!A==", "Zh==", "Zm9=", "Zg==Zg==", "Z=g="})
    EXPECT_FALSE(base64_decode(bad)) << bad;
  EXPECT_EQ(base64_decode("dGhlIHNhbXBsZSBub25jZQ==")->size(), 16u);
}

TEST(WebSocketAccept, Rfc6455Example) {
  EXPECT_EQ(websocket_accept("dGhlIHNhbXBsZSBub25jZQ=="), "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=");
}

TEST(Utf8, ValidAndInvalid) {
  EXPECT_TRUE(valid_utf8("plain ascii"));
  EXPECT_TRUE(valid_utf8("\xc3\xa9t\xc3\xa9 \xe2\x82\xac \xf0\x9f\x9b\xa9"));  // été € 🛩
  EXPECT_FALSE(valid_utf8("\xc0\xaf"));                                        // overlong '/'
  EXPECT_FALSE(valid_utf8("\xed\xa0\x80"));                                    // a surrogate
  EXPECT_FALSE(valid_utf8("\xf4\x90\x80\x80"));                                // beyond U+10FFFF
  EXPECT_FALSE(valid_utf8("\xe2\x82"));                                        // cut short
  EXPECT_FALSE(valid_utf8("\xff"));
}

// ---- A server with an echo handler and a log of its callbacks ---------------------------------------

struct Log {
  std::mutex mu;
  std::condition_variable cv;
  std::vector<ClientId> opened;
  std::vector<std::string> subprotocols;
  std::vector<std::pair<ClientId, CloseInfo>> closed;
  std::vector<std::pair<bool, std::string>> messages;

  bool wait(const std::function<bool()>& done, int timeout_ms = 5000) {
    std::unique_lock<std::mutex> lock(mu);
    return cv.wait_for(lock, std::chrono::milliseconds(timeout_ms), done);
  }
};

struct EchoServer {
  std::shared_ptr<Log> log = std::make_shared<Log>();
  std::shared_ptr<std::atomic<WebSocketServer*>> self =
      std::make_shared<std::atomic<WebSocketServer*>>(nullptr);
  std::unique_ptr<WebSocketServer> server;
  bool echo = true;

  explicit EchoServer(WebSocketOptions o = {}, bool echo_messages = true) : echo(echo_messages) {
    WebSocketHandler h;
    auto log_ = log;
    auto self_ = self;
    const bool e = echo;
    h.on_open = [log_](ClientId id, const std::string& sub, const std::string&) {
      std::lock_guard<std::mutex> lock(log_->mu);
      log_->opened.push_back(id);
      log_->subprotocols.push_back(sub);
      log_->cv.notify_all();
    };
    h.on_message = [log_, self_, e](ClientId id, bool binary, std::string_view data) {
      {
        std::lock_guard<std::mutex> lock(log_->mu);
        log_->messages.emplace_back(binary, std::string(data));
        log_->cv.notify_all();
      }
      if (e && self_->load()) self_->load()->send(id, binary, share_bytes(data));
    };
    h.on_close = [log_](ClientId id, const CloseInfo& info) {
      std::lock_guard<std::mutex> lock(log_->mu);
      log_->closed.emplace_back(id, info);
      log_->cv.notify_all();
    };
    auto s = WebSocketServer::start(o, std::move(h));
    if (!s) {
      ADD_FAILURE() << s.error().message;
      return;
    }
    server = std::move(*s);
    self->store(server.get());
  }
  ~EchoServer() {
    if (server) server->stop();
    self->store(nullptr);
  }
  int port() const { return server->port(); }
  std::size_t opened() {
    std::lock_guard<std::mutex> lock(log->mu);
    return log->opened.size();
  }
  std::size_t closed() {
    std::lock_guard<std::mutex> lock(log->mu);
    return log->closed.size();
  }
  ClientId last_opened() {
    std::lock_guard<std::mutex> lock(log->mu);
    return log->opened.empty() ? 0 : log->opened.back();
  }
  CloseInfo last_close() {
    std::lock_guard<std::mutex> lock(log->mu);
    return log->closed.empty() ? CloseInfo{} : log->closed.back().second;
  }
  bool wait_opened(std::size_t n) {
    return log->wait([&] { return log->opened.size() >= n; });
  }
  bool wait_closed(std::size_t n, int timeout_ms = 5000) {
    return log->wait([&] { return log->closed.size() >= n; }, timeout_ms);
  }
};

bool eventually(const std::function<bool()>& f, int timeout_ms = 5000) {
  const auto end = Clock::now() + std::chrono::milliseconds(timeout_ms);
  while (Clock::now() < end) {
    if (f()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return f();
}

int open_fds() {
  int n = 0;
  if (DIR* d = opendir("/proc/self/fd")) {
    while (readdir(d)) ++n;
    closedir(d);
  }
  return n;
}

// ---- Handshake -------------------------------------------------------------------------------------------

TEST(WebSocketServer, HandshakeNegotiatesTheSubprotocolAndEchoes) {
  WebSocketOptions o;
  o.subprotocols = {"foxglove.websocket.v1", "other"};
  EchoServer s(o);
  ASSERT_TRUE(s.server);
  EXPECT_GT(s.port(), 0);
  TestWsClient c(s.port());
  ASSERT_TRUE(c.connected());
  const std::string head = c.handshake("nope, other, foxglove.websocket.v1");
  EXPECT_EQ(head.rfind("HTTP/1.1 101 Switching Protocols\r\n", 0), 0u) << head;
  EXPECT_NE(head.find("\r\nSec-WebSocket-Accept: s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\n"), std::string::npos)
      << head;
  // The server's preference wins among those the client asked for.
  EXPECT_NE(head.find("\r\nSec-WebSocket-Protocol: foxglove.websocket.v1\r\n"), std::string::npos) << head;
  EXPECT_NE(head.find("\r\nUpgrade: websocket\r\n"), std::string::npos);
  ASSERT_TRUE(s.wait_opened(1));
  EXPECT_EQ(s.log->subprotocols[0], "foxglove.websocket.v1");
  ASSERT_TRUE(c.send_text("hello \xc3\xa9"));
  auto f = c.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->opcode, 0x1);
  EXPECT_TRUE(f->fin);
  EXPECT_EQ(f->payload, "hello \xc3\xa9");
  ASSERT_TRUE(c.send_frame(0x2, std::string("\x00\x01\x02\xff", 4)));
  f = c.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->opcode, 0x2);
  EXPECT_EQ(f->payload, std::string("\x00\x01\x02\xff", 4));
  const WebSocketStats st = s.server->stats();
  EXPECT_EQ(st.clients_now, 1u);
  EXPECT_EQ(st.clients_ever, 1u);
  EXPECT_EQ(st.messages_received, 2u);
  ASSERT_EQ(st.clients.size(), 1u);
  EXPECT_EQ(st.clients[0].subprotocol, "foxglove.websocket.v1");
  EXPECT_EQ(st.clients[0].peer.rfind("127.0.0.1:", 0), 0u);
}

TEST(WebSocketServer, FramesSentWithTheHandshakeAreRead) {
  EchoServer s;
  TestWsClient c(s.port());
  const std::string req =
      "GET / HTTP/1.1\r\nHost: x\r\nUpgrade: WebSocket\r\nConnection: keep-alive, Upgrade\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n";
  ASSERT_TRUE(c.send_raw(req + TestWsClient::frame(0x1, "same packet")));
  EXPECT_EQ(c.read_response_head().rfind("HTTP/1.1 101", 0), 0u);
  auto f = c.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->payload, "same packet");
}

struct BadRequest {
  const char* what;
  std::string request;
  const char* status;  // the status line's start
  const char* reason;  // in the body
};

TEST(WebSocketServer, RefusesBadRequestsWithAStatusAndAReason) {
  WebSocketOptions o;
  o.subprotocols = {"foxglove.websocket.v1"};
  EchoServer s(o);
  const std::string key = "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n";
  const std::string up = "Upgrade: websocket\r\nConnection: Upgrade\r\n";
  const std::string ver = "Sec-WebSocket-Version: 13\r\n";
  const std::string proto = "Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n";
  const std::vector<BadRequest> cases = {
      {"garbage", "\x16\x03\x01 hello\r\n\r\n", "HTTP/1.1 400", "malformed request line"},
      {"POST", "POST / HTTP/1.1\r\nHost: x\r\n" + up + key + ver + proto + "\r\n", "HTTP/1.1 405",
       "GET request"},
      {"HTTP/1.0", "GET / HTTP/1.0\r\nHost: x\r\n" + up + key + ver + proto + "\r\n", "HTTP/1.1 400",
       "HTTP/1.1 is required"},
      {"no Host", "GET / HTTP/1.1\r\n" + up + key + ver + proto + "\r\n", "HTTP/1.1 400", "no Host header"},
      {"plain HTTP GET", "GET / HTTP/1.1\r\nHost: x\r\n\r\n", "HTTP/1.1 426", "this is a WebSocket server"},
      {"no Connection: Upgrade",
       "GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\n" + key + ver + proto + "\r\n", "HTTP/1.1 400",
       "Connection header must include 'Upgrade'"},
      {"version 8",
       "GET / HTTP/1.1\r\nHost: x\r\n" + up + key + "Sec-WebSocket-Version: 8\r\n" + proto + "\r\n",
       "HTTP/1.1 426", "Sec-WebSocket-Version must be 13"},
      {"no key", "GET / HTTP/1.1\r\nHost: x\r\n" + up + ver + proto + "\r\n", "HTTP/1.1 400",
       "no Sec-WebSocket-Key"},
      {"short key",
       "GET / HTTP/1.1\r\nHost: x\r\n" + up + "Sec-WebSocket-Key: c2hvcnQ=\r\n" + ver + proto + "\r\n",
       "HTTP/1.1 400", "must be 16 bytes in base64"},
      {"no subprotocol", "GET / HTTP/1.1\r\nHost: x\r\n" + up + key + ver + "\r\n", "HTTP/1.1 400",
       "no subprotocol this server speaks: it offers foxglove.websocket.v1; the request asks for none"},
      {"wrong subprotocol",
       "GET / HTTP/1.1\r\nHost: x\r\n" + up + key + ver + "Sec-WebSocket-Protocol: mqtt\r\n\r\n",
       "HTTP/1.1 400", "the request asks for 'mqtt'"},
      {"header without colon",
       "GET / HTTP/1.1\r\nHost: x\r\nbroken header\r\n" + up + key + ver + proto + "\r\n", "HTTP/1.1 400",
       "malformed header line"},
      {"folded header", "GET / HTTP/1.1\r\nHost: x\r\n folded\r\n" + up + key + ver + proto + "\r\n",
       "HTTP/1.1 400", "malformed header line"},
  };
  for (const BadRequest& b : cases) {
    TestWsClient c(s.port());
    ASSERT_TRUE(c.send_raw(b.request)) << b.what;
    const std::string head = c.read_response_head();
    EXPECT_EQ(head.rfind(b.status, 0), 0u) << b.what << ": " << head;
    EXPECT_NE(head.find("Connection: close"), std::string::npos) << b.what;
    const std::string body = c.read_body(head);
    EXPECT_NE(body.find(b.reason), std::string::npos) << b.what << ": " << body;
    EXPECT_TRUE(c.wait_closed()) << b.what << ": the server keeps the connection";
  }
  EXPECT_EQ(s.opened(), 0u);
  EXPECT_EQ(s.server->stats().handshakes_refused, cases.size());
}

TEST(WebSocketServer, VersionRefusalNamesTheVersionItSpeaks) {
  EchoServer s;
  TestWsClient c(s.port());
  c.send_raw(
      "GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 7\r\n\r\n");
  EXPECT_NE(c.read_response_head().find("\r\nSec-WebSocket-Version: 13\r\n"), std::string::npos);
}

TEST(WebSocketServer, HeadersBeyondTheLimitAre431) {
  WebSocketOptions o;
  o.max_header_bytes = 1024;
  EchoServer s(o);
  TestWsClient c(s.port());
  // Never finished: the limit is applied while the request is still coming.
  c.send_raw("GET / HTTP/1.1\r\nHost: x\r\nX-Padding: " + std::string(4000, 'a'));
  const std::string head = c.read_response_head();
  EXPECT_EQ(head.rfind("HTTP/1.1 431", 0), 0u) << head;
  EXPECT_NE(c.read_body(head).find("limit of 1024 bytes"), std::string::npos);
  EXPECT_TRUE(c.wait_closed());
}

TEST(WebSocketServer, MaxClientsAre503) {
  WebSocketOptions o;
  o.max_clients = 1;
  EchoServer s(o);
  TestWsClient a(s.port());
  EXPECT_EQ(a.handshake().rfind("HTTP/1.1 101", 0), 0u);
  TestWsClient b(s.port());
  const std::string head = b.handshake();
  EXPECT_EQ(head.rfind("HTTP/1.1 503", 0), 0u) << head;
  EXPECT_NE(b.read_body(head).find("maximum of 1 clients"), std::string::npos);
}

TEST(WebSocketServer, StartFailsClearlyOnAPortInUseOrABadAddress) {
  EchoServer s;
  WebSocketOptions o;
  o.port = s.port();
  auto second = WebSocketServer::start(o, {});
  ASSERT_FALSE(second);
  EXPECT_EQ(second.error().message, "net::WebSocketServer::start(): cannot bind 127.0.0.1:" +
                                        std::to_string(s.port()) + ": Address already in use");
  o.port = 0;
  o.address = "not-an-address";
  auto bad = WebSocketServer::start(o, {});
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("'not-an-address' is not an address to listen on"), std::string::npos);
  o.address = "127.0.0.1";
  o.port = 70000;
  auto port = WebSocketServer::start(o, {});
  ASSERT_FALSE(port);
  EXPECT_NE(port.error().message.find("port 70000 is not a TCP port"), std::string::npos);
}

TEST(WebSocketServer, ListensOnIpv6LoopbackWhenAsked) {
  WebSocketOptions o;
  o.address = "::1";
  WebSocketHandler h;
  auto s = WebSocketServer::start(o, h);
  if (!s) GTEST_SKIP() << "no IPv6 loopback here: " << s.error().message;
  TestWsClient c((*s)->port(), 0, "::1");
  ASSERT_TRUE(c.connected());
  EXPECT_EQ(c.handshake().rfind("HTTP/1.1 101", 0), 0u);
  ASSERT_TRUE(eventually([&] { return (*s)->stats().clients_now == 1; }));
  EXPECT_EQ((*s)->stats().clients[0].peer.rfind("[::1]:", 0), 0u);
}

// ---- Frames
// ------------------------------------------------------------------------------------------------

TEST(WebSocketServer, MessagesWith16And64BitLengthsBothWays) {
  WebSocketOptions o;
  o.max_message_bytes = 4 * 1024 * 1024;
  EchoServer s(o);
  TestWsClient c(s.port());
  ASSERT_EQ(c.handshake().rfind("HTTP/1.1 101", 0), 0u);
  for (std::size_t n : {std::size_t{125}, std::size_t{126}, std::size_t{65535}, std::size_t{65536},
                        std::size_t{3 * 1024 * 1024 + 7}}) {
    std::string msg(n, '\0');
    for (std::size_t i = 0; i < n; ++i) msg[i] = static_cast<char>((i * 31 + n) & 255);
    ASSERT_TRUE(c.send_frame(0x2, msg)) << n;
    auto f = c.read_frame(10000);
    ASSERT_TRUE(f) << n;
    EXPECT_EQ(f->payload.size(), n);
    EXPECT_TRUE(f->payload == msg) << n;
  }
}

TEST(WebSocketServer, FragmentsAreReassembledWithAPingBetween) {
  EchoServer s;
  TestWsClient c(s.port());
  ASSERT_EQ(c.handshake().rfind("HTTP/1.1 101", 0), 0u);
  // "héllo" split inside the two-byte é: UTF-8 is checked on the whole message, not per fragment.
  ASSERT_TRUE(c.send_raw(TestWsClient::frame(0x1, "h\xc3", false) +
                         TestWsClient::frame(0x9, "are you there") +
                         TestWsClient::frame(0x0, "\xa9l", false) + TestWsClient::frame(0x0, "lo", true)));
  auto pong = c.read_frame();
  ASSERT_TRUE(pong);
  EXPECT_EQ(pong->opcode, 0xa);
  EXPECT_EQ(pong->payload, "are you there");
  auto f = c.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->opcode, 0x1);
  EXPECT_EQ(f->payload, "h\xc3\xa9llo");
  std::lock_guard<std::mutex> lock(s.log->mu);
  ASSERT_EQ(s.log->messages.size(), 1u);  // one message, not three
}

TEST(WebSocketServer, PingIsAnsweredWithItsPayloadAndPongIsIgnored) {
  EchoServer s;
  TestWsClient c(s.port());
  ASSERT_EQ(c.handshake().rfind("HTTP/1.1 101", 0), 0u);
  ASSERT_TRUE(c.send_frame(0xa, "unsolicited"));
  ASSERT_TRUE(c.send_frame(0x9, ""));
  auto f = c.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->opcode, 0xa);
  EXPECT_EQ(f->payload, "");
  ASSERT_TRUE(c.send_frame(0x9, std::string(125, 'p')));
  f = c.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->payload, std::string(125, 'p'));
}

TEST(WebSocketServer, CloseHandshakeStartedByTheClient) {
  EchoServer s;
  TestWsClient c(s.port());
  ASSERT_EQ(c.handshake().rfind("HTTP/1.1 101", 0), 0u);
  ASSERT_TRUE(s.wait_opened(1));
  ASSERT_TRUE(c.send_close(4001, "done here"));
  auto f = c.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->opcode, 0x8);
  EXPECT_EQ(f->close_code(), 4001);  // echoed
  EXPECT_TRUE(c.wait_closed()) << "the server ends the TCP connection after the close handshake";
  ASSERT_TRUE(s.wait_closed(1));
  EXPECT_EQ(s.last_close().code, 4001);
  EXPECT_EQ(s.last_close().reason, "done here");
  EXPECT_FALSE(s.last_close().by_server);
  EXPECT_EQ(s.server->send_text(s.last_opened(), "too late"), SendResult::kNoClient);
  EXPECT_EQ(s.server->stats().clients_now, 0u);
}

TEST(WebSocketServer, CloseWithoutACodeIsAnsweredWith1000) {
  EchoServer s;
  TestWsClient c(s.port());
  ASSERT_EQ(c.handshake().rfind("HTTP/1.1 101", 0), 0u);
  ASSERT_TRUE(c.send_frame(0x8, ""));
  auto f = c.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->close_code(), 1000);
  ASSERT_TRUE(s.wait_closed(1));
  EXPECT_EQ(s.last_close().code, kCloseNoStatus);
}

TEST(WebSocketServer, CloseHandshakeStartedByTheServer) {
  EchoServer s;
  TestWsClient c(s.port());
  ASSERT_EQ(c.handshake().rfind("HTTP/1.1 101", 0), 0u);
  ASSERT_TRUE(s.wait_opened(1));
  s.server->close(s.last_opened(), 1000, "see you");
  auto f = c.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->opcode, 0x8);
  EXPECT_EQ(f->close_code(), 1000);
  EXPECT_EQ(f->close_reason(), "see you");
  ASSERT_TRUE(s.wait_closed(1));
  EXPECT_TRUE(s.last_close().by_server);
  // Data after the server's close is no longer delivered; the client's close ends it.
  ASSERT_TRUE(c.send_text("ignored"));
  ASSERT_TRUE(c.send_close(1000));
  EXPECT_TRUE(c.wait_closed());
  std::lock_guard<std::mutex> lock(s.log->mu);
  EXPECT_TRUE(s.log->messages.empty());
}

TEST(WebSocketServer, ServerCloseTimesOutWhenTheClientNeverAnswers) {
  WebSocketOptions o;
  o.close_timeout_ms = 200;
  EchoServer s(o);
  TestWsClient c(s.port());
  ASSERT_EQ(c.handshake().rfind("HTTP/1.1 101", 0), 0u);
  ASSERT_TRUE(s.wait_opened(1));
  s.server->close(s.last_opened());
  auto f = c.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->opcode, 0x8);
  EXPECT_TRUE(c.wait_closed(3000));
}

struct ProtocolCase {
  const char* what;
  std::string bytes;
  std::uint16_t code;
  const char* reason;
};

TEST(WebSocketServer, ProtocolErrorsCloseWithTheirCodeAndReason) {
  WebSocketOptions o;
  o.max_message_bytes = 1000;
  EchoServer s(o);
  using C = TestWsClient;
  const std::vector<ProtocolCase> cases = {
      {"unmasked", C::frame(0x1, "hi", true, false), 1002, "an unmasked client frame"},
      {"reserved bits", C::frame(0x1, "hi", true, true, 0x40), 1002, "reserved bits set"},
      {"opcode 3", C::frame(0x3, "hi"), 1002, "unknown opcode 3"},
      {"opcode 11", C::frame(0xb, "hi"), 1002, "unknown opcode 11"},
      {"fragmented ping", C::frame(0x9, "hi", false), 1002, "a fragmented control frame"},
      {"long ping", C::frame(0x9, std::string(126, 'x')), 1002, "longer than 125 bytes"},
      {"lone continuation", C::frame(0x0, "hi"), 1002, "without a message to continue"},
      {"message inside a message", C::frame(0x1, "a", false) + C::frame(0x1, "b"), 1002,
       "before the last fragment of the previous one"},
      {"1-byte close", C::frame(0x8, "x"), 1002, "a close frame of 1 byte"},
      {"close code 1005", C::frame(0x8, std::string("\x03\xed", 2)), 1002, "invalid code 1005"},
      {"close code 999", C::frame(0x8, std::string("\x03\xe7", 2)), 1002, "invalid code 999"},
      {"bad UTF-8", C::frame(0x1, "\xc0\xaf"), 1007, "not valid UTF-8"},
      {"bad UTF-8 in fragments", C::frame(0x1, "ok", false) + C::frame(0x0, "\xff"), 1007, "not valid UTF-8"},
      {"too big", C::frame(0x2, std::string(1001, 'x')), 1009, "beyond this server's limit of 1000"},
      {"too big in fragments",
       C::frame(0x2, std::string(600, 'x'), false) + C::frame(0x0, std::string(600, 'x')), 1009,
       "beyond this server's limit of 1000"},
  };
  for (const ProtocolCase& p : cases) {
    TestWsClient c(s.port());
    ASSERT_EQ(c.handshake().rfind("HTTP/1.1 101", 0), 0u) << p.what;
    ASSERT_TRUE(c.send_raw(p.bytes)) << p.what;
    auto f = c.read_frame();
    ASSERT_TRUE(f) << p.what;
    EXPECT_EQ(f->opcode, 0x8) << p.what;
    EXPECT_EQ(f->close_code(), p.code) << p.what;
    EXPECT_NE(f->close_reason().find(p.reason), std::string::npos) << p.what << ": " << f->close_reason();
    EXPECT_TRUE(c.wait_closed()) << p.what;
  }
  ASSERT_TRUE(s.wait_closed(cases.size()));
  EXPECT_EQ(s.server->stats().protocol_errors, cases.size());
  std::lock_guard<std::mutex> lock(s.log->mu);
  EXPECT_TRUE(s.log->messages.empty());
}

TEST(WebSocketServer, AnOversizedFrameIsRefusedBeforeItsPayloadArrives) {
  WebSocketOptions o;
  o.max_message_bytes = 1000;
  EchoServer s(o);
  TestWsClient c(s.port());
  ASSERT_EQ(c.handshake().rfind("HTTP/1.1 101", 0), 0u);
  // A header announcing 2^40 bytes (64-bit length) and no payload: 1009 at once, nothing buffered.
  std::string h = "\x82\xff";
  for (int b = 7; b >= 0; --b) h += static_cast<char>((std::uint64_t{1} << 40) >> (8 * b));
  h += "mask";
  ASSERT_TRUE(c.send_raw(h));
  auto f = c.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->close_code(), 1009);
  // A length with the top bit set is a protocol error, not a size.
  TestWsClient d(s.port());
  ASSERT_EQ(d.handshake().rfind("HTTP/1.1 101", 0), 0u);
  ASSERT_TRUE(d.send_raw(std::string("\x82\xff\x80\x00\x00\x00\x00\x00\x00\x01mask", 14)));
  f = d.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->close_code(), 1002);
}

// ---- Queues, slow and vanishing clients
// -------------------------------------------------------------------------

TEST(WebSocketServer, ASlowClientGetsDropsWhileAFastOneGetsEverythingAndSendNeverBlocks) {
  WebSocketOptions o;
  o.queue_bytes = 4 * 1024 * 1024;
  EchoServer s(o, false);
  TestWsClient slow(s.port(), 64 * 1024);
  ASSERT_EQ(slow.handshake().rfind("HTTP/1.1 101", 0), 0u);
  TestWsClient fast(s.port());
  ASSERT_EQ(fast.handshake().rfind("HTTP/1.1 101", 0), 0u);
  ASSERT_TRUE(s.wait_opened(2));
  const ClientId slow_id = s.log->opened[0], fast_id = s.log->opened[1];
  constexpr int kMessages = 40;
  std::atomic<int> got{0};
  std::atomic<bool> in_order{true};
  std::thread reader([&] {
    for (int i = 0; i < kMessages; ++i) {
      auto f = fast.read_frame(20000);
      if (!f) return;
      if (f->payload.size() != 1024 * 1024 || static_cast<unsigned char>(f->payload[0]) != i)
        in_order = false;
      ++got;
    }
  });
  double worst_ms = 0;
  int dropped = 0;
  for (int i = 0; i < kMessages; ++i) {
    // One shared 1 MiB body for both clients, as an image is.
    std::vector<std::uint8_t> body(1024 * 1024, static_cast<std::uint8_t>(i));
    const SharedBytes b = share_bytes(std::move(body));
    const auto t0 = Clock::now();
    const SendResult rs = s.server->send(slow_id, true, b, {}, true);
    const SendResult rf = s.server->send(fast_id, true, b, {}, true);
    worst_ms = std::max(worst_ms, std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    EXPECT_NE(rs, SendResult::kNoClient);
    EXPECT_EQ(rf, SendResult::kQueued) << i;
    dropped += rs == SendResult::kDropped;
    std::this_thread::sleep_for(std::chrono::milliseconds(15));
  }
  reader.join();
  EXPECT_EQ(got.load(), kMessages);
  EXPECT_TRUE(in_order.load());
  // The slow client's kernel buffers and its 4 MiB queue hold some; the rest were dropped.
  EXPECT_GT(dropped, kMessages / 2);
  EXPECT_LT(worst_ms, 50.0) << "send() must not wait for the socket";
  const WebSocketStats st = s.server->stats();
  EXPECT_EQ(st.messages_dropped, static_cast<std::uint64_t>(dropped));
  for (const ClientStats& c : st.clients) {
    if (c.id == slow_id) {
      EXPECT_EQ(c.messages_dropped, static_cast<std::uint64_t>(dropped));
      EXPECT_LE(c.queued_bytes, o.queue_bytes);
    } else {
      EXPECT_EQ(c.messages_dropped, 0u);
    }
  }
  EXPECT_EQ(st.clients_now, 2u) << "a slow client is not disconnected for droppable messages";
}

TEST(WebSocketServer, AClientThatCannotTakeAMessageThatMustGoIsDisconnected) {
  WebSocketOptions o;
  o.queue_bytes = 1024 * 1024;
  o.control_reserve_bytes = 256 * 1024;
  EchoServer s(o, false);
  TestWsClient slow(s.port(), 64 * 1024);
  ASSERT_EQ(slow.handshake().rfind("HTTP/1.1 101", 0), 0u);
  ASSERT_TRUE(s.wait_opened(1));
  const SharedBytes b = share_bytes(std::vector<std::uint8_t>(100 * 1024, 7));
  SendResult r = SendResult::kQueued;
  int sent = 0;
  for (; sent < 1000 && r == SendResult::kQueued; ++sent) {
    r = s.server->send(s.last_opened(), true, b, {}, false);
    if (sent % 10 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_EQ(r, SendResult::kDisconnected);
  ASSERT_TRUE(s.wait_closed(1));
  EXPECT_TRUE(s.last_close().by_server);
  EXPECT_NE(s.last_close().reason.find("did not read"), std::string::npos);
  const WebSocketStats st = s.server->stats();
  EXPECT_EQ(st.disconnects_overflow, 1u);
  EXPECT_EQ(st.clients_now, 0u);
  EXPECT_EQ(s.server->send(s.last_opened(), true, b), SendResult::kNoClient);
}

TEST(WebSocketServer, AStalledClientIsDisconnectedAfterTheStallTimeout) {
  WebSocketOptions o;
  o.stall_timeout_ms = 300;
  EchoServer s(o, false);
  TestWsClient slow(s.port(), 64 * 1024);
  ASSERT_EQ(slow.handshake().rfind("HTTP/1.1 101", 0), 0u);
  ASSERT_TRUE(s.wait_opened(1));
  const SharedBytes b = share_bytes(std::vector<std::uint8_t>(1024 * 1024, 7));
  for (int i = 0; i < 8; ++i) s.server->send(s.last_opened(), true, b, {}, true);
  ASSERT_TRUE(s.wait_closed(1, 5000));
  EXPECT_NE(s.last_close().reason.find("took no data for 300 ms"), std::string::npos)
      << s.last_close().reason;
  EXPECT_EQ(s.server->stats().disconnects_stalled, 1u);
}

TEST(WebSocketServer, AClientVanishingMidFrameWhileWeSendIsFreed) {
  EchoServer s(WebSocketOptions{}, false);
  for (const bool reset : {true, false}) {
    const std::size_t before = s.closed();
    TestWsClient c(s.port(), 64 * 1024);
    ASSERT_EQ(c.handshake().rfind("HTTP/1.1 101", 0), 0u);
    ASSERT_TRUE(eventually([&] { return s.opened() == before + 1; }));
    const ClientId id = s.last_opened();
    const SharedBytes big = share_bytes(std::vector<std::uint8_t>(8 * 1024 * 1024, 1));
    ASSERT_EQ(s.server->send(id, true, big, {}, true), SendResult::kQueued);
    ASSERT_TRUE(c.read_bytes(100 * 1024)) << "part of the frame";
    if (reset) {
      c.abort();
    } else {
      c.close();
    }
    ASSERT_TRUE(s.wait_closed(before + 1)) << (reset ? "reset" : "closed");
    EXPECT_EQ(s.last_close().code, kCloseAbnormal);
    EXPECT_FALSE(s.last_close().by_server);
  }
  // The server carries on.
  TestWsClient d(s.port());
  EXPECT_EQ(d.handshake().rfind("HTTP/1.1 101", 0), 0u);
}

TEST(WebSocketServer, AClientSendingHalfAFrameThenClosingIsFreed) {
  EchoServer s;
  TestWsClient c(s.port());
  ASSERT_EQ(c.handshake().rfind("HTTP/1.1 101", 0), 0u);
  const std::string f = TestWsClient::frame(0x1, std::string(1000, 'x'));
  ASSERT_TRUE(c.send_raw(f.substr(0, 500)));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  c.close();
  ASSERT_TRUE(s.wait_closed(1));
  EXPECT_EQ(s.last_close().code, kCloseAbnormal);
  EXPECT_NE(s.last_close().reason.find("without a close frame"), std::string::npos);
  std::lock_guard<std::mutex> lock(s.log->mu);
  EXPECT_TRUE(s.log->messages.empty());
}

TEST(WebSocketServer, AClientVanishingMidHandshakeOrIdlingIsFreed) {
  WebSocketOptions o;
  o.handshake_timeout_ms = 200;
  EchoServer s(o);
  {
    TestWsClient c(s.port());
    ASSERT_TRUE(c.send_raw("GET / HTTP/1.1\r\nHost: x\r\nUpgr"));
  }
  TestWsClient idle(s.port());
  EXPECT_TRUE(idle.wait_closed(3000)) << "an idle connection is closed after the handshake timeout";
  ASSERT_TRUE(eventually([&] { return s.server->stats().handshakes_abandoned == 2; }));
  EXPECT_EQ(s.opened(), 0u);
  EXPECT_EQ(s.closed(), 0u);
}

// Idle sockets held open at the bound of connections (80 with 32 clients): a real client that
// connects is answered at once, the oldest idle one making room, not after the idle ones' handshake
// timeout (which was 4 to 9 s of no answer). Long here (30 s) so that only making room can answer.
TEST(WebSocketServer, IdleSocketsHeldOpenDoNotLockOutARealClient) {
  WebSocketOptions o;
  o.handshake_timeout_ms = 30'000;
  EchoServer s(o);
  const std::size_t bound = 2 * o.max_clients + 16, held = bound + 20;
  std::vector<std::unique_ptr<TestWsClient>> idle;
  for (std::size_t i = 0; i < held; ++i) idle.push_back(std::make_unique<TestWsClient>(s.port()));
  ASSERT_TRUE(eventually([&] { return s.server->stats().connections_accepted >= held; }));
  for (int round = 0; round < 3; ++round) {
    TestWsClient real(s.port());
    const std::string head = real.handshake("", 3000);
    ASSERT_EQ(head.rfind("HTTP/1.1 101", 0), 0u) << "round " << round << ": " << head;
    ASSERT_TRUE(real.send_text("still here"));
    const auto echo = real.read_frame(3000);
    ASSERT_TRUE(echo) << "round " << round;
    EXPECT_EQ(echo->payload, "still here");
  }
  // The idle ones that made room were closed, oldest first, and counted: 20 for the flood beyond the
  // bound, and one for each real client that came before the one before it had left (1 to 3).
  EXPECT_TRUE(idle.front()->wait_closed(3000));
  const std::uint64_t made_room = held - bound;
  EXPECT_TRUE(eventually([&] { return s.server->stats().handshakes_abandoned >= made_room + 1; }));
  EXPECT_LE(s.server->stats().handshakes_abandoned, made_room + 3);
  EXPECT_FALSE(idle.back()->wait_closed(100)) << "the newest idle connection waits for its request";
  EXPECT_EQ(s.opened(), 3u);
}

TEST(WebSocketServer, StopSaysGoingAwayToEveryClient) {
  auto s = std::make_unique<EchoServer>();
  TestWsClient a(s->port()), b(s->port());
  ASSERT_EQ(a.handshake().rfind("HTTP/1.1 101", 0), 0u);
  ASSERT_EQ(b.handshake().rfind("HTTP/1.1 101", 0), 0u);
  ASSERT_TRUE(s->wait_opened(2));
  std::thread answer([&] {
    auto f = a.read_frame();
    if (f && f->opcode == 0x8) a.send_close(f->close_code());
  });
  s->server->stop();  // b never answers: stop() waits close_timeout_ms at most
  answer.join();
  EXPECT_EQ(s->closed(), 2u);
  EXPECT_EQ(s->last_close().code, kCloseGoingAway);
  auto f = b.read_frame();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->close_code(), kCloseGoingAway);
  EXPECT_TRUE(b.wait_closed());
  EXPECT_TRUE(a.wait_closed());
  s.reset();
}

// Connections of every kind come and go while another thread sends to whoever is open: the
// counts settle and every descriptor is given back (ASan, in `make sanitize`, checks the memory).
TEST(WebSocketServer, ManyConnectionsComeAndGoWithoutLeaks) {
  const int fds_before = open_fds();
  {
    WebSocketOptions o;
    o.queue_bytes = 2 * 1024 * 1024;
    o.close_timeout_ms = 300;
    o.handshake_timeout_ms = 300;
    EchoServer s(o);
    std::atomic<bool> done{false};
    std::thread sender([&] {
      const SharedBytes b = share_bytes(std::vector<std::uint8_t>(300 * 1024, 9));
      while (!done) {
        for (ClientId id : s.server->clients()) s.server->send(id, true, b, {}, true);
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    });
    for (int i = 0; i < 150; ++i) {
      TestWsClient c(s.port(), i % 2 ? 32 * 1024 : 0);
      ASSERT_TRUE(c.connected());
      switch (i % 6) {
        case 0:  // a normal life
          c.handshake();
          c.send_text("hi");
          c.send_close(1000);
          c.read_frame(200);
          break;
        case 1:  // handshake, then a reset while data is coming
          c.handshake();
          c.read_bytes(1000, 200);
          c.abort();
          break;
        case 2:  // half a request
          c.send_raw("GET / HTTP/1.1\r\nHo");
          break;
        case 3:  // half a frame
          c.handshake();
          c.send_raw(TestWsClient::frame(0x2, std::string(5000, 'y')).substr(0, 2000));
          break;
        case 4:  // refused
          c.send_raw("GET / HTTP/1.1\r\nHost: x\r\n\r\n");
          break;
        case 5:  // a protocol error
          c.handshake();
          c.send_raw(TestWsClient::frame(0x1, "x", true, false));
          break;
      }
    }
    done = true;
    sender.join();
    EXPECT_TRUE(eventually([&] { return s.server->stats().clients_now == 0; }, 5000));
    const WebSocketStats st = s.server->stats();
    EXPECT_EQ(st.connections_accepted, 150u);
    EXPECT_EQ(st.disconnects, st.clients_ever);
    EXPECT_EQ(s.opened(), s.closed());
    // Lingering sockets (closing, draining) are gone within their timeouts.
    EXPECT_TRUE(eventually([&] { return open_fds() <= fds_before + 3; }, 5000))
        << open_fds() << " descriptors open, " << fds_before << " before (the server's own 2 or 3 aside)";
  }
  EXPECT_EQ(open_fds(), fds_before);
}

// send() from several threads at once while clients come and go (for ThreadSanitizer and ASan).
TEST(WebSocketServer, ConcurrentSendersAndClients) {
  WebSocketOptions o;
  o.queue_bytes = 1024 * 1024;
  EchoServer s(o, false);
  std::atomic<bool> done{false};
  std::vector<std::thread> senders;
  std::atomic<std::uint64_t> calls{0};
  for (int t = 0; t < 3; ++t)
    senders.emplace_back([&, t] {
      const SharedBytes b = share_bytes(std::vector<std::uint8_t>(10000, static_cast<std::uint8_t>(t)));
      while (!done) {
        for (ClientId id : s.server->clients()) {
          s.server->send(id, t == 0, b, {}, t != 1);
          ++calls;
        }
        if (t == 2)
          for (ClientId id : s.server->clients())
            if (id % 3 == 0) s.server->close(id);
        std::this_thread::yield();
      }
    });
  for (int i = 0; i < 30; ++i) {
    TestWsClient c(s.port());
    c.handshake();
    for (int k = 0; k < 5; ++k) c.read_frame(20);
    if (i % 2) c.abort();
  }
  done = true;
  for (std::thread& t : senders) t.join();
  EXPECT_TRUE(eventually([&] { return s.server->stats().clients_now == 0; }));
  EXPECT_GT(calls.load(), 0u);
}

}  // namespace
}  // namespace augrig::net
