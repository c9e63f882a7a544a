// What a Foxglove client asks of the live view (Foxglove WebSocket protocol v1, client to server),
// parsed from the message alone: the ops the server supports (subscribe, unsubscribe), each entry
// well-formed or with the problem a status message names; anything else an error in plain words.
// FoxgloveServer (foxglove_server.hpp) acts on what it gives; fuzz/fuzz_foxglove_ops.cpp feeds it
// anything.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace augrig::net {

struct ClientOp {
  enum class Kind : std::uint8_t { kSubscribe, kUnsubscribe, kError };
  Kind kind = Kind::kError;
  std::string error;  // kError: what was wrong with the message
  // subscribe: {"id": uint32, "channelId": uint} each; unsubscribe: a uint32 each. In the message's
  // order; `problem` set (and the numbers 0) for an entry that is not well-formed.
  struct Entry {
    std::string problem;
    std::uint32_t id = 0;
    std::uint64_t channel = 0;  // subscribe's; whether the server has it is the server's question
  };
  std::vector<Entry> entries;
};

// A text message of at most 16 levels of nesting holding a JSON object with a string "op"; a binary
// message is an error (the server offers no capabilities that take one).
ClientOp parse_client_op(bool binary, std::string_view data);

}  // namespace augrig::net
