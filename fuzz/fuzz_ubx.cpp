// UbxStream and the NAV-PVT / NAV-RELPOSNED decoders (nav/ubx.hpp): bytes pushed in chunks whose
// sizes the input chooses, as a serial port or UDP socket delivers them, every frame decoded; the
// stream's counts must add up whatever comes.
#include <cstdlib>

#include "nav/ubx.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  augrig::nav::UbxStream stream("fuzz", size % 2 ? 512 : 8192);
  std::size_t at = 0;
  while (at < size) {
    const std::size_t n = std::min<std::size_t>(size - at, 1 + data[at] % 64);
    stream.push(data + at, n);
    at += n;
    while (auto f = stream.next()) {
      (void)augrig::nav::decode_nav_pvt(*f);
      (void)augrig::nav::decode_nav_relposned(*f);
    }
  }
  const auto& c = stream.counts();
  if (c.bytes != c.frame_bytes + c.skipped_bytes + stream.pending_bytes()) std::abort();
  return 0;
}
