// check_handshake() and FrameDecoder (websocket_protocol.hpp): RFC 6455's rules for what a client
// sends, section by section (4.2.1 the opening handshake, 5.2 to 5.5 the frames, 7.4 close codes).
#include "net/websocket_protocol.hpp"

#include <algorithm>
#include <cctype>
#include <map>

#include "net/websocket.hpp"

namespace augrig::net {

namespace {

constexpr std::uint8_t kOpContinuation = 0x0, kOpText = 0x1, kOpBinary = 0x2, kOpClose = 0x8, kOpPing = 0x9,
                       kOpPong = 0xa;

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

// The comma-separated tokens of a header value, trimmed, empty ones left out.
std::vector<std::string> tokens(std::string_view v) {
  std::vector<std::string> out;
  while (!v.empty()) {
    const auto comma = v.find(',');
    const std::string_view t = trim(v.substr(0, comma));
    if (!t.empty()) out.emplace_back(t);
    if (comma == std::string_view::npos) break;
    v.remove_prefix(comma + 1);
  }
  return out;
}

bool has_token(std::string_view v, std::string_view token) {
  for (const std::string& t : tokens(v))
    if (lower(t) == token) return true;
  return false;
}

HandshakeVerdict refusal(int status, std::string text, std::string reason, std::string extra_headers = {}) {
  HandshakeVerdict v;
  v.status = status;
  v.status_text = std::move(text);
  v.reason = std::move(reason);
  v.extra_headers = std::move(extra_headers);
  return v;
}

using Headers = std::map<std::string, std::string>;  // lower-case names; repeated ones joined by ", "

// The request line, then the header lines into `headers`; a refusal when either is malformed.
std::optional<HandshakeVerdict> parse_request(std::string_view req, Headers& headers) {
  const std::size_t line_end = req.find("\r\n");
  const std::string_view request_line = req.substr(0, line_end);
  const auto sp1 = request_line.find(' ');
  const auto sp2 = sp1 == std::string_view::npos ? sp1 : request_line.find(' ', sp1 + 1);
  if (sp2 == std::string_view::npos || request_line.find(' ', sp2 + 1) != std::string_view::npos)
    return refusal(400, "Bad Request", "a malformed request line: expected 'GET /path HTTP/1.1'");
  const std::string_view method = request_line.substr(0, sp1);
  const std::string_view version = request_line.substr(sp2 + 1);
  if (version != "HTTP/1.1")
    return refusal(400, "Bad Request",
                   "HTTP/1.1 is required for a WebSocket handshake, the request is " +
                       std::string(version.substr(0, 32)));
  if (method != "GET")
    return refusal(405, "Method Not Allowed",
                   "a WebSocket handshake is a GET request, not " + std::string(method.substr(0, 32)),
                   "Allow: GET\r\n");
  std::size_t pos = line_end == std::string_view::npos ? req.size() : line_end + 2;
  while (pos < req.size()) {
    std::size_t e = req.find("\r\n", pos);
    if (e == std::string_view::npos) e = req.size();
    const std::string_view line = req.substr(pos, e - pos);
    pos = e + 2;
    const auto colon = line.find(':');
    if (line.empty() || line.front() == ' ' || line.front() == '\t' || colon == std::string_view::npos ||
        colon == 0 || trim(line.substr(0, colon)).size() != colon)
      return refusal(400, "Bad Request",
                     "a malformed header line: '" + std::string(line.substr(0, 64)) + "'");
    std::string& v = headers[lower(line.substr(0, colon))];
    if (!v.empty()) v += ", ";
    v += trim(line.substr(colon + 1));
  }
  return std::nullopt;
}

}  // namespace

HandshakeVerdict check_handshake(std::string_view request_head, const std::vector<std::string>& subprotocols,
                                 const std::string& server) {
  Headers headers;
  if (auto bad = parse_request(request_head, headers)) return *bad;
  auto header = [&](const char* name) -> const std::string* {
    const auto it = headers.find(name);
    return it == headers.end() ? nullptr : &it->second;
  };
  if (!header("host")) return refusal(400, "Bad Request", "no Host header (HTTP/1.1 requires one)");
  const std::string* upgrade = header("upgrade");
  if (!upgrade || !has_token(*upgrade, "websocket"))
    return refusal(426, "Upgrade Required",
                   "this is a WebSocket server (" + server +
                       "): connect with a WebSocket client, e.g. Foxglove, to ws://HOST:PORT",
                   "Upgrade: websocket\r\nConnection: Upgrade\r\n");
  const std::string* connection = header("connection");
  if (!connection || !has_token(*connection, "upgrade"))
    return refusal(400, "Bad Request", "the Connection header must include 'Upgrade'");
  const std::string* ws_version = header("sec-websocket-version");
  if (!ws_version || *ws_version != "13")
    return refusal(426, "Upgrade Required",
                   "Sec-WebSocket-Version must be 13 (RFC 6455), the request has " +
                       (ws_version ? "'" + ws_version->substr(0, 32) + "'" : std::string("none")),
                   "Sec-WebSocket-Version: 13\r\n");
  const std::string* key = header("sec-websocket-key");
  if (!key) return refusal(400, "Bad Request", "no Sec-WebSocket-Key header");
  if (auto k = base64_decode(*key); !k || k->size() != 16)
    return refusal(400, "Bad Request",
                   "Sec-WebSocket-Key must be 16 bytes in base64, got '" + key->substr(0, 64) + "'");
  HandshakeVerdict v;
  v.key = *key;
  if (subprotocols.empty()) return v;
  const std::string* asked = header("sec-websocket-protocol");
  const std::vector<std::string> wanted = asked ? tokens(*asked) : std::vector<std::string>{};
  for (const std::string& offered : subprotocols)
    if (std::find(wanted.begin(), wanted.end(), offered) != wanted.end()) {
      v.subprotocol = offered;
      return v;
    }
  std::string list;
  for (const std::string& s : subprotocols) list += (list.empty() ? "" : ", ") + s;
  return refusal(400, "Bad Request",
                 "no subprotocol this server speaks: it offers " + list + "; the request asks for " +
                     (asked ? "'" + asked->substr(0, 128) + "'" : std::string("none")) +
                     " (Sec-WebSocket-Protocol)");
}

namespace {

bool valid_close_code(std::uint32_t c) {
  return (c >= 1000 && c <= 1003) || (c >= 1007 && c <= 1014) || (c >= 3000 && c <= 4999);
}

FrameStep error(std::uint16_t code, std::string reason) {
  FrameStep s;
  s.kind = FrameStep::Kind::kError;
  s.code = code;
  s.reason = std::move(reason);
  return s;
}

// A close frame's payload: none, or a valid code and a UTF-8 reason (RFC 6455 5.5.1, 7.4).
FrameStep close_step(std::string_view payload) {
  FrameStep s;
  s.kind = FrameStep::Kind::kClose;
  s.code = kCloseNoStatus;
  if (payload.size() == 1) return error(kCloseProtocolError, "a close frame of 1 byte");
  if (payload.size() >= 2) {
    s.code = static_cast<std::uint16_t>((static_cast<unsigned char>(payload[0]) << 8) |
                                        static_cast<unsigned char>(payload[1]));
    s.reason = std::string(payload.substr(2));
    if (!valid_close_code(s.code))
      return error(kCloseProtocolError, "a close frame with the invalid code " + std::to_string(s.code));
    if (!valid_utf8(s.reason))
      return error(kCloseInvalidData, "a close frame whose reason is not valid UTF-8");
  }
  return s;
}

}  // namespace

FrameStep FrameDecoder::next(std::span<char> in, bool deliver) {
  if (in.size() < 2) return {};
  const auto* p = reinterpret_cast<const std::uint8_t*>(in.data());
  const bool fin = p[0] & 0x80;
  const std::uint8_t opcode = p[0] & 0x0f;
  const bool masked = p[1] & 0x80;
  const std::uint8_t len7 = p[1] & 0x7f;
  // What the first two bytes decide is decided before waiting for the rest.
  if (p[0] & 0x70)
    return error(kCloseProtocolError, "a frame with reserved bits set (no extension was negotiated)");
  if (!masked) return error(kCloseProtocolError, "an unmasked client frame");
  const bool control = opcode & 0x8;
  if (opcode != kOpContinuation && opcode != kOpText && opcode != kOpBinary && opcode != kOpClose &&
      opcode != kOpPing && opcode != kOpPong)
    return error(kCloseProtocolError, "a frame with the unknown opcode " + std::to_string(opcode));
  if (control && !fin) return error(kCloseProtocolError, "a fragmented control frame");
  if (control && len7 > 125) return error(kCloseProtocolError, "a control frame longer than 125 bytes");
  if (opcode == kOpContinuation && !frag_active_)
    return error(kCloseProtocolError, "a continuation frame without a message to continue");
  if ((opcode == kOpText || opcode == kOpBinary) && frag_active_)
    return error(kCloseProtocolError, "a new message before the last fragment of the previous one");
  const std::size_t ext = len7 == 126 ? 2 : len7 == 127 ? 8 : 0;
  const std::size_t header_len = 2 + ext + 4;
  if (in.size() < header_len) return {};
  std::uint64_t len = len7;
  if (ext) {
    len = 0;
    for (std::size_t k = 0; k < ext; ++k) len = (len << 8) | p[2 + k];
    if (len7 == 127 && (len >> 63))
      return error(kCloseProtocolError, "a frame length with its most significant bit set");
  }
  const std::uint64_t total = (opcode == kOpContinuation ? frag_.size() : 0) + len;
  if (!control && total > max_message_bytes_)
    return error(kCloseTooBig, "a message of " + std::to_string(total) +
                                   " bytes or more, beyond this server's limit of " +
                                   std::to_string(max_message_bytes_));
  if (in.size() - header_len < len) return {};
  const std::uint8_t* mask = p + 2 + ext;
  char* payload = in.data() + header_len;
  for (std::size_t k = 0; k < len; ++k) payload[k] = static_cast<char>(payload[k] ^ mask[k & 3]);
  const std::string_view data(payload, static_cast<std::size_t>(len));
  FrameStep s;
  if (opcode == kOpClose) s = close_step(data);
  s.consumed = header_len + static_cast<std::size_t>(len);
  if (opcode == kOpClose) return s;
  s.kind = opcode == kOpPing   ? FrameStep::Kind::kPing
           : opcode == kOpPong ? FrameStep::Kind::kPong
                               : FrameStep::Kind::kNone;
  if (control) {
    s.data = data;
    return s;
  }
  if (!deliver) return s;  // the server is closing: data is no longer delivered
  if (opcode != kOpContinuation && fin) {
    s.kind = FrameStep::Kind::kMessage;
    s.binary = opcode == kOpBinary;
    s.data = data;
  } else if (opcode != kOpContinuation) {
    frag_active_ = true;
    frag_binary_ = opcode == kOpBinary;
    frag_.assign(data);
  } else {
    frag_.append(data);
    if (fin) {
      frag_active_ = false;
      message_ = std::move(frag_);
      frag_.clear();
      s.kind = FrameStep::Kind::kMessage;
      s.binary = frag_binary_;
      s.data = message_;
    }
  }
  return s;
}

}  // namespace augrig::net
