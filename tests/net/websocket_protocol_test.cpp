// The wire format on its own (websocket_protocol.hpp), byte for byte against RFC 6455: the
// handshake verdicts (the RFC's own example request, every refusal with its status), and the frame
// decoder (the RFC's section 5.7 examples, lengths of 7, 16 and 64 bits, fragments, control frames
// between fragments, every protocol error, a frame arriving a byte at a time, close payloads, the
// message limit, dropping while the server closes). tests/net/websocket_test.cpp runs the same
// rules through sockets.
#include "net/websocket_protocol.hpp"

#include <gtest/gtest.h>

#include "net/websocket.hpp"

namespace augrig::net {
namespace {

using Kind = FrameStep::Kind;

const std::vector<std::string> kFoxglove = {"foxglove.websocket.v1"};

// RFC 6455 section 1.2's request, with the subprotocol Foxglove asks for.
std::string request(const std::string& extra = "Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n") {
  return "GET /chat HTTP/1.1\r\nHost: server.example.com\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
         "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nOrigin: http://example.com\r\n"
         "Sec-WebSocket-Version: 13\r\n" +
         extra;
}

std::string without_crlf_end(std::string s) {
  if (s.size() >= 2 && s.substr(s.size() - 2) == "\r\n") s.resize(s.size() - 2);
  return s;
}

HandshakeVerdict verdict(const std::string& head, const std::vector<std::string>& offered = kFoxglove) {
  return check_handshake(without_crlf_end(head), offered, "augrig");
}

TEST(CheckHandshake, AcceptsTheRfcsRequestWithItsSubprotocol) {
  const HandshakeVerdict v = verdict(request());
  ASSERT_TRUE(v.accepted()) << v.reason;
  EXPECT_EQ(v.key, "dGhlIHNhbXBsZSBub25jZQ==");
  EXPECT_EQ(websocket_accept(v.key), "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=");
  EXPECT_EQ(v.subprotocol, "foxglove.websocket.v1");
  // Header names in any case, values' tokens in any order; no subprotocol offered: none chosen.
  const HandshakeVerdict w = verdict(
      "GET / HTTP/1.1\r\nhOsT: x\r\nUPGRADE: WebSocket\r\nconnection: keep-alive, Upgrade\r\n"
      "sec-websocket-key: AAAAAAAAAAAAAAAAAAAAAA==\r\nSec-WebSocket-Version: 13\r\n",
      {});
  ASSERT_TRUE(w.accepted()) << w.reason;
  EXPECT_EQ(w.subprotocol, "");
}

TEST(CheckHandshake, EachRefusalHasItsStatusAndReason) {
  struct Case {
    std::string head;
    int status;
    std::string reason_part;
  };
  const std::string key = "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n";
  const Case cases[] = {
      {"GET /\r\n", 400, "a malformed request line"},
      {"GET / HTTP/1.0\r\nHost: x\r\n", 400,
       "HTTP/1.1 is required for a WebSocket handshake, the request is HTTP/1.0"},
      {"POST / HTTP/1.1\r\nHost: x\r\n", 405, "a WebSocket handshake is a GET request, not POST"},
      {"GET / HTTP/1.1\r\n", 400, "no Host header"},
      {"GET / HTTP/1.1\r\nHost x\r\n", 400, "a malformed header line: 'Host x'"},
      {"GET / HTTP/1.1\r\n Host: x\r\n", 400, "a malformed header line"},
      {"GET / HTTP/1.1\r\nHost : x\r\n", 400, "a malformed header line"},
      {"GET / HTTP/1.1\r\nHost: x\r\n", 426, "this is a WebSocket server (augrig)"},
      {"GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\n", 400,
       "the Connection header must include 'Upgrade'"},
      {"GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: "
       "8\r\n",
       426, "Sec-WebSocket-Version must be 13 (RFC 6455), the request has '8'"},
      {"GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: "
       "13\r\n",
       400, "no Sec-WebSocket-Key header"},
      {"GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: "
       "13\r\nSec-WebSocket-Key: c2hvcnQ=\r\n",
       400, "Sec-WebSocket-Key must be 16 bytes in base64, got 'c2hvcnQ='"},
      {request(""), 400,
       "no subprotocol this server speaks: it offers foxglove.websocket.v1; the request asks for none"},
      {request("Sec-WebSocket-Protocol: chat, superchat\r\n"), 400, "the request asks for 'chat, superchat'"},
  };
  for (const Case& c : cases) {
    const HandshakeVerdict v = verdict(c.head);
    EXPECT_EQ(v.status, c.status) << c.head;
    EXPECT_NE(v.reason.find(c.reason_part), std::string::npos) << c.head << " -> " << v.reason;
  }
  EXPECT_EQ(verdict("POST / HTTP/1.1\r\nHost: x\r\n").extra_headers, "Allow: GET\r\n");
  EXPECT_EQ(verdict("GET / HTTP/1.1\r\nHost: x\r\n" + key).extra_headers,
            "Upgrade: websocket\r\nConnection: Upgrade\r\n");
}

// A client frame: FIN, `opcode`, masked with `mask`.
std::string frame(std::uint8_t opcode, std::string_view payload, bool fin = true,
                  std::array<std::uint8_t, 4> mask = {0x37, 0xfa, 0x21, 0x3d}) {
  std::string f;
  f += static_cast<char>((fin ? 0x80 : 0) | opcode);
  const std::size_t n = payload.size();
  if (n < 126) {
    f += static_cast<char>(0x80 | n);
  } else if (n <= 0xffff) {
    f += static_cast<char>(0x80 | 126);
    f += static_cast<char>(n >> 8);
    f += static_cast<char>(n & 0xff);
  } else {
    f += static_cast<char>(0x80 | 127);
    for (int b = 7; b >= 0; --b) f += static_cast<char>((static_cast<std::uint64_t>(n) >> (8 * b)) & 0xff);
  }
  for (std::uint8_t m : mask) f += static_cast<char>(m);
  for (std::size_t k = 0; k < n; ++k) f += static_cast<char>(payload[k] ^ static_cast<char>(mask[k & 3]));
  return f;
}

FrameStep step(FrameDecoder& d, std::string& bytes, bool deliver = true) {
  return d.next(std::span<char>(bytes.data(), bytes.size()), deliver);
}

TEST(FrameDecoder, TheRfcsMaskedHelloAndLengthsOf7_16And64Bits) {
  FrameDecoder d(1 << 20);
  // RFC 6455 5.7: "a single-frame masked text message" containing "Hello".
  std::string hello = "\x81\x85\x37\xfa\x21\x3d\x7f\x9f\x4d\x51\x58";
  FrameStep s = step(d, hello);
  ASSERT_EQ(s.kind, Kind::kMessage);
  EXPECT_FALSE(s.binary);
  EXPECT_EQ(s.data, "Hello");
  EXPECT_EQ(s.consumed, 11u);
  for (std::size_t n : {125u, 126u, 65535u, 65536u, 300000u}) {
    const std::string payload(n, 'x');
    std::string f = frame(0x2, payload);
    s = step(d, f);
    ASSERT_EQ(s.kind, Kind::kMessage) << n;
    EXPECT_TRUE(s.binary);
    EXPECT_EQ(s.data.size(), n);
    EXPECT_EQ(s.consumed, f.size());
  }
}

TEST(FrameDecoder, AFrameArrivingAByteAtATimeNeedsMoreUntilWhole) {
  FrameDecoder d(1 << 20);
  const std::string whole = frame(0x1, std::string(300, 'y'));
  for (std::size_t n = 0; n < whole.size(); ++n) {
    std::string part = whole.substr(0, n);
    const FrameStep s = step(d, part);
    ASSERT_EQ(s.kind, Kind::kNeedMore) << n;
    ASSERT_EQ(s.consumed, 0u);
  }
  std::string all = whole;
  EXPECT_EQ(step(d, all).kind, Kind::kMessage);
}

TEST(FrameDecoder, FragmentsWithAPingBetweenMakeOneMessage) {
  FrameDecoder d(1 << 20);
  std::string bytes = frame(0x1, "Hel", false) + frame(0x9, "are you there") + frame(0x0, "lo", false) +
                      frame(0x0, " world", true);
  std::size_t pos = 0;
  std::vector<FrameStep> steps;
  while (pos < bytes.size()) {
    const FrameStep s = d.next(std::span<char>(bytes.data() + pos, bytes.size() - pos), true);
    ASSERT_NE(s.kind, Kind::kNeedMore);
    pos += s.consumed;
    steps.push_back(s);
  }
  ASSERT_EQ(steps.size(), 4u);
  EXPECT_EQ(steps[0].kind, Kind::kNone);
  EXPECT_EQ(steps[1].kind, Kind::kPing);
  EXPECT_EQ(steps[1].data, "are you there");
  EXPECT_EQ(steps[2].kind, Kind::kNone);
  EXPECT_EQ(steps[3].kind, Kind::kMessage);
  EXPECT_EQ(steps[3].data, "Hello world");
}

TEST(FrameDecoder, ProtocolErrorsHaveTheirCodeAndReason) {
  struct Case {
    std::string bytes;
    std::uint16_t code;
    std::string reason;
  };
  std::string unmasked = "\x81\x05Hello";
  const Case cases[] = {
      {"\xc1\x80", kCloseProtocolError, "a frame with reserved bits set (no extension was negotiated)"},
      {unmasked, kCloseProtocolError, "an unmasked client frame"},
      {frame(0x3, "x"), kCloseProtocolError, "a frame with the unknown opcode 3"},
      {frame(0x9, "x", false), kCloseProtocolError, "a fragmented control frame"},
      {frame(0x9, std::string(126, 'p')), kCloseProtocolError, "a control frame longer than 125 bytes"},
      {frame(0x0, "x"), kCloseProtocolError, "a continuation frame without a message to continue"},
      {std::string("\x82\xff\x80\x00\x00\x00\x00\x00\x00\x00", 10) + "mask", kCloseProtocolError,
       "a frame length with its most significant bit set"},
      {frame(0x2, std::string(1001, 'b')), kCloseTooBig,
       "a message of 1001 bytes or more, beyond this server's limit of 1000"},
      {frame(0x8, "x"), kCloseProtocolError, "a close frame of 1 byte"},
      {frame(0x8, std::string("\x03\xec", 2)), kCloseProtocolError,
       "a close frame with the invalid code 1004"},
      {frame(0x8, std::string("\x03\xe8\xff", 3)), kCloseInvalidData,
       "a close frame whose reason is not valid UTF-8"},
  };
  for (const Case& c : cases) {
    FrameDecoder d(1000);
    std::string b = c.bytes;
    const FrameStep s = step(d, b);
    EXPECT_EQ(s.kind, Kind::kError) << c.reason;
    EXPECT_EQ(s.code, c.code) << c.reason;
    EXPECT_EQ(s.reason, c.reason);
  }
  // The limit counts the fragments so far; a new message inside a fragmented one is an error.
  FrameDecoder d(1000);
  std::string first = frame(0x2, std::string(600, 'a'), false), second = frame(0x0, std::string(600, 'a'));
  ASSERT_EQ(step(d, first).kind, Kind::kNone);
  FrameStep s = step(d, second);
  EXPECT_EQ(s.kind, Kind::kError);
  EXPECT_EQ(s.reason, "a message of 1200 bytes or more, beyond this server's limit of 1000");
  std::string text = frame(0x1, "new");
  EXPECT_EQ(step(d, text).reason, "a new message before the last fragment of the previous one");
  // Decided from the first two bytes, before the rest arrives.
  FrameDecoder e(1000);
  std::string two = frame(0x3, "x").substr(0, 2);
  EXPECT_EQ(step(e, two).kind, Kind::kError);
}

TEST(FrameDecoder, ClosePayloadsAndDroppingWhileClosing) {
  FrameDecoder d(1 << 20);
  std::string none = frame(0x8, "");
  FrameStep s = step(d, none);
  ASSERT_EQ(s.kind, Kind::kClose);
  EXPECT_EQ(s.code, kCloseNoStatus);
  std::string bye = frame(0x8, std::string("\x03\xe9", 2) + "going away");
  s = step(d, bye);
  ASSERT_EQ(s.kind, Kind::kClose);
  EXPECT_EQ(s.code, 1001);
  EXPECT_EQ(s.reason, "going away");
  EXPECT_EQ(s.consumed, bye.size());
  // Not delivering (the server sent its close): a message is read and dropped, a pong still seen.
  std::string msg = frame(0x1, "late"), pong = frame(0xa, "p");
  s = step(d, msg, false);
  EXPECT_EQ(s.kind, Kind::kNone);
  EXPECT_EQ(s.consumed, msg.size());
  EXPECT_EQ(step(d, pong, false).kind, Kind::kPong);
}

}  // namespace
}  // namespace augrig::net
