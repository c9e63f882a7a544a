// WebSocketServer: an RFC 6455 WebSocket server on POSIX sockets, written for the live view
// (net/foxglove_server.hpp) and no bigger than it needs. It listens on one configured address
// (loopback by default; port 0 takes an ephemeral port, port() reports it) and serves every client
// from one I/O thread with poll() and non-blocking sockets: the HTTP/1.1 Upgrade handshake
// (Sec-WebSocket-Accept from SHA-1 and base64 written here, subprotocol negotiation, a status line
// and a plain-words reason for a request it refuses), text and binary messages, fragments
// reassembled, ping/pong, the close handshake with its status codes (1002 protocol error, 1007
// bad UTF-8, 1009 too big, ...), limits on header and message size. Sending never blocks the
// caller: send() puts the message into the client's bounded queue (bytes) and wakes the I/O
// thread. A droppable message that does not fit is dropped and counted; one that must not be
// dropped and still does not fit disconnects the client (counted): a slow client never slows the
// sender. Message bodies are shared between clients (shared_ptr), so a 1.2 MB image is in memory
// once however many clients it goes to. A client may vanish at any moment (mid-handshake, mid-frame
// either way): the server frees it and carries on; SIGPIPE is never raised (MSG_NOSIGNAL).
//
// Threads: start(), the destructor and stop() from one thread; send(), close(), stats() and
// clients() from any thread. The handler's callbacks run on the I/O thread, never under the
// server's lock, so they may call send() and close().
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/expected.hpp"

