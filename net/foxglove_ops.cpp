// parse_client_op() (foxglove_ops.hpp): nesting checked before nlohmann::json parses, then each
// op's fields.
#include "net/foxglove_ops.hpp"

#include <nlohmann/json.hpp>

namespace augrig::net {

using json = nlohmann::json;

namespace {

std::string dump(const json& j) {
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

// Nesting deeper than this is refused before parsing: no Foxglove op needs more than 3.
bool nesting_within(std::string_view text, int limit) {
  int depth = 0;
  bool in_string = false, escaped = false;
  for (const char ch : text) {
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (ch == '\\') {
        escaped = true;
      } else if (ch == '"') {
        in_string = false;
      }
      continue;
    }
    if (ch == '"') in_string = true;
    if (ch == '[' || ch == '{') {
      if (++depth > limit) return false;
    }
    if (ch == ']' || ch == '}') --depth;
  }
  return true;
}

ClientOp error(std::string text) {
  ClientOp op;
  op.error = std::move(text);
  return op;
}

bool is_uint32(const json& j) {
  return j.is_number_unsigned() && j.get<std::uint64_t>() <= 0xffffffffu;
}

void subscriptions(const json& list, ClientOp& op) {
  for (const json& s : list) {
    ClientOp::Entry e;
    if (!s.is_object() || !s.contains("id") || !s.contains("channelId") || !is_uint32(s["id"]) ||
        !s["channelId"].is_number_unsigned()) {
      e.problem = "subscribe: each subscription needs an 'id' (uint32) and a 'channelId', got " +
                  dump(s).substr(0, 200);
    } else {
      e.id = s["id"].get<std::uint32_t>();
      e.channel = s["channelId"].get<std::uint64_t>();
    }
    op.entries.push_back(std::move(e));
  }
}

void subscription_ids(const json& list, ClientOp& op) {
  for (const json& s : list) {
    ClientOp::Entry e;
    if (!is_uint32(s))
      e.problem = "unsubscribe: a subscription id is a uint32, got " + dump(s).substr(0, 200);
    else
      e.id = s.get<std::uint32_t>();
    op.entries.push_back(std::move(e));
  }
}

}  // namespace

ClientOp parse_client_op(bool binary, std::string_view data) {
  if (binary)
    return error(
        "binary client messages are not supported: this server offers no capabilities (no clientPublish, no "
        "services)");
  if (!nesting_within(data, 16)) return error("a JSON message nested deeper than 16 levels");
  const json msg = json::parse(data, nullptr, false);
  if (msg.is_discarded()) return error("a message that is not JSON: " + std::string(data.substr(0, 100)));
  if (!msg.is_object() || !msg.contains("op") || !msg["op"].is_string())
    return error("expected a JSON object with a string 'op'");
  const std::string name = msg["op"].get<std::string>();
  ClientOp op;
  if (name == "subscribe") {
    const auto it = msg.find("subscriptions");
    if (it == msg.end() || !it->is_array()) return error("subscribe: expected an array 'subscriptions'");
    op.kind = ClientOp::Kind::kSubscribe;
    subscriptions(*it, op);
  } else if (name == "unsubscribe") {
    const auto it = msg.find("subscriptionIds");
    if (it == msg.end() || !it->is_array()) return error("unsubscribe: expected an array 'subscriptionIds'");
    op.kind = ClientOp::Kind::kUnsubscribe;
    subscription_ids(*it, op);
  } else {
    return error("op '" + name.substr(0, 64) +
                 "' is not supported by this server (it supports subscribe and unsubscribe)");
  }
  return op;
}

}  // namespace augrig::net
