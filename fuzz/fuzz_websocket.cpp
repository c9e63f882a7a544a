// The WebSocket server's parsers of what a client sends (net/websocket_protocol.hpp), on the bytes
// a socket would deliver: a request head up to its blank line, checked, then the frames after it
// fed to the decoder in chunks whose sizes the input chooses (as recv() returns them), the server
// delivering or closing as the input says. Whatever comes: each step consumes no more than it was
// given, a step that needs more consumes nothing, a message never exceeds the limit, and after a
// close or an error nothing more is read (as the server does).
#include <cstdlib>
#include <string>

#include "fuzz/fuzz_common.hpp"
#include "net/websocket.hpp"
#include "net/websocket_protocol.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using augrig::net::FrameStep;
  augrig::fuzz::Input in(data, size);
  const std::uint8_t mode = in.byte();
  const std::string all(in.bytes(in.left()));
  std::string rest = all;
  if (const auto end = all.find("\r\n\r\n"); end != std::string::npos) {
    const auto v =
        augrig::net::check_handshake(std::string_view(all).substr(0, end), {"foxglove.websocket.v1"}, "fuzz");
    if (v.accepted() && augrig::net::websocket_accept(v.key).size() != 28) std::abort();
    if (!v.accepted() && (v.status < 400 || v.reason.empty())) std::abort();
    rest = all.substr(end + 4);
  }
  const std::uint64_t limit = mode & 1 ? 1000 : 1 << 20;
  augrig::net::FrameDecoder decoder(limit);
  std::string buffer;  // what has arrived and is not consumed yet
  std::size_t at = 0, chunk = 1 + mode % 61;
  bool deliver = true;
  while (at < rest.size()) {
    const std::size_t n = std::min(rest.size() - at, chunk);
    buffer.append(rest, at, n);
    at += n;
    chunk = 1 + (chunk * 7 + n) % 97;
    std::size_t pos = 0;
    while (true) {
      const FrameStep s = decoder.next(std::span<char>(buffer.data() + pos, buffer.size() - pos), deliver);
      if (s.kind == FrameStep::Kind::kNeedMore) {
        if (s.consumed != 0) std::abort();
        break;
      }
      if (s.kind == FrameStep::Kind::kError) {
        if (s.reason.empty()) std::abort();
        return 0;
      }
      if (s.consumed == 0 || s.consumed > buffer.size() - pos) std::abort();
      if (s.kind == FrameStep::Kind::kMessage && (!deliver || s.data.size() > limit)) std::abort();
      if (s.kind == FrameStep::Kind::kClose) return 0;
      if (s.kind == FrameStep::Kind::kMessage && !s.binary) (void)augrig::net::valid_utf8(s.data);
      pos += s.consumed;
      if (mode & 0x80 && s.kind == FrameStep::Kind::kPing) deliver = false;  // the server starts closing
    }
    buffer.erase(0, pos);
  }
  return 0;
}
