// What `augrig replay FILE.mcap` reads (recorder/mcap_reader.hpp, ros2/messages.hpp): a selector
// byte, then bit 0 clear: an MCAP file (through a temp file) opened, its "augrig" metadata read and
// its messages streamed to the end (at most 10000), each message's bytes given to the ROS 2
// decoders McapSource uses; bit 0 set: the bytes one message's, given to every decoder. Damage must
// be an Error, never a crash or an allocation beyond the limits.
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "fuzz/fuzz_common.hpp"
#include "recorder/mcap_reader.hpp"
#include "ros2/messages.hpp"

namespace {

void decode_all(const std::vector<std::uint8_t>& msg) {
  std::int64_t stamp = 0;
  (void)augrig::ros2::decode_image(msg, &stamp);
  (void)augrig::ros2::decode_pose_with_covariance(msg);
  (void)augrig::ros2::decode_tf_message(msg);
  (void)augrig::ros2::decode_occlusion_stats(msg);
  (void)augrig::ros2::decode_stereo_frame_info(msg);
  (void)augrig::ros2::decode_compressed_image(msg);
  (void)augrig::ros2::decode_compressed_video(msg);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  augrig::fuzz::Input in(data, size);
  const std::uint8_t mode = in.byte();
  const std::string_view bytes = in.bytes(in.left());
  if (mode & 1) {
    decode_all(std::vector<std::uint8_t>(bytes.begin(), bytes.end()));
    return 0;
  }
  auto r = augrig::recorder::McapReader::open(augrig::fuzz::write_temp("input.mcap", bytes));
  if (!r) {
    if (r.error().message.empty()) std::abort();
    if (augrig::fuzz::verbose()) std::fprintf(stderr, "open: %s\n", r.error().message.c_str());
    return 0;
  }
  (void)(*r)->metadata("augrig");
  augrig::recorder::McapMessage m;
  int messages = 0;
  for (; messages < 10000; ++messages) {
    auto more = (*r)->next(m);
    if (!more && augrig::fuzz::verbose()) std::fprintf(stderr, "next: %s\n", more.error().message.c_str());
    if (!more || !*more) break;
    decode_all(m.data);
  }
  if (augrig::fuzz::verbose()) std::fprintf(stderr, "%d message(s)\n", messages);
  return 0;
}
