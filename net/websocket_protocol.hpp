// The WebSocket wire format a server reads (RFC 6455), as functions of bytes alone: the verdict on a
// client's HTTP Upgrade request, and the decoder of a client's frames (masking, lengths, control
// frames, fragments, limits, close payloads). WebSocketServer (websocket.hpp) feeds them what its
// sockets receive; fuzz/fuzz_websocket.cpp feeds them anything. Neither touches a socket or a clock.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace augrig::net {

// ---- The handshake -------------------------------------------------------------------------------

// What to answer a complete request head (the bytes before its blank line).
struct HandshakeVerdict {
  int status = 101;           // 101 Switching Protocols, else the refusal's status (400, 405, 426)
  std::string status_text;    // a refusal's ("Bad Request")
  std::string reason;         // a refusal's, in plain words, for its body
  std::string extra_headers;  // a refusal's headers beyond the usual ("Allow: GET\r\n")
  std::string key;            // accepted: the Sec-WebSocket-Key
  std::string subprotocol;    // accepted: the first of `subprotocols` the client asked for
  bool accepted() const { return status == 101; }
};

// Checks the request line (GET, HTTP/1.1), the header lines, Host, Upgrade: websocket, Connection:
// Upgrade, Sec-WebSocket-Version 13, a 16-byte Sec-WebSocket-Key and, when the server offers
// `subprotocols`, that the client asks for one of them. `server` names the server in a refusal.
HandshakeVerdict check_handshake(std::string_view request_head, const std::vector<std::string>& subprotocols,
                                 const std::string& server);

// ---- Frames --------------------------------------------------------------------------------------

// What the next frame of a client's bytes gave.
struct FrameStep {
  enum class Kind : std::uint8_t {
    kNeedMore,  // the frame is not complete yet: nothing consumed
    kError,     // a protocol error: close with `code`, `reason`; read nothing after it
    kMessage,   // a whole message (a frame, or the last of its fragments): `binary`, `data`
    kPing,      // `data`: the payload to send back in a pong
    kPong,
    kClose,  // the client's close frame: `code` (kCloseNoStatus when it has none), `reason`
    kNone,   // a fragment kept, or a data frame dropped (not delivering)
  };
  Kind kind = Kind::kNeedMore;
  std::size_t consumed = 0;  // bytes of the frame
  bool binary = false;
  std::string_view data;  // unmasked in place, or the decoder's: valid until the next call
  std::uint16_t code = 0;
  std::string reason;
};

// A client connection's frames, one at a time, with the state fragments need between them.
class FrameDecoder {
 public:
  explicit FrameDecoder(std::uint64_t max_message_bytes) : max_message_bytes_(max_message_bytes) {}

  // The frame at the start of `in` (unmasked in place). What its first two bytes decide (reserved
  // bits, masking, opcode, control frame rules, fragment order) is decided before the rest arrives;
  // a message beyond max_message_bytes as soon as its length is known. `deliver`: false once the
  // server has sent its close frame (data frames are read and dropped; fragments are not kept).
  FrameStep next(std::span<char> in, bool deliver);

 private:
  std::uint64_t max_message_bytes_;
  bool frag_active_ = false, frag_binary_ = false;
  std::string frag_;     // the fragments of a message so far
  std::string message_;  // the last fragmented message, whole
};

}  // namespace augrig::net
