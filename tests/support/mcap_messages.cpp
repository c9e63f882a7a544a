#include "tests/support/mcap_messages.hpp"

#include <gtest/gtest.h>

#include "recorder/mcap_reader.hpp"

namespace augrig::test {

std::vector<std::pair<std::string, std::vector<std::uint8_t>>> mcap_messages(const std::string& path) {
  std::vector<std::pair<std::string, std::vector<std::uint8_t>>> v;
  auto r = recorder::McapReader::open(path);
  EXPECT_TRUE(r) << r.error().message;
  if (!r) return v;
  recorder::McapMessage m;
  while (true) {
    auto more = (*r)->next(m);
    EXPECT_TRUE(more) << more.error().message;
    if (!more || !*more) break;
    v.emplace_back((*r)->channels().at(m.channel_id).topic + " " + std::to_string(m.log_time_ns), m.data);
  }
  return v;
}

}  // namespace augrig::test
