// Every message of an MCAP file, for tests that compare two files message for message.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace augrig::test {

// In file order: ("TOPIC LOG_TIME_NS", the message's bytes). A file that cannot be read is a gtest
// failure (what was read until then comes back).
std::vector<std::pair<std::string, std::vector<std::uint8_t>>> mcap_messages(const std::string& path);

}  // namespace augrig::test