namespace augrig::net {

// ---- The handshake's primitives (FIPS 180-4, RFC 4648, RFC 6455 section 4.2.2) -------------------

std::array<std::uint8_t, 20> sha1(std::span<const std::uint8_t> data);
std::array<std::uint8_t, 20> sha1(std::string_view text);
std::string base64_encode(std::span<const std::uint8_t> data);
// Strict: padding required, no whitespace; nullopt for anything else.
std::optional<std::vector<std::uint8_t>> base64_decode(std::string_view text);
// Sec-WebSocket-Accept for a Sec-WebSocket-Key: base64(SHA-1(key + the RFC's GUID)).
std::string websocket_accept(std::string_view key);
// Whether `text` is well-formed UTF-8 (RFC 3629: no overlongs, no surrogates, at most U+10FFFF).
bool valid_utf8(std::string_view text);

// ---- The server -----------------------------------------------------------------------------------

using ClientId = std::uint64_t;  // never reused within one server
using SharedBytes = std::shared_ptr<const std::vector<std::uint8_t>>;
SharedBytes share_bytes(std::vector<std::uint8_t> bytes);
SharedBytes share_bytes(std::string_view text);

// Close status codes (RFC 6455 section 7.4.1).
enum CloseCode : std::uint16_t {
  kCloseNormal = 1000,
  kCloseGoingAway = 1001,
  kCloseProtocolError = 1002,
  kCloseUnsupportedData = 1003,
  kCloseNoStatus = 1005,     // never sent: "the close frame had no code"
  kCloseAbnormal = 1006,     // never sent: "the connection ended without a close frame"
  kCloseInvalidData = 1007,  // a text message that is not UTF-8
  kClosePolicy = 1008,
  kCloseTooBig = 1009,
  kCloseInternalError = 1011,
};

struct WebSocketOptions {
  std::string address = "127.0.0.1";  // numeric IPv4 or IPv6 ("0.0.0.0", "::1"), or "localhost"
  int port = 0;                       // 0: an ephemeral port (port() says which)
  // Offered subprotocols in order of preference; a client must ask for one of them (empty: none
  // is negotiated and a client's request for one is ignored).
  std::vector<std::string> subprotocols;
  std::size_t max_clients = 32;                 // more are refused with 503
  std::size_t max_header_bytes = 16 * 1024;     // the whole HTTP request; beyond it: 431
  std::size_t max_message_bytes = 1024 * 1024;  // a received message, fragments together; beyond: 1009
  std::size_t queue_bytes = 16 * 1024 * 1024;   // per client: droppable messages beyond it are dropped
  // Non-droppable messages may go this far beyond queue_bytes; a client whose queue would grow
  // further is disconnected (it has not read for that long).
  std::size_t control_reserve_bytes = 1024 * 1024;
  int handshake_timeout_ms = 10'000;  // from accept to a complete request
  int close_timeout_ms = 1'000;       // for the client's close frame after ours, then the socket closes
  // A client with queued output that has taken no byte for this long is disconnected (0: never).
  int stall_timeout_ms = 0;
  std::string server_header = "augrig";  // the Server: header of every response
};

// Why a client left, for on_close.
struct CloseInfo {
  std::uint16_t code = kCloseAbnormal;  // the client's close code, ours when we closed first, or 1006
  std::string reason;                   // plain words: the close frame's reason or what happened
  bool by_server = false;               // the server ended it (protocol error, overflow, stall, stop)
};

struct WebSocketHandler {
  // A client completed the handshake; `peer` is "address:port".
  std::function<void(ClientId, const std::string& subprotocol, const std::string& peer)> on_open;
  // A complete message (fragments reassembled; a text message is valid UTF-8).
  std::function<void(ClientId, bool binary, std::string_view data)> on_message;
  // A client that was open is gone (called once per on_open); send() to it returns kNoClient.
  std::function<void(ClientId, const CloseInfo&)> on_close;
};

enum class SendResult : std::uint8_t {
  kQueued,        // in the client's queue
  kDropped,       // droppable and the queue was full: counted against the client
  kNoClient,      // no open client by that id (never opened, gone, closing)
  kDisconnected,  // not droppable and not even the reserve could take it: the client is being dropped
};

struct ClientStats {
  ClientId id = 0;
  std::string peer, subprotocol;
  std::size_t queued_bytes = 0;  // accepted by send(), not yet handed to the kernel
  std::uint64_t messages_sent = 0, bytes_sent = 0, messages_dropped = 0, messages_received = 0;
};

struct WebSocketStats {
  std::size_t clients_now = 0;  // open (handshake done, not yet closed)
  std::uint64_t clients_ever = 0;
  std::uint64_t connections_accepted = 0;           // TCP connections, handshake or not
  std::uint64_t handshakes_refused = 0;             // answered with 4xx/5xx
  std::uint64_t handshakes_abandoned = 0;           // closed or timed out before a complete request
  std::uint64_t messages_sent = 0, bytes_sent = 0;  // whole messages written to a socket; their bytes
  std::uint64_t messages_dropped = 0;  // droppable messages refused by full queues, all clients ever
  std::uint64_t messages_received = 0;
  std::uint64_t disconnects = 0;           // open clients gone, for any reason
  std::uint64_t disconnects_overflow = 0;  // ... because a non-droppable message did not fit
  std::uint64_t disconnects_stalled = 0;   // ... because they took nothing for stall_timeout_ms
  std::uint64_t protocol_errors = 0;       // closed by us with 1002, 1007 or 1009
  std::vector<ClientStats> clients;        // the open clients, by id
};

class WebSocketServer {
 public:
  // Binds and listens on the calling thread (so a bad address or a port in use is this call's
  // Error: "net::WebSocketServer::start(): cannot bind 127.0.0.1:8765: Address already in use"),
  // then starts the I/O thread.
  static Expected<std::unique_ptr<WebSocketServer>> start(const WebSocketOptions& options,
                                                          WebSocketHandler handler);
  // stop().
  ~WebSocketServer();
  WebSocketServer(const WebSocketServer&) = delete;
  WebSocketServer& operator=(const WebSocketServer&) = delete;

  // Sends every open client a close frame (1001 going away), waits up to close_timeout_ms for their
  // queues to drain and their close frames, then closes every socket and joins the I/O thread.
  // on_close is called for each client still open. Idempotent.
  void stop();

  int port() const { return port_; }
  const std::string& address() const { return options_.address; }

  // One message, as one frame: `prefix` (at most kMaxPrefixBytes; e.g. a per-client header of a
  // shared body) followed by `body`. Never blocks on the socket.
  static constexpr std::size_t kMaxPrefixBytes = 24;
  SendResult send(ClientId client, bool binary, SharedBytes body, std::span<const std::uint8_t> prefix = {},
                  bool droppable = false);
  SendResult send_text(ClientId client, std::string_view text) {
    return send(client, false, share_bytes(text));
  }
  // Starts the close handshake with `code` (1000 normal, 1008 policy, ...) and `reason` (at most
  // 123 bytes are sent); messages not yet started are discarded.
  void close(ClientId client, std::uint16_t code = kCloseNormal, std::string reason = {});

  WebSocketStats stats() const;
  std::vector<ClientId> clients() const;

 private:
  struct Impl;
  WebSocketServer(const WebSocketOptions& options, WebSocketHandler handler);
  WebSocketOptions options_;
  int port_ = 0;
  std::unique_ptr<Impl> impl_;
};

}  // namespace augrig::net
