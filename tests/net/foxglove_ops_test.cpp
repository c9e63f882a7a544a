// parse_client_op() on its own: the two ops the live view supports with every entry's numbers in
// order, each malformed entry's problem beside the good ones, and each message the server refuses
// whole with its reason (the server's answers to the same mistakes, through a socket:
// FoxgloveServer.ClientMistakesAreAnsweredWithStatusAndTheConnectionStays).
#include "net/foxglove_ops.hpp"

#include <gtest/gtest.h>

namespace augrig::net {
namespace {

using Kind = ClientOp::Kind;

TEST(ParseClientOp, SubscribeAndUnsubscribeWithEachEntryInOrder) {
  const ClientOp s = parse_client_op(
      false,
      R"({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": 3}, {"id": 4294967295, "channelId": 99},
                {"id": -1, "channelId": 1}, 5, {"id": 8, "channelId": 2, "extra": true}]})");
  ASSERT_EQ(s.kind, Kind::kSubscribe) << s.error;
  ASSERT_EQ(s.entries.size(), 5u);
  EXPECT_EQ(s.entries[0].id, 7u);
  EXPECT_EQ(s.entries[0].channel, 3u);
  EXPECT_TRUE(s.entries[0].problem.empty());
  EXPECT_EQ(s.entries[1].id, 4294967295u);
  EXPECT_EQ(s.entries[1].channel, 99u);  // whether the server has it is the server's question
  EXPECT_EQ(
      s.entries[2].problem,
      R"(subscribe: each subscription needs an 'id' (uint32) and a 'channelId', got {"channelId":1,"id":-1})");
  EXPECT_EQ(s.entries[3].problem,
            "subscribe: each subscription needs an 'id' (uint32) and a 'channelId', got 5");
  EXPECT_EQ(s.entries[4].id, 8u);
  const ClientOp u =
      parse_client_op(false, R"({"subscriptionIds": [1, 4294967296, "2", 3], "op": "unsubscribe"})");
  ASSERT_EQ(u.kind, Kind::kUnsubscribe) << u.error;
  ASSERT_EQ(u.entries.size(), 4u);
  EXPECT_EQ(u.entries[0].id, 1u);
  EXPECT_EQ(u.entries[1].problem, "unsubscribe: a subscription id is a uint32, got 4294967296");
  EXPECT_EQ(u.entries[2].problem, R"(unsubscribe: a subscription id is a uint32, got "2")");
  EXPECT_EQ(u.entries[3].id, 3u);
  EXPECT_TRUE(parse_client_op(false, R"({"op": "subscribe", "subscriptions": []})").entries.empty());
}

TEST(ParseClientOp, MessagesRefusedWholeSayWhy) {
  const std::pair<std::string, std::string> cases[] = {
      {"not json {", "a message that is not JSON: not json {"},
      {"[1, 2]", "expected a JSON object with a string 'op'"},
      {R"({"op": 5})", "expected a JSON object with a string 'op'"},
      {R"({"op": "getParameters", "parameterNames": []})",
       "op 'getParameters' is not supported by this server (it supports subscribe and unsubscribe)"},
      {R"({"op": "subscribe"})", "subscribe: expected an array 'subscriptions'"},
      {R"({"op": "subscribe", "subscriptions": {"id": 1}})", "subscribe: expected an array 'subscriptions'"},
      {R"({"op": "unsubscribe", "subscriptionIds": "x"})",
       "unsubscribe: expected an array 'subscriptionIds'"},
      {std::string(17, '[') + std::string(17, ']'), "a JSON message nested deeper than 16 levels"},
  };
  for (const auto& [msg, why] : cases) {
    const ClientOp op = parse_client_op(false, msg);
    EXPECT_EQ(op.kind, Kind::kError) << msg;
    EXPECT_EQ(op.error, why) << msg;
  }
  // 16 levels are fine (then it is not an object with an op); brackets inside strings do not count.
  EXPECT_EQ(parse_client_op(false, std::string(16, '[') + std::string(16, ']')).error,
            "expected a JSON object with a string 'op'");
  EXPECT_EQ(
      parse_client_op(false, R"({"op": "subscribe", "x": "[[[[[[[[[[[[[[[[[[[[\"[[[[", "subscriptions": []})")
          .kind,
      Kind::kSubscribe);
  EXPECT_EQ(
      parse_client_op(true, R"({"op": "subscribe", "subscriptions": []})").error,
      "binary client messages are not supported: this server offers no capabilities (no clientPublish, no "
      "services)");
}

}  // namespace
}  // namespace augrig::net
