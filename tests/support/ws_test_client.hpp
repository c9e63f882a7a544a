// TestWsClient: a deliberately plain WebSocket client on a blocking TCP socket, for the tests of
// net/ (websocket_test.cpp, foxglove_server_test.cpp): it writes whatever bytes a test gives it
// (malformed requests, unmasked or half frames) and parses the server's frames itself, so a test
// sees exactly what went over the wire. Every read has a timeout; nothing here throws.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace augrig::test {

struct WsFrame {
  bool fin = true;
  std::uint8_t opcode = 0;
  std::string payload;
  // A close frame's code and reason (0 when it has none).
  std::uint16_t close_code() const;
  std::string close_reason() const;
};

class TestWsClient {
 public:
  // Connects to host:port. receive_buffer_bytes > 0 sets SO_RCVBUF before connecting (a small
  // window makes a client that does not read fill up quickly).
  explicit TestWsClient(int port, int receive_buffer_bytes = 0, const std::string& host = "127.0.0.1");
  ~TestWsClient();
  TestWsClient(const TestWsClient&) = delete;
  TestWsClient& operator=(const TestWsClient&) = delete;

  bool connected() const { return fd_ >= 0; }
  bool send_raw(std::string_view bytes);
  // Sends a handshake request (Sec-WebSocket-Key "dGhlIHNhbXBsZSBub25jZQ==") asking for
  // `subprotocols` (none when empty) and returns the response's head (status line and headers,
  // up to the blank line); "" when none came within the timeout.
  std::string handshake(const std::string& subprotocols = "", int timeout_ms = 5000);
  // The response head as above, after the test sent its own request.
  std::string read_response_head(int timeout_ms = 5000);
  // Reads the body of a response with a Content-Length (what read_response_head left).
  std::string read_body(const std::string& head, int timeout_ms = 5000);

  // A client frame: masked unless `masked` is false; `rsv` sets the reserved bits (0x70).
  static std::string frame(std::uint8_t opcode, std::string_view payload, bool fin = true, bool masked = true,
                           std::uint8_t rsv = 0);
  bool send_frame(std::uint8_t opcode, std::string_view payload, bool fin = true);
  bool send_text(std::string_view text) { return send_frame(0x1, text); }
  bool send_close(std::uint16_t code, std::string_view reason = {});
  // The next server frame; nullopt on timeout or when the connection ended (then ended() is true).
  std::optional<WsFrame> read_frame(int timeout_ms = 5000);
  // Reads exactly n bytes (part of a frame); false on timeout or end.
  bool read_bytes(std::size_t n, int timeout_ms = 5000);
  // Reads and discards until the server ends the connection; true when it did within the timeout.
  bool wait_closed(int timeout_ms = 5000);
  bool ended() const { return ended_; }

  void close();  // an orderly close of the TCP connection (FIN)
  void abort();  // a reset (RST): SO_LINGER 0, then close

 private:
  bool fill(int timeout_ms);  // reads what is there into buf_; false on timeout or end
  int fd_ = -1;
  std::string buf_;
  bool ended_ = false;
};

}  // namespace augrig::test
